"""Counter-based Gaussian noise: Philox4x32-10 and a 256-layer ziggurat, a pure function of (seed, step, human).

A counter-based generator is a keyed bijection ``block = f_key(counter)``: the random numbers
for a given counter are a pure function of the counter and the key, with no state carried
from one draw to the next (Salmon et al. 2011).  The crowd's noise ``ξ_j`` of step ``n`` is
then a function of ``(seed, n, j)`` alone, so that the humans can be drawn in any order, in
any number of chunks, on any number of threads, and give the same numbers.

The block function
    :func:`philox4x32_block` is Philox4x32-10 with the constants of Random123 (multipliers
    ``0xD2511F53``, ``0xCD9E8D57``; Weyl increments of the key ``0x9E3779B9``, ``0xBB67AE85``):
    ten rounds of two 32×32→64-bit multiplications.  The 32-bit words are held in uint64, so a
    product is exact and its high and low halves are a shift and a mask.  It is an
    :func:`~meanfield._compiled.core.inner` helper: a plain function on uint64 that becomes its
    ``numba.njit(cache=True)`` version when a compiled loop of a module that imports it compiles
    (so importing the toolkit never imports numba).  :func:`philox4x32_10` runs it over rows of
    counters, with a vectorised numpy twin; both are checked against Random123's known-answer
    vectors (``tests/compiled/test_philox.py``).

The crowd's noise
    Human ``j`` at step ``n`` under ``seed`` draws its two N(0, 1) components ``(z0, z1)``
    (:func:`normal_pair`):

    * key ``(seed & 0xffffffff, seed >> 32)`` (:func:`noise_key`; ``seed`` in [0, 2⁶⁴));
    * counter ``(j, n & 0xffffffff, attempt, n >> 32)`` (word 0 first; ``j`` in [0, 2³²),
      ``n`` in [0, 2⁶⁴));
    * attempt 0: the block's 32-bit words ``x0 .. x3`` make two 64-bit words ``A = x0:x1``,
      ``B = x2:x3`` (``x0``, ``x2`` the high halves); ``z0``'s first ziggurat attempt uses ``A``,
      ``z1``'s uses ``B``;
    * the ziggurat (Marsaglia and Tsang 2000; 256 layers, numpy's 64-bit layout, tables
      :data:`ZIG_KI`, :data:`ZIG_WI`, :data:`ZIG_FI` computed once at import): bits 0-7 of a
      word pick the layer ``i``, bit 8 the sign, bits 9-60 a 52-bit magnitude ``m``;
      ``x = ±m wi[i]``, accepted at once when ``m < ki[i]`` (98.5 % of draws);
    * a rejected draw (about 1.5 %) continues, exactly, on the blocks of attempt = 1, 2, ...:
      ``z0``'s rejections first, then ``z1``'s, in one sequence per (step, human).  Each such
      block is one test, with uniforms ``u = ((w >> 11) + 1) 2⁻⁵³`` in (0, 1] from its words:
      in a wedge (layer ``i >= 1``), accept ``x`` when ``(fi[i-1] - fi[i]) u(A) + fi[i] <
      exp(-x²/2)``, else a fresh first attempt from word ``B`` of that block; in the tail (layer
      0, ``|x|`` beyond ``r = 3.654``), Marsaglia's (1964) test ``xx = -log u(A)/r``,
      ``yy = -log u(B)``, accept ``±(r + xx)`` (the sign of the word that chose layer 0) when
      ``2 yy > xx²``, else the next block.

    So the draw of ``(seed, step, human)`` is a pure function of those three integers.

    :func:`fill_normal_pairs` fills the pairs of a range of humans: the compiled loop computes the
    Philox blocks of a chunk of :data:`CHUNK` humans in a branch-free loop that LLVM vectorises,
    then the ziggurat of each (7-8 ms per 10⁶ pairs on one core, about 2.9 times faster than numpy's
    ``default_rng().standard_normal``); its numpy twin is vectorised over all the humans, rejections
    included; ranges of :data:`~meanfield._compiled.core.PARALLEL_CHUNK` humans run on numba's
    threads.  :func:`standard_normals` is the same from a seed, arguments checked.  The crowd's
    step (:func:`meanfield.crowds._point_mass_loops.euler_maruyama`) calls :func:`fill_pairs_rows`,
    the chunked loop over one range of rows, for each of its chunks, and uses the draws at once;
    :func:`normal_pair` is one human's pair, for loops that draw one at a time.

The two paths give the same bits, on every machine.  The integer part (blocks, layers,
magnitudes, uniforms) is exact; the rare path's ``exp`` and ``log`` are computed here from
correctly rounded arithmetic only (``+ - * /``, ``floor``, ``frexp``, ``ldexp``: fdlibm's
``log``; ``exp`` by a reduction by ``ln 2`` and a Taylor polynomial; both within 1-2 ulp of the
correctly rounded values), the same operations in the same order on both paths, which numba
compiles without contracting them into FMAs (no fastmath).  With numpy's SIMD ``np.log``/``np.exp``
(not the C library's, which numba calls) the paths would differ by an ulp now and then, and
numpy's results depend on the machine's SIMD level.

Philox4x64-10, Box–Muller and streams
    The previous noise (Philox4x64-10, Box–Muller with arithmetic ``cos``/``sin``; 91 ms per 10⁶
    pairs) is gone, and with it its block function: nothing used it any more, and Philox4x32-10
    has its own reference (55 known-answer vectors).  The key now holds the whole 64-bit seed,
    so there is no ``stream`` argument: separate uses of one seed take separate seeds (or a
    separate range of steps).

References
----------
.. [1] J. K. Salmon, M. A. Moraes, R. O. Dror and D. E. Shaw, "Parallel random numbers: as easy
   as 1, 2, 3", Proc. SC'11 (Int. Conf. for High Performance Computing, Networking, Storage
   and Analysis), 2011, doi:10.1145/2063384.2063405.  (Random123: D. E. Shaw Research's
   implementation, whose constants and known-answer vectors these are.)
.. [2] G. Marsaglia and W. W. Tsang, "The ziggurat method for generating random variables",
   J. Stat. Softw. 5(8), 1-7, 2000, doi:10.18637/jss.v005.i08.
.. [3] G. Marsaglia, "Generating a variable from the tail of the normal distribution",
   Technometrics 6(1), 101-102, 1964.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import PARALLEL_CHUNK, compiled, empty_array, inner, prange

__all__ = [
    "philox4x32_block",
    "philox4x32_10",
    "normal_pair",
    "fill_normal_pairs",
    "fill_pairs_rows",
    "standard_normals",
    "noise_key",
    "PHILOX_M0",
    "PHILOX_M1",
    "PHILOX_W0",
    "PHILOX_W1",
    "CHUNK",
    "ZIG_R",
    "ZIG_KI",
    "ZIG_WI",
    "ZIG_FI",
]

_U32 = (1 << 32) - 1
_U64 = (1 << 64) - 1

PHILOX_M0 = 0xD2511F53
"""Philox4x32's first multiplier (Random123's ``PHILOX_M4x32_0``)."""
PHILOX_M1 = 0xCD9E8D57
"""Philox4x32's second multiplier (``PHILOX_M4x32_1``)."""
PHILOX_W0 = 0x9E3779B9
"""The Weyl increment of key word 0 between rounds (``PHILOX_W32_0``, the golden ratio's bits)."""
PHILOX_W1 = 0xBB67AE85
"""The Weyl increment of key word 1 (``PHILOX_W32_1``, sqrt(3) - 1's bits)."""
ROUNDS = 10
CHUNK = 256
"""Humans per chunk of :func:`fill_normal_pairs`' compiled loop (its Philox blocks first, vectorised; 128 to
4096 are as fast).  The numbers do not depend on it."""

# The constants as numba sees them: np.uint64 globals are frozen into the compiled code as uint64
# (a Python int would be an int64, and uint64 with int64 gives float64 in numba's typing).
_M0 = np.uint64(PHILOX_M0)
_M1 = np.uint64(PHILOX_M1)
_W0 = np.uint64(PHILOX_W0)
_W1 = np.uint64(PHILOX_W1)
_MASK32 = np.uint64(_U32)
_MASK52 = np.uint64((1 << 52) - 1)
_U255 = np.uint64(0xFF)
_ONE = np.uint64(1)
_ZERO = np.uint64(0)
_S8 = np.uint64(8)
_S9 = np.uint64(9)
_S11 = np.uint64(11)
_S32 = np.uint64(32)
_TWO_M53 = 2.0**-53


# ----------------------------------------------------------------------------- the block function
@inner
def philox4x32_block(c0, c1, c2, c3, k0, k1):
    """The Philox4x32-10 block of counter ``(c0, c1, c2, c3)`` under key ``(k0, k1)``: 32-bit values in uint64.

    For compiled loops (``numba.njit(cache=True)`` once a loop of the importing module compiles);
    from Python use :func:`philox4x32_10`.  Each round: ``p0 = M0 c0``, ``p1 = M1 c2`` (32×32→64-bit
    products, exact in uint64), then ``c = (hi(p1) ^ c1 ^ k0, lo(p1), hi(p0) ^ c3 ^ k1, lo(p0))``;
    the key gains ``(W0, W1)`` mod 2³² between rounds (Salmon et al. 2011, Random123's
    ``philox4x32_R(10, ...)``).

    Parameters
    ----------
    c0, c1, c2, c3 : np.uint64
        The counter, word 0 first, each in [0, 2³²).
    k0, k1 : np.uint64
        The key, each in [0, 2³²).

    Returns
    -------
    tuple of 4 np.uint64
        The block: four independent uniform 32-bit words.
    """
    x0, x1, x2, x3 = np.uint64(c0), np.uint64(c1), np.uint64(c2), np.uint64(c3)  # (uint64 throughout:
    ka, kb = np.uint64(k0), np.uint64(k1)  # an int64 among them would turn numba's arithmetic to float64)
    for r in range(ROUNDS):
        if r > 0:
            ka = (ka + _W0) & _MASK32
            kb = (kb + _W1) & _MASK32
        p0 = _M0 * x0  # < 2^64: exact
        p1 = _M1 * x2
        x0, x1, x2, x3 = (p1 >> _S32) ^ x1 ^ ka, p1 & _MASK32, (p0 >> _S32) ^ x3 ^ kb, p0 & _MASK32
    return x0, x1, x2, x3


def _blocks_numpy(c0, c1, c2, c3, k0, k1):
    """Philox4x32-10 over uint64 arrays of counter words (one block per element), keys as ints."""
    c0, c1, c2, c3 = (np.asarray(c, dtype=np.uint64) for c in (c0, c1, c2, c3))
    k0, k1 = int(k0), int(k1)
    for r in range(ROUNDS):
        ka = np.uint64((k0 + r * PHILOX_W0) & _U32)  # the key schedule in Python ints
        kb = np.uint64((k1 + r * PHILOX_W1) & _U32)
        p0 = _M0 * c0
        p1 = _M1 * c2
        c0, c1, c2, c3 = (p1 >> _S32) ^ c1 ^ ka, p1 & _MASK32, (p0 >> _S32) ^ c3 ^ kb, p0 & _MASK32
    return c0, c1, c2, c3


def _philox4x32_10_numpy(counters, key):
    out = np.empty((counters.shape[0], 4), dtype=np.uint64)
    r = _blocks_numpy(counters[:, 0], counters[:, 1], counters[:, 2], counters[:, 3], key[0], key[1])
    for i in range(4):
        out[:, i] = r[i]
    return out


@compiled(fallback=_philox4x32_10_numpy)
def philox4x32_10(counters: np.ndarray, key: np.ndarray) -> np.ndarray:
    """Philox4x32-10 blocks (Salmon et al. 2011), one per row of counters: a pure function of counter and key.

    Equal to Random123's ``philox4x32_R(10, ctr, key)`` (its known-answer vectors are in the tests).

    Parameters
    ----------
    counters : ndarray of uint64, shape (n, 4)
        One 128-bit counter per row, as four 32-bit words (word 0 first), each in [0, 2³²).
    key : ndarray of uint64, shape (2,)
        The 64-bit key as two 32-bit words, each in [0, 2³²).

    Returns
    -------
    ndarray of uint64, shape (n, 4)
        The blocks, 32-bit words.

    References
    ----------
    .. [1] J. K. Salmon, M. A. Moraes, R. O. Dror and D. E. Shaw, "Parallel random numbers: as easy
       as 1, 2, 3", Proc. SC'11, 2011, doi:10.1145/2063384.2063405.
    """
    n = counters.shape[0]
    out = np.empty((n, 4), dtype=np.uint64)
    k0, k1 = key[0], key[1]
    for i in range(n):
        r0, r1, r2, r3 = philox4x32_block(counters[i, 0], counters[i, 1], counters[i, 2], counters[i, 3], k0, k1)
        out[i, 0] = r0
        out[i, 1] = r1
        out[i, 2] = r2
        out[i, 3] = r3
    return out


# ----------------------------------------------------------------------------- the ziggurat's tables
def _ziggurat_tables(n: int = 256, r: float = 3.6541528853610088, v: float = 0.00492867323399):
    """Marsaglia and Tsang's tables in numpy's 64-bit layout: ``ki`` (uint64, 52-bit scale), ``wi``, ``fi``.

    Layer ``i >= 1`` is the rectangle of width ``x_i`` between heights ``f(x_i)`` and ``f(x_{i-1})``
    (``x_255 = r``); layer 0 is the base strip of area ``v`` (the rectangle of width ``v/f(r)``, tail
    included).  ``f(x) = exp(-x²/2)``.  Computed once, at import, by the C library (both paths read
    the same tables).
    """
    m1 = 2.0**52
    ki = np.zeros(n, dtype=np.uint64)
    wi = np.zeros(n)
    fi = np.zeros(n)
    dn = tn = r
    q = v / math.exp(-0.5 * dn * dn)
    ki[0] = np.uint64(int((dn / q) * m1))
    wi[0] = q / m1
    wi[n - 1] = dn / m1
    fi[0] = 1.0
    fi[n - 1] = math.exp(-0.5 * dn * dn)
    for i in range(n - 2, 0, -1):
        dn = math.sqrt(-2.0 * math.log(v / dn + math.exp(-0.5 * dn * dn)))
        ki[i + 1] = np.uint64(int((dn / tn) * m1))
        tn = dn
        fi[i] = math.exp(-0.5 * dn * dn)
        wi[i] = dn / m1
    return ki, wi, fi


ZIG_R = 3.6541528853610088
"""The start of the ziggurat's tail (the right edge of its top layer, ``x_255``)."""
_INV_R = 1.0 / ZIG_R
ZIG_KI, ZIG_WI, ZIG_FI = _ziggurat_tables()
"""The ziggurat's tables: ``ki`` the acceptance bounds of the 52-bit magnitude per layer, ``wi`` the magnitude's
scale, ``fi = exp(-x_i²/2)``; the arguments ``ki, wi, fi`` of :func:`normal_pair`.  Not to be modified (they are
left writeable: numba's loop is slower on read-only arrays)."""


# ----------------------------------------------------------------------------- log and exp, arithmetic only
# The rare path's log and exp from +, -, *, /, floor, frexp and ldexp alone: IEEE-754 rounds these
# exactly the same way in numpy and in numba (which contracts nothing into FMAs without fastmath),
# so the two paths give the same bits, on every machine, whatever its math library (numpy's SIMD
# np.log differed from the C library's log by 1 ulp on 0.3 % of arguments on an AVX-512 machine).
_SQRT_HALF = math.sqrt(0.5)
_LN2_HI = float.fromhex("0x1.62e42fee00000p-1")
"""``ln 2`` to 32 bits (its last 21 bits zero): ``e ln2_hi`` is exact for ``|e| < 2²¹`` (fdlibm's split)."""
_LN2_LO = 1.9082149292705877e-10
"""``ln 2 - ln2_hi`` to double precision (``ln2_hi + ln2_lo`` is ln 2 within 2e-26)."""
_INV_LN2 = 1.0 / math.log(2.0)
_ATANH_TERMS = tuple(2.0 / (2 * k + 1) for k in range(11, 0, -1))
"""``log(1 + f) = 2 atanh(s) = 2s + s R``, ``s = f/(2 + f)``, ``R = Σ 2 s²ᵏ/(2k + 1)`` for k = 1..11, highest
term first (``|s| <= 0.1716`` for ``1 + f`` in [√½, √2]: the first term left out is below 2⁻⁶⁰ of ``log``)."""
_EXP_TERMS = tuple(1.0 / math.factorial(k) for k in range(15, -1, -1))
"""``exp t = Σ tᵏ/k!``, k <= 15, highest first (``|t| <= ln2/2``: the rest is below 2e-20 of ``exp t``)."""


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


@inner
def _exp_neg(y):
    """``exp y`` for ``y`` in [-700, 0] (here ``-x²/2`` in a wedge, >= -6.7): ``y = k ln 2 + t``, ``k`` the
    nearest integer, ``t = (y - k ln2_hi) - k ln2_lo``, ``|t| <= ln2/2``; the Taylor polynomial of ``exp t``,
    times ``2ᵏ`` (exact); within 2 ulp of the correctly rounded exponential."""
    k = math.floor(y * _INV_LN2 + 0.5)
    t = (y - k * _LN2_HI) - k * _LN2_LO
    p = 0.0
    for c in _EXP_TERMS:
        p = p * t + c
    return math.ldexp(p, k)  # (k: math.floor's integer)


def _exp_neg_numpy(y):
    k = np.floor(y * _INV_LN2 + 0.5)
    t = (y - k * _LN2_HI) - k * _LN2_LO
    p = np.zeros_like(y)
    for c in _EXP_TERMS:
        p = p * t + c
    return np.ldexp(p, k.astype(np.int32))


# ----------------------------------------------------------------------------- the ziggurat
@inner
def _block_words(key0, key1, step, human, attempt):
    """The block of counter ``(human, step & 0xffffffff, attempt, step >> 32)`` as two 64-bit words ``(A, B)``."""
    st = np.uint64(step)
    x0, x1, x2, x3 = philox4x32_block(np.uint64(human), st & _MASK32, np.uint64(attempt), st >> _S32, key0, key1)
    return (x0 << _S32) | x1, (x2 << _S32) | x3


@inner
def _unit(w):
    """``((w >> 11) + 1) 2⁻⁵³``: a double in (0, 1] from a word's 53 high bits (exact)."""
    return (np.float64(np.int64(w >> _S11)) + 1.0) * _TWO_M53


@inner
def _first_attempt(w, ki, wi):
    """A ziggurat attempt from one 64-bit word: ``(x, accepted, layer)``."""
    idx = np.intp(w & _U255)
    m = (w >> _S9) & _MASK52  # < 2^52: converted through int64 (a signed conversion: fast without AVX-512)
    x = np.float64(np.int64(m)) * wi[idx]
    # the sign by a multiplication by +-1.0 (exact) rather than a branch mispredicted half the time
    x = x * (1.0 - 2.0 * np.float64(np.int64((w >> _S8) & _ONE)))
    return x, m < ki[idx], idx


@inner
def _rejected(w, idx, x, key0, key1, step, human, attempt, ki, wi, fi):
    """A draw whose first attempt (word ``w``, layer ``idx``, value ``x``) was rejected: the wedge and
    tail tests on the blocks ``attempt, attempt + 1, ...``.  Returns ``(x, the next unused attempt)``."""
    while True:
        if idx == 0:  # the tail beyond r (Marsaglia 1964); the sign of the word that chose layer 0
            neg = (w >> _S8) & _ONE
            while True:
                wa, wb = _block_words(key0, key1, step, human, attempt)
                attempt += 1
                xx = -_INV_R * _log_unit(_unit(wa))
                yy = -_log_unit(_unit(wb))
                if yy + yy > xx * xx:
                    if neg:
                        return -(ZIG_R + xx), attempt
                    return ZIG_R + xx, attempt
        wa, wb = _block_words(key0, key1, step, human, attempt)
        attempt += 1
        if (fi[idx - 1] - fi[idx]) * _unit(wa) + fi[idx] < _exp_neg(-0.5 * x * x):
            return x, attempt
        w = wb  # rejected in the wedge: a fresh attempt (layer, sign, magnitude) from word B
        x, ok, idx = _first_attempt(w, ki, wi)
        if ok:
            return x, attempt


@inner
def _pair_from_words(wa, wb, key0, key1, step, human, ki, wi, fi):
    """The pair from the attempt-0 words ``(A, B)``, rejections continued on attempts 1, 2, ..."""
    z0, ok0, i0 = _first_attempt(wa, ki, wi)
    z1, ok1, i1 = _first_attempt(wb, ki, wi)
    attempt = np.int64(1)  # (not the literal 1: one compiled _rejected for both calls below, not two)
    if not ok0:
        z0, attempt = _rejected(wa, i0, z0, key0, key1, step, human, attempt, ki, wi, fi)
    if not ok1:
        z1, attempt = _rejected(wb, i1, z1, key0, key1, step, human, attempt, ki, wi, fi)
    return z0, z1


@inner
def normal_pair(key0, key1, step, human, ki, wi, fi):
    """One human's two N(0, 1) draws at one step: the ziggurat on the Philox4x32-10 blocks of ``(step, human)``.

    A pure function of its arguments (no state, no allocation): call it from any compiled loop,
    ``prange`` included, in any order; it gives :func:`fill_normal_pairs`' numbers, slower per pair
    than its chunked loop (one block at a time: no SIMD across humans).  The mapping (key, counter,
    words, attempts) is in the module's doc.

    Parameters
    ----------
    key0, key1 : np.uint64
        The key (:func:`noise_key`: the seed's low and high 32 bits).
    step : np.uint64 or int
        The time step, in [0, 2⁶⁴) (counter words 1 and 3).
    human : int
        The human's index, in [0, 2³²) (counter word 0).
    ki, wi, fi : ndarray
        The ziggurat's tables :data:`ZIG_KI`, :data:`ZIG_WI`, :data:`ZIG_FI`.

    Returns
    -------
    (float, float)
        ``(z0, z1)``, independent N(0, 1).

    References
    ----------
    .. [1] J. K. Salmon et al., "Parallel random numbers: as easy as 1, 2, 3", SC'11, 2011.
    .. [2] G. Marsaglia and W. W. Tsang, "The ziggurat method for generating random variables",
       J. Stat. Softw. 5(8), 2000.
    """
    wa, wb = _block_words(key0, key1, step, human, 0)
    return _pair_from_words(wa, wb, key0, key1, step, human, ki, wi, fi)


# ----------------------------------------------------------------------------- the numpy twin
def _words_numpy(key0, key1, step, humans, attempts):
    st = int(step)
    n = humans.size
    x0, x1, x2, x3 = _blocks_numpy(
        humans, np.full(n, st & _U32, np.uint64), attempts, np.full(n, st >> 32, np.uint64), key0, key1
    )
    return (x0 << _S32) | x1, (x2 << _S32) | x3


def _unit_numpy(w):
    return ((w >> _S11).astype(np.int64).astype(np.float64) + 1.0) * _TWO_M53


def _first_attempt_numpy(w, ki, wi):
    idx = (w & _U255).astype(np.intp)
    m = (w >> _S9) & _MASK52
    x = m.astype(np.int64).astype(np.float64) * wi[idx]
    x = x * (1.0 - 2.0 * ((w >> _S8) & _ONE).astype(np.int64).astype(np.float64))
    return x, m < ki[idx], idx


def _rejected_numpy(w, idx, x, key0, key1, step, humans, attempt, ki, wi, fi):
    """:func:`_rejected` over arrays of rejected draws, one test per draw per pass (the same blocks in the
    same order as the scalar loop: each draw is a small state machine, tail or wedge)."""
    w, idx, x, attempt = w.copy(), idx.copy(), x.copy(), attempt.copy()
    todo = np.arange(w.size)
    while todo.size:
        wa, wb = _words_numpy(key0, key1, step, humans[todo], attempt[todo])
        attempt[todo] += np.uint64(1)
        i, xt, wt = idx[todo], x[todo], w[todo]
        tail = i == 0
        ua, ub = _unit_numpy(wa), _unit_numpy(wb)
        xx = -_INV_R * _log_unit_numpy(ua)
        yy = -_log_unit_numpy(ub)
        tail_ok = tail & (yy + yy > xx * xx)
        neg = ((wt >> _S8) & _ONE) == _ONE
        x[todo[tail_ok]] = np.where(neg, -(ZIG_R + xx), ZIG_R + xx)[tail_ok]
        wedge_ok = ~tail & ((fi[i - 1] - fi[i]) * ua + fi[i] < _exp_neg_numpy(-0.5 * xt * xt))
        again = ~tail & ~wedge_ok  # a fresh first attempt from word B
        fresh = todo[again]
        w[fresh] = wb[again]
        x[fresh], ok, idx[fresh] = _first_attempt_numpy(wb[again], ki, wi)
        done = tail_ok | wedge_ok
        done[again] = ok
        todo = todo[~done]
    return x, attempt


def _fill_normal_pairs_numpy(key0, key1, step, first, out, ki, wi, fi):
    n = out.shape[0]
    humans = np.uint64(first) + np.arange(n, dtype=np.uint64)
    wa, wb = _words_numpy(key0, key1, step, humans, np.zeros(n, np.uint64))
    z0, ok0, i0 = _first_attempt_numpy(wa, ki, wi)
    z1, ok1, i1 = _first_attempt_numpy(wb, ki, wi)
    attempt = np.ones(n, np.uint64)
    bad = np.flatnonzero(~ok0)
    z0[bad], attempt[bad] = _rejected_numpy(
        wa[bad], i0[bad], z0[bad], key0, key1, step, humans[bad], attempt[bad], ki, wi, fi
    )
    bad = np.flatnonzero(~ok1)  # (z1's rejections continue after z0's attempts)
    z1[bad], _ = _rejected_numpy(wb[bad], i1[bad], z1[bad], key0, key1, step, humans[bad], attempt[bad], ki, wi, fi)
    out[:, 0] = z0
    out[:, 1] = z1
    return out


# ----------------------------------------------------------------------------- the compiled loops
@inner
def fill_pairs_rows(key0, key1, step, first, out, lo, hi, ki, wi, fi):
    """``out[r] = normal_pair(key0, key1, step, first + r, ki, wi, fi)`` for the rows ``lo <= r < hi``.

    The loop of :func:`fill_normal_pairs` over one range of rows, for compiled loops that draw the
    noise of a range of humans and use it at once (the crowd's step,
    :func:`meanfield.crowds._point_mass_loops.euler_maruyama`): chunks of :data:`CHUNK`
    humans, their Philox4x32-10 blocks of attempt 0 first, in a branch-free loop that LLVM
    vectorises across the humans (the rounds of :func:`philox4x32_block`, written out), then
    each human's ziggurat: the first attempts written out too, a human with a rejected draw
    (3 %) redone by the helpers of :func:`normal_pair` (numba calls them without inlining).
    Allocates its two work rows of :data:`CHUNK` words; shares nothing, so that ranges can be
    drawn on different threads.
    """
    k0, k1 = np.uint64(key0), np.uint64(key1)
    st = np.uint64(step)
    s_lo, s_hi = st & _MASK32, st >> _S32
    words_a = empty_array(CHUNK, np.uint64)
    words_b = empty_array(CHUNK, np.uint64)
    for r0 in range(lo, hi, CHUNK):
        m = hi - r0 if hi - r0 < CHUNK else CHUNK
        for j in range(m):  # branch-free: vectorised across the humans
            x0, x1, x2, x3 = np.uint64(first + r0 + j), s_lo, _ZERO, s_hi
            ka, kb = k0, k1
            for _ in range(ROUNDS):
                p0 = _M0 * x0
                p1 = _M1 * x2
                x0, x1, x2, x3 = (p1 >> _S32) ^ x1 ^ ka, p1 & _MASK32, (p0 >> _S32) ^ x3 ^ kb, p0 & _MASK32
                ka = (ka + _W0) & _MASK32
                kb = (kb + _W1) & _MASK32
            words_a[j] = (x0 << _S32) | x1
            words_b[j] = (x2 << _S32) | x3
        for j in range(m):  # the first attempts written out (numba does not inline the helpers' calls)
            wa, wb = words_a[j], words_b[j]
            i0, i1 = np.intp(wa & _U255), np.intp(wb & _U255)
            m0, m1 = (wa >> _S9) & _MASK52, (wb >> _S9) & _MASK52
            z0 = np.float64(np.int64(m0)) * wi[i0] * (1.0 - 2.0 * np.float64(np.int64((wa >> _S8) & _ONE)))
            z1 = np.float64(np.int64(m1)) * wi[i1] * (1.0 - 2.0 * np.float64(np.int64((wb >> _S8) & _ONE)))
            if not (m0 < ki[i0] and m1 < ki[i1]):  # a rejection (3 % of the humans)
                z0, z1 = _pair_from_words(wa, wb, k0, k1, st, first + r0 + j, ki, wi, fi)
            out[r0 + j, 0] = z0
            out[r0 + j, 1] = z1


@compiled(fallback=_fill_normal_pairs_numpy, parallel_over="out")
def fill_normal_pairs(
    key0: np.uint64,
    key1: np.uint64,
    step: np.uint64,
    first: int,
    out: np.ndarray,
    ki: np.ndarray,
    wi: np.ndarray,
    fi: np.ndarray,
) -> np.ndarray:
    """``out[i] = normal_pair(key0, key1, step, first + i, ki, wi, fi)``: humans ``first .. first + n - 1``.

    :func:`fill_pairs_rows` on ranges of :data:`~meanfield._compiled.core.PARALLEL_CHUNK` rows, on
    numba's threads (:func:`~meanfield._compiled.core.prange`).  Each row depends only on
    ``(key, step, first + i)``: any split of the humans into calls, chunks or threads gives the same
    numbers.  The numpy twin draws all the rows at once (vectorised over the humans, rejections included).

    Parameters
    ----------
    key0, key1 : np.uint64
        The key (:func:`noise_key`).
    step : np.uint64
        The time step, in [0, 2⁶⁴).
    first : int
        The index of the human in row 0; ``first + n <= 2³²``.
    out : ndarray of float64, shape (n, 2)
        Filled with the pairs.
    ki, wi, fi : ndarray
        The ziggurat's tables :data:`ZIG_KI`, :data:`ZIG_WI`, :data:`ZIG_FI`.

    Returns
    -------
    ndarray
        ``out``.
    """
    n = out.shape[0]
    for c in prange((n + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):
        lo = c * PARALLEL_CHUNK
        hi = n if n < lo + PARALLEL_CHUNK else lo + PARALLEL_CHUNK
        fill_pairs_rows(key0, key1, step, first, out, lo, hi, ki, wi, fi)
    return out


def noise_key(seed: int) -> tuple[np.uint64, np.uint64]:
    """The Philox4x32 key of a seed's noise: ``(seed & 0xffffffff, seed >> 32)``.

    Parameters
    ----------
    seed : int
        In [0, 2⁶⁴).

    Returns
    -------
    (np.uint64, np.uint64)
        The key's two 32-bit words.

    Raises
    ------
    ValueError
        When ``seed`` is not an integer in [0, 2⁶⁴).
    """
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= int(seed) <= _U64:
        raise ValueError(f"seed must be an integer in [0, 2**64), got {seed!r}")
    return np.uint64(int(seed) & _U32), np.uint64(int(seed) >> 32)


def standard_normals(seed: int, step: int, out: np.ndarray, first: int = 0) -> np.ndarray:
    """The crowd's N(0, 1) noise of one step from a seed: row ``i`` of ``out`` is human ``first + i``'s pair.

    :func:`fill_normal_pairs` with the key :func:`noise_key` ``(seed)`` and the ziggurat's tables,
    arguments checked.  The draw for ``(seed, step, human)`` is a pure function of those integers
    (Philox4x32-10 counter ``(human, step & 0xffffffff, attempt, step >> 32)``, the ziggurat; see
    the module's doc), whatever the order, chunking or threads that compute it.

    Parameters
    ----------
    seed : int
        In [0, 2⁶⁴).
    step : int
        The time step, in [0, 2⁶⁴).
    out : ndarray of float64, shape (n, 2)
        Filled with the pairs.
    first : int, default 0
        The human of row 0; ``first + n <= 2³²``.

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
    .. [2] G. Marsaglia and W. W. Tsang, "The ziggurat method for generating random variables",
       J. Stat. Softw. 5(8), 2000.
    """
    key0, key1 = noise_key(seed)
    if not (isinstance(out, np.ndarray) and out.dtype == np.float64 and out.ndim == 2 and out.shape[1] == 2):
        raise ValueError("out must be a float64 array of shape (n, 2)")
    if isinstance(step, bool) or not isinstance(step, int | np.integer) or not 0 <= int(step) <= _U64:
        raise ValueError(f"step must be an integer in [0, 2**64), got {step!r}")
    if isinstance(first, bool) or not isinstance(first, int | np.integer) or not 0 <= int(first) <= _U32:
        raise ValueError(f"first must be an integer in [0, 2**32), got {first!r}")
    if int(first) + out.shape[0] > 1 << 32:
        raise ValueError(f"first + n must be <= 2**32, got {int(first) + out.shape[0]}")
    return fill_normal_pairs(key0, key1, np.uint64(int(step)), int(first), out, ZIG_KI, ZIG_WI, ZIG_FI)
