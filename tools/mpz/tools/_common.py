"""Helpers shared by the command-line tools (not part of the public API)."""
from __future__ import annotations

import re
import sys
import time

from mpz.errors import EncoderError

_UNIT_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}


def parse_length(text: str, units: str) -> float:
    """'2mm', '0.2 cm', '0.002m' or a bare number (the motion's own units) -> motion units."""
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([a-z]*)\s*", text)
    if not m:
        raise EncoderError(f"cannot read a length from {text!r}; write e.g. 2mm, 0.5cm or 1.5")
    value, unit = float(m.group(1)), m.group(2)
    if not unit:
        return value
    if unit not in _UNIT_MM:
        raise EncoderError(f"unknown unit {unit!r} in {text!r}; use mm, cm, m or in")
    if units not in _UNIT_MM:
        raise EncoderError(f"the input has no known units, so give {text!r} without a unit")
    return value * _UNIT_MM[unit] / _UNIT_MM[units]


def human_size(n: int) -> str:
    for unit, div in (("GB", 1 << 30), ("MB", 1 << 20), ("KB", 1 << 10)):
        if n >= div:
            return f"{n / div:.1f} {unit}"
    return f"{n} B"


class Progress:
    """A one-line progress bar on stderr, shown only when stderr is a terminal."""

    def __init__(self, label: str, enabled: bool | None = None):
        self.label = label
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.t0 = time.perf_counter()

    def __call__(self, fraction: float, message: str = "") -> None:
        if not self.enabled:
            return
        width = 30
        done = int(width * max(0.0, min(1.0, fraction)))
        bar = "#" * done + "-" * (width - done)
        sys.stderr.write(f"\r{self.label} [{bar}] {fraction:4.0%} {message[:24]:<24} "
                         f"{time.perf_counter() - self.t0:5.1f}s")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()


def read_motion(path: str, asf: str | None = None):
    """Any supported input, .mpz included."""
    if str(path).lower().endswith(".mpz"):
        from mpz.api import read_mpz
        return read_mpz(path)
    from mpz.io import read
    return read(path, asf=asf)
