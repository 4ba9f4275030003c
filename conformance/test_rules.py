"""Every rule of the spec §7.4 rule index has a vector, and each vector probes its rules.

The rule index is the ``<!-- mpz:rules -->`` table of spec/mpz-1.md; the manifest lists,
for each vector, the rules it probes (written by ``python -m mpz.tools.make_vectors``).
A rule with no vector fails here unless the manifest's ``rule_exceptions`` gives the reason
and names the unit test below that covers it. Limits whose valid file would be
impractical (``limit_boundaries`` in the manifest) are tested here at the boundary itself.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
import re
import struct

import numpy as np
import pytest

import mpz
from mpz import decoder
from mpz.chunks import Context, Smry, SummaryLevel
from mpz.conformance import manifest as mf
from mpz.container import scan
from mpz.errors import LimitExceededError, MPZError
from mpz.format import (
    LIMITS,
    MAX_CHUNK_LENGTH,
    MAX_FRAMES,
    MAX_PATTERN_SAMPLES,
    MAX_SAMPLES,
    MAX_SUMMARY_VALUES,
)

REPO = Path(__file__).resolve().parents[1]
SPEC = REPO / "spec" / "mpz-1.md"
VDIR = mf.DEFAULT_DIR
MAN = mf.load(VDIR)
RULES = mf.spec_rules(SPEC.read_text(encoding="utf-8")) if SPEC.is_file() else []
KIND = {rid: kind for rid, _, kind, _ in RULES}
SECTION = {rid: sec for rid, sec, _, _ in RULES}
INVALID = [v for v in MAN["vectors"] if v["expected"] == "reject"]


def _vectors_of(rule: str) -> list[dict]:
    return [v for v in MAN["vectors"] + MAN["encoder_inputs"] if rule in v["rules"]]


def test_rule_index_parses_and_is_large():
    assert len(RULES) >= 100
    assert {k for k in KIND.values()} == set(mf.RULE_KINDS)


@pytest.mark.parametrize("rule", [r[0] for r in RULES])
def test_every_rule_has_a_vector_of_its_kind(rule):
    """reject rules need an invalid vector, accept and decode rules a decodable one,
    encode rules an encoder input; otherwise a justified exception."""
    if rule in MAN["rule_exceptions"]:
        reason = MAN["rule_exceptions"][rule]
        m = re.search(r"(conformance/test_\w+\.py)::(\w+)", reason)
        assert m, f"{rule}: the exception must name the unit test that covers it: {reason!r}"
        assert f"def {m.group(2)}(" in (REPO / m.group(1)).read_text(encoding="utf-8"), reason
        return
    vs = _vectors_of(rule)
    kind = KIND[rule]
    if kind == "reject":
        ok = [v for v in vs if v.get("expected") == "reject"]
    elif kind == "encode":
        ok = [v for v in vs if "max_errors" in v]
    else:
        ok = [v for v in vs if v.get("expected") == "decode"]
    assert ok, f"{rule} ({kind}: {dict((r[0], r[3]) for r in RULES)[rule]}) has no vector"


def test_manifest_names_only_rules_of_the_spec():
    named = {r for v in MAN["vectors"] + MAN["encoder_inputs"] for r in v["rules"]}
    named |= set(MAN["rule_exceptions"])
    assert named - set(KIND) == set()


def test_every_decodable_vector_probes_a_rule():
    """A decodable vector with no rule tells an implementer nothing about what it tests
    (v13-smrc-positions had none: it is a marker file like the others, with smrc)."""
    missing = [v["name"] for v in MAN["vectors"] if v["expected"] == "decode" and not v["rules"]]
    assert not missing


def test_every_invalid_vector_probes_a_reject_rule():
    missing = [v["name"] for v in INVALID if not any(KIND.get(r) == "reject" for r in v["rules"])]
    assert not missing


def _covers(section: str, sections: set[str]) -> bool:
    """The error's section and a probed one are the same or one contains the other: ``§4``
    (a malformed payload) for a rule of §4.4, or §4.13.3 for a rule of §4.13."""
    return any(s == section or s.startswith(section + ".") or section.startswith(s + ".")
               for s in sections)


@pytest.mark.parametrize("vec", INVALID, ids=[v["name"] for v in INVALID])
def test_invalid_vector_is_rejected_for_its_rule(vec):
    """The reference rejects each invalid vector under a section of the rules it probes (or
    of its declared sections), not through some other check: a vector whose check was
    removed from the decoder must not stay green because a later check happens to fire."""
    with pytest.raises(MPZError) as info:
        mpz.decode((VDIR / vec["file"]).read_bytes())
    sections = set(vec["spec_sections"]) | {SECTION[r] for r in vec["rules"] if r in SECTION}
    assert info.value.section and _covers(info.value.section, sections), \
        f"{vec['name']}: rejected under {info.value.section} ({info.value}), probes {sections}"


@pytest.mark.parametrize("vec", INVALID, ids=[v["name"] for v in INVALID])
def test_reference_message_is_the_recorded_one(vec):
    """The reference's diagnosis (message, chunk, offset, §) of each invalid vector is the one
    the manifest recorded when the vector was made: a decoder change that rejects the file
    by another route (for example a range decoder that reads one byte past the payload and
    only notices at close(), x170) shows up here even where the verdict is the same."""
    with pytest.raises(MPZError) as info:
        mpz.decode((VDIR / vec["file"]).read_bytes())
    assert str(info.value) == vec["reference_message"]


# ------------------------------------------------------------- limits and boundaries --
def _stream(name: str):
    v = next(v for v in MAN["vectors"] if v["name"].split("-", 1)[1] == name)
    return decoder.read_stream((VDIR / v["file"]).read_bytes())


def test_every_limit_is_reached_by_a_vector_or_documented():
    """§8: each limit has a decodable vector exactly at it, or a note in the manifest's
    limit_boundaries saying why not (and a boundary test in this file)."""
    # the nine limits of MPZ 1.0 (a limit added later needs its line here, and a vector)
    reached = dict.fromkeys(("MAX_FRAMES", "MAX_MARKERS", "MAX_SAMPLES", "MAX_CHUNK_LENGTH",
                             "MAX_PATTERN_LENGTH", "MAX_PATTERN_SAMPLES", "MAX_SMOOTHING",
                             "MAX_SUMMARY_LEVELS", "MAX_SUMMARY_VALUES"), 0)
    for v in MAN["vectors"]:
        if v["expected"] != "decode":
            continue
        s = decoder.read_stream((VDIR / v["file"]).read_bytes())
        h = s.header
        reached["MAX_FRAMES"] = max(reached["MAX_FRAMES"], h.frame_count)
        reached["MAX_MARKERS"] = max(reached["MAX_MARKERS"], h.marker_count)
        reached["MAX_SAMPLES"] = max(reached["MAX_SAMPLES"], h.frame_count * h.marker_count)
        reached["MAX_CHUNK_LENGTH"] = max([reached["MAX_CHUNK_LENGTH"]]
                                          + [c.length for c in s.chunks])
        reached["MAX_SMOOTHING"] = max(reached["MAX_SMOOTHING"], h.smoothing)
        for i, c in s.patt.items():
            if c.record.pattern_count:
                reached["MAX_PATTERN_LENGTH"] = max(reached["MAX_PATTERN_LENGTH"],
                                                    c.record.length)
                reached["MAX_PATTERN_SAMPLES"] = max(
                    reached["MAX_PATTERN_SAMPLES"],
                    c.record.pattern_count * c.record.length * s.nodes[i].member_count)
        if s.summary is not None:
            sm = s.summary.record
            reached["MAX_SUMMARY_LEVELS"] = max(reached["MAX_SUMMARY_LEVELS"], sm.level_count)
            reached["MAX_SUMMARY_VALUES"] = max(reached["MAX_SUMMARY_VALUES"],
                                                sum(lv.k * sm.dims for lv in sm.levels))
    notes = " ".join(MAN["limit_boundaries"])
    short = [n for n in reached if reached[n] < LIMITS[n] and n not in notes]
    assert not short, f"no vector at {short} and no note in limit_boundaries"
    assert all(reached[n] <= LIMITS[n] for n in reached)


def test_limit_boundaries():
    """The valid side of each limit too large for a vector: exactly at it passes the check,
    one over fails with a limit error (the invalid sides are vectors)."""
    s = _stream("all-chunk-types")
    h = s.header
    at = Context(dataclasses.replace(h, frame_count=MAX_SAMPLES // 4, marker_count=4),
                 MAX_SAMPLES)
    at.header.check(at)                                        # F x M = 2^26
    over = Context(dataclasses.replace(h, frame_count=MAX_SAMPLES // 4 + 1, marker_count=4),
                   MAX_SAMPLES)
    with pytest.raises(LimitExceededError):
        over.header.check(over)
    one = dataclasses.replace(h, frame_count=MAX_FRAMES, marker_count=1, node_count=1)
    one.check(Context(one, MAX_SAMPLES))                       # F = 2^24
    patt = s.patt[1].record
    ctx = Context(h, MAX_SAMPLES, s.nodes, 2)                  # node 2: one member
    dataclasses.replace(patt, node=2, pattern_count=4096, length=4096).check(ctx)  # 2^24
    with pytest.raises(LimitExceededError):
        dataclasses.replace(patt, node=2, pattern_count=4097, length=4096).check(ctx)
    assert 4096 * 4096 == MAX_PATTERN_SAMPLES

    def smry(dims: int) -> Smry:
        lv = SummaryLevel(k=1, wssse=0.0, step=1.0, starts=struct.pack("<I", 0), means=b"")
        return Smry(space=1, dims=dims, level_count=1, levels=(lv,))
    smry(MAX_SUMMARY_VALUES).check(Context(h, MAX_SAMPLES))    # sum k x D = 2^24
    with pytest.raises(LimitExceededError):
        smry(MAX_SUMMARY_VALUES + 1).check(Context(h, MAX_SAMPLES))


def test_chunk_length_boundary():
    """A declared length of exactly 2^30 passes the §8 limit and fails only because the
    file is shorter (§3.2); 2^30 + 1 fails the limit itself. A valid 2^30-byte chunk needs
    a 1 GiB file, so the boundary is tested on the error each one gets."""
    good = (VDIR / next(v["file"] for v in MAN["vectors"]
                        if v["name"] == "v09-all-chunk-types")).read_bytes()
    results = {}
    for length in (MAX_CHUNK_LENGTH, MAX_CHUNK_LENGTH + 1):
        b = bytearray(good)
        struct.pack_into("<I", b, 8 + 4, length)               # MHDR's length field
        results[length] = scan(bytes(b)).errors[0]
    assert results[MAX_CHUNK_LENGTH].section == "§3.2"
    assert "left in the file" in str(results[MAX_CHUNK_LENGTH])
    assert results[MAX_CHUNK_LENGTH + 1].section == "§8"
    assert "exceeds the limit" in str(results[MAX_CHUNK_LENGTH + 1])


def test_lower_sample_limit():
    """R-4.1-1: a decoder with a lower MAX_SAMPLES rejects larger files with a limit error
    and still decodes a file exactly at its limit."""
    v = next(v for v in MAN["vectors"] if v["name"].endswith("long-20000-frames"))
    data = (VDIR / v["file"]).read_bytes()
    n = v["header"]["frames"] * v["header"]["markers"]
    assert mpz.decode(data, max_samples=n).n_frames == v["header"]["frames"]
    with pytest.raises(LimitExceededError):
        mpz.decode(data, max_samples=n - 1)


def test_allocation_failure_is_not_invalid_data(monkeypatch):
    """R-8-3: when the output cannot be allocated the reference returns no motion and lets
    MemoryError through: a resource error, never an MPZError verdict on the file."""
    v = next(v for v in MAN["vectors"] if v["name"].endswith("long-20000-frames"))
    data = (VDIR / v["file"]).read_bytes()
    shape = (v["header"]["frames"], v["header"]["markers"], 3)

    def refusing(real):
        def alloc(s, *a, **k):
            if tuple(np.atleast_1d(s)) == shape:
                raise MemoryError(f"cannot allocate {shape}")
            return real(s, *a, **k)
        return alloc
    for name in ("zeros", "empty", "full"):
        monkeypatch.setattr(decoder.np, name, refusing(getattr(np, name)))
    with pytest.raises(MemoryError):
        mpz.decode(data)
