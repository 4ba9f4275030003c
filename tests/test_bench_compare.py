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
