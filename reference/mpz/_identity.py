"""Which mpz this is: its version and a fingerprint of its own Python source.

``mpz.__version__`` is the same for every development checkout between two releases, so two
checkouts of different code (other encoders, other bytes) had the same version.
:func:`identity` adds a digest of the package's ``*.py`` files; :func:`mpz.identity` is the
public name. The ``--scheduler`` check of a corpus run (:mod:`mpz.corpus`) compares it
between the driver and each worker.
"""
from __future__ import annotations

from collections.abc import Iterable
import functools
import hashlib
import importlib.util
import os

#: the subpackages that a checkout keeps in other source roots (pyproject.toml's
#: ``package-dir``, docs/layout.md) and a wheel installs inside the ``mpz`` folder, by their
#: path below it; tests/test_identity.py checks this list against pyproject.toml
ELSEWHERE = ("spec", "tools", "conformance", "conformance/vectors")
#: hex digits of the source digest that :func:`identity` shows (48 bits)
DIGITS = 12


def source_digest(roots: Iterable[tuple[str, str]]) -> str:
    """The sha256 (hex) of the ``*.py`` files under the folders ``roots``, given as
    ``(prefix, folder)``: each file is named by ``prefix`` and its path below its folder
    (``/`` separators), and the names are taken in sorted order, each as its UTF-8 bytes,
    a NUL, its length in bytes (decimal), a NUL and its bytes. ``__pycache__`` and hidden
    files and folders (an editor's ``.#name.py`` lock) are left out, and so is everything
    not named ``*.py`` (the compiled kernels, data); a name given twice is read once. A
    file that cannot be read counts as the words of its error, so the digest is still
    made, and differs."""
    files: dict[str, str] = {}
    for prefix, root in roots:
        for folder, subfolders, names in os.walk(root):
            subfolders[:] = [d for d in subfolders
                             if d != "__pycache__" and not d.startswith(".")]
            below = os.path.relpath(folder, root).replace(os.sep, "/")
            for name in names:
                if name.endswith(".py") and not name.startswith("."):
                    rel = prefix + (name if below == "." else f"{below}/{name}")
                    files.setdefault(rel, os.path.join(folder, name))
    digest = hashlib.sha256()
    for rel in sorted(files):
        try:
            with open(files[rel], "rb") as fh:
                data = fh.read()
        except OSError as exc:
            data = f"unreadable: {exc.strerror or exc}".encode()
        digest.update(rel.encode("utf-8", "surrogateescape") + b"\0"
                      + str(len(data)).encode() + b"\0" + data)
    return digest.hexdigest()


def source_roots() -> list[tuple[str, str]]:
    """The folders of this mpz's Python source, as :func:`source_digest` takes them: the
    ``mpz`` package's own folder, and each subpackage of :data:`ELSEWHERE` found outside
    it (a checkout's other source roots; a wheel has them inside it). Each is named by
    its path in the installed package, so that a checkout and the wheel built from it
    have the same digest. Finding a subpackage imports its parent package, not itself."""
    top = os.path.dirname(os.path.abspath(__file__))
    roots = [("", top)]
    real_top = os.path.realpath(top)
    for below in ELSEWHERE:
        try:
            spec = importlib.util.find_spec("mpz." + below.replace("/", "."))
        except (ImportError, ValueError):
            continue
        for folder in (spec.submodule_search_locations or []) if spec is not None else []:
            real = os.path.realpath(folder)
            if os.path.commonpath([real, real_top]) != real_top:   # not walked already
                roots.append((below + "/", folder))
    return roots


@functools.cache
def source_fingerprint() -> str:
    """The first :data:`DIGITS` hex digits of :func:`source_digest` over
    :func:`source_roots`: computed once per process (about 4 ms for mpz's ~90 files, 2 MB)."""
    return source_digest(source_roots())[:DIGITS]


def identity() -> str:
    """This mpz: its version and a fingerprint of its own Python source, for example
    ``"0.1.0 (source 1a2b3c4d5e6f)"``.

    ``mpz.__version__`` changes at releases only, so every development checkout between
    two had the same one, whatever its encoder. The fingerprint is the start (12 hex
    digits) of a sha256 over every ``*.py`` file of the installed package, each named by
    its path inside it (:func:`mpz._identity.source_digest`; not ``__pycache__``, not the
    compiled kernels), computed once per process, in a few milliseconds.

    A release carries it too, not only a checkout: a release whose files were edited after
    it was installed is the same version of other code. The same wheel installed twice
    has the same fingerprint, and so does the checkout it was built from (a checkout's
    ``spec/``, ``tools/`` and ``conformance/`` are named by their path in the wheel).

    ``mpz encode --scheduler`` compares it between the command and each Dask worker, and
    each row of a corpus index records its writer's (``mpz_version``). An mpz older than
    this function has its version alone, which never equals an identity.
    """
    import mpz
    return f"{mpz.__version__} (source {source_fingerprint()})"
