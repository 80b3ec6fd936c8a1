"""The compiled-loop infrastructure: numba where it compiles, the numpy twin everywhere else.

:mod:`~meanfield._compiled.core` (the :func:`compiled` decorator, :class:`CompiledLoop`, the switch),
:mod:`~meanfield._compiled.blas` (dgemm from compiled loops), :mod:`~meanfield._compiled.vector_exp`
(a vectorised exp), :mod:`~meanfield._compiled.warmup` (the first compile on several cores),
:mod:`~meanfield._compiled.philox` (counter-based random numbers: Philox4x32-10 and a ziggurat's Gaussian draws
keyed by seed, step and human, the same on any number of threads: the point masses' noise) and
:mod:`~meanfield._compiled.threads` (BLAS on one thread, the crowd's ``prange`` loops on every core).

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "ARG_MAX": "meanfield._compiled.vector_exp",
    "ARG_MIN": "meanfield._compiled.vector_exp",
    "CompiledFallbackWarning": "meanfield._compiled.core",
    "CompiledLoop": "meanfield._compiled.core",
    "ENV": "meanfield._compiled.warmup",
    "NO_BOX": "meanfield._compiled.core",
    "PARALLEL_CHUNK": "meanfield._compiled.core",
    "UNAVAILABLE": "meanfield._compiled.core",
    "ZIG_FI": "meanfield._compiled.philox",
    "ZIG_KI": "meanfield._compiled.philox",
    "ZIG_WI": "meanfield._compiled.philox",
    "before_cold_compile": "meanfield._compiled.core",
    "bits_as_float": "meanfield._compiled.core",
    "blas_threads": "meanfield._compiled.threads",
    "compile_in_parallel": "meanfield._compiled.warmup",
    "compile_inner": "meanfield._compiled.core",
    "compiled": "meanfield._compiled.core",
    "compiled_loops": "meanfield._compiled.core",
    "empty_array": "meanfield._compiled.core",
    "enabled": "meanfield._compiled.core",
    "exp_inplace": "meanfield._compiled.vector_exp",
    "fill_normal_pairs": "meanfield._compiled.philox",
    "fill_pairs_rows": "meanfield._compiled.philox",
    "gemm": "meanfield._compiled.blas",
    "inlined": "meanfield._compiled.core",
    "inner": "meanfield._compiled.core",
    "limited_blas": "meanfield._compiled.threads",
    "loop_threads": "meanfield._compiled.threads",
    "matmul_into": "meanfield._compiled.blas",
    "noise_key": "meanfield._compiled.philox",
    "normal_pair": "meanfield._compiled.philox",
    "numba_available": "meanfield._compiled.core",
    "numpy_path": "meanfield._compiled.core",
    "parallel_compile_possible": "meanfield._compiled.warmup",
    "philox4x32_10": "meanfield._compiled.philox",
    "philox4x32_block": "meanfield._compiled.philox",
    "prange": "meanfield._compiled.core",
    "set_loop_threads": "meanfield._compiled.threads",
    "standard_normals": "meanfield._compiled.philox",
    "status": "meanfield._compiled.core",
    "use_compiled": "meanfield._compiled.core",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = sorted(_LAZY)
