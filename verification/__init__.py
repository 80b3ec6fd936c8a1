"""verification: each claim of the paper checked numerically, with a verdict.

Built on :mod:`analysis` and :mod:`meanfield`; never imported by them.  The checks
arrive with their own issue; this package is intentionally empty for now.
"""

__all__: list[str] = []
