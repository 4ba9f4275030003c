"""Where compiled kernels are cached (mpz._jit, issue 15.2, docs/cold-start.md).

The policy is tested as a function of the environment and of which directories are
writable; two subprocess tests then run real kernels under it: a read-only package
caches in the user cache directory and the second run loads from there, and with no
writable directory at all the codec still works, compiling, and ``-v`` says so.
Writability is simulated (tests may run as root, for whom permission bits mean nothing)
except for a directory under a regular file, which nobody can create.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import subprocess
import sys

import pytest

from mpz import _jit

PKG = _jit.PACKAGE_DIR
IN_TREE = os.path.join(PKG, "__pycache__")


def _only(*ok: str):
    """An ``is_writable`` for which exactly the directories ``ok`` are writable."""
    return lambda p: p in ok


def _decide(env: dict[str, str], *ok: str) -> _jit.CachePolicy:
    return _jit.decide(env, PKG, _only(*ok), version=lambda: "9.9")


# -- the policy ------------------------------------------------------------------------------

def test_writable_package_keeps_numbas_pycache() -> None:
    p = _decide({"HOME": "/h"}, IN_TREE, "/h/.cache/mpz/numba/9.9")
    assert (p.where, p.path) == ("package", IN_TREE)


def test_read_only_package_caches_in_the_user_cache_dir() -> None:
    p = _decide({"HOME": "/h"}, "/h/.cache/mpz/numba/9.9")
    assert (p.where, p.path, p.tried) == ("user", "/h/.cache/mpz/numba/9.9", (IN_TREE,))


def test_xdg_cache_home_is_respected_and_a_relative_one_ignored() -> None:
    p = _decide({"HOME": "/h", "XDG_CACHE_HOME": "/x"}, "/x/mpz/numba/9.9")
    assert p.path == "/x/mpz/numba/9.9"
    p = _decide({"HOME": "/h", "XDG_CACHE_HOME": "rel"}, "/h/.cache/mpz/numba/9.9")
    assert p.path == "/h/.cache/mpz/numba/9.9"


def test_explicit_directories_come_first_in_order() -> None:
    env = {"HOME": "/h", "MPZ_CACHE_DIR": "/m", "NUMBA_CACHE_DIR": "/n"}
    assert _decide(env, "/m", "/n", IN_TREE).where == "MPZ_CACHE_DIR"
    p = _decide(env, "/n", IN_TREE)
    assert (p.where, p.path, p.tried) == ("NUMBA_CACHE_DIR", "/n", ("/m",))


def test_nothing_writable_turns_the_cache_off_and_lists_what_was_tried() -> None:
    env = {"HOME": "/h", "MPZ_CACHE_DIR": "/m"}
    p = _decide(env)
    assert (p.where, p.path) == ("off", None)
    assert p.tried == ("/m", IN_TREE, "/h/.cache/mpz/numba/9.9")


@pytest.mark.parametrize("platform, env, root", [
    ("linux", {"HOME": "/h"}, "/h/.cache/mpz/numba"),
    ("darwin", {"HOME": "/h"}, "/h/Library/Caches/mpz/numba"),
    ("win32", {"HOME": "/h", "LOCALAPPDATA": "/l"}, "/l/mpz/numba"),
])
def test_user_cache_root_per_platform(platform: str, env: dict[str, str], root: str) -> None:
    assert _jit.user_cache_root(env, platform).replace(os.sep, "/") == root


def test_writable_checks_by_writing(tmp_path: Path) -> None:
    assert _jit.writable(str(tmp_path / "new" / "dir"))
    assert (tmp_path / "new" / "dir").is_dir()
    (tmp_path / "file").write_bytes(b"")
    assert not _jit.writable(str(tmp_path / "file" / "sub"))   # not even root can


def test_njit_forms_compile_and_run() -> None:
    @_jit.njit
    def bare(x: int) -> int:
        return x + 1

    @_jit.njit("int64(int64)", cache=False)
    def typed(x: int) -> int:
        return x * 2

    assert bare(1) == 2 and typed(21) == 42
    assert len(typed.signatures) == 1
    with pytest.raises(TypeError):      # compilation was closed by the explicit signature
        typed(1.5j)


# -- real kernels under the policy, in fresh processes -----------------------------------------

#: preloads mpz._jit with the package directory reported read-only, then runs the range
#: coder's kernels and prints the policy and numba's cache statistics as JSON
_CHILD = r"""
import importlib.util, json, os, sys
spec = importlib.util.spec_from_file_location("mpz._jit", sys.argv[1])
jit = importlib.util.module_from_spec(spec)
sys.modules["mpz._jit"] = jit
spec.loader.exec_module(jit)
real = jit.writable
jit.writable = lambda p: False if p.startswith(jit.PACKAGE_DIR) else real(p)
import numpy as np
from mpz.entropy import BlockDecoder, BlockEncoder, _encode_block
assert sys.modules["mpz._jit"] is jit
vals = np.arange(-40, 41, dtype=np.int64).reshape(9, 3, 3)
enc = BlockEncoder()
enc.block(vals)
back = BlockDecoder(enc.finish()).block(9, 3, 3)
p = jit.policy()
print(json.dumps({"where": p.where, "path": p.path, "ok": bool((back == vals).all()),
                  "hits": sum(_encode_block.stats.cache_hits.values()),
                  "misses": sum(_encode_block.stats.cache_misses.values()),
                  "note": jit.cache_note()}))
"""


def _child(env: dict[str, str], *args: str, script: str = _CHILD) -> dict:
    """Run ``script`` in a fresh process; the shipped kernels are off unless ``env`` turns
    them on, so that the cache policy alone decides what compiles."""
    base = {k: v for k, v in os.environ.items()
            if k not in ("MPZ_CACHE_DIR", "NUMBA_CACHE_DIR", "XDG_CACHE_HOME")}
    base[_jit.SHIPPED_ENV] = "0"
    r = subprocess.run([sys.executable, "-c", script, _jit.__file__, *args],
                       env={**base, **env}, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_read_only_package_compiles_once_into_the_user_cache(tmp_path: Path) -> None:
    env = {"HOME": str(tmp_path / "home"), "XDG_CACHE_HOME": str(tmp_path / "xdg")}
    first = _child(env)
    assert first["where"] == "user" and first["ok"]
    assert first["path"].startswith(str(tmp_path / "xdg" / "mpz" / "numba"))
    assert first["misses"] >= 1 and first["hits"] == 0
    index = list(Path(first["path"], "mpz").glob("entropy._encode_block-*.nbi"))
    assert len(index) == 1
    second = _child(env)
    assert second["ok"] and second["hits"] >= 1 and second["misses"] == 0
    assert not (tmp_path / "home").exists()   # nothing went to ~/.cache/numba either


def test_no_writable_directory_still_works_and_says_so(tmp_path: Path) -> None:
    (tmp_path / "file").write_bytes(b"")
    blocked = str(tmp_path / "file" / "cache")          # under a regular file
    env = {"HOME": blocked, "XDG_CACHE_HOME": blocked, "MPZ_CACHE_DIR": blocked}
    out = _child(env)
    assert out["where"] == "off" and out["path"] is None and out["ok"]
    assert out["hits"] == 0
    assert "MPZ_CACHE_DIR" in out["note"] and blocked in out["note"]
    assert len(out["note"].splitlines()) == 1
    again = _child(env)                                 # nothing was kept
    assert again["ok"] and again["hits"] == 0


_CLI_CHILD = _CHILD.split("import numpy as np")[0] + r"""
import mpz
from mpz.synth import generate
from mpz.tools.mpz_cli import main
src, dst = sys.argv[2], sys.argv[3]
with open(src, "wb") as f:
    f.write(mpz.encode(generate("walk", frames=24), max_error=1.0))
for verbose in ([], ["-v"]):
    try:
        main(["decode", *verbose, "-f", src, "-o", dst])
    except SystemExit as e:
        assert not e.code, e.code
    print("=== end", flush=True, file=sys.stderr)
"""


def test_cli_notes_an_uncached_run_in_verbose_mode_only(tmp_path: Path) -> None:
    (tmp_path / "file").write_bytes(b"")
    blocked = str(tmp_path / "file" / "cache")
    env = {k: v for k, v in os.environ.items()
           if k not in ("MPZ_CACHE_DIR", "NUMBA_CACHE_DIR", "XDG_CACHE_HOME")}
    env.update(HOME=blocked, XDG_CACHE_HOME=blocked)
    r = subprocess.run([sys.executable, "-c", _CLI_CHILD, _jit.__file__,
                        str(tmp_path / "a.mpz"), str(tmp_path / "a.npy")],
                       env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    plain, verbose, _ = r.stderr.split("=== end\n")
    assert "no writable cache directory" not in plain
    notes = [ln for ln in verbose.splitlines() if "no writable cache directory" in ln]
    assert len(notes) == 1 and blocked in notes[0]
    assert (tmp_path / "a.npy").stat().st_size > 0


# -- the kernels shipped with the package (mpz/_kernels, python -m mpz.tools.make_kernels) ---

def test_shipped_kernels_match_the_sources() -> None:
    """Every source file with a shipped kernel is the one they were compiled from, so a
    kernel edit without ``python -m mpz.tools.make_kernels`` fails here (numba would
    ignore the stale entries and the first run would compile again)."""
    from mpz.tools import make_kernels
    assert make_kernels.stale() == []
    info = json.loads(Path(_jit.SHIPPED_DIR, "manifest.json").read_text())
    assert {"mpz/entropy.py", "mpz/keyframe.py", "mpz/quantize.py"} <= set(info["sources"])
    # every CPython that requires-python (>= 3.11) admits today, so that a regeneration
    # with one interpreter does not quietly drop the others (README: make_kernels --python)
    assert {"3.11", "3.12", "3.13"} <= set(info["python"])
    for v in info["python"]:
        tag = "py" + v.replace(".", "")
        assert any(Path(_jit.SHIPPED_DIR).rglob(f"keyframe._fit-*.{tag}.nbi")), v


def test_the_docs_list_the_shipped_sources() -> None:
    """README's maintainer note and docs/cold-start.md list the files whose edit needs
    ``make_kernels``, as "the sources of _kernels/manifest.json": both left out
    ``fisher.py`` once its kernels shipped (a QA run from an installed wheel)."""
    import re
    root = Path(__file__).resolve().parents[1]
    info = json.loads(Path(_jit.SHIPPED_DIR, "manifest.json").read_text())
    sources = {s.removeprefix("mpz/") for s in info["sources"]}
    for doc in ("README.md", "docs/cold-start.md"):
        text = (root / doc).read_text()
        i = text.index("`c3dcodec.py`")
        listed = set(re.findall(r"`([\w/]+\.py)`", text[i:text.index(")", i)]))
        assert listed == sources, (doc, sorted(listed ^ sources))


#: kernels of the shipped sources that no encode or decode calls (the tests' references
#: of what a faster kernel must equal), so make_kernels' workload does not compile them
_NOT_IN_THE_CODEC = {"mpz/keyframe._cost", "mpz/keyframe._pairwise_sum",
                     "mpz/keyframe._predict", "mpz/keyframe._residuals"}


def test_every_codec_kernel_is_shipped() -> None:
    """Each kernel of a shipped source (not inlined) has an index file for every CPython
    of the manifest, but for the test-only references above: a new kernel that
    make_kernels' workload never calls would otherwise compile on a user's first run
    (kinematics._farthest did, as the workload's skeletal encodes had no position
    bound)."""
    import re
    info = json.loads(Path(_jit.SHIPPED_DIR, "manifest.json").read_text())
    root = Path(_jit.SHIPPED_DIR)
    package = Path(_jit.__file__).parent.parent             # the folder holding mpz/
    for v in info["python"]:
        tag = ".py" + v.replace(".", "")
        shipped = {p.relative_to(root).as_posix().split(tag)[0].rsplit("-", 1)[0]
                   for p in root.rglob(f"*{tag}.nbi")}
        defined = set()
        for src in info["sources"]:
            text = (package / src).read_text(encoding="utf-8")
            for m in re.finditer(r"@(njit\([^)]*\)|_kernel)\s*\ndef (\w+)", text):
                if 'inline="always"' not in m.group(1):
                    defined.add(f"{src.removesuffix('.py')}.{m.group(2)}")
        assert defined - _NOT_IN_THE_CODEC <= shipped, (v, sorted(defined - shipped))
        assert _NOT_IN_THE_CODEC <= defined                 # the list names real kernels


def _shipped_unusable() -> str | None:
    """Why this interpreter cannot load the shipped kernels, or None."""
    import numba
    info = json.loads(Path(_jit.SHIPPED_DIR, "manifest.json").read_text())
    here = f"{sys.version_info[0]}.{sys.version_info[1]}"
    if here not in info["python"] or info["numba"] != numba.__version__:
        return (f"kernels shipped for CPython {info['python']} / numba {info['numba']}, "
                f"this is {here} / {numba.__version__}")
    if _jit.shipped_cpu() is None:
        return "this CPU lacks the shipped kernels' baseline features"
    return None


#: encodes and decodes in a fresh process and reports the bytes and the cache statistics
#: of the kernels that encoding and decoding at 1 mm call
_CODEC_CHILD = _CHILD.split("import numpy as np")[0] + r"""
import hashlib
import numpy as np
import mpz
from mpz import fisher, keyframe, quantize
from mpz.entropy import _decode_block, _encode_block
from mpz.synth import generate
data = mpz.encode(generate("walk", frames=120, seed=4), max_error=1.0)
back = mpz.decode(data)
# a loop, the same 40 frames 6 times: partitions cut near ties, where fastmath code
# compiled for another CPU may cut otherwise (a review of stop 62)
walk = generate("walk", frames=240, seed=5)
loop = mpz.Motion(np.concatenate([walk.positions[:40]] * 6), walk.names, walk.rate, walk.units)
summarised = mpz.encode(loop, max_error=1.0, summary=(16,))
kernels = [_encode_block, _decode_block, keyframe._fit_range, keyframe._best_references,
           keyframe._rebuild, keyframe._mark_keys, quantize._choose, fisher._fisher_tables]
print(json.dumps({"sha": hashlib.sha256(data).hexdigest(), "ok": bool(back.valid.any()),
                  "summary_sha": hashlib.sha256(summarised).hexdigest(),
                  "hits": sum(sum(k.stats.cache_hits.values()) for k in kernels),
                  "misses": sum(sum(k.stats.cache_misses.values()) for k in kernels),
                  "where": jit.policy().where}))
"""


def test_shipped_kernels_load_instead_of_compiling_and_give_the_same_bytes(
        tmp_path: Path) -> None:
    """A first run with an empty cache loads every codec kernel it calls from mpz/_kernels
    (no compilation: numba counts a miss for each kernel it compiles), also with no
    writable directory at all, and writes the bytes that host-compiled kernels write. The
    summary's kernels too (a first --summary compiled them for 2.5-4 s, a QA run of stop
    62); their fastmath code may cut a near tie otherwise where the host compiles it, so
    they are loaded before the user's cache: a cache that holds host-compiled ones (after
    a run with MPZ_SHIPPED_KERNELS=0) changes no summary (the review of stop 62)."""
    why = _shipped_unusable()
    if why:
        pytest.skip(why)
    on = {_jit.SHIPPED_ENV: "1"}
    shipped = _child({"MPZ_CACHE_DIR": str(tmp_path / "a"), **on}, script=_CODEC_CHILD)
    assert shipped["ok"] and shipped["misses"] == 0 and shipped["hits"] >= 8
    host = _child({"MPZ_CACHE_DIR": str(tmp_path / "b")}, script=_CODEC_CHILD)
    assert host["misses"] >= 8 and host["hits"] == 0
    assert shipped["sha"] == host["sha"]
    again = _child({"MPZ_CACHE_DIR": str(tmp_path / "b"), **on}, script=_CODEC_CHILD)
    assert again["summary_sha"] == shipped["summary_sha"] and again["sha"] == host["sha"]
    (tmp_path / "file").write_bytes(b"")
    blocked = str(tmp_path / "file" / "cache")
    off = _child({"HOME": blocked, "XDG_CACHE_HOME": blocked, "MPZ_CACHE_DIR": blocked, **on},
                 script=_CODEC_CHILD)
    assert off["where"] == "off" and off["misses"] == 0 and off["sha"] == host["sha"]


def test_shipped_kernels_need_the_baseline_features(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Code for a CPU feature this machine lacks would fault, and files for another CPython
    or numba would be rejected entry by entry: such kernels are not looked at."""
    import numba
    here = {"python": [f"{sys.version_info[0]}.{sys.version_info[1]}"],
            "numba": numba.__version__, "cpu": "x86-64-v2"}
    monkeypatch.setattr(_jit, "SHIPPED_DIR", str(tmp_path))
    monkeypatch.delenv(_jit.SHIPPED_ENV, raising=False)
    monkeypatch.delenv(_jit.SHIP_ENV, raising=False)

    def cpu(manifest: object) -> str | None:
        (tmp_path / "manifest.json").write_text(
            manifest if isinstance(manifest, str) else json.dumps(manifest))
        _jit.shipped_cpu.cache_clear()
        return _jit.shipped_cpu()
    try:
        assert cpu({**here, "requires_features": []}) == "x86-64-v2"
        assert cpu({**here, "requires_features": ["sse2", "no-such-feature"]}) is None
        assert cpu({**here, "python": ["2.7"]}) is None
        assert cpu({**here, "numba": "0.0.1"}) is None
        assert cpu("{not json") is None
    finally:
        _jit.shipped_cpu.cache_clear()


def test_ship_policy_and_the_off_switch() -> None:
    assert _decide({"HOME": "/h", _jit.SHIP_ENV: "1"}).where == "ship"
    assert _jit.shipped_enabled({})
    assert not _jit.shipped_enabled({_jit.SHIPPED_ENV: "0"})
    assert not _jit.shipped_enabled({_jit.SHIP_ENV: "1"})    # make_kernels compiles afresh


# ---- numba's BLAS check, skipped in mpz's own processes (skip_blas_check, issue 15.2) ----
_BLAS_CHILD = r"""
import json, sys
import numpy as np
import mpz
from mpz.synth import generate
data = mpz.encode(generate("walk", frames=24), max_error=1.0)
mpz.decode(data)                                # the first kernels load here
import numba, numba.np.arraymath, numba.np.linalg
after_decode = "scipy.linalg" in sys.modules
dot = numba.njit(lambda a, b: np.dot(a, b))      # numba's BLAS, typed after the check
value = float(dot(np.arange(3.0), np.arange(3.0)))
print(json.dumps({"linalg_after_decode": after_decode,
                  "have_blas": numba.np.arraymath._HAVE_BLAS, "dot": value,
                  "restored": numba.np.linalg.ensure_blas.__name__}))
"""


@pytest.mark.parametrize("script,skipped", [("mpz", True), ("mpz-conformance", True),
                                             ("my_program.py", False)])
def test_blas_check_is_skipped_in_mpz_commands_only(tmp_path: Path, script: str,
                                                    skipped: bool) -> None:
    """In a command's process the first decode does not import scipy.linalg, and numba's
    np.dot still works afterwards (ensure_blas is numba's own again); in a program that
    imports mpz, numba checks for BLAS as it always does."""
    path = tmp_path / script
    # a command is a script of its name that imports its main, as pip's console scripts
    # do (mpz._worker: a user's own script named mpz is not one)
    entry = "from mpz.tools.mpz_cli import main\n" if skipped else ""
    path.write_text(entry + _BLAS_CHILD)
    r = subprocess.run([sys.executable, str(path)], capture_output=True, text=True,
                       timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["dot"] == 5.0 and out["restored"] == "ensure_blas"
    assert out["linalg_after_decode"] is not skipped
    assert out["have_blas"] is not skipped


def test_a_kernel_shipped_by_exception_is_loaded_before_the_users_cache() -> None:
    """The order itself, on any CPU (the loop above tells the two orders apart only where
    the host's code cuts a near tie otherwise; the review of stop 62): an exact kernel
    takes the user's cache first, a ``ship=True`` one the shipped kernels first, and each
    falls back to the other; a compile is saved to the user's cache alone."""
    if _jit._Layered is None:
        pytest.skip("numba's cache classes are not there")

    class Fake:
        def __init__(self, hit: object) -> None:
            self.hit, self.saved = hit, []

        def load_overload(self, sig: object, ctx: object) -> object:
            return self.hit

        def save_overload(self, sig: object, data: object) -> None:
            self.saved.append(data)

    user, shipped = Fake("user's"), Fake("shipped")
    assert _jit._Layered(user, shipped).load_overload("sig", None) == "user's"
    assert _jit._Layered(user, shipped, shipped_first=True).load_overload("sig", None) == \
        "shipped"
    assert _jit._Layered(Fake(None), shipped).load_overload("sig", None) == "shipped"
    assert _jit._Layered(user, Fake(None), shipped_first=True).load_overload(
        "sig", None) == "user's"
    assert _jit._Layered(None, shipped, shipped_first=True).load_overload("sig", None) == \
        "shipped"
    layered = _jit._Layered(user, shipped, shipped_first=True)
    layered.save_overload("sig", "code")
    assert user.saved == ["code"] and shipped.saved == []
    # and the package's kernels are given the orders they need, where shipped ones serve
    from mpz import entropy, fisher
    summary, exact = fisher._fisher_tables._cache, entropy._decode_block._cache
    if isinstance(summary, _jit._Layered) and isinstance(exact, _jit._Layered):
        assert summary.order[0] is summary.shipped
        assert exact.order[0] is exact.primary and exact.primary is not None
