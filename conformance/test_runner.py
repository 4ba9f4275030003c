"""The runner passes the reference decoder and catches deliberately broken ones.

Each test runs ``python -m mpz.conformance.runner`` as a subprocess, exactly
as a decoder author would, and reads its JSON results.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from mpz.conformance import manifest as mf

PY = sys.executable
REF = f"{PY} -m mpz.conformance.refdecoder"
JOBS = str(max(2, min(8, os.cpu_count() or 1)))
MAN = mf.load()


def run(tmp_path, *args, name="results.json"):
    out = tmp_path / name
    proc = subprocess.run([PY, "-m", "mpz.conformance.runner", *args, "--results", str(out),
                           "--jobs", JOBS, "--quiet"],
                          capture_output=True, text=True, timeout=600)
    doc = json.loads(out.read_text()) if out.exists() else None
    return proc, doc


def by_name(doc):
    return {r["name"]: r for r in doc["results"]}


def test_reference_decoder_passes_every_vector(tmp_path):
    proc, doc = run(tmp_path, "--decoder", REF)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert doc["schema_version"] == 1 and doc["mode"] == "decoder"
    assert doc["totals"]["failed"] == 0
    assert doc["totals"]["total"] == len(MAN["vectors"])
    for r in doc["results"]:
        assert r["passed"] and r["actual"] == r["expected"]
        if r["expected"] == "decode":
            assert r["intlayer"] == "match" and r["max_abs"] == 0.0
            assert r["allowed_rms"] <= r["allowed_max_abs"]


BROKEN = [
    # mode, vectors, the ones that must fail, a phrase the message must hold
    ("offbyone", ["v04-orders-residual-only", "u08-values-at-bits-limit", "x01-bad-signature"],
     {"v04-orders-residual-only", "u08-values-at-bits-limit"},
     "1.000 grid steps"),
    ("noresidual", ["v04-orders-residual-only", "v06-patterns-residual-g2-smooth4-m",
                    "v05-patterns-scale3-lossy-cm"],
     {"v04-orders-residual-only", "v06-patterns-residual-g2-smooth4-m"},
     "integer-layer digest"),
    ("accept-all", ["x01-bad-signature", "x03-bad-crc-mhdr", "x05-segs-index-out-of-range",
                    "u01-one-frame"], None, "but decoder exited 0"),
    ("crash", ["u01-one-frame", "x01-bad-signature"], {"u01-one-frame"},
     "expected a decode, but decoder exited 1"),
]


_RUNS = {}


def broken_run(tmp_path_factory, mode, only):
    """Run the runner once per broken mode (the detail tests reuse the result)."""
    if mode not in _RUNS:
        _RUNS[mode] = run(tmp_path_factory.mktemp(mode), "--decoder",
                          f"{PY} -m mpz.conformance.broken_decoders {mode}", "--only", *only)
    return _RUNS[mode]


@pytest.mark.parametrize("mode,only,failing,phrase", BROKEN, ids=[b[0] for b in BROKEN])
def test_broken_decoder_is_caught(tmp_path_factory, mode, only, failing, phrase):
    names = {v["name"] for v in MAN["vectors"]}
    only = [_match(n, names) for n in only]
    if failing is None:                      # accept-all: every invalid one fails
        failing = {n for n in only if n.startswith("x")}
    else:
        failing = {_match(n, names) for n in failing}
    proc, doc = broken_run(tmp_path_factory, mode, only)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert set(doc["failed"]) == failing
    res = by_name(doc)
    assert all(phrase in res[n]["message"] for n in failing), [res[n]["message"] for n in failing]
    for n in failing:
        assert n in proc.stdout                          # named in the printed summary too


def _match(name, names):
    """Invalid vectors are numbered by make_vectors; match them on their slug."""
    if name in names:
        return name
    slug = name.split("-", 1)[1]
    hits = [n for n in names if n.split("-", 1)[1] == slug]
    assert len(hits) == 1, (name, hits)
    return hits[0]


def test_offbyone_report_names_frame_marker_axis(tmp_path_factory):
    names = {v["name"] for v in MAN["vectors"]}
    proc, doc = broken_run(tmp_path_factory, "offbyone", [_match(n, names) for n in BROKEN[0][1]])
    r = by_name(doc)["v04-orders-residual-only"]
    ff = r["first_failure"]
    assert ff["frame"] == 24 and ff["axis"] == "y" and ff["marker"] == 11
    assert ff["marker_name"] == "LELB" and abs(ff["grid_steps"] - 1.0) < 1e-9
    assert "frame 24, marker 'LELB' (index 11), axis y: got" in r["message"]
    assert r["max_abs"] > r["allowed_max_abs"]


def test_encoder_mode(tmp_path):
    proc, doc = run(tmp_path, "--encoder", f"{PY} -m mpz.conformance.refencoder", "--only",
                    "e02-mixed-10-metres")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    r = doc["results"][0]
    assert r["passed"] and r["declared_bound"] <= r["max_error"]
    assert r["measured_max_error"] <= r["declared_bound"]
    proc, doc = run(tmp_path, "--encoder",
                    f"{PY} -m mpz.conformance.broken_decoders loose-encoder", "--only",
                    "e02-mixed-10-metres", name="loose.json")
    assert proc.returncode == 1
    assert "declared error_bound 0.001 > requested --max-error 0.0005" in doc["results"][0]["message"]


@pytest.mark.parametrize("args", [
    [],                                                        # neither --decoder nor --encoder
    ["--decoder", "/nonexistent/decoder"],
    ["--decoder", REF, "--only", "no-such-vector"],
    ["--decoder", REF, "--vectors", "/nonexistent"],
    ["--decoder", REF, "--timeout", "0"],
])
def test_usage_errors_exit_64(args, capsys):
    from mpz.conformance.runner import main  # in-process: no decoder is ever started
    assert main(args) == 64                  # the usage-error code of every MPZ tool
    assert capsys.readouterr().err


def test_timeout_is_enforced(tmp_path):
    proc, doc = run(tmp_path, "--decoder", f"{PY} -c 'import time; time.sleep(30)'",
                    "--only", "u01-one-frame", "--timeout", "1")
    assert proc.returncode == 1
    r = doc["results"][0]
    assert r["timed_out"] and r["actual"] == "timeout" and r["seconds"] < 10
