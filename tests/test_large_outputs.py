"""Writing and reading large motions without a copy of them per step (a QA run of stop 53
measured 2^24 marker-frames: decoding to TRC took 2.9 GB and 42 s, to CSV 2.8 GB, to C3D
2.1 GB, against 1.0 GB to NPY; mpz summary, compare and search had no --max-samples).
Peak memory is measured in bench/, not here: these tests check that the block-wise and
streamed paths give the text and notes that a hand count gives, and that the new limits
refuse a file."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import mpz
import mpz.io
from mpz.io import rounding_notes
from mpz.io.table import format_csv, write_csv
from mpz.io.trc import format_trc, write_trc
from mpz.motion import Motion
from mpz.synth import generate


def _off_grid(frames: int = 10) -> Motion:
    """3 markers whose x is 4.9e-7 off the 6-decimal grid (TRC rounds it by 4.9e-7), one
    sample a gap."""
    pos = np.zeros((frames, 3, 3))
    pos[:, :, 0] = np.arange(frames * 3).reshape(frames, 3) + 4.9e-7
    valid = np.ones((frames, 3), bool)
    valid[2, 1] = False
    return Motion(pos, ["A", "B", "C"], 100.0, "mm", valid)


@pytest.mark.parametrize("block", [1, 4, 1 << 18])
def test_rounding_notes_count_every_block(block: int, monkeypatch) -> None:
    """29 valid samples, each rounded by 4.9e-7 mm by TRC's 6 decimals, whatever the
    blocks of frames they are measured in (one frame a block for block < 3 markers)."""
    monkeypatch.setattr(mpz.io, "ROUNDING_BLOCK", block)
    m = _off_grid()
    notes = rounding_notes(m, ".trc", None)
    assert notes == ["TRC is written with 6 decimals: 29 of 29 valid samples change, by up "
                     "to 4.9e-07 mm; write .csv or .npy for the exact values"]
    # a bound of 0 (exact) leaves nothing: every one of them is beyond it
    assert "at 29 of 29 valid samples" in rounding_notes(m, ".trc", 0.0)[0]
    assert rounding_notes(m, ".trc", 1.0) == []         # far below the bound's share


def test_streamed_trc_and_csv_are_the_formatted_text(tmp_path: Path) -> None:
    """write_trc and write_csv write their lines in batches of 4096; the file is
    format_trc's and format_csv's text, over more than one batch and with gaps."""
    m = generate("walk", frames=5000, seed=3)
    valid = m.valid.copy()
    valid[::7, 2] = False
    m = Motion(m.positions, m.names, m.rate, m.units, valid)
    write_trc(m, tmp_path / "w.trc")
    text = (tmp_path / "w.trc").read_text(encoding="utf-8")
    assert text == format_trc(m, file_name="w.trc")
    assert text.count("\n") == 6 + 5000
    rows = text.split("\n")[6:-1]
    assert rows[7].split("\t")[2 + 6:2 + 9] == ["", "", ""]       # marker 2 of frame 7
    write_csv(m, tmp_path / "w.csv")
    csv_text = (tmp_path / "w.csv").read_text(encoding="utf-8")
    assert csv_text == format_csv(m) and csv_text.count("\n") == 1 + 5000
    assert mpz.io.read(tmp_path / "w.csv").positions[1, 0, 0] == m.positions[1, 0, 0]


def test_summary_compare_and_search_take_max_samples(tmp_path: Path, capsys) -> None:
    from mpz.corpus import encode_corpus, mirror_jobs
    from mpz.encoder import EncodeOptions
    from mpz.tools import mpz_cli
    src = tmp_path / "src"
    src.mkdir()
    m = generate("walk", frames=120, seed=1)                  # 120 x 41 = 4920
    mpz.io.write(m, src / "walk.trc")
    out = tmp_path / "out"
    encode_corpus(mirror_jobs(src, out), out, EncodeOptions(max_error=1.0), workers=0)
    f = str(out / "walk.mpz")
    for argv in (["summary", f], ["compare", f, f], ["search", f, "--index", str(out)]):
        code = mpz_cli.main([*argv, "--max-samples", "4919"])
        err = capsys.readouterr().err
        assert code == 2 and "= 4920 exceeds the limit 4919 (§8)" in err, (argv, err)
        code = mpz_cli.main([*argv, "--max-samples", "4920", "--json"])
        doc = json.loads(capsys.readouterr().out)
        assert code == 0 and doc, argv


def test_summary_no_decode_keeps_max_samples(tmp_path: Path, capsys) -> None:
    """--no-decode reads the summary chunk alone, and took a file of any size (a review of
    stop 53)."""
    from mpz.tools import mpz_cli
    f = tmp_path / "w.mpz"
    f.write_bytes(mpz.encode(generate("walk", frames=100, seed=2), summary=(4, 8)))  # 4100
    code = mpz_cli.main(["summary", str(f), "--no-decode", "--max-samples", "4099"])
    err = capsys.readouterr().err
    assert code == 2 and "= 4100 exceeds the limit 4099 (§8)" in err, err
    code = mpz_cli.main(["summary", str(f), "--no-decode", "--max-samples", "4100", "--json"])
    assert code == 0 and [lv["k"] for lv in json.loads(capsys.readouterr().out)["levels"]] \
        == [4, 8]
