"""mpz.tools.check_old_decoders: its comparison of marker layers, its reading of an old
mpzinfo, its verdicts, how it assembles an old revision's package, and its driver's
isolation from today's mpz.

Nothing here needs the project's git history or compiles a kernel: the revision is a
two-commit repository made here, and the "old decoder" a fake mpz package of a few
lines whose outputs are written below by hand.
"""
from __future__ import annotations

import json
from pathlib import Path
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from mpz.tools import check_old_decoders as cod


def _layer(**kw):
    pos = np.array([[[1.0, 2.0, 3.0], [np.nan, np.nan, np.nan]],
                    [[1.5, 2.5, 3.5], [4.0, 5.0, 6.0]]])
    base = {"positions": pos, "names": ["LFHD", "RFHD"], "rate": 120.0, "units": "mm",
            "metadata": {"format": "c3d"}}
    base.update(kw)
    return cod.MarkerLayer(**base)


# ------------------------------------------------------------ compare_layers --
def test_identical_layers_have_no_difference():
    assert cod.compare_layers(_layer(), _layer()) == []


def test_a_gap_is_any_nan():
    """Spec §6.8: any NaN bit pattern is acceptable at a gap."""
    other = _layer().positions.copy()
    payload = np.array([0x7FF8000000000001], dtype=np.uint64).view(np.float64)[0]
    other[0, 1] = payload
    assert np.isnan(payload) and payload.tobytes() != np.float64(np.nan).tobytes()
    assert cod.compare_layers(_layer(), _layer(positions=other)) == []


def test_one_ulp_is_a_difference():
    other = _layer().positions.copy()
    other[1, 1, 2] = np.nextafter(6.0, 7.0)
    diffs = cod.compare_layers(_layer(), _layer(positions=other))
    assert len(diffs) == 1
    assert diffs[0].startswith("1 coordinate(s) differ, by up to 8.881784197001252e-16")
    assert "frame 1, marker 1" in diffs[0]


def test_signed_zero_is_a_difference():
    """Bit for bit: -0.0 and 0.0 are different outputs."""
    a = _layer().positions.copy()
    a[0, 0, 0] = 0.0
    b = a.copy()
    b[0, 0, 0] = -0.0
    assert cod.compare_layers(_layer(positions=a), _layer(positions=b)) != []


def test_a_moved_gap_is_a_difference():
    other = _layer().positions.copy()
    other[1, 1] = np.nan
    diffs = cod.compare_layers(_layer(), _layer(positions=other))
    assert diffs == ["3 coordinate(s) are a gap in one and not the other (first: frame 1, "
                     "marker 1: [nan, nan, nan] instead of [4.0, 5.0, 6.0])"]


def test_shape_names_rate_units_and_meta():
    got = _layer(positions=np.zeros((3, 2, 3)), names=["LFHD", "RFHX"],
                 rate=65.0364, units="cm", metadata={"format": "c3d", "subject": "a"})
    expected = _layer(rate=65.0364227294921875)
    assert cod.compare_layers(expected, got) == [
        "shape (3, 2, 3) instead of (2, 2, 3)",
        "names differ (first at marker 1: 'RFHX' instead of 'RFHD')",
        "rate 65.0364 instead of 65.03642272949219",
        "units 'cm' instead of 'mm'",
        "meta differs at 'subject'",
    ]
    assert cod.compare_layers(expected, got, meta=False)[-1] == "units 'cm' instead of 'mm'"


def test_fewer_names():
    diffs = cod.compare_layers(_layer(), _layer(names=["LFHD"]))
    assert diffs == ["names differ (1 names instead of 2)"]


# ------------------------------------------------------------- mpzinfo_problem --
_WARN_1_1 = ("WARN: x.mpz (MPZ 1.1, 120 Hz)\n  chunk #7 asfs (ancillary)\n"
             "  warning: unknown ancillary chunk 'asfs' skipped\n"
             "  warning: unknown ancillary chunk 'smrc' skipped\n")


@pytest.mark.parametrize(("status", "stdout", "stderr", "problem"), [
    (0, "OK: x.mpz", "", None),
    (1, _WARN_1_1, "", None),                          # §2.3: 1.1 types skipped
    (1, "  warning: unknown ancillary chunk 'qqqq' skipped\n", "", None),
    (1, "  warning: unknown ancillary chunk 'meta' skipped\n", "",
     "exit 1: warning: unknown ancillary chunk 'meta' skipped"),   # a 1.0 type
    (1, _WARN_1_1 + "  warning: trailing bytes after MEND\n", "",
     "exit 1: warning: trailing bytes after MEND"),
    (1, "WARN: x.mpz\n", "", "exit 1: no warning named"),
    (2, "", "mpzinfo: x.mpz: bad CRC\n", "exit 2: mpzinfo: x.mpz: bad CRC"),
    (None, "", "Traceback ...\nKeyError: 'asfs'\n", "exit None: KeyError: 'asfs'"),
])
def test_mpzinfo_problem(status, stdout, stderr, problem):
    assert cod.mpzinfo_problem(status, stdout, stderr) == problem


# ------------------------------------------------------------------- verdict --
def _row(tmp_path, name="case", **kw):
    row = {"name": name, "decoded": True, "names": ["LFHD", "RFHD"],
           "rate": (120.0).hex(), "units": "mm", "metadata": {"format": "c3d"},
           "mpzinfo": {"status": 1, "stdout_tail": _WARN_1_1, "stderr_tail": ""}}
    row.update(kw)
    np.save(tmp_path / f"{name}.npy", _layer().positions)
    return row


def test_verdict_same_layer_passes(tmp_path):
    assert cod.verdict(cod.Reading(_layer()), _row(tmp_path), tmp_path) == \
        ("pass", "same marker layer")


def test_verdict_other_rate_fails(tmp_path):
    row = _row(tmp_path, rate=(119.99999999999999).hex())
    assert cod.verdict(cod.Reading(_layer()), row, tmp_path) == \
        ("fail", "decoded differently: rate 119.99999999999999 instead of 120.0")


def test_verdict_refusal_crash_and_missing_row(tmp_path):
    exp = cod.Reading(_layer())
    refused = {"name": "c", "decoded": False,
               "error": {"type": "FormatError", "message": "bad chdr", "mpz_error": True}}
    crashed = {"name": "c", "decoded": False,
               "error": {"type": "KeyError", "message": "'asfs'", "mpz_error": False}}
    assert cod.verdict(exp, refused, tmp_path) == ("fail", "refused: FormatError: bad chdr")
    assert cod.verdict(exp, crashed, tmp_path) == ("fail", "crashed: KeyError: 'asfs'")
    assert cod.verdict(exp, None, tmp_path)[0] == "fail"


def test_verdict_against_a_rejection(tmp_path):
    """A file today's reading rejects (a vector): the old decoder passes by rejecting it,
    is noted when it decodes it, and still fails when it crashes."""
    exp = cod.Reading(None, "FormatError: QUNT range")
    refused = {"name": "c", "decoded": False,
               "error": {"type": "FormatError", "message": "x", "mpz_error": True}}
    crashed = {"name": "c", "decoded": False,
               "error": {"type": "IndexError", "message": "x", "mpz_error": False}}
    assert cod.verdict(exp, refused, tmp_path)[0] == "pass"
    assert cod.verdict(exp, crashed, tmp_path)[0] == "fail"
    assert cod.verdict(exp, _row(tmp_path), tmp_path) == \
        ("note", "decoded a file today's decoder rejects (FormatError: QUNT range)")


def test_verdict_mpzinfo_failure_fails(tmp_path):
    row = _row(tmp_path, mpzinfo={"status": 2, "stdout_tail": "", "stderr_tail": "boom\n"})
    assert cod.verdict(cod.Reading(_layer()), row, tmp_path) == \
        ("fail", "mpzinfo -v: exit 2: boom")


def test_expected_reading_follows_the_minor_version():
    as10, as11 = cod.Reading(_layer()), cod.Reading(None, "rejected as 1.1")
    exp = cod.Expected(as10, as11)
    assert exp.for_minor(0) is as10
    assert exp.for_minor(1) is as11


# ---------------------------------------------------- an old revision's package --
def _git(repo, *args):
    subprocess.run(["git", "-C", str(repo), *args], check=True, capture_output=True,
                   env={"GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t",
                        "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t",
                        "PATH": "/usr/bin:/bin", "HOME": str(repo)})


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(textwrap.dedent(text), "utf-8")


# 0.1.0's layout: reference/ is mpz, spec/ is mpz.spec; its package list misses mpz.chunks,
# as 1c3163d's did, so that pip installed no mpz.chunks and the decoder could not import
OLD_LAYOUT = {
    "pyproject.toml": """
        [tool.setuptools]
        package-dir = { "mpz" = "reference", "mpz.spec" = "spec" }
        packages = ["mpz", "mpz.spec"]
        """,
    "reference/__init__.py": "WHICH = 'old'\n",
    "reference/chunks/__init__.py": "HERE = True\n",
    "spec/__init__.py": "",
    "spec/grammar.py": "VERSION_MAJOR, VERSION_MINOR = 1, 0\n",
}


def _old_layout_repo(tmp_path: Path) -> Path:
    """A repository of one commit, "old", holding :data:`OLD_LAYOUT`."""
    repo = tmp_path / "repo"
    repo.mkdir()
    _git(repo, "init", "-q")
    _write(repo, OLD_LAYOUT)
    _git(repo, "add", "-A")
    _git(repo, "commit", "-q", "-m", "old")
    return repo


def test_build_site_follows_the_revisions_package_dir(tmp_path):
    repo = _old_layout_repo(tmp_path)
    old = cod.resolve(repo, "HEAD")
    _write(repo, {"reference/__init__.py": "WHICH = 'new'\n"})
    _git(repo, "commit", "-q", "-am", "new")
    site = cod.build_site(repo, old, tmp_path / "work")
    assert (site / "mpz" / "__init__.py").read_text() == "WHICH = 'old'\n"
    assert (site / "mpz" / "chunks" / "__init__.py").is_file()
    assert (site / "mpz" / "spec" / "grammar.py").read_text() == \
        "VERSION_MAJOR, VERSION_MINOR = 1, 0\n"


def test_package_dirs_without_a_mapping(tmp_path):
    (tmp_path / "pyproject.toml").write_text("[project]\nname = 'mpz'\n")
    assert cod.package_dirs(tmp_path) == {"mpz": "mpz"}


# ----------------------------------------------------------------- the driver --
# A fake old decoder: decode() returns a fixed motion, refuses b"bad" as MPZError and
# crashes on b"crash"; it tries to import mpz.decoder, which the old tree lacks and
# today's (installed in this interpreter) has: the driver must not let it in
FAKE_OLD = {
    "mpz/__init__.py": """
        import types
        import numpy as np
        from mpz.errors import FormatError
        __version__ = "0.0.1-fake"

        def decode(data):
            try:
                import mpz.decoder  # noqa: F401
                leak = "today's mpz.decoder was imported"
            except ImportError:
                leak = "no"
            if data == b"bad":
                raise FormatError("refused by the fake")
            if data == b"crash":
                raise KeyError("asfs")
            pos = np.array([[[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]]])
            return types.SimpleNamespace(positions=pos, valid=np.array([[True, False]]),
                                         names=["A", "B"], rate=65.0364227294921875,
                                         units="mm", metadata={"leak": leak})
        """,
    "mpz/errors.py": """
        class MPZError(Exception):
            pass

        class FormatError(MPZError, ValueError):
            pass
        """,
    "mpz/spec/__init__.py": "",
    "mpz/spec/grammar.py": "VERSION_MAJOR, VERSION_MINOR = 1, 0\n",
    "mpz/tools/__init__.py": "",
    "mpz/tools/mpzinfo.py": """
        import sys

        def main(argv):
            print("WARN: " + argv[-1])
            print("  warning: unknown ancillary chunk 'smrc' skipped")
            sys.stdout.buffer.write(b"  bytes written below sys.stdout\\n")
            return 1
        """,
}


def _run_driver(tmp_path, files, inputs):
    site = tmp_path / "site"
    _write(site, files)
    cases = []
    for name, data in inputs:
        (tmp_path / f"{name}.mpz").write_bytes(data)
        cases.append({"name": name, "path": str(tmp_path / f"{name}.mpz")})
    (tmp_path / "cases.json").write_text(json.dumps(cases))
    driver = Path(cod.__file__).with_name("_old_decoder_driver.py")
    run = subprocess.run([sys.executable, "-I", str(driver), str(site),
                          str(tmp_path / "cases.json"), str(tmp_path / "out")],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    return [json.loads(x) for x in (tmp_path / "out" / "results.jsonl").read_text().splitlines()]


def test_driver_runs_the_old_package_alone(tmp_path):
    lines = _run_driver(tmp_path, FAKE_OLD,
                        [("ok", b"good"), ("bad", b"bad"), ("crash", b"crash")])
    assert lines[0]["driver"]["version"] == "0.0.1-fake"
    assert lines[0]["driver"]["bitstream"] == [1, 0]
    assert lines[-1] == {"foreign_modules": []}
    ok, bad, crash = lines[1:4]
    assert ok["decoded"] and ok["metadata"] == {"leak": "no"}
    assert ok["names"] == ["A", "B"] and ok["rate"] == "0x1.04254c0000000p+6"
    saved = np.load(tmp_path / "out" / "ok.npy")
    assert saved[0, 0].tolist() == [1.0, 2.0, 3.0] and np.isnan(saved[0, 1]).all()
    assert ok["mpzinfo"]["status"] == 1
    assert "unknown ancillary chunk 'smrc' skipped" in ok["mpzinfo"]["stdout_tail"]
    assert "bytes written below sys.stdout" in ok["mpzinfo"]["stdout_tail"]
    assert bad["decoded"] is False and bad["error"]["mpz_error"] is True
    assert bad["error"]["message"] == "refused by the fake"
    assert crash["decoded"] is False and crash["error"]["mpz_error"] is False
    assert crash["error"]["type"] == "KeyError"


def test_driver_on_a_revision_without_mpzinfo(tmp_path):
    """ff060a2, the first codec commit, had no mpzinfo yet: its decoder is still checked."""
    files = {k: v for k, v in FAKE_OLD.items() if not k.startswith("mpz/tools/")}
    lines = _run_driver(tmp_path, files, [("ok", b"good")])
    row = lines[1]
    assert row["decoded"] is True and row["mpzinfo"]["status"] is None
    assert row["mpzinfo"]["absent"].startswith("ModuleNotFoundError")
    exp = cod.Reading(cod.MarkerLayer(np.array([[[1.0, 2.0, 3.0], [np.nan] * 3]]), ["A", "B"],
                                      65.0364227294921875, "mm", {"leak": "no"}))
    verdict, why = cod.verdict(exp, row, tmp_path / "out")
    assert verdict == "pass" and "no mpzinfo at this revision" in why


def test_an_unknown_revision_is_named(tmp_path, capsys):
    """`check_old_decoders --rev deadbeef` printed git's "fatal: Needed a single revision"
    alone (a maintainer's QA run, stop 73): the message names the revision."""
    repo = _old_layout_repo(tmp_path)
    assert len(cod.resolve(repo, "HEAD")) == 40
    with pytest.raises(cod.UnknownRevision, match=r"^--rev deadbeef: no commit of .*repo "
                                                   r"has that name"):
        cod.resolve(repo, "deadbeef")
    assert cod.main(["--rev", "deadbeef", "--repo", str(repo), "--no-synthetic",
                     "--data", str(tmp_path)]) == 2
    assert "--rev deadbeef: no commit of" in capsys.readouterr().err


def test_the_json_file_has_a_schema_and_the_fields_its_document_lists(tmp_path):
    """`--json FILE` wrote no schema, and no document listed its fields (a maintainer's QA
    run of stop 75): it is schema mpz-check-old-decoders/1, and its fields, and those of a
    revision, are the ones docs/versioning.md lists (the fake old package of this file,
    no input: what the document holds, not what it finds)."""
    import re
    repo = tmp_path / "repo"
    repo.mkdir()
    _git(repo, "init", "-q")
    _write(repo, {"pyproject.toml": "[project]\nname = 'mpz'\n", **FAKE_OLD})
    _git(repo, "add", "-A")
    _git(repo, "commit", "-q", "-m", "fake")
    (tmp_path / "data").mkdir()
    out = tmp_path / "r.json"
    assert cod.main(["--rev", "HEAD", "--repo", str(repo), "--no-synthetic", "--data",
                     str(tmp_path / "data"), "--options", "1mm", "--work",
                     str(tmp_path / "work"), "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["schema"] == cod.JSON_SCHEMA == "mpz-check-old-decoders/1"
    text = (Path(__file__).resolve().parents[1] / "docs" / "versioning.md").read_text()
    table = text.split("## The `--json` file", 1)[1].split("\n## ", 1)[0]
    listed = re.findall(r"^\| `(\w+)` \|", table, re.M)
    assert set(listed) == set(doc)
    (rev,) = doc["revisions"]
    row = next(line for line in table.splitlines() if line.startswith("| `revisions` |"))
    assert set(re.findall(r"`(\w+)`", row.split("|")[2])) >= set(rev) | {"case", "verdict"}
    assert rev["driver"]["version"] == "0.0.1-fake" and rev["counts"]["fail"] == 0
