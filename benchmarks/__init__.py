"""Benchmarks of the toolkit, each against an anchor measured in the same run.

Every ``bench_*.py`` module is also a script (``python benchmarks/bench_kde.py``), and
:mod:`benchmarks.suite` runs them all as ``meanfield bench [--quick] --out FILE.json``.
This package sits above ``meanfield``, ``analysis`` and ``verification``: it imports them,
and none of them imports it.
"""
