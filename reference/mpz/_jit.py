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

Modules use :func:`njit` exactly as ``numba.njit`` (``from mpz._jit import njit``);
``cache=True`` means "cache where the policy says" instead of numba's own lookup.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
import functools
import os
import sys
import tempfile
from typing import Any, TypeVar, cast

import numba

__all__ = ["CachePolicy", "njit", "kernel", "policy", "cache_note", "user_cache_root"]

_F = TypeVar("_F", bound=Callable[..., Any])

#: the package directory (…/site-packages/mpz or reference/mpz in a checkout)
PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))


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
    ``is_writable`` defaults to :func:`writable`, looked up when called."""
    env = os.environ if env is None else env
    is_writable = writable if is_writable is None else is_writable
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
    return ("mpz: note: no writable cache directory for compiled kernels (tried "
            + ", ".join(p.tried) + "): they are compiled on every run; set "
            "MPZ_CACHE_DIR to a writable directory")


# -- numba's cache, in a directory of ours ---------------------------------------------------
try:
    from numba.core.caching import (
        CompileResultCacheImpl,
        FunctionCache,
        _CacheLocator,
        _SourceFileBackedLocatorMixin,
    )
except ImportError:  # pragma: no cover - a numba whose cache internals moved
    _DirCache: Any = None
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
            top = os.path.dirname(PACKAGE_DIR)
            rel = os.path.relpath(os.path.dirname(os.path.abspath(py_file)), top)
            if rel.startswith(os.pardir):
                rel = self.get_suitable_cache_subpath(py_file)
            self._cache_path = os.path.join(root, rel)

        def get_cache_path(self) -> str:
            return self._cache_path

    class _DirCacheImpl(CompileResultCacheImpl):
        _locator_classes = [_DirLocator]

    class _DirCache(FunctionCache):  # type: ignore[no-redef]
        _impl_class = _DirCacheImpl


def _enable_cache(disp: Any) -> None:
    """Attach the policy's cache to a dispatcher; leave it uncached if that fails."""
    p = policy()
    if p.where == "off":
        return
    try:
        if p.where in ("MPZ_CACHE_DIR", "user") and _DirCache is not None:
            disp._cache = _DirCache(disp.py_func)
        else:
            disp.enable_caching()       # numba's own lookup: NUMBA_CACHE_DIR, __pycache__, …
    except RuntimeError:
        # "cannot cache function …: no locator available": the directory went away or
        # became read-only since policy() looked; compile without a cache
        pass


def njit(*args: Any, **options: Any) -> Any:
    """``numba.njit`` with ``cache=True`` meaning "where :func:`policy` says".

    Used as ``@njit``, ``@njit(cache=True, ...)`` or ``@njit(signature, cache=True)``;
    with signatures the kernel is compiled (or loaded from the cache) here, as numba does.
    """
    if len(args) == 1 and not options and callable(args[0]) and not isinstance(args[0], str):
        return numba.njit(args[0])
    cache = bool(options.pop("cache", False))
    sigs = args[0] if args else None

    def wrap(fn: Callable[..., Any]) -> Any:
        disp = numba.njit(**options)(fn)
        if cache:
            _enable_cache(disp)
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
