"""Issue 11.6: bad encoder inputs and options are EncoderErrors that name the option or the
field, raised before any work; no other exception escapes the encoder, from the API or from
``mpz encode``.

Each row was, before the checks, one of: a ValueError from scipy's linkage (magnitudes of
1e155 and more), a ZeroDivisionError (max_error 5e-324), a ValueError (max_error 1e308), a
UnicodeEncodeError after the whole encode (names that UTF-8 cannot hold), a TypeError
(hierarchy JSON of the wrong types), an OverflowError (a weight of 1e308), or a ValueError
from the command line (``--summary x``, ``--weight M1=abc``).
"""
from __future__ import annotations

import json
from pathlib import Path
import re
import subprocess
import sys
from typing import Any

import numpy as np
import pytest

import mpz
from mpz.encoder import EncodeOptions, encode_motion
from mpz.errors import EncoderError, MotionError, MPZError
import mpz.io
from mpz.motion import Motion
from mpz.synth import generate


@pytest.fixture(scope="module")
def walk() -> Motion:
    return generate("walk", frames=24, markers=6, seed=1)


# (option values, words the message must hold: the option's name and the value at fault)
OPTIONS: list[tuple[dict[str, Any], tuple[str, ...]]] = [
    ({"max_error": 5e-324}, ("max_error", "5e-324")),
    ({"max_error": 1e308}, ("max_error", "1e+308")),
    ({"max_error": float("nan")}, ("max_error", "nan")),
    ({"max_error": True}, ("max_error", "True")),
    ({"max_error": "1"}, ("max_error", "'1'")),
    ({"max_error": 10 ** 400}, ("max_error",)),
    ({"grid": 5e-324, "lossy": True}, ("grid", "5e-324")),
    ({"grid": 1e308, "lossy": True}, ("grid", "1e+308")),
    ({"max_error": 1.0, "group_errors": {"root": 5e-324}}, ("group error", "root")),
    ({"max_error": 1.0, "group_errors": ["root"]}, ("group_errors", "mapping")),
    ({"theta": float("inf"), "lossy": True}, ("theta", "inf")),
    ({"tau": 1e308, "lossy": True}, ("tau", "1e+308")),
    ({"tau": -1.0, "lossy": True}, ("tau",)),
    ({"k0": "3", "lossy": True}, ("k0", "'3'")),
    ({"k0": 0, "lossy": True}, ("k0", "0")),
    ({"smoothing": 2.5}, ("smoothing", "2.5")),
    ({"smoothing": 17}, ("smoothing", "17")),
    ({"max_segment": 2.5, "lossy": True}, ("max_segment", "2.5")),
    ({"seed": -1}, ("seed", "-1")),
    ({"seed": 2 ** 70}, ("seed",)),
    ({"metric": None, "lossy": True}, ("metric", "None")),
    ({"summary": ("x",)}, ("summary", "'x'")),
    ({"summary": (0,)}, ("summary", "0")),
    ({"summary": tuple(range(1, 66))}, ("summary", "64")),
    ({"summary_space": "joints", "summary": (2,)}, ("summary_space", "joints")),
    ({"weights": {"LFHD": 1e308}}, ("weight", "LFHD", "1e+308")),
    ({"weights": {"LFHD": float("nan")}}, ("weight", "LFHD")),
    ({"weights": {"LFHD": "2"}}, ("weight", "LFHD", "'2'")),
    ({"weights": {"LFHD": 0.01}}, ("weight", "LFHD", "1/16")),
    ({"weights": "LFHD=2"}, ("weights", "mapping")),
    ({"metadata": {"take": "a\udcff"}}, ("metadata value", "take", "surrogate")),
    ({"metadata": {"\udcff": "x"}}, ("metadata key", "surrogate")),
    ({"metadata": {"take": 3}}, ("metadata must map str to str", "value of 'take'", "int")),
    ({"metadata": {3: "x"}}, ("metadata must map str to str", "a key is int 3")),
    ({"lossy": "yes"}, ("lossy",)),
    ({"model_errors": None}, ("model_errors", "mapping")),
]


@pytest.mark.parametrize("options,words", OPTIONS, ids=[repr(o)[:48] for o, _ in OPTIONS])
def test_bad_options_are_named(walk: Motion, options: dict[str, Any],
                               words: tuple[str, ...]) -> None:
    with pytest.raises(EncoderError) as got:
        encode_motion(walk, EncodeOptions(**options))
    for w in words:
        assert w in str(got.value), (w, str(got.value))


def _with(m: Motion, **kw: Any) -> Motion:
    fields: dict[str, Any] = {"positions": m.positions, "names": list(m.names), "rate": m.rate,
              "units": m.units, "valid": m.valid, "metadata": dict(m.metadata)}
    fields.update(kw)
    return Motion(**fields)


# (what is wrong with the motion, words of the message)
MOTIONS: list[tuple[str, Any, tuple[str, ...]]] = [
    ("magnitude 1e155", lambda m: _with(m, positions=m.positions * 1e155),
     ("position magnitude", "frame", "1e+100")),
    ("magnitude 1e300", lambda m: _with(m, positions=m.positions * 1e300),
     ("position magnitude",)),
    ("a name UTF-8 cannot hold", lambda m: _with(m, names=["A\udce9"] + list(m.names[1:])),
     ("marker 0 name", "surrogate")),
    ("a name of 256 bytes", lambda m: _with(m, names=["\u00e9" * 128] + list(m.names[1:])),
     ("marker 0 name", "255 bytes")),
    ("a name with NUL", lambda m: _with(m, names=["A\x00B"] + list(m.names[1:])),
     ("marker 0 name", "NUL")),
    ("metadata UTF-8 cannot hold", lambda m: _with(m, metadata={"subject": "\udcc3"}),
     ("metadata value", "subject")),
]


@pytest.mark.parametrize("what,make,words", MOTIONS, ids=[m[0] for m in MOTIONS])
@pytest.mark.parametrize("mode", [{}, {"max_error": 1.0}, {"lossy": True}],
                         ids=["default", "bounded", "lossy"])
def test_bad_motions_are_named(walk: Motion, what: str, make: Any, words: tuple[str, ...],
                               mode: dict[str, Any]) -> None:
    with pytest.raises(EncoderError) as got:
        mpz.encode(make(walk), **mode)
    for w in words:
        assert w in str(got.value), (w, str(got.value))


def test_largest_magnitude_still_encodes(walk: Motion) -> None:
    """The limit is not a step too early: magnitudes of 1e100 encode and decode within the
    bound (the test above must fail for a reason, not for any large value)."""
    m = _with(walk, positions=walk.positions / np.abs(walk.positions).max() * 1e100)
    out = mpz.decode(mpz.encode(m, max_error=1e97))
    assert mpz.max_error(m, out) <= 1e97


def test_too_many_markers_are_said_before_the_metadata_they_make() -> None:
    """A C3D QA run: 32800 points with 255 labels were refused for the 575 KB metadata
    value listing the names made for the others (§4.11), not for being past §8's 4096
    markers, which the encoder checks first now."""
    M = 4097
    m = Motion(np.zeros((1, M, 3)), [f"p{i}" for i in range(M)], 100.0, "mm",
               metadata={"renamed_points": "x" * 70000})
    with pytest.raises(EncoderError, match=r"1 frames x 4097 markers exceeds the limits of "
                                           r"spec §8"):
        mpz.encode(m)


def _hier(nodes: list[Any]) -> dict[str, Any]:
    return {"format": "mpz-hierarchy", "version": 1, "nodes": nodes}


def _good(names: list[str]) -> list[dict[str, Any]]:
    return [{"name": "root", "members": [names[0]], "ref": names[0], "parent": None},
            {"name": "body", "members": names[1:], "ref": names[1], "parent": "root"}]


# (how the JSON is wrong, edit of the good node list, words of the message)
HIERARCHIES: list[tuple[str, Any, tuple[str, ...]]] = [
    ("node is text", lambda g, n: ["root", g[1]], ("node 0", "object")),
    ("node is a list", lambda g, n: [[1, 2], g[1]], ("node 0", "object")),
    ("name missing", lambda g, n: [{k: v for k, v in g[0].items() if k != "name"}, g[1]],
     ("node 0", "name")),
    ("name is a list", lambda g, n: [dict(g[0], name=["a"]), g[1]], ("node 0", "name")),
    ("members is text", lambda g, n: [dict(g[0], members=n[0]), g[1]], ("members",)),
    ("members is a number", lambda g, n: [dict(g[0], members=5), g[1]], ("members", "5")),
    ("a member is an object", lambda g, n: [dict(g[0], members=[{}]), g[1]], ("members",)),
    ("members empty", lambda g, n: [g[0], dict(g[1], members=[])], ("node 1", "members")),
    ("ref is a list", lambda g, n: [dict(g[0], ref=[n[0]]), g[1]], ("ref",)),
    ("parent is a list", lambda g, n: [g[0], dict(g[1], parent=["root"])], ("parent",)),
    ("parent is a number", lambda g, n: [g[0], dict(g[1], parent=0)], ("parent", "0")),
    ("weights is a list", lambda g, n: [g[0], dict(g[1], weights=[1, 2])], ("weights",)),
    ("weight is text", lambda g, n: [g[0], dict(g[1], weights={n[1]: "2"})],
     ("weight", "'2'")),
    ("weight is true", lambda g, n: [g[0], dict(g[1], weights={n[1]: True})],
     ("weight", "True")),
    ("weight 1e308", lambda g, n: [g[0], dict(g[1], weights={n[1]: 1e308})],
     ("weight", "1e+308", "1/16")),
    # a misspelt field was ignored, and the weights it held with it (a QA run of the API)
    ("weights misspelt", lambda g, n: [g[0], dict(g[1], weigths={n[1]: 2.0})],
     ("node 1", "'body'", "unknown field 'weigths'", "weights")),
]


@pytest.mark.parametrize("what,edit,words", HIERARCHIES, ids=[h[0] for h in HIERARCHIES])
def test_hierarchy_json_types(walk: Motion, what: str, edit: Any,
                              words: tuple[str, ...]) -> None:
    names = list(walk.names)
    with pytest.raises(EncoderError) as got:
        mpz.encode(walk, hierarchy=_hier(edit(_good(names), names)))
    for w in words:
        assert w in str(got.value), (w, str(got.value))


def test_good_hierarchy_json_still_encodes(walk: Motion) -> None:
    names = list(walk.names)
    nodes = _good(names)
    nodes[1]["weights"] = {names[1]: 2, names[2]: 0.5}
    nodes[1]["why"] = "free text, as cmu41.json's"
    out = mpz.decode(mpz.encode(walk, hierarchy=_hier(nodes), max_error=1.0))
    assert mpz.max_error(walk, out) <= 1.0


# ------------------------------------------------------------------- the CLI --
@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory, walk: Motion) -> Path:
    d = tmp_path_factory.mktemp("inputs")
    np.save(d / "walk.npy", walk.positions)                 # NPY: no units, bare lengths
    np.save(d / "big.npy", walk.positions * 1e155)
    names = [f"M{i}" for i in range(walk.n_markers)]
    (d / "bad.json").write_text(json.dumps(_hier([
        {"name": "root", "members": names[0], "ref": names[0], "parent": None},
        {"name": "body", "members": names[1:], "ref": names[1], "parent": "root"}])))
    return d


# (arguments after the input, the input, words the error must hold)
CLI: list[tuple[list[str], str, tuple[str, ...]]] = [
    (["--max-error", "5e-324"], "walk.npy", ("--max-error", "5e-324", "1e-300")),
    (["--max-error", "1e308"], "walk.npy", ("--max-error", "1e308", "1e+300")),
    (["--summary", "x"], "walk.npy", ("--summary", "x")),
    (["--summary", "0"], "walk.npy", ("summary", "0")),
    (["--weight", "M1=abc"], "walk.npy", ("--weight", "M1=abc")),
    (["--weight", "M1=1e308"], "walk.npy", ("weight", "M1", "1e+308")),
    (["--theta", "nan"], "walk.npy", ("theta", "nan")),
    (["--tau", "1e308"], "walk.npy", ("tau", "1e+308")),
    (["--grid", "5e-324"], "walk.npy", ("grid", "5e-324")),
    (["--smoothing", "99"], "walk.npy", ("smoothing", "99")),
    (["--hierarchy", "{dir}/bad.json"], "walk.npy", ("members",)),
    ([], "big.npy", ("position magnitude",)),
]


@pytest.mark.parametrize("args,source,words", CLI, ids=[" ".join(c[0]) or c[1] for c in CLI])
def test_cli_bad_inputs(inputs: Path, tmp_path: Path, args: list[str], source: str,
                        words: tuple[str, ...]) -> None:
    out = tmp_path / "out.mpz"
    argv = [a.replace("{dir}", str(inputs)) for a in args]
    run = subprocess.run([sys.executable, "-m", "mpz.tools.mpz_cli", "encode",
                          str(inputs / source), "-o", str(out), *argv],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode in (2, 64), (run.returncode, run.stderr)   # bad input or usage
    assert "Traceback" not in run.stderr, run.stderr
    for w in words:
        assert w in run.stderr, (w, run.stderr)
    assert not out.exists()


def test_cli_latin1_c3d_label(tmp_path: Path) -> None:
    """A C3D label that is not UTF-8 (one latin-1 byte): read as latin-1, encoded as UTF-8,
    decoded back with its name (no UnicodeEncodeError after the encode)."""
    ezc3d = pytest.importorskip("ezc3d")
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = ["ABCD", "EFGH"]
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    pts = np.ones((4, 2, 10))
    pts[:3] = np.random.default_rng(0).normal(size=(3, 2, 10)) * 100
    c["data"]["points"] = pts
    src = tmp_path / "lab.c3d"
    c.write(str(src))
    raw = bytearray(src.read_bytes())
    at = raw.find(b"ABCD")
    raw[at + 2] = 0xE9                                      # "AB\xe9D": not UTF-8
    src.write_bytes(bytes(raw))
    out = tmp_path / "lab.mpz"
    run = subprocess.run([sys.executable, "-m", "mpz.tools.mpz_cli", "encode", str(src),
                          "-o", str(out), "--max-error", "1mm", "-q"],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    assert mpz.decode(out.read_bytes()).names == ["AB\u00e9D", "EFGH"]


def test_what_an_encode_does_not_keep(walk: Motion, two_joint_bvh: str) -> None:
    """mpz.encoder.not_kept, the rule every report uses (issue 12: a ratio counts what was
    kept): nothing for plain markers; a C3D's analog and parameters when the reader could
    not keep its archive; a skeletal motion's angles without its skeleton chunk."""
    from dataclasses import replace

    from mpz.encoder import not_kept
    from mpz.io.bvh import parse_bvh
    opts = EncodeOptions(max_error=1.0)
    assert not_kept(walk, opts) == []
    meta = {**walk.metadata, "format": "c3d", "warning": "C3D archive not kept: odd file"}
    c3d = Motion(walk.positions, walk.names, walk.rate, walk.units, walk.valid, meta)
    assert not_kept(c3d, opts) == \
        ["analog, parameters and residuals (C3D archive not kept: odd file)"]
    bvh = parse_bvh(two_joint_bvh)
    assert not_kept(bvh, opts) == []
    assert not_kept(bvh, replace(opts, keep_skeleton=False)) == \
        ["joint angles and the skeleton"]
    data, rep = mpz.encoder.encode_motion(bvh, replace(opts, keep_skeleton=False))
    assert rep.not_kept == ["joint angles and the skeleton"]



# ---- from a QA run of the Python API (stop 29) ----------------------------------------
@pytest.mark.parametrize("change,match", [
    (dict(names=["A", b"x"]), "names must be str"),        # str(b"x") was "b'x'"
    (dict(names=["A", None]), "names must be str, got NoneType"),   # was kept (stop 77)
    (dict(rate="100"), "rate must be a number"),
    (dict(rate=True), "rate must be a number"),
    (dict(valid=np.full((2, 2), 0.5)), "booleans"),          # 0.5 was True
    (dict(positions=np.zeros((2, 2, 3), complex)), "real numbers"),   # imaginary part lost
    (dict(metadata={1: "x"}), "metadata must map str to str"),   # became "1" (stop 37's
    (dict(metadata={"take": 2.5}), "metadata must map str to str"),   # QA); encode(metadata=)
    (dict(metadata={"n": None}), "metadata must map str to str"),     # refused them
    (dict(metadata={"k" * 80: 1}), r"the value of 'k{56}\.\.\. is int"),   # cut, said so
    (dict(metadata=5), "metadata must be a mapping"),      # TypeError (a QA run, stop 38)
])
def test_motion_refuses_what_it_converted_silently(change, match):
    args = dict(positions=np.zeros((2, 2, 3)), names=["A", "B"], rate=100.0)
    args.update(change)
    with pytest.raises(MotionError, match=match):
        Motion(**args)
    args = dict(positions=np.zeros((2, 2, 3)), names=[np.str_("A"), "B"], rate=np.float32(50),
                valid=np.ones((2, 2), np.int8))          # what stays accepted
    assert Motion(**args).valid.all()
    assert Motion(**args, metadata=None).metadata == {}    # "optional": None is none


@pytest.mark.parametrize("change", [
    lambda m: setattr(m, "rate", -5.0),
    lambda m: setattr(m, "units", "furlong"),
    lambda m: m.names.append("X"),
    lambda m: m.positions.__setitem__((0, 0, 0), np.nan),
])
def test_encode_checks_a_motion_changed_after_it_was_made(change):
    """A Motion is mutable: the encoder made a file the decoder rejects (rate -5), lost the
    units, or raised IndexError; now the constructor's checks run again."""
    m = generate("walk", frames=20, seed=1)
    change(m)
    with pytest.raises(EncoderError, match="not consistent"):
        mpz.encode(m, max_error=1.0)


def test_metadata_set_to_none_after_the_motion_was_made_is_refused():
    """Motion(metadata=None) is no metadata, but None set afterwards reached the encoder's
    checks as None: AttributeError (a QA run, stop 38). It is refused in words."""
    m = generate("walk", frames=20, seed=1)
    m.metadata = None   # type: ignore[assignment]
    with pytest.raises(EncoderError, match="metadata must be a mapping of str to str, got "
                       "NoneType"):
        mpz.encode(m, max_error=1.0)


@pytest.mark.parametrize("meta,match", [
    ({"k" * 256: "v"}, "256 bytes"),
    ({"": "v"}, "0 bytes"),
    ({"k": "v" * 65536}, "65536 bytes"),
])
def test_metadata_beyond_the_limits_is_refused_not_cut(meta, match):
    """§4.11's limits: values were cut to 65535 bytes, keys to 255 (two long keys became
    one), an empty key became '_', all silently."""
    m = generate("walk", frames=20, seed=1)
    with pytest.raises(EncoderError, match=match):
        mpz.encode(m, max_error=1.0, metadata=meta)
    with pytest.raises(EncoderError, match=match):      # judged without a motion too (stop 34)
        EncodeOptions(max_error=1.0, metadata=meta).validate()
    ok = {"k" * 255: "v" * 65535}
    assert mpz.decode(mpz.encode(m, max_error=1.0, metadata=ok)).metadata["k" * 255] == "v" * 65535


@pytest.mark.parametrize("key", ["format", "units_in_file", "channels", "trc.Decimals",
                                 "trc.FirstFrame", "csv.FirstFrame"])
def test_metadata_keys_the_readers_set_are_refused_as_by_the_cli(key, tmp_path):
    """A QA run of stop 48: mpz.encode(metadata={"format": "bvh"}) was taken (the CLI's
    --meta format=bvh is refused), and `mpz decode` of the file could not name its output.
    "subject" describes a person and "source" names the file (mpz decode names its output
    by it): both stay allowed; a reader's own keys still go in. So do a TRC's and a CSV's
    header fields (stop 54's list: metadata={"trc.Decimals": "1"} replaced the source's
    own, and its TRC was written back with one decimal)."""
    m = generate("walk", frames=20, seed=1)
    with pytest.raises(EncoderError, match=f"metadata '{key}': a key the readers set") as e:
        mpz.encode(m, max_error=1.0, metadata={key: "bvh"})
    # the name it suggests is taken (a review of stop 56: trc.Decimals_note was refused
    # in turn, suggesting trc.Decimals_note_note)
    suggested = re.search(r"e\.g\. (\S+)$", str(e.value))
    assert suggested, str(e.value)
    assert mpz.decode(mpz.encode(m, max_error=1.0, metadata={suggested[1]: "v"})
                      ).metadata[suggested[1]] == "v"
    data = mpz.encode(m, max_error=1.0, metadata={"subject": "P07", "source": "w.c3d"})
    assert mpz.decode(data).metadata["subject"] == "P07"
    (tmp_path / "g.mpz").write_bytes(data)
    p = subprocess.run([str(Path(sys.executable).parent / "mpz"), "decode", "g.mpz"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and (tmp_path / "g.c3d").exists(), p.stderr
    from mpz.io import read, write
    write(m, tmp_path / "w.trc")
    got = mpz.decode(mpz.encode(read(tmp_path / "w.trc"), max_error=1.0)).metadata
    assert got["format"] == "trc" and got["source"] == "w.trc"


@pytest.mark.parametrize("ext", [".c3d", ".trc", ".npy", ".csv"])
def test_write_to_a_missing_folder_says_so(tmp_path, ext):
    """ezc3d wrote nothing and returned: a C3D lost without a word."""
    m = generate("walk", frames=5, seed=1)
    with pytest.raises(FileNotFoundError, match="no folder"):
        mpz.io.write(m, tmp_path / "nowhere" / f"x{ext}")


def test_write_returns_what_the_format_does_not_hold(tmp_path):
    m = generate("walk", frames=5, seed=1)
    m.metadata["project"] = "demo"
    m.positions[2, 3] = 0.0
    notes = mpz.io.write(m, tmp_path / "x.c3d")
    assert any("'project'" in n for n in notes), notes
    assert any("(0, 0, 0)" in n and "frame 2" in n for n in notes), notes
    back = mpz.io.read(tmp_path / "x.c3d")
    assert not back.valid[2, 3] and "project" not in back.metadata     # what the notes say
    plain = generate("walk", frames=5, seed=1)
    plain.metadata.clear()                    # the generator's own keys are free metadata
    # float64 points stored as float32 are said since stop 50 (rounding_notes, no bound)
    assert [n[:29] for n in mpz.io.write(plain, tmp_path / "y.c3d")] == [
        "C3D stores points as float32:"]
    m2 = Motion(np.ones((2, 1, 3)), ["L" * 256], 100.0)
    with pytest.raises(MPZError, match="255 bytes"):
        mpz.io.write(m2, tmp_path / "z.c3d")


@pytest.mark.parametrize("shift,bound", [(1e7, 1e-7), (1e12, 1e-3)])
def test_the_bound_holds_at_large_coordinates(shift, bound):
    """§6.8's binary64 rounding at coordinates of 1e7 took the error to 1.005e-7 for a bound
    of 1e-7 (within §7.2's float slack, but not the bound the file declares): the encoder
    now keeps a margin of 2^-49 of the largest coordinate."""
    m = generate("walk", frames=40, seed=2)
    m = Motion(m.positions / 1000 + shift, m.names, m.rate, m.units, m.valid)   # 1.6 wide
    back = mpz.decode(mpz.encode(m, max_error=bound))
    err = np.linalg.norm(back.positions[m.valid] - m.positions[m.valid], axis=1)
    assert err.max() <= bound
    with pytest.raises(EncoderError, match="^max error [0-9.e+-]+ is too fine for coordinates"):
        mpz.encode(m, max_error=shift * 2.0 ** -52)


def test_a_group_error_too_fine_for_its_coordinates_is_named() -> None:
    """The message named the max error (its value too) when a node's group error was the
    bound too fine to hold (QA, stop 45)."""
    m = generate("walk", frames=40, seed=2)
    fine = float(np.abs(m.positions[m.valid]).max()) * 2.0 ** -52
    with pytest.raises(EncoderError, match=f"^group error torso={fine:g} is too fine "
                                           "for coordinates of "):
        mpz.encode(m, max_error=1.0, group_errors={"torso": fine})
    with pytest.raises(EncoderError, match=f"^max error {fine:g} is too fine"):
        mpz.encode(m, max_error=fine, group_errors={"torso": 1.0})


@pytest.mark.parametrize("kw,match", [
    (dict(keep_skeleton="no"), "keep_skeleton must be True or False"),   # was taken as True
    (dict(angle_error=-1), "angle_error must be a finite number above 0"),
    (dict(translation_error=float("nan")), "translation_error must be"),
    (dict(position_error=0), "position_error must be"),
    (dict(angle_error="1"), "angle_error must be a number"),
    (dict(summary=6), "summary must be a sequence"),        # 'int' object is not iterable
])
def test_options_are_checked_whatever_the_motion(kw, match):
    """The skeleton options were checked only for a motion with a skeleton; a bad one
    was accepted silently on any other."""
    with pytest.raises(EncoderError, match=match):
        mpz.encode(generate("walk", frames=10, seed=1), max_error=1.0, **kw)


def test_decode_arguments_are_checked(tmp_path):
    data = mpz.encode(generate("walk", frames=10, seed=1), max_error=1.0)
    for bad, exc in ((None, TypeError), (2.5, TypeError), (True, TypeError), (0, ValueError),
                     (-1, ValueError)):
        with pytest.raises(exc, match="max_samples"):
            mpz.decode(data, max_samples=bad)
    p = tmp_path / "a.mpz"
    p.write_bytes(data)
    with open(p) as text, pytest.raises(TypeError, match="binary mode"):
        mpz.decode(text)                     # it failed inside, in a bytes join
    assert mpz.decode(np.frombuffer(data, np.uint8)).n_frames == 10
    with pytest.raises(TypeError, match="uint8"):
        mpz.decode(np.frombuffer(data, np.int8))


def test_error_metrics_refuse_motions_that_do_not_line_up():
    """mpz.max_error compared sample arrays only: the same motion in cm scored 1518 against
    itself in mm, and reordered markers scored their distances. A motion without units is
    still compared as numbers (NPY)."""
    m = generate("walk", frames=10, seed=1)
    cm = Motion(m.positions / 10, m.names, m.rate, "cm", m.valid)
    with pytest.raises(MotionError, match="units differ"):
        mpz.max_error(m, cm)
    rev = Motion(m.positions[:, ::-1], m.names[::-1], m.rate, m.units, m.valid[:, ::-1])
    with pytest.raises(MotionError, match="names differ at index 0"):
        mpz.max_error(m, rev)
    bare = Motion(m.positions, m.names, m.rate, "", m.valid)
    assert mpz.max_error(m, bare) == 0.0
    assert m.duration == mpz.info(mpz.encode(m, max_error=1.0)).duration == 10 / m.rate


def test_concatenate_refuses_what_it_would_drop(two_joint_bvh, tmp_path):
    """It kept the first motion's metadata and dropped the others' and every joint angle."""
    a, b = generate("walk", frames=5, seed=1), generate("walk", frames=5, seed=1)
    b.metadata["take"] = "2"
    with pytest.raises(MotionError, match="metadata differ at 'take'"):
        mpz.concatenate([a, b])
    p = tmp_path / "arm.bvh"
    p.write_text(two_joint_bvh)
    s = mpz.io.read(p)
    both = mpz.concatenate([s, s])
    assert both.angles is not None and both.angles.shape == (6, s.angles.shape[1])
    bare = Motion(s.positions, s.names, s.rate, s.units, s.valid, s.metadata)
    with pytest.raises(MotionError, match="joint angles on some"):
        mpz.concatenate([s, bare])
    assert mpz.concatenate([a, a]).n_frames == 10


def test_concatenate_names_where_two_skeletons_differ(two_joint_bvh, tmp_path):
    """Two cuts of one AMC were refused as "skeleton vs skeleton; a C3D archive belongs to
    its own frames" (a QA run of stop 63): the refusal names the field, as for metadata,
    and a join of equal skeletons still works."""
    import dataclasses
    p = tmp_path / "arm.bvh"
    p.write_text(two_joint_bvh)
    s = mpz.io.read(p)
    skel = s.extras["skeleton"]
    other = dataclasses.replace(s, extras={**s.extras, "skeleton": dataclasses.replace(
        skel, first_frame=skel.first_frame + 3)})
    with pytest.raises(MotionError, match=r"extras\['skeleton'\] differ at 'first_frame': "
                                          rf"{skel.first_frame} vs {skel.first_frame + 3} "
                                          r"\(make them equal first; cuts of one "):
        mpz.concatenate([s, other])
    assert mpz.concatenate([other, other]).extras["skeleton"] == other.extras["skeleton"]


def test_a_long_marker_name_is_shown_short_in_the_error():
    """The refusal of a 100,000-character name repeated it whole: a 100 KB message."""
    m = Motion(np.zeros((2, 1, 3)), ["x" * 100_000], 100.0)
    with pytest.raises(EncoderError, match=r"\(100000 characters\): marker names are") as e:
        mpz.encode(m, max_error=1.0)
    assert len(str(e.value)) < 300


def test_options_cross_processes_and_key_caches(walk: Motion) -> None:
    """EncodeOptions (frozen, its mappings read-only) pickles, deep-copies, hashes and
    turns into a dict (API review F2: its MappingProxyType fields made all four fail, so a
    concurrent.futures process pool could not take it), and a process pool's encode gives
    the bytes of this process's."""
    from concurrent.futures import ProcessPoolExecutor
    import copy
    import dataclasses
    import multiprocessing
    import pickle
    opts = EncodeOptions(max_error=1.0, group_errors={"body": 0.5}, metadata={"take": "1"},
                         weights={"LFHD": 2.0}, model_errors={"angles": 1e-3})
    for twin in (pickle.loads(pickle.dumps(opts)), copy.deepcopy(opts)):
        assert twin == opts and hash(twin) == hash(opts)
        assert dict(twin.model_errors) == {"ANGLES": 1e-3}
    assert dataclasses.asdict(opts)["group_errors"] == {"body": 0.5}
    assert hash(opts) != hash(dataclasses.replace(opts, metadata={"take": "2"}))
    with pytest.raises(TypeError):
        opts.metadata["take"] = "2"        # type: ignore[index]
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        # the function a spawned process can import: mpz's own (not this test module's)
        got, _ = pool.submit(encode_motion, walk, EncodeOptions(max_error=1.0)).result()
    assert got == encode_motion(walk, EncodeOptions(max_error=1.0))[0]


# ------------------------------------ residuals beyond the coder's range (stop 37) --
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=25, deadline=None)
@given(st.integers(3, 80), st.integers(1, 5), st.floats(1.0e8, 2.4e8), st.integers(1, 2),
       st.sampled_from(["off", "on"]), st.integers(0, 2**32 - 1))
def test_values_near_the_grid_limit_encode_within_the_bound(F, M, P, threads, patterns, seed):
    """A QA run (stop 37): markers that swing between -P and +P every frame, with P just
    inside the grid's check (|u| < 2^29 at 1 mm), made the encoder raise LimitExceededError
    (a FormatError) from the coder: their order-2 residuals (4P) or key-frame residuals
    passed 2^30. Such an order or base now cannot be chosen, and order 1 (2P) always can;
    with patterns, a cluster left empty was coded as a NaN centre. The file must decode
    within the bound."""
    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 1.0, (F, M, 3))
    swing = np.where(np.arange(F) % 2, P, -P)
    for k in range(M):
        x[:, k, int(rng.integers(0, 3))] = rng.choice([-1, 1]) * swing * rng.uniform(0.5, 1)
    m = Motion(x, [f"m{k}" for k in range(M)], 100.0, "mm")
    back = mpz.decode(mpz.encode(m, max_error=1.0, threads=threads, patterns=patterns))
    assert float(np.linalg.norm(back.positions - x, axis=2).max()) <= 1.0


@pytest.mark.parametrize("frames", [2, 8, 41])
def test_a_lossy_root_near_the_grid_limit_is_coded(frames):
    """A second QA run (stop 37): in lossy mode the root is coded by _best_order, which
    passed order 1 and 2 residuals of values near 2^29 grid steps (2P, 4P) to the coder:
    LimitExceededError. Order 0 always fits; the decode must give the values back within
    the grid's rounding."""
    P = round(0.51 * 2**29)
    x = np.where(np.arange(frames)[:, None, None] % 2 == 0, -1.0, 1.0) * np.ones((frames, 1, 3)) * P
    back = mpz.decode(mpz.encode(Motion(x, ["a"], 100.0, "mm"), lossy=True, grid=1.0, threads=1))
    assert np.isfinite(back.positions).all() and back.positions.shape == x.shape


# --------------------------------- a grid far finer than the bound (stop 38, Q3) --
def _walk_on(step: float, frames: int, markers: int) -> Motion:
    w = generate("walk", frames=frames)
    return Motion(np.round(w.positions[:, :markers] / step) * step, list(w.names[:markers]),
                  100.0, "mm")


@pytest.mark.parametrize("make,kw,bound", [
    (lambda: _walk_on(1e-9, 20, 2), {"max_error": 1000.0, "grid": 1e-2}, 1000.0),
    (lambda: _walk_on(1e-3, 20, 2), {"max_error": 100.0, "source_grid": 1e-3}, 100.0),
    (lambda: _walk_on(1e-2, 120, 41), {"max_error": 50.0, "source_grid": 1e-2}, 50.0),
    (lambda: generate("walk", frames=20), {"max_error": 1000.0, "group_errors": {"head": 0.01}},
     1000.0),
    (lambda: Motion(np.full((3, 8, 3), 700.0), [f"m{k}" for k in range(8)], 100.0, "mm"),
     {"max_error": 0.1, "grid": 1e-8}, 0.1),
], ids=["grid", "source_grid", "source_grid_41", "group_error", "grid_1e-8"])
def test_a_grid_far_finer_than_the_bound_encodes_within_it(make, kw, bound):
    """A QA run (stop 37, Q3): the lattice choice searched every grid step of the bound
    (a radius of 10^5 steps: 14-30 s for 40 samples; 10^7: no end, and the key frames
    allocated 11 GB). It now searches within quantize._REACH and keyframe.MAX_RADIUS, which
    these encodes show by finishing (in milliseconds); the bound must still hold."""
    m = make()
    back = mpz.decode(mpz.encode(m, threads=1, **kw))
    assert float(np.linalg.norm(back.positions - m.positions, axis=2).max()) <= bound


# -------------------------- patterns near the grid's limit (stop 38, Q2 of stop 37) --
@settings(max_examples=25, deadline=None)
@given(st.integers(4, 40), st.integers(2, 4), st.floats(0.5, 0.999), st.booleans(),
       st.integers(0, 2**32 - 1))
def test_patterns_near_the_grid_limit_give_way_under_auto(F, M, frac, on_source, seed):
    """A QA run (stop 37, Q2): markers jumping at random between -P and +P, P from 0.9 x
    2^29 grid steps, encoded with patterns="off" but were refused under "auto" ("the
    residuals of every prediction order exceed the coder's range"): against a pattern's
    prediction a residual can reach 2P. Under "auto" such a node now goes without
    patterns; under "on" the refusal names the node and the options that code it."""
    rng = np.random.default_rng(seed)
    x = np.sign(rng.normal(size=(F, M, 3)))
    x[0], x[1] = -1, 1
    if on_source:
        x = np.round(x * frac * 2**29) * 0.08
        kw: dict[str, Any] = {"source_grid": 0.08}
        bound = 0.0
    else:
        step = 2.0 * 1.0 / np.sqrt(3) * (1.0 - 2.0**-20) / 2    # plan_grid's at 1 mm
        x = x * frac * 2**29 * step
        kw, bound = {"max_error": 1.0}, 1.0
    m = Motion(x, [f"m{k}" for k in range(M)], 100.0, "mm")
    back = mpz.decode(mpz.encode(m, patterns="auto", threads=1, **kw))
    assert float(np.linalg.norm(back.positions - x, axis=2).max()) <= bound
    try:
        back = mpz.decode(mpz.encode(m, patterns="on", threads=1, **kw))
    except EncoderError as exc:
        assert "motion patterns" in str(exc) and "patterns='auto' or 'off'" in str(exc)
    else:
        assert float(np.linalg.norm(back.positions - x, axis=2).max()) <= bound


def test_a_lossy_node_whose_patterns_cannot_be_coded_is_refused(monkeypatch):
    """In lossy mode the pattern layer is all a node has: when it cannot be coded (its
    values pass the coder's range) the encode is refused with the lossy advice whatever
    ``patterns`` says; "auto" met an AssertionError (a QA run, stop 38, found the branch
    unexercised). Forced here: real values that reach it are refused earlier, by the
    31-bit check of the decoded values."""
    from mpz import encoder
    monkeypatch.setattr(encoder, "code_patterns", lambda *a, **k: None)
    m = generate("walk", frames=30, seed=1)
    for patterns in ("auto", "on"):
        with pytest.raises(EncoderError, match=r"node 1: .*motion patterns.*coarser --grid"):
            mpz.encode(m, lossy=True, patterns=patterns, threads=1)
    with pytest.raises(EncoderError, match=r"node 1: .*patterns='auto' or 'off'"):
        mpz.encode(m, max_error=1.0, patterns="on", threads=1)
    back = mpz.decode(mpz.encode(m, max_error=1.0, patterns="auto", threads=1))
    assert float(np.linalg.norm(back.positions - m.positions, axis=2).max()) <= 1.0


def test_extras_the_file_cannot_hold_are_said_or_refused():
    """A QA run of stop 50: extras no extension writes ({"force_plates": ...}) and a
    skeleton that is no Skeleton were dropped without a word (not_kept [], the decoded
    extras {}), while the docs say extras are written to ancillary chunks."""
    import numpy as np

    import mpz
    from mpz.errors import EncoderError
    pos = np.random.default_rng(0).normal(size=(5, 2, 3)) * 100
    m = mpz.Motion(pos, ["A", "B"], 100.0, extras={"force_plates": np.zeros(3)})
    data, rep = mpz.encode_motion(m)
    assert rep.not_kept == ["motion.extras['force_plates'] (no extension of mpz.extensions "
                            "writes it)"]
    assert mpz.decode(data).extras == {}
    with pytest.raises(EncoderError, match=r"extras\['skeleton'\] is a str, not an mpz"):
        mpz.encode(mpz.Motion(pos, ["A", "B"], 100.0, extras={"skeleton": "x"}))


# ------------------------------------------------- the ancillary chunks' §8 limits --
def _bvh_motion(tmp_path: Path, text: str) -> Motion:
    (tmp_path / "arm.bvh").write_text(text)
    return mpz.io.read(tmp_path / "arm.bvh")


def test_a_skeleton_past_its_chunk_limit_is_refused_before_any_encoding(
        tmp_path, monkeypatch, two_joint_bvh):
    """A 2-hour BVH (864,000 frames x 96 channels, past MAX_CHANNEL_SAMPLES) was encoded for
    minutes into a file its decoder refused, which was left behind (a QA run of stop 51).
    The limit is checked first, with the way out; the limit is lowered here to the clip's
    size so that a small file stands in for the 2-hour one."""
    import mpz.encoder
    import mpz.skeleton
    m = _bvh_motion(tmp_path, two_joint_bvh)
    F, C = m.angles.shape
    monkeypatch.setattr(mpz.skeleton, "MAX_CHANNEL_SAMPLES", F * C - 1)
    planned = []
    real = mpz.encoder.plan_hierarchy
    monkeypatch.setattr(mpz.encoder, "plan_hierarchy",
                        lambda *a, **k: planned.append(1) or real(*a, **k))
    with pytest.raises(EncoderError) as info:
        encode_motion(m, EncodeOptions(max_error=1.0))
    said = str(info.value)
    assert f"skeleton's {C} channels over {F} frames are {F * C} values" in said, said
    assert "MAX_CHANNEL_SAMPLES" in said and "--no-skeleton" in said, said
    assert planned == []                                     # nothing was encoded first
    data, rep = encode_motion(m, EncodeOptions(max_error=1.0, keep_skeleton=False))
    assert rep.not_kept and mpz.decode(data).angles is None
    monkeypatch.setattr(mpz.skeleton, "MAX_CHANNEL_SAMPLES", F * C)         # at the limit
    assert mpz.decode(encode_motion(m, EncodeOptions(max_error=1.0))[0]).angles is not None


def test_a_c3d_archive_past_its_chunk_limits_is_refused_before_any_encoding(monkeypatch):
    """The C3D archive's cpnt and cana limits (§8, §4.13.4) are checked first too."""
    import mpz.c3darchive
    from mpz.tools.make_vectors import c3d_motion
    m = c3d_motion(5, storage=1, F=12, M=4, J=2, C=2, n=2)
    words = 12 * 2 * 2                                       # F x n analog samples x C
    monkeypatch.setattr(mpz.c3darchive, "MAX_ANALOG_SAMPLES", words - 1)
    with pytest.raises(EncoderError, match=f"= {words} words, more than {words - 1} "
                                           r"\(spec §8, MAX_ANALOG_SAMPLES\)"):
        encode_motion(m, EncodeOptions(max_error=1.0))
    monkeypatch.setattr(mpz.c3darchive, "MAX_ANALOG_SAMPLES", words)
    monkeypatch.setattr(mpz.c3darchive, "MAX_SAMPLES", 12 * 2 - 1)      # F x J outputs
    with pytest.raises(EncoderError, match="the C3D archive cannot be kept: 2 model outputs"):
        encode_motion(m, EncodeOptions(max_error=1.0))
    monkeypatch.setattr(mpz.c3darchive, "MAX_SAMPLES", 12 * 2)
    assert mpz.decode(encode_motion(m, EncodeOptions(max_error=1.0))[0]).extras["c3d"]


def test_a_file_its_own_decoder_refuses_is_a_bug_and_is_not_left(tmp_path, monkeypatch,
                                                                 capsys, two_joint_bvh):
    """Whatever an encoder check misses, `mpz encode` decodes what it wrote: a file its
    decoder refuses was left on disk with exit 2 and a decoder's message, as if the input
    were bad (a QA run of stop 51). It is removed and reported as a bug (exit 70). The
    decoder's limit is lowered here so that it refuses a valid file."""
    import mpz.chunks.base
    from mpz.tools import mpz_cli
    (tmp_path / "arm.bvh").write_text(two_joint_bvh)
    monkeypatch.setattr(mpz.chunks.base, "MAX_CHANNEL_SAMPLES", 4)
    out = tmp_path / "arm.mpz"
    code = mpz_cli.main(["encode", str(tmp_path / "arm.bvh"), "-o", str(out), "-q"])
    err = capsys.readouterr().err
    assert code == 70 and "the encoder wrote a file that its decoder refuses: " in err, err
    assert "frame_count x channel_count = " in err and " exceeds 4 (§8)" in err, err
    assert "the output was removed" in err and not out.exists(), err
