"""Issue 14: the CLI and the Python API behave the way zstd, flac and numpy users expect.

Every CLI test starts the installed ``mpz`` or ``mpzinfo`` with :mod:`subprocess`,
with real pipes between processes and a real umask, and checks what a user sees:
the exit code, standard output and standard error, and the files left behind.
The expected values come from the issue and the README, never from the code
under test. Point numbers refer to issue 14.
"""
from __future__ import annotations

import argparse
from collections.abc import Sequence
import inspect
import io
import json
import math
import os
from pathlib import Path
import re
import shutil
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import mpz
from mpz.io import read, write
from mpz.synth import generate

pytestmark = pytest.mark.skipif(os.name != "posix", reason="pipes and umasks are POSIX here")

SIGNATURE = b"\x89MPZ\r\n\x1a\n"          # spec §3.1, written out on purpose
REPO = Path(__file__).resolve().parents[1]


def command(name: str) -> str:
    """The console script installed beside this Python (else the one on PATH)."""
    beside = Path(sys.executable).parent / name
    found = str(beside) if beside.exists() else shutil.which(name)
    assert found, f"{name} is not installed (pip install -e .)"
    return found


def _umask022() -> None:
    os.umask(0o022)


def run(args: Sequence[str], cwd: Path, *, stdin: bytes | None = None,
        timeout: float = 300) -> subprocess.CompletedProcess[bytes]:
    """Run an installed command; stdout and stderr captured as bytes."""
    return subprocess.run([command(args[0]), *args[1:]], cwd=cwd, input=stdin,
                          capture_output=True, timeout=timeout, preexec_fn=_umask022)


def strict_json(text: str | bytes) -> object:
    """Parse JSON as a strict parser does: NaN and Infinity are errors."""
    def refuse(token: str) -> None:
        raise ValueError(f"non-standard JSON token {token}")
    return json.loads(text, parse_constant=refuse)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory, two_joint_bvh: str) -> dict[str, Path]:
    """Small inputs in every readable format, and an .mpz (120 frames, CMU 41 markers, mm)."""
    d = tmp_path_factory.mktemp("inputs")
    m = generate("walk", frames=120, seed=3, gap_fraction=0.02)
    out = {}
    for ext in ("c3d", "trc", "csv", "npy"):
        out[ext] = d / f"walk.{ext}"
        write(m, out[ext])
    out["mpz"] = d / "walk.mpz"
    out["mpz"].write_bytes(mpz.encode(m, max_error=1.0))
    bvh = d / "arm.bvh"
    bvh.write_text(two_joint_bvh)
    out["bvh"] = bvh
    return out


def test_summary_refuses_options_that_do_nothing_for_its_input(
        inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """mpz summary refused --rate where it did nothing but ignored --asf, --no-decode and
    --max-samples there (exit 0; a QA run of stop 61); mpz search refuses them. Each is
    an error naming the option; where it applies, it works."""
    from mpz.tools import mpz_cli
    asf = inputs["bvh"].with_suffix(".asf")        # only named: refused before reading
    renamed = tmp_path / "walk.dat"                # a C3D known by its content alone
    renamed.write_bytes(inputs["c3d"].read_bytes())
    refused = [
        ([str(inputs["c3d"]), "--asf", str(asf)], "--asf: the skeleton of .amc input; this "
                                                   "input is C3D"),
        ([str(renamed), "--asf", str(asf)], "--asf: the skeleton of .amc input; this input "
                                            "is C3D"),
        ([str(inputs["mpz"]), "--asf", str(asf)], "--asf: an .mpz file holds its own"),
        ([str(inputs["trc"]), "--no-decode"], "--no-decode is for .mpz input"),
        ([str(inputs["csv"]), "--max-samples", "100000"], "--max-samples 100000: a limit on "
                                                          "decoding .mpz input"),
        ([str(inputs["mpz"]), "--rate", "50"], "--rate 50: an .mpz file stores its rate")]
    for argv, said in refused:
        code = mpz_cli.main(["summary", *argv, "--k", "3"])
        err = capsys.readouterr().err
        assert code == 2 and said in err, (argv, err)
    summarised = tmp_path / "summarised.mpz"
    summarised.write_bytes(mpz.encode(read(inputs["trc"]), max_error=1.0, summary=(3,)))
    for argv in ([str(summarised), "--no-decode"], [str(inputs["mpz"]), "--max-samples",
                                                    "100000"]):
        assert mpz_cli.main(["summary", *argv, "--k", "3"]) == 0, capsys.readouterr().err
    capsys.readouterr()


# -- 1. pipes ------------------------------------------------------------------------------

def test_encode_to_stdout_through_a_real_pipe_into_decode(inputs: dict[str, Path],
                                                          tmp_path: Path) -> None:
    enc = subprocess.Popen([command("mpz"), "encode", str(inputs["c3d"]), "-o", "-",
                            "--max-error", "1mm"], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, cwd=tmp_path)
    dec = subprocess.Popen([command("mpz"), "decode", "-", "-o", "back.npy"],
                           stdin=enc.stdout, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           cwd=tmp_path)
    assert enc.stdout is not None
    enc.stdout.close()
    dout, derr = dec.communicate(timeout=300)
    _, eerr = enc.communicate(timeout=300)
    assert enc.returncode == 0 and dec.returncode == 0, (eerr, derr)
    assert not (tmp_path / "-").exists()                 # no file literally named "-"
    back = np.load(tmp_path / "back.npy")
    orig = read(inputs["c3d"])
    d = np.linalg.norm(back - orig.as_nan(), axis=2)
    assert np.nanmax(d) <= 1.0 + 1e-9
    assert b"frames x" in eerr                           # the report went to stderr


def test_stdout_carries_only_data_and_reports_go_to_stderr(inputs: dict[str, Path],
                                                           tmp_path: Path) -> None:
    p = run(["mpz", "encode", str(inputs["trc"]), "-o", "-", "--max-error", "1mm"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith(SIGNATURE)
    assert mpz.decode(p.stdout).n_frames == 120          # nothing but the file on stdout
    assert b"ratio" in p.stderr
    p = run(["mpz", "decode", str(inputs["mpz"]), "-o", "-", "--format", "csv"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith(b"frame,time,")
    assert b"-> -" in p.stderr


@pytest.mark.parametrize("fmt", ["c3d", "trc", "csv", "npy", "bvh", "mpz"])
def test_stdin_format_is_found_from_the_content(fmt: str, inputs: dict[str, Path],
                                                tmp_path: Path) -> None:
    data = inputs[fmt].read_bytes()
    p = run(["mpz", "show", "--json", "-"], tmp_path, stdin=data)
    assert p.returncode in (0, 1), p.stderr
    info = strict_json(p.stdout)
    assert isinstance(info, dict)
    names = {"c3d": "C3D", "trc": "TRC", "csv": "CSV", "npy": "NPY", "bvh": "BVH", "mpz": "MPZ"}
    assert info["format"] == names[fmt]
    assert info["frames"] == (3 if fmt == "bvh" else 120)       # conftest.two_joint_bvh: 3


def test_mpzinfo_and_encode_read_stdin(inputs: dict[str, Path], tmp_path: Path) -> None:
    p = run(["mpzinfo", "-"], tmp_path, stdin=inputs["mpz"].read_bytes())
    assert p.returncode == 0 and p.stdout.startswith(b"OK: - (MPZ 1."), p.stderr
    p = run(["mpz", "encode", "-", "-o", "w.mpz", "--max-error", "2mm"], tmp_path,
            stdin=inputs["c3d"].read_bytes())
    assert p.returncode == 0, p.stderr
    assert mpz.info(tmp_path / "w.mpz").error_bound == 2.0


def test_stdin_of_no_known_format_is_a_clear_error(tmp_path: Path) -> None:
    p = run(["mpz", "encode", "-", "-o", "x.mpz", "--max-error", "1mm"], tmp_path,
            stdin=b"hello, this is not motion capture\n" * 10)
    assert p.returncode == 2
    assert b"cannot tell the format" in p.stderr and b"Traceback" not in p.stderr
    assert not (tmp_path / "x.mpz").exists()


def test_detect_format_on_every_real_recording(shared_data: Path) -> None:
    from mpz.io import detect_format
    expected = {".c3d": ".c3d", ".trc": ".trc", ".bvh": ".bvh", ".amc": ".amc", ".asf": None}
    seen = 0
    for p in sorted(shared_data.rglob("*")):
        if p.suffix.lower() in expected:
            assert detect_format(p.read_bytes()[:4096]) == expected[p.suffix.lower()], p.name
            seen += 1
    assert seen >= 30


# -- 2. several inputs and folders -----------------------------------------------------------

def test_batch_into_a_folder_keeps_going_past_a_failed_file(inputs: dict[str, Path],
                                                            tmp_path: Path) -> None:
    src = tmp_path / "captures"
    (src / "day2").mkdir(parents=True)
    shutil.copy(inputs["c3d"], src / "a.c3d")
    shutil.copy(inputs["trc"], src / "day2" / "b.trc")
    (src / "broken.c3d").write_bytes(b"\x02\x50" + bytes(100))   # looks like C3D, is not
    (src / "notes.txt").write_text("not an input")
    out = tmp_path / "archive"
    out.mkdir()
    p = run(["mpz", "encode", "-r", str(src), "-o", "archive/", "--max-error", "1mm", "-q"],
            tmp_path)
    assert p.returncode == 2                          # some input failed
    err = p.stderr.decode()
    assert "broken.c3d" in err and "1 failed" in err
    # (a batch into a folder also keeps the corpus index there: index.sqlite, issue 15)
    assert sorted(n for n in os.listdir(out) if n.endswith(".mpz")) == ["a.mpz", "b.mpz"]
    # decode them all back, beside nothing: into another folder, as TRC
    (tmp_path / "back").mkdir()
    p = run(["mpz", "decode", "archive/a.mpz", "archive/b.mpz", "-o", "back/", "-F", "trc"],
            tmp_path)
    assert p.returncode == 0, p.stderr
    assert sorted(os.listdir(tmp_path / "back")) == ["a.trc", "b.trc"]
    assert p.stdout.count(b" -> ") == 2


def test_batch_rules(inputs: dict[str, Path], tmp_path: Path) -> None:
    shutil.copy(inputs["c3d"], tmp_path / "a.c3d")
    shutil.copy(inputs["trc"], tmp_path / "b.trc")
    # several inputs with one output file: usage error, nothing written
    p = run(["mpz", "encode", "a.c3d", "b.trc", "-o", "x.mpz", "--max-error", "1mm"], tmp_path)
    assert p.returncode == 64 and b"FOLDER/" in p.stderr
    # a folder without -r is reported, the other input is still encoded (beside itself)
    (tmp_path / "dir").mkdir()
    p = run(["mpz", "encode", "dir", "a.c3d", "--max-error", "1mm"], tmp_path)
    assert p.returncode == 2 and b"use -r" in p.stderr
    assert (tmp_path / "a.mpz").is_file()
    # two inputs that would make the same output: the second fails, the first is kept
    shutil.copy(inputs["trc"], tmp_path / "a.trc")
    (tmp_path / "out").mkdir()
    p = run(["mpz", "encode", "a.c3d", "a.trc", "-o", "out/", "--max-error", "1mm"], tmp_path)
    # (a batch into -o FOLDER/ is a corpus: the failure is in its summary, as the others)
    assert p.returncode == 2 and b"FAILED a.trc: its output" in p.stdout
    assert b"also the output of" in p.stdout and b"1 failed" in p.stderr
    assert b"--mirror" not in p.stdout          # one folder: --mirror would not help
    assert [n for n in os.listdir(tmp_path / "out") if n.endswith(".mpz")] == ["a.mpz"]
    assert mpz.decode(tmp_path / "out" / "a.mpz").n_frames == 120



def test_a_missing_output_folder_is_made(inputs: dict[str, Path], tmp_path: Path) -> None:
    """``-o FOLDER/`` that does not exist is made with its parents (it was a usage error:
    an archive team's first ``mpz encode -r raw/ -o archive/`` failed), for one file, a
    corpus and a decode; a file where the folder would go fails, named, exit 2."""
    shutil.copy(inputs["c3d"], tmp_path / "a.c3d")
    shutil.copy(inputs["trc"], tmp_path / "b.trc")
    p = run(["mpz", "encode", "a.c3d", "-o", "one/deeper/", "--max-error", "1mm"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert mpz.decode(tmp_path / "one" / "deeper" / "a.mpz").n_frames == 120
    p = run(["mpz", "encode", "a.c3d", "b.trc", "-o", "corpus/x/", "--max-error", "1mm"],
            tmp_path)
    assert p.returncode == 0, p.stderr
    assert sorted(os.listdir(tmp_path / "corpus" / "x")) == ["a.mpz", "b.mpz", "index.sqlite"]
    p = run(["mpz", "decode", "corpus/x/a.mpz", "corpus/x/b.mpz", "-o", "back/t/", "-F",
             "trc"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert sorted(os.listdir(tmp_path / "back" / "t")) == ["a.trc", "b.trc"]
    (tmp_path / "afile").write_text("in the way")
    for args in (["a.c3d"], ["a.c3d", "b.trc"]):
        p = run(["mpz", "encode", *args, "-o", "afile/sub/", "--max-error", "1mm"], tmp_path)
        assert p.returncode == 2, p.stderr
        assert b"cannot make the folder afile/sub/: a file (not a folder) is in its path" \
            in p.stderr and b"Traceback" not in p.stderr
    assert (tmp_path / "afile").read_text() == "in the way"
    p = run(["mpz", "encode", "a.c3d", "-o", "afile/", "--max-error", "1mm"], tmp_path)
    assert p.returncode == 2 and (b"cannot make the folder afile/: a file (not a folder) is "
                                  b"in its place") in p.stderr
    # --mirror makes it too, for a file at the top of -r's folder as for one below it (a
    # QA run of stop 47: "back/a.c3d: back does not exist", the README's own example)
    p = run(["mpz", "decode", "-r", "corpus/x", "-o", "mirrored/back/", "--mirror", "-F",
             "trc", "-q"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert sorted(os.listdir(tmp_path / "mirrored" / "back")) == ["a.trc", "b.trc"]


def test_standard_input_into_an_output_folder_is_refused_by_name(inputs: dict[str, Path],
                                                                 tmp_path: Path) -> None:
    """Standard input has no name to give its output in ``-o FOLDER/``: that input fails,
    saying so, and the others are coded (a QA run of stop 47: encode wrote FOLDER/-.mpz,
    decode said "-: no such file", and --jobs blamed the output)."""
    shutil.copy(inputs["c3d"], tmp_path / "a.c3d")
    need = b"-: standard input has no file name to name its output in out/: give -o FILE"
    stdin = inputs["c3d"].read_bytes()
    for extra in ([], ["a.c3d"], ["a.c3d", "--jobs", "0"]):
        shutil.rmtree(tmp_path / "out", ignore_errors=True)
        p = run(["mpz", "encode", "-", *extra, "-o", "out/", "--max-error", "1mm"], tmp_path,
                stdin=stdin)
        assert p.returncode == 2 and need in p.stdout + p.stderr, (extra, p.stderr)
        made = sorted(os.listdir(tmp_path / "out")) if (tmp_path / "out").exists() else []
        assert "-.mpz" not in made and ("a.mpz" in made) == bool(extra)
    mpz_bytes = (tmp_path / "out" / "a.mpz").read_bytes()
    p = run(["mpz", "decode", "-", "-o", "back/"], tmp_path, stdin=mpz_bytes)
    assert p.returncode == 2 and need.replace(b"out/", b"back/") in p.stderr, p.stderr

def test_decode_names_its_output_with_the_sources_own_extension(inputs: dict[str, Path],
                                                                tmp_path: Path) -> None:
    """A corpus QA run: a mirrored tree came back with other names, Walk.C3D as Walk.c3d
    and run.Trc as run.trc; the extension is now the source's own spelling of its format
    (and -F's, or the format's, when the source's is another)."""
    shutil.copy(inputs["c3d"], tmp_path / "Walk.C3D")
    shutil.copy(inputs["trc"], tmp_path / "run.Trc")
    p = run(["mpz", "encode", "Walk.C3D", "run.Trc", "-o", "arch/", "-q"], tmp_path)
    assert p.returncode == 0, p.stderr
    p = run(["mpz", "decode", "arch/Walk.mpz", "arch/run.mpz", "-q"], tmp_path)
    assert p.returncode == 0, p.stderr
    made = set(os.listdir(tmp_path / "arch"))
    assert {"Walk.C3D", "run.Trc"} <= made and not {"Walk.c3d", "run.trc"} & made, made
    p = run(["mpz", "decode", "arch/run.mpz", "-F", "csv", "-q"], tmp_path)
    assert p.returncode == 0 and (tmp_path / "arch" / "run.csv").is_file(), p.stderr


def test_mirror_keeps_the_layout_of_an_archive_whose_names_repeat(inputs: dict[str, Path],
                                                                  tmp_path: Path) -> None:
    """``--mirror`` (zstd's --output-dir-mirror): with -r, each output keeps its path below
    the folder given; one walk.* per subject folder, which the flat -o FOLDER/ refuses."""
    src = tmp_path / "captures"
    (src / "s02" / "deep").mkdir(parents=True)
    (src / "s01").mkdir()
    shutil.copy(inputs["c3d"], src / "s01" / "walk.c3d")                  # 120 frames
    write(generate("walk", frames=90, seed=5), src / "s02" / "walk.trc")   # 90 frames
    shutil.copy(inputs["c3d"], src / "s02" / "deep" / "run.c3d")
    shutil.copy(inputs["trc"], tmp_path / "loose.trc")                   # given by name
    (tmp_path / "flat").mkdir()
    p = run(["mpz", "encode", "-r", "captures", "-o", "flat/", "--max-error", "1mm", "-q"],
            tmp_path)
    assert p.returncode == 2 and b"also the output of" in p.stderr     # flat: names clash
    assert b"--mirror keeps each file's folder below -o" in p.stderr    # and the way out
    # the file that failed counts its bytes, and the index names its output (QA, stop 42:
    # 0.00 MB and an empty output)
    import sqlite3
    db = sqlite3.connect(tmp_path / "flat" / "index.sqlite")
    assert db.execute("SELECT path, output FROM failures").fetchall() == [
        (str((src / "s02" / "walk.trc").resolve()), "walk.mpz")]
    db.close()
    mb = (src / "s02" / "walk.trc").stat().st_size / 1e6
    p = run(["mpz", "encode", "-r", "captures", "-o", "flat/", "--max-error", "1mm"], tmp_path)
    assert re.search(rf"^\s+failed\s+1\s+{mb:.2f}\s", p.stdout.decode(), re.M), p.stdout
    (tmp_path / "archive").mkdir()
    p = run(["mpz", "encode", "-r", "captures", "loose.trc", "-o", "archive/", "--mirror",
             "--max-error", "1mm", "-q"], tmp_path)
    assert p.returncode == 0, p.stderr
    got = sorted(q.relative_to(tmp_path / "archive").as_posix()
                 for q in (tmp_path / "archive").rglob("*.mpz"))
    assert got == ["loose.mpz", "s01/walk.mpz", "s02/deep/run.mpz", "s02/walk.mpz"]
    assert mpz.decode(tmp_path / "archive" / "s02" / "walk.mpz").n_frames == 90
    assert mpz.decode(tmp_path / "archive" / "s01" / "walk.mpz").n_frames == 120
    assert (tmp_path / "archive" / "index.sqlite").is_file()
    # run again: every file is up to date (the index keys are the mirrored paths)
    p = run(["mpz", "encode", "-r", "captures", "loose.trc", "-o", "archive/", "--mirror",
             "--max-error", "1mm"], tmp_path)
    assert p.returncode == 0 and b"up to date       4" in p.stdout, p.stdout
    # and back, mirrored again; a folder that cannot be made fails its files only
    (tmp_path / "back").mkdir()
    (tmp_path / "back" / "s01").write_text("a file where a folder would go")
    p = run(["mpz", "decode", "-r", "archive", "-o", "back/", "--mirror", "-F", "trc"],
            tmp_path)
    assert p.returncode == 2
    assert b"cannot make the folder back/s01" in p.stderr and b"1 failed" in p.stderr
    got = sorted(q.relative_to(tmp_path / "back").as_posix()
                 for q in (tmp_path / "back").rglob("*.trc"))
    assert got == ["loose.trc", "s02/deep/run.trc", "s02/walk.trc"]
    assert read(tmp_path / "back" / "s02" / "walk.trc").n_frames == 90
    # --mirror is about -o FOLDER/: anything else is a usage error
    for out in ([], ["-o", "one.mpz"]):
        p = run(["mpz", "encode", "-r", "captures", *out, "--mirror", "--max-error", "1mm"],
                tmp_path)
        assert p.returncode == 64 and b"-o FOLDER/" in p.stderr


def test_a_ratio_against_the_input_counts_only_what_was_kept(inputs: dict[str, Path],
                                                             tmp_path: Path) -> None:
    """--no-skeleton keeps a BVH's joint positions only: the ratio against the BVH file is
    then not given (it would count the channels that were not kept), in text and JSON."""
    base = ["mpz", "encode", str(inputs["bvh"]), "--units", "cm", "--max-error", "1mm", "-f"]
    p = run([*base, "-o", "whole.mpz", "--json"], tmp_path)
    assert p.returncode == 0, p.stderr
    doc = strict_json(p.stdout)
    assert doc["dropped"] == [] and doc["ratio_input"] == pytest.approx(
        inputs["bvh"].stat().st_size / (tmp_path / "whole.mpz").stat().st_size)
    p = run([*base, "-o", "joints.mpz", "--no-skeleton", "--json"], tmp_path)
    doc = strict_json(p.stdout)
    assert doc["dropped"] == ["joint angles and the skeleton"] and doc["ratio_input"] is None
    p = run([*base, "-o", "joints.mpz", "--no-skeleton"], tmp_path)
    assert b"vs input file n/a (joint angles and the skeleton not kept)" in p.stdout


@pytest.mark.parametrize("ext", ["trc", "c3d", "mpz"])
def test_standard_input_is_sized_like_a_file(inputs: dict[str, Path], tmp_path: Path,
                                              ext: str) -> None:
    """What standard input held is the input's size: the report gives it and the ratio
    against it, as for the same file named (it said "input ?" and no ratio)."""
    src = inputs[ext]
    p = run(["mpz", "encode", "-", "-o", "piped.mpz", "--max-error", "1mm", "--json"],
            tmp_path, stdin=src.read_bytes())
    assert p.returncode == 0, p.stderr
    doc = strict_json(p.stdout)
    assert doc["input_bytes"] == src.stat().st_size
    assert doc["ratio_input"] == pytest.approx(
        src.stat().st_size / (tmp_path / "piped.mpz").stat().st_size)
    p = run(["mpz", "encode", "-", "-o", "piped.mpz", "--max-error", "1mm", "-f"],
            tmp_path, stdin=src.read_bytes())
    assert b"input ?" not in p.stdout and b"vs input file" in p.stdout


# -- 3. short flags --------------------------------------------------------------------------

def test_short_flags_on_encode_and_decode(inputs: dict[str, Path], tmp_path: Path) -> None:
    args = ["mpz", "encode", str(inputs["c3d"]), "-o", "x.mpz", "--max-error", "1mm"]
    p = run([*args, "-q"], tmp_path)
    assert p.returncode == 0 and p.stdout == b"" and p.stderr == b""
    p = run(args, tmp_path)
    assert p.returncode == 2 and b"exists; use --force" in p.stderr
    p = run([*args, "-f", "-v"], tmp_path)
    assert p.returncode == 0 and b"chunks   MHDR" in p.stdout
    p = run(["mpz", "decode", "x.mpz", "-o", "x.trc", "-q"], tmp_path)
    assert p.returncode == 0 and p.stdout == b"" and p.stderr == b""
    p = run(["mpz", "decode", "x.mpz", "-o", "x.trc", "-f", "-v"], tmp_path)
    assert p.returncode == 0 and b"source: walk.c3d" in p.stdout


# -- 6. units --------------------------------------------------------------------------------

def test_a_bound_without_a_unit_is_refused_with_the_accepted_units(inputs: dict[str, Path],
                                                                    tmp_path: Path) -> None:
    for opt in (["--max-error", "1"], ["--max-error", "1mm", "--grid", "0.5"]):
        p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "x.mpz", *opt], tmp_path)
        assert p.returncode == 2, p.stderr
        err = p.stderr.decode()
        assert all(u in err for u in ("mm", "cm", "m", "in")) and "unit" in err
        assert not (tmp_path / "x.mpz").exists()
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "x.mpz", "--max-error", "2furlong"],
            tmp_path)
    assert p.returncode == 64 and b"unknown unit" in p.stderr       # no input needed to judge
    p = run(["mpz", "compare", str(inputs["c3d"]), str(inputs["mpz"]), "--bound", "1furlong"],
            tmp_path)
    assert p.returncode == 64 and b"unknown unit" in p.stderr
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "x.mpz", "--max-error", "0.1cm"],
            tmp_path)
    assert p.returncode == 0, p.stderr
    assert mpz.info(tmp_path / "x.mpz").error_bound == pytest.approx(1.0)   # 0.1 cm = 1 mm


def test_the_python_api_takes_plain_numbers_and_says_so() -> None:
    doc = inspect.getdoc(mpz.encode) or ""
    assert "motion's" in doc and "units" in doc
    sig = inspect.signature(mpz.encode)
    assert sig.parameters["max_error"].kind is inspect.Parameter.KEYWORD_ONLY
    assert sig.parameters["max_error"].annotation in ("float | None", float | None)


# -- 7. output names ---------------------------------------------------------------------------

def test_decode_refuses_a_mismatched_extension_unless_forced(inputs: dict[str, Path],
                                                             tmp_path: Path) -> None:
    p = run(["mpz", "decode", str(inputs["mpz"]), "-o", "x.npy", "--format", "trc"], tmp_path)
    assert p.returncode == 2 and b"--force" in p.stderr
    assert not (tmp_path / "x.npy").exists()
    p = run(["mpz", "decode", str(inputs["mpz"]), "-o", "x.npy", "--format", "trc", "-f"],
            tmp_path)
    assert p.returncode == 0
    assert (tmp_path / "x.npy").read_bytes().startswith(b"PathFileType")
    p = run(["mpz", "decode", str(inputs["mpz"]), "-o", "back.xyz"], tmp_path)
    assert p.returncode == 2 and b"back.xyz: cannot write '.xyz'" in p.stderr
    assert b".part" not in p.stderr and os.listdir(tmp_path) == ["x.npy"]


def test_a_trc_from_bvh_never_has_an_empty_units_field(inputs: dict[str, Path],
                                                       tmp_path: Path) -> None:
    bvh = read(inputs["bvh"])
    assert bvh.units == ""                                 # BVH does not say its units
    (tmp_path / "arm.mpz").write_bytes(mpz.encode(bvh, max_error=0.01))
    p = run(["mpz", "decode", "arm.mpz", "-o", "arm.trc"], tmp_path)
    if p.returncode == 0:                                  # units declared: they are written
        header = (tmp_path / "arm.trc").read_text().splitlines()
        fields = dict(zip(header[1].split("\t"), header[2].split("\t"), strict=False))
        assert fields["Units"] in ("mm", "cm", "m", "in")
    else:
        assert p.returncode == 2 and b"TRC needs units" in p.stderr
        assert not (tmp_path / "arm.trc").exists()


def test_options_that_exclude_each_other_are_usage_errors(inputs: dict[str, Path],
                                                          tmp_path: Path) -> None:
    """README: options that exclude each other exit 64, judged before any input is read.
    --lossy with --group-error exited 2, an input error (a QA reader of the docs)."""
    for opt in (["--lossy", "--max-error", "1mm"], ["--lossy", "--group-error", "l_foot=1mm"]):
        p = run(["mpz", "encode", "missing.c3d", "-o", "x.mpz", *opt], tmp_path)
        assert p.returncode == 64, (opt, p.stderr)
        assert b"lossy" in p.stderr and b"missing.c3d" not in p.stderr
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "x.mpz", "--max-error", "1mm",
             "--group-error", "l_foot=0.5mm"], tmp_path)
    assert p.returncode == 0, p.stderr                    # bounds given together: fine


# -- 9. option errors --------------------------------------------------------------------------

def test_option_errors_come_from_the_subcommand_with_a_hint(inputs: dict[str, Path],
                                                            tmp_path: Path) -> None:
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "x.mpz", "--max-eror", "1mm"],
            tmp_path)
    err = p.stderr.decode()
    assert p.returncode == 64
    assert err.startswith("usage: mpz encode")
    assert "did you mean --max-error?" in err
    p = run(["mpz", "decode", str(inputs["mpz"]), "--fromat", "csv"], tmp_path)
    assert p.returncode == 64 and b"usage: mpz decode" in p.stderr
    assert b"did you mean --format?" in p.stderr
    # a unit written apart from its number (a newcomer's QA run: "unrecognized arguments:
    # mm" alone)
    for args in (["encode", str(inputs["c3d"]), "-o", "y.mpz", "--max-error", "1", "mm"],
                 ["compare", str(inputs["c3d"]), str(inputs["mpz"]), "--bound", "2", "cm"]):
        p = run(["mpz", *args], tmp_path)
        assert p.returncode == 64 and b"a length takes its unit without a space" in p.stderr
    p = run(["mpz", "encdoe"], tmp_path)
    assert p.returncode == 64 and b"did you mean encode?" in p.stderr
    # difflib's nearest word was the opposite ("--lossless: did you mean --lossy?"), or none
    # ("mpz info"): an animation studio's QA run of stop 75
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "y.mpz", "--lossless"], tmp_path)
    assert p.returncode == 64 and b"MPZ has no lossless flag" in p.stderr
    assert b"did you mean --lossy" not in p.stderr
    p = run(["mpz", "info", str(inputs["mpz"])], tmp_path)
    assert p.returncode == 64 and b"mpz show gives what a file holds" in p.stderr
    p = run(["mpz", "decode", str(inputs["mpz"]), "-o", "y.npy", "--lossless"], tmp_path)
    assert p.returncode == 64 and b"lossless flag" not in p.stderr     # encode's advice


def test_a_negative_length_and_a_value_out_of_range_name_the_flag(
        inputs: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    """A newcomer's QA run (stop 73): --max-error -1mm said only "expected one argument",
    --max-error=-1mm "cannot read a length ...; write a number and a unit" (it is one),
    and the encoder's range checks named the Python option (threads, lossy, max_error) to
    a reader of the command line. Each now says what is wrong, naming the flag."""
    from mpz.tools import mpz_cli
    src = str(inputs["trc"])
    cases = [(["--max-error", "-1mm"], "argument --max-error: expected one argument; a "
              "length must be above 0, and -1mm reads as an option"),
             (["--max-error=-1mm"], "--max-error -1mm: a length must be above 0"),
             (["--max-error=+1mm"], "--max-error +1mm: a length must be above 0, without "
              "a sign"),
             (["--threads", "0"], "--threads must be in 1..64, got 0"),
             (["--smoothing", "17"], "--smoothing must be in 0..16, got 17"),
             (["--lossy", "--max-error", "1mm"], "--lossy (the paper's unbounded mode) and a "
              "bound (--max-error) exclude each other")]
    for args, said in cases:
        code = 0
        try:
            code = mpz_cli.main(["encode", src, "-o", "neg.mpz", *args])
        except SystemExit as exc:
            code = int(exc.code or 0)
        err = capsys.readouterr().err
        assert code in (2, 64) and said in err, (args, err)
    # a program is told the Python name
    with pytest.raises(mpz.errors.EncoderError, match=r"^threads must be in 1\.\.64"):
        mpz.encode(generate("walk", frames=12), threads=0)


def test_the_encoder_s_flag_options_are_flags_of_mpz_encode() -> None:
    """mpz.encoder.FLAG_OPTIONS names options by the flag "--" + name with "-" for "_":
    each must be a flag of mpz encode, and an option of EncodeOptions."""
    from dataclasses import fields

    from mpz.encoder import FLAG_OPTIONS, EncodeOptions
    from mpz.tools import mpz_cli
    sub = next(a for a in mpz_cli.build_parser()._actions
               if isinstance(a, argparse._SubParsersAction))
    flags = {s for a in sub.choices["encode"]._actions for s in a.option_strings}
    names = {f.name for f in fields(EncodeOptions)}
    assert {n for n in FLAG_OPTIONS if "--" + n.replace("_", "-") not in flags} == set()
    assert FLAG_OPTIONS <= names


def test_an_option_of_another_subcommand_is_named_as_such(
        inputs: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    """`mpz decode walk.mpz -o back.trc --units cm` (a newcomer reading the README's
    decode line) was told "did you mean --quiet?; a length takes its unit without a space":
    the unit was --units' value, and --units is encode's (a QA run of stop 62)."""
    from mpz.tools import mpz_cli
    cases = [(["decode", str(inputs["mpz"]), "-o", "back.trc", "--units", "cm"],
              "unrecognized arguments: --units cm; --units is an option of mpz encode"),
             (["show", str(inputs["mpz"]), "--max-error=1mm"],
              "--max-error is an option of mpz encode"),
             (["decode", str(inputs["mpz"]), "--fromat", "csv"], "did you mean --format?"),
             # both hints, and a short option (the review of stop 62)
             (["decode", str(inputs["mpz"]), "--units", "cm", "--fromat", "x"],
              "--units is an option of mpz encode; did you mean --format?"),
             (["show", str(inputs["mpz"]), "-o", "x.trc"],
              "-o is an option of mpz decode and mpz encode")]
    for argv, said in cases:
        with pytest.raises(SystemExit) as exc:
            mpz_cli.main(argv)
        err = capsys.readouterr().err
        assert exc.value.code == 64 and said in err, err
        assert "without a space" not in err and "--quiet" not in err, err
    # a unit after an option that holds its value already is a unit apart from its number
    with pytest.raises(SystemExit):
        mpz_cli.main(["encode", str(inputs["trc"]), "-o", "y.mpz", "--max-eror=1", "mm"])
    assert "a length takes its unit without a space" in capsys.readouterr().err


def test_an_unknown_option_is_named_when_an_argument_is_missing_too(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """argparse says what is missing before what it did not know: ``mpz --bogus`` and
    ``mpz encode -walk.c3d`` (a file whose name begins with -) said only "the following
    arguments are required" (a QA run of the CLI plumbing). The unknown word is named,
    with the cure for a file name that begins with -."""
    from mpz.tools import mpz_cli, mpzinfo
    (tmp_path / "-walk.c3d").write_bytes(b"")
    monkeypatch.chdir(tmp_path)
    cases = [(mpz_cli.main, ["--bogus"], "mpz: error: unrecognized arguments: --bogus"),
             (mpz_cli.main, ["encode", "-q", "-walk.c3d"],
              "mpz encode: error: unrecognized arguments: -walk.c3d; -walk.c3d is a file: "
              "put -- before a file name that begins with -, or write ./-walk.c3d"),
             (mpz_cli.main, ["show", "--jsn"],
              "unrecognized arguments: --jsn; did you mean --json?"),
             (mpzinfo.main, ["--bogus"], "mpzinfo: error: unrecognized arguments: --bogus")]
    for main, argv, said in cases:
        with pytest.raises(SystemExit) as exc:
            main(argv)
        err = capsys.readouterr().err
        assert exc.value.code == 64 and said in err, (argv, err)
    # what is only missing is still said so: an option's value, an abbreviation, -qf
    for argv in (["encode", "-o", "x.mpz"], ["encode", "--max-err", "1mm"], ["encode", "-qf"],
                 ["summary", "--k", "6"]):
        with pytest.raises(SystemExit) as exc:
            mpz_cli.main(argv)
        err = capsys.readouterr().err
        assert exc.value.code == 64 and "the following arguments are required" in err, err


def test_the_group_error_example_in_the_help_works(inputs: dict[str, Path],
                                                   tmp_path: Path) -> None:
    p = run(["mpz", "encode", "--help"], tmp_path)
    example = "l_foot=0.5mm"
    assert example in p.stdout.decode()
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "x.mpz", "--max-error", "2mm",
             "--hierarchy", "cmu41", "--group-error", example], tmp_path)
    assert p.returncode == 0, p.stderr
    orig, back = read(inputs["c3d"]), mpz.decode(tmp_path / "x.mpz")
    feet = [orig.names.index(n) for n in ("LHEE", "LTOE", "LMT5")]
    d = np.linalg.norm(orig.positions[:, feet] - back.positions[:, feet], axis=2)
    assert d[orig.valid[:, feet]].max() <= 0.5 + 1e-9


def test_seed_is_the_apis_seed(inputs: dict[str, Path], tmp_path: Path) -> None:
    """``--seed`` (the clustering's, with patterns) was in the API only (a QA note): the
    same seed gives the API's bytes, another seed other patterns."""
    from mpz.tools import mpz_cli
    src = inputs["c3d"]
    for seed in (0, 7):
        assert mpz_cli.main(["encode", str(src), "-o", str(tmp_path / f"{seed}.mpz"),
                             "--lossy", "--seed", str(seed), "-q"]) == 0
        want = mpz.encode(read(src), lossy=True, seed=seed,
                          metadata={"source": src.name})
        assert (tmp_path / f"{seed}.mpz").read_bytes() == want
    assert (tmp_path / "0.mpz").read_bytes() != (tmp_path / "7.mpz").read_bytes()


# -- 10. the Python API --------------------------------------------------------------------------

def test_mpz_io_is_there_after_import_mpz() -> None:
    p = subprocess.run([sys.executable, "-c", "import mpz; print(mpz.io.read.__name__)"],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and p.stdout.strip() == "read", p.stderr


def test_decode_takes_a_path_bytes_or_a_binary_file(inputs: dict[str, Path]) -> None:
    path = inputs["mpz"]
    data = path.read_bytes()
    ref = mpz.decode(data)
    for source in (path, str(path), bytearray(data), memoryview(data), io.BytesIO(data)):
        m = mpz.decode(source)
        assert m.names == ref.names and np.array_equal(m.as_nan(), ref.as_nan(),
                                                       equal_nan=True)
    with open(path, "rb") as fh:
        assert mpz.decode(fh).n_frames == ref.n_frames
    # a file object is read up to the end of the MPZ file, not beyond (as np.load does)
    stream = io.BytesIO(data + b"next record")
    assert mpz.decode(stream).n_frames == ref.n_frames
    assert stream.read() == b"next record"
    with pytest.raises(TypeError):
        mpz.decode(12345)  # type: ignore[arg-type]
    with pytest.raises(mpz.FormatError, match="no such file"):
        mpz.decode(path.parent / "missing.mpz")


def test_encode_keywords_are_the_encode_options() -> None:
    import dataclasses
    params = {n: p for n, p in inspect.signature(mpz.encode).parameters.items()
              if p.kind is not inspect.Parameter.VAR_KEYWORD}
    fields = {f.name: f for f in dataclasses.fields(mpz.EncodeOptions)}
    assert list(params)[0] == "motion"
    assert set(params) - {"motion"} == set(fields)
    for name, f in fields.items():
        p = params[name]
        assert p.kind is inspect.Parameter.KEYWORD_ONLY, name
        if f.default is not dataclasses.MISSING:
            assert p.default == f.default, name
        else:                                          # a mapping: None means empty
            assert p.default is None and f.default_factory() == {}, name  # type: ignore[misc]
    with pytest.raises(mpz.EncoderError, match="did you mean max_error"):
        mpz.encode(generate("walk", frames=10), max_eror=1.0)  # type: ignore[arg-type]


def test_info_reads_the_facts_without_decoding(inputs: dict[str, Path]) -> None:
    from mpz import container
    data = inputs["mpz"].read_bytes()
    # damage the RESI payload (CRC repaired): the file no longer decodes, info still works
    chunks = container.parse(data)
    resi = next(c for c in chunks if c.type == "RESI")
    bad = bytearray(data)
    end = resi.offset + 8 + len(resi.payload)
    for i in range(end - 8, end):
        bad[i] ^= 0xA5
    bad_bytes = container.repair_crcs(bytes(bad))
    with pytest.raises(mpz.MPZError):
        mpz.decode(bad_bytes)
    fi = mpz.info(bad_bytes)
    m = generate("walk", frames=120, seed=3)
    assert (fi.frames, fi.markers, fi.rate, fi.units) == (120, 41, 120.0, "mm")
    assert list(fi.names) == m.names and fi.error_bound == 1.0
    assert fi.duration == pytest.approx(1.0)
    assert (REPO / "docs" / "partial-decode.md").is_file()


# -- 11. plots ------------------------------------------------------------------------------

@pytest.mark.parametrize("command", ["compare", "summary"])
def test_a_plot_replaces_a_file_only_with_force_and_needs_a_known_extension(
        command: str, inputs: dict[str, Path], tmp_path: Path) -> None:
    """QA, stop 33: --plot replaced any existing file (a C3D, another figure) without
    --force, against the README's rule for outputs, and an extension matplotlib cannot
    write raised its ValueError as a traceback after the work."""
    pytest.importorskip("matplotlib")
    src = ([str(inputs["c3d"]), str(inputs["mpz"])] if command == "compare"
           else [str(inputs["c3d"]), "--k", "6,12"])
    (tmp_path / "keep.png").write_bytes(b"precious")
    for target, extra, code, said in (("keep.png", [], 2, "exists; use --force"),
                                      ("plot.txt", [], 2, "matplotlib writes"),
                                      ("noext", [], 2, "not a file without an extension"),
                                      ("keep.png", ["--force"], 0, "")):
        p = run(["mpz", command, *src, "--plot", target, *extra], tmp_path)
        assert p.returncode == code, (target, p.stderr)
        assert said.encode() in p.stderr and b"Traceback" not in p.stderr, p.stderr
    assert (tmp_path / "keep.png").read_bytes().startswith(b"\x89PNG")   # replaced, with -f
    assert not (tmp_path / "plot.txt").exists() and not (tmp_path / "noext").exists()


def test_compare_plot_shows_the_error_over_time_with_the_bound(inputs: dict[str, Path],
                                                               tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    p = run(["mpz", "compare", str(inputs["c3d"]), str(inputs["mpz"]), "--plot", "e.png"],
            tmp_path)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "e.png").read_bytes().startswith(b"\x89PNG")
    # the figure itself: error (not positions) per marker, the bound line, units, one legend
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from mpz.tools import cmd_compare
    a, b = read(inputs["c3d"]), mpz.decode(inputs["mpz"])
    figures: list[Figure] = []
    import matplotlib.pyplot as plt
    orig_close = plt.close
    plt.close = lambda fig=None: figures.append(fig)  # type: ignore[assignment]
    try:
        cmd_compare.plot(a, b, ["LHEE", "RTOE"], str(tmp_path / "f.png"), bound=1.0)
    finally:
        plt.close = orig_close  # type: ignore[assignment]
    fig = figures[0]
    axes = fig.get_axes()
    assert len(axes) == 2
    for ax in axes:
        assert ax.get_ylabel() == "error (mm)"
        ys = [line.get_ydata() for line in ax.get_lines()]
        bound_lines = [y for y in ys if len(y) == 2 and np.allclose(y, 1.0)]
        assert bound_lines, "the bound is drawn as a line in every panel"
        err = [np.asarray(y, float) for y in ys if len(y) == a.n_frames][0]
        assert np.nanmax(err) <= 1.0 + 1e-9 and np.nanmin(err) >= 0   # errors, not positions
    assert axes[-1].get_xlabel() == "time (s)"
    assert len(fig.legends) == 1                       # one legend, for every panel
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any("bound 1 mm" in t for t in texts)


def test_summary_colours_are_distinct_and_thumbnails_explained(inputs: dict[str, Path],
                                                               tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from mpz.tools.cmd_summary import segment_colours
    for k in (6, 12, 20, 48, 200):
        cols = segment_colours(k)
        assert len(set(cols)) == k, k                 # no colour repeats (tab10 did from 11)
        gaps = [math.dist(cols[i], cols[i + 1]) for i in range(k - 1)]
        assert min(gaps) > 0.15, k                     # neighbours are told apart
    p = run(["mpz", "summary", str(inputs["c3d"]), "--k", "6,12,24", "--plot", "s.png"],
            tmp_path)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "s.png").read_bytes().startswith(b"\x89PNG")


# -- 12. the summary chunk ---------------------------------------------------------------------

def test_encode_reports_the_summary_chunk_and_summary_shows_units(inputs: dict[str, Path],
                                                                  tmp_path: Path) -> None:
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "s.mpz", "--max-error", "2mm",
             "--summary", "4,8"], tmp_path)
    assert p.returncode == 0, p.stderr
    size = mpz.info(tmp_path / "s.mpz").chunk_bytes["smrc"]    # the 1.1 default (§4.15)
    line = [ln for ln in p.stdout.decode().splitlines() if "smrc chunk" in ln]
    shown = f"{size} B" if size < 1024 else f"{size / 1024:.1f} KiB"
    assert len(line) == 1 and shown in line[0]
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "s2.mpz", "--max-error", "2mm",
             "--summary", "4,8", "--json"], tmp_path)
    assert strict_json(p.stdout)["summary_bytes"] == size  # type: ignore[index]
    p = run(["mpz", "summary", "s.mpz"], tmp_path)
    assert p.returncode == 0, p.stderr
    text = p.stdout.decode()
    assert "RMS per frame" in text
    rms_line = [ln for ln in text.splitlines() if "RMS per frame" in ln][0]
    # every marker of a pose together, then one marker's: per frame / sqrt(markers)
    got = re.search(r"RMS per frame ([\d.e+-]+) mm \(all (\d+) markers; per marker "
                    r"([\d.e+-]+) mm\)$", rms_line.rstrip())
    assert got, rms_line
    frame, markers, marker = float(got[1]), int(got[2]), float(got[3])
    assert markers == read(inputs["c3d"]).n_markers
    assert marker == pytest.approx(frame / math.sqrt(markers), rel=2e-3)
    rows = [ln.split() for ln in text.splitlines() if ln.strip()[:1].isdigit()]
    shares = [float(r[-1]) for r in rows]
    assert rows and all(math.isfinite(s) for s in shares)   # the WSSSE % column is filled
    assert sum(shares[:4]) == pytest.approx(100.0, abs=0.3)



def test_summary_of_an_mpz_without_a_summary_chunk_segments_its_motion(tmp_path: Path) -> None:
    """`mpz summary x.mpz` of a file encoded without --summary segments the decoded motion,
    as for any motion file, and says so (a QA run of stop 47: it was refused); with
    --no-decode there is nothing to segment (exit 2, said). At k = 1 the WSSSE is the
    series' total squared deviation from its mean, here the marker positions relative to
    their centroid, computed with numpy from the decoded motion."""
    m = generate("walk", frames=90, markers=8, seed=3)
    assert m.valid.all()
    write(m, tmp_path / "w.trc")
    p = run(["mpz", "encode", "w.trc", "-o", "w.mpz", "--max-error", "1mm", "-q"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert mpz.info(tmp_path / "w.mpz").summary_levels == ()
    p = run(["mpz", "summary", "w.mpz", "--k", "1,3", "--json"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert b"note: w.mpz has no summary chunk" in p.stderr
    doc = strict_json(p.stdout)
    levels = {lv["k"]: lv for lv in doc["levels"]}  # type: ignore[index]
    pos = mpz.decode(tmp_path / "w.mpz").positions
    rel = (pos - pos.mean(axis=1, keepdims=True)).reshape(len(pos), -1)
    total = float(((rel - rel.mean(axis=0)) ** 2).sum())
    assert levels[1]["wssse"] == pytest.approx(total, rel=1e-9)
    assert levels[3]["wssse"] < levels[1]["wssse"]
    p = run(["mpz", "summary", "w.mpz", "--no-decode"], tmp_path)
    assert p.returncode == 2 and b"--no-decode leaves nothing to segment" in p.stderr


# -- 13. small things ----------------------------------------------------------------------------

def test_no_runtime_warning_from_metrics_on_gap_only_markers() -> None:
    from mpz import Motion
    from mpz.metrics import arms, summary
    rng = np.random.default_rng(0)
    pos = rng.normal(size=(6, 3, 3))
    valid = np.ones((6, 3), bool)
    valid[:, 1] = False                                   # a marker that is never seen
    valid[3] = False                                      # a frame without any marker
    a = Motion(pos, ["a", "b", "c"], 10.0, "mm", valid)
    b = Motion(pos + 0.1, ["a", "b", "c"], 10.0, "mm", valid)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = summary(a, b)
        assert arms(a, b) == pytest.approx(math.sqrt(0.03))
    assert s["per_marker_rms"]["b"] is None and s["per_marker_max"]["b"] is None


def _on_a_terminal(args: list[str], env: dict[str, str], cwd: Path, *,
                   until: bytes | None = None) -> bytes:
    """What ``args`` writes on standard error when that is a terminal (a pty); with
    ``until``, the command is stopped (SIGTERM) once that has been written."""
    import pty
    master, slave = pty.openpty()
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=slave, env=env, cwd=cwd)
    os.close(slave)
    out = b""
    while True:
        try:
            chunk = os.read(master, 1024)
        except OSError:
            break
        if not chunk:
            break
        out += chunk
        if until is not None and until in out and proc.poll() is None:
            proc.terminate()
    code = proc.wait(timeout=600)
    assert code == 0 or (until is not None and code == -signal.SIGTERM), (code, out)
    os.close(master)
    return out


def test_first_run_compile_notice_on_a_terminal_only(inputs: dict[str, Path],
                                                     tmp_path: Path) -> None:
    """The notice comes before the first kernel is compiled, so each run is stopped once
    that has begun: the notice seen on the terminal, or numba's first index file written
    in the pipe's cache (a whole compile is 20-30 s, twice over, of CI's 15 minutes)."""
    # the kernels shipped with the package off, so that a first run compiles
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"),
               MPZ_SHIPPED_KERNELS="0")
    env.pop("MPZ_CACHE_DIR", None)
    args = [command("mpz"), "encode", str(inputs["trc"]), "-o", "-", "--max-error", "1mm"]
    # standard error is a pipe: no notice, even when compiling (run beside the next case,
    # with its own empty cache)
    with open(tmp_path / "out.mpz", "wb") as sink:
        piped = subprocess.Popen(args, stdout=sink, stderr=subprocess.PIPE, env=env,
                                 cwd=tmp_path)
    # standard error is a terminal and the cache is empty: one line that says why it waits
    out = _on_a_terminal(args, {**env, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache-2")},
                         tmp_path, until=b"later runs)")
    deadline = time.monotonic() + 600
    compiled: list[Path] = []
    while not compiled and piped.poll() is None and time.monotonic() < deadline:
        compiled = list((tmp_path / "numba-cache").rglob("*.nbi"))
        time.sleep(0.05)
    piped.terminate()
    _, err = piped.communicate(timeout=600)
    assert compiled, "the piped run compiled nothing: the case tests nothing"
    assert err is not None and b"compiling" not in err, err
    assert out.count(b"compiling") == 1 and b"first run" in out


def _sigint_blocked(pid: int) -> bool:
    """Whether the process's main thread blocks SIGINT (Linux's /proc)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    found = re.search(r"^SigBlk:\s*(\w+)", status, re.M)
    return found is not None and bool(int(found.group(1), 16) >> (signal.SIGINT - 1) & 1)


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc")
@pytest.mark.parametrize("argv", [
    ["mpz", "encode", "-", "-o", "never.mpz"],          # then waits for standard input
    ["mpz-conformance", "--decoder", "sleep 60", "--only", "v01"],
    ["mpzinfo", "-"],
], ids=["mpz", "mpz-conformance", "mpzinfo"])
def test_ctrl_c_while_the_command_imports_is_one_line(argv: list[str], tmp_path: Path) -> None:
    """A Ctrl-C in the first second, while Python imports numpy, numba and Dask, printed a
    KeyboardInterrupt traceback and the command died by the signal (QA of stop 31, on the
    real data: 2 of 5 runs of `mpz encode -r`). The command blocks SIGINT from its first
    import (mpz._worker) until its main, which reports it. The signal is sent once the
    block is seen, so it lands in the imports or, at worst, in main."""
    if argv[0] == "mpz-conformance":
        from mpz.conformance import manifest as mf
        argv = [*argv[:-1], next(v["name"] for v in mf.load()["vectors"]
                                 if v["group"] == "valid")]
    proc = subprocess.Popen([command(argv[0]), *argv[1:]], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
    deadline = time.monotonic() + 60
    while not _sigint_blocked(proc.pid) and proc.poll() is None \
            and time.monotonic() < deadline:
        time.sleep(0.001)
    held = _sigint_blocked(proc.pid)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert held, "the command never blocked SIGINT while it imported"
    assert proc.returncode == 130, err
    assert err.decode().strip().splitlines() == [
        "interrupted" if argv[0] == "mpz" else f"{argv[0]}: interrupted"], err


def _kernel_interrupt(depth: int, first: BaseException | None = None) -> SystemError:
    """What a numba kernel raises when a Ctrl-C lands in one of its Python callbacks:
    SystemError "returned a result with an exception set", each the direct cause of the
    next, the KeyboardInterrupt first (the QA of stop 42: _fisher_tables, _fit_range); or
    ``first``, the SystemExit that SIGTERM raises (signals_exit)."""
    exc: BaseException = KeyboardInterrupt() if first is None else first
    for _ in range(depth):
        outer = SystemError("CPUDispatcher(<function _fit_range>) returned a result with "
                            "an exception set")
        outer.__cause__ = exc
        exc = outer
    assert isinstance(exc, SystemError)
    return exc


def test_a_ctrl_c_a_kernel_heard_is_reported_as_interrupted(capsys) -> None:
    """Before, it ended the command with a SystemError traceback and exit 1; any other
    SystemError is still a bug: its traceback, then exit 70 (EXIT_BUG)."""
    from mpz.tools._cli import EXIT_BUG, EXIT_INTERRUPTED, interrupted, reports_ctrl_c
    assert interrupted(_kernel_interrupt(1)) and interrupted(_kernel_interrupt(3))
    other = SystemError("a bug")
    other.__cause__ = ValueError()
    assert not interrupted(other) and not interrupted(SystemError("a bug"))
    wrapped = SystemError("in a handler")
    wrapped.__context__ = KeyboardInterrupt()                # not the cause: not taken
    assert not interrupted(wrapped)

    def raises(exc: BaseException) -> int:
        raise exc

    main = reports_ctrl_c("interrupted")(raises)
    assert main(_kernel_interrupt(2)) == EXIT_INTERRUPTED
    assert capsys.readouterr().err == "interrupted\n"
    assert main(other) == EXIT_BUG
    err = capsys.readouterr().err
    assert "SystemError: a bug" in err and "mpz: internal error: this is a bug" in err


def test_a_sigterm_a_kernel_heard_exits_as_sigterm(tmp_path: Path, monkeypatch,
                                                  capsys) -> None:
    """SIGTERM (signals_exit's SystemExit 143) that lands inside a kernel came as a chain
    of SystemErrors: a traceback and "internal error", exit 70 (a review of stop 56, 4 of 6
    tries of a `--jobs 0` corpus run). It is the exit SIGTERM asked for, and a corpus run
    says how far it got, as for a Ctrl-C there."""
    from mpz.tools import mpz_cli
    from mpz.tools._cli import reports_ctrl_c, signal_in
    term = _kernel_interrupt(2, SystemExit(143))
    assert isinstance(signal_in(term), SystemExit) and signal_in(SystemError("x")) is None

    def raises(exc: BaseException) -> int:
        raise exc
    with pytest.raises(SystemExit) as got:
        reports_ctrl_c("interrupted")(raises)(term)
    assert got.value.code == 143 and capsys.readouterr().err == ""

    import mpz.corpus
    src = tmp_path / "src"
    src.mkdir()
    for i in range(3):
        write(generate("walk", frames=20, seed=i), src / f"w{i}.trc")

    def one_then(signal_exc: BaseException):
        def run(jobs, *args, progress, **kwargs):
            from mpz.corpus import FileResult
            progress(1, len(jobs), FileResult(jobs[0][0], jobs[0][1], "encoded"))
            raise _kernel_interrupt(2, signal_exc)
        return run

    argv = ["encode", "-r", str(src), "-o", f"{tmp_path / 'out'}/", "--jobs", "0"]
    monkeypatch.setattr(mpz.corpus, "encode_corpus", one_then(SystemExit(143)))
    assert mpz_cli.main(argv) == 143
    err = capsys.readouterr().err
    assert "terminated (signal 15): 1 of 3 files finished: 1 written, each in the index" in err, err
    assert "Traceback" not in err and "internal error" not in err
    monkeypatch.setattr(mpz.corpus, "encode_corpus", one_then(KeyboardInterrupt()))
    assert mpz_cli.main(argv) == 130
    err = capsys.readouterr().err
    assert "1 of 3 files finished before the interrupt" in err and err.endswith(
        "interrupted\n"), err
    assert "run the same command again to encode the rest" in err

    def kept_then(signal_exc: BaseException):
        def run(jobs, *args, progress, **kwargs):
            from mpz.corpus import FileResult
            progress(1, len(jobs), FileResult(jobs[0][0], jobs[0][1], "skipped"))
            progress(2, len(jobs), FileResult(jobs[1][0], jobs[1][1], "kept"))
            raise signal_exc
        return run

    # files up to date were said "written and indexed" (an archive team's QA, stop 72)
    monkeypatch.setattr(mpz.corpus, "encode_corpus", kept_then(KeyboardInterrupt()))
    assert mpz_cli.main(argv) == 130
    err = capsys.readouterr().err
    assert "2 of 3 files finished before the interrupt: 2 already up to date, each in the " \
        "index; run the same command again" in err, err

    def all_then(signal_exc: BaseException):
        def run(jobs, *args, progress, **kwargs):
            from mpz.corpus import FileResult
            for i, job in enumerate(jobs):
                progress(i + 1, len(jobs), FileResult(job[0], job[1], "encoded"))
            raise signal_exc
        return run

    # a Ctrl-C as the cluster closed, every file done: it said "3 of 3 files finished
    # ... run the same command again to encode the rest" (a QA run of stop 57)
    monkeypatch.setattr(mpz.corpus, "encode_corpus", all_then(KeyboardInterrupt()))
    assert mpz_cli.main(argv) == 130
    err = capsys.readouterr().err
    assert "all 3 files finished before the interrupt: 3 written, each in the index\n" in err, err
    assert "again" not in err
    monkeypatch.setattr(mpz.corpus, "encode_corpus", all_then(SystemExit(143)))
    assert mpz_cli.main(argv) == 143
    err = capsys.readouterr().err
    assert "terminated (signal 15): all 3 files finished: 3 written, each in the index\n" \
        in err, err


def test_a_run_stopped_with_its_log_left_says_to_copy_it(tmp_path, monkeypatch, capsys):
    """A corpus QA run of stop 76: a full disk stopped the run with its rows in
    index.sqlite-wal, which could not be folded back, so a copy of index.sqlite alone was
    an empty index. The run says so when the log is left, and not otherwise."""
    from mpz.corpus import CorpusReport, CorpusStopped
    from mpz.tools import mpz_cli
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    write(generate("walk", frames=30, seed=1), src / "a.trc")
    out.mkdir()
    index = out / "index.sqlite"

    def stops(jobs, *args, **kwargs):
        report = CorpusReport([], 0.1, 1, "this process", str(index),
                              stopped="cannot write the index: database or disk is full")
        raise CorpusStopped(report.stopped, report)

    monkeypatch.setattr(mpz.corpus, "encode_corpus", stops)
    argv = ["encode", "-r", str(src), "-o", f"{out}/", "--jobs", "0", "-q"]
    assert mpz_cli.main(argv) == 2
    assert "-wal" not in capsys.readouterr().err
    (out / "index.sqlite-wal").write_bytes(b"log")
    assert mpz_cli.main(argv) == 2
    err = capsys.readouterr().err
    assert f"note: the index's rows are partly in {index}-wal (it could not be folded into " \
        "the index: a full disk, or another program holding the index open): copy it with " \
        "the index, or run again" in err, err


def test_an_interrupt_before_any_file_finished_says_none_written() -> None:
    """A corpus QA run of stop 76: a Ctrl-C during the cluster's start said "0 of 47 files
    finished before the interrupt: none written, each in the index"."""
    from mpz.corpus import FileResult
    from mpz.tools._corpus_cli import _Bar
    bar = _Bar(False)
    assert (bar.finished(47), bar.kinds()) == ("0 of 47 files finished", "none written")
    bar(1, 3, FileResult("a.trc", "a.mpz", "skipped"))
    assert bar.kinds() == "1 already up to date, each in the index"


class _DropsASignal:
    """An object whose finalizer receives ``signum`` (its handler runs inside ``__del__``,
    as a Ctrl-C once landed in llvmlite's ``ObjectRef.__del__``): Python drops the
    exception the handler raises there, "Exception ignored in ..."."""

    def __init__(self, signum: int) -> None:
        self.signum = signum

    def __del__(self) -> None:
        signal.raise_signal(self.signum)
        total = 0
        for i in range(100):          # instructions, where Python runs the handler
            total += i


def _works_on(seconds: float = 5.0) -> int:
    """The rest of a command's work: ``seconds`` of small steps, then 0 (done)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        time.sleep(0.001)
    return 0


def test_a_ctrl_c_a_finalizer_dropped_is_heard_again(capsys) -> None:
    """Python drops a KeyboardInterrupt raised inside a finalizer and goes on: 1 in 60
    interrupted runs of `mpz encode` finished the encode and exited 0 (stops 55-56). The
    command now hears it again a moment later, says "interrupted", exits 130, and Python's
    "Exception ignored" is not printed."""
    from mpz.tools._cli import EXIT_INTERRUPTED, reports_ctrl_c

    def main() -> int:
        _DropsASignal(signal.SIGINT)               # finalized at once
        return _works_on()

    started = time.monotonic()
    assert reports_ctrl_c("interrupted")(main)() == EXIT_INTERRUPTED
    assert time.monotonic() - started < 2.5          # heard at once, not after the work
    err = capsys.readouterr().err
    assert err == "interrupted\n", err


def test_a_sigterm_a_finalizer_dropped_is_heard_again(capsys) -> None:
    """The same for SIGTERM under signals_exit (SystemExit 143 raised in a finalizer)."""
    from mpz.api import signals_exit
    from mpz.tools._cli import reports_ctrl_c

    def main() -> int:
        with signals_exit(signal.SIGTERM):
            _DropsASignal(signal.SIGTERM)
            return _works_on()

    started = time.monotonic()
    with pytest.raises(SystemExit) as got:
        reports_ctrl_c("interrupted")(main)()
    assert got.value.code == 143 and time.monotonic() - started < 2.5
    assert "Exception ignored" not in capsys.readouterr().err


def _in_numba(seconds: float, done: list[bool], at_end=None) -> None:
    """Work for ``seconds`` in a function whose code, as far as a frame can tell, is
    numba's (its file name is in numba's folder; no file is written), call ``at_end``
    from it, then note it finished."""
    import numba
    src = ("def work(seconds, done, at_end):\n"
           "    import time\n"
           "    t = time.monotonic()\n"
           "    while time.monotonic() - t < seconds:\n"
           "        pass\n"
           "    if at_end is not None:\n"
           "        at_end()\n"
           "    done.append(True)\n")
    where = os.path.join(os.path.dirname(numba.__file__), "_mpz_test_stand_in.py")
    names: dict = {}
    exec(compile(src, where, "exec"), names)
    names["work"](seconds, done, at_end)


def test_a_ctrl_c_in_numba_s_code_is_put_off_until_the_main_thread_leaves_it(
        capsys) -> None:
    """A KeyboardInterrupt raised in numba's or llvmlite's Python code (a kernel's
    callbacks as it boxes a returned tuple, its loading from the cache) ended `mpz search`
    in a segmentation fault in 3 of 65 interrupted runs, `mpz encode` in 1 of 150 (a QA
    run of stop 57). The command puts the Ctrl-C off until the main thread has left that
    code, then says "interrupted" as always."""
    import threading

    from mpz.tools._cli import EXIT_INTERRUPTED, reports_ctrl_c
    done: list[bool] = []

    def main() -> int:
        threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGINT)).start()
        _in_numba(0.4, done)
        return _works_on()

    started = time.monotonic()
    assert reports_ctrl_c("interrupted")(main)() == EXIT_INTERRUPTED
    assert done == [True]                 # numba's code ran to its end
    assert time.monotonic() - started < 2.5
    assert capsys.readouterr().err == "interrupted\n"


def test_a_sigterm_in_numba_s_code_is_put_off_until_the_main_thread_leaves_it() -> None:
    """The same for SIGTERM under signals_exit (SystemExit 143 as the block wants it)."""
    import threading

    from mpz.api import signals_exit
    done: list[bool] = []
    with pytest.raises(SystemExit) as got, signals_exit(signal.SIGTERM):
        threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGTERM)).start()
        _in_numba(0.4, done)
        _works_on()
    assert got.value.code == 143 and done == [True]


def test_a_second_ctrl_c_is_not_put_off(capsys) -> None:
    """A review of stop 57: in a cold start's compile the main thread stays in numba's
    code for seconds, and a Ctrl-C waited 2-20 s; a second one was put off too. The
    second stops the command at once."""
    import threading

    from mpz.tools._cli import EXIT_INTERRUPTED, reports_ctrl_c
    done: list[bool] = []

    def main() -> int:
        for at in (0.05, 0.15):
            threading.Timer(at, os.kill, (os.getpid(), signal.SIGINT)).start()
        _in_numba(3.0, done)
        return _works_on()

    started = time.monotonic()
    assert reports_ctrl_c("interrupted")(main)() == EXIT_INTERRUPTED
    assert done == [] and time.monotonic() - started < 2.0
    assert capsys.readouterr().err == "interrupted\n"


def test_a_ctrl_c_still_put_off_when_its_block_ends_is_dropped() -> None:
    """The block ends while the main thread is still in numba's code (so the Ctrl-C is
    still put off): it is dropped, as a Ctrl-C after the work, and never raised later in
    the caller."""
    import contextlib
    import threading

    from mpz.tools._cli import ctrl_c_outside_compiler
    done: list[bool] = []
    with contextlib.ExitStack() as stack:
        stack.enter_context(ctrl_c_outside_compiler())
        threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGINT)).start()
        _in_numba(0.3, done, at_end=stack.close)
    time.sleep(0.2)                       # a KeyboardInterrupt raised later lands here
    assert done == [True] and signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_sigterm_still_put_off_when_its_block_ends_gets_the_action_it_has_then() -> None:
    """The same for SIGTERM under signals_exit: sent again once the block has put the
    old handler back, it ends the process by its default action. It was sent with the
    block's handler still in place: SystemExit 143 inside the block's cleanup, and that
    handler stayed for good (a review of stop 57)."""
    script = textwrap.dedent(f"""
        import contextlib, os, signal, sys, threading, time
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_cli_usage import _in_numba
        from mpz.api import signals_exit
        with contextlib.ExitStack() as stack:
            stack.enter_context(signals_exit(signal.SIGTERM))
            threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGTERM)).start()
            _in_numba(0.3, [], at_end=stack.close)
        time.sleep(2)
        print("survived", signal.getsignal(signal.SIGTERM))
    """)
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       timeout=60)
    assert p.returncode == -signal.SIGTERM, (p.returncode, p.stdout, p.stderr[-400:])
    assert "survived" not in p.stdout


def test_other_dropped_exceptions_still_reach_python_s_hook(monkeypatch) -> None:
    """Only a signal's exception is taken: any other one a finalizer raises goes to the
    hook that was there before, which is back once the command is done, and a Ctrl-C
    dropped as the command ends is not raised later in the caller."""
    from mpz.tools._cli import _dropped_signal, reports_ctrl_c
    seen: list[type[BaseException]] = []

    def recorder(unraisable) -> None:
        seen.append(type(unraisable.exc_value))

    monkeypatch.setattr(sys, "unraisablehook", recorder)

    class RaisesValueError:
        def __del__(self) -> None:
            raise ValueError("in a finalizer")

    def main() -> int:
        RaisesValueError()
        return 0

    assert reports_ctrl_c("interrupted")(main)() == 0
    assert seen == [ValueError] and sys.unraisablehook is recorder

    def ends_at_once() -> int:
        _DropsASignal(signal.SIGINT)
        return 0

    assert reports_ctrl_c("interrupted")(ends_at_once)() == 0   # the work was done
    time.sleep(0.2)                      # no KeyboardInterrupt comes here later
    assert seen == [ValueError]
    assert _dropped_signal(_kernel_interrupt(2)) == signal.SIGINT

    import _thread

    def no_thread(*args) -> None:
        raise RuntimeError("can't start new thread")

    monkeypatch.setattr(_thread, "start_new_thread", no_thread)
    assert reports_ctrl_c("interrupted")(ends_at_once)() == 0   # Python's word, as before
    assert seen == [ValueError, KeyboardInterrupt]
    assert _dropped_signal(SystemExit(3)) is None and _dropped_signal(ValueError()) is None


def test_an_interrupted_encode_does_not_wait_for_a_stuck_pool_thread(monkeypatch) -> None:
    """A Ctrl-C can leave a lock held that a pool thread then waits on for ever (numba's
    compiler lock as a kernel loads): the encoder's shutdown(wait=True) hung the command
    (a review of stop 56, about 1 in 50 tries). On an interrupt it does not wait."""
    import threading

    import mpz.encoder as encoder
    stuck = threading.Event()
    monkeypatch.setattr(encoder, "ancillary_records", lambda m, o: stuck.wait(60) or [])

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(encoder, "plan_hierarchy", interrupted)
    t0 = time.monotonic()
    try:
        with pytest.raises(KeyboardInterrupt):
            mpz.encode(generate("walk", frames=40, markers=6, seed=1), max_error=1.0,
                       threads=2)
        assert time.monotonic() - t0 < 20
        assert any(t.name.startswith(encoder.CODEC_THREADS) for t in threading.enumerate())
    finally:
        stuck.set()


def test_a_command_leaves_a_stuck_codec_thread_behind(tmp_path: Path) -> None:
    """...and the command, whose encoder has waited for that thread already, ends with the
    signal's code, where the interpreter's exit joined the stuck thread for ever; what it
    printed is flushed."""
    script = tmp_path / "stuck.py"
    script.write_text(textwrap.dedent("""\
        import sys, threading
        import mpz.encoder
        from mpz.tools._cli import reports_ctrl_c
        threading.Thread(target=threading.Event().wait,
                         name=mpz.encoder.CODEC_THREADS + "_0").start()
        def main():
            print("half a report", end="")
            raise KeyboardInterrupt
        sys.exit(reports_ctrl_c("mpz: interrupted")(main)())
        """))
    t0 = time.monotonic()
    p = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 130 and p.stderr == "mpz: interrupted\n", p.stderr
    assert p.stdout == "half a report"
    assert time.monotonic() - t0 < 60


def test_a_command_ignores_ctrl_c_once_its_work_is_done(tmp_path: Path) -> None:
    """The interpreter's shutdown gives SIGINT its default action back: a Ctrl-C in it
    ended the command by the signal, without a word, after a complete output (QA of stop
    42). A command's main ignores it when done; a program that imports mpz keeps its own
    handler (this test's process)."""
    import signal as sig

    from mpz._worker import ignore_sigint_when_done
    assert not ignore_sigint_when_done()
    assert sig.getsignal(sig.SIGINT) is not sig.SIG_IGN
    script = tmp_path / "mpz"           # run as the mpz command is: pip's script's import
    script.write_text("import signal, sys\n"
                      "from mpz.tools.mpz_cli import main\n"
                      "from mpz.tools._cli import reports_ctrl_c\n"
                      "print(reports_ctrl_c('interrupted')(lambda: 3)(), "
                      "signal.getsignal(signal.SIGINT) is signal.SIG_IGN)\n")
    p = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                       timeout=120, check=False)
    assert p.stdout.split() == ["3", "True"], p.stderr


def test_no_compile_notice_when_the_shipped_kernels_serve(inputs: dict[str, Path],
                                                          tmp_path: Path) -> None:
    """With an empty cache but the kernels shipped with the package (mpz/_kernels), the
    first run compiles nothing, so it announces nothing (docs/cold-start.md)."""
    from mpz import _jit
    if _jit.shipped_cpu() is None:
        pytest.skip("the shipped kernels do not serve this interpreter, numba or CPU")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"),
               MPZ_SHIPPED_KERNELS="1")
    env.pop("MPZ_CACHE_DIR", None)
    args = [command("mpz"), "encode", str(inputs["trc"]), "-o", "-", "--max-error", "1mm"]
    out = _on_a_terminal(args, env, tmp_path)
    assert b"compiling" not in out and b"first run" not in out
    assert b"encoding" in out          # the progress bar: this is the terminal's output


def test_packaging_files(tmp_path: Path) -> None:
    lic = (REPO / "LICENSE").read_text()
    assert lic.startswith("MIT License") and "The MPZ authors" in lic
    readme = (REPO / "README.md").read_text()
    for doc in ("layout.md", "io-notes.md", "partial-decode.md", "summary-size.md"):
        assert f"docs/{doc}" in readme, doc              # the design notes are linked
    assert "MPZ_SHARED_DATA" in readme
    assert "ships with the package" not in readme
    manifest = (REPO / "MANIFEST.in").read_text()
    assert "recursive-include docs *.md" in manifest and "LICENSE" in manifest
    p = run(["mpz", "show", "--help"], tmp_path)
    assert p.returncode == 0 and b"``" not in p.stdout and b":func:" not in p.stdout
    for section in ("Pipes", "Batches", "Units", "Command exit codes"):
        assert section in readme


def test_decode_says_when_its_positions_are_the_joints_not_the_marker_layer(
        inputs: dict[str, Path], tmp_path: Path) -> None:
    """A skeletal file decoded to a format without a skeleton gets the forward kinematics
    of its channels (spec §6.10), not the marker layer a 1.0 decoder reads: the note says
    which (a spec-only implementer's decoder and ours disagreed on cmu_10_01 by 0.33)."""
    p = run(["mpz", "encode", str(inputs["bvh"]), "-o", "arm.mpz"], tmp_path)
    assert p.returncode == 0, p.stderr
    for out, expect in (("arm.npy", True), ("arm.csv", True), ("arm.bvh", False)):
        p = run(["mpz", "decode", "arm.mpz", "-o", out], tmp_path)
        assert p.returncode == 0, p.stderr
        assert (b"joint positions computed from the skeleton's channels" in p.stderr) is expect
    p = run(["mpz", "decode", str(inputs["mpz"]), "-o", "walk.npy"], tmp_path)
    assert p.returncode == 0 and b"skeleton's channels" not in p.stderr, p.stderr
    layer = mpz.decode((tmp_path / "arm.mpz").read_bytes()).positions
    assert not np.array_equal(np.load(tmp_path / "arm.npy"), layer)


def test_weight_that_cannot_act_is_said(inputs: dict[str, Path], tmp_path: Path) -> None:
    """--weight shapes the pattern layer only: under a bound no node keeps one and the file
    is the same bytes as without it, which the encoder now says (a QA run found it silent);
    in the paper's lossy mode the weights act and nothing is said."""
    src = str(inputs["c3d"])
    p = run(["mpz", "encode", src, "-o", "a.mpz", "--max-error", "1mm"], tmp_path)
    q = run(["mpz", "encode", src, "-o", "b.mpz", "--max-error", "1mm", "--weight", "LFHD=8"],
            tmp_path)
    assert p.returncode == 0 and q.returncode == 0, q.stderr
    assert (tmp_path / "a.mpz").read_bytes() == (tmp_path / "b.mpz").read_bytes()
    assert b"--weight: the weights act on the pattern layer only" in q.stderr
    assert b"--weight" not in p.stderr
    r = run(["mpz", "encode", src, "-o", "c.mpz", "--lossy", "--weight", "LFHD=8"], tmp_path)
    s = run(["mpz", "encode", src, "-o", "d.mpz", "--lossy"], tmp_path)
    assert r.returncode == 0 and s.returncode == 0, r.stderr
    assert b"--weight" not in r.stderr
    assert (tmp_path / "c.mpz").read_bytes() != (tmp_path / "d.mpz").read_bytes()


@pytest.mark.parametrize("opt", [["--threads", "0"], ["--smoothing", "17"], ["--summary", "abc"],
                                 ["--summary", "0"], ["--weight", "LFHD=x"],
                                 ["--lossy", "--max-error", "1mm"], ["--k0", "0"]])
def test_a_bad_option_value_is_a_usage_error(inputs: dict[str, Path], tmp_path: Path,
                                             opt: list[str]) -> None:
    """Values judged without the input exit 64 before it is read (they exited 2, the code
    of an error in the input, when the encoder's own check found them)."""
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "x.mpz", *opt], tmp_path)
    assert p.returncode == 64, (p.returncode, p.stderr)
    assert not (tmp_path / "x.mpz").exists()


OUT_OF_RANGE = [
    ["encode", "--max-error", "0mm"], ["encode", "--max-error", "1e999mm"],
    ["encode", "--max-error", "1e-320mm"], ["encode", "--max-error", "1mm", "--grid", "0mm"],
    ["encode", "--max-error", "1mm", "--group-error", "root=0cm"],
    ["encode", "--meta", "=v"], ["encode", "--rate", "nan"], ["encode", "--rate", "0"],
    ["encode", "--angle-error", "inf"], ["encode", "--translation-error", "0"],
    ["encode", "--translation-error", "nan"], ["encode", "--translation-error", "0mm"],
    ["compare", "--bound", "0mm"], ["compare", "--bound", "1e400mm"],
    ["search", "--index", "idx", "-n", "-1"],
]


@pytest.mark.parametrize("argv", OUT_OF_RANGE, ids=" ".join)
def test_a_value_out_of_range_is_a_usage_error_before_the_input_is_read(
        tmp_path: Path, argv: list[str]) -> None:
    """QA finding 10 (stop 33): zero, infinite and denormal lengths, an empty --meta key,
    a NaN rate and a negative count were judged only after the input was read, with the
    exit code of an input error (2). None of them depends on the input, so they are usage
    errors (64, README); the input here does not exist, and reading it would exit 2."""
    cmd, *opts = argv
    inputs = {"encode": ["missing.amc", "-o", "x.mpz"], "compare": ["a.c3d", "b.mpz"],
              "search": ["missing.c3d"]}[cmd]
    p = run(["mpz", cmd, *inputs, *opts], tmp_path)
    assert p.returncode == 64, (p.returncode, p.stderr)
    assert opts[-2].encode() in p.stderr or b"metadata key" in p.stderr, p.stderr
    assert not list(tmp_path.iterdir())


def test_a_group_error_that_is_not_tighter_is_said(inputs: dict[str, Path],
                                                   tmp_path: Path) -> None:
    """A node is coded within the smaller of its group error and the bound: a looser group
    error changed nothing without a word (a QA run)."""
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "x.mpz", "--max-error", "1mm",
             "--hierarchy", "auto", "--group-error", "root=2mm"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert b"--group-error root: 2 is not tighter than the bound 1" in p.stderr
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "y.mpz", "--max-error", "1mm",
             "--hierarchy", "auto", "--group-error", "root=0.5mm"], tmp_path)
    assert p.returncode == 0 and b"not tighter" not in p.stderr, p.stderr
    # against the default bound too (0.1 mm): it went unsaid without --max-error
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "z.mpz", "--hierarchy", "auto",
             "--group-error", "root=0.5mm"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert b"--group-error root: 0.5 is not tighter than the bound 0.1" in p.stderr
    # and in the --json report, with -q too (which prints no note)
    p = run(["mpz", "encode", str(inputs["c3d"]), "-o", "j.mpz", "--hierarchy", "auto",
             "--group-error", "root=0.5mm", "--json", "-q"], tmp_path)
    assert p.returncode == 0 and b"note" not in p.stderr, p.stderr
    notes = json.loads(p.stdout)["notes"]
    assert [n for n in notes if n.startswith("--group-error root: 0.5 is not tighter than "
                                            "the bound 0.1")], notes


def test_quiet_with_json_prints_the_report_and_nothing_else(inputs: dict[str, Path],
                                                            tmp_path: Path) -> None:
    """``-q --json``: the JSON report that was asked for on standard output, and no note
    or progress on standard error (an NPY input has a note: its rate is assumed)."""
    argv = ["mpz", "encode", str(inputs["npy"]), "-o", "q.mpz", "--max-error", "1", "--json"]
    p = run(argv, tmp_path)
    assert p.returncode == 0 and b"note:" in p.stderr
    p = run([*argv, "-q", "-f"], tmp_path)
    assert p.returncode == 0 and p.stderr == b""
    assert strict_json(p.stdout)["output"] == "q.mpz"


def _two_formats_of_one_take(tmp_path: Path) -> Path:
    """``tmp_path/takes`` holding one take as walk.c3d and walk.trc."""
    src = tmp_path / "takes"
    src.mkdir()
    m = generate("walk", frames=30, seed=5)
    write(m, src / "walk.c3d")
    write(m, src / "walk.trc")
    return src


def test_two_formats_of_one_take_in_one_folder_are_told_the_way_out(tmp_path: Path) -> None:
    """An archive team's QA run (stop 50): walk.c3d and walk.trc in one folder, with
    --mirror, failed "its output ... is also the output of ..." with no remedy, where the
    flat clash names --mirror."""
    _two_formats_of_one_take(tmp_path)
    p = run(["mpz", "encode", "-r", "takes", "-o", "arch/", "--mirror", "--max-error", "1mm",
             "--jobs", "0", "-q"], tmp_path)
    assert p.returncode == 2 and b"also the output of" in p.stderr, p.stderr
    assert b"--keep-extension names each output after its whole input name" in p.stderr


def test_keep_extension_archives_two_formats_of_one_take_and_decode_gives_both_back(
        tmp_path: Path) -> None:
    """A corpus QA run of stop 76: the remedy said above, encoding one of the two alone,
    took it out of the corpus (no index row, no search), and the C3D lost, the file with
    the analog data. ``--keep-extension`` names each output NAME.EXT.mpz; ``mpz decode``
    names walk.c3d.mpz's output walk.c3d, not walk.c3d.c3d."""
    src = _two_formats_of_one_take(tmp_path)
    p = run(["mpz", "encode", "-r", "takes", "-o", "arch/", "--mirror", "--max-error", "1mm",
             "--jobs", "0", "-q", "--keep-extension"], tmp_path)
    assert p.returncode == 0, p.stderr
    arch = tmp_path / "arch"
    assert sorted(f.name for f in arch.glob("*.mpz")) == ["walk.c3d.mpz", "walk.trc.mpz"]
    with sqlite3.connect(arch / "index.sqlite") as db:
        assert sorted(r[0] for r in db.execute("SELECT output FROM files")) == [
            "walk.c3d.mpz", "walk.trc.mpz"]
    p = run(["mpz", "decode", "-r", "arch", "-o", "back/", "--mirror", "-q"], tmp_path)
    assert p.returncode == 0, p.stderr
    back = tmp_path / "back"
    assert sorted(f.name for f in back.iterdir()) == ["walk.c3d", "walk.trc"]
    for name in ("walk.c3d", "walk.trc"):
        got = read(back / name)
        assert got.n_frames == 30 and mpz.max_error(read(src / name), got) <= 1.0
    p = run(["mpz", "encode", "takes/walk.trc", "--keep-extension", "--max-error", "1mm",
             "-q"], tmp_path)                        # beside its input, too
    assert p.returncode == 0 and (src / "walk.trc.mpz").is_file(), p.stderr
    # --format names the same extension: walk.c3d, not walk.c3d.c3d (a review of stop 76)
    p = run(["mpz", "decode", "arch/walk.c3d.mpz", "--format", "c3d", "-q"], tmp_path)
    assert p.returncode == 0 and (arch / "walk.c3d").is_file(), p.stderr
    p = run(["mpz", "decode", "arch/walk.c3d.mpz", "--format", "trc", "-q", "-f"], tmp_path)
    assert p.returncode == 0 and (arch / "walk.c3d.trc").is_file(), p.stderr


def test_a_damaged_archive_of_a_deleted_source_fails_the_run(tmp_path: Path) -> None:
    """The command line of a corpus QA run of stop 76: an output cut short whose source was
    deleted fails the run (exit 2) and is named on stderr with -q and --json, which print
    no table."""
    src = tmp_path / "takes"
    src.mkdir()
    for k, name in enumerate(("a.trc", "b.trc")):
        write(generate("walk", frames=30, seed=k), src / name)
    argv = ["mpz", "encode", "-r", "takes", "-o", "arch/", "--max-error", "1mm", "--jobs",
            "0", "-q"]
    assert run(argv, tmp_path).returncode == 0
    (src / "a.trc").unlink()
    out = tmp_path / "arch" / "a.mpz"
    out.write_bytes(out.read_bytes()[:200])
    for extra in ([], ["--json"]):
        p = run([*argv, *extra], tmp_path)
        assert p.returncode == 2, p.stderr
        assert b"mpz encode: error: a.mpz: damaged: it is 200 bytes, its index row says " \
            in p.stderr, p.stderr
    assert strict_json(p.stdout)["damaged"][0]["output"] == "a.mpz"


@pytest.mark.parametrize("cmd", ["show", "summary"])
def test_a_folder_given_for_a_file_is_said_alike(tmp_path, cmd):
    """mpz summary said "not a regular file" of a folder, where mpz show and the API say
    "is a folder, not a file" (a QA run of the CLI plumbing, stop 64; mpzinfo says it in
    its own verdict line)."""
    (tmp_path / "takes").mkdir()
    p = run(["mpz", cmd, "takes"], tmp_path)
    assert p.returncode == 2 and b"takes: is a folder, not a file" in p.stderr, p.stderr
