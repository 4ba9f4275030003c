"""Shared fixtures. Real recordings are read from ../shared/data (never copied
into the repo); tests that need them skip with a reason when it is absent."""
from __future__ import annotations

from collections.abc import Callable
import os
from pathlib import Path
import sys
import tracemalloc
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[1]


def shared_data_dir() -> Path | None:
    """``$MPZ_SHARED_DATA`` or ``../shared/data`` beside the checkout, if present."""
    env = os.environ.get("MPZ_SHARED_DATA")
    cand = Path(env) if env else REPO.parent / "shared" / "data"
    return cand if cand.is_dir() else None


@pytest.fixture(scope="session")
def shared_data() -> Path:
    d = shared_data_dir()
    if d is None:
        env = os.environ.get("MPZ_SHARED_DATA")    # the value tried, when it is set (QA)
        pytest.skip(f"real recordings not available: MPZ_SHARED_DATA={env} is not a folder"
                    if env else "real recordings not available: ../shared/data is absent "
                    "(set MPZ_SHARED_DATA)")
    return d


@pytest.fixture(scope="session")
def two_joint_bvh() -> str:
    """A BVH of two joints over three frames (no length unit, as every BVH)."""
    return """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 10 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.0333333
0 0 0 0 0 0 0 0 0
1 0 0 0 5 0 10 0 0
2 0 0 0 10 0 20 0 0
"""


def _one_bone_asf(angle: str = "deg", axis: str = "0 0 90", dofs: str = "rx rz") -> str:
    """The ASF text of a root and one bone ``b1`` (length 2 along x) with ``dofs``."""
    return f""":version 1.10
:name T
:units
  mass 1.0
  length 0.45
  angle {angle}
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name b1
     direction 1 0 0
     length 2
     axis {axis} XYZ
    dof {dofs}
  end
:hierarchy
  begin
    root b1
  end
"""


@pytest.fixture(scope="session")
def one_bone_asf():
    """A function giving a one-bone ASF text (angle unit, bone axis and dofs as asked)."""
    return _one_bone_asf


@pytest.fixture
def bench_script(monkeypatch):
    """``load(name)``: the script ``bench/<name>.py`` as a module, imported from its path
    (bench/ is not a package; its scripts import their neighbours, ``_common`` and
    ``peers``, so bench/ goes on sys.path for the test)."""
    import importlib.util
    bench = Path(__file__).resolve().parents[1] / "bench"
    monkeypatch.syspath_prepend(str(bench))

    def load(name: str):
        spec = importlib.util.spec_from_file_location(f"mpz_bench_{name}", bench / f"{name}.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        monkeypatch.setitem(sys.modules, spec.name, module)   # a dataclass looks it up
        spec.loader.exec_module(module)
        return module
    return load


def install_copy(site: Path) -> Path:
    """A copy of this checkout's mpz laid out as a wheel installs it: ``site/mpz``, with
    each subpackage of pyproject.toml's ``package-dir`` (spec, tools, conformance, the
    vectors) in its folder inside it, ``__pycache__`` left out. A process with ``site``
    first on its ``PYTHONPATH`` imports this copy instead of the checkout. Returns the
    copy's ``mpz`` folder."""
    import shutil
    import tomllib
    dirs = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-dir"]
    top = site / "mpz"
    for name in sorted(dirs, key=len):                  # mpz first, then inside it
        below = name.split(".")[1:]
        shutil.copytree(REPO / dirs[name], top.joinpath(*below), dirs_exist_ok=True,
                        ignore=shutil.ignore_patterns("__pycache__"))
    return top


@pytest.fixture
def installed_copy(tmp_path: Path) -> Path:
    """:func:`install_copy` into ``tmp_path/site``; returns the copy's ``mpz`` folder."""
    return install_copy(tmp_path / "site")


def _traced_peak(run: Callable[[], Any]) -> int:
    """The largest traced allocation total while ``run()`` runs, beyond what was traced
    before it (numpy's and numba's allocations report to tracemalloc)."""
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        run()
        return tracemalloc.get_traced_memory()[1] - before
    finally:
        tracemalloc.stop()


@pytest.fixture()
def traced_peak() -> Callable[[Callable[[], Any]], int]:
    """:func:`_traced_peak`, for the tests that bound a step's memory."""
    return _traced_peak
