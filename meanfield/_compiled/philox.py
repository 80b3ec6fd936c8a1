"""Counter-based random numbers: Philox4x64-10, and the crowd's Gaussian noise drawn from it.

A counter-based generator is a keyed bijection ``block = f_key(counter)``: the random numbers
for a given counter are a pure function of the counter and the key, with no state carried
from one draw to the next (Salmon et al. 2011).  The crowd's noise ``ξ_j`` of step ``n`` is
then a function of ``(seed, n, j)`` alone, so that the humans can be drawn in any order, in
any number of chunks, on any number of threads, and give the same numbers.

The block function
    :func:`philox_block` is Philox4x64-10 with the constants of Random123 (multipliers
    ``0xD2E7470EE14C6C93``, ``0xCA5A826395121157``; Weyl increments of the key
    ``0x9E3779B97F4A7C15``, ``0xBB67AE8584CAA73B``): ten rounds of two 64×64→128-bit
    multiplications, each split into 32-bit halves (numba has no 128-bit integers).  It is an
    :func:`~meanfield._compiled.core.inner` helper: a plain function on uint64 that becomes its
    ``numba.njit(cache=True)`` version when a compiled loop of a module that imports it compiles
    (so importing the toolkit never imports numba).  :func:`philox4x64_10` runs it over rows of
    counters, with a vectorised numpy twin.

The exact reference: numpy's ``np.random.Philox``
    is the same Philox4x64-10, with the counter and key as little-endian uint64 words (word 0
    the least significant).  Its ``random_raw`` *increments the counter before each block*
    (``philox_next`` in numpy's ``numpy/random/src/philox/philox.h``: ``ctr.v[0]++`` with the
    carry into words 1-3, then the block): ``Philox(counter=c, key=k).random_raw(4)`` is the
    block of counter ``c + 1`` (mod 2²⁵⁶), the next four values that of ``c + 2``, and so on.
    The block of counter ``c`` is hence ``Philox(counter=c - 1, key=k).random_raw(4)``
    (``c - 1`` mod 2²⁵⁶, the borrow running through the words).  ``key`` sets the key directly
    (``seed`` would go through ``SeedSequence``).  The tests check the block function against
    numpy that way, and against Random123's known-answer vectors.

The crowd's noise
    Human ``j`` at step ``n`` draws its two N(0, 1) components ``(z0, z1)`` from one block,
    :func:`normal_pair`:

    * key ``(k0, k1) = (seed, stream)`` (:func:`noise_key`; the crowd's noise is stream 0), set
      directly as numpy's ``Philox(key=...)`` does (numpy's documentation makes independent
      streams from consecutive keys the same way; the tests check neighbouring seeds);
    * counter ``(n, j, 0, 0)``: word 0 the step, word 1 the human; words 2 and 3 are 0 (free for
      further draws per human and step);
    * uniforms ``u = ((w >> 11) + 1) 2⁻⁵³`` from the 53 high bits of block words 0 and 1: exact
      doubles in (0, 1], so ``log(u)`` is finite (``u = 1`` gives ``r = 0``);
    * Box–Muller: ``r = sqrt(-2 log u₀)``, ``z0 = r cos(2π u₁)``, ``z1 = r sin(2π u₁)``.  The
      smallest ``u₀`` is 2⁻⁵³, so ``|z| <= sqrt(106 ln 2) = 8.57`` (the normal's mass beyond is
      about 1e-17).  Block words 2 and 3 are not used.

    :func:`fill_normal_pairs` runs it over a range of humans (the compiled loop, and its numpy
    twin vectorised over the humans); :func:`standard_normals` is the same from a seed.  A
    compiled crowd step calls :func:`normal_pair` inside its own loop (``prange`` included: it
    allocates nothing and shares no state).

    So the draw of ``(seed, step, human, component)`` is a pure function of those four integers.

The two paths give the same bits.  The integer part (block, uniforms) is exact; Box–Muller's
``log``, ``cos`` and ``sin`` are computed here from correctly rounded arithmetic only (fdlibm's
``log``, within 1 ulp of the correctly rounded value; ``cos``/``sin`` of ``2πu`` by an exact
reduction of ``u`` to the nearest quarter turn and Taylor series, within 2e-16), the same
operations in the same order on both paths.  With numpy's ``np.log`` (SIMD code, not the C
library's ``log`` that numba calls) the two paths differed by up to 2 ulp in ``z``, and numpy's
results depend on the machine's SIMD level; now the noise is the same on every machine and path
(``tests/compiled/test_philox.py``).

References
----------
.. [1] J. K. Salmon, M. A. Moraes, R. O. Dror and D. E. Shaw, "Parallel random numbers: as easy
   as 1, 2, 3", Proc. SC'11 (Int. Conf. for High Performance Computing, Networking, Storage
   and Analysis), 2011, doi:10.1145/2063384.2063405.  (Random123: D. E. Shaw Research's
   implementation, whose constants and known-answer vectors these are.)
.. [2] G. E. P. Box and M. E. Muller, "A note on the generation of random normal deviates",
   Ann. Math. Statist. 29(2), 610-611, 1958.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import compiled, inner

__all__ = [
    "philox_block",
    "philox4x64_10",
    "normal_pair",
    "fill_normal_pairs",
    "standard_normals",
    "noise_key",
    "PHILOX_M0",
    "PHILOX_M1",
    "PHILOX_W0",
    "PHILOX_W1",
]

_U64 = (1 << 64) - 1

PHILOX_M0 = 0xD2E7470EE14C6C93
"""Philox4x64's first multiplier (Random123's ``PHILOX_M4x64_0``)."""
PHILOX_M1 = 0xCA5A826395121157
"""Philox4x64's second multiplier (``PHILOX_M4x64_1``)."""
PHILOX_W0 = 0x9E3779B97F4A7C15
"""The Weyl increment of key word 0 between rounds (``PHILOX_W64_0``, the golden ratio's bits)."""
PHILOX_W1 = 0xBB67AE8584CAA73B
"""The Weyl increment of key word 1 (``PHILOX_W64_1``, sqrt(3) - 1's bits)."""
ROUNDS = 10

# The constants as numba sees them: np.uint64 globals are frozen into the compiled code as uint64
# (a Python int would be an int64, and uint64 with int64 gives float64 in numba's typing).
_M0_LO = np.uint64(PHILOX_M0 & 0xFFFFFFFF)
_M0_HI = np.uint64(PHILOX_M0 >> 32)
_M1_LO = np.uint64(PHILOX_M1 & 0xFFFFFFFF)
_M1_HI = np.uint64(PHILOX_M1 >> 32)
_W0 = np.uint64(PHILOX_W0)
_W1 = np.uint64(PHILOX_W1)
_MASK32 = np.uint64(0xFFFFFFFF)
_S32 = np.uint64(32)
_S11 = np.uint64(11)
_ZERO = np.uint64(0)
_TWO_M53 = 2.0**-53
_TWO_PI = 2.0 * math.pi


# ----------------------------------------------------------------------------- the block function
@inner
def _mulhilo(a, m_lo, m_hi):
    """``(hi, lo)`` of the 128-bit product ``a m``, from 32-bit halves (``m`` given as its halves)."""
    a_lo = a & _MASK32
    a_hi = a >> _S32
    ll = a_lo * m_lo  # each partial product < 2^64: exact
    lh = a_lo * m_hi
    hl = a_hi * m_lo
    hh = a_hi * m_hi
    mid = (ll >> _S32) + (lh & _MASK32) + (hl & _MASK32)  # < 3 * 2^32: exact
    hi = hh + (lh >> _S32) + (hl >> _S32) + (mid >> _S32)  # the high word of a product: no overflow
    lo = (mid << _S32) | (ll & _MASK32)  # the low word, without a wrapping multiplication
    return hi, lo


@inner
def philox_block(c0, c1, c2, c3, k0, k1):
    """The Philox4x64-10 block of counter ``(c0, c1, c2, c3)`` under key ``(k0, k1)`` (all uint64).

    For compiled loops (``numba.njit(cache=True)`` once a loop of the importing module compiles);
    from Python use :func:`philox4x64_10`.  Each round: ``(h0, l0) = M0 c0``, ``(h1, l1) = M1 c2``
    (128-bit products), then ``c = (h1 ^ c1 ^ k0, l1, h0 ^ c3 ^ k1, l0)``; the key gains
    ``(W0, W1)`` between rounds (Salmon et al. 2011, Random123's ``philox4x64_R(10, ...)``).

    Parameters
    ----------
    c0, c1, c2, c3 : np.uint64
        The counter, word 0 the least significant (numpy's ``Philox`` order).
    k0, k1 : np.uint64
        The key.

    Returns
    -------
    tuple of 4 np.uint64
        The block: four independent uniform 64-bit words.
    """
    x0, x1, x2, x3 = np.uint64(c0), np.uint64(c1), np.uint64(c2), np.uint64(c3)  # (uint64 throughout:
    ka, kb = np.uint64(k0), np.uint64(k1)  # an int64 among them would turn numba's arithmetic to float64)
    for r in range(ROUNDS):
        if r > 0:
            ka = ka + _W0  # wraps mod 2^64
            kb = kb + _W1
        h0, l0 = _mulhilo(x0, _M0_LO, _M0_HI)
        h1, l1 = _mulhilo(x2, _M1_LO, _M1_HI)
        x0, x1, x2, x3 = h1 ^ x1 ^ ka, l1, h0 ^ x3 ^ kb, l0
    return x0, x1, x2, x3


def _mulhilo_numpy(a, m):
    """``(hi, lo)`` of ``a m`` for a uint64 array ``a`` and a 64-bit int ``m`` (numpy, elementwise)."""
    m_lo, m_hi = np.uint64(m & 0xFFFFFFFF), np.uint64(m >> 32)
    a_lo, a_hi = a & _MASK32, a >> _S32
    ll, lh, hl, hh = a_lo * m_lo, a_lo * m_hi, a_hi * m_lo, a_hi * m_hi
    mid = (ll >> _S32) + (lh & _MASK32) + (hl & _MASK32)
    hi = hh + (lh >> _S32) + (hl >> _S32) + (mid >> _S32)
    return hi, a * np.uint64(m)  # an array product wraps mod 2^64 silently: the low word


def _blocks_numpy(c0, c1, c2, c3, k0, k1):
    """Philox4x64-10 over uint64 arrays of counter words (one block per element), keys as ints."""
    c0, c1, c2, c3 = (np.asarray(c, dtype=np.uint64) for c in (c0, c1, c2, c3))
    k0, k1 = int(k0), int(k1)
    for r in range(ROUNDS):
        ka = np.uint64((k0 + r * PHILOX_W0) & _U64)  # the key schedule in Python ints: no overflow warning
        kb = np.uint64((k1 + r * PHILOX_W1) & _U64)
        h0, l0 = _mulhilo_numpy(c0, PHILOX_M0)
        h1, l1 = _mulhilo_numpy(c2, PHILOX_M1)
        c0, c1, c2, c3 = h1 ^ c1 ^ ka, l1, h0 ^ c3 ^ kb, l0
    return c0, c1, c2, c3


def _philox4x64_10_numpy(counters, key):
    out = np.empty((counters.shape[0], 4), dtype=np.uint64)
    r = _blocks_numpy(counters[:, 0], counters[:, 1], counters[:, 2], counters[:, 3], key[0], key[1])
    for i in range(4):
        out[:, i] = r[i]
    return out


@compiled(fallback=_philox4x64_10_numpy)
def philox4x64_10(counters: np.ndarray, key: np.ndarray) -> np.ndarray:
    """Philox4x64-10 blocks (Salmon et al. 2011), one per row of counters: a pure function of counter and key.

    Equal to numpy's ``np.random.Philox``: ``philox4x64_10(c, k)[i]`` is
    ``Philox(counter=c[i] - 1, key=k).random_raw(4)`` (numpy increments its counter before a block;
    see the module's doc), and to Random123's known-answer vectors.

    Parameters
    ----------
    counters : ndarray of uint64, shape (n, 4)
        One 256-bit counter per row, word 0 the least significant.
    key : ndarray of uint64, shape (2,)
        The 128-bit key, word 0 the least significant.

    Returns
    -------
    ndarray of uint64, shape (n, 4)
        The blocks.

    References
    ----------
    .. [1] J. K. Salmon, M. A. Moraes, R. O. Dror and D. E. Shaw, "Parallel random numbers: as easy
       as 1, 2, 3", Proc. SC'11, 2011, doi:10.1145/2063384.2063405.
    """
    n = counters.shape[0]
    out = np.empty((n, 4), dtype=np.uint64)
    k0, k1 = key[0], key[1]
    for i in range(n):
        r0, r1, r2, r3 = philox_block(counters[i, 0], counters[i, 1], counters[i, 2], counters[i, 3], k0, k1)
        out[i, 0] = r0
        out[i, 1] = r1
        out[i, 2] = r2
        out[i, 3] = r3
    return out


# ----------------------------------------------------------------------------- log and sin/cos, arithmetic only
# Box–Muller's log, cos and sin from +, -, *, /, sqrt, floor and frexp alone: IEEE-754 rounds
# these exactly the same way in numpy and in numba (which contracts nothing into FMAs without
# fastmath), so the two paths give the same bits, on every machine, whatever its math library
# (numpy's SIMD np.log differed from the C library's log by 1 ulp on 0.3 % of arguments on an
# AVX-512 machine).
_SQRT_HALF = math.sqrt(0.5)
_LN2_HI = float.fromhex("0x1.62e42fee00000p-1")
"""``ln 2`` to 32 bits (its last 21 bits zero): ``e ln2_hi`` is exact for ``|e| < 2²¹`` (fdlibm's split)."""
_LN2_LO = 1.9082149292705877e-10
"""``ln 2 - ln2_hi`` to double precision (``ln2_hi + ln2_lo`` is ln 2 within 2e-26)."""
_ATANH_TERMS = tuple(2.0 / (2 * k + 1) for k in range(11, 0, -1))
"""``log(1 + f) = 2 atanh(s) = 2s + s R``, ``s = f/(2 + f)``, ``R = Σ 2 s²ᵏ/(2k + 1)`` for k = 1..11, highest
term first (``|s| <= 0.1716`` for ``1 + f`` in [√½, √2]: the first term left out is below 2⁻⁶⁰ of ``log``)."""
_COS_TERMS = tuple((-1) ** k / math.factorial(2 * k) for k in range(8, -1, -1))
"""``cos a = Σ (-1)ᵏ a²ᵏ/(2k)!``, k <= 8, highest first (``|a| <= π/4``: the rest is below 3e-18)."""
_SIN_TERMS = tuple((-1) ** k / math.factorial(2 * k + 1) for k in range(8, -1, -1))
"""``sin a = a Σ (-1)ᵏ a²ᵏ/(2k+1)!``, k <= 8, highest first (the rest is below 1e-19)."""


@inner
def _log_unit(u):
    """``log u`` for ``u`` in (0, 1] (fdlibm's ``log``: ``u = (1 + f) 2ᵉ``, ``1 + f`` in [√½, √2], ``f`` exact,
    ``log(1 + f) = f - (f²/2 - s (f²/2 + R))``); within 1 ulp of the correctly rounded logarithm."""
    m, e = math.frexp(u)
    if m < _SQRT_HALF:
        m = 2.0 * m
        e = e - 1
    f = m - 1.0  # exact (Sterbenz)
    s = f / (2.0 + f)
    z = s * s
    p = 0.0
    for c in _ATANH_TERMS:
        p = p * z + c
    r = z * p
    hfsq = 0.5 * f * f
    return e * _LN2_HI - ((hfsq - (s * (hfsq + r) + e * _LN2_LO)) - f)


@inner
def _cos_sin_turn(u):
    """``(cos 2πu, sin 2πu)`` for ``u`` in [0, 1]: ``u = q/4 + t`` exactly (nearest quarter turn ``q``,
    ``|t| <= 1/8``), the Taylor series at ``a = 2π t``, then ``q`` quarter turns by swaps and signs."""
    q = math.floor(4.0 * u + 0.5)
    a = _TWO_PI * (u - 0.25 * q)  # (u - q/4: exact, both are multiples of 2^-53)
    a2 = a * a
    c = 0.0
    for k in _COS_TERMS:
        c = c * a2 + k
    s = 0.0
    for k in _SIN_TERMS:
        s = s * a2 + k
    s = a * s
    quarter = int(q) & 3
    if quarter == 0:
        return c, s
    if quarter == 1:
        return -s, c
    if quarter == 2:
        return -c, -s
    return s, -c


def _log_unit_numpy(u):
    m, e = np.frexp(u)
    low = m < _SQRT_HALF
    m = np.where(low, 2.0 * m, m)
    e = e - low
    f = m - 1.0
    s = f / (2.0 + f)
    z = s * s
    p = np.zeros_like(u)
    for c in _ATANH_TERMS:
        p = p * z + c
    r = z * p
    hfsq = 0.5 * f * f
    return e * _LN2_HI - ((hfsq - (s * (hfsq + r) + e * _LN2_LO)) - f)


def _cos_sin_turn_numpy(u):
    q = np.floor(4.0 * u + 0.5)
    a = _TWO_PI * (u - 0.25 * q)
    a2 = a * a
    c = np.zeros_like(u)
    for k in _COS_TERMS:
        c = c * a2 + k
    s = np.zeros_like(u)
    for k in _SIN_TERMS:
        s = s * a2 + k
    s = a * s
    quarter = q.astype(np.int64) & 3
    cos = np.select([quarter == 0, quarter == 1, quarter == 2], [c, -s, -c], s)
    sin = np.select([quarter == 0, quarter == 1, quarter == 2], [s, c, -s], -c)
    return cos, sin


# ----------------------------------------------------------------------------- the crowd's normals
@inner
def normal_pair(key0, key1, step, human):
    """One human's two N(0, 1) draws at one step: Box–Muller on the Philox block of counter ``(step, human, 0, 0)``.

    A pure function of its arguments (no state, no allocation): call it from any compiled loop,
    ``prange`` included, in any order.  The mapping is in the module's doc.

    Parameters
    ----------
    key0, key1 : np.uint64
        The key (:func:`noise_key`: the seed, the stream).
    step : int
        The time step, >= 0 (counter word 0).
    human : int
        The human's index, >= 0 (counter word 1).

    Returns
    -------
    (float, float)
        ``z0 = r cos(2π u₁)``, ``z1 = r sin(2π u₁)``, ``r = sqrt(-2 log u₀)`` with ``u₀, u₁`` in (0, 1]
        from the 53 high bits of the block's words 0 and 1 (Box and Muller 1958).

    References
    ----------
    .. [1] J. K. Salmon et al., "Parallel random numbers: as easy as 1, 2, 3", SC'11, 2011.
    .. [2] G. E. P. Box and M. E. Muller, "A note on the generation of random normal deviates",
       Ann. Math. Statist. 29(2), 610-611, 1958.
    """
    w0, w1, _, _ = philox_block(step, human, _ZERO, _ZERO, key0, key1)  # (it casts to uint64)
    u0 = (np.float64(w0 >> _S11) + 1.0) * _TWO_M53  # (0, 1], exact
    u1 = (np.float64(w1 >> _S11) + 1.0) * _TWO_M53
    r = math.sqrt(-2.0 * _log_unit(u0))
    c, s = _cos_sin_turn(u1)
    return r * c, r * s


def _fill_normal_pairs_numpy(key0, key1, step, first, out):
    n = out.shape[0]
    humans = np.uint64(first) + np.arange(n, dtype=np.uint64)
    steps = np.full(n, np.uint64(step), dtype=np.uint64)
    zero = np.zeros(n, dtype=np.uint64)
    w0, w1, _, _ = _blocks_numpy(steps, humans, zero, zero, key0, key1)
    u0 = ((w0 >> _S11).astype(np.float64) + 1.0) * _TWO_M53
    u1 = ((w1 >> _S11).astype(np.float64) + 1.0) * _TWO_M53
    r = np.sqrt(-2.0 * _log_unit_numpy(u0))
    c, s = _cos_sin_turn_numpy(u1)
    out[:, 0] = r * c
    out[:, 1] = r * s
    return out


@compiled(fallback=_fill_normal_pairs_numpy)
def fill_normal_pairs(key0: np.uint64, key1: np.uint64, step: int, first: int, out: np.ndarray) -> np.ndarray:
    """``out[i] = normal_pair(key0, key1, step, first + i)``: the N(0, 1) pairs of humans ``first .. first + n - 1``.

    Each row depends only on ``(key, step, first + i)``: any split of the humans into calls gives
    the same numbers.  The numpy twin draws all the rows at once (vectorised over the humans).

    Parameters
    ----------
    key0, key1 : np.uint64
        The key (:func:`noise_key`).
    step : int
        The time step, >= 0.
    first : int
        The index of the human in row 0, >= 0.
    out : ndarray of float64, shape (n, 2)
        Filled with the pairs.

    Returns
    -------
    ndarray
        ``out``.
    """
    for i in range(out.shape[0]):
        z0, z1 = normal_pair(key0, key1, step, first + i)
        out[i, 0] = z0
        out[i, 1] = z1
    return out


def noise_key(seed: int, stream: int = 0) -> tuple[np.uint64, np.uint64]:
    """The Philox key of a seed's noise: ``(seed, stream)``, set directly (as ``np.random.Philox(key=...)`` does).

    Parameters
    ----------
    seed : int
        In [0, 2⁶⁴): key word 0.
    stream : int, default 0
        In [0, 2⁶⁴): key word 1, which separates independent uses of one seed (0: the crowd's noise).

    Returns
    -------
    (np.uint64, np.uint64)

    Raises
    ------
    ValueError
        When ``seed`` or ``stream`` is not an integer in [0, 2⁶⁴).
    """
    for name, value in (("seed", seed), ("stream", stream)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or not 0 <= int(value) <= _U64:
            raise ValueError(f"{name} must be an integer in [0, 2**64), got {value!r}")
    return np.uint64(int(seed)), np.uint64(int(stream))


def standard_normals(seed: int, step: int, out: np.ndarray, first: int = 0, stream: int = 0) -> np.ndarray:
    """The crowd's N(0, 1) noise of one step from a seed: row ``i`` of ``out`` is human ``first + i``'s pair.

    :func:`fill_normal_pairs` with the key :func:`noise_key` ``(seed, stream)``, arguments checked.
    The draw for ``(seed, step, human, component)`` is a pure function of those integers (counter
    ``(step, human, 0, 0)``, Box–Muller; see the module's doc), whatever the order, chunking or
    threads that compute it.

    Parameters
    ----------
    seed : int
        In [0, 2⁶⁴).
    step : int
        The time step, in [0, 2⁶³).
    out : ndarray of float64, shape (n, 2)
        Filled with the pairs.
    first : int, default 0
        The human of row 0; ``first + n <= 2⁶³``.
    stream : int, default 0
        In [0, 2⁶⁴); 0 is the crowd's noise.

    Returns
    -------
    ndarray
        ``out``.

    Raises
    ------
    ValueError
        When an argument is outside its range, or ``out`` is not a float64 array of shape (n, 2).

    References
    ----------
    .. [1] J. K. Salmon et al., "Parallel random numbers: as easy as 1, 2, 3", SC'11, 2011.
    .. [2] G. E. P. Box and M. E. Muller, Ann. Math. Statist. 29(2), 610-611, 1958.
    """
    key0, key1 = noise_key(seed, stream)
    if not (isinstance(out, np.ndarray) and out.dtype == np.float64 and out.ndim == 2 and out.shape[1] == 2):
        raise ValueError("out must be a float64 array of shape (n, 2)")
    big = 1 << 63
    for name, value in (("step", step), ("first", first)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or not 0 <= int(value) < big:
            raise ValueError(f"{name} must be an integer in [0, 2**63), got {value!r}")
    if int(first) + out.shape[0] > big:
        raise ValueError(f"first + n must be <= 2**63, got {int(first) + out.shape[0]}")
    return fill_normal_pairs(key0, key1, int(step), int(first), out)
