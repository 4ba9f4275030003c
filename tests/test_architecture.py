"""Issue 9's structural promises, kept by tests: immutable options with one definition of
each default, one chunk table that the reader, the writer and mpzinfo all use, and format
constants that the encoder takes from mpz.format rather than from the decoder."""
import ast
from dataclasses import FrozenInstanceError, fields, replace
from pathlib import Path

import construct
import pytest

import mpz
from mpz.chunks import CHUNKS, Record
from mpz.encoder import DEFAULTS, EncodeOptions, encode_motion
from mpz.spec import grammar
from mpz.synth import generate

PKG = Path(mpz.__file__).resolve().parent


def test_options_are_immutable_and_reusable():
    m = generate("walk", frames=40, markers=8, seed=1)
    opts = EncodeOptions(max_error=1.0)
    with pytest.raises(FrozenInstanceError):
        opts.patterns = "on"  # type: ignore[misc]
    first, _ = encode_motion(m, opts)
    assert opts.patterns is None and opts.pattern_mode == "off"   # nothing resolved in place
    assert encode_motion(m, opts)[0] == first                     # same options, same bytes
    lossy = replace(opts, max_error=None, lossy=True)              # reuse after an encode works
    assert lossy.pattern_mode == "on"
    encode_motion(m, lossy)


def test_option_mappings_cannot_be_changed_behind_the_options_back():
    groups = {"l_foot": 0.5}
    opts = EncodeOptions(max_error=2.0, group_errors=groups)
    groups["r_foot"] = 0.1
    assert dict(opts.group_errors) == {"l_foot": 0.5}
    with pytest.raises(TypeError):
        opts.group_errors["x"] = 1.0  # type: ignore[index]


def test_cli_defaults_are_the_options_defaults():
    """The options mpz encode builds from a command line without options are the
    encoder's defaults (one definition of each; --summary-space and --summary-format
    parse to None, so that a note can say when they change nothing, and take the
    encoder's default then)."""
    from mpz.tools.cmd_encode import _options
    from mpz.tools.mpz_cli import build_parser
    args = build_parser().parse_args(["encode", "in.c3d", "-o", "out.mpz"])
    for name in ("theta", "k0", "tau", "metric", "smoothing", "segmentation"):
        assert getattr(args, name) == getattr(DEFAULTS, name), name
    opts = _options(args, "mm", None)
    for name in ("theta", "k0", "tau", "metric", "smoothing", "segmentation",
                 "summary_space", "summary_format", "patterns", "hierarchy", "lossy"):
        assert getattr(opts, name) == getattr(DEFAULTS, name), name


def test_every_chunk_type_is_one_table_entry_with_its_layout_and_section():
    layouts = [v for v in vars(grammar).values() if isinstance(v, construct.Construct)]
    for ctype, cls in CHUNKS.items():
        assert issubclass(cls, Record) and cls.TYPE == ctype
        assert any(cls.GRAMMAR is g for g in layouts), ctype
        assert cls.SECTION.startswith("§4."), ctype
        # the record's fields are the layout's named fields, in layout order; a record
        # with §4.13 byte coding holds its content's fields in place of ``body``
        named = [s.name for s in cls.GRAMMAR.subcons if s.name]
        content = getattr(cls, "CONTENT", None)
        if content is not None:
            assert named[-1] == "body", ctype
            named = named[:-1] + [s.name for s in content.subcons if s.name]
        assert [f.name for f in fields(cls)] == named, ctype


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
    return out


def test_the_encoder_does_not_import_the_decoder():
    assert "mpz.decoder" not in _imports(PKG / "encoder.py")


def test_format_constants_are_defined_once():
    """Code tables and limits live in mpz.format; no other module assigns them."""
    names = {"FLAG_RESIDUAL", "ROOT_PARENT", "UNIT_CODES", "MAX_SAMPLES", "MAX_FRAMES",
             "MAX_MARKERS", "MAX_CHUNK_LENGTH", "MAX_SMOOTHING", "MM_PER_UNIT"}
    offenders = []
    roots = [PKG, PKG.parents[2] / "tools" / "mpz" / "tools",
             PKG.parents[2] / "conformance" / "mpz" / "conformance"]
    for root in roots:
        for p in root.rglob("*.py"):
            if p.name == "format.py":
                continue
            for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Assign):
                    for t in node.targets:
                        if isinstance(t, ast.Name) and t.id in names:
                            offenders.append(f"{p.name}:{t.id}")
    assert offenders == []
