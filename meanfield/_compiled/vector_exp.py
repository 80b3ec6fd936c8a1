"""The exponential that compiled loops vectorise: ``exp`` over a buffer, within 1 ulp.

``math.exp`` inside a numba loop is a call into the C library per value: it does not
vectorise, and at a few nanoseconds a value it dominates the loops that evaluate Gaussians
(the KDE's axis factors, the signs' field at each human).  :func:`exp_inplace` computes
``exp`` over a buffer with arithmetic only, which LLVM turns into SIMD code:

    exp(v) = 2^k p(r),   k = round(v / ln 2),   r = (v - k ln2_hi) - k ln2_lo,   |r| <= ln2 / 2

with the Cody–Waite split of ``ln 2`` (``ln2_hi`` has 11 trailing zero bits, so ``k ln2_hi``
is exact for ``|k| < 2^11``) and ``p`` the Taylor polynomial of degree 13 (truncation below
5e-18 relative on ``|r| <= ln2/2``); ``2^k`` is its exponent bits ``(k + 1023) << 52`` read
as a float, one bit cast (:func:`meanfield._compiled.core.bits_as_float`; a ``view`` of an integer
buffer did the same at 0.2 s more compile time and a second pass).  The result is within
1 ulp of ``exp`` (tests: ``tests/compiled/test_core.py``).  Arguments are clamped to
``[-708, 700]`` (below ``-708`` the result is 0: the callers' Gaussians are then more than
37 bandwidths away).
"""

from __future__ import annotations

import numpy as np

from meanfield._compiled.core import bits_as_float, inner

__all__ = ["exp_inplace", "ARG_MIN", "ARG_MAX"]

ARG_MIN = -708.0
"""Arguments below this give 0."""
ARG_MAX = 700.0
"""Arguments above this are clamped to it."""
_LOG2E = 1.4426950408889634
_LN2_HI = 0.693145751953125
_LN2_LO = 1.4286068203094173e-06
_C3, _C4, _C5, _C6, _C7, _C8 = 1 / 6, 1 / 24, 1 / 120, 1 / 720, 1 / 5040, 1 / 40320
_C9, _C10, _C11, _C12, _C13 = 1 / 362880, 1 / 3628800, 1 / 39916800, 1 / 479001600, 1 / 6227020800


@inner
def exp_inplace(vals: np.ndarray, count: int) -> None:
    """``vals[:count] = exp(vals[:count])`` in one vectorisable pass.

    Parameters
    ----------
    vals : ndarray of float64, shape (>= count,)
        The arguments, overwritten by their exponentials.
    count : int
        How many leading entries to transform.
    """
    for i in range(count):
        a = vals[i]  # min(max(a, ARG_MIN), ARG_MAX), as numba's min and max select (NaN stays)
        v = ARG_MIN if ARG_MIN > a else a
        v = ARG_MAX if ARG_MAX < v else v
        kf = np.floor(v * _LOG2E + 0.5)
        r = (v - kf * _LN2_HI) - kf * _LN2_LO
        p = _C13  # Horner, degree 13
        p = p * r + _C12
        p = p * r + _C11
        p = p * r + _C10
        p = p * r + _C9
        p = p * r + _C8
        p = p * r + _C7
        p = p * r + _C6
        p = p * r + _C5
        p = p * r + _C4
        p = p * r + _C3
        p = p * r + 0.5
        p = p * r + 1.0
        p = p * r + 1.0
        p = p if vals[i] >= ARG_MIN else 0.0  # (the argument, read before it is overwritten)
        vals[i] = p * bits_as_float((np.int64(kf) + 1023) << 52)  # p 2^k
