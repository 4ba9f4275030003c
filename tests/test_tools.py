"""mpzinfo and mpz subcommands: documented output and exit codes.

0 ok, 1 warnings only, 2 errors, 64 usage error (tools/mpz/tools/_cli.py)."""
import json

import numpy as np
import pytest

import mpz
from mpz import container
from mpz.spec.grammar import SIGNATURE
from mpz.synth import generate
from mpz.tools import mpz_cli, mpzinfo


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("mpzinfo")
    m = generate("walk", frames=120, seed=1, gap_fraction=0.02)
    data = mpz.encode(m, max_error=2.0, summary=(4,))
    chunks = container.parse(data)
    anc = SIGNATURE \
        + b"".join(container.build_chunk(c.type, payload=c.payload) for c in chunks[:2]) \
        + container.build_chunk("zzzz", payload=b"note") \
        + b"".join(container.build_chunk(c.type, payload=c.payload) for c in chunks[2:])
    bad = bytearray(data)
    bad[chunks[1].offset + 10] ^= 0x01          # inside MNAM payload: CRC mismatch
    out = {"ok": data, "trunc": data[: len(data) // 2], "badcrc": bytes(bad), "anc": anc}
    paths = {}
    for k, v in out.items():
        paths[k] = d / f"{k}.mpz"
        paths[k].write_bytes(v)
    return paths, m


def run(capsys, fn, argv):
    code = fn(argv)
    return code, capsys.readouterr()


def test_default_line_and_exit_codes(files, capsys):
    paths, m = files
    code, out = run(capsys, mpzinfo.main, [str(paths["ok"])])
    assert code == 0
    # a summary is written as smrc, a 1.1 chunk: the file is 1.1 (§2.1, lowest minor version)
    assert out.out.startswith(f"OK: {paths['ok']} (MPZ 1.1, 120 Hz, 120 frames, 41 markers,")
    assert "max error \u2264 2 mm" in out.out and ":1" in out.out
    code, out = run(capsys, mpzinfo.main, [str(paths["trunc"])])
    assert code == 2 and out.out.startswith("ERROR:") and "truncated" in out.out
    code, out = run(capsys, mpzinfo.main, [str(paths["badcrc"])])
    assert code == 2 and "CRC-32 mismatch" in out.out
    code, out = run(capsys, mpzinfo.main, [str(paths["anc"])])
    assert code == 1 and out.out.startswith("WARN:")


def test_verbose_lists_chunks_and_keeps_going_past_bad_crc(files, capsys):
    paths, _ = files
    code, out = run(capsys, mpzinfo.main, ["-v", str(paths["badcrc"])])
    lines = [ln for ln in out.out.splitlines() if ln.strip().startswith("chunk #")]
    assert code == 2
    assert any("MNAM" in ln and "CRC bad (computed 0x" in ln and "stored 0x" in ln for ln in lines)
    assert lines[-1].split()[2] == "MEND"             # shown up to the end despite the bad CRC
    assert all("CRC ok" in ln for ln in lines if "MNAM" not in ln)


def test_vv_prints_fields_with_offsets(files, capsys):
    paths, _ = files
    code, out = run(capsys, mpzinfo.main, ["-vv", str(paths["ok"])])
    assert code == 0
    # MHDR payload starts at byte 16: version_major at 0x00010, frame_count at 0x00014
    assert "0x00010  version_major = 1" in out.out
    assert "0x00014  frame_count = 120" in out.out


def test_vv_shows_the_fields_the_grammar_adapts_as_stored():
    """MNAM's front coding (shared, suffix) and HIER's weight codes were shown decoded
    only (names, weights 1.0): an implementer could not follow a front-coding bug in the
    dump (a QA of stop 42). Built here by hand: names "ab", "ac" -> (0, "ab"), (1, "c");
    weight 1.0 is code 15 (w = (c + 1) / 16)."""
    import mpz
    from mpz.motion import Motion
    m = Motion(np.zeros((3, 2, 3)), ["ab", "ac"], 10.0, "mm")
    data = mpz.encode(m, max_error=1.0)
    from mpz.tools.mpzinfo import inspect
    info = inspect(data, "x.mpz")
    mnam = next(c for c in info["chunks"] if c["type"] == "MNAM")
    hier = next(c for c in info["chunks"] if c["type"] == "HIER")
    names = mnam["stored"]["names"]
    start = mnam["offset"] + 8                       # the payload after the 8-byte frame
    assert [(e["shared"], bytes.fromhex(e["suffix"]["hex"])) for e in names] == \
        [(0, b"ab"), (1, b"c")]
    assert [e["at"] for e in names] == [start + 2, start + 2 + 1 + 1 + 2]  # u16 count
    assert data[names[1]["at"]] == 1 and data[names[1]["at"] + 2:names[1]["at"] + 3] == b"c"
    codes = [w for node in hier["stored"]["nodes"] for w in node["weights"]]
    shown = [w for node in hier["fields"]["nodes"] for w in node["weights"]]
    assert shown == [1.0] * len(codes) and codes == [15] * len(codes) and codes


def test_json_schema(files, capsys):
    paths, _ = files
    code, out = run(capsys, mpzinfo.main, ["--json", str(paths["ok"]), str(paths["badcrc"])])
    doc = json.loads(out.out)
    assert code == 2 and doc["schema"] == "mpzinfo/2"
    ok, bad = doc["files"]
    assert ok["status"] == "ok" and ok["frames"] == 120 and isinstance(ok["ratio"], float)
    assert ok["errors"] == [] and ok["summary_levels"] == [4]
    assert bad["errors"][0]["class"] == "ChecksumError" and bad["errors"][0]["offset"] is not None
    assert ok["chunks"][0]["type"] == "MHDR" and ok["chunks"][0]["crc_ok"] is True


def test_usage_error_exit_code(capsys):
    with pytest.raises(SystemExit) as exc:
        mpzinfo.main([])
    assert exc.value.code == 64
    with pytest.raises(SystemExit) as exc:
        mpz_cli.main(["encode"])
    assert exc.value.code == 64


def test_encode_decode_compare_cli(tmp_path, capsys):
    from mpz.io import write
    m = generate("jump", frames=90, seed=3, gap_fraction=0.03)
    src = tmp_path / "in.trc"
    write(m, src)
    out = tmp_path / "out.mpz"
    code, o = run(capsys, mpz_cli.main, ["encode", str(src), "-o", str(out), "--max-error", "1mm",
                                         "--json"])
    rep = json.loads(o.out)
    assert code == 0 and rep["max_error"] <= 1.0 and rep["ratio_float32"] > 1
    # refuses to overwrite its input, and an existing output without --force
    code, o = run(capsys, mpz_cli.main, ["encode", str(src), "-o", str(src), "--max-error", "1mm"])
    assert code == 2 and "input" in o.err
    code, o = run(capsys, mpz_cli.main, ["encode", str(src), "-o", str(out), "--max-error", "1mm"])
    assert code == 2 and "exists" in o.err
    npy = tmp_path / "back.npy"
    code, _ = run(capsys, mpz_cli.main, ["decode", str(out), "-o", str(npy)])
    arr = np.load(npy)
    assert code == 0 and arr.dtype == np.float64 and arr.shape == (90, 41, 3)
    assert np.array_equal(np.isnan(arr).any(axis=2), ~m.valid)
    code, o = run(capsys, mpz_cli.main, ["compare", str(src), str(out), "--json"])
    stats = json.loads(o.out)
    assert code == 0 and stats["max"] <= 1.0 + 1e-5      # TRC text keeps 6 decimals
    leftovers = [p.name for p in tmp_path.iterdir()
                 if p.name.startswith(".") or ".part" in p.name]
    assert leftovers == []



def test_vv_and_the_plain_dump_agree_on_every_vector(capsys):
    """``mpzinfo -vv`` crashed (KeyError) on every file with an asfs chunk, whose strings
    are top-level adapted fields without an offset of their own, and exited 1, "warnings
    only", for valid and invalid files alike (a QA of stop 48). Each vector's -vv code is
    now its plain code, which the manifest fixes: 2 for a vector expected to be rejected,
    0 or 1 for one expected to decode."""
    from pathlib import Path
    root = Path(__file__).resolve().parents[1] / "conformance" / "vectors"
    vectors = json.loads((root / "manifest.json").read_text())["vectors"]
    for v in vectors:
        path = root / v["file"]                     # e.g. "invalid/x01-....mpz"
        code, out = run(capsys, mpzinfo.main, ["-vv", str(path)])
        plain, _ = run(capsys, mpzinfo.main, [str(path)])
        assert code == plain and "Traceback" not in out.err, (v["name"], out.err[-800:])
        assert (code == 2) if v["expected"] != "decode" else code in (0, 1), v["name"]
    assert len(vectors) >= 335             # every vector, not an empty list


def test_vv_shows_a_string_field_as_stored_at_its_offset():
    """asfs's top-level strings (name, version, documentation ...) are shown as stored,
    each with its offset in the file: the u8/u16 length there, then the bytes."""
    from pathlib import Path

    from mpz.tools.mpzinfo import inspect
    path = (Path(__file__).resolve().parents[1] / "conformance" / "vectors" / "valid"
            / "v12-asfs-synthetic-default.mpz")
    data = path.read_bytes()
    asfs = next(c for c in inspect(data, path.name)["chunks"] if c["type"] == "asfs")
    name = asfs["stored"]["name"]
    raw = bytes.fromhex(name["hex"])
    assert raw == asfs["fields"]["name"].encode() and raw
    at = name["at"]
    assert data[at] == len(raw) and data[at + 1:at + 1 + len(raw)] == raw    # str8
    lines = [ln for ln in _vv_lines(path) if ln.strip().startswith(f"0x{at:05x}")]
    assert lines == [f"      0x{at:05x}  name = {raw.decode()!r}",           # decoded
                     f"      0x{at:05x}  name, as stored: bytes = {len(raw)}, "
                     f"hex = \"{raw.hex()}\""]


def _vv_lines(path) -> list[str]:
    from pathlib import Path
    import subprocess
    import sys
    exe = Path(sys.executable).parent / "mpzinfo"
    p = subprocess.run([str(exe), "-vv", str(path)], capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0, p.stderr
    return p.stdout.splitlines()


@pytest.mark.parametrize("command", ["mpzinfo", "mpz", "mpz-conformance"])
def test_a_bug_is_a_traceback_and_its_own_exit_code(command, monkeypatch, capsys, tmp_path):
    """An exception no command handles exited 1, which the tools' help defines as
    "warnings only" (mpz-conformance: "a vector failed"): a crash read as a pass with
    warnings (a QA of stop 48). It is now 70, after the traceback and a line that calls it
    a bug, and it is not taken for invalid input."""
    from mpz.conformance import runner

    def broken(*args, **kwargs):
        raise KeyError("planted by the test")
    path = tmp_path / "x.mpz"
    path.write_bytes(mpz.encode(generate("walk", frames=10), max_error=1.0))
    if command == "mpzinfo":
        monkeypatch.setattr(mpzinfo, "inspect", broken)
        code = mpzinfo.main([str(path)])
    elif command == "mpz":
        from mpz.tools import cmd_show
        monkeypatch.setattr(cmd_show, "summary", broken)
        code = mpz_cli.main(["show", str(path)])
    else:
        monkeypatch.setattr(runner, "_parser", broken)
        code = runner.main(["--help"])
    err = capsys.readouterr().err
    assert code == 70, err
    assert "Traceback" in err and "KeyError: 'planted by the test'" in err
    # which code it is, not the version alone: 0.1.0 for every development checkout
    assert f"{command}: internal error: this is a bug in mpz {mpz.identity()}, " in err
    assert " (source " in err


def test_vv_shows_every_record_of_a_chunk_whole(capsys):
    """A QA audit of stop 49: -vv cut every field at 100 characters, so a cprm's records
    past the first (and its type, dims and data) never showed. Records are listed one a
    line, each the whole record that --json gives; v10's parameter section has 16
    records, the last the undeclared group 9's ORPHAN (make_vectors.c3d_motion)."""
    import json
    from pathlib import Path
    root = Path(__file__).resolve().parents[1] / "conformance" / "vectors"
    path = root / "valid" / "v10-c3d-archive-float32.mpz"
    code, out = run(capsys, mpzinfo.main, ["-vv", str(path)])
    assert code == 0
    lines = [ln.strip() for ln in out.out.splitlines() if ln.strip().startswith("records[")]
    _, dumped = run(capsys, mpzinfo.main, ["--json", str(path)])
    cprm = next(c for c in json.loads(dumped.out)["files"][0]["chunks"]
                if c["type"] == "cprm")
    records = cprm["fields"]["records"]
    assert len(lines) == len(records) == 16
    for i, (ln, rec) in enumerate(zip(lines, records, strict=True)):
        assert ln.startswith(f"records[{i}] = ") and json.loads(ln.split(" = ", 1)[1]) == rec
    assert any('"name": "ORPHAN"' in ln and '"type": 2' in ln for ln in lines)


def test_make_example_does_not_replace_a_file_without_force(tmp_path, capsys):
    """`python -m mpz.tools.make_example walk.c3d` replaced an existing walk.c3d silently,
    where every mpz command refuses without -f (a newcomer's QA run of stop 62)."""
    from mpz.tools import make_example
    out = tmp_path / "walk.trc"
    out.write_text("mine")
    assert make_example.main([str(out), "--frames", "12"]) == 2
    assert out.read_text() == "mine"
    assert "exists; use --force" in capsys.readouterr().err
    assert make_example.main([str(out), "--frames", "12", "-f"]) == 0
    assert out.read_text().startswith("PathFileType")
