"""``mpz encode -r``, the corpus index and ``mpz search`` on hostile input (QA of issue 15,
report qa45a: D1-D9).

Each test names the defect it covers. Inputs are built here from :mod:`mpz.synth`; the
expected values are reasoned in the comments (a descriptor of two frames, of a static
motion, a marker left out of the summary), not copied from the code's output.
"""
from __future__ import annotations

import contextlib
import json
import math
from pathlib import Path
import sqlite3
import warnings

import numpy as np
import pytest

import mpz
from mpz.corpus import INDEX_NAME, CorpusReport, encode_corpus, mirror_jobs, open_index
from mpz.encoder import EncodeOptions
from mpz.errors import EncoderError
from mpz.io import read, write
from mpz.motion import Motion
from mpz.similarity import FEATURES, descriptor, summarize
from mpz.synth import generate

OPTS = EncodeOptions(max_error=1.0)
LEVELS = (2, 4)


def run_corpus(src: Path, out: Path, **kw) -> CorpusReport:
    kw.setdefault("workers", 0)
    kw.setdefault("levels", LEVELS)
    return encode_corpus(mirror_jobs(src, out), out, OPTS, **kw)


def change_index(out: Path, statement: str, *args: object) -> None:
    """Run one SQL ``statement`` on ``out``'s index, as another program would."""
    db = sqlite3.connect(out / INDEX_NAME)
    db.execute(statement, args)
    db.commit()
    db.close()


def statuses(rep: CorpusReport) -> dict[str, str]:
    return {Path(r.source).stem: r.status for r in rep.results}


def search(capsys, *args: str) -> tuple[int, str, str]:
    """``mpz search ARGS`` in this process, with numpy's warnings made errors (a
    RuntimeWarning leaked to the user's terminal: D4)."""
    from mpz.tools import mpz_cli
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        code = mpz_cli.main(["search", *args])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


@pytest.fixture()
def corpus(tmp_path: Path) -> tuple[Path, Path, dict[str, Path]]:
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    paths = {"walk": src / "walk.trc", "jump": src / "jump.trc", "wave": src / "wave.trc"}
    write(generate("walk", frames=90, seed=1), paths["walk"])
    write(generate("jump", frames=90, seed=2), paths["jump"])
    write(generate("wave", frames=97, seed=3, markers=20), paths["wave"])
    return src, out, paths


def _one_frame(path: Path) -> Path:
    m = generate("walk", frames=10, seed=4)
    write(Motion(np.asarray(m.positions)[:1], m.names, m.rate, units=m.units), path)
    return path


# ----------------------------------------------------------- D1: one frame --
def test_a_one_frame_capture_is_archived_unsearchable_and_the_run_goes_on(corpus, capsys):
    """D1: ValueError in descriptor() stopped the whole run (traceback, exit 1) and left
    the 1-frame output without a row; every rerun the same. An archive keeps every file
    (a static trial may hold one frame): it is encoded and indexed without a summary,
    said, and search leaves it out."""
    from mpz.tools import mpz_cli
    src, out, paths = corpus
    _one_frame(src / "a_one.trc")      # sorted first: the files after it must still go
    out.mkdir()
    code = mpz_cli.main(["encode", "-r", str(src), "-o", f"{out}/", "--max-error", "1mm",
                         "--jobs", "0"])
    cap = capsys.readouterr()
    assert code in (0, 1) and "Traceback" not in cap.err, cap.err
    assert "not searchable (too short to describe: 1 frame" in cap.out + cap.err
    assert sorted(p.name for p in out.glob("*.mpz")) == ["a_one.mpz", "jump.mpz", "walk.mpz",
                                                          "wave.mpz"]
    back = mpz.decode((out / "a_one.mpz").read_bytes())
    assert back.n_frames == 1                                  # archived, and it decodes
    with open_index(out) as ix:
        rows = {r["output"]: r for r in ix.rows()}
        assert sorted(rows) == ["a_one.mpz", "jump.mpz", "walk.mpz", "wave.mpz"]
        assert rows["a_one.mpz"]["summary_method"] == "none" and rows["a_one.mpz"].summary is None
        assert ix.failures() == []
        values, table = ix.descriptors()
        assert [v["output"] for v in values] == ["jump.mpz", "walk.mpz", "wave.mpz"]
    code = mpz_cli.main(["encode", "-r", str(src), "-o", f"{out}/", "--max-error", "1mm",
                         "--jobs", "0"])                       # the next run: up to date
    assert code == 0, capsys.readouterr()
    capsys.readouterr()
    code, o, err = search(capsys, str(paths["walk"]), "--index", str(out))
    assert code == 0 and "a_one.mpz" not in o and "(and 1 not searchable" in o, o
    code, _, err = search(capsys, str(src / "a_one.trc"), "--index", str(out))
    assert code == 2 and "a_one.trc: too short to describe" in err and "Traceback" not in err
    # its neighbour, 2 frames at 100 Hz, is 2 segments of 1 frame. Each frame is its own
    # segment, so the segments explain all the variance (ev_k = 1), their lengths are
    # equal (length_cv = 0), and the duration is 2 / 100 s
    m = generate("walk", frames=2, rate=100.0, seed=5)
    d = dict(zip(FEATURES, descriptor(summarize(m)), strict=True))
    assert all(np.isfinite(v) for v in d.values())
    assert [d[f"ev_{k}"] for k in (6, 12, 24, 48)] == [1.0, 1.0, 1.0, 1.0]
    assert d["length_cv"] == 0.0 and d["log_duration"] == pytest.approx(math.log(0.02))


# ------------------------------------------------------ D2: a damaged page --
def _damage_pages_of(index: Path, table: str) -> None:
    """Flip every byte of ``table``'s root page; the header page (the schema) is intact,
    so the index opens and a later query meets the damage."""
    db = sqlite3.connect(index)
    size = db.execute("PRAGMA page_size").fetchone()[0]
    root = db.execute("SELECT rootpage FROM sqlite_master WHERE name = ?", (table,)
                      ).fetchone()[0]
    db.close()
    assert root > 1
    data = bytearray(index.read_bytes())
    for i in range((root - 1) * size, root * size):
        data[i] ^= 0x5A
    index.write_bytes(bytes(data))


def test_a_damaged_page_is_the_documented_error_in_search_and_encode(corpus, capsys):
    """D2: sqlite3.DatabaseError ("database disk image is malformed") from a query after
    the opening came out as a traceback with exit 1, in search and in encode -r."""
    from mpz.tools import mpz_cli
    src, out, paths = corpus
    run_corpus(src, out)
    _damage_pages_of(out / INDEX_NAME, "files")
    code, _, err = search(capsys, str(paths["walk"]), "--index", str(out))
    assert code == 2 and "Traceback" not in err
    assert "a damaged MPZ corpus index" in err and "remove it" in err
    code = mpz_cli.main(["encode", "-r", str(src), "-o", f"{out}/", "--max-error", "1mm",
                         "--jobs", "0", "-q"])
    err = capsys.readouterr().err
    assert code == 2 and "a damaged MPZ corpus index" in err and "remove it" in err
    # and what it says works: removed, the index is rebuilt from the outputs
    (out / INDEX_NAME).unlink()
    assert set(statuses(run_corpus(src, out)).values()) == {"kept"}


# ------------------------------------------------------------ D3: --rate --
def test_an_npy_query_takes_rate_and_says_when_one_is_assumed(corpus, tmp_path, capsys):
    """D3: an NPY query was read at 1 Hz without a word, and search had no --rate."""
    src, out, paths = corpus
    run_corpus(src, out, levels=(6, 12))
    walk = read(paths["walk"])            # 120 Hz (generate's default)
    q = tmp_path / "walk.npy"
    write(walk, q)                        # NPY keeps the positions, not the rate
    code, o, err = search(capsys, str(q), "--index", str(out), "--json")
    doc = json.loads(o)
    assert code == 0 and doc["query"]["rate"] == 1.0 and doc["query"]["rate_assumed"]
    assert "NPY stores no frame rate: 1 Hz is assumed; give the true one with --rate HZ" in err
    # at its true rate the NPY holds the TRC's motion: the same summary, distance 0
    code, o, err = search(capsys, str(q), "--index", str(out), "--json", "--rate", "120")
    doc = json.loads(o)
    assert code == 0 and doc["query"]["rate"] == 120.0 and not doc["query"]["rate_assumed"]
    assert "assumed" not in err
    top = doc["results"][0]
    assert top["output"] == "walk.mpz" and top["distance"] == 0.0 and not top["identical"]
    # a query that stores its rate: --rate would override it silently, so it is an error
    code, _, err = search(capsys, str(paths["walk"]), "--index", str(out), "--rate", "60")
    assert code == 2 and "walk.trc: --rate 60: this TRC stores its rate" in err


# -------------------------------------------------- D4: degenerate queries --
def _degenerate(tmp_path: Path) -> dict[str, Path]:
    m = generate("walk", frames=50, seed=6)
    p = np.asarray(m.positions)
    gaps = tmp_path / "all_gaps.trc"
    write(Motion(np.full_like(p, np.nan), m.names, m.rate, units=m.units,
                 valid=np.zeros(p.shape[:2], bool)), gaps)
    one = tmp_path / "one_marker.trc"
    write(Motion(p[:, :1], m.names[:1], m.rate, units=m.units), one)
    nan = tmp_path / "all_nan.npy"
    np.save(nan, np.full((50, 10, 3), np.nan))
    return {"gaps": gaps, "one": one, "nan": nan}


@pytest.mark.parametrize("kind,said", [
    ("gaps", "no pose to describe: no valid marker sample"),
    ("one", "no pose to describe: 1 marker valid"),
    ("nan", "no pose to describe: no valid marker sample"),
])
def test_a_query_without_a_pose_is_refused(corpus, tmp_path, capsys, kind, said):
    """D4: numpy's RuntimeWarnings, then a ranking of meaningless distances, exit 0."""
    src, out, paths = corpus
    run_corpus(src, out)
    q = _degenerate(tmp_path)[kind]
    code, o, err = search(capsys, str(q), "--index", str(out))
    assert code == 2 and o == "" and f"{q.name}: {said}" in err, err
    assert "Warning" not in err and "Traceback" not in err


def test_a_file_without_a_pose_is_archived_unsearchable(corpus, tmp_path):
    """D4, indexing: the all-gaps file got a row whose descriptor was NaN-laden, which
    made every distance of a search unscaled. Such files are archived (nothing is lost)
    and indexed without a summary: not search candidates, and no NaN in the index."""
    src, out, paths = corpus
    for p in _degenerate(tmp_path).values():
        p.rename(src / p.name)
    rep = run_corpus(src, out)
    got = {Path(r.source).name: r for r in rep.results}
    for name in ("all_gaps.trc", "one_marker.trc", "all_nan.npy"):
        r = got[name]
        assert r.status == "encoded" and any("not searchable (no pose to describe" in n
                                             for n in r.notes), (r.status, r.notes)
        assert (out / (Path(name).stem + ".mpz")).exists()
    assert [got[n].status for n in ("walk.trc", "jump.trc", "wave.trc")] == ["encoded"] * 3
    with open_index(out) as ix:
        assert len(ix.rows()) == 6 and ix.failures() == [] and ix.damaged() == set()
        values, table = ix.descriptors()
        assert len(values) == 3 and np.all(np.isfinite(table))


def test_a_static_motion_has_the_floor_speed():
    """D4: a perfectly static file had log_speed = log(1e-9) = -20.7, which raised the
    feature's spread over an index from 0.73 to 3.77 (QA). Its segment means are all the
    same pose, so the speed is 0 and the floor applies: log(MIN_SPEED); nothing moves, so
    the segments explain all of the (zero) variance by convention: ev_k = 1."""
    m = generate("walk", frames=60, seed=7)
    still = np.repeat(np.asarray(m.positions)[:1], 60, axis=0)
    d = dict(zip(FEATURES, descriptor(summarize(Motion(still, m.names, m.rate,
                                                       units=m.units))), strict=True))
    assert d["log_speed"] == math.log(0.05)           # MIN_SPEED
    assert d["amplitude"] == 0.0 and d["ev_6"] == 1.0


# ----------------------------------------------- D5: outputs and what is gone --
def test_an_output_of_another_size_than_its_row_is_marked_changed(corpus, tmp_path, capsys):
    """A corpus QA run of stop 76: an output cut to 3,000 bytes, its source deleted, was
    listed as if sound, with the note "the .mpz holds the motion", exit 0, where mpz decode
    refuses it."""
    src, out, paths = corpus
    run_corpus(src, out)
    query = tmp_path / "query.trc"
    query.write_bytes(paths["walk"].read_bytes())
    code, o, err = search(capsys, str(query), "--index", str(out), "--json")
    assert code == 0 and not any(r["output_changed"] for r in json.loads(o)["results"])
    walk = out / "walk.mpz"
    walk.write_bytes(walk.read_bytes()[:3000])
    paths["walk"].unlink()
    code, o, err = search(capsys, str(query), "--index", str(out), "--json")
    flags = {r["output"]: (r["output_exists"], r["output_changed"])
             for r in json.loads(o)["results"]}
    assert flags == {"walk.mpz": (True, True), "jump.mpz": (True, False),
                     "wave.mpz": (True, False)}
    assert code == 1
    assert "1 of the outputs listed has another size than the index recorded" in err
    assert "the .mpz holds the motion, if it is sound" in err
    code, o, err = search(capsys, str(query), "--index", str(out), "-n", "1")
    assert code == 1 and "=walk.mpz [changed]  <- " in o.splitlines()[-1]


def test_results_name_the_output_and_mark_what_is_gone(corpus, tmp_path, capsys):
    """D5: results showed the source path only, and still listed a deleted output and
    moved sources without a sign."""
    src, out, paths = corpus
    run_corpus(src, out)
    query = tmp_path / "query.trc"
    query.write_bytes(paths["walk"].read_bytes())
    (out / "walk.mpz").unlink()
    src.rename(tmp_path / "moved")
    code, o, err = search(capsys, str(query), "--index", str(out), "--json")
    doc = json.loads(o)
    flags = {r["output"]: (r["output_exists"], r["source_exists"]) for r in doc["results"]}
    assert flags == {"walk.mpz": (False, False), "jump.mpz": (True, False),
                     "wave.mpz": (True, False)}
    assert code == 1                       # warnings only: a result is no longer there
    code, o, err = search(capsys, str(query), "--index", str(out), "-n", "1")
    line = o.splitlines()[-1]
    assert code == 1 and "=walk.mpz [missing]  <- " in line and line.endswith("[missing]")
    assert "1 of the files listed is no longer in the index's folder" in err


# ------------------------------------------------- D6: a marker seen briefly --
def test_a_marker_valid_in_a_few_frames_is_left_out_of_the_summary():
    """D6: the gap filling holds a marker at its last valid position; one seen in 8 of
    2,751 frames then set the shape of the mean pose. Seen in 5 of 200 frames (2.5 %,
    under MIN_VALID_SHARE = 10 %) it must count as a gap throughout: the summary, and so
    the descriptor, are those of the same motion with that marker never valid."""
    m = generate("jump", frames=200, seed=8)
    pos = np.asarray(m.positions).copy()
    sparse = np.ones(pos.shape[:2], bool)
    sparse[:, 0] = False
    sparse[50:55, 0] = True
    never = sparse.copy()
    never[:, 0] = False
    a = summarize(Motion(np.where(sparse[..., None], pos, np.nan), m.names, m.rate,
                         units=m.units, valid=sparse))
    b = summarize(Motion(np.where(never[..., None], pos, np.nan), m.names, m.rate,
                         units=m.units, valid=never))
    for la, lb in zip(a.levels, b.levels, strict=True):
        assert np.array_equal(la.starts, lb.starts) and np.array_equal(la.means, lb.means)
    assert np.array_equal(descriptor(a), descriptor(b))
    # seen in 40 of 200 frames (20 %) it stays: its columns are not all zeros
    kept = np.ones(pos.shape[:2], bool)
    kept[:, 0] = False
    kept[50:90, 0] = True
    c = summarize(Motion(np.where(kept[..., None], pos, np.nan), m.names, m.rate,
                         units=m.units, valid=kept))
    assert np.any(c.levels[-1].means[:, :3] != 0.0)


def test_an_index_of_the_old_descriptor_is_refused_then_rebuilt(corpus, capsys):
    """D6 changed the summaries: an index of descriptor version 1 holds summaries made the
    old way. Search refuses it clearly; the next run rebuilds its rows from the outputs
    (kept, nothing encoded again)."""
    src, out, paths = corpus
    run_corpus(src, out)
    # such an index was written before the corpus table's checksum (stop 74); a version
    # changed in place under its checksum is a damaged index (test_corpus.py)
    change_index(out, "UPDATE corpus SET value = '1' WHERE key = 'descriptor_version'")
    change_index(out, "DELETE FROM corpus WHERE key = 'corpus_sha256'")
    code, _, err = search(capsys, str(paths["walk"]), "--index", str(out))
    assert code == 2 and "an index of descriptor version 1" in err
    assert "run mpz encode -r into its folder again" in err
    rep = run_corpus(src, out)
    assert statuses(rep) == {"walk": "kept", "jump": "kept", "wave": "kept"}
    assert any("another descriptor version" in n for n in rep.index_notes)
    code, o, err = search(capsys, str(paths["walk"]), "--index", str(out), "--json")
    assert code == 0 and json.loads(o)["results"][0]["output"] == "walk.mpz"


# ------------------------------------------------- D7: a foreign database --
def test_a_foreign_database_is_not_written_into(corpus, capsys):
    """D7: an index.sqlite of another program got our tables beside its own, and search
    said "no such table: corpus"."""
    src, out, paths = corpus
    out.mkdir()
    db = sqlite3.connect(out / INDEX_NAME)
    db.execute("CREATE TABLE invoices (id, amount)")
    db.execute("INSERT INTO invoices VALUES (1, 9.5)")
    db.commit()
    db.close()
    before = (out / INDEX_NAME).read_bytes()
    with pytest.raises(EncoderError, match="not an MPZ corpus index .*table invoices"):
        run_corpus(src, out)
    assert (out / INDEX_NAME).read_bytes() == before and not list(out.glob("*.mpz"))
    code, _, err = search(capsys, str(paths["walk"]), "--index", str(out))
    assert code == 2 and "not an MPZ corpus index" in err and "no such table" not in err
    # an empty file is no one's database: it becomes the index
    (out / INDEX_NAME).write_bytes(b"")
    code, _, err = search(capsys, str(paths["walk"]), "--index", str(out))
    assert code == 2 and "not an MPZ corpus index (an empty database" in err
    assert not run_corpus(src, out).failed


# ------------------------------------------------------------ D8: messages --
def test_query_errors_name_the_file_and_the_option(corpus, tmp_path, capsys):
    """D8: a damaged .mpz query's error named no file; --asf naming a C3D gave "IndexError";
    --asf with a TRC query was ignored; an AMC on stdin without --asf did not name it."""
    import subprocess
    import sys
    src, out, paths = corpus
    run_corpus(src, out)
    good = out / "walk.mpz"
    cut = tmp_path / "cut.mpz"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    code, _, err = search(capsys, str(cut), "--index", str(out))
    assert code == 2 and f"error: {cut}" in err and "Traceback" not in err
    c3d = tmp_path / "x.c3d"
    write(generate("walk", frames=20), c3d)
    # the ASF is checked before the AMC is read, so the AMC need not exist
    code, _, err = search(capsys, str(tmp_path / "none.amc"), "--asf", str(c3d), "--index",
                          str(out))
    assert code == 2 and f"{c3d}: --asf: not a readable ASF skeleton file" in err
    assert "IndexError" not in err
    code, _, err = search(capsys, str(paths["walk"]), "--asf", str(c3d), "--index", str(out))
    assert code == 2 and "--asf" in err
    exe = Path(sys.executable).parent / "mpz"
    amc_text = b":FULLY-SPECIFIED\n:DEGREES\n1\nroot 0 0 0 0 0 0\n"
    from mpz.io import detect_format
    assert detect_format(amc_text) == ".amc"
    p = subprocess.run([str(exe), "search", "-", "--index", str(out)], input=amc_text,
                       capture_output=True, timeout=120)
    assert p.returncode == 2 and b"--asf FILE.asf" in p.stderr, p.stderr


# ------------------------------------------------------- D9: damaged rows --
@pytest.mark.parametrize("damage", [
    "UPDATE files SET descriptor = ? WHERE output = 'walk.mpz'",
    "UPDATE levels SET means = substr(means, 1, 10) WHERE output = 'walk.mpz' AND k = 4",
    # the right length, a NaN in it (stop 45 left it unchecked: it was, through the
    # descriptor the query's identical row is described by)
    "UPDATE levels SET means = substr(means, 1, 4) || x'0000c07f' || substr(means, 9) "
    "WHERE output = 'walk.mpz' AND k = 4",
    # a level row deleted: it passed the run as up to date, and a query by the file itself
    # ranked it at 0.635, not 0 (a QA run of stop 48)
    "DELETE FROM levels WHERE output = 'walk.mpz' AND k = 4",
    # columns another program filled with what they cannot hold: exit 70 (a text frame
    # count or duration, a BLOB path), a rate of 0 blamed on the query, a negative wssse
    # and 2^63 - 1 frames shown as they were (a QA run of stop 53)
    "UPDATE files SET frames = 'x' WHERE output = 'walk.mpz'",
    "UPDATE files SET duration_s = 'x' WHERE output = 'walk.mpz'",
    "UPDATE files SET path = CAST(path AS BLOB) WHERE output = 'walk.mpz'",
    "UPDATE files SET units = CAST(units AS BLOB) WHERE output = 'walk.mpz'",
    "UPDATE files SET rate = 0 WHERE output = 'walk.mpz'",
    "UPDATE files SET frames = 9223372036854775807 WHERE output = 'walk.mpz'",
    "UPDATE files SET max_error = -1 WHERE output = 'walk.mpz'",
    "UPDATE levels SET wssse = -1 WHERE output = 'walk.mpz' AND k = 4",
    "UPDATE levels SET k = 'x' WHERE output = 'walk.mpz' AND k = 4",
    # a text that is not UTF-8: "cannot read the index: Could not decode to UTF-8", as if
    # the disk were locked or full, and never rebuilt (a review of stop 53)
    "UPDATE files SET path = CAST(x'ff41' AS TEXT) WHERE output = 'walk.mpz'",
    "UPDATE files SET warning = CAST(x'ff41' AS TEXT) WHERE output = 'walk.mpz'",
    # values changed in place, each still of its kind: they passed every check, and search
    # ranked from the changed descriptor (a corpus QA run of stop 55); row_sha256 finds them
    "UPDATE files SET descriptor = CAST((CASE WHEN substr(descriptor, 1, 1) = x'00' THEN "
    "x'01' ELSE x'00' END) || substr(descriptor, 2) AS BLOB) WHERE output = 'walk.mpz'",
    "UPDATE files SET source_sha256 = (CASE WHEN substr(source_sha256, 1, 1) = '0' THEN '1' "
    "ELSE '0' END) || substr(source_sha256, 2) WHERE output = 'walk.mpz'",
    "UPDATE files SET frames = frames + 1 WHERE output = 'walk.mpz'",
    "UPDATE files SET ratio = ratio * 2 WHERE output = 'walk.mpz'",
    "UPDATE files SET notes = '[\"x\"]' WHERE output = 'walk.mpz'",
])
def test_damaged_rows_are_refused_by_search_and_rebuilt_by_a_run(corpus, capsys, damage):
    """D9: a NaN descriptor and a summary cut short passed encode -r as up to date (exit
    0); search used the NaN (every distance unscaled, the query's file ranked last). A
    NaN among a level's means, of the right length, is refused alike."""
    src, out, paths = corpus
    run_corpus(src, out)
    nan = np.full(len(LEVELS) + 6, np.nan).astype("<f8").tobytes()
    change_index(out, damage, *((nan,) if "?" in damage else ()))
    code, _, err = search(capsys, str(paths["walk"]), "--index", str(out))
    assert code == 2 and "the row of walk.mpz is damaged" in err and "remove it" in err
    rep = run_corpus(src, out)
    assert statuses(rep) == {"walk": "kept", "jump": "skipped", "wave": "skipped"}
    assert any("damaged index row" in n and "walk.mpz" in n for n in rep.index_notes)
    code, o, _ = search(capsys, str(paths["walk"]), "--index", str(out), "--json")
    top = json.loads(o)["results"][0]
    assert code == 0 and top["output"] == "walk.mpz" and top["distance"] == 0.0


def test_a_row_without_a_checksum_is_read_unchecked_until_a_run_gives_it_one(corpus,
                                                                              capsys):
    """A row of an mpz before row_sha256 (NULL there) is read as it is: search ranks it.
    The next run gives every such row the checksum of its values as they are, and says
    so (a review of stop 56: they stayed unchecked for good); a change after that is
    found."""
    from mpz.corpus import row_digest
    src, out, paths = corpus
    run_corpus(src, out)
    change_index(out, "UPDATE files SET row_sha256 = NULL")
    change_index(out, "UPDATE files SET ratio = ratio * 2 WHERE output = 'jump.mpz'")
    code, o, _ = search(capsys, str(paths["walk"]), "--index", str(out), "--json")
    assert code == 0 and json.loads(o)["results"][0]["output"] == "walk.mpz"
    rep = run_corpus(src, out)
    assert set(statuses(rep).values()) == {"skipped"}
    assert "3 index rows written before row_sha256 got the checksum of their values as " \
           "they are: a value changed from now on is found" in rep.index_notes
    with contextlib.closing(open_index(out)) as ix:
        for r in ix.rows():
            assert r.values["row_sha256"] == row_digest(ix.row(r["output"]))
    assert run_corpus(src, out).index_notes == []
    change_index(out, "UPDATE files SET ratio = ratio * 2 WHERE output = 'jump.mpz'")
    code, _, err = search(capsys, str(paths["walk"]), "--index", str(out))
    assert code == 2 and "the row of jump.mpz is damaged" in err


# a level changed in place, each value still of its kind and length: the levels were
# checked by length and type only (stop 57's list), so the API's rows and an .mpz query's
# summary were read from the changed level; levels_sha256 finds them
_LEVEL_CHANGES = [
    "UPDATE levels SET means = CAST((CASE WHEN substr(means, 1, 1) = x'00' THEN x'01' ELSE "
    "x'00' END) || substr(means, 2) AS BLOB) WHERE output = 'walk.mpz' AND k = 4",
    "UPDATE levels SET wssse = wssse * 2 WHERE output = 'walk.mpz' AND k = 2",
    "UPDATE levels SET starts = CAST(substr(starts, 1, 4) || x'01000000' || "
    "substr(starts, 9) AS BLOB) WHERE output = 'walk.mpz' AND k = 4",
]


@pytest.mark.parametrize("damage", _LEVEL_CHANGES)
def test_a_level_changed_in_place_is_found_where_levels_are_read(corpus, capsys, damage):
    """``Index.rows`` and an .mpz query of ``mpz search`` (which read the levels) refuse
    the row; a run checks the levels' checksum only with ``verify`` (every level read
    whole), and then rebuilds the row."""
    src, out, paths = corpus
    run_corpus(src, out)
    mpz_query = out / "walk.mpz"
    change_index(out, damage)
    with contextlib.closing(open_index(out)) as ix, \
            pytest.raises(EncoderError, match="the row of walk.mpz is damaged .its levels "
                                              "are not those written: their levels_sha256"):
        ix.rows()
    code, _, err = search(capsys, str(mpz_query), "--index", str(out))
    assert code == 2 and "the row of walk.mpz is damaged" in err, err
    # a capture's query reads the descriptors alone: still searchable
    code, o, _ = search(capsys, str(paths["walk"]), "--index", str(out), "--json")
    assert code == 0 and json.loads(o)["results"][0]["output"] == "walk.mpz"
    assert set(statuses(run_corpus(src, out)).values()) == {"skipped"}
    rep = run_corpus(src, out, verify=True)
    assert statuses(rep) == {"walk": "kept", "jump": "skipped", "wave": "skipped"}
    assert any("damaged index row" in n and "walk.mpz" in n for n in rep.index_notes)
    with contextlib.closing(open_index(out)) as ix:
        assert len(ix.rows()) == 3
    code, o, _ = search(capsys, str(mpz_query), "--index", str(out), "--json")
    assert code == 0 and json.loads(o)["results"][0]["output"] == "walk.mpz"


def test_an_mpz_query_reads_the_row_of_its_source_alone(corpus, capsys, monkeypatch):
    """A search QA run: an .mpz query read and checked every row's stored summary to find
    its source's (18 s and 2.2 GB a query at 20,000 rows, against 3.8 s for a capture).
    It reads that row alone now, checked as before: a damaged level in another row does
    not stop it, one in its own row does (by checksum, and by type)."""
    from mpz.corpus import Index
    src, out, paths = corpus
    run_corpus(src, out)
    mpz_query = out / "walk.mpz"
    change_index(out, _LEVEL_CHANGES[0].replace("'walk.mpz'", "'jump.mpz'"))

    def every_row(self):
        raise AssertionError("Index.rows() read for one row")
    monkeypatch.setattr(Index, "rows", every_row)
    code, o, err = search(capsys, str(mpz_query), "--index", str(out), "--json")
    assert code == 0, err
    doc = json.loads(o)
    assert doc["query"]["summary"] == "the index's row of its source"
    assert doc["results"][0]["output"] == "walk.mpz" and doc["results"][0]["distance"] == 0
    change_index(out, _LEVEL_CHANGES[1])
    code, _, err = search(capsys, str(mpz_query), "--index", str(out))
    assert code == 2 and "the row of walk.mpz is damaged" in err, err
    change_index(out, "UPDATE levels SET starts = 'text' WHERE output = 'walk.mpz' AND k = 4")
    code, _, err = search(capsys, str(mpz_query), "--index", str(out))
    assert code == 2 and "the row of walk.mpz is damaged" in err and "not a BLOB" in err, err


def test_levels_without_a_checksum_are_read_unchecked_until_a_run_gives_them_one(corpus):
    """Rows of an mpz before levels_sha256 (NULL there) are read as they are; the next run
    gives each the checksum of its levels as they are, and says so; a change after that is
    found. The digest is that of the levels as stored, computed here with hashlib."""
    import hashlib
    src, out, _ = corpus
    run_corpus(src, out)
    change_index(out, "UPDATE files SET levels_sha256 = NULL")
    change_index(out, "UPDATE levels SET wssse = wssse * 2 WHERE output = 'jump.mpz'")
    with contextlib.closing(open_index(out)) as ix:
        assert len(ix.rows()) == 3
    rep = run_corpus(src, out)
    assert set(statuses(rep).values()) == {"skipped"}
    assert any(n.startswith("3 index rows written before levels_sha256 got the checksum of "
                            "their levels as they are") for n in rep.index_notes), \
        rep.index_notes
    db = sqlite3.connect(out / INDEX_NAME)
    for output, stored in db.execute("SELECT output, levels_sha256 FROM files"):
        text = "".join(f"{k}\t{w!r}\t{s.hex()}\t{m.hex()}\n" for k, w, s, m in db.execute(
            "SELECT k, wssse, starts, means FROM levels WHERE output = ? ORDER BY k",
            (output,)))
        assert stored == hashlib.sha256(text.encode()).hexdigest(), output
    db.close()
    assert run_corpus(src, out).index_notes == []
    change_index(out, "UPDATE levels SET wssse = wssse * 2 WHERE output = 'jump.mpz'")
    with contextlib.closing(open_index(out)) as ix, \
            pytest.raises(EncoderError, match="the row of jump.mpz is damaged"):
        ix.rows()


def test_one_file_and_one_moved_source_are_said_in_the_singular(tmp_path, capsys):
    """A QA run of stop 48: "1 files in OUT/index.sqlite" and "1 of the sources listed it
    is no longer at the path"."""
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    write(generate("walk", frames=90, seed=1), src / "walk.trc")
    run_corpus(src, out)
    query = tmp_path / "q.trc"
    (src / "walk.trc").rename(query)
    code, o, err = search(capsys, str(query), "--index", str(out))
    assert code == 0 and f"\n1 file in {out / INDEX_NAME};" in o, o
    assert "note: 1 of the sources listed is no longer at the path the index holds" in err


def test_a_finer_level_beside_the_index_levels_leaves_the_descriptor_as_it_is():
    """An .mpz query whose summary chunk holds a level finer than the index's (--summary
    6,12,24,48,96) was described from that level: amplitude and speed of 96 segments
    against rows of 48, so its own source moved from 0.004 to 0.17 away, and to 1.08
    with 580 (a QA run of stop 53). The features come from the finest of the index's."""
    from mpz.similarity import descriptor, summarize
    from mpz.synth import generate
    m = generate("walk", frames=400, seed=5)
    index = (6, 12, 24, 48)
    plain = descriptor(summarize(m, index), index)
    for extra in ((96,), (96, 200)):
        finer = summarize(m, index + extra)
        assert np.array_equal(descriptor(finer, index), plain), extra
        assert not np.array_equal(descriptor(finer, index + extra), plain)


def _cut_short(path: Path, out: Path) -> Path:
    """``path``, a TRC, with a header that declares 999999 frames: read with a warning."""
    lines = path.read_text().split("\n")
    fields = lines[2].split("\t")
    fields[2] = "999999"
    lines[2] = "\t".join(fields)
    out.write_text("\n".join(lines))
    return out


def test_a_readers_warning_about_the_query_is_said_and_exits_1(corpus, tmp_path, capsys):
    """`mpz show` and `mpz encode` say a TRC's header disagrees with its rows and exit 1;
    `mpz search`, `mpz summary` and `mpz compare` dropped the warning and exited 0 (a QA
    run of stop 53)."""
    from mpz.tools import mpz_cli

    def cli(capsys, *argv: str) -> tuple[int, str, str]:
        code = mpz_cli.main(list(argv))
        cap = capsys.readouterr()
        return code, cap.out, cap.err
    src, out, paths = corpus
    run_corpus(src, out, levels=(6, 12))
    cut = _cut_short(paths["walk"], tmp_path / "cut.trc")
    said = "NumFrames says 999999, file has 90 rows"
    code, o, err = search(capsys, str(cut), "--index", str(out), "--json")
    assert code == 1 and f"mpz search: warning: {cut}: {said}" in err, err
    assert json.loads(o)["query"]["warnings"] == [said]
    code, o, err = search(capsys, str(paths["walk"]), "--index", str(out), "--json")
    assert code == 0 and json.loads(o)["query"]["warnings"] == []
    code, o, err = cli(capsys, "summary", str(cut), "--k", "2,3")
    assert code == 1 and f"mpz summary: warning: {cut}: {said}" in err, err
    code, o, err = cli(capsys, "compare", str(cut), str(cut))
    assert code == 1 and f"mpz compare: warning: {cut}: {said}" in err, err
    code, o, err = cli(capsys, "compare", str(paths["walk"]), str(paths["walk"]))
    assert code == 0 and "warning" not in err


def test_a_row_whose_output_is_no_text_is_refused_and_dropped_by_a_run(corpus, capsys):
    """An output key stored as a BLOB: the run crashed on it (bytes.split("/")), search
    showed it (a QA run of stop 53)."""
    src, out, paths = corpus
    run_corpus(src, out)
    change_index(out, "UPDATE files SET output = CAST(output AS BLOB) WHERE output = 'walk.mpz'")
    code, _, err = search(capsys, str(paths["walk"]), "--index", str(out))
    assert code == 2 and "the row of b'walk.mpz' is damaged" in err, err
    rep = run_corpus(src, out)
    assert statuses(rep) == {"walk": "kept", "jump": "skipped", "wave": "skipped"}
    code, o, _ = search(capsys, str(paths["walk"]), "--index", str(out), "--json")
    results = json.loads(o)["results"]
    assert code == 0 and results[0]["output"] == "walk.mpz" and len(results) == 3


def test_levels_of_no_file_are_dropped_and_an_uncovered_damaged_row_is_not_said_rebuilt(
        corpus, capsys):
    """A review of stop 53: a levels row of no file that holds what it cannot made search
    refuse the index for good while every run said it "rebuilt" it; and a run over a part
    of the inputs said it rebuilt a damaged row it never touched."""
    src, out, paths = corpus
    run_corpus(src, out)
    change_index(out, "INSERT INTO levels VALUES ('gone.mpz', 'x', 1.0, x'00', x'00')")
    code, o, err = search(capsys, str(paths["walk"]), "--index", str(out), "--json")
    assert code == 0 and json.loads(o)["results"][0]["output"] == "walk.mpz", err
    rep = run_corpus(src, out)
    assert not any("damaged" in n for n in rep.index_notes), rep.index_notes
    db = sqlite3.connect(out / INDEX_NAME)
    assert db.execute("SELECT COUNT(*) FROM levels WHERE output = 'gone.mpz'").fetchone() == (0,)
    db.close()
    # walk's row damaged, then a run over jump and wave alone: walk's row is not rebuilt
    change_index(out, "UPDATE files SET frames = 'x' WHERE output = 'walk.mpz'")
    rep = encode_corpus([j for j in mirror_jobs(src, out) if "walk" not in j[0]], out, OPTS,
                        workers=0, levels=LEVELS)
    assert not any("rebuilt: walk.mpz" in n for n in rep.index_notes), rep.index_notes
    assert any("left as it is" in n and "walk.mpz" in n for n in rep.index_notes)
    rep = run_corpus(src, out)
    assert any("rebuilt: walk.mpz" in n for n in rep.index_notes)
    code, _, _ = search(capsys, str(paths["walk"]), "--index", str(out))
    assert code == 0
