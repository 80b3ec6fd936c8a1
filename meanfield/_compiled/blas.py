"""BLAS called from compiled loops: ``C = op(A) op(B)`` (or ``C +=``) into a given array, by ``dgemm``.

A compiled loop (:mod:`meanfield._compiled.core`) that ends in a matrix product can write ``np.dot``
or ``@``, but numba then compiles its dot overloads (0.3 to 0.5 s the first time in a process),
allocates the result, and cannot accumulate into an existing array.  The helpers here call the
same BLAS routine directly: scipy's ``dgemm`` (``scipy.linalg.cython_blas``), through
``numba_xxgemm``, the C helper behind numba's own ``np.dot``, declared to numba as an external
function of that name.  Being found by its name when machine code is loaded, the call lets
the loop be cached on disk as usual (a ``ctypes`` function pointer would be written into the
machine code as an address, and numba does not cache such a loop).

* :func:`gemm`: the CBLAS row-major convention (``cblas_dgemm(CblasRowMajor, ...)``, with
  ``alpha = 1`` and ``beta`` 0 or 1) on buffers and leading dimensions, unchecked as BLAS is;
  for loops that keep their matrices in blocks of rows of one scratch array.  About 0.05 s of
  compilation for each combination of buffer types.
* :func:`matmul_into`: ``out = a @ b`` or ``out += a @ b`` for 2-D arrays, each C-contiguous
  or the transpose (``.T``) of a C-contiguous array, shapes and layouts checked.  About
  0.15 s of compilation for each combination of layouts.

* :func:`numpy_gemm`: :func:`gemm`'s convention, by *numpy's* own BLAS (the library numpy's ``@`` calls, which
  need not be scipy's: numpy 2.4's wheel ships OpenBLAS 0.3.31, scipy 1.17's 0.3.30, and their ``dgemm`` can
  differ in the last bit).  A loop that moves numpy products onto numba's threads calls it, so that each product
  is numpy's to the bit (issue 45: the same numbers as before, on any number of threads).

Row-major ``C = op(A) op(B)`` is column-major ``Cᵀ = op(B)ᵀ op(A)ᵀ``, which is the call made:
``dgemm(op_b, op_a, n, m, k, 1, B, ldb, A, lda, beta, C, ldc)``.  Operands are float64; ``C``
must not overlap ``A`` or ``B``; with ``beta = 0`` it is not read (it may come from ``np.empty``).

Both helpers are plain Python functions when called from Python (the same ``dgemm``, through
``ctypes``), and a compiled loop that calls them compiles their numba versions on first use:
importing this module does not import numba.  Unlike :func:`meanfield._compiled.core.inner` helpers
they need not be imported into the loop's module, and they are compiled without the wrappers
that let Python call them.  Their numba versions are cached on disk under these options: do not
``numba.njit(cache=True)`` the functions yourself (numba's cache does not tell options apart).
"""

from __future__ import annotations

import ctypes
import functools
from typing import Any

import numpy as np

__all__ = ["gemm", "matmul_into", "numpy_gemm", "numpy_gemm_found", "numpy_uses_gemm", "register_symbols"]

_KIND = 100  # ord("d"): float64
_NO = 78  # ord("N")
_TRANS = 84  # ord("T")
_ONE_ZERO = np.array([1.0, 0.0])
"""``alpha`` and ``beta`` by pointer: 1 at ``_ONE_ZERO[0:]``, 0 at ``_ONE_ZERO[1:]`` (compiled code embeds it)."""


class _XXGemm:
    """numba's C helper ``int numba_xxgemm(char kind, char transa, char transb, Py_ssize_t m, n, k,
    void *alpha, void *a, Py_ssize_t lda, void *b, Py_ssize_t ldb, void *beta, void *c, Py_ssize_t ldc)``.

    Column-major BLAS ``gemm`` (kind ``'d'``: ``dgemm``) with the sizes by value, from numba's
    ``_helperlib``, whose functions every numba process makes known to the JIT by name.
    Compiled code sees it through ``_numba_type_`` (built on first use); a Python call runs
    scipy's ``dgemm`` through ``ctypes``.  Returns 0, or -1 when scipy's BLAS cannot be loaded.
    """

    _type: Any = None
    _python: Any = None

    @property
    def _numba_type_(self) -> Any:
        if _XXGemm._type is None:
            from numba import _helperlib
            from numba.core import types

            if "xxgemm" not in _helperlib.c_helpers:  # a numba without it: the calling loop falls back
                raise TypeError("this numba has no numba_xxgemm helper")
            p, i, c = types.voidptr, types.intp, types.int8
            signature = types.int32(c, c, c, i, i, i, p, p, i, p, i, p, p, i)
            _XXGemm._type = types.ExternalFunction("numba_xxgemm", signature)
        return _XXGemm._type

    @staticmethod
    def _dgemm() -> Any:
        if _XXGemm._python is None:
            from scipy.linalg import cython_blas

            api = ctypes.pythonapi
            api.PyCapsule_GetName.restype = ctypes.c_char_p
            api.PyCapsule_GetName.argtypes = [ctypes.py_object]
            api.PyCapsule_GetPointer.restype = ctypes.c_void_p
            api.PyCapsule_GetPointer.argtypes = [ctypes.py_object, ctypes.c_char_p]
            capsule = cython_blas.__pyx_capi__["dgemm"]
            address = api.PyCapsule_GetPointer(capsule, api.PyCapsule_GetName(capsule))
            char, ptr, num = ctypes.c_char_p, ctypes.c_void_p, ctypes.POINTER(ctypes.c_int)
            proto = ctypes.CFUNCTYPE(None, char, char, num, num, num, ptr, ptr, num, ptr, num, ptr, ptr, num)
            _XXGemm._python = proto(address)
        return _XXGemm._python

    def __call__(self, kind: int, ta: int, tb: int, *args: Any) -> int:
        m, n, k, alpha, a, lda, b, ldb, beta, c, ldc = args
        if kind != _KIND:
            return -1
        m, n, k, lda, ldb, ldc = (ctypes.byref(ctypes.c_int(int(v))) for v in (m, n, k, lda, ldb, ldc))
        self._dgemm()(bytes([ta]), bytes([tb]), m, n, k, alpha, a, lda, b, ldb, beta, c, ldc)
        return 0


_xxgemm = _XXGemm()

_ROW_MAJOR, _CBLAS_NO, _CBLAS_TRANS = 101, 111, 112  # CBLAS's enums: CblasRowMajor, CblasNoTrans, CblasTrans
_NUMPY_DGEMM_NAMES = ("scipy_cblas_dgemm64_", "cblas_dgemm64_")
"""numpy's ILP64 ``cblas_dgemm`` (64-bit sizes), as numpy's wheels name it: ``scipy-openblas64`` (numpy >= 2.0) and
``openblas64_`` (numpy 1.26).  The ``64_`` suffix says the integer width; a BLAS named otherwise (numpy built
against Accelerate, MKL or a system BLAS) is not called: :func:`numpy_gemm_found` is then False."""


class _NumpyDgemm:
    """numpy's own ``cblas_dgemm`` (:data:`_NUMPY_DGEMM_NAMES`), found among the libraries numpy's core module
    loaded, ``void (order, transa, transb, m, n, k, alpha, A, lda, B, ldb, beta, C, ldc)`` with 64-bit sizes.

    Compiled code calls it by the name :attr:`ALIAS`, which :func:`register_symbols` makes known to numba's JIT
    (numpy loads its BLAS privately, so its symbols are not the process's): found by name when machine code is
    loaded, as ``numba_xxgemm``, the loop is cached on disk as usual.  A Python call goes through ``ctypes``.
    """

    ALIAS = "meanfield_numpy_cblas_dgemm64"
    _address: int | None = None
    _type: Any = None
    _python: Any = None

    @staticmethod
    def address() -> int:
        """The function's address, 0 when numpy's BLAS has none of :data:`_NUMPY_DGEMM_NAMES` (looked up once)."""
        if _NumpyDgemm._address is None:
            _NumpyDgemm._address = 0
            try:
                from numpy._core import _multiarray_umath as core  # numpy >= 2.0
            except ImportError:
                from numpy.core import _multiarray_umath as core  # numpy 1.26
            try:
                library = ctypes.CDLL(core.__file__)  # (numpy's own handle: a lookup searches its BLAS too)
            except (OSError, AttributeError, TypeError):
                return 0
            for name in _NUMPY_DGEMM_NAMES:
                function = getattr(library, name, None)
                if function is not None:
                    _NumpyDgemm._address = ctypes.cast(function, ctypes.c_void_p).value or 0
                    break
        return _NumpyDgemm._address

    @property
    def _numba_type_(self) -> Any:
        if _NumpyDgemm._type is None:
            from numba.core import types

            if not register_symbols():  # the calling loop falls back to its numpy twin
                raise TypeError("numpy's BLAS has no ILP64 cblas_dgemm (scipy_cblas_dgemm64_ or cblas_dgemm64_)")
            i32, i64, f64, p = types.int32, types.int64, types.float64, types.voidptr
            signature = types.void(i32, i32, i32, i64, i64, i64, f64, p, i64, p, i64, f64, p, i64)
            _NumpyDgemm._type = types.ExternalFunction(_NumpyDgemm.ALIAS, signature)
        return _NumpyDgemm._type

    def __call__(self, *args: Any) -> None:
        if _NumpyDgemm._python is None:
            if not self.address():
                raise RuntimeError("numpy_gemm: numpy's BLAS has no ILP64 cblas_dgemm (numpy_gemm_found() is False)")
            i32, i64, f64, p = ctypes.c_int32, ctypes.c_int64, ctypes.c_double, ctypes.c_void_p
            proto = ctypes.CFUNCTYPE(None, i32, i32, i32, i64, i64, i64, f64, p, i64, p, i64, f64, p, i64)
            _NumpyDgemm._python = proto(self.address())
        order, ta, tb, m, n, k, alpha, a, lda, b, ldb, beta, c, ldc = args
        _NumpyDgemm._python(order, ta, tb, m, n, k, alpha, a.data, lda, b.data, ldb, beta, c.data, ldc)


_numpy_dgemm = _NumpyDgemm()
_registered = False


def numpy_gemm_found() -> bool:
    """Whether :func:`numpy_gemm` can call numpy's BLAS (numpy's wheels: yes); else a caller keeps numpy's ``@``."""
    return bool(_NumpyDgemm.address())


def numpy_uses_gemm(m: int, n: int, k: int) -> bool:
    """Whether numpy's ``@`` of an ``m × k`` by a ``k × n`` matrix is one ``dgemm`` (or zeros, with nothing to sum):
    every size at least 2.  numpy computes the other shapes by ``ddot``, ``dgemv`` or a loop of its own
    (``numpy/_core/src/umath/matmul.c.src``), whose last bits :func:`numpy_gemm` does not reproduce: a caller that
    must give numpy's numbers keeps numpy's ``@`` for them."""
    return m == 0 or n == 0 or k == 0 or (m >= 2 and n >= 2 and k >= 2)


def register_symbols() -> bool:
    """Make numpy's ``cblas_dgemm`` known to numba's JIT under :attr:`_NumpyDgemm.ALIAS` (once per process, before
    any compiled loop is compiled or read from the cache: :func:`meanfield._compiled.core` calls it when it imports
    numba).  Returns whether it was found."""
    global _registered
    if not _registered and _NumpyDgemm.address():
        from llvmlite import binding

        binding.add_symbol(_NumpyDgemm.ALIAS, _NumpyDgemm.address())
        _registered = True
    return _registered


class _Helper:
    """A function for compiled loops: plain Python when called from Python; inside a compiled loop,
    its numba version (typed through ``_numba_type_``: compiled on first use, cached on disk, and
    without the wrappers that let Python call it, which a helper never needs)."""

    def __init__(self, func: Any):
        functools.update_wrapper(self, func)
        self._dispatcher: Any = None

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.__wrapped__(*args, **kwargs)

    @property
    def _numba_type_(self) -> Any:
        import numba
        from numba.core import types

        if self._dispatcher is None:
            options = {"no_cpython_wrapper": True, "no_cfunc_wrapper": True}
            self._dispatcher = numba.njit(cache=True, error_model="numpy", **options)(self.__wrapped__)
        return types.Dispatcher(self._dispatcher)


@_Helper
def gemm(
    trans_a: bool,
    trans_b: bool,
    m: int,
    n: int,
    k: int,
    a: np.ndarray,
    lda: int,
    b: np.ndarray,
    ldb: int,
    c: np.ndarray,
    ldc: int,
    accumulate: bool = False,
) -> None:
    """``C = op(A) op(B)`` (or ``C += op(A) op(B)``), row-major as ``cblas_dgemm(CblasRowMajor, ...)``, float64.

    ``C`` is ``m × n`` with rows ``ldc`` apart in ``c``'s buffer; ``op(A)`` is ``m × k``, stored
    as ``A`` (``m × k``, rows ``lda`` apart) or, with ``trans_a``, as ``Aᵀ`` (``k × m``, rows
    ``lda`` apart); the same for ``B`` (``k × n``).  The arrays only give their data pointers
    (a view's first element).  Nothing is checked, as in BLAS and in numba's own indexing: the
    caller guarantees ``m, n, k >= 0``, leading dimensions of at least the stored rows' length
    (and 1), and buffers holding the entries addressed (:func:`matmul_into` derives all of
    this from the arrays, and checks it).

    Parameters
    ----------
    trans_a, trans_b : bool
        Whether ``A``, ``B`` are stored transposed.
    m, n, k : int
        The product's sizes.
    a, b, c : ndarray of float64 (any number of dimensions)
        The buffers; ``c`` must not overlap ``a`` or ``b``.
    lda, ldb, ldc : int
        Leading dimensions: the distance between consecutive stored rows, in entries.
    accumulate : bool
        Add the product to ``C`` (BLAS ``beta = 1``); else ``C`` is overwritten and not read
        (``beta = 0``: it may hold anything, as after ``np.empty``).

    Raises
    ------
    RuntimeError
        scipy's BLAS could not be loaded.
    """
    if m == 0 or n == 0:
        return
    op_a = _TRANS if trans_a else _NO
    op_b = _TRANS if trans_b else _NO
    beta = _ONE_ZERO[0:] if accumulate else _ONE_ZERO[1:]
    if _xxgemm(_KIND, op_b, op_a, n, m, k, _ONE_ZERO.ctypes, b.ctypes, ldb, a.ctypes, lda, beta.ctypes, c.ctypes, ldc):
        raise RuntimeError("gemm: scipy's BLAS (scipy.linalg.cython_blas) could not be loaded")


@_Helper
def matmul_into(a: np.ndarray, b: np.ndarray, out: np.ndarray, accumulate: bool = False) -> np.ndarray:
    """``out = a @ b`` (or ``out += a @ b``) by BLAS ``dgemm``, float64, for 2-D arrays.

    Each operand is C-contiguous, or the transpose of a C-contiguous array (``x.T``), or any
    view with unit stride along one of its axes (a block of rows or of columns of such arrays);
    ``out`` has unit stride along its rows (C-contiguous, or a block of its columns).

    Parameters
    ----------
    a : ndarray, shape (m, k)
    b : ndarray, shape (k, n)
    out : ndarray, shape (m, n)
        Must not overlap ``a`` or ``b``; not read unless ``accumulate``.
    accumulate : bool
        Add the product to ``out`` instead of overwriting it.

    Returns
    -------
    ndarray
        ``out``.

    Raises
    ------
    ValueError
        Shapes that do not multiply, an item size other than 8, or a layout without a unit
        stride (``out``: along its rows).
    """
    m, k = a.shape
    n = b.shape[1]
    sa0, sa1 = a.strides  # in bytes
    sb0, sb1 = b.strides
    so0, so1 = out.strides
    # an operand is stored by rows (unit stride along them) or transposed (unit stride down its
    # columns); the stride along an axis of length 1 is never used.  (Bitwise & and | on the
    # conditions: each `and`/`or` is a branch, which numba compiles slowly.)
    a_rows = ((k <= 1) | (sa1 == 8)) & ((m <= 1) | ((sa0 & 7 == 0) & (sa0 >= 8 * k)))
    a_cols = ((m <= 1) | (sa0 == 8)) & ((k <= 1) | ((sa1 & 7 == 0) & (sa1 >= 8 * m)))
    b_rows = ((n <= 1) | (sb1 == 8)) & ((k <= 1) | ((sb0 & 7 == 0) & (sb0 >= 8 * n)))
    b_cols = ((k <= 1) | (sb0 == 8)) & ((n <= 1) | ((sb1 & 7 == 0) & (sb1 >= 8 * k)))
    o_rows = ((n <= 1) | (so1 == 8)) & ((m <= 1) | ((so0 & 7 == 0) & (so0 >= 8 * n)))
    shapes = (b.shape[0] == k) & (out.shape[0] == m) & (out.shape[1] == n)
    items = (a.itemsize == 8) & (b.itemsize == 8) & (out.itemsize == 8)
    if not (shapes & items & (a_rows | a_cols) & (b_rows | b_cols) & o_rows):
        raise ValueError("matmul_into: a (m×k), b (k×n), out (m×n) float64, each with a unit stride along an axis")
    lda = (k if m <= 1 else sa0 >> 3) if a_rows else (m if k <= 1 else sa1 >> 3)
    ldb = (n if k <= 1 else sb0 >> 3) if b_rows else (k if n <= 1 else sb1 >> 3)
    ldc = n if m <= 1 else so0 >> 3
    lda = 1 if lda < 1 else lda
    ldb = 1 if ldb < 1 else ldb
    ldc = 1 if ldc < 1 else ldc
    if m > 0 and n > 0:  # (the call itself rather than gemm's: gemm would compile for each layout)
        op_a = _NO if a_rows else _TRANS
        op_b = _NO if b_rows else _TRANS
        beta = _ONE_ZERO[0:] if accumulate else _ONE_ZERO[1:]
        one = _ONE_ZERO.ctypes
        if _xxgemm(_KIND, op_b, op_a, n, m, k, one, b.ctypes, ldb, a.ctypes, lda, beta.ctypes, out.ctypes, ldc):
            raise RuntimeError("matmul_into: scipy's BLAS (scipy.linalg.cython_blas) could not be loaded")
    return out


@_Helper
def numpy_gemm(
    trans_a: bool,
    trans_b: bool,
    m: int,
    n: int,
    k: int,
    a: np.ndarray,
    lda: int,
    b: np.ndarray,
    ldb: int,
    c: np.ndarray,
    ldc: int,
) -> None:
    """``C = op(A) op(B)`` as :func:`gemm` (row-major, the arrays giving their data pointers, nothing checked), by
    numpy's own BLAS: the call numpy's ``a @ b`` makes on these operands wherever :func:`numpy_uses_gemm`, so the
    same numbers to the bit.

    ``C`` is overwritten and not read (BLAS ``beta = 0``: with ``k = 0`` it is set to zeros, as numpy's ``@``
    gives).  Only where :func:`numpy_gemm_found`; a compiled loop that calls it elsewhere falls back to its numpy
    twin.

    Parameters
    ----------
    trans_a, trans_b : bool
        Whether ``A``, ``B`` are stored transposed.
    m, n, k : int
        The product's sizes.
    a, b, c : ndarray of float64
        The buffers (a view's first element); ``c`` must not overlap ``a`` or ``b``.
    lda, ldb, ldc : int
        Leading dimensions, in entries.
    """
    if m == 0 or n == 0:
        return
    op_a = _CBLAS_TRANS if trans_a else _CBLAS_NO
    op_b = _CBLAS_TRANS if trans_b else _CBLAS_NO
    _numpy_dgemm(_ROW_MAJOR, op_a, op_b, m, n, k, 1.0, a.ctypes, lda, b.ctypes, ldb, 0.0, c.ctypes, ldc)
