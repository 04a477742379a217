"""One source for each law, run interpreted or compiled with numba.

The laws of :mod:`companion.control` are plain Python functions over floats and tuples (NumPy
arrays of shape ``(N,)`` work too, in Python). :func:`jitable` marks a function that numba may
compile when a compiled kernel calls it; it returns the function unchanged, so importing the
control core never imports numba: the companion runs these functions interpreted, with nothing
but NumPy (docs/benchmarks.md, "the companion's loop", has the measurement behind that choice).

A kernel (the simulator's vehicle step and its batch loop, ``sitl``) is built with
:func:`kernel`, which calls :func:`register_with_numba` first: every :func:`jitable` function
becomes callable from compiled code (``numba.extending.register_jitable``), each of the few
element-wise helpers that pick float-or-array at run time (:func:`float_form`) gets its float
implementation, and each entry that stands for several laws (:func:`chosen_by_type`: one step
function per type of constants) calls the law of its argument's type, chosen when the compiled
caller is compiled (``numba.extending.overload``). ``NUMBA_DISABLE_JIT=1`` turns every kernel
back into its Python function, so the same source runs both ways (``tests/sitl/test_compiled.py``
holds the two within 1e-12 over an E3 flight).

Compiled kernels are cached on disk (``cache=True``) in a folder named after a digest of the
sources they are compiled from (:func:`cache_dir`): numba's own cache only watches the file of
the kernel itself, so an edited law in another file would otherwise run stale code. Processes
that need the same kernel at once compile it once (:func:`compile_once`): the test suite's
workers each compiled every kernel they flew on an empty cache.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
from pathlib import Path
from typing import Any, Callable, Mapping, TypeVar

__all__ = ["jitable", "chosen_by_type", "float_form", "lanewise", "kernel", "register_with_numba", "numba_available",
           "cache_dir", "compile_once", "SOURCES", "depends_on", "KERNEL_OPT", "float_forms", "lanewise_functions"]

F = TypeVar("F", bound=Callable[..., Any])

_JITABLE: list[Callable[..., Any]] = []
_FLOAT_FORMS: list[tuple[Callable[..., Any], Callable[..., Any]]] = []
_LANEWISE: list[Callable[..., Any]] = []
_BY_TYPE: list[tuple[Callable[..., Any], Mapping[type, Callable[..., Any]]]] = []
_registered = (0, 0, 0, 0)

SOURCES: list[Path] = [Path(__file__).parent]
"""Folders (or files) whose ``.py`` sources compiled kernels depend on (:func:`depends_on`)."""


def depends_on(path: str | Path) -> None:
    """Kernels built from now on also depend on the sources in ``path`` (a folder or a file)."""
    p = Path(path).resolve()
    if p not in SOURCES:
        SOURCES.append(p)


def jitable(fn: F) -> F:
    """Mark ``fn`` as compilable by numba when a kernel calls it; returns ``fn`` itself."""
    _JITABLE.append(fn)
    return fn


def chosen_by_type(laws: Mapping[type, Callable[..., Any]]) -> Callable[[F], F]:
    """Mark the decorated ``fn(c, ...)`` as the entry to ``laws[type(c)](c, ...)``: ``c`` is the
    constants of one of several laws, each a NamedTuple type of its own. Interpreted, ``fn``'s body
    makes the choice; compiled, it is made once, from ``c``'s type, when the caller is compiled, so a
    kernel is specialised on the law it runs and the others cost it nothing."""

    def wrap(fn: F) -> F:
        _BY_TYPE.append((fn, laws))
        return fn

    return wrap


def float_form(impl: Callable[..., Any]) -> Callable[[F], F]:
    """``impl`` is what the decorated float-or-array helper computes for floats, in compiled code.

    Only the element-wise primitives (``sqrt``, ``clip``, ``where`` ...) have one: they choose
    between :mod:`math` and NumPy by the argument's type, which numba cannot ask at run time.
    """

    def wrap(fn: F) -> F:
        _FLOAT_FORMS.append((fn, impl))
        return fn

    return wrap


def lanewise(fn: F) -> F:
    """Mark ``fn``, a function of numbers, as applied vehicle by vehicle when a compiled batch calls
    it with lanes (``sitl.plant.lanes``): the noise's draws, whose loops and integer hashing
    have no element-wise form. Compiled for numbers like :func:`jitable`; returns ``fn`` itself."""
    _LANEWISE.append(fn)
    return fn


def float_forms() -> list[tuple[Callable[..., Any], Callable[..., Any]]]:
    """Every :func:`float_form` helper with its float implementation."""
    return list(_FLOAT_FORMS)


def lanewise_functions() -> list[Callable[..., Any]]:
    """Every :func:`lanewise` function."""
    return list(_LANEWISE)


def numba_available() -> bool:
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def _digest() -> str:
    """Of every source file, in path order: the same whichever module called depends_on first
    (the import order differs between processes; the cache folder must not)."""
    h = hashlib.sha256()
    files: set[Path] = set()
    for src in SOURCES:
        files.update(src.rglob("*.py") if src.is_dir() else [src])
    for f in sorted(files):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def cache_dir() -> Path:
    """Where compiled kernels are cached: ``$NUMBA_CACHE_DIR`` (or ``~/.cache/ismdo-numba``)
    then a folder per digest of :data:`SOURCES`, so any edit of a law recompiles."""
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "ismdo-numba")
    return Path(base) / _digest()


def compile_once(dispatcher: Any, *args: Any) -> None:
    """Have ``dispatcher`` (a :func:`kernel`) compiled for ``args``' types before they are flown:
    loaded from the disk cache, or compiled and saved there by the first of the processes that
    ask for it at once while the others wait for it under a file lock, then load it. (A
    :func:`kernel` compiles on its first call all the same; this keeps two processes from
    compiling the same kernel side by side. Nothing happens interpreted, or once compiled.)"""
    typeof = getattr(dispatcher, "typeof_pyval", None)
    if typeof is None:  # numba absent or disabled: a plain function
        return
    signature = tuple(typeof(a) for a in args)
    if signature in dispatcher.overloads:
        return
    name = f"{dispatcher.py_func.__module__}.{dispatcher.py_func.__qualname__}.lock"
    try:
        # the folder numba keeps this kernel's cache in (fixed when the kernel was built; cache_dir()
        # now could differ: it digests the sources of the modules imported so far)
        folder = Path(getattr(dispatcher._cache, "_cache_path", None) or cache_dir())
        folder.mkdir(parents=True, exist_ok=True)
        lock = open(folder / name, "w")
    except OSError:  # no cache folder to write (read-only home): compile here, as numba would
        dispatcher.compile(signature)
        return
    with lock, _locked(lock):
        dispatcher.compile(signature)


@contextlib.contextmanager
def _locked(f: Any) -> Any:
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock, each process compiles as numba would
        yield
        return
    fcntl.flock(f, fcntl.LOCK_EX)
    try:
        yield
    finally:
        fcntl.flock(f, fcntl.LOCK_UN)


def register_with_numba() -> None:
    """Make every :func:`jitable` function, :func:`float_form` and :func:`chosen_by_type` entry
    callable from compiled code (those marked since the last call: a module imported later
    registers its own)."""
    global _registered
    from numba.extending import overload, register_jitable

    for fn, impl in _FLOAT_FORMS[_registered[0]:]:
        overload(fn, jit_options={}, strict=False)(_returning(impl))
    for fn in _JITABLE[_registered[1]:]:
        register_jitable(fn)
    for fn in _LANEWISE[_registered[2]:]:
        overload(fn, jit_options={}, strict=False)(_returning(fn))
    for fn, laws in _BY_TYPE[_registered[3]:]:
        overload(fn, jit_options={}, strict=False)(_law_of_type(laws))
    _registered = (len(_FLOAT_FORMS), len(_JITABLE), len(_LANEWISE), len(_BY_TYPE))


def _law_of_type(laws: Mapping[type, Callable[..., Any]]) -> Callable[..., Any]:
    """The typer of a :func:`chosen_by_type` entry: the law of the first argument's NamedTuple class
    (the same class whether its numbers are floats or lanes)."""
    def typer(c: Any, *args: Any) -> Callable[..., Any] | None:
        return laws.get(getattr(c, "instance_class", None))  # type: ignore[arg-type]

    return typer


def _returning(impl: Callable[..., Any]) -> Callable[..., Any]:
    """The typer of a float implementation: it declines lanes (a batch's values, whose types say
    ``lanes``), which their own overloads serve (``sitl.plant.lanes``)."""
    def typer(*args: Any) -> Callable[..., Any] | None:
        if any(getattr(a, "lanes", False) for a in args):
            return None
        return impl

    return typer


KERNEL_OPT = "1"
"""LLVM's optimisation level for the kernels (unless ``NUMBA_OPT`` says otherwise). Measured on the
E3 kernel (docs/benchmarks.md, "cold compile"): level 1 compiles in 26 s where numba's default 3
takes 33 s, and the compiled vehicle runs as fast (within the host's noise, one vehicle and
batches); level 0 is no faster to compile and runs 7x slower."""


def kernel(fn: F | None = None, *, nogil: bool = False) -> Any:
    """Compile ``fn`` with numba (``nopython``, ``cache=True``; ``nogil``: it releases the GIL, so
    Python threads can run it at once), or return it as it is when numba is not installed (the
    simulator then runs interpreted, slowly but with the same numbers)."""

    def build(f: F) -> Any:
        if not numba_available():
            return f
        os.environ.setdefault("NUMBA_OPT", KERNEL_OPT)
        import numba

        numba.core.config.reload_config()  # reads NUMBA_OPT again if numba was imported before
        register_with_numba()
        # numba reads the folder when a cached kernel is created (NUMBA_CACHE_DIR is the base)
        numba.config.CACHE_DIR = str(cache_dir())  # type: ignore[attr-defined]
        return numba.njit(cache=True, nogil=nogil, error_model="numpy")(f)

    return build(fn) if fn is not None else build
