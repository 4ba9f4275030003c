"""Marker-name matching shared by the builders, weights and the head scale.

Contract: a name given by a hierarchy file, a weight or the CMU template
matches a marker of the motion exactly, or after stripping a ``"Subject:"``
prefix (everything up to the last ``:``) when the stripped name is
unambiguous. Nothing here raises.
"""
from __future__ import annotations

from collections.abc import Iterable


def strip_subject(name: str) -> str:
    """``"Subject:LFHD"`` -> ``"LFHD"`` (everything up to the last ``:`` removed)."""
    return str(name).rsplit(":", 1)[-1]


def name_lookup(names: Iterable[object]) -> dict[str, int]:
    """Exact names, plus stripped names where they are unambiguous."""
    text = [str(n) for n in names]
    lookup = {n: i for i, n in enumerate(text)}
    stripped: dict[str, list[int]] = {}
    for i, n in enumerate(text):
        stripped.setdefault(strip_subject(n), []).append(i)
    for s, idx in stripped.items():
        if len(idx) == 1 and s not in lookup:
            lookup[s] = idx[0]
    return lookup
