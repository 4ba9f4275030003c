"""bench/bench_encode.py --compare, the maintainers' byte gate for encoder changes: it must
fail (exit 1) whenever it could not compare every encode, and whenever any thread count's
bytes changed (QA 45d, items 6 and 7). Small result files built in tmp_path; no real data.
"""
from __future__ import annotations

import json


def _run(tmp_path, name, rows):
    """A result file as bench_encode.py writes it; ``rows``: key -> {threads: (sha, bytes)}.
    ``sha256`` / ``bytes`` are the first thread count's, as the measure step stores them."""
    doc = {"bench": "encode", "schema": 1, "threads": [1, 2], "rows": {}}
    for key, per in rows.items():
        first = next(iter(per.values()))
        doc["rows"][key] = {
            "bound": "1mm", "sha256": first[0], "bytes": first[1],
            "seconds": {t: 0.010 for t in per},
            "sha256_threads": {t: sha for t, (sha, _) in per.items()},
            "bytes_threads": {t: n for t, (_, n) in per.items()}}
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


SAME = {"1": ("aa", 1000), "2": ("aa", 1000)}


def test_identical_runs_pass(tmp_path, bench_script, capsys):
    be = bench_script("bench_encode")
    a = _run(tmp_path, "a.json", {"c3d/x.c3d 1mm": SAME, "bvh/y.bvh 1mm": SAME})
    assert be.compare([a], [a]) == 0
    assert "all 2 encodes identical" in capsys.readouterr().out


def test_an_after_run_without_rows_fails(tmp_path, bench_script, capsys):
    """Nothing compared is not "all identical": before, this printed "all 0 encodes
    identical" and exited 0."""
    be = bench_script("bench_encode")
    a = _run(tmp_path, "a.json", {"c3d/x.c3d 1mm": SAME})
    empty = _run(tmp_path, "empty.json", {})
    assert be.compare([a], [empty]) == 1
    out = capsys.readouterr().out
    assert "nothing compared" in out and "c3d/x.c3d 1mm (before only)" in out
    assert be.main(["--compare", str(a), "--against", str(empty)]) == 1


def test_a_dropped_or_renamed_row_fails_and_is_named(tmp_path, bench_script, capsys):
    """One row compared identical and one on each side only (the key spelled otherwise):
    the identical one does not make the gate pass."""
    be = bench_script("bench_encode")
    a = _run(tmp_path, "a.json", {"c3d/x.c3d 1mm": SAME, "c3d/y.c3d 1mm": SAME})
    b = _run(tmp_path, "b.json", {"c3d/x.c3d 1mm": SAME, "C3D/y.c3d 1mm": SAME})
    assert be.compare([a], [b]) == 1
    out = capsys.readouterr().out
    assert "c3d/y.c3d 1mm (before only)" in out and "C3D/y.c3d 1mm (after only)" in out
    dropped = _run(tmp_path, "d.json", {"c3d/x.c3d 1mm": SAME})
    assert be.compare([a], [dropped]) == 1


def test_a_thread_count_that_changed_the_bytes_fails(tmp_path, bench_script, capsys):
    """The after run's 2-thread encode gave other bytes; its 1-thread digest (the one a
    single stored digest would keep) is unchanged. Before, that passed: "all 1 encodes
    identical", exit 0."""
    be = bench_script("bench_encode")
    a = _run(tmp_path, "a.json", {"c3d/x.c3d 1mm": SAME})
    thr = _run(tmp_path, "thr.json", {"c3d/x.c3d 1mm": {"1": ("aa", 1000),
                                                        "2": ("ab", 1000)}})
    assert be.compare([a], [thr]) == 1
    out = capsys.readouterr().out
    assert "1 of 1 encodes changed" in out and "after: the thread counts disagree" in out
    assert be.compare([thr], [a]) == 1                  # and the other way round


def test_changed_bytes_of_one_thread_count_only(tmp_path, bench_script):
    """Both sides agree within themselves, but the 2-thread bytes moved between them."""
    be = bench_script("bench_encode")
    a = _run(tmp_path, "a.json", {"k 1mm": {"1": ("aa", 9), "2": ("aa", 9)}})
    b = _run(tmp_path, "b.json", {"k 1mm": {"1": ("aa", 9), "2": ("ac", 9)}})
    c = _run(tmp_path, "c.json", {"k 1mm": {"1": ("ac", 9), "2": ("ac", 9)}})
    assert be.compare([a], [b]) == 1
    assert be.compare([a], [c]) == 1


def test_a_results_file_that_cannot_be_compared_exits_2(tmp_path, bench_script, capsys):
    """A maintainer's QA run (stop 50): an unreadable results file exited 1, the code of a
    regression; mpz bench gives 2."""
    be = bench_script("bench_encode")
    a = _run(tmp_path, "a.json", {"c3d/x.c3d 1mm": SAME})
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    assert be.main(["--compare", str(a), "--against", str(bad)]) == 2
    assert "cannot read it as JSON" in capsys.readouterr().err
