"""Test suite of the meanfield toolkit."""
