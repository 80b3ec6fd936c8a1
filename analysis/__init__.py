"""analysis: constants and designs behind the paper's guarantees (Poincaré constant,
decay rates and ISS gains, robot count, bounded β/γ program, NMPC baseline).

Built on :mod:`meanfield`; never imported by it.  The capabilities arrive with their
own issue; this package is intentionally empty for now.
"""

__all__: list[str] = []
