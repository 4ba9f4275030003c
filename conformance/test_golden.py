"""Regression across codec versions: mpzinfo --json and the decoded digests of
every vector are frozen in conformance/golden/golden.json (regenerated only by
``python -m mpz.tools.make_golden``, with a CHANGELOG.md entry naming the new
golden id)."""
import json
from pathlib import Path

import pytest

from mpz.tools.make_golden import GOLDEN_DIR, GOLDEN_FILE, compute

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def frozen():
    return json.loads((GOLDEN_DIR / GOLDEN_FILE).read_text())


@pytest.fixture(scope="module")
def current():
    return compute()


def test_golden_matches_current_codec(frozen, current):
    from mpz.tools.make_golden import describe_changes
    said = describe_changes(frozen, current)
    assert not said, (
        f"golden output changed: {'; '.join(said)}. See each change with python -m "
        f"mpz.tools.make_golden --out /tmp/golden and a JSON diff against "
        f"conformance/golden/golden.json; if intended, run python -m mpz.tools.make_golden "
        f"and say why in CHANGELOG.md")
    assert frozen["golden_id"] == current["golden_id"]


def test_changelog_explains_the_golden_id(frozen):
    text = (REPO / "CHANGELOG.md").read_text()
    assert frozen["golden_id"] in text, "CHANGELOG.md must name the current golden id and say why"


def test_vector_set_and_spec_version_history_in_step():
    """Every format version the vectors use is in spec Appendix B, and the newest spec
    version has vectors: a 1.x decoder must decode every vector of every earlier 1.y."""
    import re
    man = json.loads((REPO / "conformance" / "vectors" / "manifest.json").read_text())
    spec = (REPO / "spec" / "mpz-1.md").read_text()
    history = spec[spec.index("## Appendix B"):spec.index("## Appendix C")]
    versions = re.findall(r"^\| (\d+\.\d+) \|", history, flags=re.M)
    assert versions, "Appendix B lists no version"
    fmt = man["format"].split()[-1]
    assert fmt in versions
    assert max(versions, key=lambda v: tuple(map(int, v.split(".")))) == fmt, \
        "the newest spec version has no vector set: run python -m mpz.tools.make_vectors"


def test_changes_are_told_apart_and_an_unchanged_id_is_said(tmp_path, monkeypatch, capsys):
    """A QA run of stop 48: the failure said "changed for 120 vector(s)" whether a vector
    decoded otherwise or only its mpzinfo report moved, and make_golden asked for a
    CHANGELOG entry even when the id had not changed."""
    from mpz.tools import make_golden
    entry = {"decoded_sha256": "a", "integer_layer_digest": "b", "error_class": None,
             "mpzinfo": {"size": 1}}
    old = {"golden_id": "x", "vectors": {"v1": entry, "v2": entry, "v3": entry}}
    new = {"golden_id": "y", "vectors": {"v1": dict(entry, decoded_sha256="c"),
                                         "v2": dict(entry, mpzinfo={"size": 2}),
                                         "v3": entry, "v4": entry}}
    # an added vector is said as added (it was "decodes otherwise": a QA run of stop 53),
    # and a skeleton's channels are part of what a vector decodes to
    # which part of the decoded result moved is said, and an integer layer left as it was
    # points past it (a QA run of stop 55: only the float conversion had changed)
    past = ("; the integer layer is the same in each: the change is past it, in the "
            "conversion to binary64 (spec §6.8) or later")
    assert make_golden.describe_changes(old, new) == [
        "1 vector(s) added, e.g. v4",
        f"1 vector(s) decode otherwise (the output of 1{past}), e.g. v1",
        "1 vector(s) only report otherwise (mpzinfo --json), e.g. v2"]
    assert make_golden.describe_changes(new, old) == [
        "1 vector(s) removed, e.g. v4",
        f"1 vector(s) decode otherwise (the output of 1{past}), e.g. v1",
        "1 vector(s) only report otherwise (mpzinfo --json), e.g. v2"]
    both = {"vectors": {"v1": dict(entry, decoded_sha256="c", integer_layer_digest="e"),
                        "v2": dict(entry, decoded_sha256="c")}}
    assert make_golden.describe_changes({"vectors": {"v1": entry, "v2": entry}}, both) == [
        "2 vector(s) decode otherwise (the output of 2; the integer layer of 1), e.g. v1, v2"]
    skel = {"vectors": {"v1": dict(entry, channels_sha256="d")}}
    assert make_golden.describe_changes(skel, {"vectors": {"v1": dict(entry,
                                                                       channels_sha256="e")}}
                                        )[0].startswith("1 vector(s) decode otherwise")
    assert make_golden.describe_changes(old, old) == []
    shipped = tmp_path / "conformance" / "golden"          # in a clone (its top: tmp_path)
    shipped.mkdir(parents=True)
    (tmp_path / "pyproject.toml").write_text("")
    (tmp_path / "spec").mkdir()
    (tmp_path / "spec" / "mpz-1.md").write_text("")
    (shipped / "golden.json").write_text(json.dumps(old))
    monkeypatch.setattr(make_golden, "GOLDEN_DIR", shipped)
    monkeypatch.setattr(make_golden, "compute", lambda: new)
    # "--out /tmp/golden: see what changed first" compared with the empty /tmp/golden (a
    # QA run of stop 50: no change said, "was None"): it compares with the shipped file
    make_golden.main(["--out", str(tmp_path / "look")])
    out = capsys.readouterr().out
    assert "1 vector(s) decode otherwise" in out and "1 vector(s) only report" in out
    assert "would change from x to y" in out and "untouched" in out
    assert (shipped / "golden.json").read_text() == json.dumps(old)
    make_golden.main(["--out", str(shipped)])
    assert "names golden id y (was x)" in capsys.readouterr().out
    make_golden.main(["--out", str(tmp_path / "again")])
    out = capsys.readouterr().out
    assert "the golden id is unchanged: nothing for CHANGELOG.md" in out and "decode" not in out


def test_the_makers_write_into_a_clone_only(tmp_path, monkeypatch, capsys):
    """Installed from a wheel, make_vectors deleted and rewrote the vectors in site-packages
    that mpz-conformance checks against, and make_golden wrote a folder beside
    site-packages that uninstall left behind (a release QA run, stop 74). Their default
    outputs outside a clone are refused before anything is written; --out still works."""
    from mpz.conformance import manifest as mf
    from mpz.tools import make_golden, make_vectors
    installed = tmp_path / "site-packages" / "mpz" / "conformance" / "vectors"
    (installed / "valid").mkdir(parents=True)
    (installed / "valid" / "v.mpz").write_bytes(b"kept")
    monkeypatch.setattr(mf, "DEFAULT_DIR", installed)
    with pytest.raises(SystemExit) as exc:
        make_vectors.main([])
    assert exc.value.code == 2
    assert "installed package's vectors" in capsys.readouterr().err
    assert (installed / "valid" / "v.mpz").read_bytes() == b"kept"
    golden = tmp_path / "lib" / "conformance" / "golden"

    def never() -> dict:
        raise AssertionError("computed before the folder was checked")
    monkeypatch.setattr(make_golden, "GOLDEN_DIR", golden)
    monkeypatch.setattr(make_golden, "compute", never)
    assert make_golden.main([]) == 64
    assert "not in a clone of the repository" in capsys.readouterr().err
    assert not golden.exists()


def test_an_out_that_is_a_file_is_refused_before_computing(tmp_path, monkeypatch, capsys):
    """--out naming a file worked for 5 s, then ended in FileExistsError (a QA run of stop
    53)."""
    from mpz.tools import make_golden

    def never() -> dict:
        raise AssertionError("computed before --out was checked")
    monkeypatch.setattr(make_golden, "compute", never)
    (tmp_path / "new.json").write_text("{}")
    assert make_golden.main(["--out", str(tmp_path / "new.json")]) == 64
    assert "not a folder" in capsys.readouterr().err


def test_a_verdict_that_flips_is_named_with_its_direction():
    """A QA run: a decoder with a spec check dropped accepted x46-mask-flag-2, and the golden
    failure said "decode otherwise (...; the verdict of 1)" and "if intended, run
    make_golden", which would have frozen the bug."""
    from mpz.tools.make_golden import describe_changes
    entry = {"decoded_sha256": None, "integer_layer_digest": None,
             "error_class": "FormatError", "mpzinfo": {}}
    ok = {"decoded_sha256": "a", "integer_layer_digest": "b", "error_class": None,
          "mpzinfo": {}}
    said = describe_changes({"vectors": {"x46": entry, "v1": ok}},
                            {"vectors": {"x46": ok, "v1": entry}})
    assert said[0].startswith("2 vector(s) decode otherwise")
    assert said[1].startswith("2 vector(s) change verdict: v1: decoded -> rejected "
                              "(FormatError), x46: rejected (FormatError) -> decoded; "
                              "1 now decode(s) what was rejected: where the manifest says "
                              "reject, that is a decoder bug")
    assert "not a golden change" in said[1]
