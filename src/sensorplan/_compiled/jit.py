"""The compiled kernels: numba's just-in-time ones, or ahead-of-time ones when they are built.

Every kernel of the package is written once, as a Python function decorated with
:func:`njit` (this module's, with numba's options). Calling it runs compiled code from one
of two places, the same source compiled by the same compiler:

* **ahead of time** (:mod:`sensorplan._compiled.aot`): an extension module holding the kernels the
  planners call, for the argument types they are called with. It needs numpy only, so a
  process that finds every call there (``sensorplan plan``) never imports numba: it starts
  in a fraction of a second instead of about one. It is built once (``sensorplan plan``
  builds it the first time, in about a minute) and cached next to numba's cache.
* **just in time**: numba's dispatcher, for every other kernel or argument type. The first
  such call imports numba (about a second with a warm cache) and from then on every kernel
  of the process runs numba's, as before the ahead-of-time build existed.

Both give the same numbers bit for bit (the planner reference tests run under each).

numba's on-disk cache, and what happens when nowhere is writable:
:mod:`sensorplan._compiled.cache`.
"""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from .cache import ensure_cache, first_run_notice

_KERNELS: list[Kernel] = []
#: numba's dispatchers of the kernels defined after numba was loaded (the others are
#: ``_KERNELS``' own).
_LATE: list[Any] = []
_NUMBA_GLOBALS: dict[str, Callable[[], dict[str, Any]]] = {}
_ACTIVE = False
_LOCK = threading.Lock()
_UNSET: Any = object()


#: The array dtypes and scalar types the ahead-of-time tables hold, by their names there
#: (a non-native byte order is a different dtype: it is not found).
_ARRAY_CHARS = {np.dtype(np.float64): "d", np.dtype(np.int64): "l", np.dtype(np.bool_): "?"}
_SCALARS = {float: "f", np.float64: "f", bool: "b", np.bool_: "b", np.int64: "i"}


def arg_key(args: tuple) -> tuple | None:
    """The argument types of a call as the ahead-of-time tables name them, or None for a
    type they never hold (the call then goes to numba).

    Arrays: ``(dtype char, ndim)`` of aligned, C-contiguous float64, int64 or bool arrays
    (numba's ``Array(dtype, ndim, 'C')``), ``(dtype char, ndim, "r")`` if read-only;
    scalars: ``"b"`` (bool), ``"i"`` (int64), ``"f"`` (float64), as numba types them.
    Called for every kernel call: written for speed (dictionary lookups, one flags object).
    """
    key: list = []
    add = key.append
    for a in args:
        t = type(a)
        if t is np.ndarray:
            f = a.flags
            char = _ARRAY_CHARS.get(a.dtype)
            if char is None or not (f.c_contiguous and f.aligned):
                return None
            add((char, a.ndim) if f.writeable else (char, a.ndim, "r"))
        elif t is int:
            if not -(2 ** 63) <= a < 2 ** 63:
                return None
            add("i")
        else:
            name = _SCALARS.get(t)
            if name is None:
                return None
            add(name)
    return tuple(key)


class Kernel:
    """A compiled kernel: the ahead-of-time build when it holds the call's argument types,
    numba's dispatcher otherwise (see the module docstring)."""

    def __init__(self, py_func: Callable, options: dict[str, Any]) -> None:
        self.py_func = py_func
        self.options = options
        self.__name__ = py_func.__name__
        self.__qualname__ = py_func.__qualname__
        self.__module__ = py_func.__module__
        self.__doc__ = py_func.__doc__
        self.__wrapped__ = py_func
        self._aot: dict | None = _UNSET
        self._dispatcher: Any = None

    def __call__(self, *args: Any) -> Any:
        aot = self._aot
        if aot is _UNSET:
            from . import aot as _aot

            _aot.attach(_KERNELS)
            aot = self._aot
        if aot:
            fn = aot.get(arg_key(args))
            if fn is not None:
                return fn(*args)
        return self.dispatcher(*args)

    @property
    def dispatcher(self) -> Any:
        """numba's dispatcher of this kernel (imports numba on first use)."""
        if self._dispatcher is None:
            activate()
        return self._dispatcher

    def __repr__(self) -> str:
        return f"<kernel {self.__module__}.{self.__qualname__}>"


def njit(*args: Any, **options: Any) -> Any:
    """``numba.njit`` for the package's kernels: ``@njit`` or ``@njit(**options)``.

    Before numba is loaded it returns a :class:`Kernel`; afterwards numba's dispatcher.
    """
    def wrap(py_func: Callable) -> Any:
        if _ACTIVE:
            import numba

            dispatcher = numba.njit(**options)(py_func)
            _LATE.append(dispatcher)
            return dispatcher
        kernel = Kernel(py_func, options)
        _KERNELS.append(kernel)
        return kernel

    if args and callable(args[0]):
        return wrap(args[0])
    return wrap


def numba_globals(module: str, make: Callable[[], dict[str, Any]]) -> None:
    """Names that ``module``'s kernels use from numba (types, typed containers): ``make()``
    is set into the module's namespace when numba is loaded, before any kernel compiles."""
    _NUMBA_GLOBALS[module] = make
    if _ACTIVE:
        vars(sys.modules[module]).update(make())


def activate(patch: bool = True) -> None:
    """Load numba and give every kernel its dispatcher (once per process).

    The package's modules then hold the dispatchers themselves in place of the
    :class:`Kernel` objects (``patch``), so that Python calls go straight to numba. With
    ``patch`` False they keep the kernels (whose calls can then be watched, as
    ``scripts/aot_signatures.py`` does) and numba types a kernel as its dispatcher.
    """
    global _ACTIVE
    if _ACTIVE:
        return
    with _LOCK:                     # threads of one process (a threaded Dask worker)
        if _ACTIVE:
            return
        import numba

        if ensure_cache() is None or os.environ.get("NUMBA_CACHE_DIR"):
            first_run_notice()      # not when nothing can be cached: every run compiles then
        for owner, make in _NUMBA_GLOBALS.items():
            vars(sys.modules[owner]).update(make())
        for kernel in _KERNELS:
            kernel._dispatcher = numba.njit(**kernel.options)(kernel.py_func)
            kernel._aot = None
        _ACTIVE = True              # only now: every kernel has its dispatcher
        if not patch:
            from numba.core.typing.typeof import typeof_impl

            typeof_impl.register(Kernel)(lambda val, c: typeof_impl(val._dispatcher, c))
            return
        for name, module in list(sys.modules.items()):
            if name == "sensorplan" or name.startswith("sensorplan."):
                space = vars(module)
                for attr, value in list(space.items()):
                    if isinstance(value, Kernel):
                        space[attr] = value._dispatcher


def is_active() -> bool:
    """Whether numba is loaded and the kernels run numba's dispatchers."""
    return _ACTIVE


def dispatchers() -> list[Any]:
    """numba's dispatchers of every kernel of the package defined so far (none before
    :func:`activate`)."""
    if not _ACTIVE:
        return []
    return [k._dispatcher for k in _KERNELS] + list(_LATE)


def loaded() -> int:
    """How many compiled versions (one per argument types) numba's dispatchers hold in this
    process, compiled or loaded from the disk cache: a count that grows exactly when a call
    waits for numba (0 before :func:`activate`)."""
    return sum(len(d.overloads) for d in dispatchers())


__all__ = ["Kernel", "activate", "arg_key", "dispatchers", "is_active", "loaded", "njit",
           "numba_globals"]
