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
