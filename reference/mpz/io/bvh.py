"""BVH (Biovision hierarchy) reading and writing.

Contract: :func:`parse_bvh` takes the text of a BVH file and returns a
:class:`mpz.Motion` of joint-centre trajectories computed by forward
kinematics: one point per ROOT/JOINT, plus one per ``End Site`` named
``<parent>_End``, in file order. ``parents`` gives the hierarchy; the raw
channel values are kept in ``angles`` with names like ``Hips.Xrotation``, and the
whole hierarchy (names, offsets, channel layout, frame time) in
``extras["skeleton"]``, a :class:`mpz.io.kinematics.Skeleton`. :func:`format_bvh`
and :func:`write_bvh` turn such a motion back into BVH text.

Conventions: see :mod:`mpz.io.kinematics` (the usual BVH reading: a joint's local
transform is ``T(OFFSET + position channels) @ R``, ``R`` the rotation channels
multiplied in the order listed). BVH has no unit field; units are ``""`` unless the
caller sets them (``mpz encode --units``; the CMU conversions here are roughly
centimetre-like, see docs/io-notes.md).
"""
from __future__ import annotations

import codecs
from collections.abc import Callable, Iterator
import functools
import itertools
import math
import os
import re

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpz.errors import InputFormatError
from mpz.format import ChannelKind
from mpz.io._common import (
    LINE_BREAK,
    TEXT_BLOCK,
    StrPath,
    decode_text,
    integer,
    named,
    number,
    plain_numbers,
    read_regular,
    reader,
    samples_problem,
    text_encoding_of,
    unique_names,
    write_pieces,
)
from mpz.io.kinematics import BVH_CHANNELS, Joint, Skeleton, forward
from mpz.motion import READER_NOT_KEPT, Motion

_CODES = {name.upper(): int(kind) for kind, name in BVH_CHANNELS.items()}
#: the words that open or close a part of a hierarchy (a CHANNELS line that names fewer
#: channels than its count runs into one of them)
_STRUCTURE = frozenset({"{", "}", "ROOT", "JOINT", "END", "OFFSET", "CHANNELS", "MOTION"})
MAX_JOINTS = 10000  # sanity bound on the hierarchy size
MAX_CHANNELS_PER_JOINT = 6 * 4  # generous: a joint rarely has more than 6


class _Joint:
    """A ROOT, JOINT or End Site while parsing: parent index (-1 for a root), channels,
    ``at``, the index of the word that opens it (the line a message names), and ``listed``,
    whether a CHANNELS line gave the channels (a joint without one has none)."""

    __slots__ = ("name", "parent", "offset", "channels", "end", "at", "listed")

    def __init__(self, name: str, parent: int, end: bool = False, at: int = 0) -> None:
        self.name, self.parent, self.end, self.at = name, parent, end, at
        self.offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.channels: list[int] = []
        self.listed = False

    def joint(self) -> Joint:
        return Joint("" if self.end else self.name, self.parent, tuple(self.channels),
                     self.offset, end_site=self.end)


def _bad(msg: str) -> InputFormatError:
    return InputFormatError(f"BVH: {msg}")


def _numeric(words: list[str]) -> bool:
    """Whether ``words`` is one word that reads as a number (:func:`~mpz.io._common.number`)."""
    try:
        return len(words) == 1 and math.isfinite(number(words[0]))
    except InputFormatError:
        return False


def _what(joints: list[_Joint], i: int) -> str:
    """Joint ``i`` in a message: ``joint 'Chest'`` or ``the End Site of 'Chest'``."""
    j = joints[i]
    return f"the End Site of {joints[j.parent].name!r}" if j.end else f"joint {j.name!r}"


def _parse_hierarchy(tokens: list[str], pos: int, line_of: Callable[[int], int],
                     respelled: list[str] | None = None
                     ) -> tuple[list[_Joint], int, int]:
    """Parse from after 'HIERARCHY' to 'MOTION'. Returns (joints, n_channels, pos).
    ``line_of(i)``: the line of word ``i`` (or of the last word, past the end); a refusal
    names the line of the word that starts what it refuses. The keywords and channel names
    are read in any case; those not spelled as :func:`format_bvh` writes them (``root``,
    ``xrotation``) are appended to ``respelled``, when given."""
    spelled = [] if respelled is None else respelled
    joints: list[_Joint] = []
    stack: list[int] = []
    pending: _Joint | None = None
    n_channels = 0
    with_channels: set[int] = set()
    with_offset: set[int] = set()
    # a refusal names the line of the word that starts what it refuses (they named none:
    # a QA run of the text readers); ``pos`` is that word's index when ``bad`` is called
    def bad(msg: str) -> InputFormatError:
        return _bad(f"line {line_of(pos)}: {msg}")

    while pos < len(tokens):
        t = tokens[pos]
        up = t.upper()
        if pending is not None and t != "{":
            # the next ROOT, JOINT or End Site replaced it, and OFFSET or CHANNELS went to
            # the joint around it: "JOINT Toe {" then "ROOT root" and an OFFSET lost the
            # words without a word (a round-trip QA run of mutated files)
            opened = (f"End Site of {joints[pending.parent].name!r}" if pending.end
                      else f"{tokens[pending.at]} {pending.name}")
            raise bad(f"{opened} (line {line_of(pending.at)}) is not followed by '{{' "
                      f"but by {t!r}")
        if up == "MOTION":
            break
        if up in ("ROOT", "JOINT"):
            if up == "JOINT" and not stack:
                raise bad("JOINT outside of a ROOT block")
            if up == "ROOT" and stack:        # read as a JOINT, written back as one
                raise bad(f"ROOT inside {_what(joints, stack[-1])} (from line "
                          f"{line_of(joints[stack[-1]].at)}): a ROOT opens a hierarchy, "
                          "outside every block")
            if stack and joints[stack[-1]].end:     # spec §4.14.1: an End Site has no
                raise bad(f"{t} inside the End Site of "    # children (a QA run: exit 70)
                          f"{joints[joints[stack[-1]].parent].name!r}")
            if pos + 1 >= len(tokens):
                raise bad(f"{t} without a name")
            if tokens[pos + 1] in ("{", "}"):     # "JOINT\n{": '{' was taken for its
                raise bad(f"{t} without a name (followed by {tokens[pos + 1]!r})")  # name
            if "\x00" in tokens[pos + 1]:         # spec §4.14.1: a name holds no U+0000
                raise bad(f"{t} name {tokens[pos + 1]!r} holds a NUL character")
            pending = _Joint(tokens[pos + 1], stack[-1] if stack else -1, at=pos)
            if t != up:
                spelled.append(t)
            pos += 2
        elif up == "END":
            if not stack:
                raise bad("End Site outside of a joint")
            if joints[stack[-1]].end:
                raise bad(f"End Site inside the End Site of "
                          f"{joints[joints[stack[-1]].parent].name!r}")
            # "End Site", and no other word after End: "End Sight" was read as one, and
            # "End" alone took the next word ('{') with it (a QA run of the text readers)
            after = tokens[pos + 1] if pos + 1 < len(tokens) else ""
            if after.upper() != "SITE":
                raise bad(f"{t} followed by {after!r}, not 'Site' ('End Site' opens an "
                          f"End Site)" if after else f"{t} without 'Site'")
            # named after its parent
            pending = _Joint(f"{joints[stack[-1]].name}_End", stack[-1], end=True, at=pos)
            if (t, after) != ("End", "Site"):
                spelled.append(f"{t} {after}")
            pos += 2
        elif t == "{":
            if pending is None:
                raise bad("'{' without ROOT/JOINT/End Site")
            if len(joints) >= MAX_JOINTS:
                raise bad(f"more than {MAX_JOINTS} joints")
            joints.append(pending)
            stack.append(len(joints) - 1)
            pending = None
            pos += 1
        elif t == "}":
            if not stack:
                raise bad("unbalanced '}'")
            shut = stack.pop()
            if shut not in with_offset:
                # read as 0 0 0 without a word: the joint drawn at its parent's place;
                # every BVH description has the line, and no exporter leaves it out
                raise bad(f"{_what(joints, shut)} (from line {line_of(joints[shut].at)})"
                          " has no OFFSET line: every ROOT, JOINT and End Site needs one"
                          " (it is not taken as 0 0 0)")
            pos += 1
        elif up == "OFFSET":
            if not stack:
                raise bad("OFFSET outside of a joint")
            # "OFFSET 0 10" said "'CHANNELS' is not a number", "OFFSET 0 1 0 7"
            # "unexpected token '7'" (a QA run of the text readers)
            given = 0
            while given < 4 and _numeric(tokens[pos + 1 + given:pos + 2 + given]):
                given += 1
            stop = tokens[pos + 1 + given:pos + 2 + given]
            if given > 3 or (given < 3 and (not stop or stop[0].upper() in _STRUCTURE)):
                raise bad(f"OFFSET of {_what(joints, stack[-1])} has "
                          f"{'more than 3' if given > 3 else given} "
                          f"number{'' if given == 1 else 's'}, not 3")
            try:
                off = [number(x) for x in tokens[pos + 1:pos + 4]]
            except InputFormatError as exc:
                raise bad(f"OFFSET of {joints[stack[-1]].name!r}: {exc.message}") from None
            if stack[-1] in with_offset:     # the second replaced the first, without a word
                raise bad(f"{_what(joints, stack[-1])} has two OFFSET lines")
            with_offset.add(stack[-1])
            joints[stack[-1]].offset = (off[0], off[1], off[2])
            if t != up:
                spelled.append(t)
            pos += 4
        elif up == "CHANNELS":
            if not stack:
                raise bad("CHANNELS outside of a joint")
            j = joints[stack[-1]]
            if j.end:
                raise bad(f"CHANNELS inside the End Site of {joints[j.parent].name!r}")
            if stack[-1] in with_channels:      # the second replaced the first's columns
                raise bad(f"joint {j.name!r} has two CHANNELS lines")
            with_channels.add(stack[-1])
            j.listed = True
            n = (named(integer, tokens[pos + 1], f"CHANNELS of joint {j.name!r}", bad)
                 if pos + 1 < len(tokens) else -1)
            if not 0 <= n <= MAX_CHANNELS_PER_JOINT:
                raise bad(f"bad channel count {n} for joint {j.name!r}")
            chans = tokens[pos + 2:pos + 2 + n]
            named_here = next((k for k, c in enumerate(chans) if c.upper() not in _CODES),
                              len(chans))
            more = tokens[pos + 2 + n:pos + 3 + n]
            if named_here == len(chans) < n:     # the file ends inside the list: an
                # IndexError of chans[named_here] (a fuzzing QA run of the text readers)
                raise bad(f"CHANNELS of joint {j.name!r} says {n} but the file ends after "
                          f"{len(chans)}{': ' if chans else ''}{' '.join(chans)}")
            if (named_here < n and chans[named_here].upper() in _STRUCTURE) or (
                    named_here == n and more and more[0].upper() in _CODES):
                # was "unexpected token 'Yrotation' in HIERARCHY", or a list of the
                # words read as channels, '}' among them (a QA run of the text readers)
                names = tokens[pos + 2:pos + 2 + named_here]
                while (pos + 2 + len(names) < len(tokens)
                       and tokens[pos + 2 + len(names)].upper() in _CODES):
                    names.append(tokens[pos + 2 + len(names)])
                raise bad(f"CHANNELS of joint {j.name!r} says {n} but names "
                          f"{len(names)}: {' '.join(names)}")
            if len(chans) != n or named_here < n:
                raise bad(f"bad CHANNELS for joint {j.name!r}: {chans}")
            if len({c.upper() for c in chans}) != n:       # spec §4.14.1: each at most once
                raise bad(f"CHANNELS of joint {j.name!r} name a channel twice: {chans}")
            j.channels = [_CODES[c.upper()] for c in chans]
            spelled.extend(w for w in [t, *chans]
                           if w not in ("CHANNELS", *BVH_CHANNELS.values()))
            n_channels += n
            pos += 2 + n
        else:
            raise bad(f"unexpected token {t!r} in HIERARCHY")
    if stack:
        raise _bad(f"HIERARCHY ends inside {_what(joints, stack[-1])} (from line "
                   f"{line_of(joints[stack[-1]].at)}): a '}}' is missing")
    if not joints:
        raise _bad("no joints in HIERARCHY")
    return joints, n_channels, pos


def frame_rate_from_frame_time(ft: float, written: str = "") -> float:
    """``1 / ft``, snapped to the nearest integer when within 1e-3 of it, or when
    ``written`` (the Frame Time as the file prints it) is that integer's frame time rounded
    to the decimals it shows, and no other integer's.

    BVH stores the frame time with few digits (``0.0083333`` for 120 Hz). Blender and
    MotionBuilder print 6 decimals: 120 fps is ``0.008333``, 1 / 0.008333 = 120.0048 Hz,
    which the 1e-3 rule alone left as it was (and 60 fps as 59.9988 Hz).

    Examples
    --------
    >>> frame_rate_from_frame_time(0.0083333)
    120.0
    >>> frame_rate_from_frame_time(0.04)
    25.0
    >>> frame_rate_from_frame_time(0.008333, "0.008333")
    120.0
    >>> frame_rate_from_frame_time(1500.0) == 1 / 1500
    True
    """
    if not ft > 0:
        raise _bad(f"Frame Time must be positive, got {ft!r}")
    r = 1.0 / ft
    if not math.isfinite(r):
        raise _bad(f"Frame Time {ft!r} is too small: its rate, 1 / Frame Time, overflows")
    n = round(r)
    # never to 0: a Frame Time of 1500 s snapped 1/1500 Hz to 0, and the file was refused
    # for a rate of 0 (a CLI fuzzing QA run of stop 54)
    if n >= 1 and abs(r - n) < 1e-3:
        return float(n)
    half = _half_unit(written)
    if half is not None and ft > half:
        # the integers whose frame time, rounded to the printed decimals, reads as written
        low, high = math.ceil(1.0 / (ft + half)), math.floor(1.0 / (ft - half))
        if low == high and low >= 1:
            return float(low)
    return r


_PLAIN_NUMBER = re.compile(r"\+?\d*\.?(\d*)(?:[eE]([-+]?\d{1,4}))?")


def _half_unit(written: str) -> float | None:
    """Half a unit of the last decimal ``written`` shows (``"0.008333"``: 5e-7;
    ``"8.33e-3"``: 5e-6), or None for a text that is not a plain number."""
    m = _PLAIN_NUMBER.fullmatch(written)
    if m is None or not any(c.isdigit() for c in written):
        return None
    decimals = len(m.group(1)) - int(m.group(2) or 0)
    return 0.5 * 10.0 ** -decimals


def _line_of(text: str, starts: list[int], i: int) -> int:
    """The line of word ``i`` of ``text``, whose words start at ``starts`` (of the last word,
    past the end)."""
    return len(LINE_BREAK.findall(text, 0, starts[min(i, len(starts) - 1)])) + 1


def parse_bvh(text: str, *, source: str = "", encoding: str = "utf-8") -> Motion:
    """Parse BVH text into a Motion of joint centres.

    Parameters
    ----------
    text : str
        The whole file.
    source : str, optional
        File name for the metadata.
    encoding : {"utf-8", "latin-1"}, optional
        How the text was decoded from bytes (kept for writing it back).

    Returns
    -------
    Motion
        With ``extras["skeleton"]`` the :class:`~mpz.io.kinematics.Skeleton`.

    Raises
    ------
    InputFormatError
        On a malformed hierarchy, a missing MOTION section, or a frame
        count or row width that does not match the channels.
    """
    tokens, starts, data_start = _head_tokens(text)
    if not tokens or tokens[0].upper() != "HIERARCHY":
        raise _bad("file does not start with HIERARCHY")

    respelled = [w for w in tokens[:1] if w != "HIERARCHY"]
    joints, n_channels, pos = _parse_hierarchy(
        tokens, 1, functools.partial(_line_of, text, starts), respelled)
    if pos >= len(tokens):
        raise _bad("no MOTION section")
    # MOTION / Frames: n / Frame Time: t
    head = tokens[pos + 1:pos + 6]
    if (len(head) < 5 or head[0].rstrip(":").upper() != "FRAMES"
            or head[2].upper() != "FRAME" or head[3].rstrip(":").upper() != "TIME"):
        raise _bad(f"expected 'Frames: n' and 'Frame Time: t' after MOTION, got {head}")
    words = [tokens[pos], head[0], head[2], head[3]]
    respelled += [w for w, canon in zip(words, ["MOTION", "Frames:", "Frame", "Time:"],
                                        strict=True) if w != canon]
    n_frames = named(integer, head[1], "MOTION header", _bad)
    ft = named(number, head[4], "MOTION header", _bad)
    rate = frame_rate_from_frame_time(ft, head[4])
    if n_frames <= 0:
        raise _bad(f"Frames must be positive, got {n_frames}")
    if n_channels == 0 and n_frames > _frame_lines(text):
        # nothing else bounds the count (and the positions allocated by it): spec §4.14.1
        # writes one line per frame, empty without channels
        raise _bad(f"Frames: {n_frames} without channels, but {_frame_lines(text)} frame "
                   "lines follow Frame Time (one line per frame, empty without channels)")
    values = _motion_values(text, data_start, n_frames, n_channels)
    too_many = samples_problem(n_frames, len(joints), len(text), "joints and End Sites")
    # the text is read: it is let go before the joints' positions are made (issue 15.3)
    del text
    if too_many:        # the positions are not in the text: forward kinematics makes them
        raise _bad(f"{too_many}: each joint and End Site has a position in every frame, "
                   "refused before they are computed")
    if not np.isfinite(values).all():
        raise _bad("non-finite channel value")
    skel = Skeleton("bvh", tuple(j.joint() for j in joints), frame_time=ft, encoding=encoding)
    positions = source_joints(skel, values)
    meta = {"format": "bvh", "frame_time": repr(ft), "channels": str(n_channels),
            "joints": str(sum(not j.end for j in joints)),
            "end_sites": str(sum(j.end for j in joints))}
    if source:
        meta["source"] = source
    points, renamed = unique_names([j.name for j in joints])   # BVH names may repeat
    if renamed:
        meta["renamed_points"] = "; ".join(renamed)
    names = [f"{j.name}.{BVH_CHANNELS[ChannelKind(c)]}" for j in joints for c in j.channels]
    extras: dict[str, object] = {"skeleton": skel}
    lost: list[str] = []
    if respelled:
        # the skeleton chunk holds channel kinds and joints, not how their words were spelled:
        # 'xrotation' came back as 'Xrotation' without a word (a round-trip QA run)
        shown = ", ".join(dict.fromkeys(respelled))
        lost.append(
            f"from the BVH: the spelling of {len(respelled)} keyword"
            f"{'' if len(respelled) == 1 else 's'} and channel names ({shown[:200]}"
            f"{'...' if len(shown) > 200 else ''}): written back as HIERARCHY, ROOT, JOINT, "
            "End Site, OFFSET, CHANNELS, Xrotation ..., MOTION, Frames:, Frame Time:")
    unlisted = [j.name for j in joints if not j.end and not j.listed]
    if unlisted:
        # the chunk holds each joint's channels, none alike for both: a joint without a
        # CHANNELS line came back with "CHANNELS 0" without a word
        shown = ", ".join(unlisted)
        lost.append(
            f"from the BVH: that {len(unlisted)} joint{' has' if len(unlisted) == 1 else 's have'}"
            f" no CHANNELS line ({shown[:200]}{'...' if len(shown) > 200 else ''}): "
            "written back with CHANNELS 0")
    if lost:
        extras[READER_NOT_KEPT] = lost
    return Motion(positions, points, rate, "", None, meta,
                  [j.parent for j in joints], values, names, extras)


def text_encoding(data: bytes) -> str:
    """``"utf-8"`` if ``data`` is UTF-8 (a BOM allowed), else ``"latin-1"``: what
    :func:`mpz.io._common.decode_text` used. Checked :data:`_VALUES_CHUNK` bytes at a
    time, the decoded text let go: the readers call it beside the text they parse, and
    decoding it whole held a third copy of a 30-minute BVH's 278 MB (issue 15.3)."""
    # the BOM is taken off here: the incremental "utf-8-sig" decoder accepts a file of one
    # or two of its bytes alone, which is not UTF-8
    view = memoryview(data)[3 if data.startswith(codecs.BOM_UTF8) else 0:]
    check = codecs.getincrementaldecoder("utf-8")()
    try:
        for at in range(0, len(view), _VALUES_CHUNK):
            check.decode(view[at:at + _VALUES_CHUNK])
        check.decode(b"", final=True)
    except UnicodeDecodeError:
        return "latin-1"
    return "utf-8"


@reader
def read_bvh(path: StrPath) -> Motion:
    """Read a BVH file (see :func:`parse_bvh`).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Motion
        Joint centres and end sites, ``units=""``, ``parents``, ``angles`` and
        ``extras["skeleton"]`` set.

    Raises
    ------
    InputFormatError
    """
    return bvh_from_bytes(path, read_regular(path))


@reader
def bvh_from_bytes(path: StrPath, data: bytes) -> Motion:
    """:func:`read_bvh` of the file's bytes, read once by :func:`mpz.io.read` (``path``
    names the file; it is not opened)."""
    return parse_bvh(decode_text(data), source=os.path.basename(os.fspath(path)),
                     encoding=text_encoding(data))


# ------------------------------------------------------------------ writing --
def num(x: float) -> str:
    """A number as the shortest text that reads back as the same binary64 (``repr``),
    without a trailing ``.0``: ``1.5`` -> ``'1.5'``, ``2.0`` -> ``'2'``, ``1e-14`` ->
    ``'1e-14'``.

    Examples
    --------
    >>> [num(v) for v in (1.5, 2.0, -0.0, 1e-14, 12.34)]
    ['1.5', '2', '-0', '1e-14', '12.34']
    """
    r = repr(float(x))
    return r[:-2] if r.endswith(".0") else r


#: a ``.0`` that ends a number of a line of :func:`num` texts
_POINT_ZERO = re.compile(r"\.0(?= |$)")


def nums(values: list[float]) -> str:
    """``" ".join(num(v) for v in values)``, faster: every ``repr`` made in one C loop and
    each ``.0`` that ends a number stripped by one regular-expression pass (issue 15: a BVH
    of 100,000 channel values took 40 ms to write through :func:`num`, 0.4 us a number).

    Examples
    --------
    >>> nums([1.5, 2.0, -0.0, 1e-14, 10.0, float("inf")])
    '1.5 2 -0 1e-14 10 inf'
    """
    return _POINT_ZERO.sub("", " ".join(map(repr, map(float, values))))


def skeleton_problem(motion: Motion, convention: str) -> str | None:
    """Why ``motion`` cannot be written in the skeleton format of ``convention`` ("bvh" or
    "asf"), or None when it can."""
    skel = motion.extras.get("skeleton")
    what = {"bvh": "BVH", "asf": "AMC/ASF"}[convention]
    if not isinstance(skel, Skeleton) or skel.convention != convention:
        have = "no skeleton" if not isinstance(skel, Skeleton) else \
            {"bvh": "a BVH skeleton", "asf": "an ASF skeleton"}.get(
                skel.convention, f"a {skel.convention} skeleton")
        # (an .mpz made from BVH with --no-skeleton holds the joint positions alone: the
        # hint was "an .mpz made from one", which it was; a QA run of stop 47)
        return (f"the motion has {have}; {what} output needs a motion read from {what}, or "
                f"an .mpz made from one with its skeleton (not --no-skeleton); the joint "
                f"positions alone can be written as .npy or .csv (.c3d, .trc: with units)")
    C = skel.channel_count
    ang = motion.angles
    if (ang is None and C) or (ang is not None and ang.shape != (motion.n_frames, C)):
        shape = None if ang is None else ang.shape
        return f"the skeleton has {C} channels but the motion's angles are {shape}"
    return None


def source_joints(skel: Skeleton, values: ArrayLike,
                  scale: float = 1.0) -> NDArray[np.float64]:
    """:func:`forward` times ``scale`` for a reader: the joint positions of a BVH or AMC
    source, which must all be finite.

    Raises
    ------
    InputFormatError
        Where a position overflows binary64 (a bone length or offset near 1e308): the
        positions became infinities that the Motion took for gaps, silently, and the
        encoder then failed on NaN (a QA run of stop 54).
    """
    with np.errstate(over="ignore", invalid="ignore"):
        positions = forward(skel, values)
        positions *= scale          # in place: no second array of every joint position
    bad = ~np.isfinite(positions)
    if bad.any():
        f, j, _ = np.argwhere(bad)[0]
        raise InputFormatError(
            f"{skel.convention.upper()}: the position of joint {skel.joints[j].name!r} at "
            f"frame {f} overflows binary64: its bone lengths, offsets or translations are "
            "too large for joint positions")
    return positions


def skeleton_problems(motion: Motion, ext: str) -> list[str]:
    """:func:`skeleton_problem` for an output extension (".bvh" or ".amc"), as a list."""
    problem = skeleton_problem(motion, "bvh" if ext == ".bvh" else "asf")
    return [] if problem is None else [problem]


def skeleton_of(motion: Motion, convention: str) -> Skeleton:
    """The motion's skeleton of ``convention``, with channel values that fit it.

    Raises
    ------
    InputFormatError
        When the motion has none (it was not read from, or decoded from, such a file), or
        its ``angles`` do not have one column per channel.
    """
    problem = skeleton_problem(motion, convention)
    if problem is not None:
        what = {"bvh": "BVH", "asf": "AMC/ASF"}[convention]
        raise InputFormatError(f"cannot write {what}: {problem}")
    skel = motion.extras["skeleton"]
    assert isinstance(skel, Skeleton)
    return skel


def format_bvh(motion: Motion) -> str:
    """The BVH text of a motion that has a BVH skeleton (see :func:`parse_bvh`): the
    pieces of :func:`_bvh_text` joined.

    Raises
    ------
    InputFormatError
        If the motion has no BVH skeleton.
    """
    return "".join(_bvh_text(motion))


def _bvh_text(motion: Motion) -> Iterator[str]:
    """The BVH text of ``motion`` in pieces: the hierarchy and the MOTION header lines
    first, then the frame lines, :data:`~mpz.io._common.TEXT_BLOCK` frames a piece, so
    that :func:`write_bvh` holds one piece at a time (the whole text, with every value
    as a Python float first, peaked at 2.3 GB for a 30-minute capture of 278 MB of
    text: issue 15.3). Every line ends with a line feed.
    """
    skel = skeleton_of(motion, "bvh")
    values = motion.angles if motion.angles is not None else np.zeros((motion.n_frames, 0))
    out = ["HIERARCHY"]
    stack: list[int] = []

    def close_to(parent: int) -> None:
        while stack and stack[-1] != parent:
            stack.pop()
            out.append("\t" * len(stack) + "}")

    for i, j in enumerate(skel.joints):
        close_to(j.parent)
        pad = "\t" * len(stack)
        if j.end_site:
            out.append(f"{pad}End Site")
        else:
            out.append(f"{pad}{'ROOT' if j.parent < 0 else 'JOINT'} {j.name}")
        out.append(pad + "{")
        out.append(f"{pad}\tOFFSET {' '.join(num(v) for v in j.offset)}")
        if not j.end_site:
            kinds = " ".join(BVH_CHANNELS[ChannelKind(c)] for c in j.channels)
            out.append(f"{pad}\tCHANNELS {len(j.channels)}{' ' if kinds else ''}{kinds}")
        stack.append(i)
    close_to(-1)
    out.append("MOTION")
    out.append(f"Frames: {motion.n_frames}")
    out.append(f"Frame Time: {num(skel.frame_time)}")
    yield "\n".join(out) + "\n"
    for lo in range(0, len(values), TEXT_BLOCK):
        rows = np.asarray(values[lo:lo + TEXT_BLOCK], np.float64).tolist()
        yield "".join(nums(row) + "\n" for row in rows)


def _head_tokens(text: str) -> tuple[list[str], list[int], int]:
    """The words of a BVH up to the five after the ``MOTION`` that ends the hierarchy
    (``Frames: n Frame Time: t``), where each starts in ``text``, and the offset in
    ``text`` where the motion's values start. The values are not split into words here: a
    list of every word took 14 bytes of memory per byte of BVH (a QA of stop 50). A joint
    named ``Motion`` (the word after ROOT or JOINT) does not end the hierarchy, as
    :func:`_parse_hierarchy` reads it. After MOTION, ``Frames:60`` and ``Time:0.04`` are
    two words each, as with a space (they were refused: a QA run of BVH exporters)."""
    words: list[str] = []
    starts: list[int] = []
    after: int | None = None      # words left to take after MOTION
    for m in re.finditer(r"\S+", text):
        word = m.group()
        if after is None:
            words.append(word)
            starts.append(m.start())
            if word.upper() == "MOTION" and not (
                    len(words) > 1 and words[-2].upper() in ("ROOT", "JOINT")):
                after = 5
            continue
        key, colon, value = word.partition(":")
        parts = [key + colon, value] if colon and key and value else [word]
        words += parts
        starts += [m.start()] * len(parts)
        after -= len(parts)
        if after <= 0:
            return words, starts, m.end()
    return words, starts, len(text)


#: characters of motion values converted at a time by :func:`_motion_values`
_VALUES_CHUNK = 1 << 22
_SPACE = re.compile(r"\s")


def _word_chunks(text: str, start: int) -> Iterator[list[str]]:
    """The words of ``text[start:]``, a list for each piece of about :data:`_VALUES_CHUNK`
    characters, each piece cut at white space."""
    pos = start
    while pos < len(text):
        stop = len(text)
        if pos + _VALUES_CHUNK < len(text):
            space = _SPACE.search(text, pos + _VALUES_CHUNK)
            stop = len(text) if space is None else space.start()
        yield text[pos:stop].split()
        pos = stop


def _motion_values(text: str, start: int, n_frames: int, n_channels: int
                   ) -> NDArray[np.float64]:
    """The ``n_frames x n_channels`` values written in ``text[start:]``, converted a piece
    of text at a time (:func:`_word_chunks`); InputFormatError when there are fewer or
    more (said first, as the count was checked before the values), or one is not a plain
    number (:func:`plain_numbers`). Nothing is allocated for more values than the text
    can hold: 179 bytes declaring 10^17 frames asked numpy for 2 EiB (a QA of stop 50)."""
    need = n_frames * n_channels

    def bad_line() -> str:
        where = _first_bad_line(text, start, n_channels)
        return "" if where is None else f"; {where[0]} {where[1]}"

    def wrong_count() -> InputFormatError | None:
        got = sum(len(words) for words in _word_chunks(text, start))
        if got < need:
            return _bad(f"{got} values for {n_frames} frames x {n_channels} channels "
                        f"(truncated motion data){bad_line()}")
        if got > need:
            return _bad(f"{got - need} values beyond {n_frames} frames x {n_channels} "
                        f"channels{bad_line()}")
        return None

    if need > (len(text) - start + 1) // 2:     # words of one character and one space
        raise wrong_count() or _bad("fewer values than declared")
    out = np.empty(need)
    got = 0
    for words in _word_chunks(text, start):
        if got + len(words) > need:
            raise wrong_count() or _bad("more values than declared")
        try:
            out[got:got + len(words)] = plain_numbers(words)
        except InputFormatError as exc:
            where = _first_bad_line(text, start, n_channels)
            at = "" if where is None else f", {where[0]}"
            raise wrong_count() or _bad(f"MOTION: {exc.message}{at}") from None
        got += len(words)
    if got < need:
        raise wrong_count() or _bad("fewer values than declared")
    _check_rows(text, start, n_frames, n_channels)
    return out.reshape(n_frames, n_channels)


def _check_rows(text: str, start: int, n_frames: int, n_channels: int) -> None:
    """Refuse values whose count is right but whose rows are not: one line a frame (spec
    §4.14.1), and a line of the wrong width among them. A row one value short and a later
    one a value long read as one stream with every frame between them shifted by a channel,
    without a word (a QA run of BVH exporters). Values spread over another number of lines
    than frames (a frame wrapped over two lines) are read as one stream, as before: no line
    then says where a frame starts. Costs about 4 ms a MB (a fifth of reading the values)."""
    rows = 0                        # lines that hold a value
    same = True                     # each of them n_channels values
    for piece in _line_pieces(text, start):
        for width in map(len, map(str.split, piece.splitlines())):
            if width:
                rows += 1
                same = same and width == n_channels
    if rows != n_frames or same:
        return
    where = _first_bad_line(text, start, n_channels)
    at = "" if where is None else f"; {where[0]} {where[1]}"
    raise _bad(f"{n_frames} frames x {n_channels} channels over {n_frames} lines, but not one "
               f"frame a line{at}: the frames after it would be read shifted")


#: where :func:`_line_pieces` may cut: after a line feed, a CR LF, or a CR alone
_PIECE_END = re.compile(r"\r\n?|\n")


def _line_pieces(text: str, start: int) -> Iterator[str]:
    """``text[start:]`` in pieces of about :data:`_VALUES_CHUNK` characters, each but the
    last ending at a line end (LF, CR LF or CR alone, whole), so that their
    ``splitlines()`` are the whole one's (none of str.splitlines' breaks starts with a
    line feed, and a CR is cut after only when no line feed follows it): the lines of a
    30-minute BVH, with a copy of its text, were 0.56 GB (issue 15.3)."""
    pos = start
    while pos < len(text):
        end = _PIECE_END.search(text, pos + _VALUES_CHUNK)
        stop = len(text) if end is None else end.end()
        yield text[pos:stop]
        pos = stop


def _first_bad_line(text: str, start: int, n_channels: int) -> tuple[str, str] | None:
    """Where the motion values of ``text[start:]`` first go wrong, for a message: ``("line
    L (frame k)", "has c values, not C")``, or ``("line L (frame k)", "'x' is not a
    number")``, L counted in the file, k from 1 among the lines that hold values; None when
    every line has its ``n_channels`` numbers (whole lines are missing or extra). Only
    called on the way to an error: the values are read as one stream, and a row cut short
    in the middle of a file was said as "truncated motion data" with no place to look (a
    QA run of BVH exporters)."""
    lineno = len(LINE_BREAK.findall(text, 0, start)) + 1
    frame = 0
    pos = start
    while pos <= len(text):
        brk = LINE_BREAK.search(text, pos)
        end = len(text) if brk is None else brk.start()
        words = text[pos:end].split()
        if words:
            frame += 1
            try:
                plain_numbers(words)
            except InputFormatError as exc:
                return f"line {lineno} (frame {frame})", exc.message
            if len(words) != n_channels:
                return f"line {lineno} (frame {frame})", (f"has {len(words)} values, not "
                                                          f"{n_channels}")
        if brk is None:
            break
        pos, lineno = brk.end(), lineno + 1
    return None


def _frame_lines(text: str) -> int:
    """The number of lines after the last ``Frame Time:`` line."""
    lines = text.splitlines()
    for i in range(len(lines) - 1, -1, -1):
        words = lines[i].split()
        if len(words) >= 2 and words[0].upper() == "FRAME" and words[1].upper().startswith(
                "TIME"):
            return len(lines) - i - 1
    return 0


def write_bvh(motion: Motion, path: StrPath) -> None:
    """Write a motion with a BVH skeleton as a BVH file (the hierarchy, offsets, channel
    layout, frame count and frame time of the source, and its channel values).

    Raises
    ------
    InputFormatError
        If the motion has no BVH skeleton (see :func:`skeleton_of`).
    """
    pieces = _bvh_text(motion)
    head = next(pieces)                 # the names are here alone: the values are ASCII
    write_pieces(path, itertools.chain([head], pieces),
                 text_encoding_of(head, motion.extras["skeleton"].encoding))
