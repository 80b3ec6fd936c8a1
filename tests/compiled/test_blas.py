"""BLAS from compiled loops (meanfield._compiled.blas) against numpy's ``@``.

* :func:`matmul_into` and :func:`gemm` equal ``a @ b`` (and ``out + a @ b``) to round-off, from
  Python and from a compiled loop, for C-contiguous operands, transposed ones (``x.T``), blocks
  of rows or columns of larger arrays, and the degenerate sizes (1, and an empty inner dimension);
* what does not multiply, or has no unit stride, is refused;
* :func:`numpy_gemm` is numpy's ``a @ b`` to the bit (numpy's own BLAS, which need not be scipy's), from Python
  and from a compiled loop, and a ``@compiled`` loop that calls it is read from the cache in a new process;
* importing the module does not import numba, and a loop that calls it is cached on disk.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from meanfield._compiled import core as compiled
from meanfield._compiled.blas import gemm, matmul_into, numpy_gemm, numpy_gemm_found, numpy_uses_gemm

needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")


def close(got, want, a, b, start=0.0):
    """Equal to round-off: each entry within ``1e-13 (|a| @ |b| + |start|)`` of numpy's."""
    scale = np.abs(a) @ np.abs(b) + np.abs(start)
    assert np.all(np.abs(got - want) <= 1e-13 * scale)


def operands(rng, m, k, n, ta, tb):
    """``a`` (m×k) and ``b`` (k×n), each C-contiguous or the transpose of a C-contiguous array."""
    a = rng.standard_normal((k, m)).T if ta else rng.standard_normal((m, k))
    b = rng.standard_normal((n, k)).T if tb else rng.standard_normal((k, n))
    return a, b


CASES = [(m, k, n, ta, tb) for (m, k, n) in [(30, 200, 30), (7, 13, 5), (1, 9, 4), (6, 1, 3), (5, 8, 1)]
         for ta in (False, True) for tb in (False, True)]  # fmt: skip


def _jitted():
    import numba

    @numba.njit
    def product(a, b, out, accumulate):
        return matmul_into(a, b, out, accumulate)

    @numba.njit
    def flat(ta, tb, m, n, k, a, lda, b, ldb, c, ldc, accumulate):
        gemm(ta, tb, m, n, k, a, lda, b, ldb, c, ldc, accumulate)
        return c

    return product, flat


@pytest.mark.parametrize("path", ["python", pytest.param("compiled", marks=needs_numba)])
def test_matmul_into_equals_numpy_for_contiguous_and_transposed_operands(path):
    product = _jitted()[0] if path == "compiled" else matmul_into
    rng = np.random.default_rng(1)
    for m, k, n, ta, tb in CASES:
        a, b = operands(rng, m, k, n, ta, tb)
        out = np.full((m, n), np.nan)  # not read without accumulate
        assert product(a, b, out, False) is out
        close(out, a @ b, a, b)
        start = rng.standard_normal((m, n))
        out = start.copy()
        product(a, b, out, True)
        close(out, start + a @ b, a, b, start)


@pytest.mark.parametrize("path", ["python", pytest.param("compiled", marks=needs_numba)])
def test_matmul_into_takes_blocks_of_larger_arrays(path):
    """Rows or columns of a larger array (leading dimensions above the row length), into a block of columns."""
    product = _jitted()[0] if path == "compiled" else matmul_into
    rng = np.random.default_rng(2)
    big = rng.standard_normal((20, 30))
    a = big[2:9, 3:14]  # 7 × 11, rows 30 apart
    b = big[5:16, 1:7]  # 11 × 6
    bt = big.T[4:15, 2:8]  # 11 × 6, transposed storage
    b2 = big[::2, 20:26]  # every other row: 10 × 6, rows 60 apart
    a2 = big[2:9, 5:15]  # 7 × 10
    host = np.zeros((7, 10))
    out = host[:, 2:8]
    product(a2, b2, out, False)
    close(out, a2 @ b2, a2, b2)
    for rhs in (b, bt):
        product(a, rhs, out, False)
        close(out, a @ rhs, a, rhs)
        assert np.all(host[:, :2] == 0) and np.all(host[:, 8:] == 0)  # nothing written beside


@pytest.mark.parametrize("path", ["python", pytest.param("compiled", marks=needs_numba)])
def test_an_empty_inner_dimension_gives_zeros_or_leaves_out(path):
    product = _jitted()[0] if path == "compiled" else matmul_into
    a, b = np.empty((4, 0)), np.empty((0, 3))
    out = np.full((4, 3), np.nan)
    product(a, b, out, False)
    assert np.all(out == 0)
    out = np.ones((4, 3))
    product(a, b, out, True)
    assert np.all(out == 1)


@pytest.mark.parametrize("path", ["python", pytest.param("compiled", marks=needs_numba)])
def test_gemm_on_rows_of_one_scratch_buffer(path):
    """The row-major convention of cblas_dgemm, operands in blocks of rows of one buffer (as the KDE's loop)."""
    flat = _jitted()[1] if path == "compiled" else gemm
    rng = np.random.default_rng(3)
    m, n, k, width = 9, 7, 40, 64
    work = rng.standard_normal((m + n, width))
    fx, fy = work[:m, :k], work[m:, :k]
    out = np.full((m, n), np.nan)
    flat(False, True, m, n, k, work, width, work[m:], width, out, n, False)
    close(out, fx @ fy.T, fx, fy.T)
    flat(False, True, m, n, k, work, width, work[m:], width, out, n, True)
    close(out, 2 * (fx @ fy.T), fx, fy.T, fx @ fy.T)
    c = np.empty((n, m))  # the transposed product: op(A) = fy (stored as is), op(B) = fxᵀ (stored transposed)
    flat(False, True, n, m, k, work[m:], width, work, width, c, m, False)
    close(c, fy @ fx.T, fy, fx.T)
    flat(True, False, m, n, k, np.ascontiguousarray(fx.T), m, np.ascontiguousarray(fy.T), n, out, n, False)
    close(out, fx @ fy.T, fx, fy.T)


@pytest.mark.parametrize("path", ["python", pytest.param("compiled", marks=needs_numba)])
def test_what_does_not_multiply_is_refused(path):
    product = _jitted()[0] if path == "compiled" else matmul_into
    rng = np.random.default_rng(4)
    a, b = rng.standard_normal((5, 4)), rng.standard_normal((4, 3))
    bad = [
        (a, rng.standard_normal((5, 3)), np.empty((5, 3))),  # inner sizes differ
        (a, b, np.empty((5, 4))),  # out's shape
        (rng.standard_normal((5, 8))[:, ::2], b, np.empty((5, 3))),  # no unit stride
        (a, b, np.empty((3, 5)).T),  # out stored by columns
    ]
    for x, y, out in bad:
        with pytest.raises(ValueError):
            product(x, y, out, False)


def test_importing_the_module_does_not_import_numba():
    code = ("import sys, meanfield._compiled.blas, meanfield.crowds._kde_loops, meanfield.signs._lattice_loops; "
            "assert 'numba' not in sys.modules and 'llvmlite' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)


@needs_numba
def test_a_loop_that_calls_gemm_is_cached_on_disk(tmp_path):
    """The BLAS function is found by name when cached code loads: a second process compiles nothing."""
    script = tmp_path / "loop.py"
    script.write_text(
        textwrap.dedent(
            """
            import numba, numpy as np
            from meanfield._compiled.blas import matmul_into

            @numba.njit(cache=True)
            def product(a, b, out):
                return matmul_into(a, b, out)

            a, b = np.arange(6.0).reshape(2, 3), np.arange(12.0).reshape(3, 4)
            assert np.array_equal(product(a, b, np.empty((2, 4))), a @ b)
            print(sum(product.stats.cache_hits.values()))
            """
        )
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    runs = [subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True) for _ in range(2)]
    assert [r.returncode for r in runs] == [0, 0], [r.stderr[-2000:] for r in runs]
    assert [r.stdout.split()[-1] for r in runs] == ["0", "1"]


needs_numpy_blas = pytest.mark.skipif(not numpy_gemm_found(), reason="numpy's BLAS has no ILP64 cblas_dgemm here")


def _numpy_gemm_call(a, b, out):
    """``out = a @ b`` by :func:`numpy_gemm` for operands each C-contiguous or transposed (``x.T``), ``out`` a block of
    columns of a wider array (leading dimension its row stride)."""
    ta, tb = not a.flags.c_contiguous, not b.flags.c_contiguous
    lda = a.shape[0] if ta else a.shape[1]
    ldb = b.shape[0] if tb else b.shape[1]
    base_a = a.T if ta else a
    base_b = b.T if tb else b
    m, k, n = a.shape[0], a.shape[1], b.shape[1]
    return ta, tb, m, n, k, base_a, max(lda, 1), base_b, max(ldb, 1), out, out.strides[0] // 8


@needs_numpy_blas
@pytest.mark.parametrize("path", ["python", pytest.param("compiled", marks=needs_numba)])
def test_numpy_gemm_is_numpys_product_to_the_bit(path):
    """The same numbers as numpy's ``@`` on every layout, bit for bit, wherever numpy calls ``dgemm`` (scipy's
    ``dgemm``, which :func:`gemm` calls, differs from it in the last bit on the first shape with numpy 2.4 and
    scipy 1.17), including an empty inner dimension (zeros) and an output that is a block of columns of a wider
    array; a size of 1 is numpy's ``ddot``, ``dgemv`` or its own loop, which :func:`numpy_uses_gemm` tells."""
    rng = np.random.default_rng(7)
    call = numpy_gemm
    if path == "compiled":
        import numba

        call = numba.njit(lambda *args: numpy_gemm(*args))
    shapes = [(257, 64, 257), (43, 120, 384), (16, 50, 384), (7, 13, 5), (2, 2, 2), (4, 0, 3), (0, 3, 2)]
    for m, k, n in shapes:
        assert numpy_uses_gemm(m, n, k)
        for ta in (False, True):
            for tb in (False, True):
                a, b = operands(rng, m, k, n, ta, tb)
                wide = np.full((m, n + 5), np.nan)
                out = wide[:, 2 : 2 + n]
                call(*_numpy_gemm_call(a, b, out))
                assert np.array_equal(out, a @ b), (m, k, n, ta, tb)
                assert np.isnan(wide[:, :2]).all() and np.isnan(wide[:, 2 + n :]).all()  # nothing beside it written


@needs_numpy_blas
@needs_numba
def test_a_compiled_loop_that_calls_numpy_gemm_is_read_from_the_cache(tmp_path):
    """numpy's BLAS is made known to numba's JIT by name before any loop loads (``meanfield._compiled.core``): a
    second process reads the binned estimate's products from the cache, compiles nothing, warns nothing, and gets
    numpy's numbers."""
    script = tmp_path / "loop.py"
    script.write_text(
        textwrap.dedent(
            """
            import warnings
            import numpy as np
            from meanfield.crowds._kde_loops import _banded_numpy, banded_products

            warnings.simplefilter("error")
            rng = np.random.default_rng(0)
            fx, fy, counts = rng.random((32, 96)), rng.random((24, 80)), rng.random((96, 80))
            bands_x = np.array([[0, 16, 0, 60], [16, 32, 30, 96]], np.int64)
            bands_y = np.array([[0, 16, 0, 50], [16, 24, 40, 80]], np.int64)
            got = banded_products(fx, counts, bands_x, fy, bands_y, np.empty((32, 80)), np.empty((32, 24)))
            want = _banded_numpy(fx, counts, bands_x, fy, bands_y, np.empty((32, 80)), np.empty((32, 24)))
            assert np.array_equal(got, want)
            print(sum(banded_products._jitted.stats.cache_hits.values()))
            """
        )
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    runs = [subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True) for _ in range(2)]
    assert [r.returncode for r in runs] == [0, 0], [r.stderr[-2000:] for r in runs]
    assert [r.stdout.split()[-1] for r in runs] == ["0", "1"]


def test_numpy_uses_gemm_only_for_every_size_two_or_more():
    """numpy's ``@`` calls ``dgemm`` for matrices with every size at least 2 (or zeros); a size of 1 is another
    routine (``numpy/_core/src/umath/matmul.c.src``), which the callers of :func:`numpy_gemm` leave to numpy."""
    for m, n, k in [(1, 9, 4), (9, 1, 4), (9, 4, 1), (1, 1, 1)]:
        assert not numpy_uses_gemm(m, n, k)
    for m, n, k in [(2, 2, 2), (257, 257, 64), (3, 4, 0), (0, 1, 1)]:
        assert numpy_uses_gemm(m, n, k)
