"""The installed commands as a user runs them: exit codes, output files, modes, races, signals.

Issue 9.7 (one exit-code table, one parser, one atomic writer, one input check),
issue 11.10 (SIGTERM leftovers, the --force race, dangling symlinks) and issue 14.4,
14.5, 14.7, 14.8 (umask and modes, tracebacks, temporary names, exit codes). Every
test here starts ``mpz``, ``mpzinfo`` or ``mpz-conformance`` with :mod:`subprocess`,
with a real umask, real pipes and real signals.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
import json
import os
from pathlib import Path
import shutil
import signal
import stat
import subprocess
import sys
import time

import numpy as np
import pytest

import mpz
from mpz.errors import EncoderError
from mpz.io import read, write
from mpz.synth import generate

pytestmark = pytest.mark.skipif(os.name != "posix", reason="umask, signals and modes are POSIX")
VECTORS = Path(__file__).parents[1] / "conformance" / "vectors"


def command(name: str) -> str:
    """The console script installed beside this Python (else the one on PATH)."""
    beside = Path(sys.executable).parent / name
    found = str(beside) if beside.exists() else shutil.which(name)
    assert found, f"{name} is not installed (pip install -e .)"
    return found


def run(args: Sequence[str], cwd: Path, umask: int = 0o022,
        timeout: float = 300) -> subprocess.CompletedProcess[str]:
    """Run an installed command under ``umask``; capture stdout and stderr as text."""
    return subprocess.run([command(args[0]), *args[1:]], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout, preexec_fn=_umask(umask))


def _umask(mask: int) -> Callable[[], None]:
    def apply() -> None:
        os.umask(mask)
    return apply


def mode(path: Path) -> int:
    return stat.S_IMODE(path.lstat().st_mode)


def hidden(folder: Path) -> list[str]:
    """Names an interrupted writer could leave: hidden files and ``*.part*`` files."""
    return sorted(n for n in os.listdir(folder) if n.startswith(".") or ".part" in n)


@pytest.fixture(scope="module")
def small(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A TRC input and its .mpz (60 frames, gaps)."""
    d = tmp_path_factory.mktemp("small")
    m = generate("walk", frames=60, seed=2, gap_fraction=0.02)
    trc = d / "in.trc"
    write(m, trc)
    enc = d / "in.mpz"
    enc.write_bytes(mpz.encode(m, max_error=1.0))
    return trc, enc


def test_new_files_follow_the_umask(small: tuple[Path, Path], tmp_path: Path) -> None:
    trc, enc = small
    # every writer: bytes (.mpz) and writers that open the path themselves (the rest)
    for umask, want, exts in ((0o022, 0o644, (".trc", ".c3d")), (0o027, 0o640, (".npy", ".csv"))):
        out = tmp_path / f"u{umask:o}.mpz"
        p = run(["mpz", "encode", str(trc), "-o", str(out), "--quiet"], tmp_path, umask)
        assert p.returncode == 0, p.stderr
        assert mode(out) == want, f"umask {umask:o}: mode {mode(out):o}"
        for ext in exts:
            back = tmp_path / f"u{umask:o}{ext}"
            p = run(["mpz", "decode", str(enc), "-o", str(back), "--quiet"], tmp_path, umask)
            assert p.returncode == 0, p.stderr
            assert mode(back) == want, f"{ext} under umask {umask:o}: mode {mode(back):o}"
    assert hidden(tmp_path) == []


def test_force_keeps_the_mode_of_the_replaced_file(small: tuple[Path, Path],
                                                   tmp_path: Path) -> None:
    trc, enc = small
    out = tmp_path / "o.mpz"
    back = tmp_path / "o.trc"
    out.write_bytes(b"old")
    back.write_text("old")
    for path, m in ((out, 0o644), (back, 0o640)):
        path.chmod(m)
    # umask 077 would give 0600 to a new file: the replaced files keep 0644 and 0640
    p = run(["mpz", "encode", str(trc), "-o", str(out), "--force", "--quiet"], tmp_path, 0o077)
    assert p.returncode == 0, p.stderr
    p = run(["mpz", "decode", str(enc), "-o", str(back), "--force", "--quiet"], tmp_path, 0o077)
    assert p.returncode == 0, p.stderr
    assert (mode(out), mode(back)) == (0o644, 0o640)
    assert mpz.read_mpz(out).n_frames == 60 and read(back).n_frames == 60
    assert hidden(tmp_path) == []


def test_two_encoders_racing_for_one_new_output(tmp_path: Path) -> None:
    m = generate("jump", frames=1500, seed=5)
    src = tmp_path / "in.trc"
    write(m, src)
    out = tmp_path / "race.mpz"
    argv = [command("mpz"), "encode", str(src), "-o", str(out), "--max-error", "1mm", "--quiet"]
    procs = [subprocess.Popen(argv, cwd=tmp_path, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [(p.wait(timeout=300), p.stderr.read() if p.stderr else "") for p in procs]
    for p in procs:
        for f in (p.stdout, p.stderr):
            if f:
                f.close()
    codes = sorted(code for code, _ in results)
    assert codes == [0, 2], results
    loser = next(err for code, err in results if code == 2)
    assert f"{out} exists; use --force to replace it" in loser   # the command's spelling
    assert "Traceback" not in loser and len(loser.strip().splitlines()) == 1
    back = mpz.read_mpz(out)                       # the winner's file is complete
    assert back.n_frames == 1500 and back.names == m.names
    assert hidden(tmp_path) == []


def test_dangling_symlink_is_refused_without_force(small: tuple[Path, Path],
                                                   tmp_path: Path) -> None:
    trc, enc = small
    link = tmp_path / "out.mpz"
    link.symlink_to(tmp_path / "missing.mpz")
    p = run(["mpz", "encode", str(trc), "-o", str(link)], tmp_path)
    assert p.returncode == 2
    assert "symbolic link to a missing file; use --force" in p.stderr
    assert link.is_symlink() and not (tmp_path / "missing.mpz").exists()
    dlink = tmp_path / "out.npy"
    dlink.symlink_to(tmp_path / "missing.npy")
    p = run(["mpz", "decode", str(enc), "-o", str(dlink)], tmp_path)
    assert p.returncode == 2 and "symbolic link to a missing file" in p.stderr
    assert dlink.is_symlink()
    # --force replaces the link itself with the file (the link's target is not created)
    p = run(["mpz", "encode", str(trc), "-o", str(link), "--force", "--quiet"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert not link.is_symlink() and link.is_file()
    assert not (tmp_path / "missing.mpz").exists()
    assert hidden(tmp_path) == []


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="no /proc/self/fd here")
def test_a_name_of_an_open_descriptor_is_refused_even_with_force(small: tuple[Path, Path],
                                                                 tmp_path: Path) -> None:
    """``mpz encode -f x -o /dev/stdout > out.mpz`` renamed its file over the link (for
    root: /dev/stdout itself, for every later process) and exited 0, out.mpz empty; into a
    pipe it said "not a regular file" and not what to write instead (a QA run of the CLI
    plumbing). A link of the test's own stands in for /dev/stdout, which the old code
    would have replaced."""
    trc, enc = small
    link = tmp_path / "so.mpz"
    link.symlink_to("/proc/self/fd/1")
    with open(tmp_path / "out.mpz", "wb") as out:
        p = subprocess.run([command("mpz"), "encode", "-q", "-f", str(trc), "-o", str(link)],
                           cwd=tmp_path, stdout=out, stderr=subprocess.PIPE, timeout=300)
    err = p.stderr.decode()
    assert p.returncode == 2 and "names an open file descriptor" in err, err
    assert "write to standard output with -o -" in err
    assert link.is_symlink() and hidden(tmp_path) == []
    p = run(["mpz", "decode", "-q", str(enc), "-o", "/dev/stdout", "-F", "csv"], tmp_path)
    assert p.returncode == 2 and "with -o -" in p.stderr and p.stdout == "", p.stderr
    with pytest.raises(EncoderError, match="open file descriptor"):
        mpz.write_atomic(link, b"x")
    assert link.is_symlink()


@pytest.fixture(scope="module")
def large(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An .mpz whose TRC output takes a good second to format and write."""
    d = tmp_path_factory.mktemp("large")
    path = d / "large.mpz"
    path.write_bytes(mpz.encode(generate("walk", frames=12000, seed=1), lossy=True))
    return path


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_while_decoding_leaves_no_temporary_file(large: Path, tmp_path: Path,
                                                         signum: int) -> None:
    """SIGHUP (a terminal closed) left the hidden temporary file (a QA run of stop 57):
    it ends the write as SIGTERM does, exit 129."""
    out = tmp_path / "big.trc"
    proc = subprocess.Popen([command("mpz"), "decode", str(large), "-o", str(out)],
                            cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    seen: list[str] = []
    t0 = time.monotonic()
    while proc.poll() is None and time.monotonic() - t0 < 120:
        seen = hidden(tmp_path)
        if seen:                    # the temporary file exists: the writer has started
            break
        time.sleep(0.002)
    proc.send_signal(signum)
    code = proc.wait(timeout=60)
    err = proc.stderr.read().decode() if proc.stderr else ""
    if proc.stderr:
        proc.stderr.close()
    assert seen and seen[0].startswith(".big.trc.") and ".part" in seen[0], \
        "the decoder finished before it was seen writing; make the input larger"
    assert code == 128 + signum, (code, err)
    assert "Traceback" not in err
    assert hidden(tmp_path) == [] and not out.exists()


def test_bad_output_paths_fail_first_in_one_line(small: tuple[Path, Path],
                                                 tmp_path: Path) -> None:
    trc, enc = small
    (tmp_path / "folder").mkdir()
    cases = [
        (["mpz", "encode", str(trc), "-o", "nodir/x.mpz", "--max-error", "1mm"],
         "cannot write nodir/x.mpz: nodir does not exist"),
        (["mpz", "encode", str(trc), "-o", "folder", "--force"],
         "folder is a folder; give a file name"),
        (["mpz", "decode", str(enc), "-o", "nodir/x.trc"],
         "cannot write nodir/x.trc: nodir does not exist"),
        (["mpz", "decode", str(enc), "-o", "folder", "--force"],
         "folder is a folder; give a file name"),
        (["mpz", "decode", str(enc), "-o", "back.xyz"],
         "back.xyz: cannot write '.xyz' files; can write .c3d, .trc, .npy, .csv, .bvh, .amc "
         "(or choose one with --format)"),
        (["mpz", "decode", str(enc), "-o", str(enc), "--force"],
         f"refusing to overwrite the input file {enc}"),
        (["mpz", "encode", str(trc), "-o", str(trc), "--force"],
         f"refusing to overwrite the input file {trc}"),
        (["mpz", "encode", str(trc), "-o", "x.bin"],
         "x.bin: an MPZ file should end in .mpz; use --force to write it under this name"),
        # a motion format's name, even with --force: every tool would read it as one, and
        # the user meant mpz decode (it was written with -f, without a word)
        (["mpz", "encode", str(trc), "-o", "x.c3d", "--force"],
         "x.c3d: an MPZ file named .c3d would be read as C3D; name it .mpz (to write C3D, "
         "decode an .mpz: mpz decode FILE.mpz -o x.c3d)"),
        (["mpz", "encode", str(trc), "-o", "x.Trc"],
         "x.Trc: an MPZ file named .trc would be read as TRC; name it .mpz (to write TRC, "
         "decode an .mpz: mpz decode FILE.mpz -o x.Trc)"),
    ]
    for argv, message in cases:
        p = run(argv, tmp_path)
        lines = p.stderr.strip().splitlines()
        assert p.returncode == 2, (argv, p.stderr)
        assert lines == [f"mpz {argv[1]}: error: {message}"], (argv, p.stderr)
        assert ".part" not in p.stderr and "mpz-decode" not in p.stderr
    assert sorted(os.listdir(tmp_path)) == ["folder"]
    assert os.listdir(tmp_path / "folder") == []


def test_a_file_encoded_from_standard_input_decodes_to_its_format(small: tuple[Path, Path],
                                                                   tmp_path: Path) -> None:
    """Standard input has no name, so the file records no ``source``: `mpz decode F.mpz`
    and `-o -` failed with "cannot name the decoded output", where the reader's recorded
    ``format`` says TRC (docs/cli.md: the default is the format the file was encoded
    from; a QA run of stop 53)."""
    trc, _ = small
    with open(trc, "rb") as fh:
        p = subprocess.run([command("mpz"), "encode", "-", "-o", "s.mpz", "-q"], cwd=tmp_path,
                           stdin=fh, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "source" not in mpz.info(tmp_path / "s.mpz").metadata
    p = run(["mpz", "decode", "s.mpz", "-q"], tmp_path)
    assert p.returncode == 0, p.stderr
    back = read(tmp_path / "s.trc")
    assert back.n_frames == 60 and back.names == read(trc).names
    p = run(["mpz", "decode", "s.mpz", "-o", "-"], tmp_path)
    assert p.returncode == 0 and p.stdout.startswith("PathFileType"), p.stderr


@pytest.mark.skipif(not os.path.exists(os.devnull) or os.name != "posix",
                    reason="needs a null device that is a character device")
def test_the_null_device_takes_a_whole_output_and_drops_it(small: tuple[Path, Path],
                                                           tmp_path: Path) -> None:
    """``-o /dev/null`` times or checks a writer (as ``zstd -o /dev/null``): it was refused as
    "not a regular file" even with --force. The whole file is written, then dropped; the
    device stays a device, no format or --force is needed (decode takes the format the
    file was encoded from), and nothing is left behind."""
    trc, enc = small
    before = os.stat(os.devnull)
    p = run(["mpz", "encode", str(trc), "-o", "x.mpz", "--max-error", "1mm", "--json"],
            tmp_path)
    written = json.loads(p.stdout)["file_bytes"]
    for argv in (["mpz", "encode", str(trc), "-o", os.devnull, "--max-error", "1mm"],
                 ["mpz", "decode", "x.mpz", "-o", os.devnull],        # as TRC, its source
                 ["mpz", "decode", str(enc), "-o", os.devnull, "-F", "c3d"]):
        p = run(argv, tmp_path)
        assert p.returncode == 0, (argv, p.stderr)
        assert f"-> {os.devnull}: 60 frames x " in p.stdout + p.stderr, argv
    # an .mpz that names no source format needs --format, as for standard output
    p = run(["mpz", "decode", str(enc), "-o", os.devnull], tmp_path)
    assert p.returncode == 2 and f"writing to {os.devnull} needs --format" in p.stderr
    after = os.stat(os.devnull)
    assert stat.S_ISCHR(after.st_mode) and after.st_rdev == before.st_rdev
    assert os.listdir(tmp_path) == ["x.mpz"]
    # the report still measures what was written: MPZ bytes, as to a file
    p = run(["mpz", "encode", str(trc), "-o", os.devnull, "--max-error", "1mm", "--json"],
            tmp_path)
    assert json.loads(p.stdout)["file_bytes"] == written > 0


def test_trc_header_names_the_output_not_the_temporary_file(small: tuple[Path, Path],
                                                            tmp_path: Path) -> None:
    _, enc = small
    p = run(["mpz", "decode", str(enc), "-o", "back.trc"], tmp_path)
    assert p.returncode == 0, p.stderr
    first = (tmp_path / "back.trc").read_text().splitlines()[0]
    assert first == "PathFileType\t4\t(X/Y/Z)\tback.trc"


def test_show_exits_1_when_the_reader_warned(small: tuple[Path, Path], tmp_path: Path) -> None:
    trc, _ = small
    lines = trc.read_text().splitlines(keepends=True)
    vals = lines[2].split("\t")
    vals[2] = "61"                                 # NumFrames: the file has 60 rows
    lines[2] = "\t".join(vals)
    warned = tmp_path / "warned.trc"
    warned.write_text("".join(lines))
    p = run(["mpz", "show", str(warned)], tmp_path)
    assert p.returncode == 1, p.stderr
    assert "warning:   NumFrames says 61, file has 60 rows" in p.stdout
    p = run(["mpz", "show", "--json", str(warned)], tmp_path)
    assert p.returncode == 1 and '"warning": "NumFrames says 61' in p.stdout
    p = run(["mpz", "show", str(trc)], tmp_path)
    assert p.returncode == 0 and "warning" not in p.stdout


def test_conformance_usage_and_version(tmp_path: Path) -> None:
    p = run(["mpz-conformance", "--decoder", "true", "--bogus"], tmp_path)
    assert p.returncode == 64 and "unrecognized arguments: --bogus" in p.stderr
    p = run(["mpz-conformance", "--bogus"], tmp_path)
    assert p.returncode == 64 and p.stderr.startswith("usage: mpz-conformance")
    p = run(["mpz-conformance"], tmp_path)
    assert p.returncode == 64 and "one of the arguments --decoder --encoder" in p.stderr
    p = run(["mpz-conformance", "--version"], tmp_path)
    assert p.returncode == 0 and p.stdout.strip() == f"mpz-conformance {mpz.identity()}"
    p = run(["mpz-conformance", "--help"], tmp_path)
    assert p.returncode == 0 and "64 usage error" in p.stdout.replace("\n", " ")
    p = run(["mpz-conformance", "--decoder", "true", "--results", "nodir/r.json"], tmp_path)
    assert p.returncode == 64 and "nodir does not exist" in p.stderr


@pytest.mark.parametrize("tool", ["mpz", "mpzinfo", "mpz-conformance"])
def test_version_names_the_source_not_only_the_release(tool: str, tmp_path: Path) -> None:
    """`--version` said "mpz 0.1.0" for every development checkout, so a bug report or two
    hosts compared by it could not tell which code ran. It now gives mpz.identity(): the
    version and the fingerprint of the package's source, the 12 hex digits a worker's
    check compares (mpz._identity)."""
    from mpz._identity import source_digest, source_roots
    p = run([tool, "--version"], tmp_path)
    assert p.returncode == 0 and p.stderr == "", p.stderr
    digest = source_digest(source_roots())[:12]     # of the files, not of identity()
    assert p.stdout == f"{tool} {mpz.__version__} (source {digest})\n"


def test_one_exit_code_table_for_every_tool(tmp_path: Path) -> None:
    for argv in (["mpz", "--bogus"], ["mpz", "encode"], ["mpzinfo"], ["mpz-conformance", "-x"]):
        p = run(argv, tmp_path)
        assert p.returncode == 64, (argv, p.stderr)
        assert p.stderr.startswith("usage: ") and "Traceback" not in p.stderr
    p = subprocess.run([sys.executable, "-m", "mpz.tools.spec_example", "--bogus"],
                       cwd=tmp_path, capture_output=True, text=True)
    assert p.returncode == 64
    from mpz.conformance import runner
    from mpz.tools import _cli, cmd_show, cmd_summary, mpz_cli, mpzinfo, spec_example
    for mod in (mpz_cli, mpzinfo, runner, spec_example, cmd_summary):
        assert mod.Parser is _cli.Parser, mod.__name__
    assert (mpzinfo.EXIT_OK, mpzinfo.EXIT_WARN, mpzinfo.EXIT_ERROR) == (0, 1, 2)
    assert (runner.EXIT_OK, runner.EXIT_FAIL, runner.EXIT_USAGE) == (0, 1, 64)
    assert cmd_show.EXIT_WARN == _cli.EXIT_WARN == 1


def test_the_help_of_mpz_and_mpzinfo_lists_every_code_of_the_readme_table(
        tmp_path: Path) -> None:
    """Each exit code in the README's table is in both tools' --help (mpzinfo's lacked 130:
    docs audit, finding 10)."""
    import re
    readme = (Path(__file__).parents[1] / "README.md").read_text(encoding="utf-8")
    codes = re.findall(r"^\| (\d+) \|", readme, re.M)
    assert codes[:1] == ["0"] and "130" in codes
    for tool in ("mpz", "mpzinfo"):
        text = " ".join(run([tool, "--help"], tmp_path).stdout.split())
        listed = re.findall(r"\b(\d+) [a-z]", text.split("exit codes:", 1)[1])
        assert listed == codes, (tool, listed)


def test_output_piped_into_head_stops_quietly(small: tuple[Path, Path], tmp_path: Path) -> None:
    _, enc = small
    files = [str(enc)] * 200                       # far more than a pipe buffer of -vv text
    for argv in (["mpzinfo", "-vv", *files],):
        proc = subprocess.Popen([command(argv[0]), *argv[1:]], cwd=tmp_path,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        assert proc.stdout is not None and proc.stderr is not None
        proc.stdout.read(20)
        proc.stdout.close()                        # what head does after its lines
        err = proc.stderr.read().decode()
        proc.stderr.close()
        assert proc.wait(timeout=120) == 0, err
        assert "Traceback" not in err and "BrokenPipeError" not in err and err == ""


def _into_a_closed_pipe(argv: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run ``argv`` with a standard output whose reader has gone: every write fails (EPIPE),
    as after `| head` stopped reading, but at the first write, whatever the timing."""
    r, w = os.pipe()
    os.close(r)
    try:
        return subprocess.run([command(argv[0]), *argv[1:]], cwd=cwd, stdout=w,
                              stderr=subprocess.PIPE, text=True, timeout=300)
    finally:
        os.close(w)


def test_a_closed_pipe_keeps_the_exit_code_of_what_was_found(small: tuple[Path, Path],
                                                             tmp_path: Path) -> None:
    """README: a tool whose output is cut ends "with the code it would have had". An
    invalid file gave 0 from `mpzinfo -vv BAD | head -1`, a difference 0 from `mpz compare
    ... | head -1`, and a batch with a failed input 0 (a docs QA run, stop 52): the error
    was found, and often printed, before the pipe broke."""
    trc, enc = small
    bad = VECTORS / "invalid" / "x05-bad-crc-root.mpz"
    other = tmp_path / "other.mpz"
    m = generate("walk", frames=60, seed=3, gap_fraction=0.02)
    other.write_bytes(mpz.encode(m, max_error=1.0))
    (tmp_path / "broken.trc").write_text("not a TRC\n")
    for argv, code in ((["mpzinfo", str(bad)], 2),
                       (["mpzinfo", "-vv", str(enc), str(bad)], 2),
                       (["mpz", "compare", str(trc), str(other)], 2),
                       (["mpz", "show", str(enc)], 0),
                       (["mpz", "encode", "broken.trc", str(trc), "-o", "out/"], 2)):
        proc = _into_a_closed_pipe(argv, tmp_path)
        assert proc.returncode == code, (argv, proc.stderr)
        assert "Traceback" not in proc.stderr


def test_a_closed_pipe_keeps_the_warning_of_an_output_on_standard_output(
        small: tuple[Path, Path], tmp_path: Path) -> None:
    """`mpz encode -o -` and `mpz decode -o -` write the output to standard output before
    their report: a closed pipe there exited 0 after the reader's warning had been
    printed (the review of stop 52)."""
    trc, _ = small
    cut = tmp_path / "cut.trc"
    cut.write_bytes(trc.read_bytes().rstrip(b"\r\n"))     # no final line break: a warning
    proc = _into_a_closed_pipe(["mpz", "encode", str(cut), "-o", "-"], tmp_path)
    assert proc.returncode == 1 and "warning" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr


def test_quiet_still_prints_a_warning(small: tuple[Path, Path], tmp_path: Path) -> None:
    """-q "prints nothing on success", and a warning-only run (exit 1) printed nothing at
    all, single files and folders alike (a text-formats QA run of stop 52)."""
    trc, _ = small
    (tmp_path / "in").mkdir()
    cut = tmp_path / "in" / "cut.trc"
    cut.write_bytes(trc.read_bytes().rstrip(b"\r\n"))     # no final line break: a warning
    for argv in (["mpz", "encode", str(cut), "-o", "one.mpz", "-q"],
                 ["mpz", "encode", "-r", "in", "-o", "out/", "--jobs", "0", "-q"]):
        p = run(argv, tmp_path)
        assert p.returncode == 1, p.stderr
        assert "warning" in p.stderr and "line break" in p.stderr, argv
        assert p.stdout == ""


def test_standard_input_with_asf_is_not_read_whole_when_it_is_no_text(tmp_path: Path) -> None:
    """--asf makes content of no known format an AMC, but zeros (binary) are refused at
    their first bytes as before: they were read whole, up to 4 GiB, and then refused as an
    AMC (the review of stop 52)."""
    (tmp_path / "s.asf").write_text(":version 1.10\n")
    with open("/dev/zero", "rb") as zeros:
        proc = subprocess.run([command("mpz"), "encode", "-", "--asf", "s.asf", "-o", "z.mpz"],
                              cwd=tmp_path, stdin=zeros, capture_output=True, text=True,
                              timeout=60)
    assert proc.returncode == 2 and "cannot tell the format" in proc.stderr, proc.stderr


def test_a_closed_pipe_does_not_lose_the_conformance_results(tmp_path: Path) -> None:
    """mpz-conformance writes --results before its report: `| head` stopped it before the
    file was written, and exited 0 with a vector failed (a docs QA run, stop 52)."""
    valid = sorted(p.stem for p in (VECTORS / "valid").glob("*.mpz"))[0]
    proc = _into_a_closed_pipe(["mpz-conformance", "--decoder", "false", "--only", valid,
                                "--results", "r.json"], tmp_path)
    assert proc.returncode == 1, proc.stderr
    doc = json.loads((tmp_path / "r.json").read_text())
    assert doc["totals"]["failed"] == 1


# -- the atomic writer itself (in-process) -------------------------------------------------

def test_atomic_output_cleans_up_and_never_names_the_temporary_file(tmp_path: Path) -> None:
    from mpz.api import atomic_output, write_atomic
    target = tmp_path / "x.bin"
    with pytest.raises(RuntimeError), atomic_output(target) as tmp:
        Path(tmp).write_bytes(b"partial")
        assert Path(tmp).parent == tmp_path and Path(tmp).name.startswith(".x.bin.")
        assert tmp.endswith(".part.bin")            # same suffix: format-by-name writers
        raise RuntimeError("writer failed")
    assert os.listdir(tmp_path) == []
    with pytest.raises(EncoderError) as ei, atomic_output(target) as tmp:
        raise PermissionError(13, "Permission denied", tmp)
    assert str(ei.value) == f"cannot write {target}: Permission denied"
    assert os.listdir(tmp_path) == []
    # exclusive without force; the public write_atomic keeps replacing by default
    write_atomic(target, b"one")
    with pytest.raises(EncoderError, match="exists; pass force=True"):
        write_atomic(target, b"two", force=False)
    write_atomic(target, b"three")
    assert target.read_bytes() == b"three" and os.listdir(tmp_path) == ["x.bin"]
    with pytest.raises(EncoderError, match="refusing to overwrite the input"):
        write_atomic(tmp_path / "." / "x.bin", b"four", source=target)


def test_exclusive_commit_loses_to_a_file_made_meanwhile(tmp_path: Path) -> None:
    from mpz.api import atomic_output
    target = tmp_path / "late.npy"
    with pytest.raises(EncoderError, match="exists; pass force=True"), \
            atomic_output(target) as tmp:
        np.save(tmp, np.zeros(3))
        target.write_bytes(b"the other writer")    # appears after the first check
    assert target.read_bytes() == b"the other writer"
    assert os.listdir(tmp_path) == ["late.npy"]


def test_a_signal_delivered_to_another_thread_waits_for_the_held_region() -> None:
    """While atomic_output creates its temporary file, SIGTERM must not strike. Blocking
    it in the main thread's mask is not enough: sent to the process, the kernel gives it to
    a thread that does not block it, and Python runs the handler in the main thread at its
    next instruction (a .part file was once left behind so). The region must finish, and
    the signal act when it ends."""
    import threading

    from mpz.api import _signals_held, signals_exit
    go = threading.Event()
    # made before the region, so this thread does not inherit the blocked mask
    killer = threading.Thread(target=lambda: (go.wait(10), os.kill(os.getpid(), signal.SIGTERM)))
    killer.start()
    finished = []
    with pytest.raises(SystemExit) as exc:
        with signals_exit(signal.SIGTERM):
            with _signals_held():
                go.set()
                killer.join()
                for _ in range(100000):          # instructions, where a handler would run
                    pass
                time.sleep(0.05)
                finished.append(True)
    assert finished == [True] and exc.value.code == 128 + signal.SIGTERM
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


@pytest.mark.parametrize("name", ["SIGTERM", "SIGHUP", "SIGINT"])
def test_a_signal_as_the_temporary_file_is_made_leaves_no_file(name: str, tmp_path: Path,
                                                               monkeypatch) -> None:
    """A CI run of stop 66 left a .part file after SIGHUP during `mpz decode -o`: the file
    was made and its name not yet recorded when the signal struck. SIGTERM and SIGINT were
    held back over those statements, SIGHUP, which ends a write as SIGTERM does, was not.
    Here each signal is raised at the worst moment, just after the file is created."""
    from mpz import api
    signum = getattr(signal, name, None)
    if signum is None:
        pytest.skip(f"no {name} here")
    made = api._create_temp

    def create_then_signal(*args, **kwargs):
        tmp = made(*args, **kwargs)
        assert os.path.exists(tmp)
        signal.raise_signal(signum)             # the file exists; its name not yet kept
        return tmp
    monkeypatch.setattr(api, "_create_temp", create_then_signal)
    with pytest.raises((SystemExit, KeyboardInterrupt)) as exc:
        with api.atomic_output(tmp_path / "out.trc") as tmp:
            Path(tmp).write_text("partial")
    if name != "SIGINT":
        assert exc.value.code == 128 + signum
    assert os.listdir(tmp_path) == []
    assert signal.getsignal(signum) in (signal.SIG_DFL, signal.default_int_handler)


def _chattr(path: Path, flag: str) -> bool:
    """Set a Linux file attribute (+i, +a) if this machine lets us; False where not."""
    if shutil.which("chattr") is None:
        return False
    return subprocess.run(["chattr", flag, str(path)], capture_output=True).returncode == 0


def test_an_output_that_cannot_be_replaced_is_refused_before_the_work(tmp_path: Path) -> None:
    """A folder that is not writable, and a file marked immutable or append-only (which no
    rename replaces, not even root's), were found only when the output was written: after
    the encode, or after every conformance vector had run (QA notes)."""
    from mpz.api import check_output
    locked = tmp_path / "locked"
    locked.mkdir()
    (tmp_path / "imm.json").write_text("{}")
    (tmp_path / "app.json").write_text("{}")
    try:
        if os.geteuid() != 0:
            locked.chmod(0o555)
        elif not _chattr(locked, "+i"):
            pytest.skip("root, and chattr cannot mark a folder immutable here")
        with pytest.raises(EncoderError, match="locked is not writable"):
            check_output(locked / "x.mpz")
        for name, flag in (("imm.json", "+i"), ("app.json", "+a")):
            if _chattr(tmp_path / name, flag):
                with pytest.raises(EncoderError, match="marked immutable or append-only"):
                    check_output(tmp_path / name, force=True)
        check_output(tmp_path / "fine.mpz")                     # and a plain path passes
    finally:
        for p in (locked, tmp_path / "imm.json", tmp_path / "app.json"):
            _chattr(p, "-i")
            _chattr(p, "-a")
        locked.chmod(0o755)



def test_a_folder_that_cannot_be_entered_is_named_so(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """A folder writable but without execute permission was reported "is not writable"
    (a QA run of stop 47, as a user other than root). os.access answers for that user;
    here it is told to answer as for such a folder (root passes every check)."""
    from mpz import api
    (tmp_path / "nox").mkdir()
    monkeypatch.setattr(api.os, "access", lambda path, mode: mode == os.W_OK)
    with pytest.raises(EncoderError, match=r"nox cannot be entered \(no execute permission\)"):
        api.check_output(tmp_path / "nox" / "x.mpz")
    monkeypatch.setattr(api.os, "access", lambda path, mode: False)
    with pytest.raises(EncoderError, match="nox is not writable"):
        api.check_output(tmp_path / "nox" / "x.mpz")

@pytest.mark.parametrize("args", [["summary", "IN", "--k", "2,4"],
                                  ["compare", "IN", "MPZ"]])
def test_a_closed_pipe_does_not_lose_the_plot(small: tuple[Path, Path], tmp_path: Path,
                                             args: list[str]) -> None:
    """The --plot file is written before the report: a reader that stops reading (`| head`)
    ended the tool quietly with exit 0 and no plot (docs audit, finding 7)."""
    pytest.importorskip("matplotlib")
    trc, enc = small
    argv = [command("mpz"), *[str(trc) if a == "IN" else str(enc) if a == "MPZ" else a
                              for a in args], "--plot", str(tmp_path / "p.png")]
    r, w = os.pipe()
    os.close(r)                         # every write to standard output fails: EPIPE
    try:
        proc = subprocess.run(argv, cwd=tmp_path, stdout=w, stderr=subprocess.PIPE,
                              text=True, timeout=300)
    finally:
        os.close(w)
    assert "Traceback" not in proc.stderr
    assert (tmp_path / "p.png").stat().st_size > 1000, proc.stderr


def test_an_unknown_unit_is_null_in_every_json_output(tmp_path: Path) -> None:
    """README: every --json output has null for an unknown value; mpzinfo and encode gave ""
    for a file without a length unit while show gave null (docs audit, finding 9)."""
    import json
    np.save(tmp_path / "walk.npy", generate("walk", frames=20).as_nan())   # NPY: no unit
    p = run(["mpz", "encode", "walk.npy", "-o", "walk.mpz", "--json", "-q"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)["units"] is None
    p = run(["mpzinfo", "--json", "walk.mpz"], tmp_path)
    assert p.returncode == 0, p.stderr
    doc = json.loads(p.stdout)
    files = doc["files"] if "files" in doc else [doc]
    assert files[0]["units"] is None
    p = run(["mpz", "show", "--json", "walk.mpz"], tmp_path)
    assert json.loads(p.stdout)["units"] is None


def test_compare_a_plot_of_a_marker_that_is_not_there_fails_before_any_output(
        small: tuple[Path, Path], tmp_path: Path) -> None:
    """With the plot written first, a mistyped --marker ended the command after nothing was
    printed, where the report used to come first (review of stop 35): it is now judged
    before both, in one line, and no plot file is left."""
    pytest.importorskip("matplotlib")
    trc, enc = small
    p = run(["mpz", "compare", str(trc), str(enc), "--plot", "p.png", "--marker", "NOPE"],
            tmp_path)
    assert p.returncode == 2 and p.stdout == ""
    assert "--marker: no marker named 'NOPE'" in p.stderr and "Traceback" not in p.stderr
    assert not (tmp_path / "p.png").exists()
    names = read(trc).names
    p = run(["mpz", "compare", str(trc), str(enc), "--plot", "q.png", "--marker", names[0]],
            tmp_path)
    assert p.returncode == 0 and "plot written to q.png" in p.stdout
    assert (tmp_path / "q.png").stat().st_size > 1000


def test_a_ctrl_c_after_the_output_is_written_says_so(tmp_path: Path, capsys,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """mpz encode writes its output, then measures the report's figures. A Ctrl-C there
    exited 130, "interrupted", with a --force target already replaced (a QA run of stop
    47: a user who reads 130 as "nothing changed" has lost the old file). It still exits
    130, and now says that the output was written."""
    from mpz.tools import mpz_cli
    write(generate("walk", frames=30, markers=5, seed=2), tmp_path / "w.trc")
    (tmp_path / "w.mpz").write_bytes(b"old")

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt
    monkeypatch.setattr(mpz, "decode", interrupted)
    code = mpz_cli.main(["encode", str(tmp_path / "w.trc"), "-o", str(tmp_path / "w.mpz"),
                         "--max-error", "1mm", "--force"])
    assert code == 130
    assert f"{tmp_path / 'w.mpz'} was written" in capsys.readouterr().err
    assert mpz.info(tmp_path / "w.mpz").frames == 30                  # the new file, whole


@pytest.mark.parametrize("when", ["in the write's last step", "before the report",
                                  "before the write"])
def test_a_ctrl_c_between_the_write_and_the_report_says_so(tmp_path, monkeypatch, capsys,
                                                           when):
    """The window between the output's rename and the report's handler: a Ctrl-C there
    ended with exit 130 and "interrupted" alone, the output written (a review of stop 56,
    1 in 30 tries). It says the file was written when it holds the new bytes, and not
    when the write had not happened."""
    from mpz.tools import _common, mpz_cli
    write(generate("walk", frames=30, markers=5, seed=2), tmp_path / "w.trc")
    (tmp_path / "w.mpz").write_bytes(b"old")
    real_write, real_stage = mpz.write_atomic, _common.stage

    def write_then(*args, **kwargs):
        if when == "before the write":
            raise KeyboardInterrupt
        real_write(*args, **kwargs)
        if when == "in the write's last step":
            raise KeyboardInterrupt

    def stage(command, quiet, size, text, *rest):
        if when == "before the report" and text.startswith("decoding what was written"):
            raise KeyboardInterrupt
        return real_stage(command, quiet, size, text, *rest)
    monkeypatch.setattr(mpz, "write_atomic", write_then)
    monkeypatch.setattr(_common, "stage", stage)
    code = mpz_cli.main(["encode", str(tmp_path / "w.trc"), "-o", str(tmp_path / "w.mpz"),
                         "--max-error", "1mm", "--force"])
    err = capsys.readouterr().err
    assert code == 130 and err.endswith("interrupted\n"), err
    if when == "before the write":
        assert "was written" not in err and (tmp_path / "w.mpz").read_bytes() == b"old"
    else:
        assert f"{tmp_path / 'w.mpz'} was written" in err
        assert mpz.info(tmp_path / "w.mpz").frames == 30


def test_a_sigterm_after_the_output_is_written_says_so(tmp_path: Path) -> None:
    """The same for SIGTERM (a QA run of stop 48: exit 143, which README gives as
    "terminated while writing an output", and no word, with the output complete). In a
    child process: on code without the handler the signal ends the process."""
    write(generate("walk", frames=30, markers=5, seed=2), tmp_path / "w.trc")
    script = (
        "import os, signal, sys, time\n"
        "import mpz\n"
        "from mpz.tools import mpz_cli\n"
        "def terminated(*a, **k):\n"
        "    os.kill(os.getpid(), signal.SIGTERM)\n"
        "    time.sleep(5)\n"
        "mpz.decode = terminated\n"
        "sys.exit(mpz_cli.main(['encode', 'w.trc', '-o', 'w.mpz', '--max-error', '1mm']))\n")
    p = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True,
                       text=True, timeout=120)
    assert p.returncode == 143, (p.returncode, p.stderr)
    assert "w.mpz was written (the SIGTERM came while its report was measured)" in p.stderr
    assert mpz.info(tmp_path / "w.mpz").frames == 30


def test_another_users_file_in_a_sticky_folder_is_refused_before_the_work(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """In a folder with the sticky bit (/tmp, shared folders) only a file's owner, the
    folder's owner and root may replace it: `-f` ran the whole encode and then failed the
    rename (a QA run of stop 47, 11 s of work). The check is made up front. Here the
    files are root's, and the user is made another by its euid; as root it passes."""
    from mpz import api
    for name, mode in (("sticky", 0o1777), ("plain", 0o777)):
        (tmp_path / name).mkdir()
        (tmp_path / name).chmod(mode)
        (tmp_path / name / "x.mpz").write_bytes(b"old")
    if os.stat(tmp_path / "sticky").st_uid == 12345:
        pytest.skip("the test's other user is this folder's owner")
    api.check_output(tmp_path / "sticky" / "x.mpz", force=True)        # this user's own
    monkeypatch.setattr(api.os, "geteuid", lambda: 12345)
    with pytest.raises(EncoderError, match="belongs to another user in a folder with the "
                                           "sticky bit"):
        api.check_output(tmp_path / "sticky" / "x.mpz", force=True)
    monkeypatch.setattr(api.os, "access", lambda path, mode: True)      # as for root
    api.check_output(tmp_path / "plain" / "x.mpz", force=True)          # no sticky bit


def test_long_inputs_say_each_long_step_on_a_terminal(tmp_path, monkeypatch, capsys):
    """A 2-hour capture was read for 20 s and decoded for minutes with nothing on the
    terminal, and a bounded encode's bar came at its end (a scale QA run of stop 51).
    On a terminal, an input past STAGE_BYTES gets a line before each long step, and the
    encoding bar starts at once; off a terminal, and with -q, nothing is added."""
    from mpz.io import write
    from mpz.synth import generate
    from mpz.tools import mpz_cli
    import mpz.tools._common as common
    write(generate("walk", frames=60, seed=5), tmp_path / "w.trc")
    argv = ["encode", str(tmp_path / "w.trc"), "-o", str(tmp_path / "w.mpz"), "-f",
            "--max-error", "1mm"]
    back = ["decode", str(tmp_path / "w.mpz"), "-o", str(tmp_path / "b.trc"), "-f"]
    assert mpz_cli.main(argv) == 0 and mpz_cli.main(back) == 0
    assert "mpz encode: reading" not in capsys.readouterr().err      # not a terminal
    monkeypatch.setattr(common, "on_terminal", lambda: True)
    monkeypatch.setattr(common, "STAGE_BYTES", 1)
    assert mpz_cli.main(argv) == 0
    err = capsys.readouterr().err
    size = (tmp_path / "w.trc").stat().st_size
    lines = [ln for ln in err.split("\n") if ln.startswith("mpz encode: ")]
    assert lines[:1] == [f"mpz encode: reading {tmp_path / 'w.trc'} "
                         f"({common.human_size(size)})"], err
    assert "mpz encode: decoding what was written, to measure its error" in lines, err
    assert "encoding [------------------------------]   0% planning" in err, err
    assert mpz_cli.main(back) == 0
    err = capsys.readouterr().err
    assert f"mpz decode: decoding {tmp_path / 'w.mpz'}\n" in err, err
    assert f"mpz decode: writing {tmp_path / 'b.trc'}\n" in err, err
    assert mpz_cli.main([*argv, "-q"]) == 0 and mpz_cli.main([*back, "-q"]) == 0
    assert capsys.readouterr().err == ""


def test_encode_json_of_several_inputs_is_json_alone_on_stdout(small: tuple[Path, Path],
                                                               tmp_path: Path) -> None:
    """A CI audit: with several inputs, the batch's closing line ("mpz encode: 2 inputs: 2
    done, 0 failed") went to stdout before the JSON, so stdout did not parse."""
    trc, _ = small
    for name in ("a.trc", "b.trc"):
        shutil.copy(trc, tmp_path / name)
    p = run(["mpz", "encode", "a.trc", "b.trc", "--max-error", "1mm", "--json"], tmp_path)
    assert p.returncode == 0, p.stderr
    doc = json.loads(p.stdout)
    assert doc["schema"] == "mpz-encode-batch/1" and doc["failures"] == [], doc
    assert [os.path.basename(r["output"]) for r in doc["files"]] == ["a.mpz", "b.mpz"], doc
    assert "2 inputs: 2 done, 0 failed" in p.stderr


def test_no_valid_sample_gives_no_error_figures(tmp_path: Path) -> None:
    """A CLI audit: a motion whose every sample is a gap was reported with a max, RMS and
    ARMS error of 0.0 (a figure of nothing compared) and "every sample within" the bound.
    The figures are null in JSON and said to be unmeasured in text."""
    from mpz import Motion
    m = Motion(np.full((20, 3, 3), np.nan), ["A", "B", "C"], rate=100.0, units="mm")
    write(m, tmp_path / "gaps.c3d")
    p = run(["mpz", "encode", "gaps.c3d", "--max-error", "1mm", "--json"], tmp_path)
    assert p.returncode == 0, p.stderr
    doc = json.loads(p.stdout)
    assert [doc[k] for k in ("max_error", "arms", "p99", "rms")] == [None] * 4, doc
    p = run(["mpz", "encode", "gaps.c3d", "--max-error", "1mm", "-o", "t.mpz"], tmp_path)
    assert "error    none measured: no sample of the input is valid" in p.stdout, p.stdout
    p = run(["mpz", "compare", "gaps.c3d", "t.mpz", "--json"], tmp_path)
    doc = json.loads(p.stdout)
    assert [doc[k] for k in ("max", "arms", "rms", "p99", "mean")] == [None] * 5, doc
    p = run(["mpz", "compare", "gaps.c3d", "t.mpz"], tmp_path)
    assert "no sample of the original is valid: no error to measure" in p.stdout
    assert "no valid sample to hold to it" in p.stdout and "every sample" not in p.stdout
    # one valid sample: measured as before
    m.positions[3, 1] = (1.0, 2.0, 3.0)
    m.valid[3, 1] = True
    write(m, tmp_path / "one.c3d")
    p = run(["mpz", "encode", "one.c3d", "--max-error", "1mm", "--json"], tmp_path)
    assert isinstance(json.loads(p.stdout)["max_error"], float)


def test_summary_of_a_short_motion_lowers_the_default_levels(tmp_path: Path) -> None:
    """A CLI audit: `mpz summary` of a 5-frame file, no --k given, failed ("no requested k
    fits the 5 frames", exit 2) and of a 10-frame one warned (exit 1) of default levels
    nobody had asked for; 10 of the conformance suite's valid vectors failed so. The
    default levels are lowered to the frames, as the encoder lowers a summary's; a k given
    beyond them is still dropped with a warning."""
    for frames, want in ((5, [5]), (10, [6, 10])):
        write(generate("walk", frames=frames), tmp_path / f"f{frames}.c3d")
        p = run(["mpz", "summary", f"f{frames}.c3d", "--json"], tmp_path)
        assert p.returncode == 0 and "warning" not in p.stderr, p.stderr
        levels = json.loads(p.stdout)["levels"]
        assert [lv["k"] for lv in levels] == want
        # k = frames: every frame a segment of its own, WSSSE 0
        assert levels[-1]["wssse"] == 0.0
    p = run(["mpz", "summary", "f10.c3d", "--k", "6,12", "--json"], tmp_path)
    assert p.returncode == 1 and "k=12 dropped: the motion has only 10 frames" in p.stderr


def test_standard_input_given_twice_is_a_usage_error(small: tuple[Path, Path],
                                                     tmp_path: Path) -> None:
    """A CLI audit: `mpz compare - -` exited 2 (an input error) where `mpz bench --compare
    - -` exits 64 for the same mistake, and `mpzinfo - -` read standard input twice, the
    second time nothing ("bad signature b''", exit 2)."""
    _, enc = small
    data = enc.read_bytes()
    for args in (["mpz", "compare", "-", "-"], ["mpzinfo", "-", "-"]):
        p = subprocess.run([command(args[0]), *args[1:]], input=data, capture_output=True,
                           cwd=tmp_path, timeout=300)
        assert p.returncode == 64, (args, p.stderr)
        assert b"standard input" in p.stderr and b"signature" not in p.stderr
    p = subprocess.run([command("mpzinfo"), "-"], input=data, capture_output=True,
                       cwd=tmp_path, timeout=300)
    assert p.returncode == 0, p.stderr


def test_a_failing_command_run_with_json_prints_an_error_document(small: tuple[Path, Path],
                                                                  tmp_path: Path) -> None:
    """A CLI audit: `mpz show --json` and `mpzinfo --json` print an error document when
    they fail, but `mpz compare`, `summary` and `search --json` printed nothing on stdout,
    which a script then failed to parse."""
    trc, enc = small
    data = bytearray(enc.read_bytes())
    data[len(data) // 2] ^= 0xFF                    # a CRC that no longer matches
    (tmp_path / "flip.mpz").write_bytes(bytes(data))
    for args, cls in ((["compare", str(trc), "flip.mpz"], "ChecksumError"),
                      (["summary", "flip.mpz"], "ChecksumError"),
                      (["summary", "nosuch.c3d"], None),
                      (["search", str(trc), "--index", "nowhere.sqlite"], "EncoderError")):
        p = run(["mpz", *args, "--json"], tmp_path)
        assert p.returncode == 2, (args, p.stderr)
        doc = json.loads(p.stdout)
        assert doc["status"] == "error" and doc["command"] == f"mpz {args[0]}", doc
        assert doc["error"]["class"] == cls and doc["error"]["message"], doc
        if cls == "ChecksumError":
            assert doc["error"]["section"] == "§3.3" and doc["error"]["offset"] > 0, doc


# -- standard streams as a shell can leave them (a QA run of the CLI plumbing) -----------------

def _buffered_env(**extra: str) -> dict[str, str]:
    """The environment without PYTHONUNBUFFERED: a user's, where standard output is buffered
    (set where the earlier QA runs ran, it hid every failure of the final flush)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    env.update(extra)
    return env


def _with_fds(argv: Sequence[str], cwd: Path, *, stdout: str, stderr: str = "pipe",
              **env: str) -> subprocess.CompletedProcess[bytes]:
    """Run ``argv`` as ``CMD >&-`` (``stdout="closed"``), ``1</dev/null`` ("read-only"),
    ``> /dev/full`` ("full") or into a pipe ("pipe"); ``stderr`` "closed" or "pipe"."""
    def close() -> None:
        if stdout == "closed":
            os.close(1)
        if stderr == "closed":
            os.close(2)
    out: object = subprocess.PIPE
    opened = None
    if stdout == "read-only":
        opened = out = open(os.devnull, "rb")
    elif stdout == "full":
        opened = out = open("/dev/full", "wb")
    try:
        return subprocess.run([command(argv[0]), *argv[1:]], cwd=cwd, stdout=out,
                              stderr=subprocess.PIPE, preexec_fn=close, timeout=300,
                              env=_buffered_env(**env))
    finally:
        if opened is not None:
            opened.close()


_CANNOT_WRITE = {"full": "No space left on device", "closed": "Bad file descriptor",
                 "read-only": "Bad file descriptor"}


def _cannot_write(argv: Sequence[str], cwd: Path, how: str) -> None:
    p = _with_fds(argv, cwd, stdout=how)
    err = p.stderr.decode()
    prog = "mpzinfo" if argv[0] == "mpzinfo" else "mpz" if "-h" in argv else " ".join(argv[:2])
    assert (p.returncode, err) == (
        2, f"{prog}: error: cannot write standard output: {_CANNOT_WRITE[how]}\n"), (
        argv, how, p.returncode, err[-800:])


def test_a_buffered_report_that_cannot_be_written_is_an_error(small: tuple[Path, Path],
                                                              tmp_path: Path) -> None:
    """With standard output buffered, as it is for a user (no PYTHONUNBUFFERED), a report
    that could not be written failed only in the final flush: ``mpz show x > /dev/full``
    printed a traceback and exited 120; ``>&-`` (closed) made sys.stdout None: a
    traceback and exit 1; ``1</dev/null``: exit 70. Each is now "cannot write standard
    output", exit 2, no traceback (a QA run of the CLI plumbing)."""
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full on this system")
    _trc, enc = small
    _cannot_write(["mpz", "show", str(enc)], tmp_path, "full")
    _cannot_write(["mpz", "show", "--json", str(enc)], tmp_path, "closed")
    _cannot_write(["mpzinfo", str(enc)], tmp_path, "read-only")


def test_help_and_data_into_a_standard_output_that_cannot_take_them(
        small: tuple[Path, Path], tmp_path: Path) -> None:
    """``mpz encode -h > /dev/full`` exited 0 (argparse drops its write errors), and
    ``mpz encode x -o - >&-`` failed on sys.stdout being None (exit 70); a command that
    prints nothing on success still succeeds with standard output closed."""
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full on this system")
    trc, _enc = small
    _cannot_write(["mpz", "encode", "-h"], tmp_path, "full")
    _cannot_write(["mpz", "encode", "-q", str(trc), "-o", "-"], tmp_path, "closed")
    p = _with_fds(["mpz", "encode", "-q", str(trc), "-o", "out.mpz"], tmp_path, stdout="closed")
    assert p.returncode == 0 and p.stderr == b"", p.stderr[-800:]
    assert mpz.decode((tmp_path / "out.mpz").read_bytes()).n_frames == 60


def test_a_non_blocking_standard_output_waits_for_a_slow_reader(small: tuple[Path, Path],
                                                                tmp_path: Path) -> None:
    """A pipe that a parent set non-blocking (O_NONBLOCK is shared by every process that
    holds it), read slower than mpz writes: the write raised BlockingIOError, and
    ``mpz decode x -o - -F csv`` ended with 64 KiB of its data, a traceback and exit 120."""
    import fcntl
    m = generate("walk", frames=3000, seed=4)
    (tmp_path / "w.mpz").write_bytes(mpz.encode(m, max_error=1.0))
    r, w = os.pipe()
    fcntl.fcntl(w, fcntl.F_SETFL, fcntl.fcntl(w, fcntl.F_GETFL) | os.O_NONBLOCK)
    proc = subprocess.Popen([command("mpz"), "decode", "-q", "w.mpz", "-o", "-", "-F", "csv"],
                            cwd=tmp_path, stdout=w, stderr=subprocess.PIPE,
                            env=_buffered_env())
    os.close(w)
    try:
        time.sleep(2.0)                     # the pipe is full, the command still writing
        with os.fdopen(r, "rb") as reader:
            got = reader.read()
        err = proc.communicate(timeout=120)[1]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0 and err == b"", err[-800:]
    assert got.count(b"\n") == 3001, len(got)


def test_a_closed_standard_error_keeps_the_notes_out_of_standard_output(
        small: tuple[Path, Path], tmp_path: Path) -> None:
    """With standard error closed (``2>&-``), ``print(..., file=sys.stderr)`` printed to
    standard output: CSV notes went into ``decode -o -``'s data, and a traceback (exit 70)
    into ``encode -o -``'s MPZ stream."""
    trc, enc = small
    p = _with_fds(["mpz", "decode", str(enc), "-o", "-", "-F", "csv"], tmp_path,
                  stdout="pipe", stderr="closed")
    assert p.returncode == 0 and p.stdout.startswith(b"frame,time,"), p.stdout[:300]
    assert b"note:" not in p.stdout
    p = _with_fds(["mpz", "encode", str(trc), "-o", "-"], tmp_path, stdout="pipe",
                  stderr="closed")
    assert p.returncode == 0, p.stdout[-800:]
    assert mpz.decode(p.stdout).n_frames == 60
    p = _with_fds(["mpz", "show", "--json", "missing.trc"], tmp_path, stdout="pipe",
                  stderr="closed")
    assert p.returncode == 2 and json.loads(p.stdout)["status"] == "error", p.stdout[-800:]


def test_a_standard_output_that_is_not_utf8_takes_every_name(tmp_path: Path) -> None:
    """A standard output that is not UTF-8 (a Latin-1 locale, PYTHONIOENCODING=ascii)
    could not print a marker called "tête" or mpzinfo's own "→": UnicodeEncodeError, a
    traceback and exit 70. Text now escapes what it cannot encode, and --json writes
    \\u escapes: strict JSON in any ASCII-compatible encoding."""
    m = generate("walk", frames=30, seed=3)
    m = replace(m, names=["tête", "肩", *m.names[2:]])
    write(m, tmp_path / "tête.trc")
    (tmp_path / "tête.mpz").write_bytes(mpz.encode(m, max_error=1.0))
    for encoding, argv in (("latin-1", ["mpzinfo", "-vv", "tête.mpz"]),
                           ("ascii", ["mpz", "compare", "tête.trc", "tête.mpz", "--top", "0"]),
                           ("ascii", ["mpz", "show", "--json", "tête.trc"]),
                           ("latin-1", ["mpzinfo", "--json", "-vv", "tête.mpz"])):
        p = subprocess.run([command(argv[0]), *argv[1:]], cwd=tmp_path, capture_output=True,
                           timeout=300, env=_buffered_env(PYTHONIOENCODING=encoding))
        assert p.returncode == 0 and b"Traceback" not in p.stderr, (argv, p.stderr[-800:])
        text = p.stdout.decode(encoding)
        if "--json" in argv:
            assert p.stdout.isascii() and "t\\u00eate" in text, (argv, text[:300])
            json.loads(text)
        else:
            assert "\\u80a9" in text, (argv, text[-800:])        # 肩, escaped


def test_a_ratio_below_one_keeps_its_digits():
    """A one-frame AMC's ratio of 0.06 printed "0.0:1" (an animation studio's QA run of
    stop 75): two significant digits, in fixed notation, where one decimal shows less than
    1.0; one decimal elsewhere, as before."""
    from mpz.tools._common import ratio_text
    assert [ratio_text(r) for r in (0.0625, 0.5, 0.94, 0.95, 0.96, 0.999, 1.0, 11.6944,
                                    250.0, 0.0, 1.234e-5)] == \
        ["0.062", "0.50", "0.94", "0.95", "1.0", "1.0", "1.0", "11.7", "250.0", "0.0",
         "0.000012"]


def test_mpzinfo_vv_prints_names_as_they_are(tmp_path: Path) -> None:
    """`mpzinfo -vv` printed a name "Hüfte_links" as JSON's "H\\u00fcfte_links", where every
    other report prints it (an animation studio's QA run of stop 75); what a terminal
    must not get is still escaped."""
    m = mpz.Motion(np.zeros((3, 3, 3)), ["Hüfte_links", "肩", "A\x1b[2J"], 60.0, "mm")
    (tmp_path / "u.mpz").write_bytes(mpz.encode(m))
    p = subprocess.run([command("mpzinfo"), "-vv", "u.mpz"], cwd=tmp_path,
                       capture_output=True, timeout=300,
                       env=_buffered_env(PYTHONIOENCODING="utf-8"))
    text = p.stdout.decode("utf-8")
    # the escape character as JSON writes it, \u001b: never the raw byte
    assert p.returncode == 0 and 'names = ["Hüfte_links", "肩", "A\\u001b[2J"]' in text, text
    assert "\\u00fc" not in text and "\x1b" not in text
