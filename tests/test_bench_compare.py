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
