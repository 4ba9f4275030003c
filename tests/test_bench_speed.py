"""bench/bench_speed.py's verdict lines name every row below issue 15.1's two yardsticks:
the encode at 2x zstd -19 and the decode at 0.1x zstd -19's decompression, both timed in
alternation with zstd on the same bytes (docs/speed.md, "Where it stands"). The verdict
needs no peer, so these run without the bench extra too (CI)."""
from __future__ import annotations


def _row(name: str, x_zstd: float, dec_x: float) -> dict:
    """An MPZ row of bench_speed's JSON, with the figures the verdict reads."""
    return {"file": name, "name": name + ".c3d", "bound": "1mm", "asked": "1mm",
            "codec": "mpz", "mb": 1.0, "enc_1": 10.0, "enc_2": 20.0, "sec_1": 0.1,
            "sec_2": 0.05, "dec": 100.0, "x_zstd": x_zstd, "x_zstd_mk": x_zstd,
            "zstd_s": 0.2, "dec_x_zstd": dec_x, "E": 1.0, "max_err": 0.5}


def test_decode_rows_below_a_tenth_of_zstd_are_named(bench_script, capsys):
    bench = bench_script("bench_speed")
    bench.verdict([_row("fast", 3.0, 0.25), _row("slow", 2.5, 0.04),
                   _row("edge", 2.0, 0.1)], [1, 2])
    lines = capsys.readouterr().out.splitlines()
    line = next(x for x in lines if x.startswith("issue 15, decode every row"))
    assert "2 of 3 at 0.1x or more" in line
    assert line.endswith("below: slow.c3d 1mm (0.040x)")


def test_every_decode_row_at_a_tenth_of_zstd_names_none(bench_script, capsys):
    bench = bench_script("bench_speed")
    bench.verdict([_row("a", 3.0, 0.5), _row("b", 1.5, 0.2)], [1, 2])
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("issue 15, decode every row"))
    assert line.endswith("2 of 2 at 0.1x or more")
    assert "below: b.c3d 1mm (1.50x)" in out          # the encode line still names b
