"""mpzinfo's size ratio (QA 45c, D4): labelled for what it compares (the markers as float32,
12 bytes a marker-frame, against the whole file, as mpz encode's "ratio vs float32"), the
file's bytes by part, no ratio for a file in error, and MHDR fields whose CRC failed marked
unverified; a WARN line gives its reason. Expected values are worked out by hand from the
file's size and its F x M."""
from __future__ import annotations

from pathlib import Path
import subprocess
import sys

import mpz
from mpz.synth import generate
from mpz.tools.mpzinfo import inspect, summary_line

REPO = Path(__file__).resolve().parents[1]
U06 = REPO / "conformance" / "vectors" / "uncommon" / "u06-unknown-ancillary-zzzz.mpz"


def _walk() -> bytes:
    return mpz.encode(generate("walk", frames=40), max_error=1.0)


def test_ratio_is_markers_float32_over_the_file_and_labelled():
    data = _walk()
    info = inspect(data, "w.mpz")
    assert info["ratio"] == 12 * 40 * 41 / len(data)            # walk: 41 markers
    assert "markers as float32" in info["ratio_of"] and "whole file" in info["ratio_of"]
    parts = info["bytes_by_part"]
    assert sum(parts.values()) == len(data) and parts["analog"] == 0
    assert "markers 19.2 KiB as float32 \u2192 file" in summary_line(info)   # 19680 B


def test_a_file_in_error_gets_no_ratio():
    data = _walk()
    for cut in (51, 1000, len(data) - 1):
        info = inspect(data[:cut], "cut.mpz")
        assert info["status"] == "error"
        assert info["ratio"] is None and info["bytes_by_part"] is None
        assert ":1" not in summary_line(info)


def test_fields_of_an_mhdr_with_a_bad_crc_are_marked():
    data = bytearray(_walk())
    data[20] ^= 0x01               # inside MHDR's payload (it starts at byte 16)
    info = inspect(bytes(data), "flip.mpz")
    assert info["status"] == "error" and info["header_crc_ok"] is False
    assert "MHDR CRC bad, unverified" in summary_line(info)
    assert inspect(_walk(), "w.mpz")["header_crc_ok"] is True


def test_parts_of_a_c3d_with_analog(tmp_path, shared_data):
    exe = Path(sys.executable).parent / "mpz"
    src = shared_data / "c3d" / "c3dorg_Eb015pi.c3d"
    subprocess.run([str(exe), "encode", str(src), "-o", str(tmp_path / "e.mpz"), "-q"],
                   check=True, timeout=300)
    data = (tmp_path / "e.mpz").read_bytes()
    info = inspect(data, "e.mpz")
    # the cana chunk, by walking the frames by hand: type, length (LE), payload, crc
    pos, cana = 8, 0
    while pos < len(data):
        n = int.from_bytes(data[pos + 4:pos + 8], "little")
        if data[pos:pos + 4] == b"cana":
            cana += n + 12
        pos += n + 12
    assert cana > 0 and info["bytes_by_part"]["analog"] == cana
    assert f"analog {cana / 1024:.1f} KiB" in summary_line(info)


def test_a_warning_line_gives_its_reason():
    info = inspect(U06.read_bytes(), "u06.mpz")
    line = summary_line(info)
    assert line.startswith("WARN:") and "unknown ancillary chunk 'qqqq'" in line
