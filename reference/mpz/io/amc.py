"""Acclaim ASF/AMC (CMU, HDM05) reading and writing.

Contract: :func:`parse_asf` turns ASF text into a :class:`mpz.io.kinematics.Skeleton`
(the root is joint 0, the bones follow with every parent before its children);
:func:`parse_amc` turns AMC text plus a skeleton into a :class:`mpz.Motion` of joint
positions: the root, then the end point of every bone, with ``parents`` from
``:hierarchy``, every dof channel in ``angles`` and the skeleton (with the layout of
the AMC: header lines, first frame number, the order of the bone lines) in
``extras["skeleton"]``. :func:`format_asf` / :func:`format_amc` are the inverse, and
:func:`read_amc` / :func:`write_amc` the thin file wrappers.

Forward kinematics (the Acclaim convention, as in the CMU viewer): see
:mod:`mpz.io.kinematics`. Rotation order: ``axis ... XYZ`` and ``dof rx ry rz`` both
mean "X first", i.e. ``R = Rz @ Ry @ Rx``.

Units: lengths are multiplied by ``(1 / :units length) * 25.4`` to give
millimetres (CMU ``length 0.45``: one file unit is 1/0.45 inch). This is
checked against the C3D of the same CMU take in docs/io-notes.md.

Not kept: ASF keywords other than those above (``:skin``, a bone's ``bodymass`` ...)
are listed in ``metadata["asf_dropped"]`` (and ``mpz encode`` says so).
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
import glob
import itertools
import math
import os
import re
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from mpz._worker import spelled
from mpz.errors import InputFormatError
from mpz.format import ChannelKind
from mpz.io._common import (
    _PARSE_ERRORS,
    LINE_BREAK,
    TEXT_BLOCK,
    StrPath,
    decode_text,
    encoded_text,
    integer,
    most_frames,
    named,
    number,
    number_list,
    read_regular,
    reader,
    samples_problem,
    split_lines,
    text_encoding_of,
    translate,
    write_pieces,
)
from mpz.io.bvh import num, nums, skeleton_of, source_joints, text_encoding
from mpz.io.kinematics import ASF_DOFS, MM_PER_INCH, Joint, Skeleton
from mpz.motion import READER_NOT_KEPT, Motion

_DOF = {name: int(kind) for kind, name in ASF_DOFS.items()}
MAX_BONES = 1000
#: the ASF keywords this module reads (anything else is reported as dropped)
_SECTIONS = {"version", "name", "units", "documentation", "root", "bonedata", "hierarchy"}
_BONE_KEYS = {"begin", "end", "id", "name", "direction", "length", "axis", "dof", "limits"}


_N = TypeVar("_N", int, float)


def _bad(msg: str) -> InputFormatError:
    return InputFormatError(f"ASF/AMC: {msg}")


def _unbracketed(read: Callable[[str], _N]) -> Callable[[str], _N]:
    """``read`` (:func:`number`, :func:`integer`), whose refusal of a word holding a
    parenthesis says where parentheses belong: "length (2)", "direction (1 0 0)", an AMC
    value "(0)" were refused as "'(2)' is not a number", which did not say why (a QA run of
    the text readers); no writer puts parentheses elsewhere than around limits, and a
    comment may hold any."""
    def checked(text: str) -> _N:
        try:
            return read(text)
        except InputFormatError as exc:
            if "(" not in text and ")" not in text:
                raise
            raise InputFormatError(f"{exc.message}; parentheses enclose only the (lo hi) "
                                   "pairs of an ASF's limits, and a comment after '#' may "
                                   "hold any") from None
    return checked


_number = _unbracketed(number)
_integer = _unbracketed(integer)


def _spaced(line: str) -> str:
    """A line of numbers and names with its commas made blanks: the Acclaim ASF definition
    (V1.10) reads commas as white space ("commas are discouraged"), so ``direction 0.3, -0.9,
    0`` or ``limits (-160, 20)`` was refused as "'0.3,' is not a number" (an archive QA run).
    Not for the text fields (``:name``, ``:documentation``, ``:version``, ``mass``)."""
    return line.replace(",", " ") if "," in line else line


#: the sections whose lines are text, where a '#' is part of the text, not a comment
#: (``:name Subject#3`` was read as "Subject", silently: a QA run of stop 52); a whole
#: line there too, since the writer puts each documentation line on a line of its own
_TEXT_SECTIONS = ("name", "documentation")


def _sections(text: str) -> tuple[dict[str, list[str]], list[str], int, list[str]]:
    """Split ASF text into ``{keyword: [lines]}`` at lines starting with ':', the comment
    lines that come before the first keyword (their text after the '#'), how many
    lines after it hold a comment, and what else is not kept (a keyword given again,
    whose lines join the first's; a line before the first keyword that is not a
    comment), as ``metadata["asf_dropped"]`` says them."""
    out: dict[str, list[str]] = {}
    comments: list[str] = []
    later = 0
    notes: list[str] = []
    cur = None
    # lines end at CR LF, LF or CR alone (LINE_BREAK), not also at U+0085, U+2028, form feeds
    # ... as str.splitlines has it: a Latin-1 comment holding byte 0x85 (cp1252's ellipsis)
    # lost its tail silently, or made an AMC "data before the first frame number"
    for raw in LINE_BREAK.split(text):
        if cur is None and raw.lstrip().startswith("#"):
            comments.append(raw.lstrip()[1:])
        line = raw.strip()
        key = line[1:].split(None, 1)[0].lower() if line.startswith(":") and line[1:].split() \
            else None
        if not (key in _TEXT_SECTIONS or (key is None and cur in _TEXT_SECTIONS)):
            # a whole-line comment before the first keyword is kept; any other is not,
            # the first keyword's own included (a review of stop 61)
            if "#" in line and not (cur is None and line.startswith("#")):
                later += 1
            line = line.split("#", 1)[0].strip()
            if not _spaced(line).strip():   # commas alone: a blank line, as commas are
                continue                    # white space (a line of them was an IndexError
            #                                 of its first word: a fuzzing QA run)
        if not line:
            continue
        if line.startswith(":"):
            parts = line[1:].split(None, 1)
            if not parts:                  # ':' alone: an IndexError, reported by name (QA)
                raise _bad("a line of the ASF holds ':' with no keyword after it")
            cur = parts[0].lower()
            if cur in out and cur in _SECTIONS:
                # its lines joined the first's without a word (a round-trip QA run); an
                # unknown section is not written back at all, and said so below
                notes.append(f"a second :{parts[0]} keyword (its lines are written back "
                             "under the first)")
            out.setdefault(cur, [])
            if len(parts) > 1:
                out[cur].append(parts[1])
        elif cur is not None:
            out[cur].append(line)
        else:                   # "õ:version 1.10" was skipped without a word (a QA run)
            notes.append(f"a line before the first keyword ({line})")
    return out, comments, later, notes


_ROOT_KEYS = {"order", "axis", "position", "orientation"}
_UNIT_KEYS = {"mass", "length", "angle"}


def _respellings(text: str, sec: dict[str, list[str]]) -> list[str]:
    """The keywords of ``text`` (an ASF) that are read in any case but not spelled as
    :func:`write_asf` writes them (``:UNITS``, ``LENGTH``, ``dof RX``, ``axis xyz``):
    the skeleton keeps what they say, not their spelling (``LENGTH`` came back as
    ``length`` without a word: a round-trip QA run)."""
    out = [f":{k}" for k in re.findall(r"(?m)^[ \t]*:(\S+)", text)
           if k.lower() in _SECTIONS and k != k.lower()]

    def check(words: list[str], upper: bool) -> None:
        out.extend(w for w in words if w != (w.upper() if upper else w.lower()))

    for section, keys in (("units", _UNIT_KEYS), ("root", _ROOT_KEYS),
                          ("bonedata", _BONE_KEYS), ("hierarchy", {"begin", "end"})):
        for ln in sec.get(section, []):
            words = _spaced(ln).replace("(", " ").split()
            if not words or words[0].lower() not in keys:
                continue
            check(words[:1], upper=False)
            key = words[0].lower()
            if section == "root" and key in ("order", "axis"):
                check(words[1:], upper=True)
            elif section == "units" and key == "angle":
                check(words[1:2], upper=False)
            elif key == "dof":
                check(words[1:], upper=False)
            elif section == "bonedata" and key == "axis":
                check(words[4:5], upper=True)
    return out


def _keyvals(lines: list[str], section: str, known: tuple[str, ...], dropped: list[str]
             ) -> dict[str, list[str]]:
    """``{first word (lower case): the other words}`` of each line; a ``known`` key's
    earlier lines, which the last replaces, go to ``dropped`` (two ``position`` lines of
    ``:root`` kept the last without a word, as a bone's twice-given keys are said: a QA
    run of the text readers)."""
    kv = {}
    for ln in lines:
        parts = ln.split()
        key = parts[0].lower()
        if key in kv and key in known:
            dropped.append(f"an earlier :{section} {key} line (the last is kept)")
        kv[key] = parts[1:]
    return kv


_NTH = {1: "first", 3: "third", 4: "fourth"}


def _beyond(words: list[str], n: int, what: str, dropped: list[str]) -> None:
    """Note in ``dropped`` the words of a field after its first ``n``, which are not read:
    ``direction 1 0 0 5`` and ``length 2 3`` lost their 5 and 3 without a word (a QA run of
    the text readers), where ``id 1 5`` was said."""
    if len(words) > n:
        dropped.append(f"{what} values after the {_NTH[n]} ({' '.join(words[n:])})")


def _vec3(vals: list[str], what: str) -> tuple[float, float, float]:
    if len(vals) < 3:
        raise _bad(f"{what} needs 3 numbers, got {vals}")
    try:
        return _number(vals[0]), _number(vals[1]), _number(vals[2])
    except InputFormatError as exc:                # the skeleton chunk holds finite ones
        raise _bad(f"{what}: {exc.message}") from None


def _limit(text: str) -> float:
    """A bound of a ``limits`` pair: a :func:`number`, or ``inf`` / ``-inf``."""
    if text.lower() in ("inf", "-inf", "+inf"):
        return float(text)
    return number(text)


def _limits(text: str, what: str) -> list[tuple[float, float]]:
    """``(lo hi)`` pairs of a ``limits`` entry; ``inf`` and ``-inf`` allowed."""
    pairs = re.findall(r"\(\s*([^\s()]+)\s+([^\s()]+)\s*\)", text)
    rest = re.sub(r"\(\s*[^\s()]+\s+[^\s()]+\s*\)", "", text).strip()
    if rest:        # "(1.0)" was "bad limits of b1: '(1.0)'", saying nothing of what is bad
        raise _bad(f"bad limits of {what}: {text!r}: each limit is a pair of two numbers "
                   "(lo hi) in parentheses, inf and -inf allowed")
    try:
        out = [(_limit(a), _limit(b)) for a, b in pairs]
    except InputFormatError as exc:
        raise _bad(f"bad limits of {what}: {exc.message}") from None
    if any(math.isnan(v) for p in out for v in p):
        raise _bad(f"NaN in the limits of {what}")
    return out


@dataclass
class _RawBone:
    """One ``begin`` ... ``end`` block of ``:bonedata``: its fields as words, its limits."""

    fields: dict[str, list[str]] = field(default_factory=dict)
    limits: list[tuple[float, float]] = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.fields["name"][0] if self.fields.get("name") else "?"


def _bones(lines: list[str], dropped: list[str]) -> list[_RawBone]:
    """The bone blocks of ``:bonedata``; keys this module does not read go to ``dropped``."""
    bones: list[_RawBone] = []
    cur: _RawBone | None = None
    last = ""
    pending: list[str] = []     # the bone's dropped lines, named at its end (a line before
    for ln in map(_spaced, lines):  # 'name' said "bone ?": a review of stop 61)
        if ln[:7].lower() == "limits(":     # "limits(-10 10)": the key was "limits(-10",
            ln = f"{ln[:6]} {ln[6:]}"       # and the limits not kept (a QA run)
        parts = ln.split()
        key = parts[0].lower()
        if key == "begin":
            if cur is not None and (cur.fields or cur.limits or pending):
                # the new block replaced the open one, whose lines were lost without a
                # word (a round-trip QA run of mutated files)
                raise _bad(f"'begin' inside block {len(bones) + 1} of :bonedata (counted "
                           f"from 1, begin ... end; bone {cur.name}): its 'end' is missing")
            if cur is not None:
                dropped.append("a second 'begin' of a :bonedata block")
            cur, last, pending = _RawBone(), "", []
            continue
        if cur is None:     # was skipped without a word (a QA run of the text readers)
            dropped.append(f"a :bonedata line outside begin ... end ({ln.strip()})")
            continue
        if key == "end":
            if not cur.fields.get("name"):    # which one (a fuzzing QA run)
                raise _bad(f"the bone of block {len(bones) + 1} of :bonedata (counted from "
                           "1, begin ... end) has no name")
            dropped += [f"bone {cur.name}: {what}" for what in pending]
            bones.append(cur)
            if len(bones) > MAX_BONES:
                raise _bad(f"more than {MAX_BONES} bones")
            cur = None
        elif key == "limits":
            cur.limits += _limits(ln.split(None, 1)[1] if len(parts) > 1 else "", cur.name)
            last = key
        elif last == "limits" and ln.startswith("("):
            cur.limits += _limits(ln, cur.name)       # one more (lo hi) pair per line
        elif key in _BONE_KEYS:
            if key in cur.fields:     # the last is kept (a review of stop 61: "id 1, id 5")
                pending.append(f"an earlier {key} line (the last is kept)")
            cur.fields[key] = parts[1:]
            last = key
        else:
            pending.append(key)
            last = key
    if cur is not None:
        raise _bad("'begin' without 'end' in :bonedata")
    return bones


def parse_asf(text: str, *, encoding: str = "utf-8") -> Skeleton:
    """Parse an ASF skeleton.

    Parameters
    ----------
    text : str
    encoding : {"utf-8", "latin-1"}, optional
        How the text was decoded (kept for writing it back).

    Returns
    -------
    Skeleton
        ``convention="asf"``: joint 0 is the root, the bones follow with each parent
        before its children (ASF order otherwise). ``metadata`` of the motion later lists
        what was not kept (see :func:`dropped`).

    Raises
    ------
    InputFormatError
        If ``:root``, ``:bonedata`` or ``:hierarchy`` is missing or malformed.
    """
    skel, _ = _parse_asf(text, encoding)
    return skel


def _parse_asf(text: str, encoding: str) -> tuple[Skeleton, list[str]]:
    sec, comments, later, notes = _sections(text)
    dropped = [f":{k}" for k in sec if k not in _SECTIONS] + notes
    respelled = _respellings(text, sec)
    if respelled:
        dropped.append(f"the spelling of {len(respelled)} keyword"
                       f"{'' if len(respelled) == 1 else 's'} ({', '.join(respelled[:8])}"
                       f"{' ...' if len(respelled) > 8 else ''}: written back as :units, "
                       "length, dof rx, order TX, axis XYZ ...)")
    if later:           # kept before the first keyword only (a QA run of stop 61)
        dropped.append(f"{later} comment{'' if later == 1 else 's'} after the first keyword")
    for need in ("root", "bonedata", "hierarchy"):
        if need not in sec:
            raise _bad(f"ASF has no :{need} section")
    units = _keyvals(sec.get("units", []), "units", ("mass", "length", "angle"), dropped)
    dropped += [f":units {k}" for k in units if k not in ("mass", "length", "angle")]
    _beyond(units.get("length", []), 1, ":units length", dropped)
    _beyond(units.get("angle", []), 1, ":units angle", dropped)
    length = named(_number, (units.get("length", ["1.0"]) or [""])[0], ":units length", _bad)
    if not (math.isfinite(length) and length > 0):
        raise _bad(f":units length must be positive, got {length}")
    if not math.isfinite(25.4 / length):     # 1e-320: millimetres per unit overflow
        raise _bad(f":units length {length!r} is too small: 25.4 / length, the millimetres "
                   "per unit, overflows")
    angle_unit = (units.get("angle", ["deg"]) or [""])[0].lower()
    if angle_unit not in ("deg", "rad"):
        raise _bad(f":units angle {angle_unit!r}: deg or rad" if angle_unit else
                   ":units angle has no value: deg or rad")
    root_keys = ("order", "axis", "position", "orientation")
    root = _keyvals([_spaced(ln) for ln in sec["root"]], "root", root_keys, dropped)
    dropped += [f":root {k}" for k in root if k not in root_keys]
    for key, n in (("axis", 1), ("position", 3), ("orientation", 3)):
        _beyond(root.get(key, []), n, f":root {key}", dropped)
    order = [c.lower() for c in root.get("order", ["TX", "TY", "TZ", "RX", "RY", "RZ"])]
    if any(c not in _DOF or c == "l" for c in order) or len(set(order)) != len(order):
        raise _bad(f"bad root order {order}")
    root_axis = (root.get("axis", ["XYZ"]) or [""])[0].upper()
    if not root_axis:       # "axis" alone: an IndexError, exit 70 (a QA run of stop 54)
        raise _bad(":root axis has no value: XYZ or another order of X, Y and Z")
    if sorted(root_axis) != ["X", "Y", "Z"]:
        raise _bad(f"bad root axis order {root_axis!r}")
    root_joint = Joint("root", -1, tuple(_DOF[c] for c in order),
                       _vec3(root.get("position", ["0", "0", "0"]), "root position"),
                       axis=_vec3(root.get("orientation", ["0", "0", "0"]), "root orientation"),
                       axis_order=root_axis)

    raw = _bones(sec["bonedata"], dropped)
    if not raw:
        raise _bad("no bones in :bonedata")
    names = [b.name for b in raw]
    if len(set(names)) != len(names) or "root" in names:
        # named, with the blocks that give it (it named neither: a fuzzing QA run)
        name = next(n for k, n in enumerate(names) if n == "root" or n in names[:k])
        at = [k + 1 for k, n in enumerate(names) if n == name]
        raise _bad(f"bone name {name!r} is given to the bone" + (
            f"s of blocks {', '.join(map(str, at))}" if len(at) > 1 else f" of block {at[0]}")
            + " of :bonedata (counted from 1): bone names must be unique and not 'root'")
    nul = next((n for n in names if "\x00" in n), None)
    if nul is not None:            # spec §4.14.2: a name holds no U+0000, as the BVH reader
        raise _bad(f"bone name {nul!r} holds a NUL character")     # says (a QA run, stop 64)
    parent: dict[str, str] = {}
    # the writer writes each link once, in one begin ... end block: a link given again,
    # and a begin or end beyond that one block, were dropped without a word (a round-trip
    # QA run); a link outside the block is kept, and written back inside it
    inside, blocks = False, 0
    for ln in sec["hierarchy"]:
        parts = _spaced(ln).split()
        word = parts[0].lower()
        if word in ("begin", "end"):
            if word == "begin" and (inside or blocks):
                dropped.append(f"a second {parts[0]} in :hierarchy (written back as one "
                               "begin ... end block)")
            elif word == "end" and not inside:
                dropped.append(f"an {parts[0]} in :hierarchy outside begin ... end")
            blocks += word == "begin" and not inside
            inside = word == "begin"
            continue
        p = parts[0]
        if p != "root" and p not in names:
            raise _bad(f":hierarchy names unknown bone {p!r}")
        again = []
        for child in parts[1:]:
            if child not in names:
                raise _bad(f":hierarchy names unknown bone {child!r}")
            if child in parent and parent[child] != p:     # the last one silently won
                raise _bad(f":hierarchy gives bone {child!r} two parents, "
                           f"{parent[child]!r} and {p!r}")
            if child in parent:
                again.append(child)
            parent[child] = p
        if again:
            dropped.append(f":hierarchy links {p} to {' '.join(again)} again")
    missing = [n for n in names if n not in parent]
    if missing:
        raise _bad(f"bones not in :hierarchy: {missing}")
    joints = [root_joint]
    zero: list[str] = []                  # the bones whose id line says 0
    index = {"root": 0}
    for b in _ordered(raw, parent):
        name, f = b.name, b.fields
        axis = f.get("axis", ["0", "0", "0", "XYZ"])
        dofs = [d.lower() for d in f.get("dof", [])]
        if any(d not in _DOF for d in dofs) or len(set(dofs)) != len(dofs):
            raise _bad(f"bone {name!r} has bad dof {dofs}")
        axis_order = (axis[3] if len(axis) > 3 else "XYZ").upper()
        if sorted(axis_order) != ["X", "Y", "Z"]:
            raise _bad(f"bone {name!r} has bad axis order {axis_order!r}")
        if not f.get("length"):
            raise _bad(f"bone {name!r} has no length")
        bone_len = named(_number, f["length"][0], f"length of bone {name!r}", _bad)
        if b.limits and len(b.limits) != len(dofs):
            raise _bad(f"bone {name!r} has {len(b.limits)} limits for {len(dofs)} dofs")
        ids = f.get("id", [])
        bone_id = named(_integer, ids[0], f"id of bone {name!r}", _bad) if ids else 0
        if ids and bone_id == 0:
            zero.append(name)
        # "id 1 5": the first is kept (a review of stop 61), and so of the others
        for key, n in (("id", 1), ("name", 1), ("direction", 3), ("length", 1),
                       ("axis", 4)):
            _beyond(f.get(key, []), n, f"bone {name}: {key}", dropped)
        index[name] = len(joints)
        joints.append(Joint(name, index[parent[name]], tuple(_DOF[d] for d in dofs),
                            direction=_vec3(f.get("direction", []), f"direction of {name}"),
                            length=bone_len, axis=_vec3(axis, f"axis of {name}"),
                            axis_order=axis_order, limits=tuple(b.limits),
                            bone_id=bone_id))
    if zero:            # the chunk's 0 is "no id": written back without the line
        dropped.append(f"the id 0 line of bone{'' if len(zero) == 1 else 's'} "
                       f"{', '.join(zero[:3])}{' ...' if len(zero) > 3 else ''}")
    doc = "\n".join(sec.get("documentation", []))
    skel = Skeleton("asf", tuple(joints), angle_unit=angle_unit, encoding=encoding,
                    length=length, mass=" ".join(units.get("mass", [])),
                    version=" ".join(sec.get("version", [])), name=" ".join(sec.get("name", [])),
                    documentation=doc, comments="\n".join(comments))
    return skel, dropped


def _ordered(bones: list[_RawBone], parent: dict[str, str]) -> list[_RawBone]:
    """Bones in ASF order, except that a bone listed before its parent moves to just after
    the parent's place: every parent precedes its children (ASF order when it already does).
    """
    done = {"root"}
    out: list[_RawBone] = []
    todo = list(bones)
    while todo:
        k = next((i for i, b in enumerate(todo) if parent[b.name] in done), None)
        if k is None:
            raise _bad(f"cycle in :hierarchy around {[b.name for b in todo]}")
        b = todo.pop(k)
        out.append(b)
        done.add(b.name)
    return out


def parse_amc(text: str, skel: Skeleton, *, rate: float = 120.0, source: str = "",
              encoding: str | None = None) -> Motion:
    """Parse AMC frames and compute joint positions by forward kinematics.

    Parameters
    ----------
    text : str
        The AMC file.
    skel : Skeleton
        From :func:`parse_asf`.
    rate : float, optional
        Frames per second (AMC does not store it; CMU and HDM05 use 120).
    source : str, optional
        File name for the metadata.
    encoding : {"utf-8", "latin-1"}, optional
        How the AMC text was decoded (default: as the skeleton's).

    Returns
    -------
    Motion
        Points ``root`` then each bone's end, in mm; ``angles`` holds the root
        channels then every bone's dof values (file units: degrees or radians,
        root translation in ASF length units), ``angle_names`` like
        ``"lfemur.rx"``; ``extras["skeleton"]`` the skeleton with the AMC's layout.

    Raises
    ------
    InputFormatError
        On a frame with a missing or unknown bone, a wrong value count,
        non-consecutive frame numbers, or no frames.
    """
    if skel.convention != "asf":
        raise _bad("parse_amc needs an ASF skeleton")
    slot: dict[str, tuple[int, int, int]] = {}
    for i, (j, s) in enumerate(zip(skel.joints, skel.channel_starts(), strict=True)):
        slot[j.name] = (s, len(j.channels), i)
    n_chan = skel.channel_count

    # the joints every frame needs a line for (the root and the bones with dofs), and the
    # frames the text may make positions for (samples_problem), checked as frames come: a
    # frame check over every joint and a list of the joints seen (quadratic in the bones)
    # took 1.7 s a MB of AMC of 1000 bones, and a 1 MB AMC of a line "root" a frame (1000
    # bones without dofs) 6 s to be refused at its end (a hostile-input QA run)
    needed = [i for i, j in enumerate(skel.joints) if j.channels or i == 0]
    J = len(skel.joints)
    size = len(text)
    most = most_frames(J, size)

    def add(frame: NDArray[np.float64]) -> None:
        too_many = (samples_problem(len(frames) + 1, J, size, "joints")
                    if len(frames) >= most else None)
        if too_many:
            raise _bad(f"{too_many}: the root and each bone have a position in every "
                       "frame, refused before they are computed")
        frames.append(frame)

    frames: list[NDArray[np.float64]] = []
    header: list[str] = []
    seen: dict[int, None] = {}      # the joints of this frame's lines, in order
    order: list[int] | None = None
    cur: NDArray[np.float64] | None = None
    first: int | None = None
    expected_frame: int | None = None
    later = 0                       # lines after the first frame that hold no value
    # frames whose bone lines are not the first frame's, in its order: the writer writes
    # every frame in the first's order, and a line for a bone without dofs in a later
    # frame only was lost without a word (a round-trip QA run of stop 67)
    reordered = 0

    def listed(seen: dict[int, None]) -> None:
        """Keep the first frame's order of bone lines; count a later frame's otherwise."""
        nonlocal order, reordered
        if order is None:
            order = list(seen)
        elif list(seen) != order:
            reordered += 1

    start_line = 0                  # the line of the current frame's number
    start_word = ""                 # and that number as written
    for lineno, raw in enumerate(split_lines(text), 1):     # as _sections'
        line = _spaced(raw.split("#", 1)[0]).strip()
        if cur is None and (not line or line.startswith(":")):
            header.append(raw.rstrip("\r"))
            continue
        if "#" in raw or (cur is not None and line.startswith(":")):
            later += 1              # a comment from the first frame line on, or a header
            #                         line among the frames (a review of stop 61)
        if not line or line.startswith(":"):
            continue
        parts = line.split()
        if (len(parts) == 1 and parts[0].startswith("-") and parts[0][1:].isascii()
                and parts[0][1:].isdigit() and parts[0] not in slot):
            # was "data before the first frame number" (or "unknown bone '-3'"): §4.14.2
            # keeps the first frame number as a u32 (an archive QA run)
            raise _bad(f"line {lineno}: frame number {parts[0]}: negative frame numbers are "
                       "not supported (renumber the frames from 0 or 1)")
        if len(parts) == 1 and parts[0].isascii() and parts[0].isdigit():
            # at most 18 digits: int() of 5000 said "cannot read: ValueError: Exceeds the
            # limit (4300 digits) for integer string conversion" (a hostile-input QA run)
            n = named(_integer, parts[0], f"line {lineno}: frame number", _bad)
            if expected_frame is not None and n != expected_frame:
                # the previous number first: a bone "2" read as frame 2 made the real
                # frame 2 after it the one out of sequence
                raise _bad(f"line {lineno}: frame {n} follows frame {expected_frame - 1}"
                           + (_bone_too(start_word, start_line, slot)
                              or _bone_too(parts[0], lineno, slot)))
            if first is None:
                first = n
            expected_frame = n + 1
            if cur is not None:
                _check_frame(seen, needed, skel, n - 1, start_line,
                             hint=(_bone_too(parts[0], lineno, slot)
                                   or _bone_too(start_word, start_line, slot)))
                add(cur)
                listed(seen)
            start_line, start_word = lineno, parts[0]
            cur = np.full(n_chan, np.nan)
            seen = {}
            continue
        if cur is None:
            raise _bad(f"line {lineno}: data before the first frame number")
        name = parts[0]
        if name not in slot:
            raise _bad(f"line {lineno}: unknown bone {name!r}")
        start, count, joint = slot[name]
        if len(parts) - 1 != count:
            raise _bad(f"line {lineno}: {name} has {len(parts) - 1} values, expected {count}")
        if joint in seen:
            raise _bad(f"line {lineno}: {name} appears twice in one frame")
        try:
            cur[start:start + count] = number_list(parts[1:], _number)
        except InputFormatError as exc:
            raise _bad(f"line {lineno}: {name}: {exc.message}") from None
        seen[joint] = None
    if cur is None:
        raise _bad("no frames in AMC")
    _check_frame(seen, needed, skel, (expected_frame or 1) - 1, start_line, last=True,
                 hint=_bone_too(start_word, start_line, slot))
    add(cur)
    listed(seen)
    assert order is not None
    # the text and the frames are read: both are let go before the joints' positions are
    # made (issue 15.3)
    del text
    values = np.array(frames)
    frames.clear()
    if not np.isfinite(values).all():
        raise _bad("non-finite value in AMC")
    while header and not header[-1].strip():
        header.pop()
    skel = replace(skel, amc_header="\n".join(header), first_frame=first or 0,
                   amc_order=tuple(order), encoding=encoding or skel.encoding)
    positions = source_joints(skel, values, MM_PER_INCH / skel.length)
    meta = {"format": "amc", "asf_length_unit": repr(skel.length),
            "mm_per_unit": repr(MM_PER_INCH / skel.length), "rate_assumed": repr(float(rate))}
    if source:
        meta["source"] = source
    if skel.name:
        meta["skeleton"] = skel.name
    warnings = [w for w in (_unit_clash(header, skel.angle_unit), _negative_lengths(skel)) if w]
    if warnings:
        meta["warning"] = "; ".join(warnings)
    names = [j.name for j in skel.joints]
    extras: dict[str, object] = {"skeleton": skel}
    lost = []
    if later:               # kept before the first frame only (a QA run of stop 61)
        lost.append(f"from the AMC: {later} comment or ':' line"
                    f"{'' if later == 1 else 's'} after its first frame")
    if reordered:
        lost.append(f"from the AMC: the bone lines of {reordered} frame"
                    f"{'' if reordered == 1 else 's'} as listed (other bones or another "
                    "order than the first frame's; written back as the first frame lists "
                    "them)")
    if lost:
        extras[READER_NOT_KEPT] = lost
    return Motion(positions, names, rate, "mm", None, meta, skel.parents(), values,
                  skel.channel_names(), extras)


def _unit_clash(header: list[str], angle_unit: str) -> str | None:
    """The warning for an AMC whose ``:DEGREES`` or ``:RADIANS`` line contradicts the ASF's
    ``:units angle``, else None.

    The values are read in the ASF's unit either way, because the skeleton has one angle
    unit for its axes, limits and channels (§4.14.2 ``angle_unit``). The AMC's header comes
    back verbatim and its values exactly, so nothing of the file is lost; what may be wrong
    is the positions computed from it, and so the error that a length bound measures.
    """
    lines = {line.split("#", 1)[0].strip().upper() for line in header}
    said = [flag for flag, unit in ((":DEGREES", "deg"), (":RADIANS", "rad"))
            if flag in lines and unit != angle_unit]
    if not said:
        return None
    return (f"the AMC says {said[0]} but its ASF's angles are in {angle_unit} (its ':units "
            "angle', deg when it has none): the values are read in the ASF's unit, so the "
            "joint positions, and the error a length bound measures, are those of that "
            "reading; the AMC's values and header are kept as written")


def _negative_lengths(skel: Skeleton) -> str | None:
    """The warning for an ASF with bones of negative ``length``, else None.

    Read with a warning, not refused: a bone's end is at ``length * direction`` (Acclaim's
    length is a scale along ``direction``; spec §4.14.2 asks only a finite one), which is
    defined for any sign, so a negative length flips the bone against its direction, and
    it is kept and written back as it is. Said, since no exporter means a length below 0,
    and the joint positions are those of the flipped bone (a QA run of the text readers).
    """
    flipped = [(j.name, j.length) for j in skel.joints[1:] if j.length < 0]
    if not flipped:
        return None
    shown = ", ".join(f"{name!r} ({num(length)})" for name, length in flipped[:3])
    more = f" and {len(flipped) - 3} more" if len(flipped) > 3 else ""
    one = len(flipped) == 1
    return (f"the ASF gives bone{'' if one else 's'} {shown}{more} a negative length: "
            f"{'its end is' if one else 'their ends are'} placed at length * direction, so "
            f"the bone{'' if one else 's'} point{'s' if one else ''} against the direction; "
            f"the length{'' if one else 's'} {'is' if one else 'are'} kept as written")


def _bone_too(word: str, line: int, slot: dict[str, tuple[int, int, int]]) -> str:
    """For the refusal of a frame: what line ``line`` was besides a frame number, when its
    word ``word`` is the name of a bone without dofs, else "".

    A lone whole number is a frame number, and a bone's line its name and its values: the
    name alone for a bone without dofs, so the line of such a bone named by digits was read
    as a frame number, and the frames went wrong after it (a QA run of the text readers).
    It cannot be read otherwise (the number may be the next frame's), and it is never read
    silently: every frame has its number, in sequence, and a line for the root. The ASF is
    read, since its AMC may leave that bone out (CMU's leave out every bone without dofs),
    and a bone with dofs named so is told apart by its values."""
    if word not in slot or slot[word][1]:
        return ""
    return (f"; line {line} ({word!r}) was read as a frame number, and it is also the line "
            f"of bone {word!r}, which has no dofs: a lone whole number is a frame number, "
            "so an AMC cannot hold that bone's line (give the bone a name that is not a "
            "whole number, in the ASF and the AMC)")


def _check_frame(seen: dict[int, None], needed: list[int], skel: Skeleton, frame: int,
                 line: int, *, last: bool = False, hint: str = "") -> None:
    """Refuse a frame without a line for the root or for a bone with dofs: it is named by its
    number and the line of that number (it was "frame ending at line end lacks [...]", of a
    file cut short, and "frame ending at line 93" named the next frame's line: an archive
    QA run). ``needed``: the joints that need one (the root, the bones with dofs), looked
    for in ``seen``, the joints of the frame's lines; ``hint``: :func:`_bone_too`'s."""
    missing = [skel.joints[i].name for i in needed if i not in seen]
    if missing:
        shown = ", ".join(missing[:8]) + (f" and {len(missing) - 8} more" if len(missing) > 8
                                          else "")
        raise _bad(f"frame {frame} (from line {line}{', the last frame' if last else ''}) "
                   f"has no line for {shown}: every frame needs one for the root and each "
                   "bone with dofs" + ("; the file may be cut short" if last and not hint
                                       else "") + hint)


def find_asf(amc_path: StrPath) -> str:
    """The ASF for an AMC file: the longest ``*.asf`` in the same folder whose
    stem is a prefix of the AMC stem (``02_01.amc`` -> ``02.asf``,
    ``HDM_dg_06-03_03_120.amc`` -> ``HDM_dg.asf``).

    Parameters
    ----------
    amc_path : str or os.PathLike
        The AMC file (it need not exist: only its folder and stem are used).

    Raises
    ------
    InputFormatError
        If no such file exists, or two of that longest stem differ (``02.asf`` and
        ``02.ASF``: whichever sorted last was taken, without a word, a corpus QA run).
    """
    amc_path = os.fspath(amc_path)
    folder = os.path.dirname(os.path.abspath(amc_path))
    stem = os.path.splitext(os.path.basename(amc_path))[0]
    cands: list[tuple[int, str]] = []
    for p in glob.glob(os.path.join(glob.escape(folder), "*")):
        s, e = os.path.splitext(os.path.basename(p))
        if e.lower() == ".asf" and stem.startswith(s) and s:
            cands.append((len(s), p))
    if not cands:
        raise InputFormatError(f"no .asf skeleton found for {os.path.basename(amc_path)} "
                               f"(looked for <prefix of {stem!r}>.asf in {folder}); name it with "
                               f"{spelled('--asf PATH', 'asf=')}",
                               path=amc_path)
    longest = max(n for n, _ in cands)
    tied = sorted(p for n, p in cands if n == longest)
    if len(tied) > 1 and len({_bytes_or_none(p) for p in tied}) > 1:
        raise InputFormatError(f"{len(tied)} skeletons fit {os.path.basename(amc_path)}: "
                               + ", ".join(os.path.basename(p) for p in tied)
                               + f" differ; name one with {spelled('--asf PATH', 'asf=')}",
                               path=amc_path)
    return tied[-1]


def _bytes_or_none(path: str) -> bytes | None:
    """The bytes of a candidate ASF for :func:`find_asf`'s comparison; None for one that
    cannot be read (its reader says why, if it is the one taken)."""
    try:
        with open(path, "rb") as f:
            return f.read(1 << 22)
    except OSError:
        return None


@reader
def read_asf(path: StrPath) -> Skeleton:
    """Read an ASF skeleton file (see :func:`parse_asf`).

    Parameters
    ----------
    path : str or os.PathLike
        The ASF file.

    Returns
    -------
    Skeleton
        The skeleton alone; :func:`read_amc` reads a motion with it.
    """
    data = read_regular(path)
    return parse_asf(decode_text(data), encoding=text_encoding(data))


@reader
def read_amc(amc_path: StrPath, asf_path: StrPath | None = None, *,
             rate: float = 120.0) -> Motion:
    """Read an AMC motion with its ASF skeleton.

    Parameters
    ----------
    amc_path : str or os.PathLike
    asf_path : str or os.PathLike, optional
        Default: found by :func:`find_asf`.
    rate : float, optional
        Frame rate (not stored in AMC); 120 Hz for CMU and HDM05.

    Returns
    -------
    Motion
        Joint positions in mm (see :func:`parse_amc`).

    Raises
    ------
    InputFormatError
    """
    return amc_from_bytes(amc_path, read_regular(amc_path), asf_path, rate=rate)


@reader
def amc_from_bytes(amc_path: StrPath, data: bytes, asf_path: StrPath | None = None, *,
                   rate: float = 120.0) -> Motion:
    """:func:`read_amc` of the AMC's bytes, read once by :func:`mpz.io.read` (``amc_path``
    names the file and finds the ASF when ``asf_path`` is None; it is not opened)."""
    if asf_path is None:
        asf_path = find_asf(amc_path)
    try:            # the ASF's faults name the ASF, not the AMC (a QA run)
        asf_data = read_regular(asf_path)
        skel, dropped = _parse_asf(decode_text(asf_data), text_encoding(asf_data))
    except _PARSE_ERRORS + (InputFormatError,) as exc:
        raise translate(asf_path, exc) from (None if isinstance(exc, InputFormatError)
                                             else exc)
    m = parse_amc(decode_text(data), skel, rate=rate,
                  source=os.path.basename(os.fspath(amc_path)), encoding=text_encoding(data))
    m.metadata["asf"] = os.path.basename(os.fspath(asf_path))
    if dropped:
        m.metadata["asf_dropped"] = "; ".join(dropped)
        # what this read drops, for mpz.encoder.not_kept (the report's "dropped"); the
        # metadata entry stays with the file, this one with this read only
        m.extras[READER_NOT_KEPT] = [f"from the ASF: {'; '.join(dropped)}",
                                     *m.extras.get(READER_NOT_KEPT, [])]
    return m


# ------------------------------------------------------------------ writing --
#: the ASF text fields a skeleton keeps as written (spec §4.14.2), in file order
ASF_TEXT_FIELDS = ("comments", "version", "name", "mass", "documentation")


def asf_text_changes(skel: Skeleton, back: Skeleton | None = None) -> dict[str, str]:
    """The text fields of ``skel`` (:data:`ASF_TEXT_FIELDS`) that the ASF :func:`format_asf`
    writes would read back differently, each with the value it reads back as.

    §4.14.2 refuses only U+000A and U+000D in a one-line field; this reader splits lines
    there alone, but words at white space (U+000B, U+000C, U+001C-U+001F, U+0085, U+2028,
    U+2029 among it), and a field's leading and trailing white space is not read, so such
    a field (``mass "a\u2028b"``, a name that starts with a blank), which only a hand-made
    skeleton holds, changes when written: the writers say so (:func:`mpz.io.writer_problems`).
    ``back``: the ASF already read back (:func:`mpz.io.skeleton_read_back`), else it is
    written and read here.
    """
    if back is None:
        try:
            back, _ = _parse_asf(format_asf(skel), skel.encoding)
        except InputFormatError as exc:          # the skeleton's own problems are refused
            return {"the ASF": str(exc)}          # elsewhere (skeleton_problem)
    return {f: getattr(back, f) for f in ASF_TEXT_FIELDS if getattr(back, f) != getattr(skel, f)}


def format_asf(skel: Skeleton) -> str:
    """The ASF text of a skeleton (``convention="asf"``)."""
    out = [f"#{c}" for c in skel.comments.split("\n")] if skel.comments else []
    if skel.version:
        out.append(f":version {skel.version}")
    if skel.name:
        out.append(f":name {skel.name}")
    out.append(":units")
    if skel.mass:
        out.append(f"  mass {skel.mass}")
    out.append(f"  length {num(skel.length)}")
    out.append(f"  angle {skel.angle_unit}")
    if skel.documentation:
        out.append(":documentation")
        out += [f"   {ln}" for ln in skel.documentation.split("\n")]
    root = skel.joints[0]
    out.append(":root")
    out.append("   order " + " ".join(ASF_DOFS[ChannelKind(c)].upper() for c in root.channels))
    out.append(f"   axis {root.axis_order}")
    out.append("   position " + " ".join(num(v) for v in root.offset))
    out.append("   orientation " + " ".join(num(v) for v in root.axis))
    out.append(":bonedata")
    for b in skel.joints[1:]:
        out.append("  begin")
        if b.bone_id:
            out.append(f"     id {b.bone_id}")
        out.append(f"     name {b.name}")
        out.append("     direction " + " ".join(num(v) for v in b.direction))
        out.append(f"     length {num(b.length)}")
        out.append("     axis " + " ".join(num(v) for v in b.axis) + f" {b.axis_order}")
        if b.channels:
            out.append("    dof " + " ".join(ASF_DOFS[ChannelKind(c)] for c in b.channels))
        for k, (lo, hi) in enumerate(b.limits):
            out.append(("    limits " if k == 0 else "           ") + f"({num(lo)} {num(hi)})")
        out.append("  end")
    out.append(":hierarchy")
    out.append("  begin")
    for i, j in enumerate(skel.joints):
        kids = [c.name for c in skel.joints if c.parent == i]
        if kids:
            out.append(f"    {j.name} {' '.join(kids)}")
    out.append("  end")
    return "\n".join(out) + "\n"


def format_amc(motion: Motion) -> str:
    """The AMC text of a motion that has an ASF skeleton (see :func:`parse_amc`): the
    pieces of :func:`_amc_text` joined, its frame template left out.

    Raises
    ------
    InputFormatError
        If the motion has no ASF skeleton.
    """
    pieces = _amc_text(motion)
    head = next(pieces)
    next(pieces)                        # the template
    return head + "".join(pieces)


def _amc_text(motion: Motion) -> Iterator[str]:
    """The AMC text of ``motion`` in pieces: the header lines first, then one frame's
    lines with a ``{}`` for each value (the bone names, every character of the frames
    beyond ASCII: :func:`write_amc_text` picks the encoding from these two), then the
    frames, :data:`~mpz.io._common.TEXT_BLOCK` a piece (the whole text, with every value
    as a Python float first, was held at once: issue 15.3). Every line ends with a line
    feed; the template is not part of the text.
    """
    skel = skeleton_of(motion, "asf")
    values = motion.angles if motion.angles is not None else np.zeros((motion.n_frames, 0))
    starts = skel.channel_starts()
    order = list(skel.amc_order) or [i for i, j in enumerate(skel.joints)
                                     if j.channels or i == 0]
    # no header lines (a source without any, a skeleton built in Python): the two most
    # AMC files start with, the angle unit the ASF's (":DEGREES" beside an `angle rad` ASF
    # made readers that trust the flag take radians for degrees: a QA run of stop 52)
    out = (skel.amc_header.split("\n") if skel.amc_header else
           [":FULLY-SPECIFIED", ":RADIANS" if skel.angle_unit == "rad" else ":DEGREES"])
    yield "\n".join(out) + "\n"
    # a frame's lines are one template, its joints' names with a {} for each value, in
    # AMC order (issue 15: a join per joint line took most of the write)
    cols = [k for i in order for k in range(starts[i], starts[i] + len(skel.joints[i].channels))]
    lines = "\n".join(skel.joints[i].name.replace("{", "{{").replace("}", "}}")
                      + " {}" * len(skel.joints[i].channels) for i in order)
    yield lines
    for lo in range(0, len(values), TEXT_BLOCK):
        rows = np.asarray(values[lo:lo + TEXT_BLOCK], np.float64)[:, cols].tolist()
        yield "".join(f"{skel.first_frame + lo + t}\n{lines.format(*nums(row).split(' '))}\n"
                      for t, row in enumerate(rows))


def default_asf_path(amc_path: StrPath) -> str:
    """Where :func:`write_amc` puts the ASF by default: beside the AMC, with its stem
    (``x.amc`` -> ``x.asf``, which :func:`find_asf` finds again)."""
    return os.path.splitext(os.fspath(amc_path))[0] + ".asf"


def write_asf(motion: Motion, path: StrPath) -> None:
    """Write the ASF skeleton of a motion read from (or decoded from) AMC/ASF."""
    skel = skeleton_of(motion, "asf")
    with open(path, "wb") as fh:
        fh.write(encoded_text(format_asf(skel), skel.encoding))


def write_amc(motion: Motion, path: StrPath, *, asf: StrPath | None = None) -> None:
    """Write the AMC of a motion with an ASF skeleton, and its ASF at ``asf`` (default:
    beside it, :func:`default_asf_path`).

    Raises
    ------
    InputFormatError
        If the motion has no ASF skeleton.
    """
    write_amc_text(motion, path)
    write_asf(motion, default_asf_path(path) if asf is None else asf)


def write_amc_text(motion: Motion, path: StrPath) -> None:
    """Write the AMC of a motion with an ASF skeleton, without its ASF (see
    :func:`write_amc`)."""
    skel = skeleton_of(motion, "asf")
    pieces = _amc_text(motion)
    head, names = next(pieces), next(pieces)
    write_pieces(path, itertools.chain([head], pieces),
                 text_encoding_of(head + names, skel.encoding))

