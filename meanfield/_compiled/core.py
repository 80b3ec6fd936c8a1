"""Compiled loops: numba where it is installed and compiles, the numpy path everywhere else.

A hot loop of the toolkit (the crowd's step, the KDE's binning, the controller's integrals)
is written twice: once in numpy, which is the reference, and once as a plain loop that
numba compiles to machine code (``@njit(cache=True)``: compiled on first use, then read
from numba's on-disk cache by every later process).  :func:`compiled` pairs the two::

    def _binned_numpy(points, ...): ...          # the reference

    @compiled(fallback=_binned_numpy)
    def binned(points, ...): ...                 # the same arithmetic, one pass per point

Calling ``binned(...)`` runs the compiled loop when :func:`enabled`, else the numpy one.
A loop that fails to compile (numba missing, a numba that cannot type it, a read-only
cache directory it cannot work around) falls back to numpy with **one** warning naming the
cause; the run goes on.  The environment variable ``MEANFIELD_COMPILED=0`` (or
:func:`use_compiled` ``(False)``) selects the numpy path everywhere, which is what the
benchmarks' anchors and the tests that compare the two paths do.

Why numba: it compiles the plain loops the equations are written in (no new language, no
build step at install time), caches the machine code on disk, and is already what py-pde,
the field's PDE library, is built on.  Its wheels exist for every platform the toolkit runs on.

What "the same results" means: the two paths do the same floating-point operations in a
different order, so they agree to round-off on one call (the tests check this for every
pair); a chaotic closed loop then amplifies round-off, so whole runs agree in distribution,
not bit for bit.  A given path is deterministic: the same seed gives the same numbers.

How a loop is written so that its first compile stays short: numba compiles its own overloads
(``np.empty``, ``np.zeros``, ``np.full``, ``min``, ``max``, ``int``, ``np.argsort``, a slice assignment's
shape-mismatch message) as functions of their own, in every process and for every new combination of
argument types, and never caches them on disk (issue 45: up to 2 s each for the sort and the message).
So a loop allocates with :func:`empty_array` (filling what it reads), writes ``min(a, b)`` as
``b if b < a else a`` and ``max(a, b)`` as ``b if b > a else a`` (numba's own select, NaN included),
``int(x)`` of a float as ``np.int64(x)``, and copies element by element.
"""

from __future__ import annotations

import functools
import gc
import inspect
import os
import struct
import types
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

__all__ = [
    "compiled",
    "enabled",
    "use_compiled",
    "numpy_path",
    "numba_available",
    "status",
    "compiled_loops",
    "inner",
    "inlined",
    "UNAVAILABLE",
    "CompiledLoop",
    "CompiledFallbackWarning",
    "bits_as_float",
    "empty_array",
    "compile_inner",
    "before_cold_compile",
    "collector_paused",
    "NO_BOX",
    "prange",
    "PARALLEL_CHUNK",
]

ENV = "MEANFIELD_COMPILED"
"""``MEANFIELD_COMPILED=0`` (or ``false``/``no``/``off``) selects the numpy path everywhere."""


class CompiledFallbackWarning(RuntimeWarning):
    """A compiled loop could not be used; the numpy path runs instead (the message says why)."""


_override: bool | None = None
_failures: dict[str, str] = {}
_loops: list[CompiledLoop] = []


@functools.cache
def _numba() -> Any:
    try:
        import numba
    except Exception as exc:  # ImportError, or a numba broken against this numpy or its environment
        if _from_environment():  # (MEANFIELD_COMPILED=0 asked for numpy: nothing to say)
            warnings.warn(
                f"numba could not be imported ({_cause(exc)}); the compiled loops are off and their numpy twins "
                "run instead (slower)" + (" (NUMBA_NUM_THREADS must be >= 1)" if "NUMBA_NUM_THREADS" in os.environ
                                           and "threads" in str(exc).lower() else ""),
                CompiledFallbackWarning,
                stacklevel=4,
            )  # fmt: skip
        return exc
    from meanfield._compiled.blas import register_symbols

    register_symbols()  # numpy's BLAS by name, before any loop that calls it is compiled or read from the cache
    return numba


def numba_available() -> bool:
    """Whether numba imports (not whether every loop compiles: see :func:`status`)."""
    return not isinstance(_numba(), Exception)


def _from_environment() -> bool:
    return os.environ.get(ENV, "1").strip().lower() not in {"0", "false", "no", "off"}


_environment = _from_environment()  # read at import, and again by use_compiled(None)


_selected: bool | None = None  # enabled(), remembered until the selection changes


def enabled() -> bool:
    """Whether the compiled path is selected: numba imports, and neither :func:`use_compiled`
    nor ``MEANFIELD_COMPILED=0`` (read at import, and again by ``use_compiled(None)``) turned it off."""
    global _selected
    if _selected is None:
        on = _environment if _override is None else _override
        _selected = on and numba_available()
    return _selected


def use_compiled(on: bool | None) -> None:
    """Select the compiled path (True), the numpy path (False), or follow ``MEANFIELD_COMPILED`` (None, read now)."""
    global _override, _environment, _selected
    if on is not None and not isinstance(on, bool):
        from meanfield.errors import ParameterError

        raise ParameterError("on", on, "True, False or None")
    _override, _selected = on, None
    if on is None:
        _environment = _from_environment()


@contextmanager
def numpy_path() -> Iterator[None]:
    """Run the block on the numpy path (the reference), then restore the previous choice."""
    global _override, _selected
    before = _override
    _override, _selected = False, None
    try:
        yield
    finally:
        _override, _selected = before, None


def status() -> dict[str, Any]:
    """What runs: ``{"enabled": bool, "numba": version or the import error, "fallbacks": {name: cause}}``."""
    nb = _numba()
    return {
        "enabled": enabled(),
        "numba": str(nb) if isinstance(nb, Exception) else nb.__version__,
        "fallbacks": dict(_failures),
    }


_before_cold_compile: list[Callable[[], None]] = []  # see before_cold_compile


def before_cold_compile(callback: Callable[[], None]) -> Callable[[], None]:
    """Call ``callback()`` once, just before the next loop compiles with nothing in numba's on-disk cache.

    How :func:`meanfield._compiled.warmup.compile_in_parallel` learns that the cache is cold, and how
    ``meanfield run`` says that the first run on a machine compiles. A warm cache never
    calls it. Returns a function that unregisters it (a no-op once it has run).
    """
    _before_cold_compile.append(callback)

    def unregister() -> None:
        if callback in _before_cold_compile:
            _before_cold_compile.remove(callback)

    return unregister


def prepare_compiler() -> None:
    """Load numba's typing and lowering registries now (about 0.3 s, which the first compile pays otherwise).

    Done before forking processes that compile (:mod:`meanfield._compiled.warmup`), so that each child
    starts from the loaded registries instead of loading its own.
    """
    nb = _numba()
    if isinstance(nb, Exception):
        return
    from numba.core.registry import cpu_target

    cpu_target.target_context.refresh()
    cpu_target.typing_context.refresh()


def cached_on_disk(dispatcher: Any) -> bool:
    """Whether numba's on-disk cache holds a fresh entry for this dispatcher's loop (any signature).

    Reads numba's cache index (``dispatcher._cache``, a private attribute of numba's
    dispatchers; the ``numba`` pin in ``pyproject.toml`` covers it).  An index that is missing,
    from another numba or older than the loop's source file counts as empty; anything this
    cannot read counts as cached, so that nothing is started on a guess.
    """
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:
        return True


UNAVAILABLE = object()
"""What a loop without a numpy twin (``fallback=None``) returns when it cannot run compiled:
the caller then takes its own numpy path."""


def inner(loop: Callable[..., Any]) -> Callable[..., Any]:
    """Mark a helper called only from inside compiled loops of the same module.

    It stays a plain function until a loop of its module compiles: then it is replaced, in
    the module, by its ``numba.njit(cache=True)`` version (so importing the toolkit never
    imports numba).  Its own failures surface when that loop compiles, and fall back there.
    """
    loop._compiled_inner = True  # type: ignore[attr-defined]
    return loop


def inlined(loop: Callable[..., Any]) -> Callable[..., Any]:
    """An :func:`inner` helper that numba also inlines into its callers (``inline="always"``).

    For a helper called once per human in a hot loop: a call between two compiled functions is not inlined by
    LLVM (each is compiled on its own), and passing a dozen arrays costs more than a short helper's work.  The
    numbers are the same: inlining moves no floating-point operation.
    """
    inner(loop)
    loop._compiled_inline = True  # type: ignore[attr-defined]
    return loop


def bits_as_float(bits: int) -> float:
    """The float64 whose IEEE-754 bits are the int64 ``bits`` (e.g. ``(k + 1023) << 52`` is ``2.0**k``).

    Inside a compiled loop this is one LLVM ``bitcast``, which costs nothing and vectorises
    (a numba intrinsic, put in place of this function when a loop of the module compiles, as
    :func:`inner` helpers are); called from Python it unpacks the bits with :mod:`struct`.
    """
    return struct.unpack("<d", struct.pack("<q", bits))[0]


@functools.cache
def _bitcast_intrinsic() -> Any:
    from llvmlite import ir
    from numba.core import types
    from numba.extending import intrinsic

    @intrinsic
    def bits_as_float(typingctx: Any, bits: Any) -> Any:
        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            return builder.bitcast(args[0], ir.DoubleType())

        return types.float64(types.int64), codegen

    return bits_as_float


def empty_array(shape: int | tuple[int, ...], dtype: Any) -> np.ndarray:
    """A new C-ordered array of ``shape`` (an integer or a tuple of integers, each >= 0) and ``dtype`` (a numpy
    scalar type, ``np.float64`` say), not initialised: ``np.empty(shape, dtype)``.

    Inside a compiled loop this is a numba intrinsic (put in place of this function when a loop of the module
    compiles, as :func:`bits_as_float` is): the allocation is lowered where it is called. ``np.empty`` is an
    overload that numba compiles, with its allocator, in every process and for every new combination of shape
    and dtype, about 0.03 to 0.1 s each and never cached on disk (issue 45: about 0.5 s of CPU in the paper's
    first run, over its three compiling processes). The sizes are not checked (a loop asks for what it needs).
    """
    return np.empty(shape, dtype)


@functools.cache
def _empty_intrinsic() -> Any:
    from numba.core import cgutils, types
    from numba.extending import intrinsic
    from numba.np.arrayobj import make_array, populate_array

    @intrinsic
    def empty_array(typingctx: Any, shape: Any, dtype: Any) -> Any:
        if isinstance(shape, types.Integer):
            dims: tuple[Any, ...] = (shape,)
        elif isinstance(shape, types.BaseTuple) and len(shape) and all(isinstance(t, types.Integer) for t in shape):
            dims = tuple(shape)
        else:
            return None
        if not isinstance(dtype, types.NumberClass):
            return None
        array = types.Array(dtype.dtype, len(dims), "C")

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            intp = context.get_value_type(types.intp)
            if isinstance(shape, types.Integer):
                sizes = [context.cast(builder, args[0], shape, types.intp)]
            else:
                sizes = [context.cast(builder, builder.extract_value(args[0], i), t, types.intp)
                         for i, t in enumerate(dims)]  # fmt: skip
            data_type = context.get_data_type(array.dtype)
            itemsize = context.get_constant(types.intp, context.get_abi_sizeof(data_type))
            strides = [itemsize]  # C order: the last axis is contiguous
            for size in reversed(sizes[1:]):
                strides.append(builder.mul(strides[-1], size))
            nbytes = itemsize
            for size in sizes:
                nbytes = builder.mul(nbytes, size)
            align = context.get_constant(types.uint32, context.get_preferred_array_alignment(array.dtype))
            meminfo = context.nrt.meminfo_alloc_aligned(builder, nbytes, align)  # (freed with the array, by NRT)
            out = make_array(array)(context, builder)
            populate_array(
                out,
                data=builder.bitcast(context.nrt.meminfo_data(builder, meminfo), data_type.as_pointer()),
                shape=cgutils.pack_array(builder, sizes, ty=intp),
                strides=cgutils.pack_array(builder, strides[::-1], ty=intp),
                itemsize=itemsize,
                meminfo=meminfo,
            )
            return out._getvalue()

        return array(shape, dtype), codegen

    return empty_array


def prange(*args: int) -> range:
    """``range`` everywhere but inside a loop compiled with ``parallel=True``, where it is ``numba.prange``.

    A loop module imports this name (so that importing the toolkit never imports numba); when a
    loop of the module compiles, it is replaced in the module by ``numba.prange``, as :func:`inner`
    helpers are by their compiled versions.  The iterations of a ``prange`` loop run on numba's
    threads in any order: each must write only its own outputs, and a loop that must give the same
    numbers on any number of threads sums nothing across iterations (it writes per-iteration
    partial results, then adds them in a fixed order: :data:`PARALLEL_CHUNK`).
    """
    return range(*args)


PARALLEL_CHUNK = 4096
"""Humans per iteration of the crowd's parallel loops: a chunk's work (tens of µs) dwarfs a thread's
start; below one chunk a loop runs on the calling thread.  The chunks, and so the order of every
partial sum, depend on the number of humans only, never on the number of threads."""


def _is_pending_helper(value: Any) -> bool:
    return getattr(value, "_compiled_inner", False) and not hasattr(value, "py_func")


_helper_dispatchers: dict[Callable[..., Any], Any] = {}  # one per helper, whichever modules import it
_callable_helpers: dict[Callable[..., Any], Any] = {}  # compile_inner's twins, callable from Python

_INNER_OPTIONS = {"no_cpython_wrapper": True, "no_cfunc_wrapper": True}
"""An :func:`inner` helper is only ever called from compiled code: numba builds neither the wrapper that lets
Python call it nor its C-callable one (about 0.45 s of the paper's 6.4 s of compiling on one core; issue 45).
:func:`compile_inner` compiles a twin with them, for the tests that call a helper from Python."""


def _resolve_helpers(space: dict[str, Any], nb: Any) -> None:
    """In one module's namespace: each :func:`inner` helper by its dispatcher, :func:`bits_as_float` and
    :func:`empty_array` by their intrinsics; then the same in the modules the helpers come from (before anything
    compiles)."""
    homes = []
    for name, value in list(space.items()):
        if value is bits_as_float:
            space[name] = _bitcast_intrinsic()
        elif value is empty_array:
            space[name] = _empty_intrinsic()
        elif value is prange:
            space[name] = nb.prange
        elif _is_pending_helper(value):
            if value not in _helper_dispatchers:
                inline = {"inline": "always"} if getattr(value, "_compiled_inline", False) else {}
                _helper_dispatchers[value] = nb.njit(cache=True, error_model="numpy", **_INNER_OPTIONS, **inline)(value)
            space[name] = _helper_dispatchers[value]
            if value.__globals__ is not space:
                homes.append(value.__globals__)
    for home in homes:
        _resolve_helpers(home, nb)


def _renamed(function: Callable[..., Any], suffix: str) -> Callable[..., Any]:
    """A copy of ``function`` whose qualified name ends in ``suffix``: numba's on-disk cache, keyed by that name,
    keeps a compiled version with other options apart from the function's own."""
    twin = types.FunctionType(
        function.__code__, function.__globals__, function.__name__, function.__defaults__, function.__closure__
    )
    twin.__qualname__ = f"{function.__qualname__}{suffix}"
    twin.__module__ = function.__module__
    return twin


def compile_inner(helper: Callable[..., Any]) -> Any:
    """The numba-compiled version of an :func:`inner` helper that Python can call, its own helpers resolved (for
    tests: the one the loops call has no Python wrapper, :data:`_INNER_OPTIONS`; this twin computes the same)."""
    if hasattr(helper, "py_func"):
        helper = helper.py_func
    nb = _numba()
    if isinstance(nb, Exception):
        raise nb
    _resolve_helpers(helper.__globals__, nb)
    if helper not in _callable_helpers:
        inline = {"inline": "always"} if getattr(helper, "_compiled_inline", False) else {}
        _callable_helpers[helper] = nb.njit(cache=True, error_model="numpy", **inline)(_renamed(helper, "_from_python"))
    return _callable_helpers[helper]


_LOOP_OPTIONS = {"error_model": "numpy", "no_cfunc_wrapper": True}
"""A loop is called from Python only: no C-callable wrapper (numba builds one by default)."""


def _cause(exc: BaseException) -> str:
    """An exception in one line, for the fallback warnings: its type and the first line of its message."""
    text = str(exc).strip()
    return f"{type(exc).__name__}: {text.splitlines()[0] if text else ''}"


class CompiledLoop:
    """A loop compiled by numba on first call, with its numpy fallback (see the module's doc).

    A loop declared ``parallel_over`` an argument has a second compiled version, on numba's
    threads (``parallel=True``: its :func:`prange` loops run their iterations on threads),
    compiled the first time that argument has more than :data:`PARALLEL_CHUNK` rows, and used
    from then on for such calls; smaller calls run the one-thread version.  Compiling a
    ``parallel=True`` loop costs several times more than the loop alone, and a crowd of a few
    hundred (the paper's, a building's) never needs it: its first run does not pay for it.  The
    two versions are the same code, so they give the same numbers.  A threaded version that does
    not compile is replaced by the one-thread version, with one warning.
    """

    def __init__(
        self,
        loop: Callable[..., Any],
        fallback: Callable[..., Any] | None,
        options: dict[str, Any],
        parallel_over: str | None = None,
    ):
        self.loop = loop
        self.fallback = fallback
        self.name = f"{loop.__module__}.{loop.__qualname__}"
        self._options = options
        self._jitted: Callable[..., Any] | None = None
        self._ready = False
        self._over = None if parallel_over is None else list(inspect.signature(loop).parameters).index(parallel_over)
        self._threaded: Callable[..., Any] | None = None  # the parallel version, compiled on the first large call
        self._threads_failed = False
        functools.update_wrapper(self, loop)

    def _compile_threaded(self) -> Callable[..., Any]:
        """The loop's ``parallel=True`` version: a copy of the function under its own name, so that numba's
        on-disk cache keeps the two versions apart (the cache is keyed by the function's qualified name)."""
        nb = _numba()
        twin = _renamed(self.loop, "_on_threads")
        return nb.njit(cache=True, parallel=True, **{**_LOOP_OPTIONS, **self._options})(twin)

    def _on_threads(self, *args: Any) -> Any:
        """A large call: the threaded version (compiled now on the first), or the one-thread version if it failed."""
        if self._threaded is None:
            try:
                self._threaded = self._compile_threaded()
                with collector_paused():
                    return self._threaded(*args)  # (numba's typing and lowering fail before anything runs)
            except Exception as exc:
                self._threads_failed = True
                self._threaded = None
                cause = _cause(exc)
                warnings.warn(
                    f"the compiled {self.name} could not run on threads ({cause}); it runs on one",
                    CompiledFallbackWarning,
                    stacklevel=3,
                )
                return self._jitted(*args)
        return self._threaded(*args)

    def _compile(self) -> Callable[..., Any] | None:
        nb = _numba()
        if isinstance(nb, Exception):
            return None
        _resolve_helpers(self.loop.__globals__, nb)  # the module's @inner helpers, compiled versions
        return nb.njit(cache=True, **{**_LOOP_OPTIONS, **self._options})(self.loop)

    def _fail(self, exc: BaseException) -> None:
        cause = _cause(exc)
        _failures[self.name] = cause
        warnings.warn(
            f"the compiled {self.name} could not be used ({cause}); the numpy path runs instead",
            CompiledFallbackWarning,
            stacklevel=3,
        )

    def _numpy(self, *args: Any) -> Any:
        return UNAVAILABLE if self.fallback is None else self.fallback(*args)

    def __call__(self, *args: Any) -> Any:
        if self._ready and (_selected if _selected is not None else enabled()):
            # the common case first: a few hundred ns per call matter here
            if self._over is not None and args[self._over].shape[0] > PARALLEL_CHUNK and not self._threads_failed:
                return self._on_threads(*args)
            return self._jitted(*args)
        if self.name in _failures or not enabled():
            return self._numpy(*args)
        try:  # the first call compiles (or loads the cache); a failure there falls back, once
            with collector_paused():
                self._jitted = self._jitted or self._compile()
                if self._jitted is None:
                    return self._numpy(*args)
                if _before_cold_compile and not cached_on_disk(self._jitted):
                    while _before_cold_compile:  # (meanfield._compiled.warmup: other processes start compiling too)
                        _before_cold_compile.pop(0)()
                large = self._over is not None and args[self._over].shape[0] > PARALLEL_CHUNK
                # a large first call runs on threads as every later one (the one-thread version, the same numbers,
                # compiles at the first small call): a million humans' first step no longer runs on one thread
                out = self._on_threads(*args) if large else self._jitted(*args)
        except Exception as exc:  # numba's typing/lowering errors, a cache it cannot write
            self._fail(exc)
            return self._numpy(*args)
        self._ready = True
        return out


@contextmanager
def collector_paused() -> Iterator[None]:
    """Python's cyclic garbage collector off for the block (as it was before, after it).

    Around a loop's first call, which compiles it (or reads numba's cache): compiling makes millions of short-lived
    Python objects, which set off the collector's full passes, each over every object of the process (the toolkit,
    numpy, scipy, numba: about 80 ms a pass).  The paper's first run made 8 of them, 0.7 s of its 7.4 s on one core;
    with the collector off while compiling, 1 (issue 45).  The cycles compiling leaves are collected by the next
    pass after the block; the peak memory of that first run grows by about 55 MB (270 → 325 MB).  The collector is
    per process: another thread's objects wait for their collection as long as the block lasts.
    """
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def compiled(
    fallback: Callable[..., Any] | None, parallel_over: str | None = None, **options: Any
) -> Callable[[Callable[..., Any]], CompiledLoop]:
    """Decorator: the loop below, compiled by numba (``cache=True``), with ``fallback`` its numpy twin.

    Parameters
    ----------
    fallback : callable or None
        The numpy implementation, same arguments, same result (to round-off).  None: the
        caller has its own numpy path and takes it when the call returns :data:`UNAVAILABLE`.
    parallel_over : str, optional
        The argument whose rows the loop's :func:`prange` loops split: above
        :data:`PARALLEL_CHUNK` rows the call runs a second, ``parallel=True`` version of the loop
        (:class:`CompiledLoop`).  None: one thread always.
    **options
        Passed to ``numba.njit`` (``fastmath`` is left off: the two paths must agree).  Loops
        use numpy's error model (``error_model="numpy"``: a division by zero gives inf/nan as
        in the numpy twin, and the loop carries no exception checks) unless told otherwise.
    """

    def wrap(loop: Callable[..., Any]) -> CompiledLoop:
        compiled_loop = CompiledLoop(loop, fallback, options, parallel_over)
        _loops.append(compiled_loop)
        return compiled_loop

    return wrap


def compiled_loops() -> list[CompiledLoop]:
    """Every compiled loop defined so far (for the tests that compare each with its fallback)."""
    return list(_loops)


NO_BOX = np.empty(0)
"""The ``box`` of :func:`euler_maruyama` and :func:`robot_euler` that folds no walls into the pass."""
