"""The runner against decoders, commands and vector folders that misbehave (a black-box QA
of stop 28 found each of these): it must give the right verdict, never a traceback, a
hang or an unbounded use of its own memory.

Each decoder here is a small script written into the test's folder; most wrap the
reference decoder and then break its output.
"""
from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path
import re
import shutil
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

PY = sys.executable
ONE = "spec-example"          # a small valid vector
BAD = "x01-bad-signature"     # an invalid one


def script(path: Path, text: str) -> Path:
    """An executable file holding ``text`` (a fake decoder)."""
    path.write_text(text)
    path.chmod(0o755)
    return path


def python_script(path: Path, body: str) -> Path:
    """An executable Python script of ``body``, with sys imported."""
    return script(path, f"#!{PY}\nimport sys\n{body}")


def decoder(tmp_path: Path, body: str, name: str = "dec.py") -> Path:
    """An executable decoder script: the reference decoder, then ``body`` (IN, OUT bound)."""
    return script(tmp_path / name, f"#!{PY}\n" + textwrap.dedent('''\
        import subprocess, sys
        import numpy as np
        IN, OUT = sys.argv[-2], sys.argv[-1]
        REF = [sys.executable, "-m", "mpz.conformance.refdecoder"]
        rc = subprocess.run(REF + [IN, OUT]).returncode
        ''') + textwrap.dedent(body) + "\nsys.exit(rc)\n")


def run(tmp_path: Path, *args: str, timeout: float = 300) -> tuple[subprocess.CompletedProcess,
                                                                  dict | None]:
    out = tmp_path / "results.json"
    proc = subprocess.run([PY, "-m", "mpz.conformance.runner", *args, "--results", str(out)],
                          capture_output=True, text=True, timeout=timeout, cwd=tmp_path)
    return proc, (json.loads(out.read_text()) if out.exists() else None)


def test_a_huge_wrong_value_fails_with_finite_json(tmp_path):
    """1e300 made the RMS infinite: the results file was never written (a traceback)."""
    dec = decoder(tmp_path, '''
        if rc == 0:
            x = np.load(OUT); i = np.argwhere(np.isfinite(x))[0]
            x[tuple(i)] = -1e300; np.save(OUT, x)
            import os; os.path.exists(OUT + ".intlayer") and os.remove(OUT + ".intlayer")
        ''')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    r = doc["results"][0]
    # the RMS is scaled, so finite since stop 50 (it was inf, written as null)
    assert not r["passed"] and 1e299 < r["rms"] < r["max_abs"] and r["max_abs"] > 1e299
    assert "beyond max_abs" in r["message"] and "rms error 2.58199e+299" in r["message"]


def test_an_npz_output_is_not_a_npy(tmp_path):
    dec = decoder(tmp_path, '''
        if rc == 0:
            x = np.load(OUT); np.savez(open(OUT, "wb"), x)
        ''')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "not a .npy file" in doc["results"][0]["message"]


def test_a_huge_integer_units_code_is_a_mismatch(tmp_path):
    dec = decoder(tmp_path, '''
        if rc == 0:
            p = OUT + ".json"; t = open(p).read()
            import json; d = json.loads(t); d["units"] = 10 ** 400
            open(p, "w").write(json.dumps(d))
        ''')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert doc["results"][0]["sidecar"] == "mismatch"


def test_huge_files_beside_the_output_are_not_read(tmp_path):
    """QA (stop 33): a decoder that left a 1.5 GB (sparse) sidecar or integer-layer digest
    took the runner to 3.2 GB while it read them whole. Past their caps they are named,
    not read, and the vector fails."""
    dec = decoder(tmp_path, '''
        if rc == 0:
            for ext in (".json", ".intlayer"):
                with open(OUT + ext, "r+b" if ext == ".json" else "wb") as fh:
                    fh.truncate(1 << 31)
        ''')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    r = doc["results"][0]
    assert not r["passed"] and r["sidecar"] == "unreadable", r
    assert "larger than" in r["message"], r["message"]


@pytest.mark.parametrize("last_lines, verdict", [
    ("Traceback (most recent call last):\\nnumpy._core._exceptions._ArrayMemoryError: "
     "Unable to allocate 8.00 TiB", "memory"),
    ("fatal error: runtime: out of memory\\n\\nruntime stack:\\nruntime.throw()", "memory"),
    ('Exception in thread \\"main\\" java.lang.OutOfMemoryError: Java heap space\\n'
     "\\tat Dec.main(Dec.java:3)", "memory"),
    ("error: the file declares 2^36 samples; refusing it, it would run out of memory",
     "reject"),
    # Python under a small --memory: a MemoryError while starting, then a fatal error that
    # ends in two more lines (it passed as "rejected (exit 1)", a QA run of stop 55)
    ("MemoryError\\nFatal Python error: init_importlib_external: external importer setup "
     "failed\\nPython runtime state: core initialized", "memory"),
    ("Fatal Python error: _PyInterpreterState_GET: the function must be called with the GIL "
     "held\\nPython runtime state: initialized", "crash"),
    ("OpenBLAS error: Memory allocation still failed after 10 retries, giving up.", "crash"),
    # ... but a decoder that met it, said so and rejected the file rejected it (a review of
    # stop 55: an optional library's loader note failed every invalid vector)
    ("mydec: note: libfast.so: failed to map segment from shared object; using the "
     "portable code\\nerror: bad signature (spec §3.1)", "reject"),
    ("error: the file is no MPZ file: fatal error: bad signature", "reject"),
])
def test_out_of_memory_is_told_from_a_rejection(tmp_path, last_lines, verdict):
    """numpy's, Go's and Java's out-of-memory ends passed as rejections of invalid files;
    a rejection that only mentions memory failed as one. So did a Python runtime that
    aborted, and OpenBLAS giving up its buffers, which exit 1 too."""
    dec = python_script(tmp_path / "oom.py", f'sys.stderr.write("{last_lines}\\n")\nsys.exit(2)\n')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD)
    r = doc["results"][0]
    assert r["actual"] == verdict and r["passed"] == (verdict == "reject"), r


def test_a_command_that_cannot_run_is_no_rejection(tmp_path):
    """A wrapper whose interpreter is missing exits 127: every invalid vector "passed"."""
    dec = script(tmp_path / "badshebang.sh", "#!/bin/sh\nexec /nonexistent/python4 \"$@\"\n")
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD)
    r = doc["results"][0]
    assert proc.returncode == 1 and r["actual"] == "error" and "127" in r["message"]


def test_relative_paths_in_the_command_are_found(tmp_path):
    """`python3 dec.py` ran dec.py in the temporary folder, where it is not: every valid
    vector failed and every invalid one passed."""
    decoder(tmp_path, "")
    proc, doc = run(tmp_path, "--decoder", f"{PY} dec.py", "--only", ONE, BAD)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert all(r["passed"] for r in doc["results"])


def test_an_argument_made_absolute_is_said_and_as_given_keeps_it(tmp_path):
    """An argument that happens to name a folder where the runner runs ("fast", a mode of
    the decoder) was made absolute without a word (a conformance QA run of stop 55): a
    note names each one, and --as-given passes them as written."""
    (tmp_path / "fast").mkdir()
    seen = tmp_path / "seen.txt"
    decoder(tmp_path, f"open({str(seen)!r}, 'w').write(sys.argv[1])")
    proc, doc = run(tmp_path, "--decoder", f"{PY} dec.py fast", "--only", ONE)
    assert proc.returncode == 0 and doc["results"][0]["passed"], proc.stdout + proc.stderr
    assert seen.read_text() == str(tmp_path / "fast")
    assert (f"note: arguments that name a file or folder here are given as absolute paths "
            f"(the command runs in a temporary directory): dec.py -> {tmp_path / 'dec.py'}, "
            f"fast -> {tmp_path / 'fast'}; --as-given leaves them as written") in proc.stderr
    proc, doc = run(tmp_path, "--decoder", f"{PY} {tmp_path / 'dec.py'} fast", "--only", ONE,
                    "--as-given")
    assert proc.returncode == 0 and doc["results"][0]["passed"], proc.stdout + proc.stderr
    assert seen.read_text() == "fast" and "note: arguments" not in proc.stderr
    proc, _ = run(tmp_path, "--decoder", f"{PY} dec.py fast", "--only", ONE, "--as-given")
    assert proc.returncode == 1 and "with --as-given, a relative path among its arguments " \
        "is looked for there too" in proc.stderr, proc.stderr
    proc, _ = run(tmp_path, "--decoder", f"{PY} dec.py fast", "--only", ONE, "-q")
    assert proc.returncode == 0 and "note: arguments" not in proc.stderr


def test_what_the_decoder_prints_on_stdout_is_kept(tmp_path):
    """A JVM that cannot start under the memory limit says why on stdout, which was
    thrown away."""
    dec = python_script(tmp_path / "vm.py", "print('Error occurred during initialization of VM')\n"
                        "sys.exit(1)\n")
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    assert "initialization of VM" in doc["results"][0]["message"]


def test_a_child_left_running_is_killed_and_costs_no_wait(tmp_path):
    """A decoder that leaves `sleep 30` behind (holding its stderr) cost 5 s a vector and
    the sleep outlived the runner. The decoder copies the reference decoder's output, made
    beforehand, so that its own time is tens of milliseconds and 4 s tells the wait apart
    on a loaded machine (running the reference decoder inside took 4.5 s on one: CI)."""
    from mpz.conformance import manifest as mf
    ref = tmp_path / "ref.npy"
    made = subprocess.run([PY, "-m", "mpz.conformance.refdecoder",
                           str(Path(mf.DEFAULT_DIR) / f"{ONE}.mpz"), str(ref)],
                          capture_output=True, text=True, timeout=300)
    assert made.returncode == 0 and Path(f"{ref}.json").exists(), made.stderr
    mark = tmp_path / "child.pid"
    dec = python_script(tmp_path / "dec.py", f"""
import shutil, subprocess
OUT = sys.argv[-1]
shutil.copyfile({str(ref)!r}, OUT)
shutil.copyfile({str(ref)!r} + ".json", OUT + ".json")
p = subprocess.Popen(["sleep", "30"])
open({str(mark)!r}, "w").write(str(p.pid))
""")
    t0 = time.monotonic()
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    assert doc["results"][0]["passed"] and doc["results"][0]["seconds"] < 4
    pid = int(mark.read_text())
    time.sleep(0.2)
    gone = True
    try:
        os.kill(pid, 0)
        state = Path(f"/proc/{pid}/stat").read_text().split()[2] if Path(
            f"/proc/{pid}").exists() else "X"
        gone = state == "Z"                     # killed, not yet reaped by init
    except ProcessLookupError:
        pass
    assert gone and time.monotonic() - t0 < 60


def test_megabytes_of_output_keep_a_short_tail(tmp_path):
    dec = python_script(tmp_path / "spam.py", "sys.stderr.write('x' * (64 << 20))\n"
                        "sys.stderr.write('\\nthe end\\n')\nsys.exit(2)\n")
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD)
    r = doc["results"][0]
    assert r["passed"] and len(r["stderr_tail"]) <= 2000 and "the end" in r["stderr_tail"]


@pytest.mark.parametrize("args, phrase", [
    (["--timeout", "nan"], "--timeout"), (["--timeout", "inf"], "--timeout"),
    (["--memory", "99999999999999"], "--memory"),
])
def test_option_values_that_disable_a_limit_are_usage_errors(tmp_path, args, phrase):
    proc, _ = run(tmp_path, "--decoder", f"{PY} -m mpz.conformance.refdecoder", "--only", ONE,
                  *args)
    assert proc.returncode == 64 and phrase in proc.stderr and "Traceback" not in proc.stderr


def test_a_results_folder_is_refused_before_any_vector_runs(tmp_path):
    (tmp_path / "res").mkdir()
    proc = subprocess.run([PY, "-m", "mpz.conformance.runner", "--decoder",
                           f"{PY} -c 'raise SystemExit(9)'", "--only", ONE, "--results",
                           str(tmp_path / "res")], capture_output=True, text=True)
    assert proc.returncode == 64 and "a folder" in proc.stderr and "PASS" not in proc.stdout


def _copy_vectors(tmp_path: Path) -> Path:
    from mpz.conformance import manifest as mf
    dst = tmp_path / "vectors"
    shutil.copytree(mf.DEFAULT_DIR, dst, ignore=shutil.ignore_patterns("__pycache__", "*.py"))
    return dst


def test_damaged_or_missing_vectors_are_usage_errors(tmp_path):
    """A damaged copy made a correct decoder fail, and a missing file was a traceback."""
    vdir = _copy_vectors(tmp_path)
    with open(vdir / "spec-example.npy", "r+b") as f:
        f.seek(-1, 2)
        f.write(b"\x01")
    (vdir / "invalid" / f"{BAD}.mpz").unlink()
    for only in (ONE, BAD):
        proc, _ = run(tmp_path, "--decoder", f"{PY} -m mpz.conformance.refdecoder",
                      "--vectors", str(vdir), "--only", only)
        assert proc.returncode == 64 and "do not match the manifest" in proc.stderr, only


@pytest.mark.parametrize("manifest", [
    b'{"schema_version": 2, "vectors": ["x"]}', b"\xff\xfe{}",
])
def test_a_malformed_manifest_is_a_usage_error(tmp_path, manifest):
    (tmp_path / "v").mkdir()
    (tmp_path / "v" / "manifest.json").write_bytes(manifest)
    proc, _ = run(tmp_path, "--decoder", f"{PY} -m mpz.conformance.refdecoder", "--vectors",
                  str(tmp_path / "v"))
    assert proc.returncode == 64 and "Traceback" not in proc.stderr


@pytest.mark.parametrize("kind", ["step a string", "names a number", "fifo", "device"])
def test_a_hostile_vectors_folder_is_a_usage_error(tmp_path, kind):
    """QA (stop 33): a header fact of the wrong type (step "abc") was a traceback in the
    comparison, a FIFO as manifest.json hung, and /dev/zero was read without end."""
    from mpz.conformance import manifest as mf
    vdir = tmp_path / "v"
    if kind in ("fifo", "device"):
        vdir.mkdir()
        if kind == "fifo":
            os.mkfifo(vdir / "manifest.json")
        else:
            (vdir / "manifest.json").symlink_to("/dev/zero")
    else:
        vdir = _copy_vectors(tmp_path)
        man = json.loads((vdir / "manifest.json").read_text())
        v = next(x for x in man["vectors"] if x["name"] == ONE)
        if kind == "step a string":
            v["header"]["step"] = "abc"
        else:
            v["header"]["names"] = 3
        (vdir / "manifest.json").write_text(json.dumps(man))
        with pytest.raises(mf.ManifestError, match="header"):
            mf.load(vdir)
    proc, _ = run(tmp_path, "--decoder", f"{PY} -m mpz.conformance.refdecoder", "--vectors",
                  str(vdir), "--only", ONE, timeout=120)
    assert proc.returncode == 64 and "Traceback" not in proc.stderr, proc.stderr


def test_ctrl_c_stops_at_once(tmp_path):
    """Ctrl-C waited for the running decoder's timeout, then printed a traceback. The signal
    is sent once the decoder runs (a fixed 3 s wait could still be the runner's imports
    on a slow machine)."""
    mark = tmp_path / "started"
    decoder_cmd = (f'{PY} -c "import pathlib, time; pathlib.Path(\'{mark}\').touch(); '
                   f'time.sleep(60)"')
    proc = subprocess.Popen([PY, "-m", "mpz.conformance.runner", "--decoder", decoder_cmd,
                             "--only", ONE, "--timeout", "50"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not mark.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    assert mark.exists(), proc.communicate(timeout=30)
    t0 = time.monotonic()
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130 and time.monotonic() - t0 < 10
    assert "interrupted" in err and "Traceback" not in err


def test_encoder_only_names_are_checked_and_compared_as_numbers(tmp_path):
    enc = f"{PY} -m mpz.conformance.refencoder"
    proc, _ = run(tmp_path, "--encoder", enc, "--only", "e01-walk-41-gaps", "bogus")
    assert proc.returncode == 64 and "bogus" in proc.stderr
    proc, _ = run(tmp_path, "--encoder", enc, "--only", "bogus")        # alone, too (QA)
    assert proc.returncode == 64 and "bogus" in proc.stderr, proc.stderr
    from mpz.conformance import manifest as mf
    item = mf.load()["encoder_inputs"][0]
    E = float(item["max_errors"][0])
    proc, doc = run(tmp_path, "--encoder", enc, "--only", f"{item['name']}@{E!r}")
    assert proc.returncode == 0 and len(doc["results"]) == 1, proc.stderr


def test_control_characters_from_the_decoder_are_escaped(tmp_path):
    dec = python_script(tmp_path / "esc.py", "sys.stderr.write('bad \\x1b[2J file\\n')\n"
                        "sys.exit(3)\n")
    proc, _ = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    assert "\x1b" not in proc.stdout and "bad \\x1b[2J file" in proc.stdout


# -- QA of stop 42 ----------------------------------------------------------------------------

@pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="POSIX signals")
@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
def test_sigterm_and_sighup_kill_the_decoders_too(tmp_path, signame):
    """The decoders run in their own process groups: a SIGTERM (a CI job's timeout) or
    SIGHUP to the runner alone ended it and left every running decoder behind."""
    pids = tmp_path / "pids"
    pids.mkdir()
    dec = python_script(tmp_path / "hang.py", f"import os, time\n"
                        f"open(os.path.join({str(pids)!r}, str(os.getpid())), 'w').close()\n"
                        "time.sleep(120)\n")
    proc = subprocess.Popen([PY, "-m", "mpz.conformance.runner", "--decoder", str(dec),
                             "--only", BAD, "x02-signature-only", "--jobs", "2",
                             "--timeout", "100"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while len(list(pids.iterdir())) < 2 and proc.poll() is None \
            and time.monotonic() < deadline:
        time.sleep(0.02)
    started = [int(p.name) for p in pids.iterdir()]
    assert len(started) == 2, proc.communicate(timeout=30)
    sig = getattr(signal, signame)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 128 + sig and f"stopped by {signame}" in err, err
    assert "Traceback" not in err

    def alive(pid: int) -> bool:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True
    deadline = time.monotonic() + 10
    while any(alive(p) for p in started) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(alive(p) for p in started), "a decoder outlived the runner"


def test_a_value_just_beyond_tolerance_shows_the_difference(tmp_path):
    """An FMA-sized error printed 'got 1673.000000, expected 1673.000000 (... 0.000 grid
    steps)': nothing looked wrong. Both values now show where they differ."""
    dec = decoder(tmp_path, '''
        if rc == 0:
            x = np.load(OUT); i = tuple(np.argwhere(np.isfinite(x))[0])
            x[i] += 4.9e-7; np.save(OUT, x)           # below the 6th decimal's half
            import os; os.path.exists(OUT + ".intlayer") and os.remove(OUT + ".intlayer")
        ''')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    r = doc["results"][0]
    f = r["first_failure"]
    assert r["allowed_max_abs"] < 4.9e-7 and not r["passed"] and f["got"] != f["expected"]
    shown = re.search(r"got (\S+), expected (\S+) \(off by \S+ = (\S+) grid steps", r["message"])
    assert shown and shown.group(1) != shown.group(2), r["message"]
    assert float(shown.group(1)) == f["got"] and float(shown.group(3)) != 0, r["message"]


@pytest.mark.parametrize("body, said", [
    ('open(OUT, "w").write("not an array")', "does not begin with the NPY magic"),
    ('d = open(OUT, "rb").read(); open(OUT, "wb").write(d[:len(d) // 2])',
     "bytes of data, and the file holds"),
])
def test_an_unreadable_npy_is_told_in_the_formats_terms(tmp_path, body, said):
    """numpy said a text file 'contains pickled (object) data' and a short one 'mmap length
    is greater than file size'."""
    dec = decoder(tmp_path, f"if rc == 0:\n    {body}\n")
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    msg = doc["results"][0]["message"]
    assert said in msg and "pickle" not in msg and "mmap" not in msg, msg
    assert "Warning" not in proc.stderr, proc.stderr


def test_only_takes_the_labels_the_runner_prints(tmp_path):
    proc, doc = run(tmp_path, "--decoder", f"{PY} -m mpz.conformance.refdecoder", "--only",
                    f"valid/{ONE}", f"invalid/{BAD}")
    assert proc.returncode == 0 and sorted(r["name"] for r in doc["results"]) == [ONE, BAD]
    proc, _ = run(tmp_path, "--decoder", f"{PY} -m mpz.conformance.refdecoder", "--only",
                  "valid/nothing-of-that-name")
    assert proc.returncode == 64 and "no vector named valid/nothing-of-that-name" in proc.stderr


@pytest.mark.parametrize("code", [131, 152, 153, 159])
def test_a_shells_report_of_any_fatal_signal_is_a_crash(tmp_path, code):
    """128 + SIGQUIT, SIGXCPU (ulimit -t), SIGXFSZ and SIGSYS (seccomp) passed as
    rejections, while the same signals delivered directly were crashes."""
    dec = script(tmp_path / "dec.sh", f"#!/bin/sh\nexit {code}\n")
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD)
    r = doc["results"][0]
    assert r["actual"] == "crash" and not r["passed"], r


@pytest.mark.parametrize("code, actual", [(130, "crash"), (141, "crash"), (143, "crash"),
                                          (200, "error"), (255, "error")])
def test_exit_statuses_above_125_are_no_rejection(tmp_path, code, actual):
    """Spec §7.3: a rejection is an exit status from 1 to 125. 128 + SIGTERM, SIGINT or
    SIGPIPE and statuses such as 200 or 255 passed as "rejected (exit 143)" (a QA run of
    stop 53); only the fatal signals' 128 + N were counted as crashes."""
    dec = script(tmp_path / "dec.sh", f"#!/bin/sh\nexit {code}\n")
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD)
    r = doc["results"][0]
    assert r["actual"] == actual and not r["passed"], r
    assert "not a rejection" in r["message"] and "§7.3" in r["message"], r
    dec = script(tmp_path / "ok.sh", "#!/bin/sh\nexit 125\n")
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD)
    assert doc["results"][0]["passed"], doc["results"][0]


def test_a_command_selected_for_invalid_vectors_alone_must_decode_one(tmp_path):
    """With only invalid vectors selected, a command that never starts (python -m of no
    module) "rejected" every one: "319/319 passed", exit 0 (a QA run of stop 53). The
    runner decodes one valid vector as well, not counted, and fails when it cannot."""
    proc, doc = run(tmp_path, "--decoder", f"{PY} -m no_such_decoder_module", "--only", BAD)
    assert proc.returncode == 1, proc.stderr
    assert doc["totals"] == {"total": 1, "passed": 1, "failed": 0, "not_run": 0,
                             "groups": doc["totals"]["groups"]}
    assert not doc["probe"]["passed"] and "its rejections prove nothing" in proc.stderr
    # the summary line says it too: "1/1 passed" stood above exit 1 (a CLI audit)
    assert "1/1 passed (invalid 1/1); not proven: the command did not decode valid/" \
        in proc.stdout, proc.stdout
    proc, doc = run(tmp_path, "--decoder", f"{PY} -m mpz.conformance.refdecoder", "--only",
                    BAD)
    assert proc.returncode == 0 and doc["probe"]["passed"], proc.stderr
    assert "not proven" not in proc.stdout
    assert "run as a check that it decodes at all (not counted)" in proc.stdout
    proc, doc = run(tmp_path, "--decoder", f"{PY} -m mpz.conformance.refdecoder", "--only",
                    BAD, ONE)
    assert proc.returncode == 0 and "probe" not in doc


def test_a_command_that_decodes_nothing_is_warned_of(tmp_path):
    """`python3 -m mydec` finds no module from the temporary directory: it exits 1 on
    every vector, and every invalid one passed as rejected, without a word."""
    (tmp_path / "mydec.py").write_text("raise SystemExit(0)\n")
    proc, _ = run(tmp_path, "--decoder", f"{PY} -m mydec", "--only", ONE, BAD)
    assert proc.returncode == 1 and "No module named mydec" in proc.stdout
    assert "decoded none of the 1 valid vector(s)" in proc.stderr
    assert "prove nothing" in proc.stderr
    proc, _ = run(tmp_path, "--decoder", f"{PY} -m mpz.conformance.refdecoder", "--only",
                  ONE, BAD)
    assert proc.returncode == 0 and "warning" not in proc.stderr



def test_a_decoder_that_runs_but_fails_every_check_is_not_sent_after_its_path(tmp_path):
    """A decoder that runs and exits 0 with float32 output passes no valid vector; the
    warning told it to check that it starts at all (a QA run of stop 47). It says that the
    command ran, and the FAIL line says why."""
    dec = decoder(tmp_path, """
        if rc == 0:
            np.save(OUT, np.load(OUT).astype(np.float32))
        """)
    proc, _ = run(tmp_path, "--decoder", str(dec), "--only", ONE, BAD)
    assert proc.returncode == 1 and "float64" in proc.stdout
    assert "passed none of the 1 valid vector(s), though it ran and exited 0" in proc.stderr
    assert "check that it runs at all" not in proc.stderr


def test_a_decoder_that_crashes_or_hangs_is_not_sent_after_its_path(tmp_path):
    """A decoder that starts and then crashes (SIGSEGV) or hangs on every valid vector was
    told to check that it runs at all from a temporary directory (an implementer's QA run
    of stop 50); the warning says what it did instead."""
    crash = script(tmp_path / "crash.sh", "#!/bin/sh\nkill -SEGV $$\n")
    proc, _ = run(tmp_path, "--decoder", str(crash), "--only", ONE, BAD)
    assert proc.returncode == 1
    assert "the command crashed on each of the 1 valid vector(s)" in proc.stderr
    assert "check that it runs at all" not in proc.stderr
    hang = script(tmp_path / "hang.sh", "#!/bin/sh\nexec sleep 60\n")
    proc, _ = run(tmp_path, "--decoder", str(hang), "--timeout", "1", "--only", ONE)
    assert "the command timed out on each of the 1 valid vector(s)" in proc.stderr
    assert "check that it runs at all" not in proc.stderr


def test_an_encoder_that_renames_a_marker_is_told_which(tmp_path):
    """The encoder check quoted the first four names of each list, which were equal when
    the last marker was renamed (a QA run of stop 47). It names the first index that
    differs."""
    enc = python_script(tmp_path / "enc.py", textwrap.dedent("""\
        import json, subprocess
        IN, OUT = sys.argv[1], sys.argv[2]
        side = IN[:-len(".npy")] + ".json"
        meta = json.load(open(side))
        meta["names"][-1] = meta["names"][-1] + "_X"
        json.dump(meta, open(side, "w"))
        sys.exit(subprocess.run([sys.executable, "-m", "mpz.conformance.refencoder",
                                 *sys.argv[1:]]).returncode)
        """))
    from mpz.conformance import manifest as mf
    item = mf.load()["encoder_inputs"][0]
    proc, _ = run(tmp_path, "--encoder", str(enc), "--only", item["name"])
    names = json.loads((mf.DEFAULT_DIR / item["sidecar"]).read_text())["names"]
    assert proc.returncode == 1, proc.stdout[-600:]
    assert (f"marker names[{len(names) - 1}] = {names[-1] + '_X'!r} != input {names[-1]!r}"
            in proc.stdout), proc.stdout[-600:]

def test_an_encoder_that_drops_a_marker_is_told_which(tmp_path):
    """A dropped marker was reported as a shape alone, "(60, 40, 3) != input (60, 41, 3)"
    (a QA run of stop 48): the missing marker is named."""
    enc = python_script(tmp_path / "enc.py", textwrap.dedent("""\
        import json, subprocess
        import numpy as np
        IN, OUT = sys.argv[1], sys.argv[2]
        side = IN[:-len(".npy")] + ".json"
        meta = json.load(open(side))
        meta["names"] = meta["names"][:-1]
        json.dump(meta, open(side, "w"))
        np.save(IN, np.load(IN)[:, :-1])
        sys.exit(subprocess.run([sys.executable, "-m", "mpz.conformance.refencoder",
                                 *sys.argv[1:]]).returncode)
        """))
    from mpz.conformance import manifest as mf
    item = mf.load()["encoder_inputs"][0]
    proc, _ = run(tmp_path, "--encoder", str(enc), "--only", item["name"])
    names = json.loads((mf.DEFAULT_DIR / item["sidecar"]).read_text())["names"]
    assert proc.returncode == 1, proc.stdout[-600:]
    assert f"markers missing: {names[-1]!r}" in proc.stdout, proc.stdout[-600:]


def test_each_encoder_failure_names_its_rule():
    """Encoder-mode failures said what was wrong without the §7.4 rule, where every
    decoder-mode failure names its rules (a conformance QA run of stop 55): each names
    R-7.2-1 (the bound held), R-7.2-2 (gaps, names, rate, units), R-7.3-1 (the bound
    declared, error_bound <= E: an encoder QA run of stop 71), or §7.2's valid files."""
    import mpz
    from mpz.conformance import manifest as mf
    from mpz.conformance.runner import check_encoded
    from mpz.motion import Motion
    item = mf.load()["encoder_inputs"][0]
    x = np.load(mf.DEFAULT_DIR / item["input"])
    side = json.loads((mf.DEFAULT_DIR / item["sidecar"]).read_text())
    E = float(item["max_errors"][0])
    valid = ~np.isnan(x).any(axis=2)
    assert (~valid).any()                    # the input has gaps to fill

    def problems(bound: float = E, **change) -> list[str]:
        m = {"positions": np.where(valid[..., None], x, np.nan), "names": side["names"],
             "rate": side["rate"], "units": side.get("units", ""), **change}
        data = mpz.encode(Motion(m["positions"], m["names"], m["rate"], m["units"]),
                          max_error=bound)
        return check_encoded(data, x, side, E)[0]

    assert problems() == []
    filled = np.where(valid[..., None], x, 0.0)
    for change, rule in [({"bound": 2 * E}, "R-7.3-1"), ({"rate": side["rate"] + 1}, "R-7.2-2"),
                         ({"names": [*side["names"][:-1], "other"]}, "R-7.2-2"),
                         ({"units": "in" if side.get("units") != "in" else "m"}, "R-7.2-2"),
                         ({"positions": filled}, "R-7.2-2")]:
        got = problems(**change)
        assert got and all(rule in p for p in got), (change.keys(), got)
    # two markers swapped, names and data together: the order alone is wrong (a review
    # of stop 56: by index, a broken bound and gaps were said too)
    swap = list(range(x.shape[1]))
    gappy = next(j for j in range(x.shape[1]) if (~valid[:, j]).any())
    other = next(j for j in range(x.shape[1]) if j != gappy)
    swap[gappy], swap[other] = other, gappy
    got = problems(positions=np.where(valid[..., None], x, np.nan)[:, swap],
                   names=[side["names"][j] for j in swap])
    assert len(got) == 1 and "the same markers in another order (gaps and bound checked " \
        "by name) (R-7.2-2)" in got[0], got
    shifted = np.where(valid[..., None], x + 3 * E, np.nan)   # valid, beyond the bound
    got = check_encoded(mpz.encode(Motion(shifted, side["names"], side["rate"],
                                          side.get("units", "")), max_error=E), x, side, E)[0]
    assert len(got) == 1 and "declared bound" in got[0] and got[0].endswith("(R-7.2-1)")
    got = check_encoded(b"not an MPZ file", x, side, E)[0]
    # its rule, which the runner's message ends with, as every other failure's (a
    # maintainer's QA run of stop 75: this one had none)
    assert got[0].endswith("(§7.2: a conforming encoder writes only valid files) (R-7.3-1)")


@pytest.mark.parametrize("args, said", [
    (["--jobs", "0"], "--jobs must be at least 1, got 0"),
    (["--timeout", "0"], "--timeout must be a finite number > 0, got 0.0"),
    (["--memory", "-1"], "--memory must be 0 (no limit) .. "),
])
def test_each_bad_option_is_named_alone(tmp_path, args, said):
    proc, _ = run(tmp_path, "--decoder", f"{PY} -m mpz.conformance.refdecoder", "--only", ONE,
                  *args)
    assert proc.returncode == 64 and said in proc.stderr, proc.stderr


def test_a_crash_under_a_small_memory_limit_names_the_limit(tmp_path):
    """Under --memory 1 a shell cannot even start and dies by SIGSEGV: the report said only
    "killed by SIGSEGV". Below 64 MiB a crash names the limit; above, it does not."""
    dec = script(tmp_path / "segv.sh", "#!/bin/sh\nkill -SEGV $$\n")
    for memory, hinted in (("32", True), ("2048", False)):
        proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD, "--memory", memory)
        r = doc["results"][0]
        assert r["actual"] == "crash", r
        assert ("perhaps too little for the command to start" in r["message"]) == hinted, r


@pytest.mark.parametrize("name", ["u15-qunt-step-2pow992-bits-31",
                                  "u16-qunt-range-rounds-to-max-finite"])
def test_one_ulp_off_near_the_float_range_passes(tmp_path, name):
    """A decoder one ulp off (an FMA, another order of evaluation: §7.1 allows it) failed
    u15 and u16 with "rms error inf": the differences, about 1e292, overflowed when
    squared (a QA run of stop 50). The RMS is scaled by the largest difference first."""
    dec = decoder(tmp_path, '''
        if rc == 0:
            x = np.load(OUT); i = tuple(np.argwhere(np.isfinite(x))[0])
            x[i] = np.nextafter(x[i], 0.0); np.save(OUT, x)
        ''')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", name)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    r = doc["results"][0]
    assert r["passed"] and r["rms"] is not None and 1e290 < r["max_abs"] < r["allowed_max_abs"]


def test_an_intlayer_digest_that_is_not_a_file_fails(tmp_path):
    """A folder (or a link to /dev/urandom) named OUT.npy.intlayer passed as "absent"
    (a QA run of stop 50): the README says a digest that exists must match."""
    dec = decoder(tmp_path, '''
        import os
        if rc == 0:
            os.path.exists(OUT + ".intlayer") and os.remove(OUT + ".intlayer")
            os.mkdir(OUT + ".intlayer")
        ''')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    r = doc["results"][0]
    assert r["intlayer"] == "mismatch" and "is not a regular file" in r["message"]


def test_a_command_under_test_cannot_write_past_4_gib_and_array_only_is_for_decoders(
        tmp_path):
    """A runaway decoder could fill the temporary folder's disk within its timeout (no
    RLIMIT_FSIZE); --array-only was taken silently with --encoder (a QA run of stop 50)."""
    seen = tmp_path / "fsize.txt"
    dec = python_script(tmp_path / "lim.py", f'''
import resource
open({str(seen)!r}, "w").write(str(resource.getrlimit(resource.RLIMIT_FSIZE)[0]))
sys.exit(2)
''')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD)
    assert doc["results"][0]["passed"], proc.stdout + proc.stderr      # rejected (exit 2);
    assert proc.returncode == 1 and not doc["probe"]["passed"]       # it decodes nothing
    assert int(seen.read_text()) == 4 << 30
    proc = subprocess.run([PY, "-m", "mpz.conformance.runner", "--encoder", str(dec),
                           "--array-only"], capture_output=True, text=True, timeout=120,
                          cwd=tmp_path)
    assert proc.returncode == 64 and "--array-only is for --decoder" in proc.stderr


def test_a_rate_kept_as_binary32_fails_a_vector(tmp_path):
    """Every decodable vector's rate was exact in binary32 and every encoder input at 120 Hz
    with short ASCII names, so a decoder or encoder that kept the rate as a float32 (or cut
    names) passed the whole suite (a QA run of stop 53): u47 (59.94 Hz) and e03 (59.94 Hz,
    names of up to 64 bytes, a marker that is a gap throughout) catch them."""
    dec = decoder(tmp_path, '''
        if rc == 0:
            import json
            side = json.load(open(OUT + ".json"))
            side["rate"] = float(np.float32(side["rate"]))
            json.dump(side, open(OUT + ".json", "w"))
        ''')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", "u47-rate-59.94", ONE)
    got = {r["name"]: r["passed"] for r in doc["results"]}
    assert got == {"u47-rate-59.94": False, ONE: True}, proc.stdout
    enc = python_script(tmp_path / "enc.py", '''
import json
from pathlib import Path
import numpy as np
import mpz
src, dst, E = sys.argv[1], sys.argv[2], float(sys.argv[-1])
side = json.loads(Path(src).with_suffix(".json").read_text(encoding="utf-8"))
rate = float(np.float32(side["rate"]))
mpz.write_mpz(mpz.Motion(np.load(src), side["names"], rate, side["units"]), dst, max_error=E)
''')
    proc, doc = run(tmp_path, "--encoder", str(enc), "--only", "e03-names-cm-59.94-gap-throughout",
                    "e04-inches-23.976", "e05-no-units")
    got = {r["name"]: r["passed"] for r in doc["results"]}
    assert not got["e03-names-cm-59.94-gap-throughout@0.1"] and not got["e04-inches-23.976@0.05"]
    assert got["e05-no-units@2"], doc["results"]            # 250 Hz is a binary32
    assert any("rate" in r["message"] for r in doc["results"] if not r["passed"])


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full here")
def test_results_on_a_device_that_fails_the_write_keep_the_report(tmp_path):
    """``--results /dev/full``: the runner exited 2 with "cannot write" alone, the report of
    every vector lost (a QA run of stop 53); now the report, then the error, exit 64."""
    proc = subprocess.run([PY, "-m", "mpz.conformance.runner", "--decoder",
                           f"{PY} -m mpz.conformance.refdecoder", "--only", ONE,
                           "--results", "/dev/full"], capture_output=True, text=True,
                          timeout=300, cwd=tmp_path)
    assert proc.returncode == 64, proc.stderr
    assert re.search(rf"^PASS \S*{ONE}: ", proc.stdout, re.M), proc.stdout
    assert "1/1 passed" in proc.stdout
    assert "--results: /dev/full: cannot write: No space left on device" in proc.stderr


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full here")
def test_a_report_that_cannot_be_written_exits_with_a_code_the_help_names(tmp_path):
    """A CLI audit: standard output on a full disk ended the run with exit 2, a code the
    help did not list."""
    with open("/dev/full", "w") as full:
        proc = subprocess.run([PY, "-m", "mpz.conformance.runner", "--decoder",
                               f"{PY} -m mpz.conformance.refdecoder", "--only", ONE],
                              stdout=full, stderr=subprocess.PIPE, text=True, timeout=300,
                              cwd=tmp_path)
    assert proc.returncode == 2 and "cannot write" in proc.stderr, proc.stderr
    helped = subprocess.run([PY, "-m", "mpz.conformance.runner", "--help"],
                            capture_output=True, text=True, timeout=60).stdout
    assert "2 the report could not be written to standard output" in " ".join(helped.split())


def test_a_1_1_decoder_run_as_1_0_is_told_so_not_sent_after_a_start_up_problem(tmp_path):
    """``--implements 1.0`` with vectors that break only 1.1 rules, run with a 1.1 decoder
    (which rejects them): the runner said "decoded none of the 2 valid vector(s)" of the
    invalid group and to check that the command runs at all (a QA run of stop 53)."""
    from mpz.conformance import manifest as mf
    man = {v["name"]: v for v in mf.load()["vectors"]}
    only = ["x171-c3d-two-chdr", "x172-c3d-no-cprm"]
    proc, doc = run(tmp_path, "--decoder", f"{PY} -m mpz.conformance.refdecoder",
                    "--implements", "1.0", "--only", *only)
    assert proc.returncode == 1 and doc is not None
    assert "check that it runs at all" not in proc.stderr
    assert "rejected each of the 2 invalid vector(s) that break only rules of a later" in \
        proc.stderr and "leave out --implements" in proc.stderr, proc.stderr
    for r in doc["results"]:
        rules = ", ".join(man[r["name"]]["rules"])
        assert f"rules {rules} (spec §7.4), rules of a later minor version" in r["message"]
    assert doc["probe"]["passed"]             # it decodes: the hint is about --implements
    # a command that never starts rejects them too: it was told to leave out --implements
    # (a review of stop 53); the probe tells the two apart
    proc, doc = run(tmp_path, "--decoder", f"{PY} -m no_such_decoder_module",
                    "--implements", "1.0", "--only", *only)
    assert proc.returncode == 1 and not doc["probe"]["passed"]
    assert "leave out --implements" not in proc.stderr
    assert "check that it runs at all" in proc.stderr, proc.stderr


def test_a_decoder_whose_write_the_file_limit_cuts_off_did_not_reject(tmp_path):
    """Python ignores SIGXFSZ: a decoder writing past the 4 GiB limit gets EFBIG, and its
    clean exit 1 passed an invalid vector as rejected though it had decoded it (a QA run of
    stop 53). The file is sparse: no disk is used."""
    def past_the_limit(name: str, cleanup: str) -> Path:
        """A decoder that writes one byte past 4 GiB (sparse), then ``cleanup``s."""
        return python_script(tmp_path / name, f'''
import os
try:
    with open(sys.argv[2], "wb") as f:
        f.seek((4 << 30) - 1)
        f.write(b"x")
        f.flush()
        f.write(b"y")
        f.flush()
except OSError as exc:
    {cleanup}
    print(f"cannot write: {{exc}}", file=sys.stderr)
    sys.exit(1)
''')
    proc, doc = run(tmp_path, "--decoder", str(past_the_limit("big.py", "pass")), "--only", BAD)
    r = doc["results"][0]
    assert not r["passed"] and r["actual"] == "error", r
    assert "the runner's file size limit (4 GiB, RLIMIT_FSIZE)" in r["message"]
    assert proc.returncode == 1
    # one that removes its partial output (mpz decode does) says EFBIG: it passed (review)
    tidy = past_the_limit("tidy.py", "os.remove(sys.argv[2])")
    proc, doc = run(tmp_path, "--decoder", str(tidy), "--only", BAD)
    r = doc["results"][0]
    assert not r["passed"] and r["actual"] == "error", r
    assert "File too large" in r["message"] and "not a rejection" in r["message"]


def test_vectors_removed_during_a_run_are_a_clean_error(tmp_path):
    """Vectors regenerated or removed while the runner went on ended it with a traceback,
    exit 70 (a QA run of stop 53): the suite's own files, not the command, are at fault."""
    vdir = _copy_vectors(tmp_path)
    dec = python_script(tmp_path / "rm.py", f'''
import os, subprocess
os.remove({str(vdir / (ONE + ".npy"))!r})
sys.exit(subprocess.call([{PY!r}, "-m", "mpz.conformance.refdecoder", *sys.argv[1:]]))
''')
    proc, _ = run(tmp_path, "--decoder", str(dec), "--vectors", str(vdir), "--only", ONE)
    assert proc.returncode == 64, proc.stderr
    assert "were the vectors regenerated or removed while the run went on?" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("output, noted", [
    ("Traceback (most recent call last):\\n  File dec.py, line 3\\nIndexError: "
     "index 9 is out of bounds", True),
    ("thread 'main' panicked at src/main.rs:9:5:\\nindex out of bounds\\nnote: run with "
     "`RUST_BACKTRACE=1`", True),
    ("error: bad signature (spec §3.1)", False),
])
def test_a_rejection_by_an_uncaught_exception_or_a_panic_is_noted(tmp_path, output, noted):
    """Spec §7.3 counts exit 1 or 101 as a rejection, but a traceback or a panic is no check
    of the spec: such rejections passed with no word (a QA run of stop 55). They still
    pass, with a note that says what the output shows."""
    dec = python_script(tmp_path / "exc.py", f'sys.stderr.write("{output}\\n")\nsys.exit(1)\n')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD)
    r = doc["results"][0]
    assert r["passed"] and r["actual"] == "reject", r
    assert ("uncaught exception or a panic" in r["message"]) == noted, r


def test_nothing_decoded_under_a_memory_limit_names_the_limit(tmp_path):
    """A command that could not start under --memory (numba's library fails to load under
    256 MiB, and the reference decoder exits 1) was sent after a path problem; the
    warning now names the limit too, and only when one is set."""
    dec = python_script(tmp_path / "noload.py", 'sys.stderr.write("OSError: Could not find/load '
                        'shared object file\\n")\nsys.exit(1)\n')
    for memory, hinted in (("256", True), ("0", False)):
        proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE, "--memory", memory)
        assert "decoded none" in proc.stderr, proc.stderr
        assert ("--memory 256 MiB is too little for it to start" in proc.stderr) == hinted
    # a module not found says nothing of memory: no hint (a review of stop 55)
    dec = python_script(tmp_path / "nomod.py", 'sys.stderr.write("ModuleNotFoundError: No '
                        'module named mydec\\n")\nsys.exit(1)\n')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE, "--memory", "256")
    assert "decoded none" in proc.stderr and "too little" not in proc.stderr, proc.stderr


@pytest.mark.parametrize("text, said", [
    ("import sys\nsys.exit(1)\n", "a text file without a #! line"),
    ("#!/bin/sh\r\nexit 1\r\n", "carriage return (CRLF line ends)"),
    ("#!/nonexistent/python4\nexit 1\n", "names /nonexistent/python4, which does not exist"),
    ("#!\nexit 1\n", "its #! line names no program"),
])
def test_a_script_the_system_cannot_start_is_a_usage_error(tmp_path, text, said):
    """A script without a #! line, or whose #! line has a CRLF end or names no program, ran
    every vector as "cannot start" (naming the script as missing) and exited 1 (a QA run
    of stop 55): it is now refused before any vector runs, saying why (exit 64)."""
    dec = tmp_path / "dec.py"
    dec.write_bytes(text.encode())
    dec.chmod(0o755)
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD)
    assert proc.returncode == 64 and doc is None, proc.stdout + proc.stderr
    assert said in proc.stderr


def test_values_in_the_other_byte_order_are_said_so(tmp_path):
    """A decoder that wrote big-endian float64 under a little-endian header was told "NaN
    pattern differs" or values off by 1e300 (a QA run of stop 55); the failure now says
    what happened. A value off by one step in that order is not taken for it."""
    dec = decoder(tmp_path, '''
        if rc == 0:
            x = np.load(OUT); np.save(OUT, x.byteswap().view("<f8"))
        ''')
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    r = doc["results"][0]
    assert not r["passed"] and "in the other byte order" in r["message"], r
    dec = decoder(tmp_path, '''
        if rc == 0:
            x = np.load(OUT); i = tuple(np.argwhere(np.isfinite(x))[0]); x[i] += 1.0
            np.save(OUT, x)
        ''', name="off.py")
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    r = doc["results"][0]
    assert not r["passed"] and "byte order" not in r["message"], r


def test_small_usage_points_of_an_implementers_run(tmp_path):
    """From a QA run of stop 55: `--results -` wrote a file named "-"; `--only uncommon/`
    (a shell's completion of the folder) named nothing; a sidecar unit given by name
    ("mm") was refused without the code it must be."""
    dec = decoder(tmp_path, "")
    proc = subprocess.run([PY, "-m", "mpz.conformance.runner", "--decoder", str(dec),
                           "--only", "u01-one-frame", "--results", "-"],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert proc.returncode == 64 and "--results -" in proc.stderr
    assert not (tmp_path / "-").exists()
    quick = script(tmp_path / "quick.sh", "#!/bin/sh\nexit 3\n")   # the selection, quickly
    proc, doc = run(tmp_path, "--decoder", str(quick), "--only", "uncommon/")
    assert proc.returncode == 1 and doc is not None and len(doc["results"]) > 10, proc.stderr
    assert {r["group"] for r in doc["results"]} == {"uncommon"}
    dec = decoder(tmp_path, '''
        import json
        if rc == 0:
            s = json.load(open(OUT + ".json")); s["units"] = "mm"
            json.dump(s, open(OUT + ".json", "w"))
        ''', name="units.py")
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", ONE)
    r = doc["results"][0]
    assert not r["passed"] and 'not an integer code: "mm" (MHDR\'s code, ' in r["message"], r


def _held_open(tmp_path: Path, name: str, last: str, code: int) -> dict:
    """The result of a decoder that prints ``last`` after (or before) starting a child in a
    session of its own, which holds the output 8 s, and exits ``code``; the child is
    killed here."""
    mark = tmp_path / f"{name}.pid"
    dec = python_script(tmp_path / f"{name}.py", f"""
import subprocess
print({last!r}, flush=True)
p = subprocess.Popen(["sleep", "8"], start_new_session=True)
open({str(mark)!r}, "w").write(str(p.pid))
sys.exit({code})
""")
    try:
        proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD)
    finally:
        if mark.exists():
            with contextlib.suppress(ProcessLookupError):
                os.kill(int(mark.read_text()), signal.SIGKILL)
    return doc["results"][0]


def test_output_held_open_by_a_child_of_another_session_is_said(tmp_path):
    """A decoder whose child starts a session of its own (a build tool's daemon) holds the
    output open past its exit: the runner waited 5 s and kept nothing of what the decoder
    had printed, with no word (a QA run of stop 55). What it printed is kept, and a line
    says why the output stopped."""
    r = _held_open(tmp_path, "dec", "error: not an MPZ file (spec §3.1)", 2)
    assert r["passed"] and "not an MPZ file" in r["stderr_tail"], r
    assert "a process it started in a session of its own holds it" in r["stderr_tail"], r
    # the note is the runner's, not the decoder's last line: a MemoryError before it is
    # still out of memory, not a rejection (a review of stop 55)
    r = _held_open(tmp_path, "oom", "MemoryError", 1)
    assert not r["passed"] and r["actual"] == "memory", r
    assert "a session of its own" in r["stderr_tail"], r


def test_the_float_slack_is_taken_over_the_valid_samples_only():
    """§7.2: "max|x| is the largest magnitude of any valid input coordinate". The runner
    took it over every finite input coordinate, so one gap sample (NaN, 1e30, 0) made the
    slack 8.9e14 and a file 3 units off every sample of a 1-unit bound passed (a
    clean-room encoder written from the spec, stop 64)."""
    import mpz
    from mpz.conformance.runner import check_encoded
    from mpz.motion import Motion
    rng = np.random.default_rng(7)
    x = 1000.0 + np.cumsum(rng.normal(0.0, 5.0, (20, 3, 3)), axis=0)
    x[4, 1] = [np.nan, 1e30, 0.0]                     # a gap: one coordinate is NaN
    side = {"names": ["a", "b", "c"], "rate": 100.0, "units": "mm"}
    valid = ~np.isnan(x).any(axis=2)
    shifted = np.where(valid[..., None], x + 3.0, np.nan)
    got, facts = check_encoded(mpz.encode(Motion(shifted, side["names"], side["rate"],
                                                 side["units"]), max_error=1.0), x, side, 1.0)
    assert facts["measured_max_error"] > 5.0
    assert len(got) == 1 and "declared bound" in got[0] and got[0].endswith("(R-7.2-1)"), got


def test_an_input_with_an_infinity_in_a_valid_sample_is_not_run(tmp_path):
    """§7.3's inputs are finite or NaN: an infinity in a sample without a NaN is valid
    there, and no bound can hold (the reference encoder writes it as a gap, which R-7.2-2
    then failed, blaming the encoder). Such an input of one's own manifest is said to be
    the fault, and the encoder is not run."""
    from mpz.conformance.runner import run_encoder_item
    x = np.zeros((4, 2, 3))
    x[2, 1, 0] = np.inf
    x[1, 0] = [np.nan, np.inf, 0.0]                   # a gap: its infinity is no matter
    np.save(tmp_path / "in.npy", x)
    (tmp_path / "in.json").write_text(json.dumps({"names": ["a", "b"], "rate": 10.0,
                                                  "units": "mm"}))
    marker = tmp_path / "ran"
    entry = run_encoder_item(["touch", str(marker)], tmp_path,
                             {"name": "inf", "input": "in.npy", "sidecar": "in.json"},
                             1.0, 60, 0)
    assert not entry["passed"] and entry["actual"] == "input" and not marker.exists()
    assert "infinite coordinate in a valid sample (frame 2, marker 1)" in entry["message"]


def test_a_manifest_of_encoder_inputs_alone_runs_an_encoder(tmp_path):
    """A clean-room encoder's author had to copy a decoder vector into a manifest of their
    own inputs ("manifest lists no vectors", exit 64, stop 64); a decoder run of such a
    manifest is a usage error, never a pass of nothing."""
    vdir = _copy_vectors(tmp_path)
    man = json.loads((vdir / "manifest.json").read_text())
    man["vectors"] = []
    (vdir / "manifest.json").write_text(json.dumps(man))
    item = man["encoder_inputs"][0]["name"]
    proc, doc = run(tmp_path, "--encoder", f"{PY} -m mpz.conformance.refencoder",
                    "--vectors", str(vdir), "--only", item)
    assert proc.returncode == 0 and doc["results"] and all(
        r["passed"] for r in doc["results"]), proc.stdout[-400:] + proc.stderr
    proc, _ = run(tmp_path, "--decoder", f"{PY} -m mpz.conformance.refdecoder",
                  "--vectors", str(vdir))
    assert proc.returncode == 64 and "run it with --encoder" in proc.stderr, proc.stderr
    man["encoder_inputs"] = []
    (vdir / "manifest.json").write_text(json.dumps(man))
    proc, _ = run(tmp_path, "--encoder", f"{PY} -m mpz.conformance.refencoder",
                  "--vectors", str(vdir))
    assert proc.returncode == 64 and "no vectors and no encoder inputs" in proc.stderr


def test_a_tiny_or_huge_value_is_printed_so_that_it_shows():
    """A coordinate of 5.55e-307 was printed "got 0.000000" (a maintainer's QA run of stop
    75, a bit flip in an exponent): six significant digits where six decimals show none,
    six decimals elsewhere, as before."""
    from mpz.conformance.runner import _fmt
    assert [_fmt(v) for v in (5.551115123125783e-307, -0.000123456, 0.0, 1673.0, 0.001,
                              2.5e7, float("nan"))] == \
        ["5.55112e-307", "-0.000123456", "0.000000", "1673.000000", "0.001000", "2.5e+07",
         "NaN"]
