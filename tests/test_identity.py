"""mpz.identity(): the version and a fingerprint of the package's own Python source, which
``mpz encode --scheduler`` compares between the command and its Dask workers (every
development checkout had the version 0.1.0, whatever its code)."""
from __future__ import annotations

import importlib.util
import os
from pathlib import Path
import re
import subprocess
import sys
import tomllib

import pytest

import mpz
from mpz._identity import DIGITS, ELSEWHERE, source_digest, source_fingerprint, source_roots

REPO = Path(__file__).resolve().parents[1]


def _tree(root: Path) -> Path:
    (root / "sub").mkdir(parents=True)
    (root / "__init__.py").write_text("x = 1\n")
    (root / "sub" / "mod.py").write_text("y = 2\n")
    (root / "data.json").write_text("{}")
    return root


def test_the_digest_changes_with_a_files_bytes_and_name_and_with_a_new_file(tmp_path):
    root = _tree(tmp_path / "pkg")
    first = source_digest([("", str(root))])
    assert re.fullmatch("[0-9a-f]{64}", first)
    assert source_digest([("", str(root))]) == first                # stable
    (root / "sub" / "mod.py").write_text("y = 3\n")                  # same length, one byte
    edited = source_digest([("", str(root))])
    assert edited != first
    (root / "sub" / "mod.py").write_text("y = 2\n")
    assert source_digest([("", str(root))]) == first                # the bytes, not the time
    (root / "sub" / "mod.py").rename(root / "sub" / "other.py")      # same bytes, other name
    assert source_digest([("", str(root))]) not in (first, edited)
    (root / "sub" / "other.py").rename(root / "sub" / "mod.py")
    (root / "new.py").write_text("")                                 # an empty new module
    assert source_digest([("", str(root))]) != first


def test_the_digest_leaves_out_pycache_hidden_files_and_everything_not_python(tmp_path):
    root = _tree(tmp_path / "pkg")
    first = source_digest([("", str(root))])
    (root / "__pycache__").mkdir()
    (root / "__pycache__" / "mod.cpython-311.pyc").write_bytes(b"\0" * 16)
    (root / "__pycache__" / "stray.py").write_text("z = 3\n")
    (root / "sub" / "__pycache__").mkdir()
    (root / "sub" / "__pycache__" / "kernel.nbi").write_bytes(b"k")  # numba's cache
    (root / "kernel.nbc").write_bytes(b"compiled")                  # shipped kernels
    (root / "data.json").write_text('{"other": 1}')
    (root / "notes.pyc").write_bytes(b"\0")
    (root / ".#mod.py").symlink_to("nowhere")                        # an editor's lock
    (root / ".hidden").mkdir()
    (root / ".hidden" / "x.py").write_text("")
    assert source_digest([("", str(root))]) == first


def test_files_are_named_by_their_path_in_the_installed_package(tmp_path):
    """A checkout keeps spec/, tools/ and conformance/ in other folders than a wheel does:
    the same files give the same digest in both layouts, not in another place."""
    one = tmp_path / "wheel" / "mpz"
    (one / "spec").mkdir(parents=True)
    (one / "__init__.py").write_text("")
    (one / "spec" / "grammar.py").write_text("G = 1\n")
    two = tmp_path / "checkout"
    (two / "reference" / "mpz").mkdir(parents=True)
    (two / "spec" / "mpz" / "spec").mkdir(parents=True)
    (two / "reference" / "mpz" / "__init__.py").write_text("")
    (two / "spec" / "mpz" / "spec" / "grammar.py").write_text("G = 1\n")
    wheel = source_digest([("", str(one))])
    checkout = source_digest([("", str(two / "reference" / "mpz")),
                              ("spec/", str(two / "spec" / "mpz" / "spec"))])
    assert wheel == checkout
    # given twice (a wheel's subpackage found inside the package): read once
    assert source_digest([("", str(one)), ("spec/", str(one / "spec"))]) == wheel
    assert source_digest([("", str(two / "reference" / "mpz")),
                          ("tools/", str(two / "spec" / "mpz" / "spec"))]) != wheel


def test_the_subpackages_outside_the_package_folder_are_those_of_pyproject():
    """ELSEWHERE names every subpackage that pyproject.toml maps to its own folder: a
    package-dir entry added without it would leave its files out of a checkout's digest."""
    dirs = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-dir"]
    assert {"mpz." + below.replace("/", ".") for below in ELSEWHERE} == set(dirs) - {"mpz"}


def test_the_identity_is_the_version_and_the_fingerprint_of_every_source_root():
    found = source_roots()
    top = Path(mpz.__file__).resolve().parent
    assert found[0] == ("", str(Path(mpz.__file__).parent.absolute()))
    # a checkout's other source roots, named by their path in a wheel; none in a wheel
    spec = importlib.util.find_spec("mpz.spec")
    assert spec is not None and spec.submodule_search_locations
    inside = Path(spec.submodule_search_locations[0]).resolve().is_relative_to(top)
    assert {p for p, _ in found[1:]} == (set() if inside else {b + "/" for b in ELSEWHERE})
    fp = source_fingerprint()
    assert re.fullmatch(f"[0-9a-f]{{{DIGITS}}}", fp)
    assert fp == source_digest(found)[:DIGITS] == source_fingerprint()
    assert mpz.identity() == f"{mpz.__version__} (source {fp})" == mpz.identity()
    assert "identity" in mpz.__all__


def test_an_installed_copy_has_the_checkouts_identity_and_an_edited_one_another(
        installed_copy):
    """The identity a process reports that imports a wheel-like copy of this mpz (one
    folder, the subpackages inside it): the checkout's, until one file of it is edited,
    when the version stays and the fingerprint changes."""
    def reported() -> str:
        env = dict(os.environ, PYTHONPATH=str(installed_copy.parent), PYTHONDONTWRITEBYTECODE="1")
        proc = subprocess.run([sys.executable, "-c", "import mpz; print(mpz.__file__); "
                               "print(mpz.identity())"], capture_output=True, text=True,
                              env=env, timeout=120, check=True, cwd=installed_copy.parent)
        where, said = proc.stdout.splitlines()
        assert Path(where).parent == installed_copy
        return said

    assert reported() == mpz.identity()
    smooth = installed_copy / "smooth.py"
    smooth.write_text(smooth.read_text() + "\n# edited\n")
    other = reported()
    assert other != mpz.identity() and other.startswith(f"{mpz.__version__} (source ")


def test_the_fingerprint_is_computed_once_per_process(monkeypatch):
    """Computed once per process, on the first check of a corpus run and in each worker;
    every later mpz.identity() is the cached value. Its time (a few ms) is measured by
    bench/bench_coldstart.py: this test asserted it, and failed under load (stop 72)."""
    from mpz import _identity
    calls = []

    def counted(roots):
        calls.append(roots)
        return "ab" * 32
    source_fingerprint.cache_clear()
    monkeypatch.setattr(_identity, "source_digest", counted)
    try:
        first = mpz.identity()
        assert mpz.identity() == first == f"{mpz.__version__} (source {'ab' * (DIGITS // 2)})"
        assert len(calls) == 1
    finally:
        source_fingerprint.cache_clear()               # the real one again, for the others


@pytest.mark.skipif(sys.platform == "win32", reason="a symbolic link needs privileges")
def test_an_unreadable_file_still_gives_a_digest_and_another(tmp_path):
    root = _tree(tmp_path / "pkg")
    first = source_digest([("", str(root))])
    (root / "gone.py").symlink_to(root / "missing.py")               # a dangling link
    assert source_digest([("", str(root))]) != first
