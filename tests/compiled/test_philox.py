"""Philox4x64-10 and the crowd's counter-based normals (meanfield._compiled.philox).

* the block function is numpy's ``np.random.Philox`` (whose ``random_raw`` increments the counter
  before each block) and Random123's known-answer vectors, on both paths;
* the compiled loops and their numpy twins give the same bits (normals included: the log and
  sin/cos are built from correctly rounded arithmetic only);
* the normals are N(0, 1) (mean, variance, Kolmogorov–Smirnov on 10⁶ draws with a fixed seed),
  uncorrelated between neighbouring humans, steps, seeds and components;
* a human's draw does not depend on which call, chunk, order or thread count computes it.
"""

from __future__ import annotations

import contextlib
import math
import warnings

import numpy as np
import pytest

from meanfield._compiled import core as compiled
from meanfield._compiled.core import compile_inner
from meanfield._compiled.philox import (
    _cos_sin_turn,
    _cos_sin_turn_numpy,
    _log_unit,
    _log_unit_numpy,
    fill_normal_pairs,
    noise_key,
    normal_pair,
    philox4x64_10,
    philox_block,
    standard_normals,
)

needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")
needs_compiled = pytest.mark.skipif(
    not compiled.enabled(), reason="the compiled path is off (numba missing, or MEANFIELD_COMPILED=0)"
)

U64 = 2**64 - 1
U256 = 2**256


def words(value: int) -> list[int]:
    """A 256-bit counter as its four little-endian 64-bit words (numpy's Philox order)."""
    return [(value >> (64 * i)) & U64 for i in range(4)]


def counters(values) -> np.ndarray:
    return np.array([words(v % U256) for v in values], dtype=np.uint64)


def key_words(key: int) -> np.ndarray:
    return np.array([key & U64, key >> 64], dtype=np.uint64)


def both_paths(loop, *args):
    """The loop's result on the compiled path (checked to have run compiled) and on the numpy path."""
    fresh = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
    fast = loop(*fresh)
    assert loop._ready, f"{loop.name} did not run compiled"
    with compiled.numpy_path():
        ref = loop(*[a.copy() if isinstance(a, np.ndarray) else a for a in args])
    return fast, ref


def numpy_philox_blocks(counter: int, key: int, n: int) -> np.ndarray:
    """Blocks ``counter, counter + 1, ...`` from numpy: its random_raw increments the counter *before*
    each block, so the generator starts at ``counter - 1``."""
    gen = np.random.Philox(counter=(counter - 1) % U256, key=key)
    return gen.random_raw(4 * n).reshape(n, 4)


# ----------------------------------------------------------------------------- the block function
KEYS = [0, 1, 0x452821E638D01377 | (0xBE5466CF34E90C6C << 64), 2**128 - 1, 2**64, 12345]
COUNTERS = [
    0,  # numpy's generator then starts at 2**256 - 1: the decrement borrows through every word
    1,
    2**64 - 1,  # word 0 = 2**64 - 1: the next block carries into word 1
    2**64,  # word 0 = 0: numpy's counter - 1 borrows from word 1
    (5 << 64) | U64,
    (U64 << 64) | U64,  # carries into word 2
    2**192 - 1,  # carries into word 3
    U256 - 1,  # the last counter: the next block wraps to 0
    0x082EFA98EC4E6C89A4093822299F31D013198A2E03707344243F6A8885A308D3,
]


@pytest.mark.parametrize("key", KEYS)
def test_the_block_function_is_numpys_philox(key):
    """numpy's ``Philox(counter=c - 1, key=k).random_raw`` gives the blocks of counters c, c + 1, ...:
    four consecutive blocks from each start, so that every carry between words is crossed."""
    for start in COUNTERS:
        expected = numpy_philox_blocks(start, key, 4)
        ctr = counters([start + i for i in range(4)])
        fast = philox4x64_10(ctr, key_words(key))
        with compiled.numpy_path():
            ref = philox4x64_10(ctr, key_words(key))
        assert fast.dtype == np.uint64 and fast.shape == (4, 4)
        assert np.array_equal(fast, expected), (hex(start), hex(key))
        assert np.array_equal(ref, expected), (hex(start), hex(key))


def test_numpy_increments_its_counter_before_the_first_block():
    """The convention the tests rely on, stated by itself: a fresh ``Philox(counter=c)`` returns the
    block of ``c + 1`` first and then holds the counter ``c + 1`` (numpy's ``philox_next``)."""
    key, c = 7, (3 << 64) | U64
    gen = np.random.Philox(counter=c, key=key)
    first = gen.random_raw(4)
    with compiled.numpy_path():
        assert np.array_equal(first, philox4x64_10(counters([c + 1]), key_words(key))[0])
        assert not np.array_equal(first, philox4x64_10(counters([c]), key_words(key))[0])
    assert gen.state["state"]["counter"].tolist() == words(c + 1)
    # the array forms of counter and key are the same little-endian words
    same = np.random.Philox(counter=np.array(words(c), np.uint64), key=key_words(key)).random_raw(4)
    assert np.array_equal(first, same)


def test_the_block_function_is_numpys_on_random_counters_and_keys():
    rng = np.random.default_rng(11)
    for _ in range(20):
        key = int.from_bytes(rng.bytes(16), "little")
        start = int.from_bytes(rng.bytes(32), "little")
        ctr = counters([start + i for i in range(3)])
        expected = numpy_philox_blocks(start, key, 3)
        assert np.array_equal(philox4x64_10(ctr, key_words(key)), expected)  # compiled, where numba is
        with compiled.numpy_path():
            assert np.array_equal(philox4x64_10(ctr, key_words(key)), expected)


# Random123's known-answer vectors for philox4x64_10, in its kat_vectors format:
# name rounds ctr[0..3] key[0..1] expected[0..3] (hexadecimal words, element 0 first).
# The first three are Random123's own philox4x64_10 vectors (zeros; all ones; digits of pi), as
# quoted by several independent implementations' tests (one C++ test calls them "known-answer tests
# from the original Random123 distribution"; the original kat_vectors file was not at hand).  The
# others are from the extended examples/kat_vectors ("generated by gentests.py") of the Random123
# copy girving/random123-manual (commit 61e8479252c4).
KAT = """
philox4x64 10 0000000000000000 0000000000000000 0000000000000000 0000000000000000   0000000000000000 0000000000000000   16554d9eca36314c db20fe9d672d0fdc d7e772cee186176b 7e68b68aec7ba23b
philox4x64 10 ffffffffffffffff ffffffffffffffff ffffffffffffffff ffffffffffffffff   ffffffffffffffff ffffffffffffffff   87b092c3013fe90b 438c3c67be8d0224 9cc7d7c69cd777b6 a09caebf594f0ba0
philox4x64 10 243f6a8885a308d3 13198a2e03707344 a4093822299f31d0 082efa98ec4e6c89   452821e638d01377 be5466cf34e90c6c   a528f45403e61d95 38c72dbd566e9788 a5a1610e72fd18b5 57bd43b5e52b7fe6
philox4x64 10 0000000000000001 0000000000000000 0000000000000000 0000000000000000   0000000000000001 0000000000000000   4db6a27b756282df d944fa03babe0e2f 27f872e577060d32 07f697696a0482a2
philox4x64 10 0000000000000000 ffffffffffffffff 0000000000000000 0000000000000000   0000000000000001 0000000000000000   82a98ead15250c68 dca14805e19e01bc 7bc58279fe853ad2 4366ca54a9015751
philox4x64 10 243f6a8885a308d3 13198a2e03707344 a4093822299f31d0 082efa98ec4e6c89   0000000000000001 0000000000000000   c306b6f69047b4d3 50a141b88a52f51f c1255f575c5efa40 e9ec1af0c5fd12e7
philox4x64 10 0000000000000000 0000000000000000 0000000000000000 0000000000000001   0000000000000000 0000000000000001   c403b0ed4f4a56bc 4c10205602338da5 44026cf45fd8c7b3 c85ab2577611200a
philox4x64 10 0000000000000000 0000000000000000 ffffffffffffffff 0000000000000000   0000000000000000 ffffffffffffffff   9dd4b8f423be915e 43cd5fa1ab84838c 9bdd5bc7b21d5372 ae35cb6a3d94c1fe
philox4x64 10 0000000000000000 0000000000000000 0000000000000000 8000000000000000   0000000000000000 8000000000000000   4e5204874c73745c b416cb6ef85bba05 87819def7e3f93a0 cc38b1dbe3d9d6e9
philox4x64 10 243f6a8885a308d3 13198a2e03707344 a4093822299f31d0 082efa98ec4e6c89   0000000000000000 8000000000000000   79b0012fa80e5ad7 15b81f9bf706cc38 6586b6802ea9ba1c 1bba4ac847739bca
"""  # noqa: E501 (the vectors' own format, one per line)


def _kat():
    rows = [line.split() for line in KAT.strip().splitlines()]
    assert all(r[0] == "philox4x64" and r[1] == "10" and len(r) == 12 for r in rows)
    return [([int(w, 16) for w in r[2:6]], [int(w, 16) for w in r[6:8]], [int(w, 16) for w in r[8:12]]) for r in rows]


@pytest.mark.parametrize(("ctr", "key", "expected"), _kat())
def test_random123_known_answer_vectors(ctr, key, expected):
    c, k = np.array([ctr], dtype=np.uint64), np.array(key, dtype=np.uint64)
    with compiled.numpy_path():
        assert philox4x64_10(c, k)[0].tolist() == expected
    if compiled.enabled():
        assert philox4x64_10(c, k)[0].tolist() == expected and philox4x64_10._ready
        block = compile_inner(philox_block)
        assert [int(w) for w in block(*(np.uint64(v) for v in ctr + key))] == expected
    # and numpy agrees with the vector (its counter one below)
    gen = np.random.Philox(counter=(sum(w << (64 * i) for i, w in enumerate(ctr)) - 1) % U256, key=k)
    assert gen.random_raw(4).tolist() == expected


@needs_compiled
def test_the_block_loop_matches_its_numpy_twin_bit_for_bit():
    rng = np.random.default_rng(3)
    ctr = rng.integers(0, 2**64, (5000, 4), dtype=np.uint64, endpoint=False)
    ctr[:10] = U64
    ctr[10:20] = 0
    key = rng.integers(0, 2**64, 2, dtype=np.uint64)
    fast, ref = both_paths(philox4x64_10, ctr, key)
    assert np.array_equal(fast, ref)


def test_the_numpy_twin_warns_of_no_overflow():
    """The wrapping uint64 arithmetic is intended: no RuntimeWarning (the key schedule is in Python ints)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with compiled.numpy_path():
            philox4x64_10(counters([U256 - 1, 0]), key_words(2**128 - 1))
            standard_normals(U64, 2**63 - 1, np.empty((3, 2)), first=2**63 - 3, stream=U64)


# ----------------------------------------------------------------------------- log and sin/cos
def _unit_uniforms(n: int, seed: int) -> np.ndarray:
    """Doubles ``(k + 1) 2⁻⁵³`` as the normals use, with the ends of (0, 1] and the binade edges."""
    k = np.random.default_rng(seed).integers(0, 2**53, n, dtype=np.uint64)
    u = (k.astype(np.float64) + 1.0) * 2.0**-53
    edges = [2.0**-53, 2.0**-52, 0.5, 0.25, 0.125, 0.75, 1.0, math.sqrt(0.5), 1 - 2.0**-53, 0.5 + 2.0**-53]
    return np.concatenate([u, edges, 1.0 - np.arange(1, 200) * 2.0**-53, np.arange(1, 200) * 2.0**-53])


def test_the_logarithm_is_within_one_ulp_of_the_c_library():
    u = _unit_uniforms(100_000, 1)
    own = _log_unit_numpy(u)
    ref = np.array([math.log(v) for v in u])
    assert np.all(np.abs(own - ref) <= np.spacing(np.abs(ref)))  # 1 ulp (measured: 1)
    assert own[u == 1.0][0] == 0.0 and np.isfinite(own).all()
    assert own[u == 2.0**-53][0] == pytest.approx(-53 * math.log(2), rel=1e-16)


def test_cos_and_sin_of_a_turn_are_accurate_and_exact_at_quarter_turns():
    u = _unit_uniforms(100_000, 2)
    c, s = _cos_sin_turn_numpy(u)
    # libm's cos(2πu) rounds its argument 2πu first (up to ~6e-16 off); ours reduces u exactly
    assert np.max(np.abs(c - np.cos(2 * np.pi * u))) <= 1e-15 and np.max(np.abs(s - np.sin(2 * np.pi * u))) <= 1e-15
    assert np.max(np.abs(c * c + s * s - 1.0)) <= 4.5e-16
    quarters = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    cq, sq = _cos_sin_turn_numpy(quarters)
    assert cq.tolist() == [1.0, 0.0, -1.0, 0.0, 1.0] and sq.tolist() == [0.0, 1.0, 0.0, -1.0, 0.0]


@needs_numba
def test_the_compiled_log_and_cos_sin_are_the_numpy_twins_bit_for_bit():
    u = _unit_uniforms(20_000, 3)
    log, turn = compile_inner(_log_unit), compile_inner(_cos_sin_turn)
    assert np.array_equal(np.array([log(v) for v in u]), _log_unit_numpy(u))
    c, s = _cos_sin_turn_numpy(u)
    fast = np.array([turn(v) for v in u])
    assert np.array_equal(fast[:, 0], c) and np.array_equal(fast[:, 1], s)


# ----------------------------------------------------------------------------- the normals
SEED, STEP = 20240611, 17


def _draws(seed: int, step: int, n: int, first: int = 0) -> np.ndarray:
    return standard_normals(seed, step, np.empty((n, 2)), first)


@needs_compiled
def test_the_normals_of_both_paths_are_the_same_bits():
    for seed, step, first, n in ((SEED, STEP, 0, 100_000), (0, 0, 0, 1000), (U64, 2**62, 2**62, 1000)):
        out = np.empty((n, 2))
        fast, ref = both_paths(fill_normal_pairs, *noise_key(seed), step, first, out)
        assert np.array_equal(fast, ref), (seed, step, first)


def test_the_normals_are_box_muller_on_numpys_philox():
    """End to end against numpy: the uniforms from ``Philox(key=(seed, 0), counter=(step, j, 0, 0) - 1)``'s
    first two words, through the C library's Box–Muller, are our normals to round-off."""
    seed, step, n = 99, 5, 300
    z = _draws(seed, step, n)
    for j in range(n):
        w = np.random.Philox(key=seed, counter=(step + (j << 64) - 1) % U256).random_raw(2)
        u0, u1 = ((int(w[0]) >> 11) + 1) * 2.0**-53, ((int(w[1]) >> 11) + 1) * 2.0**-53
        r = math.sqrt(-2.0 * math.log(u0))
        expected = (r * math.cos(2 * math.pi * u1), r * math.sin(2 * math.pi * u1))
        assert np.allclose(z[j], expected, rtol=0, atol=1e-14 * max(1.0, r))


def test_a_million_draws_are_standard_normal():
    """10⁶ draws (5·10⁵ humans × 2), fixed seed: mean and variance within 5 standard errors, and
    Kolmogorov–Smirnov against N(0, 1) (p = 0.097 for this seed and step, on both paths: the same bits)."""
    from scipy import stats

    z = _draws(SEED, STEP, 500_000).ravel()
    n = z.size
    assert abs(z.mean()) < 5 / math.sqrt(n)
    assert abs(z.var() - 1.0) < 5 * math.sqrt(2 / n)
    p = stats.kstest(z, "norm").pvalue
    assert p > 1e-3, p
    assert np.abs(z).max() <= math.sqrt(-2 * math.log(2.0**-53))  # the largest |z| Box–Muller can give here


def test_draws_are_uncorrelated_between_neighbours():
    """Neighbouring humans, steps, seeds and the two components of a pair: |r| < 5/sqrt(n)."""
    n = 200_000
    z = _draws(SEED, STEP, n + 1)
    bound = 5 / math.sqrt(n)

    def r(a, b):
        return abs(np.corrcoef(a, b)[0, 1])

    assert r(z[:-1, 0], z[1:, 0]) < bound and r(z[:-1, 1], z[1:, 1]) < bound  # humans j, j + 1
    assert r(z[:, 0], z[:, 1]) < bound  # the pair's two components
    nxt = _draws(SEED, STEP + 1, n + 1)
    assert r(z[:, 0], nxt[:, 0]) < bound and r(z[:, 1], nxt[:, 1]) < bound  # steps s, s + 1
    other = _draws(SEED + 1, STEP, n + 1)
    assert r(z[:, 0], other[:, 0]) < bound and r(z[:, 1], other[:, 1]) < bound  # seeds
    assert r(z[:, 0] ** 2, z[:, 1] ** 2) < bound  # independent, not only uncorrelated: the squares too
    assert r(z[:-1, 0] ** 2, z[1:, 0] ** 2) < bound


@pytest.mark.parametrize("path", ["compiled", "numpy"])
def test_a_humans_draw_does_not_depend_on_the_chunking_or_the_order(path):
    if path == "compiled" and not compiled.enabled():
        pytest.skip("the compiled path is off")
    n = 10_001
    with compiled.numpy_path() if path == "numpy" else contextlib.nullcontext():
        whole = _draws(SEED, STEP, n)
        halves = np.concatenate([_draws(SEED, STEP, n // 2), _draws(SEED, STEP, n - n // 2, first=n // 2)])
        ragged = np.concatenate([_draws(SEED, STEP, m, first=a) for a, m in ((0, 1), (1, 4999), (5000, 5001))])
    assert np.array_equal(whole, halves) and np.array_equal(whole, ragged)
    if path == "compiled":
        pair = compile_inner(normal_pair)
        k0, k1 = noise_key(SEED)
        rng = np.random.default_rng(0)
        for j in (*rng.permutation(n)[:200], n - 1, 0):  # one human at a time, in a shuffled order
            assert pair(k0, k1, STEP, int(j)) == tuple(whole[j])


@needs_numba
def test_normal_pair_in_a_prange_loop_gives_the_same_bits_on_any_number_of_threads():
    """What the crowd's step will do: call normal_pair from a parallel loop.  The numbers are the
    serial loop's, with 1 thread and with every thread numba has."""
    import numba

    pair = compile_inner(normal_pair)

    @numba.njit(parallel=True)
    def parallel_pairs(k0, k1, step, out):
        for j in numba.prange(out.shape[0]):
            z0, z1 = pair(k0, k1, step, j)
            out[j, 0] = z0
            out[j, 1] = z1
        return out

    n, k0, k1 = 20_000, *noise_key(SEED)
    serial = fill_normal_pairs(k0, k1, STEP, 0, np.empty((n, 2)))
    before = numba.get_num_threads()
    try:
        for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            numba.set_num_threads(threads)
            assert np.array_equal(parallel_pairs(k0, k1, STEP, np.empty((n, 2))), serial), threads
    finally:
        numba.set_num_threads(before)


def test_the_seed_is_the_key_and_bad_arguments_are_refused():
    assert noise_key(5) == (np.uint64(5), np.uint64(0)) and noise_key(5, 2) == (np.uint64(5), np.uint64(2))
    assert noise_key(U64)[0] == np.uint64(U64)
    out = np.empty((7, 2))
    assert standard_normals(5, 3, out, first=2) is out
    assert np.array_equal(out, fill_normal_pairs(np.uint64(5), np.uint64(0), 3, 2, np.empty((7, 2))))
    assert not np.array_equal(standard_normals(5, 3, np.empty((7, 2)), 2, stream=1), out)  # another stream
    for bad in (-1, 2**64, 1.5, True, "3"):
        with pytest.raises(ValueError, match="seed"):
            standard_normals(bad, 0, np.empty((2, 2)))
    with pytest.raises(ValueError, match="stream"):
        noise_key(0, -1)
    with pytest.raises(ValueError, match="step"):
        standard_normals(0, -1, np.empty((2, 2)))
    with pytest.raises(ValueError, match="first"):
        standard_normals(0, 0, np.empty((2, 2)), first=2**63)
    with pytest.raises(ValueError, match="first \\+ n"):
        standard_normals(0, 0, np.empty((2, 2)), first=2**63 - 1)
    for bad_out in (np.empty((3, 3)), np.empty(4), np.empty((2, 2), np.float32), [[0.0, 0.0]]):
        with pytest.raises(ValueError, match="out"):
            standard_normals(0, 0, bad_out)
