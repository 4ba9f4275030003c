"""The conformance manifest (``vectors/manifest.json``): load, validate, hash.

Contract: :func:`load` returns the manifest as plain JSON data after
:func:`validate` has checked its shape (schema version, groups, expected
outcomes, tolerances with rms <= max_abs). It never regenerates anything;
``python -m mpz.tools.make_vectors`` is the only writer. :func:`tolerances`
is the one place the float-tier bounds of spec §7.1 are computed, shared by
the generator and the tests.
"""
from __future__ import annotations

import hashlib
import importlib.util
import json
import math
from pathlib import Path
import re

#: 2: decodable vectors' header has ``meta`` (the §7.3 sidecar), every vector and encoder
#: input lists the ``rules`` of the spec §7.4 rule index it probes, ``rule_exceptions``
SCHEMA_VERSION = 2
#: Vector groups, as subfolders of the vector directory (FLAC test-file style).
GROUPS = ("valid", "uncommon", "invalid")
#: What a decoder must do with a vector of each group.
EXPECTED = {"valid": "decode", "uncommon": "decode", "invalid": "reject"}
#: The vectors shipped with the package.
def _vectors_dir() -> Path:
    # conformance/vectors/ is installed as the data-only package mpz.conformance.vectors
    # (pyproject.toml), so the same lookup works in a checkout and in a wheel
    spec = importlib.util.find_spec("mpz.conformance.vectors")
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError("the conformance vectors are not installed (mpz.conformance.vectors)")
    return Path(list(spec.submodule_search_locations)[0])


DEFAULT_DIR = _vectors_dir()
MANIFEST_NAME = "manifest.json"
#: the file of spec Appendix A, written by ``python -m mpz.tools.spec_example``
SPEC_EXAMPLE = "spec-example.mpz"

#: §7.1 float tier: |x - x_ref| <= step * 2^-20 + max|x_ref| * 2^-50
STEP_FRACTION = 2.0 ** -20
MAGNITUDE_FRACTION = 2.0 ** -50


class ManifestError(ValueError):
    """The manifest is missing, malformed or disagrees with the files."""


def sha256_file(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def tolerances(step: float, max_abs_value: float) -> dict:
    """Float-tier tolerances of one vector (spec §7.1).

    ``max_abs = step * 2^-20 + max|x| * 2^-50``, where ``max|x|`` is the
    largest magnitude of any valid expected coordinate. A decoder that
    computes ``offset + q * step`` in binary64 (§6.8), in either order or with
    a fused multiply-add, stays far inside it; one grid step off never does.
    ``rms`` uses the same value: a uniform error of max_abs has exactly that
    RMS, so rms <= max_abs holds by construction (and is checked).
    """
    v = float(step) * STEP_FRACTION + float(max_abs_value) * MAGNITUDE_FRACTION
    return {"max_abs": v, "rms": v}


def intlayer_digest(q, valid) -> str:
    """§7.1 integer-layer digest: sha256 of q (<i8, [F, M, 3], C order), then valid
    (u1 0/1, [F, M])."""
    import numpy as np
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(q, dtype="<i8").tobytes())
    h.update(np.ascontiguousarray(valid, dtype=np.uint8).tobytes())
    return h.hexdigest()


def exercised_sections(stream) -> list:
    """Spec sections a decodable file exercises, derived from its content (not declared).

    ``stream`` is an :class:`mpz.decoder.Stream`. A section counts only when
    the file makes it do real work: §6.1 needs a MASK chunk, §6.3 a node with
    patterns, §6.4 smoothing h > 0 across at least one boundary, §6.5 a RESI
    chunk, §6.6 a non-root node.
    """
    from mpz.chunks import CHUNKS
    from mpz.decoder import decode_segments
    from mpz.extensions import owner
    secs = {"§3.1", "§3.2", "§3.3", "§3.4", "§4.1", "§4.2", "§4.3", "§4.4", "§4.6", "§4.12",
            "§5.1", "§5.2", "§5.3", "§5.4", "§5.5", "§5.6", "§6.2", "§6.7", "§6.8", "§7.1"}
    if s_has(stream.mask):
        secs |= {"§4.5", "§6.1"}
    if len(stream.nodes) > 1:
        secs |= {"§4.7", "§6.6"}
    for i, c in stream.patt.items():
        if c.record.pattern_count:
            secs |= {"§4.8", "§6.3"}
            _, counts = decode_segments(stream, i)
            if stream.header.smoothing and len(counts) > 1:
                secs.add("§6.4")
    if stream.resi:
        secs |= {"§4.9", "§6.5"}
    if stream.summary is not None:
        secs.add(type(stream.summary.record).SECTION)      # smry §4.10, smrc §4.15 (1.1)
    if stream.meta:
        secs.add("§4.11")
    if stream.unknown:
        secs.add("§2.3")
    for ctype in stream.extras:              # the extensions' chunks (1.1: issues 12, 13)
        ext = owner(ctype)
        assert ext is not None, f"{ctype} is kept as an extra but no extension owns it"
        secs |= {"§2.1", *ext.sections, CHUNKS[ctype].SECTION}
    return sorted(secs, key=section_key)


def s_has(x) -> bool:
    return x is not None


def section_key(s: str) -> tuple:
    return tuple(int(p) for p in s.lstrip("§").split("."))


def spec_decoding_steps(text: str) -> list:
    """(step, section, name) rows of the machine-readable table of spec §6.

    The table sits between ``<!-- mpz:decoding-steps -->`` and
    ``<!-- /mpz:decoding-steps -->`` with columns ``Step | Section | Name | Rule``.
    """
    import re
    m = re.search(r"<!--\s*mpz:decoding-steps\s*-->(.*?)<!--\s*/mpz:decoding-steps\s*-->", text,
                  re.S)
    if not m:
        raise ManifestError("spec has no <!-- mpz:decoding-steps --> table")
    rows = []
    for line in m.group(1).splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 3 and cells[0].isdigit():
            sec = re.fullmatch(r"§\d+(\.\d+)*", cells[1])
            if not sec:
                raise ManifestError(f"decoding-step row {line!r}: bad section {cells[1]!r}")
            rows.append((int(cells[0]), cells[1], cells[2]))
    if not rows:
        raise ManifestError("the decoding-steps table has no rows")
    return rows


#: what a rule of the §7.4 rule index needs in the suite: "reject" rules an invalid vector
#: (a file that breaks them), "accept" and "decode" rules a decodable one, "encode" rules an
#: encoder input
RULE_KINDS = ("reject", "accept", "decode", "encode")


def spec_rules(text: str) -> list:
    """(id, section, kind, text) rows of the rule index of spec §7.4.

    The table sits between ``<!-- mpz:rules -->`` and ``<!-- /mpz:rules -->`` with
    columns ``Rule | Section | Kind | Text``; ids are ``R-<section>-<n>`` and unique.
    """
    m = re.search(r"<!--\s*mpz:rules\s*-->(.*?)<!--\s*/mpz:rules\s*-->", text, re.S)
    if not m:
        raise ManifestError("spec has no <!-- mpz:rules --> table")
    rows = []
    seen = set()
    for line in m.group(1).splitlines():
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]
        if len(cells) < 4 or not cells[0].startswith("R-"):
            continue
        rid, sec, kind, what = cells[:4]
        mm = re.fullmatch(r"R-(\d+(?:\.\d+)*)-\d+", rid)
        if not mm or sec != "§" + mm.group(1):
            raise ManifestError(f"rule row {line!r}: id {rid!r} does not name section {sec!r}")
        if kind not in RULE_KINDS:
            raise ManifestError(f"rule {rid}: kind {kind!r} not one of {RULE_KINDS}")
        if rid in seen:
            raise ManifestError(f"rule {rid} listed twice")
        seen.add(rid)
        rows.append((rid, sec, kind, what))
    if not rows:
        raise ManifestError("the rule index has no rows")
    return rows


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _need(cond, msg):
    if not cond:
        raise ManifestError(msg)


def _inside(rel, what: str) -> None:
    """``rel`` names a file inside the suite's folder: a relative path of ``/``-separated
    parts, none of them ``..`` (a vector "file" of ``invalid/../../..`` and an absolute
    ``expected_output`` were read from anywhere: a security QA run, stop 73)."""
    _need(isinstance(rel, str) and rel and "\0" not in rel and "\\" not in rel
          and not rel.startswith("/") and ":" not in rel.split("/")[0]
          and all(part not in ("", ".", "..") for part in rel.split("/")),
          f"{what}: {rel!r:.80} is not a path inside the suite's folder")


def _digest(x, what: str) -> None:
    _need(isinstance(x, str) and re.fullmatch(r"[0-9a-f]{64}", x) is not None,
          f"{what}: sha256 {x!r:.80} is not 64 lower-case hex digits")


def validate(man: dict) -> dict:
    """Check the manifest's structure and the types of every field the runner reads
    (a field of another JSON type was a traceback, exit 70, not the suite's fault it is:
    a security QA run, stop 73); returns it. Raises ManifestError."""
    _need(isinstance(man, dict), "manifest is not a JSON object")
    _need(man.get("schema_version") == SCHEMA_VERSION,
          f"schema_version {man.get('schema_version')!r}, this runner reads {SCHEMA_VERSION}")
    vecs = man.get("vectors")
    _need(isinstance(vecs, list), "manifest has no list of vectors")
    assert isinstance(vecs, list)
    # a manifest of encoder inputs alone is a third-party encoder's own suite (a clean-room
    # encoder had to copy a decoder vector in to run its inputs, stop 64)
    _need(len(vecs) > 0 or bool(man.get("encoder_inputs")),
          "manifest lists no vectors and no encoder inputs")
    rule_id = re.compile(r"R-\d+(\.\d+)*-\d+")
    seen = set()
    for v in vecs:
        _need(isinstance(v, dict), f"a vector entry is not an object: {v!r:.80}")
        name = v.get("name")
        _need(isinstance(name, str) and name, f"vector without a name: {v!r}")
        _need(name not in seen, f"duplicate vector name {name!r}")
        seen.add(name)
        for key in ("file", "sha256", "group", "description", "expected", "spec_sections",
                    "features", "rules"):
            _need(key in v, f"{name}: missing {key!r}")
        _need(isinstance(v["rules"], list) and all(isinstance(r, str) and rule_id.fullmatch(r)
                                                   for r in v["rules"]),
              f"{name}: rules must be a list of rule ids R-<section>-<n>: {v['rules']!r}")
        _need(isinstance(v["group"], str) and v["group"] in GROUPS,
              f"{name}: unknown group {v['group']!r:.80}")
        _need(v["expected"] == EXPECTED[v["group"]],
              f"{name}: group {v['group']} must expect {EXPECTED[v['group']]!r}")
        _inside(v["file"], f"{name}: file")
        _need(v["file"].startswith(v["group"] + "/") or v["file"] == SPEC_EXAMPLE,
              f"{name}: file not under {v['group']}/")
        _digest(v["sha256"], f"{name}: file")
        _need(isinstance(v["spec_sections"], list)
              and all(isinstance(x, str) for x in v["spec_sections"])
              and isinstance(v["features"], dict) and isinstance(v["description"], str),
              f"{name}: spec_sections must be a list of text, features an object and "
              "description text")
        if v["expected"] == "decode":
            for key in ("expected_output", "integer_layer_digest", "tolerances", "header"):
                _need(v.get(key) is not None, f"{name}: decodable vector without {key!r}")
            out = v["expected_output"]
            _need(isinstance(out, dict), f"{name}: expected_output is not an object")
            _inside(out.get("file"), f"{name}: expected_output file")
            _digest(out.get("sha256"), f"{name}: expected_output")
            _need(isinstance(v["integer_layer_digest"], str),
                  f"{name}: integer_layer_digest is not text")
            for key in ("tolerances", "header"):       # the one at fault named (docs QA)
                _need(isinstance(v[key], dict), f"{name}: {key} is not an object")
            tol = v["tolerances"]
            _need(all(isinstance(tol.get(k), (int, float)) and math.isfinite(tol[k]) and tol[k] >= 0
                      for k in ("max_abs", "rms")), f"{name}: bad tolerances {tol!r}")
            _need(tol["rms"] <= tol["max_abs"],
                  f"{name}: rms tolerance {tol['rms']} > max_abs {tol['max_abs']}")
            for key in ("frames", "markers", "rate", "names", "units", "units_code", "meta",
                        "error_bound", "step"):
                _need(key in v["header"], f"{name}: header facts lack {key!r}")
            h = v["header"]
            _need(isinstance(h["meta"], dict), f"{name}: header meta is not an object")
            # the runner computes with these: a string step was a traceback (QA, stop 33)
            _need(all(_finite(h[k]) for k in ("rate", "step", "error_bound"))
                  and h["step"] > 0 and h["rate"] > 0,
                  f"{name}: header rate, step and error_bound must be finite numbers")
            _need(all(isinstance(h[k], int) and not isinstance(h[k], bool) and h[k] >= 0
                      for k in ("frames", "markers", "units_code")),
                  f"{name}: header frames, markers and units_code must be whole numbers")
            _need(isinstance(h["names"], list) and all(isinstance(x, str) for x in h["names"])
                  and isinstance(h["units"], str), f"{name}: header names or units malformed")
        else:
            for key in ("expected_error", "corruption", "risk"):
                _need(v.get(key), f"{name}: invalid vector without {key!r}")
            _need(isinstance(v["expected_error"], str),
                  f"{name}: expected_error is not text")
    inputs = man.get("encoder_inputs", [])
    _need(isinstance(inputs, list), "encoder_inputs is not a list")
    for e in inputs:
        _need(isinstance(e, dict), f"an encoder input is not an object: {e!r:.80}")
        # sidecar_sha256 among them: its absence said "sha256 None" (a docs QA run, stop 74)
        for key in ("name", "input", "sidecar", "sha256", "sidecar_sha256", "max_errors",
                    "rules"):
            _need(key in e, f"encoder input {e!r:.200}: missing {key!r}")
        what = f"encoder input {e['name']!r:.80}"
        _need(isinstance(e["name"], str) and e["name"], f"{what}: name is not text")
        _inside(e["input"], f"{what}: input")
        _inside(e["sidecar"], f"{what}: sidecar")
        _digest(e["sha256"], f"{what}: input")
        _digest(e["sidecar_sha256"], f"{what}: sidecar")
        _need(isinstance(e["max_errors"], list) and e["max_errors"]
              and all(_finite(x) and x > 0 for x in e["max_errors"]),
              f"{what}: max_errors must be a list of finite numbers above 0")
    exc = man.get("rule_exceptions", {})
    _need(isinstance(exc, dict) and all(rule_id.fullmatch(k) and isinstance(r, str) and r
                                        for k, r in exc.items()),
          "rule_exceptions must map rule ids to a non-empty reason")
    return man


#: the most of a manifest.json that is read (the shipped one is well under 1 MiB)
MAX_MANIFEST_BYTES = 64 << 20


def load(directory=None) -> dict:
    """Read and validate ``manifest.json`` of ``directory`` (default: the shipped vectors)."""
    d = Path(directory) if directory is not None else DEFAULT_DIR
    path = d / MANIFEST_NAME
    from mpz.api import read_source
    from mpz.errors import FormatError
    try:                    # a FIFO hung and /dev/zero read without end (QA, stop 33)
        text = read_source(path, limit=MAX_MANIFEST_BYTES)[0].decode("utf-8")
    except FormatError as exc:      # not a regular file, or larger than the limit
        raise ManifestError(f"cannot read {path}: {exc.message}") from None
    except OSError as exc:
        raise ManifestError(f"cannot read {path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise ManifestError(f"{path}: not UTF-8: {exc}") from None
    try:
        man = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ManifestError(f"{path}: not JSON: {exc}") from None
    except RecursionError:          # 100,000 nested brackets
        raise ManifestError(f"{path}: not JSON this runner reads: nested too deeply") from None
    return validate(man)


def check_hashes(man: dict, directory=None) -> list:
    """Every mismatch between the manifest's sha256 values and the files, as messages."""
    d = Path(directory) if directory is not None else DEFAULT_DIR
    problems = []
    items = []
    for v in man["vectors"]:
        items.append((v["file"], v["sha256"]))
        if v.get("expected_output"):
            items.append((v["expected_output"]["file"], v["expected_output"]["sha256"]))
    for e in man.get("encoder_inputs", []):
        items.append((e["input"], e["sha256"]))
        items.append((e["sidecar"], e["sidecar_sha256"]))
    for rel, digest in items:
        p = d / rel
        if not p.is_file():
            problems.append(f"{rel}: missing")
        elif sha256_file(p) != digest:
            problems.append(f"{rel}: sha256 {sha256_file(p)} != manifest {digest}")
    return problems


def vectors(man: dict, only=None) -> list:
    """The manifest's vectors, optionally restricted to ``only``: names, files (with or
    without their folder and extension), groups, or ``group/name`` as the runner prints
    them (:func:`selectors`)."""
    vs = man["vectors"]
    if not only:
        return list(vs)
    want = set(only)
    return [v for v in vs if selectors(v) & want]


def selectors(v: dict) -> set[str]:
    """What ``--only`` may call vector ``v``: its name, its file with and without its
    folder and extension, its group, and ``group/name`` (the runner's PASS/FAIL label:
    it was refused, a QA of stop 42)."""
    stem = Path(v["file"]).name
    return {v["name"], v["file"], stem, Path(stem).stem, v["group"], f"{v['group']}/{v['name']}"}
