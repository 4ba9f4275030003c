"""What the runner's messages say, as an outside implementer reads them (a QA report of
stop 71, revB): the rule of the check that failed, the hint a 1.0 decoder needs, JSON terms
for the sidecar, the code points of strings that print alike, and so on.

The fake decoders are small scripts that import numpy alone: most copy a vector's expected
output and sidecar (the manifest's) and then break one thing, so a run takes a fraction of
a second where the reference decoder takes one or two.
"""
from __future__ import annotations

import json
from pathlib import Path
import subprocess
import sys
import textwrap

import pytest

from mpz.conformance import manifest as mf

PY = sys.executable
MAN = mf.load()
VEC = {v["name"]: v for v in MAN["vectors"]}
ONE = "v04-orders-residual-only"        # a decodable vector that probes neither R-6.8-x
BAD = "x01-bad-signature"


def script(path: Path, text: str) -> Path:
    path.write_text(text)
    path.chmod(0o755)
    return path


def copier(tmp_path: Path, name: str, body: str = "", *, sidecar: bool = True,
           file: str = "dec.py") -> Path:
    """A decoder that writes vector ``name``'s expected output (``x``) and sidecar (``side``),
    after ``body`` has changed them (IN, OUT, x, side, np, json, sys are bound)."""
    v = VEC[name]
    h = v["header"]
    side = {"names": h["names"], "rate": h["rate"], "units": h["units_code"], "meta": h["meta"]}
    exp = mf.DEFAULT_DIR / v["expected_output"]["file"]
    return script(tmp_path / file, f"#!{PY}\n" + textwrap.dedent(f'''\
        import json, sys
        import numpy as np
        IN, OUT = sys.argv[-2], sys.argv[-1]
        x = np.load({str(exp)!r})
        side = json.loads({json.dumps(side)!r})
        ''') + textwrap.dedent(body) + textwrap.dedent(f'''
        np.save(OUT, x)
        if {sidecar!r} and side is not None:
            with open(OUT + ".json", "w", encoding="utf-8") as fh:
                json.dump(side, fh)
        '''))


def python_script(path: Path, body: str) -> Path:
    return script(path, f"#!{PY}\nimport sys\n{textwrap.dedent(body)}")


def run(tmp_path: Path, *args: str) -> tuple[subprocess.CompletedProcess, dict]:
    out = tmp_path / "results.json"
    proc = subprocess.run([PY, "-m", "mpz.conformance.runner", *args, "--results", str(out)],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert out.exists(), proc.stdout + proc.stderr
    return proc, json.loads(out.read_text())


def one(tmp_path: Path, dec: Path, name: str = ONE, *extra: str) -> dict:
    _, doc = run(tmp_path, "--decoder", str(dec), "--only", name, *extra)
    return doc["results"][0]


# ------------------------------------------------ finding 2: the rule of the check --
@pytest.mark.parametrize("body, lead", [
    ('side["names"] = side["names"][::-1]', "R-6.8-2 (§6.8, §7.3): sidecar names[0] = "),
    ('x[0, 0, 0] += 1.0', "R-6.8-1 (§7.1 item 3): 1 coordinate(s) beyond max_abs"),
    ('x[0, 0, 0] = np.nan', "R-6.8-1 (§7.1 item 3): NaN pattern differs"),
    ('x = x.astype(np.float32)', "§7.3: output dtype float32 != float64"),
    ('open(OUT + ".intlayer", "w").write("0" * 64)', "§7.1 item 2: integer-layer digest 000"),
])
def test_a_failure_leads_with_the_rule_of_its_check(tmp_path, body, lead):
    """v04 probes R-5.2-1 .. R-6.8-1 and not R-6.8-2: a wrong name cited them alone."""
    r = one(tmp_path, copier(tmp_path, ONE, body))
    assert not r["passed"] and r["message"].startswith(lead), r["message"]
    assert r["message"].endswith(f"; vector probes: {', '.join(VEC[ONE]['rules'])} "
                                 "(spec §7.4)"), r["message"]


# --------------------------------------------------- finding 1: the 1.1 rules hint --
def test_no_hint_where_a_1_0_decoder_must_reject_too(tmp_path):
    """x206 and x236 probe only (1.1) rules, but a 1.0 decoder must still reject them
    (for another reason, outside the 1.1 chunks): a decoder that decodes them is not told
    to run with --implements 1.0, which would fail it all the same. The hint follows what
    a 1.0 decoder must do (the runner's as_read_by), not the rules' marks."""
    dec = python_script(tmp_path / "accept.py", "sys.exit(0)\n")
    names = [n for n in VEC if n.split("-")[0] in ("x206", "x236")]
    assert len(names) == 2
    text = (Path(__file__).parents[1] / "spec" / "mpz-1.md").read_text(encoding="utf-8")
    later = {rid for rid, _, _, what in mf.spec_rules(text) if what.startswith("(1.1)")}
    assert all(set(VEC[n]["rules"]) <= later for n in names)
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", *names, "-q")
    assert doc["totals"]["failed"] == 2
    assert not any("--implements" in r["message"] for r in doc["results"]), doc["results"]
    assert "(1.1)" not in proc.stdout


def test_a_1_0_decoder_run_without_implements_is_told_of_it(tmp_path):
    """A 1.0 decoder decodes x171 (two chdr: a 1.1 rule); without --implements 1.0 its
    failure said nothing of the option (an implementer's QA run of stop 71)."""
    dec = python_script(tmp_path / "accept.py", "sys.exit(0)\n")
    x171 = next(n for n in VEC if n.startswith("x171-"))
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", x171, BAD, "-q")
    got = {r["name"]: r["message"] for r in doc["results"]}
    assert got[x171].endswith("; rules R-4.13-1 (spec §7.4); it is a 1.1 rule: a decoder of "
                              "1.0 alone runs with --implements 1.0 (spec §2.1)"), got[x171]
    assert "--implements" not in got[BAD]
    assert ("note: 1 failure(s) are decodes of invalid vectors that break only rules marked "
            "(1.1) in spec §7.4") in proc.stdout, proc.stdout
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD, "-q")
    assert "(1.1)" not in proc.stdout


# ------------------------------------------- finding 8: exit 0 on an invalid vector --
def test_exit_0_on_an_invalid_vector_says_what_it_wrote_and_said(tmp_path):
    """A decoder that printed its rejection and exited 0, or decoded the file: the message
    says which, with the end of its output and the reference's message (which names its
    §), not only in --results."""
    dec = python_script(tmp_path / "said.py", 'print("mydec: reject: bad signature (§3.1)")\n'
                        "sys.exit(0)\n")
    r = one(tmp_path, dec, BAD)
    ref = VEC[BAD]["reference_message"]
    assert "§" in ref
    assert ("but decoder exited 0 (it wrote no out.npy; its output ends: 'mydec: reject: bad "
            "signature (§3.1)'): a rejection is a non-zero exit status (spec §7.3); the "
            f"reference raises {VEC[BAD]['expected_error']}: {ref}; rules ") in r["message"], \
        r["message"]
    dec = python_script(tmp_path / "wrote.py", 'open(sys.argv[2], "wb").write(b"x")\n')
    r = one(tmp_path, dec, BAD)
    assert "but decoder exited 0 (it wrote out.npy; it printed nothing); the reference" \
        in r["message"], r["message"]


# ------------------------------------- finding 5: out of memory, then killed by abort --
def test_an_allocation_failure_that_aborts_is_memory_not_a_crash(tmp_path):
    """An uncaught std::bad_alloc and Rust's failed allocation end in abort() (SIGABRT):
    classed `crash`, with the cause dropped (an implementer's QA run of stop 71)."""
    from mpz.conformance.runner import failure_kind
    bad_alloc = ("terminate called after throwing an instance of 'std::bad_alloc'\n"
                 "  what():  std::bad_alloc")
    rust = "memory allocation of 68719476736 bytes failed"
    for out in (bad_alloc, rust):
        for code, sig in ((-6, "SIGABRT"), (134, None)):
            got = failure_kind({"exit_code": code, "stderr": out, "timed_out": False,
                                "signal": sig})
            assert got is not None and got[0] == "memory", got
            assert out.splitlines()[0][:60] in got[1], got
    assert failure_kind({"exit_code": -6, "stderr": "assertion failed", "timed_out": False,
                         "signal": "SIGABRT"}) == ("crash", "killed by SIGABRT")
    dec = python_script(tmp_path / "oom.py", f"import os\nprint({bad_alloc!r}, flush=True)\n"
                        "os.abort()\n")
    r = one(tmp_path, dec, BAD)
    assert r["actual"] == "memory" and not r["passed"], r
    assert r["message"].startswith("decoder ran out of memory (killed by SIGABRT, after: "
                                   "terminate called after throwing an instance of "
                                   "'std::bad_alloc') (limit 2048 MB)"), r["message"]


# ------------------------------- finding 4: -q and rejections by a traceback or panic --
def test_quiet_still_counts_rejections_by_a_traceback_or_a_panic(tmp_path):
    """Under -q only the summary line is left of a pass: a decoder that panics on every
    bad file (Rust exits 101) read as fully conformant (an implementer's QA run of stop
    71)."""
    dec = python_script(tmp_path / "panic.py", "sys.stderr.write(\"thread 'main' panicked at "
                        "src/main.rs:9:5:\\nindex out of bounds\\n\")\nsys.exit(101)\n")
    x05 = next(n for n in VEC if n.startswith("x05-"))
    proc, doc = run(tmp_path, "--decoder", str(dec), "--only", BAD, x05, "-q")
    assert doc["totals"]["passed"] == 2
    assert ("2/2 passed (invalid 2/2); 2 of the rejections by an uncaught exception or a "
            "panic (see --results)") in proc.stdout, proc.stdout
    dec = python_script(tmp_path / "clean.py", "sys.exit(2)\n")
    proc, _ = run(tmp_path, "--decoder", str(dec), "--only", BAD, "-q")
    assert "uncaught" not in proc.stdout


# ------------------------------------------- finding 9: the sidecar in JSON's terms --
def _sidecar(tmp_path: Path, raw: bytes, name: str = "v09-all-chunk-types",
             file: str = "out.npy.json") -> tuple[str, list[str]]:
    from mpz.conformance.runner import compare_sidecar
    p = tmp_path / file
    p.write_bytes(raw)
    return compare_sidecar(tmp_path / "out.npy.json", VEC[name])


def _good(name: str = "v09-all-chunk-types") -> dict:
    h = VEC[name]["header"]
    return {"names": h["names"], "rate": h["rate"], "units": h["units_code"], "meta": h["meta"]}


def test_sidecar_problems_are_said_in_json_terms(tmp_path):
    good = _good()
    assert _sidecar(tmp_path, json.dumps(good).encode()) == ("match", [])
    units_code = {k: v for k, v in good.items() if k != "units"} | {"units_code": 1}
    assert _sidecar(tmp_path, json.dumps(units_code).encode()) == (
        "mismatch", ['sidecar member "units" missing (found "units_code")'])
    no_meta = {k: v for k, v in good.items() if k != "meta"}
    assert _sidecar(tmp_path, json.dumps(no_meta).encode()) == (
        "mismatch", ['sidecar member "meta" missing: write {} when the file has no meta chunk'])
    status, said = _sidecar(tmp_path, json.dumps(dict(good, units=None)).encode())
    assert status == "mismatch" and said[0].startswith("sidecar units is not an integer "
                                                       "code: null ("), said
    # "names" twice, the first right: Python keeps the last, a C parser often the first
    twice = json.dumps(good)[:-1] + ', "names": []}'
    status, said = _sidecar(tmp_path, twice.encode())
    assert status == "mismatch" and said[0] == ('sidecar has the member "names" twice (RFC '
                                                "8259 leaves its meaning open: write each "
                                                "member once)"), said
    status, said = _sidecar(tmp_path, b"\xef\xbb\xbf" + json.dumps(good).encode())
    assert status == "unreadable" and said == ["out.npy.json starts with a UTF-8 byte order "
                                               "mark (EF BB BF), which RFC 8259 §8.1 "
                                               "forbids: write none"], said


def test_a_sidecar_named_as_the_encoders_is_told_so(tmp_path):
    status, said = _sidecar(tmp_path, json.dumps(_good()).encode(), file="out.json")
    assert status == "missing" and said[0].startswith(
        "no out.npy.json (out.json exists: the decoder's sidecar name is OUT.npy with .json "
        "appended, where the encoder contract's IN.json replaces .npy): "), said


# ------------------------------------ finding 6: strings that differ but print alike --
def test_strings_that_print_alike_are_shown_by_code_point(tmp_path):
    """(Names: the nfc-names broken decoder of test_runner.py.) A meta value with a
    zero-width space, and below a key in NFC for the file's NFD, are shown by code point;
    strings that print otherwise are not."""
    good = _good("u24-meta-repeated-key")
    nfd = "caf" + "e\u0301"
    key = next(iter(good["meta"]))
    value = good["meta"][key]
    doc = dict(good, meta=dict(good["meta"], **{key: value + "\u200b"}))
    status, said = _sidecar(tmp_path, json.dumps(doc).encode(), "u24-meta-repeated-key")
    points = " ".join(f"U+{ord(c):04X}" for c in value)
    assert status == "mismatch" and said == [
        f"sidecar meta[{key!r}] = {value + chr(0x200b)!r} ({points} U+200B), expected "
        f"{value!r} ({points}) (for a repeated key, the last value: §4.11)"], said
    doc = dict(good, meta=dict(good["meta"], **{key: value + "x"}))
    status, said = _sidecar(tmp_path, json.dumps(doc).encode(), "u24-meta-repeated-key")
    assert status == "mismatch" and "U+" not in said[0], said
    # a key in NFC where the file's is in NFD
    want = dict(good, meta={nfd: "x"})
    vec = dict(VEC["u24-meta-repeated-key"], header=dict(
        VEC["u24-meta-repeated-key"]["header"], meta={nfd: "x"}))
    from mpz.conformance.runner import compare_sidecar
    p = tmp_path / "out.npy.json"
    p.write_text(json.dumps(dict(want, meta={"caf\u00e9": "x"})))
    status, said = compare_sidecar(p, vec)
    assert said == ["sidecar meta has key 'caf\u00e9' (U+0063 U+0061 U+0066 U+00E9) where "
                    "the file holds 'cafe\u0301' (U+0063 U+0061 U+0066 U+0065 U+0301) (keys "
                    "compare as exact code points)"], said


# --------------------------------------------- finding 10: the digest file's form --
@pytest.mark.parametrize("raw, said", [
    (bytes(range(200, 232)), "out.npy.intlayer holds 32 bytes that are not ASCII text (the "
     "SHA-256 itself?), not 64 hex characters: write the digest in hex"),
    (b"", "out.npy.intlayer is empty: write the digest as 64 hex characters, or no file"),
    (b" \n", "out.npy.intlayer is empty but for whitespace: "),
    (b"abc123", "out.npy.intlayer holds 6 hex characters, not 64 hex characters"),
    (b"sha256:" + b"0" * 64, "out.npy.intlayer holds the text 'sha256:000"),
])
def test_a_digest_file_of_the_wrong_form_is_said_so(tmp_path, raw, said):
    from mpz.conformance.runner import _digest_problem
    p = tmp_path / "out.npy.intlayer"
    p.write_bytes(raw)
    got = _digest_problem(p, VEC[ONE]["integer_layer_digest"], True)
    assert got is not None and got.startswith(said), got


def test_a_wrong_digest_of_a_right_array_points_at_its_layout(tmp_path):
    want = VEC[ONE]["integer_layer_digest"]
    dec = copier(tmp_path, ONE, f'open(OUT + ".intlayer", "w").write("  {want.upper()}\\n")\n')
    assert one(tmp_path, dec)["intlayer"] == "match"
    dec = copier(tmp_path, ONE, 'open(OUT + ".intlayer", "w").write("ab" * 32)\n')
    r = one(tmp_path, dec)
    assert r["message"].startswith(f"§7.1 item 2: integer-layer digest {'ab' * 32} != "
                                   f"expected {want} (the integers q and the mask must be "
                                   "exact; the array matched: check the digest's layout"), r


# ------------------------------------- finding 12: the encoder's rules and sections --
def test_an_encoders_refusal_or_missing_output_names_the_rule_and_section(tmp_path):
    item = MAN["encoder_inputs"][0]
    E = float(item["max_errors"][0])
    only = f"{item['name']}@{E:g}"
    refuse = python_script(tmp_path / "refuse.py", 'print("myenc: cannot hold bound")\n'
                           "sys.exit(2)\n")
    _, doc = run(tmp_path, "--encoder", str(refuse), "--only", only)
    assert doc["results"][0]["message"] == (
        "encoder exited 2: myenc: cannot hold bound: every input and bound the suite ships "
        "can be held, so a refusal fails here (spec §7.3); rules R-7.3-1 (spec §7.4)")
    # no output: its size and digest are null, present as the README lists them
    assert (doc["results"][0]["bytes"], doc["results"][0]["sha256"]) == (None, None)
    nothing = python_script(tmp_path / "nothing.py", "sys.exit(0)\n")
    _, doc = run(tmp_path, "--encoder", str(nothing), "--only", only)
    assert doc["results"][0]["message"] == (
        "encoder exited 0 but wrote no file out.mpz (nor any other file in its working "
        "folder): OUT.mpz is the second argument, as given (spec §7.3); rules R-7.3-1 (spec "
        "§7.4)")
    elsewhere = python_script(tmp_path / "elsewhere.py", "open('out.MPZ', 'wb').close()\n")
    _, doc = run(tmp_path, "--encoder", str(elsewhere), "--only", only)
    assert doc["results"][0]["message"].startswith(
        "encoder exited 0 but wrote no file out.mpz (it wrote out.MPZ in its working "
        "folder)"), doc["results"][0]["message"]
    # a wrong file: the rules at the end, as in decoder mode
    loose = python_script(tmp_path / "loose.py", textwrap.dedent(f"""\
        import subprocess
        sys.exit(subprocess.run([sys.executable, "-m", "mpz.conformance.refencoder",
                                 sys.argv[1], sys.argv[2], "--max-error", "{2 * E!r}"]
                                ).returncode)
        """))
    _, doc = run(tmp_path, "--encoder", str(loose), "--only", only)
    msg = doc["results"][0]["message"]
    assert msg.startswith("declared error_bound ") and msg.endswith(
        f"> requested --max-error {E!r} (§7.3: error_bound <= E); rules R-7.3-1 (spec "
        "§7.4)"), msg


# --------------------------------------------------- finding 11: the docs and the runner --
def test_the_re_judged_count_is_on_the_summary_line(tmp_path):
    """conformance/README.md: "The summary line says how many vectors changed from reject
    to decode"; it was a note line of its own."""
    dec = python_script(tmp_path / "reject.py", "sys.exit(2)\n")
    x171 = next(n for n in VEC if n.startswith("x171-"))
    proc, _ = run(tmp_path, "--decoder", str(dec), "--implements", "1.0", "--only", x171, ONE)
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("0/2 passed"))
    assert "; --implements 1.0: 1 vector(s) judged as a 1.0 decoder must read them, from " \
           "reject to decode" in line, proc.stdout


def test_only_suggests_the_names_it_begins_or_is_close_to(tmp_path):
    proc = subprocess.run([PY, "-m", "mpz.conformance.runner", "--decoder", "true", "--only",
                           "v09", "v09-all-chunk-typs", "zzzz"], capture_output=True,
                          text=True, cwd=tmp_path)
    assert proc.returncode == 64
    assert proc.stderr.rstrip().endswith("; v09: did you mean v09-all-chunk-types?; "
                                         "v09-all-chunk-typs: did you mean "
                                         "v09-all-chunk-types?"), proc.stderr


def test_the_readmes_results_example_has_the_runners_keys(tmp_path):
    """The example of conformance/README.md "JSON results" against a real document: the
    same members, at the top and in a result, and an absolute command, as the runner
    writes it (the example said ./mydecoder)."""
    import os
    import re
    text = (Path(__file__).parent / "README.md").read_text(encoding="utf-8")
    block = re.search(r"## JSON results.*?```json\n(.*?)```", text, re.S)
    assert block
    example = json.loads(block.group(1))
    _, doc = run(tmp_path, "--decoder", str(copier(tmp_path, ONE)), "--only", ONE)
    assert doc["totals"]["passed"] == 1
    assert list(example) == list(doc)
    assert list(example["results"][0]) == list(doc["results"][0])
    assert all(os.path.isabs(a) for a in (example["command"][0], doc["command"][0]))


# ------------------------------------------ finding 3: values off the file's grid --
def test_values_off_the_files_grid_are_hinted(tmp_path):
    """`mpz decode` of a BVH or AMC file writes joint positions, a fraction of a grid step
    from the marker layer (an implementer's QA run of stop 71: 0.387 grid steps)."""
    step = float(VEC[ONE]["header"]["step"])
    r = one(tmp_path, copier(tmp_path, ONE, f"x = x + 0.387 * {step!r}\n"))
    assert "beyond max_abs 4.77e-07 (most are a fraction of a grid step off, off the file's " \
           "grid: not the §6.8 marker layer, offset + q × step?): " in r["message"], r
    r = one(tmp_path, copier(tmp_path, ONE, f"x[:2] += {step!r}\n"))
    assert "beyond max_abs" in r["message"] and "off the file's grid" not in r["message"], r


# ------------------------------ an encoder QA run of stop 71 (revD): the encoder mode --
def test_an_encoders_crash_or_odd_exit_names_the_rule_and_section(tmp_path):
    """A crash, a hang and an exit above 125 said what happened and no rule, where a
    refusal named §7.3 and R-7.3-1: each names them now."""
    item = MAN["encoder_inputs"][0]
    only = f"{item['name']}@{float(item['max_errors'][0]):g}"
    for body, start in [("import os\nos.abort()\n", "encoder killed by SIGABRT"),
                        ("sys.exit(200)\n", "exit 200"),
                        ("import time\ntime.sleep(30)\n", "encoder did not finish")]:
        enc = python_script(tmp_path / "enc.py", body)
        _, doc = run(tmp_path, "--encoder", str(enc), "--only", only, "--timeout", "3")
        msg = doc["results"][0]["message"]
        assert start in msg and msg.endswith(": the encoder must write the file and exit 0 "
                                              "(spec §7.3); rules R-7.3-1 (spec §7.4)"), msg


def test_encoder_only_takes_the_names_the_runner_prints_and_suggests(tmp_path):
    """``--only`` in encoder mode took an input or input@E alone: the label of a FAIL line
    (encoder/input@E), the input's file and the group named nothing, with no hint."""
    from mpz.conformance.runner import _selects
    name = MAN["encoder_inputs"][0]["name"]
    for only in (name, f"{name}@1", f"{name}@1.0", f"encoder/{name}@1", f"inputs/{name}.npy",
                 f"{name}.npy", "encoder"):
        assert _selects(only, name, 1.0), only
    for only in (f"{name}@2", f"encoder/{name}@2", "e0", f"inputs/{name}", "valid"):
        assert _selects(only, name, 1.0) == (only == f"inputs/{name}"), only
    proc = subprocess.run([PY, "-m", "mpz.conformance.runner", "--encoder", "true", "--only",
                           name[:3]], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 64
    assert f"{name[:3]}: did you mean {name}@" in proc.stderr, proc.stderr


# ------------------------- an encoder implementer's QA of stop 72: the encoder mode --
E01 = MAN["encoder_inputs"][0]
E01_ONLY = f"{E01['name']}@{float(E01['max_errors'][0]):g}"


def test_an_encoders_traceback_is_a_crash_not_a_refusal(tmp_path):
    """An encoder that died with a Python traceback was told it had refused; a crash is an
    uncaught exception or a panic (decoder mode's classification, ``_uncaught``), a refusal
    the encoder's own non-zero exit. The verdict stays a failure."""
    enc = python_script(tmp_path / "enc.py", 'raise RuntimeError("boom")\n')
    _, doc = run(tmp_path, "--encoder", str(enc), "--only", E01_ONLY)
    r = doc["results"][0]
    assert not r["passed"] and r["actual"] == "reject", r
    assert r["message"] == (
        "encoder crashed: exited 1 after an uncaught exception or a panic, not a refusal (its "
        "output shows 'Traceback (most recent call last):' and ends 'RuntimeError: boom'): "
        "the encoder must write the file and exit 0 (spec §7.3); rules R-7.3-1 (spec §7.4)")


def test_an_encoder_that_converts_units_is_told_the_cause_first(tmp_path):
    """An encoder that wrote millimetres for a metre input was told of a declared bound
    above E, then of the units, then of the broken bound: the cause leads now, and the
    figures after it are said to come from it."""
    item = next(i for i in MAN["encoder_inputs"] if i["name"].startswith("e02-"))
    E = float(item["max_errors"][0])
    enc = python_script(tmp_path / "mm.py", textwrap.dedent("""\
        import json
        from pathlib import Path
        import numpy as np
        import mpz
        x = np.load(sys.argv[1])
        side = json.loads(Path(sys.argv[1]).with_suffix(".json").read_text())
        E = float(sys.argv[sys.argv.index("--max-error") + 1])
        assert side["units"] == "m"
        mpz.write_mpz(mpz.Motion(x * 1000, side["names"], side["rate"], "mm"), sys.argv[2],
                      max_error=E * 1000)
        """))
    _, doc = run(tmp_path, "--encoder", str(enc), "--only", item["name"])
    msg = doc["results"][0]["message"]
    assert msg.startswith("units 'mm' != input 'm', and the values were converted with them "
                          "(the input's × 1000, within the declared bound): keep the input's "
                          "units; the figures that follow come from it (mm against m); "
                          f"declared error_bound {E * 1000!r} > requested --max-error "
                          f"{E!r}"), msg
    assert msg.endswith("; rules R-7.2-1, R-7.2-2, R-7.3-1 (spec §7.4)"), msg


#: the reference encoder's file, then one change to MHDR (IN, OUT, E, x, data, b bound)
PATCHED = """\
import json, struct
from pathlib import Path
import numpy as np
import mpz
from mpz.container import repair_crcs
IN, OUT = sys.argv[1], sys.argv[2]
E = float(sys.argv[sys.argv.index("--max-error") + 1])
x = np.load(IN)
side = json.loads(Path(IN).with_suffix(".json").read_text())
data = mpz.encode(mpz.Motion(x, side["names"], side["rate"], side["units"]), max_error=E)
b = bytearray(data)
"""


@pytest.mark.parametrize("change, note", [
    # MHDR.version_minor (payload byte 1, at 16 + 1) 1 in a file of 1.0 chunk types
    ("b[17] = 1\n", "; note: the file is marked version 1.1, where the lowest minor version "
     "that describes it (by its newest chunk type) is 1.0: an encoder SHOULD write that "
     "(§2.1); not a failure"),
    # MHDR.error_bound (payload offset 22) a few ulps below the error measured: the bound
    # holds only by §7.2's slack
    (textwrap.dedent("""\
        from mpz.decoder import decode_layers
        y = decode_layers(data).motion().positions
        err = np.sqrt(((y - x) ** 2).sum(axis=2))[~np.isnan(x).any(axis=2)].max()
        b[38:46] = struct.pack("<d", float(err) * (1 - 2.0 ** -50))
        """), "; note: within the declared bound only by the float slack of §7.2: error "),
])
def test_a_pass_says_what_it_rests_on_and_a_version_above_the_lowest(tmp_path, change, note):
    """A PASS line did not say that the bound held only by the float slack of §7.2 (which
    an encoder SHOULD NOT rely on), nor that the file was marked 1.1 while it holds nothing
    that 1.0 lacks (§2.1's SHOULD): each is a note on the line, not a failure."""
    enc = python_script(tmp_path / "enc.py", PATCHED + change
                        + "Path(OUT).write_bytes(repair_crcs(bytes(b)))\n")
    proc, doc = run(tmp_path, "--encoder", str(enc), "--only", E01_ONLY)
    r = doc["results"][0]
    assert proc.returncode == 0 and r["passed"], proc.stdout + proc.stderr
    assert note in r["message"] and r["notes"] == [r["message"].split("; note: ")[1]], r
    assert f"PASS encoder/{E01_ONLY}: " in proc.stdout and note in proc.stdout
    ref = python_script(tmp_path / "ref.py", PATCHED
                        + "Path(OUT).write_bytes(repair_crcs(bytes(b)))\n")
    _, doc = run(tmp_path, "--encoder", str(ref), "--only", E01_ONLY)
    assert doc["results"][0]["passed"] and "note" not in doc["results"][0]["message"]


def test_an_input_with_an_infinity_is_counted_apart_and_exits_64(tmp_path):
    """An input of one's own manifest with an infinity in a valid sample is not run (§7.3:
    the input is at fault, not the encoder); it was counted as a failed run and the run
    exited 1. It is counted apart, said so on its line and the summary line, and the run
    exits 64, the code of the suite's other faults, even beside the encoder's failures."""
    import hashlib
    import shutil

    import numpy as np
    vdir = tmp_path / "vectors"
    (vdir / "inputs").mkdir(parents=True)
    for key in ("input", "sidecar"):
        shutil.copyfile(mf.DEFAULT_DIR / E01[key], vdir / E01[key])
    x = np.load(vdir / E01["input"])
    x[3, 2, 1] = np.inf
    np.save(vdir / "inputs" / "inf.npy", x)
    shutil.copyfile(vdir / E01["sidecar"], vdir / "inputs" / "inf.json")

    def sha(p: str) -> str:
        return hashlib.sha256((vdir / p).read_bytes()).hexdigest()
    inf = dict(E01, name="inf", input="inputs/inf.npy", sidecar="inputs/inf.json",
               sha256=sha("inputs/inf.npy"), sidecar_sha256=sha("inputs/inf.json"),
               max_errors=[1.0])
    (vdir / "manifest.json").write_text(json.dumps(dict(MAN, vectors=[],
                                                        encoder_inputs=[E01, inf])))
    refuse = python_script(tmp_path / "refuse.py", "sys.exit(2)\n")
    proc, doc = run(tmp_path, "--encoder", str(refuse), "--vectors", str(vdir), "-q")
    runs = len(E01["max_errors"])
    assert proc.returncode == 64, proc.stdout + proc.stderr
    assert doc["totals"] == {"total": runs + 1, "passed": 0, "failed": runs, "not_run": 1,
                             "groups": {"encoder": {"passed": 0, "failed": runs}}}, doc["totals"]
    assert "inf@1" not in doc["failed"] and len(doc["failed"]) == runs
    assert doc["results"][-1]["actual"] == "input" and not doc["results"][-1]["passed"]
    assert "\nNOT RUN encoder/inf@1: input inputs/inf.npy holds an infinite coordinate in a " \
           "valid sample (frame 3, marker 2): " in "\n" + proc.stdout, proc.stdout
    assert proc.stdout.rstrip().splitlines()[-1].startswith(f"0/{runs} passed (encoder 0/"), \
        proc.stdout
    assert proc.stdout.rstrip().endswith("; not run, the input at fault, not the encoder "
                                         "(§7.3): inf@1"), proc.stdout
    assert "1 encoder input(s) of the manifest not run" in proc.stderr, proc.stderr
