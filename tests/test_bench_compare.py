"""mpz bench --compare flags ratio drops, bound violations and slow-downs."""
import json

from mpz.tools import mpz_cli
from mpz.tools.cmd_bench import compare


def rows(**over):
    base = {"file": "a", "E": 1.0, "mpz_ratio": 20.0, "max": 0.9, "enc_s": 1.0, "dec_s": 0.1}
    base.update(over)
    return {(base["file"], base["E"]): base}


def test_compare_rules():
    assert compare(rows(), rows()) == []
    assert "ratio dropped" in compare(rows(), rows(mpz_ratio=19.0))[0][1]
    assert compare(rows(), rows(mpz_ratio=19.9)) == []              # within 1 %
    assert "bound violated" in compare(rows(), rows(max=1.01))[0][1]
    assert "slower" in compare(rows(), rows(enc_s=1.5))[0][1]
    assert compare(rows(), rows(enc_s=1.2)) == []                    # within noise
    assert "missing" in compare(rows(), rows(file="b"))[0][1]


def test_cli_exit_codes(tmp_path, capsys):
    old, new = tmp_path / "old.json", tmp_path / "new.json"
    r = list(rows().values())
    old.write_text(json.dumps({"schema": 1, "rows": r}))
    new.write_text(json.dumps({"schema": 1, "rows": [dict(r[0], mpz_ratio=10.0)]}))
    assert mpz_cli.main(["bench", "--compare", str(old), str(old)]) == 0
    assert mpz_cli.main(["bench", "--compare", str(old), str(new)]) == 1
    assert "REGRESSION a E=1.0: ratio dropped" in capsys.readouterr().out
    (tmp_path / "bad.json").write_text("{}")
    assert mpz_cli.main(["bench", "--compare", str(old), str(tmp_path / "bad.json")]) == 2


def test_cli_refuses_json_nested_too_deeply(tmp_path, capsys):
    """100,000 nested brackets raised RecursionError: exit 70 where an unreadable result
    file is exit 2 (a QA run of stop 53)."""
    deep = tmp_path / "deep.json"
    deep.write_text('{"schema": 1, "rows": ' + "[" * 100_000 + "]" * 100_000 + "}")
    ok = tmp_path / "ok.json"
    ok.write_text(json.dumps({"schema": 1, "rows": list(rows().values())}))
    assert mpz_cli.main(["bench", "--compare", str(deep), str(ok)]) == 2
    assert "JSON nested too deeply" in capsys.readouterr().err


def test_cli_refuses_malformed_rows_and_figures_that_would_pass_every_check(tmp_path, capsys):
    """QA, stop 33: valid JSON of the wrong shape gave tracebacks (exit 1, "regressions");
    a NaN figure or a NaN / inf tolerance made every check false: '0 regression(s)', exit
    0, for a run whose ratio halved. Now exit 2 for the files, 64 for the options."""
    import pytest
    r = list(rows().values())[0]
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"schema": 1, "rows": [r, dict(r, E="op"), dict(r, E=None)]}))
    assert mpz_cli.main(["bench", "--compare", str(old), str(old)]) == 0   # op and lossy rows
    bad = {"list": [], "rows not a list": {"schema": 1, "rows": {}},
           "row not a dict": {"schema": 1, "rows": [3]},
           "no file": {"schema": 1, "rows": [{k: v for k, v in r.items() if k != "file"}]},
           "no ratio": {"schema": 1, "rows": [{"file": "a", "E": 1}]},
           "E a list": {"schema": 1, "rows": [dict(r, E=[1])]},
           "negative time": {"schema": 1, "rows": [dict(r, enc_s=-1.0)]},
           "ratio a string": {"schema": 1, "rows": [dict(r, mpz_ratio="20")]}}
    for what, doc in bad.items():
        f = tmp_path / "new.json"
        f.write_text(json.dumps(doc))
        assert mpz_cli.main(["bench", "--compare", str(old), str(f)]) == 2, what
    for figure in ("mpz_ratio", "max", "enc_s"):
        f = tmp_path / "nan.json"
        f.write_text(json.dumps({"schema": 1, "rows": [dict(r, **{figure: float("nan")})]}))
        assert mpz_cli.main(["bench", "--compare", str(old), str(f)]) == 2, figure
        assert "NaN" in capsys.readouterr().err
    for tol in ("nan", "inf", "-0.5", "x"):
        with pytest.raises(SystemExit) as ei:
            mpz_cli.main(["bench", "--compare", str(old), str(old), "--ratio-tolerance", tol])
        assert ei.value.code == 64, tol



# -- QA 45 (items 5 and 14): the checks `mpz bench --compare` missed; expected figures
# -- worked out by hand from the rows below
def _write(tmp_path, name, *rs):
    f = tmp_path / name
    f.write_text(json.dumps({"schema": 1, "rows": list(rs)}))
    return str(f)


def test_operating_point_row_is_bound_checked():
    """The "op" row is a bounded 6.5 mm encode: a max error of 9.0 breaks it (the old code
    checked only numeric E). A row's own "bound" is used when it has one."""
    ok = rows(E="op", max=6.5)
    assert compare(ok, ok) == []
    flags = compare(ok, rows(E="op", max=9.0))
    assert flags == [(("a", "op"), "bound violated: max error 9.0 > 6.5")]
    flags = compare(rows(E="x", bound=2.0, max=1.9), rows(E="x", bound=2.0, max=2.0001))
    assert flags == [(("a", "x"), "bound violated: max error 2.0001 > 2.0")]


def test_bound_violation_prints_the_digits_that_break_it():
    """1.0001 > 1.0 printed as 'max error 1 > 1.0' with .4g."""
    flags = compare(rows(), rows(max=1.0001))
    assert flags == [(("a", 1.0), "bound violated: max error 1.0001 > 1.0")]


def test_lossy_row_distortion_is_checked():
    """An unbounded row: ARMS 3.66 -> 20 and max 20 -> 200 with the ratio up 10 % passed.
    The default tolerance is 1 %: 3.66 x 1.01 = 3.6966, so 3.69 passes and 3.70 does not."""
    old = rows(E=None, arms=3.66, max=20.0)
    flags = compare(old, rows(E=None, mpz_ratio=22.0, arms=20.0, max=200.0))
    assert flags == [(("a", None), "ARMS grew 3.6600 -> 20.0000"),
                     (("a", None), "max error grew 20.0000 -> 200.0000")]
    assert compare(old, rows(E=None, arms=3.69, max=20.0)) == []
    assert [p for _, p in compare(old, rows(E=None, arms=3.70, max=20.0))] == [
        "ARMS grew 3.6600 -> 3.7000"]
    # a bounded row may trade distortion within its bound: not a regression
    assert compare(rows(arms=0.5), rows(arms=0.6)) == []


def test_time_floor_is_a_growth_in_seconds_not_a_minimum_time():
    """A decode 0.006 -> 0.5 s (80x) was skipped because the old time was under 50 ms.
    A time is flagged when it grows by more than 25 % and by more than the floor: with
    0.05 s, 0.006 -> 0.009 (+50 %, +3 ms) and 0.100 -> 0.140 (+40 %, +40 ms) are noise,
    0.100 -> 0.160 (+60 %, +60 ms) is not. The default floor was 5 ms from stop 48 (a
    decoder three times slower, 7 -> 21 ms, went unflagged under 0.05 s), and is 1 ms
    since stop 53 (the real files decode in about 1 ms: 0.73-1.24 -> 2.3-3.67 ms, three
    times slower, went unflagged under 5 ms, a QA run)."""
    assert [p for _, p in compare(rows(dec_s=0.006), rows(dec_s=0.5), time_floor=0.05)] == [
        "decoding slower 0.006 s -> 0.500 s"]
    assert compare(rows(dec_s=0.006), rows(dec_s=0.009), time_floor=0.05) == []
    assert compare(rows(enc_s=0.100), rows(enc_s=0.140), time_floor=0.05) == []
    assert [p for _, p in compare(rows(enc_s=0.100), rows(enc_s=0.160),
                                  time_floor=0.05)] == ["encoding slower 0.100 s -> 0.160 s"]
    assert [p for _, p in compare(rows(dec_s=0.007), rows(dec_s=0.021))] == [
        "decoding slower 0.007 s -> 0.021 s"]
    assert [p for _, p in compare(rows(dec_s=0.0012), rows(dec_s=0.0036))] == [
        "decoding slower 0.001 s -> 0.004 s"]
    assert compare(rows(dec_s=0.0012), rows(dec_s=0.0019)) == []       # +0.7 ms: noise


def test_cpu_seconds_are_compared_when_both_runs_have_them():
    """Two back-to-back runs of the same code on a loaded machine: the wall-clock best of
    three went 0.141 -> 0.432 s while the CPU time stayed. With enc_cpu_s on both sides
    that is compared: 0.20 -> 0.21 (+5 %) is no regression whatever the wall clock did;
    0.20 -> 0.30 (+50 %, +0.1 s) is, and is named as CPU time."""
    old = rows(enc_s=0.141, enc_cpu_s=0.20)
    assert compare(old, rows(enc_s=0.432, enc_cpu_s=0.21)) == []
    assert [p for _, p in compare(old, rows(enc_s=0.141, enc_cpu_s=0.30))] == [
        "encoding slower (CPU) 0.200 s -> 0.300 s"]
    # one side without CPU seconds: the wall clock, as before (0.141 -> 0.432: +206 %)
    assert [p for _, p in compare(rows(enc_s=0.141), rows(enc_s=0.432, enc_cpu_s=0.2))] == [
        "encoding slower 0.141 s -> 0.432 s"]


def test_duplicate_rows_and_unbounded_checks_are_refused(tmp_path, capsys):
    """Two rows with the same (file, E): the last one won silently. A bounded row without
    max skipped its bound check silently. Both are now unreadable input (exit 2)."""
    r = list(rows().values())[0]
    good = _write(tmp_path, "good.json", r)
    dup = _write(tmp_path, "dup.json", r, dict(r, max=0.5))
    assert mpz_cli.main(["bench", "--compare", good, dup]) == 2
    assert "rows 0 and 1 are both file 'a' at E=1.0" in capsys.readouterr().err
    nomax = _write(tmp_path, "nomax.json", {k: v for k, v in r.items() if k != "max"})
    assert mpz_cli.main(["bench", "--compare", good, nomax]) == 2
    assert "no max error" in capsys.readouterr().err
    # an unbounded row needs none
    lossy = _write(tmp_path, "lossy.json", {"file": "a", "E": None, "mpz_ratio": 8.0})
    assert mpz_cli.main(["bench", "--compare", lossy, lossy]) == 0


def test_dash_reads_standard_input(tmp_path, monkeypatch, capsys):
    """README: '-' means standard input everywhere; it gave '-: no such file'."""
    import io
    import types

    import pytest
    r = list(rows().values())[0]
    old = _write(tmp_path, "old.json", r)
    half = json.dumps({"schema": 1, "rows": [dict(r, mpz_ratio=10.0)]}).encode()
    monkeypatch.setattr("sys.stdin", types.SimpleNamespace(buffer=io.BytesIO(half)))
    assert mpz_cli.main(["bench", "--compare", old, "-"]) == 1        # 20 -> 10: -50 %
    assert "ratio dropped 20.00 -> 10.00 (-50.0 %)" in capsys.readouterr().out
    monkeypatch.setattr("sys.stdin", types.SimpleNamespace(buffer=io.BytesIO(half)))
    assert mpz_cli.main(["bench", "--compare", "-", old]) == 0        # 10 -> 20: no drop
    with pytest.raises(SystemExit) as ei:
        mpz_cli.main(["bench", "--compare", "-", "-"])
    assert ei.value.code == 64


def test_ratio_tolerance_must_be_a_fraction_below_one(tmp_path):
    """--ratio-tolerance 1.5 was accepted and switched the ratio check off (a ratio cannot
    drop by 150 %); 1 and 0 are outside (0, 1) too."""
    import pytest
    old = _write(tmp_path, "old.json", list(rows().values())[0])
    for tol in ("1.5", "1", "0"):
        with pytest.raises(SystemExit) as ei:
            mpz_cli.main(["bench", "--compare", old, old, "--ratio-tolerance", tol])
        assert ei.value.code == 64, tol
    assert mpz_cli.main(["bench", "--compare", old, old, "--ratio-tolerance", "0.5"]) == 0

# ------------------------------------------------ bench/bench_encode.py --compare --
def _bench_encode(monkeypatch):
    """``bench/bench_encode.py``, imported from its path (bench/ is not a package)."""
    import importlib.util
    from pathlib import Path
    bench = Path(__file__).resolve().parents[1] / "bench"
    monkeypatch.syspath_prepend(str(bench))            # its `from _common import ...`
    spec = importlib.util.spec_from_file_location("mpz_bench_encode", bench / "bench_encode.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _encode_run(tmp_path, name, **rows):
    """A bench_encode.py result: rows key -> (sha256, bytes, {threads: seconds})."""
    doc = {"bench": "encode", "schema": 1, "threads": [1, 2], "rows": {
        k: {"bound": "1mm", "sha256": sha, "bytes": n, "seconds": secs}
        for k, (sha, n, secs) in rows.items()}}
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


def test_encode_compare_reports_changed_bytes_and_times(tmp_path, capsys, monkeypatch):
    """The maintainers' check of an encoder change (issue 15: "identical output or a
    measured, reported ratio change"): exit 0 when every encode kept its bytes, 1 with the
    sizes when some changed; times are each side's best over its runs and thread counts."""
    be = _bench_encode(monkeypatch)
    a1 = _encode_run(tmp_path, "a1.json", x=("aa", 1000, {"1": 0.020, "2": 0.015}),
                     y=("bb", 500, {"1": 0.010, "2": 0.008}))
    a2 = _encode_run(tmp_path, "a2.json", x=("aa", 1000, {"1": 0.018, "2": 0.016}),
                     y=("bb", 500, {"1": 0.012, "2": 0.009}))
    b1 = _encode_run(tmp_path, "b1.json", x=("aa", 1000, {"1": 0.012, "2": 0.010}),
                     y=("cc", 510, {"1": 0.010, "2": 0.0096}))
    assert be.best_times([be.load(a1), be.load(a2)]) == {"x": 0.015, "y": 0.008}
    assert be.compare([a1, a2], [a1]) == 0
    assert "all 2 encodes identical" in capsys.readouterr().out
    assert be.compare([a1, a2], [b1]) == 1
    out = capsys.readouterr().out
    assert "1 of 2 encodes changed" in out and "500 ->       510 B (+2.00 %)" in out
    assert "more than 10 % slower: y" in out                      # 8.0 -> 9.6 ms: +20 %
    assert "x " in out and "-33.3%" in out                        # 15 -> 10 ms


def test_encode_compare_refuses_what_it_cannot_judge(tmp_path, monkeypatch):
    """Two runs of one side with different bytes (a nondeterministic encoder, or runs of
    two versions mixed up) and files of another kind are errors, not a verdict."""
    import pytest
    be = _bench_encode(monkeypatch)
    a1 = _encode_run(tmp_path, "a1.json", x=("aa", 1000, {"1": 0.02}))
    a2 = _encode_run(tmp_path, "a2.json", x=("ab", 1000, {"1": 0.02}))
    with pytest.raises(SystemExit, match="two runs of the same side gave different bytes"):
        be.compare([a1, a2], [a1])
    other = tmp_path / "rd.json"
    other.write_text(json.dumps({"bench": "rd", "schema": 1, "rows": []}))
    with pytest.raises(SystemExit, match="not a bench_encode.py result"):
        be.compare([other], [a1])


def test_runs_of_different_inputs_are_not_compared(tmp_path, capsys):
    """bench_rd.py's ratios were against the whole MPZ file (a C3D's archive included)
    before it coded the marker positions alone and said so ("input"): an old baseline
    against a new run compares two different figures, so it is refused (exit 2)."""
    r = list(rows().values())[0]
    old = _write(tmp_path, "old.json", r)
    new = tmp_path / "new.json"
    new.write_text(json.dumps({"schema": 1, "input": "marker positions only", "rows": [r]}))
    assert mpz_cli.main(["bench", "--compare", old, str(new)]) == 2
    assert "different inputs" in capsys.readouterr().err
    assert mpz_cli.main(["bench", "--compare", str(new), str(new)]) == 0


def test_changes_below_the_tolerances_and_improvements_are_listed(tmp_path, capsys):
    """A QA run of stop 48: an encoder change that moved most file sizes by -0.5 .. +0.7 %
    printed "18 rows compared, 0 regression(s)", as two runs of the same code do, and a
    20 % better ratio or a 30 % higher ARMS of a bounded row printed nothing. They are
    listed as CHANGED (exit 0: no regression), rows without a partner are not counted as
    compared, and other data under the same name is refused."""
    base = dict(list(rows().values())[0], bytes=1000, raw=20000, arms=0.3)
    old = _write(tmp_path, "old.json", base, dict(base, file="b"))
    new = _write(tmp_path, "new.json", dict(base, bytes=1005, mpz_ratio=20000 / 1005),
                 dict(base, file="b", arms=0.39), dict(base, file="c"))
    assert mpz_cli.main(["bench", "--compare", old, new]) == 0
    out = capsys.readouterr().out
    assert "CHANGED a E=1.0: 1000 -> 1005 B (+0.50 %)" in out
    assert "CHANGED b E=1.0: ARMS 0.3 -> 0.39 (+30.00 %)" in out
    assert "2 rows compared, 1 without a row in the old run; 0 regression(s), 2 changed" in out
    assert mpz_cli.main(["bench", "--compare", old, old]) == 0
    assert "0 changed" in capsys.readouterr().out
    other = _write(tmp_path, "other.json", dict(base, raw=30000, mpz_ratio=30.0))
    assert mpz_cli.main(["bench", "--compare", old, other]) == 2
    assert "other data under the same names" in capsys.readouterr().err


def test_times_of_runs_on_two_machines_are_not_compared(tmp_path, capsys):
    """A QA run of stop 48: a baseline from another machine flagged every time as a
    regression, with no hint. bench_rd.py now records where it ran; two hosts' times are
    left out, said in a note; one host's are compared as before."""
    r = dict(list(rows().values())[0], enc_s=1.0)
    slow = dict(r, enc_s=3.0)

    def run_file(name, row, host):
        f = tmp_path / name
        f.write_text(json.dumps({"schema": 1, "host": host, "machine": "x86_64",
                                 "rows": [row]}))
        return str(f)
    old = run_file("old.json", r, "laptop")
    assert mpz_cli.main(["bench", "--compare", old, run_file("a.json", slow, "ci")]) == 0
    out = capsys.readouterr().out
    assert "different machines (host 'laptop' and 'ci'): their times are not compared" in out
    assert mpz_cli.main(["bench", "--compare", old, run_file("b.json", slow, "laptop")]) == 1
    assert "encoding slower 1.000 s -> 3.000 s" in capsys.readouterr().out


# -- a maintainer's QA run of stop 50 ---------------------------------------------------------

def test_the_version_benches_import_nothing_of_mpz_from_their_shared_helpers():
    """bench_rd.py, bench_encode.py and bench_decode.py are run with an older version
    installed (README): bench/_common.py imported mpz.tools._cli.whole_number, which 515 of
    593 revisions lack, so every such run ended in an ImportError. _common may use mpz
    only inside functions, through the public API."""
    import ast
    from pathlib import Path
    tree = ast.parse((Path(__file__).resolve().parents[1] / "bench" / "_common.py")
                     .read_text())
    top = [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))]
    names = [a.name for n in top if isinstance(n, ast.Import) for a in n.names]
    names += [n.module or "" for n in top if isinstance(n, ast.ImportFrom)]
    assert top and not [m for m in names if m.split(".")[0] == "mpz"], names


def test_bench_rd_meets_no_target_with_a_broken_bound(bench_script, capsys):
    """bench_rd.py printed "MPZ bound violations: 10" and, for the same rows, "MET" for
    both ratio targets (exit 0): a ratio reached by breaking the bound is no ratio at it."""
    rd = bench_script("bench_rd")
    row = {"file": "a", "E": 1.0, "mm_per_unit": 1.0, "vs_qpz": 2.0, "vs_qpz16": 2.0,
           "ok": True}
    rd.report([row])
    assert "geometric mean 2.00 (target 1.5) MET" in capsys.readouterr().out
    rd.report([row, dict(row, file="b", ok=False)])
    out = capsys.readouterr().out
    assert "MET" not in out and "MISSED: 1 file(s) broke the bound" in out, out
    op = {"file": "a", "E": "op", "mm_per_unit": 1.0, "mpz_ratio": 130.1, "arms": 3.9,
          "ok": True}
    rd.report([op])                    # better than the paper's point is not a miss
    assert "paper operating point, ARMS 4-6 mm, >= 25:1 vs float32: MET" in \
        capsys.readouterr().out
    rd.report([dict(op, ok=False)])
    assert "vs float32: MISSED" in capsys.readouterr().out


def test_bench_rd_exits_1_when_the_codec_broke_its_bound(bench_script, tmp_path,
                                                        monkeypatch, capsys):
    """A maintainers' QA run: bench_rd.py printed "MPZ bound violations: 15" and exited 0,
    so a script of runs went on; only mpz bench --compare turned it into a failure."""
    rd = bench_script("bench_rd")
    row = {"file": "a", "E": 1.0, "mm_per_unit": 1.0, "vs_qpz": 2.0, "vs_qpz16": 2.0,
           "ok": True}
    monkeypatch.setattr(rd, "shared_data", lambda: tmp_path)
    monkeypatch.setattr(rd, "find_recording", lambda root, name: tmp_path / "a.c3d")
    for rows, code in (([row], 0), ([row, dict(row, file="b", ok=False)], 1)):
        monkeypatch.setattr(rd, "run", lambda files, bounds, repeat, rows=rows: rows)
        assert rd.main(["--files", "c3d/a"]) == code
    assert "MPZ bound violations: 1" in capsys.readouterr().out


def test_bench_rd_refuses_a_json_path_it_cannot_write_before_measuring(bench_script,
                                                                       tmp_path, capsys):
    """`bench_rd.py --json /tmp` measured every file, then ended in IsADirectoryError (a
    missing folder: FileNotFoundError), losing the run."""
    rd = bench_script("bench_rd")
    assert rd.main(["--files", "c3d/cmu_02_01", "--json", str(tmp_path)]) == 2
    assert "a folder" in capsys.readouterr().err
    assert rd.main(["--files", "c3d/cmu_02_01", "--json", str(tmp_path / "no" / "x.json")]) == 2
    assert "no folder" in capsys.readouterr().err


def test_compare_names_what_it_cannot_check(tmp_path, capsys):
    """A row without E was taken for the lossy row; rows without a raw size skipped the
    same-data check without a word; a new row without an old one was counted, not named;
    lossy rows printed as E=None; with --json the notes were lost."""
    base = dict(list(rows().values())[0], bytes=1000, raw=20000, arms=0.3)
    old = _write(tmp_path, "old.json", base, dict(base, E=None))
    no_e = _write(tmp_path, "noe.json", {k: v for k, v in base.items() if k != "E"})
    assert mpz_cli.main(["bench", "--compare", old, no_e]) == 2
    assert "E: a bound, a label or null for lossy" in capsys.readouterr().err
    new = _write(tmp_path, "new.json", {k: v for k, v in base.items() if k != "raw"},
                 dict(base, E=None, mpz_ratio=10.0), dict(base, file="c"))
    assert mpz_cli.main(["bench", "--compare", old, new]) == 1
    out = capsys.readouterr().out
    assert "REGRESSION a E=lossy: ratio dropped" in out
    assert "1 row(s) have no raw size in one of the runs (the first a E=1.0)" in out
    assert "1 row(s) of the new run have no row in the old run: c E=1.0" in out
    assert mpz_cli.main(["bench", "--compare", old, new, "--json"]) == 1
    got = capsys.readouterr()
    doc = json.loads(got.out)
    assert doc["schema"] == "mpz-bench-compare/1" and doc["compared"] == 2
    assert doc["regressions"][0] == {"file": "a", "E": None,
                                     "problem": "ratio dropped 20.00 -> 10.00 (-50.0 %)"}
    assert doc["unmatched"] == [{"file": "c", "E": 1.0}]
    assert any("no row in the old run: c E=1.0" in n for n in doc["notes"])
    assert "no row in the old run: c E=1.0" in got.err


def test_rows_of_another_bound_or_unit_and_huge_numbers(tmp_path, capsys):
    """A QA run of stop 53: a row whose bound went 1.0 -> 0.1 (its reader took other
    units, mm_per_unit 1 -> 10) was compared without a word; an int of 10**400 in a row
    ended in OverflowError, exit 70; and a comparison of no row at all exited 0."""
    problems = [p for _, p in compare(rows(bound=1.0, mm_per_unit=1.0),
                                      rows(bound=0.1, mm_per_unit=10.0, max=0.09))]
    assert problems == [
        "bound changed 1.0 -> 0.1: the rows measure another question (a reader that takes "
        "other units?)",
        "mm_per_unit changed 1.0 -> 10.0: the rows measure another question (a reader that "
        "takes other units?)"]
    old_doc = {"schema": 1, "rows": [dict(rows()[("a", 1.0)], file="a", E=1.0)]}
    huge = json.loads(json.dumps(old_doc))
    huge["rows"][0]["bytes"] = 10 ** 400
    (tmp_path / "old.json").write_text(json.dumps(old_doc))
    (tmp_path / "huge.json").write_text(json.dumps(huge))
    code = mpz_cli.main(["bench", "--compare", str(tmp_path / "old.json"),
                         str(tmp_path / "huge.json")])
    assert code == 2 and "Traceback" not in capsys.readouterr().err
    (tmp_path / "empty.json").write_text(json.dumps({"schema": 1, "rows": []}))
    code = mpz_cli.main(["bench", "--compare", str(tmp_path / "empty.json"),
                         str(tmp_path / "old.json")])
    out = capsys.readouterr().out
    assert code == 1 and "no row was compared" in out and "0 rows compared" in out


def test_find_recording_takes_every_form_of_a_name(tmp_path, monkeypatch):
    """bench's --files takes a name with or without its folder and extension; a bare name
    with its extension (cmu_02_01.c3d) was looked for as cmu_02_01.c3d.c3d and never
    found (a maintainer's QA run of stop 55). A name that matches nothing is None."""
    import importlib.util
    from pathlib import Path
    bench = Path(__file__).resolve().parents[1] / "bench"
    monkeypatch.syspath_prepend(str(bench))
    spec = importlib.util.spec_from_file_location("mpz_bench_common", bench / "_common.py")
    assert spec is not None and spec.loader is not None
    common = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(common)
    (tmp_path / "c3d").mkdir()
    (tmp_path / "amc").mkdir()
    c3d = tmp_path / "c3d" / "walk.c3d"
    amc = tmp_path / "amc" / "walk.amc"
    c3d.write_bytes(b"x")
    amc.write_bytes(b"x")
    for name, want in (("walk.c3d", c3d), ("walk.amc", amc), ("c3d/walk", c3d),
                       ("amc/walk.amc", amc), ("c3d/walk.c3d", c3d), ("WALK.bvh", None),
                       ("run", None)):
        assert common.find_recording(tmp_path, name) == want, name
    assert common.find_recording(tmp_path, "walk") in (c3d, amc)
