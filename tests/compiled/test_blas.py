"""BLAS from compiled loops (meanfield._compiled.blas) against numpy's ``@``.

* :func:`matmul_into` and :func:`gemm` equal ``a @ b`` (and ``out + a @ b``) to round-off, from
  Python and from a compiled loop, for C-contiguous operands, transposed ones (``x.T``), blocks
  of rows or columns of larger arrays, and the degenerate sizes (1, and an empty inner dimension);
* what does not multiply, or has no unit stride, is refused;
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
from meanfield._compiled.blas import gemm, matmul_into

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
    code = "import sys, meanfield._compiled.blas, meanfield.crowds._kde_loops; assert 'numba' not in sys.modules"
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
