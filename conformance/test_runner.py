"""The runner passes the reference decoder and catches deliberately broken ones.

Each test runs ``python -m mpz.conformance.runner`` as a subprocess, exactly
as a decoder author would, and reads its JSON results. Every broken decoder of
``mpz.conformance.broken_decoders`` must fail on the vectors where its bug shows,
for the right reason, and pass where it does not.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import shutil
import subprocess
import sys

import pytest

from mpz.conformance import manifest as mf

PY = sys.executable
REF = f"{PY} -m mpz.conformance.refdecoder"
BROKEN_CMD = f"{PY} -m mpz.conformance.broken_decoders"
JOBS = str(max(2, min(8, os.cpu_count() or 1)))
MAN = mf.load()
NAMES = {v["name"] for v in MAN["vectors"]}


def run(tmp_path, *args, name="results.json"):
    out = tmp_path / name
    proc = subprocess.run([PY, "-m", "mpz.conformance.runner", *args, "--results", str(out),
                           "--jobs", JOBS, "--quiet"],
                          capture_output=True, text=True, timeout=900)
    doc = json.loads(out.read_text()) if out.exists() else None
    return proc, doc


def by_name(doc):
    return {r["name"]: r for r in doc["results"]}


def _match(name):
    """Vectors are numbered by make_vectors; match them on their slug."""
    if name in NAMES:
        return name
    slug = name.split("-", 1)[1]
    hits = [n for n in NAMES if n.split("-", 1)[1] == slug]
    assert len(hits) == 1, (name, hits)
    return hits[0]


#: the vectors the reference decoder runs through the runner in CI: every valid one, every
#: third uncommon one and every sixteenth invalid one, so every group and both outcomes
#: (each run starts a Python process, 1.2-1.8 s here; 126 runs took 99 s of CI's 15
#: minutes, and the 71 of stop 30 still 94 s on a busy machine).
#: Every vector is also decoded in process, against the same expected output, integer-layer
#: digest and header, by conformance/test_manifest.py. MPZ_CONFORMANCE_FULL=1 runs all of
#: them through the runner, as a decoder author does.
FULL = os.environ.get("MPZ_CONFORMANCE_FULL") == "1"
_EVERY = {"valid": 1, "uncommon": 3, "invalid": 16}
THROUGH_RUNNER = [v["name"] for g in _EVERY
                  for i, v in enumerate(x for x in MAN["vectors"] if x["group"] == g)
                  if FULL or i % _EVERY[g] == 0]


def test_reference_decoder_passes_the_vectors(tmp_path):
    proc, doc = run(tmp_path, "--decoder", REF, *([] if FULL else ["--only", *THROUGH_RUNNER]))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert doc["schema_version"] == 5 and doc["mode"] == "decoder"
    assert doc["contract"] == "full" and doc["implements"] == "1.1"
    assert doc["totals"]["failed"] == 0
    assert doc["totals"]["total"] == len(THROUGH_RUNNER)
    assert {r["group"] for r in doc["results"]} == set(mf.GROUPS)
    for r in doc["results"]:
        assert r["passed"] and r["actual"] == r["expected"]
        if r["expected"] == "decode":
            assert r["intlayer"] == "match" and r["max_abs"] == 0.0
            assert r["sidecar"] == "match"
            assert r["allowed_rms"] <= r["allowed_max_abs"]
        else:
            assert r["exit_code"] == 2 and r["signal"] is None


#: mode, vectors, the ones that must fail (None: every invalid one), the phrase each
#: failure message holds, the ``actual`` of each failure, extra runner options
BROKEN = [
    ("offbyone", ["v04-orders-residual-only", "u08-values-at-bits-limit", "x01-bad-signature"],
     {"v04-orders-residual-only", "u08-values-at-bits-limit"}, "1.000 grid steps", "decode", ()),
    ("overtol", ["v04-orders-residual-only", "u08-values-at-bits-limit", "x01-bad-signature"],
     {"v04-orders-residual-only", "u08-values-at-bits-limit"}, "beyond max_abs", "decode", ()),
    ("fill-gaps", ["v02-jump-lossy-gaps", "u03-marker-gap-throughout", "v04-orders-residual-only"],
     {"v02-jump-lossy-gaps", "u03-marker-gap-throughout"},
     "0.000000 where a gap (NaN) was expected", "decode", ()),
    ("extra-gap", ["v04-orders-residual-only", "x01-bad-signature"],
     {"v04-orders-residual-only"}, "NaN (gap) where a value was expected", "decode", ()),
    ("noresidual", ["v04-orders-residual-only", "v06-patterns-residual-g2-smooth4-m",
                    "v05-patterns-scale3-lossy-cm"],
     {"v04-orders-residual-only", "v06-patterns-residual-g2-smooth4-m"},
     "integer-layer digest", "decode", ()),
    ("accept-all", ["x01-bad-signature", "x03-bad-crc-mhdr", "x05-segs-index-out-of-range",
                    "u01-one-frame"], None, "but decoder exited 0", "decode", ()),
    ("no-sidecar", ["u01-one-frame", "x01-bad-signature"], {"u01-one-frame"},
     "no out.npy.json", "decode", ()),
    ("nfc-names", ["u19-names-compared-as-bytes", "v04-orders-residual-only"],
     {"u19-names-compared-as-bytes"}, "sidecar names[4] = 'é' (U+00E9) != expected 'e\u0301' "
     "(U+0065 U+0301)", "decode",
     ()),
    ("rate-15-digits", ["u04-rate-65.0364227294921875", "v04-orders-residual-only"],
     {"u04-rate-65.0364227294921875"}, "sidecar rate 65.0364227294922 != expected "
     "65.03642272949219", "decode", ()),
    ("first-meta-value", ["u24-meta-repeated-key", "u18-meta-nul", "v09-all-chunk-types"],
     {"u24-meta-repeated-key"}, "sidecar meta['take'] = 'first', expected 'last' (for a "
     "repeated key, the last value", "decode", ()),
    ("crash", ["u01-one-frame", "x01-bad-signature"], {"u01-one-frame"},
     "expected a decode, but decoder exited 1", "reject", ()),
    ("segv-on-invalid", ["u01-one-frame", "x01-bad-signature", "x31-frames-x-markers-over-limit"],
     {"x01-bad-signature", "x31-frames-x-markers-over-limit"}, "killed by SIGSEGV", "crash", ()),
    ("abort-on-invalid", ["u01-one-frame", "x01-bad-signature"], {"x01-bad-signature"},
     "killed by SIGABRT", "crash", ()),
    ("exit139-on-invalid", ["u01-one-frame", "x01-bad-signature"], {"x01-bad-signature"},
     "exit 139 = 128 + SIGSEGV", "crash", ()),
    ("oom-on-invalid", ["u01-one-frame", "x31-frames-x-markers-over-limit"],
     {"x31-frames-x-markers-over-limit"}, "ran out of memory", "memory", ()),
    ("hang-on-invalid", ["x01-bad-signature"], {"x01-bad-signature"},
     "did not finish within the time limit", "timeout", ("--timeout", "2")),
]

_RUNS: dict = {}


def broken_run(tmp_path_factory, mode, only, extra=()):
    """Run the runner once per broken mode (the detail tests reuse the result)."""
    key = (mode, tuple(extra))
    if key not in _RUNS:
        _RUNS[key] = run(tmp_path_factory.mktemp(mode), "--decoder", f"{BROKEN_CMD} {mode}",
                         "--only", *only, *extra)
    return _RUNS[key]


@pytest.mark.parametrize("mode,only,failing,phrase,actual,extra", BROKEN,
                         ids=[b[0] for b in BROKEN])
def test_broken_decoder_is_caught(tmp_path_factory, mode, only, failing, phrase, actual, extra):
    only = [_match(n) for n in only]
    if failing is None:                      # accept-all: every invalid one fails
        failing = {n for n in only if n.startswith("x")}
    else:
        failing = {_match(n) for n in failing}
    proc, doc = broken_run(tmp_path_factory, mode, only, extra)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert set(doc["failed"]) == failing
    res = by_name(doc)
    assert all(phrase in res[n]["message"] for n in failing), [res[n]["message"] for n in failing]
    assert {res[n]["actual"] for n in failing} == {actual}
    man = {v["name"]: v for v in MAN["vectors"]}
    for n in failing:
        assert n in proc.stdout                          # named in the printed summary too
        # every failure names the §7.4 rules of its vector, not a wrong acceptance alone
        # (a QA run of stop 53: a wrong output or rejection sent them to the manifest)
        rules = man[n]["rules"]
        # ... after the rule of the check that failed, for an output judged wrong (a QA run
        # of stop 71: a wrong name cited the range coder's rules alone)
        said = ("vector probes:" if res[n]["actual"] == "decode" == man[n]["expected"]
                else "rules")
        assert rules and f"{said} {', '.join(rules)} (spec §7.4)" in res[n]["message"], n


def test_offbyone_report_names_frame_marker_axis(tmp_path_factory):
    proc, doc = broken_run(tmp_path_factory, "offbyone", [_match(n) for n in BROKEN[0][1]])
    r = by_name(doc)["v04-orders-residual-only"]
    ff = r["first_failure"]
    assert ff["frame"] == 24 and ff["axis"] == "y" and ff["marker"] == 11
    assert ff["marker_name"] == "LELB" and abs(ff["grid_steps"] - 1.0) < 1e-9
    assert "frame 24, marker 'LELB' (index 11), axis y: got" in r["message"]
    assert r["max_abs"] > r["allowed_max_abs"]


def test_overtol_is_just_over_the_tolerance(tmp_path_factory):
    """1.5 x max_abs: a runner with any slack factor of 1.5 or more would pass it."""
    proc, doc = broken_run(tmp_path_factory, "overtol", [_match(n) for n in BROKEN[1][1]])
    r = by_name(doc)["v04-orders-residual-only"]
    assert r["allowed_max_abs"] < r["max_abs"] <= 1.5 * r["allowed_max_abs"] * (1 + 1e-6)


def test_rms_is_checked_on_its_own(tmp_path):
    """A decoder off by max_abs / 2 everywhere passes the shipped manifest (rms = max_abs)
    but fails a third-party manifest whose rms tolerance is max_abs / 4."""
    name = "v04-orders-residual-only"
    proc, doc = run(tmp_path, "--decoder", f"{BROKEN_CMD} half-tol", "--only", name)
    assert proc.returncode == 0, proc.stdout
    vdir = tmp_path / "vectors"
    vec = dict(next(v for v in MAN["vectors"] if v["name"] == name))
    for rel in (vec["file"], vec["expected_output"]["file"]):
        (vdir / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(mf.DEFAULT_DIR / rel, vdir / rel)
    vec["tolerances"] = {"max_abs": vec["tolerances"]["max_abs"],
                         "rms": vec["tolerances"]["max_abs"] / 4}
    man = dict(MAN, vectors=[vec])
    (vdir / mf.MANIFEST_NAME).write_text(json.dumps(man))
    proc, doc = run(tmp_path, "--decoder", f"{BROKEN_CMD} half-tol", "--vectors", str(vdir),
                    name="rms.json")
    assert proc.returncode == 1
    r = doc["results"][0]
    assert r["max_abs"] <= r["allowed_max_abs"]
    assert "rms error" in r["message"] and "beyond max_abs" not in r["message"]


def test_array_only_keeps_the_1_0_contract(tmp_path):
    proc, doc = run(tmp_path, "--decoder", f"{BROKEN_CMD} no-sidecar", "--array-only",
                    "--only", "u01-one-frame", _match("x01-bad-signature"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert doc["contract"] == "array-only"
    r = by_name(doc)["u01-one-frame"]
    assert r["sidecar"] == "not checked" and "not checked (--array-only)" in r["message"]
    assert "names, rate, units and meta were not checked" in proc.stdout


def _rules_of_1_1() -> set[str]:
    """The rules spec §7.4 marks (1.1): those of the chunk types MPZ 1.1 added."""
    text = (Path(__file__).parents[1] / "spec" / "mpz-1.md").read_text(encoding="utf-8")
    return {rid for rid, _, _, what in mf.spec_rules(text) if what.startswith("(1.1)")}


def test_a_1_0_decoder_must_decode_the_files_that_break_only_1_1_rules():
    """Spec §2.1: a 1.0 decoder skips the 1.1 chunk types as unknown, so what it must do
    with each vector differs from the manifest exactly where a vector breaks only (1.1)
    rules (the spec's rule index, not the code, says which). Every such vector becomes one
    to decode, unless it is also broken for 1.0 (and then outside the 1.1 chunks)."""
    from mpz.chunks import CHUNKS
    from mpz.conformance.runner import as_read_by
    from mpz.decoder import decode_layers
    from mpz.errors import MPZError
    later = {t for t, c in CHUNKS.items() if c.MINOR > 0}
    r11 = _rules_of_1_1()
    assert len(r11) >= 30
    vdir = mf.DEFAULT_DIR
    changed = []
    still = []
    for v in MAN["vectors"]:
        w, x = as_read_by(v, vdir, 0)
        only_1_1 = v["expected"] == "reject" and set(v["rules"]) <= r11
        if w["expected"] == v["expected"]:
            assert x is None
            if only_1_1:             # still invalid for 1.0: for a reason outside 1.1 chunks
                with pytest.raises(MPZError) as err:
                    decode_layers((vdir / v["file"]).read_bytes(), minor=0)
                assert err.value.chunk not in later, (v["name"], str(err.value))
                assert (err.value.chunk, err.value.section) == ("ROOT", "§5.3"), str(err.value)
                still.append(v["name"].split("-")[0])
            continue
        changed.append(v["name"])
        assert only_1_1, (v["name"], v["rules"])
        assert w["expected"] == "decode" and x is not None and x.ndim == 3
        assert w["header"]["names"] and w["tolerances"]["max_abs"] > 0
        assert "unknown" in w["note"] and set(later) & set(w["note"].replace(",", " ").split())
    assert len(changed) >= 100
    # the count the documents state is this one (conformance/README.md said 106 in one
    # place and 105 in two after a vector was added, a QA run of stop 47)
    invalid = sum(v["group"] == "invalid" for v in MAN["vectors"])
    spec = " ".join((vdir.parents[1] / "spec" / "mpz-1.md").read_text().split())
    assert f"{len(changed)} invalid vectors must then decode" in spec
    # and it names the others whose rules are all (1.1), and the rule that rejects them
    # (an implementer counting them from `rules` found 149, not 147: a clean-room review of
    # stop 54)
    assert len(still) == 2
    assert (f"Two more whose `rules` are all marked (1.1), {' and '.join(sorted(still))}, "
            "stay invalid for a 1.0 decoder: it rejects them by R-5.3-1") in spec
    guide = " ".join((vdir.parent / "README.md").read_text().split())
    assert f"{len(changed)} of the {invalid} invalid vectors must then decode" in guide
    assert f"those {len(changed)};" in guide and f"decode the {len(changed)} whose" in guide


#: the vectors whose expectation a 1.0 decoder changes, one in sixteen (each run of each is a
#: process: 3 runs of 9 vectors take about 20 s)
_AS_1_0 = sorted(v["name"] for v in MAN["vectors"]
                 if v["expected"] == "reject" and set(v["rules"]) <= _rules_of_1_1())[::16]


def test_implements_1_0_passes_a_1_0_decoder_and_fails_a_1_1_one(tmp_path):
    """The reference reading as 1.0 passes; the reference reading as 1.1 rejects, as a 1.1
    decoder must, the files a 1.0 decoder must decode, and fails exactly those."""
    only = ["--only", *_AS_1_0, "v10-c3d-archive-float32", _match("x01-bad-signature")]
    proc, doc = run(tmp_path, "--decoder", f"{REF} --implements 1.0", "--implements", "1.0",
                    *only)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert doc["implements"] == "1.0" and doc["totals"]["failed"] == 0
    assert "judged as a 1.0 decoder must read them" in proc.stdout
    got = by_name(doc)
    # a re-judged vector says so when it passes too (only its failure said it: stop 50)
    for n in _AS_1_0:
        assert got[n]["judged_as"].startswith("as a 1.0 decoder reads it, with "), got[n]
        assert got[n]["message"].endswith(f"[judged {got[n]['judged_as']}]")
    assert [got[n]["judged_as"] for n in only[-2:]] == [None, None]     # as written
    assert all(got[n]["actual"] == "decode" for n in _AS_1_0 if n not in
               ("x206-cana-samples-over-limit", "x236-skeleton-channel-samples-over-limit"))
    proc, doc = run(tmp_path, "--decoder", REF, "--implements", "1.0", *only, name="r2.json")
    assert proc.returncode == 1
    failed = set(doc["failed"])
    assert failed and failed <= set(_AS_1_0)
    assert all("expected a decode, but decoder exited 2" in by_name(doc)[n]["message"]
               for n in failed)
    proc, doc = run(tmp_path, "--decoder", f"{REF} --implements 1.0", *only, name="r3.json")
    assert proc.returncode == 1 and set(doc["failed"]) == failed


def test_sidecar_comparison_unit(tmp_path):
    """compare_sidecar on hand-written files: every member, exact, JSON escapes allowed."""
    from mpz.conformance.runner import compare_sidecar
    vec = next(v for v in MAN["vectors"] if v["name"] == _match("u18-meta-nul"))
    h = vec["header"]
    good = {"names": h["names"], "rate": h["rate"], "units": h["units_code"], "meta": h["meta"]}
    p = tmp_path / "out.npy.json"

    def check(doc, raw=None):
        p.write_bytes(raw if raw is not None else json.dumps(doc).encode())
        return compare_sidecar(p, vec)

    assert check(good) == ("match", [])
    assert check(dict(good, extra=1))[0] == "match"                    # other members ignored
    assert check(dict(good, units=float(h["units_code"])))[0] == "match"   # 1.0 is the integer 1
    for bad in (dict(good, names=h["names"][::-1]), dict(good, rate=h["rate"] * (1 + 2e-16)),
                dict(good, rate=str(h["rate"])), dict(good, units=True),
                dict(good, units=h["units_code"] + 1), dict(good, meta={}),
                {k: v for k, v in good.items() if k != "meta"}):
        assert check(bad)[0] == "mismatch", bad
    assert check(None, b"\xff")[0] == "unreadable"
    assert check(None, b'{"rate": NaN}')[0] == "unreadable"
    assert check(None, b"[]")[0] == "unreadable"
    p.unlink()
    assert compare_sidecar(p, vec)[0] == "missing"


def test_failure_kind_unit():
    """What counts as a clean exit, and what does not (spec §8: a crash is not a rejection)."""
    from mpz.conformance.runner import failure_kind

    def kind(code, stderr="", timed_out=False, sig=None):
        got = failure_kind({"exit_code": code, "stderr": stderr, "timed_out": timed_out,
                            "signal": sig})
        return got and got[0]

    assert kind(0) is None and kind(2, "FormatError: bad") is None and kind(1) is None
    assert kind(-11, sig="SIGSEGV") == "crash" and kind(139) == "crash" and kind(134) == "crash"
    # spec §7.3: a rejection is 1 to 125; 128 + SIGINT is a child killed from outside, and
    # 200 a status no rejection has
    assert kind(125) is None and kind(130) == "crash" and kind(200) == "error"
    assert kind(1, "Traceback ...\nMemoryError") == "memory"
    assert kind(1, "terminate called after throwing an instance of 'std::bad_alloc'") == "memory"
    assert kind(2, "error: out of memory") == "memory"
    assert kind(2, "MemoryError mentioned, then\nLimitExceededError: too big") is None
    assert kind(9, timed_out=True) == "timeout" and kind(None, "cannot start") == "error"


def test_encoder_mode(tmp_path):
    proc, doc = run(tmp_path, "--encoder", f"{PY} -m mpz.conformance.refencoder", "--only",
                    "e02-mixed-10-metres")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    r = doc["results"][0]
    assert r["passed"] and r["declared_bound"] <= r["max_error"]
    assert r["measured_max_error"] <= r["declared_bound"]
    # the output's digest (stop 75): the reference encoder's bytes for that input and E
    import hashlib

    import numpy as np

    import mpz
    npy = Path(mf.DEFAULT_DIR) / "inputs" / "e02-mixed-10-metres.npy"
    side = json.loads(npy.with_suffix(".json").read_text(encoding="utf-8"))
    data = mpz.encode(mpz.Motion(np.load(npy), side["names"], side["rate"],
                                 side.get("units", "")), max_error=r["max_error"])
    assert r["sha256"] == hashlib.sha256(data).hexdigest() and r["bytes"] == len(data)
    proc, doc = run(tmp_path, "--encoder", f"{BROKEN_CMD} loose-encoder", "--only",
                    "e02-mixed-10-metres", name="loose.json")
    assert proc.returncode == 1
    msg = doc["results"][0]["message"]
    assert "declared error_bound 0.001 > requested --max-error 0.0005" in msg


@pytest.mark.parametrize("args", [
    [],                                                        # neither --decoder nor --encoder
    ["--decoder", "/nonexistent/decoder"],
    ["--decoder", REF, "--only", "no-such-vector"],
    ["--decoder", REF, "--vectors", "/nonexistent"],
    ["--decoder", REF, "--timeout", "0"],
    ["--decoder", REF, "--implements", "1.2"],
    ["--decoder", REF, "--implements", "2.0"],
    ["--decoder", REF, "--implements", "1"],
    ["--encoder", REF, "--implements", "1.0"],
])
def test_usage_errors_exit_64(args, capsys):
    from mpz.conformance.runner import main  # in-process: no decoder is ever started
    assert main(args) == 64                  # the usage-error code of every MPZ tool
    assert capsys.readouterr().err


def test_a_mistyped_required_option_is_named(capsys):
    """``mpz-conformance --decodr x`` said only that one of --decoder and --encoder is
    required (a newcomer's QA run, stop 73); mpz and mpzinfo named the typo."""
    from mpz.conformance.runner import main
    assert main(["--decodr", "x"]) == 64
    err = capsys.readouterr().err
    assert "unrecognized arguments: --decodr; did you mean --decoder?" in err, err


def test_timeout_is_enforced(tmp_path):
    proc, doc = run(tmp_path, "--decoder", f"{PY} -c 'import time; time.sleep(30)'",
                    "--only", "u01-one-frame", "--timeout", "1")
    assert proc.returncode == 1
    r = doc["results"][0]
    assert r["timed_out"] and r["actual"] == "timeout" and r["seconds"] < 10


def test_manifest_schema_rejects_a_manifest_without_sidecar_facts():
    import copy
    bad = copy.deepcopy(MAN)
    dec = next(v for v in bad["vectors"] if v["expected"] == "decode")
    del dec["header"]["meta"]
    with pytest.raises(mf.ManifestError, match="meta"):
        mf.validate(bad)


def test_readme_documents_every_broken_mode():
    from mpz.conformance.broken_decoders import MODES
    text = (Path(__file__).parent / "README.md").read_text(encoding="utf-8")
    assert not [m for m in MODES if f"`{m}`" not in text]


@pytest.mark.parametrize("minor", [-1, 2, 7])
def test_a_minor_version_the_reference_does_not_implement_is_an_argument_error(minor):
    from mpz.decoder import decode_layers
    data = (mf.DEFAULT_DIR / "spec-example.mpz").read_bytes()
    assert decode_layers(data, minor=0).q.shape == decode_layers(data).q.shape
    with pytest.raises(ValueError, match="minor must be an int 0 .. 1"):
        decode_layers(data, minor=minor)


def test_an_accepted_invalid_vector_names_the_rules_it_breaks(tmp_path_factory):
    """An implementer's QA run (stop 50): "expected rejection (byte 1 XOR 0x20)" sent them to
    the manifest for the rule; the message names its §7.4 IDs, from the manifest."""
    only = [_match(n) for n in BROKEN[next(i for i, b in enumerate(BROKEN)
                                           if b[0] == "accept-all")][1]]
    _, doc = broken_run(tmp_path_factory, "accept-all", only)
    man = {v["name"]: v for v in mf.load()["vectors"]}
    for name in (n for n in only if n.startswith("x")):
        rules = man[name]["rules"]
        assert rules and f"rules {', '.join(rules)} (spec §7.4)" in by_name(doc)[name]["message"]
