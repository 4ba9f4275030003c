"""The numba decorator of mpz's kernels and where their machine code is cached (issue 15.2).

numba compiles a kernel on its first call, a few tenths of a second each (about 4 s
for everything an encode needs, docs/cold-start.md). With a cache, only the first run
on a machine pays; the cache directory is chosen once per process, the first that
applies of:

1. ``MPZ_CACHE_DIR``, if set: that directory;
2. ``NUMBA_CACHE_DIR``, if set: numba's own setting, for every numba user;
3. ``__pycache__`` beside the sources, when it is writable (numba's default): a
   checkout, an editable install, a venv the user owns;
4. the user cache directory ``$XDG_CACHE_HOME/mpz/numba/VERSION`` (``~/.cache`` when
   XDG_CACHE_HOME is unset, ``~/Library/Caches`` on macOS, ``%LOCALAPPDATA%`` on
   Windows) when the package is read-only: a system or container install, where numba
   by itself would fall back to ``~/.cache/numba`` keyed by the install path;
5. none: each run compiles again, still correctly; ``mpz -v`` says so in one line
   (:func:`cache_note`). numba alone raises ``RuntimeError: cannot cache function``
   at import in this case, so ``import mpz`` failed with a read-only HOME.

The directory in 4 is keyed by mpz's version rather than by the install path, so a
second venv or a reinstall of the same version finds the kernels compiled.
numba's index still checks each entry against the source file's contents, the
kernel's bytecode and the CPU, so a stale or foreign entry is recompiled, never
loaded.

Shipped kernels (issue 15.2). When the directory above has no entry for a kernel, it is
looked up in ``mpz/_kernels``: the codec's kernels compiled by
``python -m mpz.tools.make_kernels`` for a baseline CPU of the build's platform (on
x86-64, ``x86-64-v2``: SSE4.2 and POPCNT, every x86-64 CPU since 2009, no AVX; elsewhere
LLVM's ``generic``), so that the first run after an install loads them instead of
compiling for seconds. They are used only where the build's configuration holds: a CPU
with the baseline's features (checked once per process), the same CPython minor version
(in the file names), the same numba version, the same target triple, and source files
with the same contents (numba's stamp is their SHA-256), checked entry by entry;
anywhere else the kernel compiles as before. Baseline code computes the same values: the
codec's shipped kernels are exact integer and IEEE code (no ``fastmath``), and run as fast
as host code within the noise (docs/cold-start.md). The one exception, marked
``ship=True``: the optimal partition's kernels (:mod:`mpz.fisher`, the summary chunk),
which compiled for 2.5-4 s on the first ``--summary`` (a newcomer's QA run, stop 62).
Their ``fastmath`` sums follow the code they compile to (FMA or not, the vector width), so
a host compile may cut a near tie otherwise; they are loaded from the shipped kernels
first, so that every machine the shipped kernels serve cuts it the same way, whatever its
own cache holds.
``MPZ_SHIPPED_KERNELS=0`` turns the lookup off.

Modules use :func:`njit` exactly as ``numba.njit`` (``from mpz._jit import njit``);
``cache=True`` means "cache where the policy says" instead of numba's own lookup.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
import functools
import json
import os
import sys
import tempfile
from typing import Any, TypeVar, cast

import numba

__all__ = ["CachePolicy", "njit", "kernel", "policy", "cache_note", "user_cache_root"]

_F = TypeVar("_F", bound=Callable[..., Any])

#: the package directory (…/site-packages/mpz or reference/mpz in a checkout)
PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))
#: the kernels shipped with the package (see the module docstring)
SHIPPED_DIR = os.path.join(PACKAGE_DIR, "_kernels")
#: set by ``mpz.tools.make_kernels`` in the process that compiles into SHIPPED_DIR
SHIP_ENV = "MPZ_SHIP_KERNELS"
#: "0" turns the shipped kernels off
SHIPPED_ENV = "MPZ_SHIPPED_KERNELS"


@dataclass(frozen=True)
class CachePolicy:
    """Where compiled kernels go: ``where`` names the rule that applied (see the module
    docstring): ``"MPZ_CACHE_DIR"``, ``"NUMBA_CACHE_DIR"``, ``"package"``, ``"user"`` or
    ``"off"``; ``path`` is the directory (None for ``"off"``); ``tried`` the directories
    found unwritable on the way."""

    where: str
    path: str | None
    tried: tuple[str, ...] = ()


def writable(path: str) -> bool:
    """True if ``path`` exists or can be created and a file can be written in it.

    The same test numba makes (a temporary file), so it also holds for root on a
    read-only mount, where permission bits say nothing.
    """
    try:
        os.makedirs(path, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError:
        return False
    return True


def user_cache_root(env: Mapping[str, str] | None = None, platform: str | None = None) -> str:
    """``$XDG_CACHE_HOME/mpz/numba`` (``~/.cache/mpz/numba``), or the macOS/Windows
    equivalent. A relative XDG_CACHE_HOME is ignored, as the XDG spec says."""
    env = os.environ if env is None else env
    platform = sys.platform if platform is None else platform
    home = env.get("HOME") or os.path.expanduser("~")
    if platform == "win32":
        base = env.get("LOCALAPPDATA") or os.path.join(home, "AppData", "Local")
    elif platform == "darwin":
        base = os.path.join(home, "Library", "Caches")
    else:
        xdg = env.get("XDG_CACHE_HOME", "")
        base = xdg if os.path.isabs(xdg) else os.path.join(home, ".cache")
    return os.path.join(base, "mpz", "numba")


def _version() -> str:
    try:
        from importlib.metadata import PackageNotFoundError, version
        try:
            return version("mpz")
        except PackageNotFoundError:
            return "unknown"
    except ImportError:  # pragma: no cover - Python >= 3.8 always has it
        return "unknown"


def decide(env: Mapping[str, str] | None = None, package_dir: str = PACKAGE_DIR,
           is_writable: Callable[[str], bool] | None = None,
           version: Callable[[], str] = _version) -> CachePolicy:
    """The cache policy for these settings (see the module docstring for the order);
    ``is_writable`` defaults to :func:`writable`, looked up when called. With
    ``MPZ_SHIP_KERNELS`` set (by ``mpz.tools.make_kernels``) the policy is ``"ship"``: the
    shippable kernels are compiled into ``package_dir/_kernels``."""
    env = os.environ if env is None else env
    is_writable = writable if is_writable is None else is_writable
    if env.get(SHIP_ENV):
        return CachePolicy("ship", os.path.join(package_dir, "_kernels"))
    tried: list[str] = []
    for where in ("MPZ_CACHE_DIR", "NUMBA_CACHE_DIR", "package", "user"):
        if where == "package":
            path = os.path.join(package_dir, "__pycache__")
        elif where == "user":
            path = os.path.join(user_cache_root(env), version())
        else:
            path = env.get(where, "")
            if not path:
                continue
        if is_writable(path):
            return CachePolicy(where, path, tuple(tried))
        tried.append(path)
    return CachePolicy("off", None, tuple(tried))


@functools.lru_cache(maxsize=1)
def policy() -> CachePolicy:
    """This process's cache policy, decided on first use (the first kernel defined)."""
    return decide()


def cache_note() -> str | None:
    """One line for ``-v`` when compiled kernels cannot be cached, else None."""
    p = policy()
    if p.where != "off":
        return None
    shipped = " (but those shipped with the package)" if shipped_cpu() is not None else ""
    return ("mpz: note: no writable cache directory for compiled kernels (tried "
            + ", ".join(p.tried) + f"): they are compiled on every run{shipped}; set "
            "MPZ_CACHE_DIR to a writable directory")


def shipped_enabled(env: Mapping[str, str] | None = None) -> bool:
    """True if kernels may be loaded from :data:`SHIPPED_DIR` in this process."""
    env = os.environ if env is None else env
    return env.get(SHIPPED_ENV, "1") != "0" and not env.get(SHIP_ENV)


@functools.lru_cache(maxsize=1)
def shipped_cpu() -> str | None:
    """The CPU name the shipped kernels were compiled for, or None when this process
    cannot use them: turned off, none shipped, shipped for other CPython versions or
    another numba (numba would reject every entry anyway), or a CPU without the features
    they need (the manifest lists them; code for them would fault here)."""
    if not shipped_enabled():
        return None
    try:
        with open(os.path.join(SHIPPED_DIR, "manifest.json"), encoding="utf-8") as fh:
            info = json.load(fh)
    except (OSError, ValueError):
        return None
    here = f"{sys.version_info[0]}.{sys.version_info[1]}"
    if here not in info.get("python", ()) or info.get("numba") != numba.__version__:
        return None                     # files for another CPython or numba: never loaded
    need = info.get("requires_features", [])
    if need:
        import llvmlite.binding as ll
        have = ll.get_host_cpu_features()
        if not all(have.get(f, False) for f in need):
            return None
    cpu = info.get("cpu")
    return cpu if isinstance(cpu, str) else None


def _relative_dir(py_file: str) -> str:
    """A kernel's source directory below the package root's parent (``mpz``, ``mpz/io``)."""
    top = os.path.dirname(PACKAGE_DIR)
    return os.path.relpath(os.path.dirname(os.path.abspath(py_file)), top)


# -- numba's cache, in a directory of ours ---------------------------------------------------
try:
    from numba.core.caching import (
        CompileResultCacheImpl,
        FunctionCache,
        _Cache,
        _CacheLocator,
        _SourceFileBackedLocatorMixin,
    )
except ImportError:  # pragma: no cover - a numba whose cache internals moved
    _DirCache: Any = None
    _ShippedCache: Any = None
    _Layered: Any = None
else:
    class _DirLocator(_SourceFileBackedLocatorMixin, _CacheLocator):
        """numba's source-file locator with the directory taken from :func:`policy`.

        Below it, kernels keep their path inside the package (``mpz/``), so two modules
        of the same name in different subpackages cannot share index files.
        """

        def __init__(self, py_func: Callable[..., Any], py_file: str):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            root = policy().path
            assert root is not None
            rel = _relative_dir(py_file)
            if rel.startswith(os.pardir):
                rel = self.get_suitable_cache_subpath(py_file)
            self._cache_path = os.path.join(root, rel)

        def get_cache_path(self) -> str:
            return self._cache_path

    class _DirCacheImpl(CompileResultCacheImpl):
        _locator_classes = [_DirLocator]

    class _DirCache(FunctionCache):  # type: ignore[no-redef]
        _impl_class = _DirCacheImpl

    class _ShippedLocator(_SourceFileBackedLocatorMixin, _CacheLocator):
        """The kernel's place in :data:`SHIPPED_DIR`, read-only (never written here)."""

        def __init__(self, py_func: Callable[..., Any], py_file: str):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._cache_path = os.path.join(SHIPPED_DIR, _relative_dir(py_file))

        def get_cache_path(self) -> str:
            return self._cache_path

        @classmethod
        def from_function(cls, py_func: Callable[..., Any], py_file: str) -> Any:
            return cls(py_func, py_file) if os.path.exists(py_file) else None

    class _ShippedCacheImpl(CompileResultCacheImpl):
        _locator_classes = [_ShippedLocator]

    class _ShippedCache(FunctionCache):  # type: ignore[no-redef]
        """Loads what make_kernels compiled for the baseline CPU (:func:`shipped_cpu`):
        the index key names that CPU with no extra features, whatever this process's."""

        _impl_class = _ShippedCacheImpl

        def _index_key(self, sig: Any, codegen: Any) -> Any:
            sig_, magic, hashes = super()._index_key(sig, codegen)
            return sig_, (magic[0], shipped_cpu(), ""), hashes

        def save_overload(self, sig: Any, data: Any) -> None:
            return None                 # shipped kernels are made by make_kernels only

    class _Layered(_Cache):  # type: ignore[no-redef]
        """The policy's cache (if any), then the shipped kernels: what numba's dispatcher
        calls (load_overload, save_overload, flush, cache_path). ``shipped_first``: the
        shipped kernel before the policy's cache, for a kernel whose values depend on the
        code it compiles to (``fastmath``): else a host-compiled entry in the user's cache
        (from a run with ``MPZ_SHIPPED_KERNELS=0``) changed a machine's output for good (a
        review of stop 62: a summary's partition on a near tie)."""

        def __init__(self, primary: Any, shipped: Any, shipped_first: bool = False):
            self.primary, self.shipped = primary, shipped
            self.order = (shipped, primary) if shipped_first else (primary, shipped)

        @property
        def cache_path(self) -> str:
            return str((self.primary or self.shipped).cache_path)

        def load_overload(self, sig: Any, target_context: Any) -> Any:
            for cache in self.order:
                hit = None if cache is None else cache.load_overload(sig, target_context)
                if hit is not None:
                    return hit
            return None

        def save_overload(self, sig: Any, data: Any) -> None:
            if self.primary is not None:
                self.primary.save_overload(sig, data)

        def enable(self) -> None:
            for c in (self.primary, self.shipped):
                if c is not None:
                    c.enable()

        def disable(self) -> None:
            for c in (self.primary, self.shipped):
                if c is not None:
                    c.disable()

        def flush(self) -> None:
            if self.primary is not None:
                self.primary.flush()


def _enable_cache(disp: Any, shippable: bool = True, exact: bool = True) -> None:
    """Attach the policy's cache to a dispatcher, with the shipped kernels behind it for a
    ``shippable`` kernel (in front of it unless ``exact``: :class:`_Layered`); leave it
    uncached if that fails."""
    p = policy()
    if p.where == "ship":               # make_kernels: compile into SHIPPED_DIR
        if shippable and _DirCache is not None:
            disp._cache = _DirCache(disp.py_func)
        return
    if p.where != "off":
        try:
            if p.where in ("MPZ_CACHE_DIR", "user") and _DirCache is not None:
                disp._cache = _DirCache(disp.py_func)
            else:
                disp.enable_caching()   # numba's own lookup: NUMBA_CACHE_DIR, __pycache__, …
        except RuntimeError:
            # "cannot cache function …: no locator available": the directory went away or
            # became read-only since policy() looked; compile without a cache
            pass
    if shippable and _Layered is not None and shipped_cpu() is not None:
        primary = getattr(disp, "_cache", None)
        has_primary = primary is not None and type(primary).__name__ != "NullCache"
        try:
            disp._cache = _Layered(primary if has_primary else None,
                                   _ShippedCache(disp.py_func), shipped_first=not exact)
        except RuntimeError:
            pass


def skip_blas_check() -> bool:
    """Spare this process numba's BLAS check; True if it will be spared.

    When numba loads its first kernel it imports ``numba.np.arraymath``, which asks once
    whether BLAS is there by importing ``scipy.linalg.cython_blas``: all of scipy.linalg,
    0.2 s of the first ``mpz decode`` of a short file (0.57 -> 0.39 s, issue 15.2), for a
    flag that only numba's own ``np.correlate`` and ``np.convolve`` read (a BLAS dot or a
    loop; no mpz kernel calls them, nor BLAS at all). Here the check finds no BLAS at
    once: ``numba.np.linalg.ensure_blas`` is replaced by a function that puts the original
    back and raises ImportError, which is what arraymath's check catches. Every later call
    (numba typing ``np.dot`` in a kernel) gets the original, so BLAS still works. Done
    only in mpz's own processes (:func:`mpz._worker.own_process`), where no other code
    runs; anything unexpected in numba leaves its check as it is."""
    if "numba.np.arraymath" in sys.modules:
        return False                    # checked already
    try:
        import numba.np.linalg as linalg
        original = linalg.ensure_blas
    except (ImportError, AttributeError):
        return False

    def skipped() -> None:
        linalg.ensure_blas = original
        raise ImportError("not checked in an mpz command (mpz._jit.skip_blas_check)")
    linalg.ensure_blas = skipped
    return True


# mpz._worker is the package's first import (mpz/__init__.py); a _jit loaded on its own,
# as some tests do, has none and keeps numba's check
_WORKER: Any = sys.modules.get("mpz._worker")
if _WORKER is not None and _WORKER.own_process():
    skip_blas_check()


def njit(*args: Any, **options: Any) -> Any:
    """``numba.njit`` with ``cache=True`` meaning "where :func:`policy` says".

    Used as ``@njit``, ``@njit(cache=True, ...)`` or ``@njit(signature, cache=True)``;
    with signatures the kernel is compiled (or loaded from the cache) here, as numba does.
    ``ship=True``: ship a kernel that ``fastmath`` or ``parallel`` would keep out (or that
    calls one with ``fastmath``), and load the shipped code before the policy's cache.
    """
    if len(args) == 1 and not options and callable(args[0]) and not isinstance(args[0], str):
        return numba.njit(args[0])
    cache = bool(options.pop("cache", False))
    sigs = args[0] if args else None
    # fastmath may contract differently on another CPU, so such kernels, and the parallel
    # ones, are not shipped unless they say ship=True: the summary's, whose values follow
    # the code they compile to (their own fastmath, or a callee's). Those load the shipped
    # code first, so that a machine's output does not follow its cache (module docstring)
    ship = options.pop("ship", None)
    shippable = bool(ship) if ship is not None else \
        not options.get("fastmath") and not options.get("parallel")
    exact = ship is None

    def wrap(fn: Callable[..., Any]) -> Any:
        disp = numba.njit(**options)(fn)
        if cache:
            _enable_cache(disp, shippable, exact)
        if sigs is not None:
            for sig in (sigs if isinstance(sigs, list | tuple) else [sigs]):
                disp.compile(sig)
            disp.disable_compile()
        return disp
    return wrap


def kernel(fn: _F) -> _F:
    """``njit(cache=True)``, keeping the kernel's Python signature for type checkers.

    numba's ``njit`` is not annotated, so a kernel it decorates would be ``Any`` to mypy
    and no call to it would be checked. The dispatcher numba returns is called exactly
    like ``fn``.
    """
    return cast(_F, njit(cache=True)(fn))


def will_compile(disp: Any) -> bool:
    """True if the kernel ``disp`` has nothing to load on its first call in this process, so
    that it will be compiled: no index file in the policy's cache, and none among the
    shipped kernels when they serve this process (:func:`shipped_cpu`). numba's cache
    layout is not a public API, so anything unexpected counts as "will not compile"."""
    cache: Any = getattr(disp, "_cache", None)
    if _Layered is not None and isinstance(cache, _Layered):
        caches = [cache.primary, cache.shipped if shipped_cpu() is not None else None]
    else:
        caches = [cache]
    for c in caches:
        if c is None:
            continue
        try:
            index = c._cache_file._index_path
        except AttributeError:
            return False
        if os.path.exists(index):
            return False
    return True
