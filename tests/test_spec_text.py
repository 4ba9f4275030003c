"""The text of spec/mpz-1.md agrees with the code and the example file.

Each test parses one machine-readable part of the spec (HTML-comment
markers ``<!-- mpz:NAME -->`` ... ``<!-- /mpz:NAME -->``, or headings) and
compares it with the implementation, so that editing either side alone
makes a test fail.
"""
from __future__ import annotations

import io
from pathlib import Path
import re
import tokenize
import zlib

import numpy as np
import pytest

from mpz import container, format
from mpz.chunks import CHUNKS
from mpz.conformance.manifest import spec_rules
from mpz.entropy import BlockDecoder, BlockEncoder
from mpz.spec.grammar import SIGNATURE

REPO = Path(__file__).resolve().parents[1]
SPEC = REPO / "spec" / "mpz-1.md"
EXAMPLE = REPO / "conformance" / "vectors" / "spec-example.mpz"
GRAMMAR = REPO / "spec" / "mpz" / "spec" / "grammar.py"
CITING = sorted([*(REPO / "reference" / "mpz").rglob("*.py"),
                 *(REPO / "tools" / "mpz").rglob("*.py")]) + [GRAMMAR]

#: where the checks of the §7.4 rules are: the reference decoder and the grammar
ENFORCING = sorted((REPO / "reference" / "mpz").rglob("*.py")) + [GRAMMAR]

HEADING = re.compile(r"^#{2,4} (\d+(?:\.\d+)*)\.? +(.*)$", re.M)
SECTION_REF = re.compile(r"§(\d+(?:\.\d+)*)")
RULE_ID = re.compile(r"\bR-\d+(?:\.\d+)*-\d+\b")


@pytest.fixture(scope="module")
def text() -> str:
    return SPEC.read_text(encoding="utf-8")


def block(text: str, name: str) -> str:
    m = re.search(rf"<!-- mpz:{name} -->\n(.*?)\n<!-- /mpz:{name} -->", text, re.S)
    assert m, f"spec has no <!-- mpz:{name} --> block"
    return m.group(1)


def table_rows(md: str) -> list[list[str]]:
    """Cells of every body row of the first markdown table in ``md``."""
    rows = []
    for line in md.splitlines():
        line = line.strip()
        if not line.startswith("|"):
            continue
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip("|"))]
        if all(set(c) <= set("-: ") for c in cells):
            continue                      # the separator row
        rows.append(cells)
    return rows[1:]                       # drop the header row


def headings(text: str) -> dict:
    return {num: title for num, title in HEADING.findall(text)}


# (1) Appendix A ---------------------------------------------------------------
def test_appendix_a_matches_the_example_file_byte_for_byte(text):
    data = EXAMPLE.read_bytes()
    rows = table_rows(block(text, "example-bytes"))
    assert len(rows) > 20
    pos = 0
    for start, length, contents, desc in rows:
        start, length = int(start, 16), int(length)
        raw = bytes.fromhex(contents.strip("`").replace(" ", ""))
        at = f"row at {start:#06x}"
        assert start == pos, f"{at} does not follow the previous row (expected {pos:#06x}): {desc}"
        assert len(raw) == length, f"{at}: Length {length} but {len(raw)} bytes shown"
        assert data[start:start + length] == raw, f"{at} ({desc}) differs from the file"
        pos += length
    assert pos == len(data), f"table covers {pos} of {len(data)} bytes"


def test_example_file_is_what_the_generator_writes():
    from mpz.tools.spec_example import build, verify
    data = build()
    verify(data)                          # decodes to the integers Appendix A states
    assert EXAMPLE.read_bytes() == data, \
        "regenerate: python -m mpz.tools.spec_example " + str(EXAMPLE)


def test_appendix_a_digest_and_size(text):
    import hashlib

    from mpz.conformance.manifest import intlayer_digest
    from mpz.decoder import decode_layers
    data = EXAMPLE.read_bytes()
    d = decode_layers(data)
    assert intlayer_digest(d.q, d.valid) in text
    assert hashlib.sha256(data).hexdigest() in text
    assert f"({len(data)} bytes" in text


# (2) chunk catalogue ----------------------------------------------------------
def test_every_chunk_type_has_a_section_4_heading_and_vice_versa(text):
    """Each chunk type has one heading '§4.k TYPE: ...' (or '§4.k.j TYPE: ...' for chunk
    types grouped under a feature), and the catalogue follows the table's order."""
    in_spec = {}
    for num, title in HEADING.findall(text):
        if not re.match(r"4\.\d+(\.\d+)?$", num):
            continue
        ctype = title.split(":")[0].strip()
        if re.fullmatch(r"[A-Za-z]{4}", ctype):
            in_spec[ctype] = tuple(int(p) for p in num.split("."))
        else:
            # only a feature's group heading may lack a chunk type, and it has subsections
            assert any(n.startswith(num + ".") for n, _ in HEADING.findall(text)), \
                f"§{num} title {title!r} does not start with a chunk type"
    in_code = list(CHUNKS)
    assert set(in_spec) == set(in_code)
    assert sorted(in_spec, key=in_spec.get) == in_code


def test_grammar_field_sections_name_their_own_chunk(text):
    """A field doc string '§4.k ...' in the layout of chunk T cites the heading of chunk T
    (or, for a chunk of a family such as §4.13.1, the family's §4.13, whose rules it
    shares); each chunk's entry in the table (mpz.chunks) names the same § as its heading.
    Every chunk's layout is found: the lower-case types but smry and meta were skipped
    (a newcomer adding a chunk type, stop 51)."""
    secs = {title.split(":")[0].strip(): num for num, title in HEADING.findall(text)
            if num.startswith("4.") and re.fullmatch(r"[A-Za-z]{4}", title.split(":")[0].strip())}
    src = GRAMMAR.read_text(encoding="utf-8")
    for ctype, cls in CHUNKS.items():
        assert cls.SECTION == f"§{secs[ctype]}", (ctype, cls.SECTION)
        name = ctype.upper()
        m = re.search(rf"^{name} = Struct\((.*?)^\)", src, re.S | re.M)
        assert m is not None, f"no {name} = Struct(...) in the grammar"
        cited = set(SECTION_REF.findall(m.group(1)))
        own = secs[ctype]
        family = own.rsplit(".", 1)[0] if own.count(".") > 1 else own
        also = {"smrc": {secs["smry"]}}.get(ctype, set())    # §4.15: "as for smry"
        assert cited <= {own, family, *also}, f"{name} cites {cited}"


# (3) every § the code cites exists ----------------------------------------------
def test_every_section_cited_in_the_code_is_a_heading(text):
    have = set(headings(text))
    missing = {}
    for path in CITING:
        for num in SECTION_REF.findall(path.read_text(encoding="utf-8")):
            if num not in have:
                missing.setdefault(num, []).append(path.name)
    assert not missing, f"sections cited in code but absent from mpz-1.md: {missing}"


def test_required_section_numbers_exist(text):
    have = set(headings(text))
    need = {"1", "2", "2.1", "2.2", "2.3", "2.4", "3", "3.1", "3.2", "3.3", "3.4", "4", "5", "6",
            "7", "7.1", "7.2", "7.3", "8"}
    need |= {f"4.{i}" for i in range(1, 13)} | {f"5.{i}" for i in range(1, 8)}
    need |= {f"6.{i}" for i in range(1, 9)}
    assert need <= have, sorted(need - have)


def test_spec_cross_references_resolve(text):
    have = set(headings(text))
    bad = sorted({n for n in SECTION_REF.findall(text) if n not in have})
    assert not bad, f"spec refers to missing sections {bad}"


# (3b) §7.4 rule IDs: from a rule to the check that enforces it, and back --------------
def comment_rule_ids(path: Path) -> set[str]:
    """The rule IDs that the ``#`` comments of a Python file cite."""
    tokens = tokenize.generate_tokens(io.StringIO(path.read_text(encoding="utf-8")).readline)
    return {rid for t in tokens if t.type == tokenize.COMMENT for rid in RULE_ID.findall(t.string)}


def test_every_reject_rule_id_is_cited_at_its_check(text):
    """Each ``reject`` rule of the §7.4 index is named in a comment (``# R-4.13-2``) on or
    above the check that raises for it, in reference/mpz or the grammar."""
    cited = set().union(*(comment_rule_ids(p) for p in ENFORCING))
    reject = [rid for rid, _, kind, _ in spec_rules(text) if kind == "reject"]
    assert len(reject) > 100
    missing = [rid for rid in reject if rid not in cited]
    assert not missing, f"reject rules no comment in reference/mpz or the grammar cites: {missing}"


def test_every_rule_id_cited_in_the_code_is_in_the_index(text):
    index = {rid for rid, *_ in spec_rules(text)}
    unknown: dict[str, list[str]] = {}
    for path in sorted(set(CITING) | set(ENFORCING)):
        for rid in RULE_ID.findall(path.read_text(encoding="utf-8")):
            if rid not in index:
                unknown.setdefault(rid, []).append(path.name)
    assert not unknown, f"rule IDs cited in code but absent from the §7.4 index: {unknown}"


# (4) the worked entropy example -----------------------------------------------
def _entropy_example(text):
    kv = dict(re.findall(r"^(\w+)\s*=\s*(.+)$", block(text, "entropy-example"), re.M))
    values = np.array(eval(kv["input"], {"__builtins__": {}}), dtype=np.int64)   # a literal list
    signed = kv["signed"].strip() == "true"
    return values, int(kv["period"]), signed, bytes.fromhex(kv["bytes"].replace(" ", ""))


def test_entropy_example_bytes_equal_the_reference_coder(text):
    values, period, signed, expected = _entropy_example(text)
    enc = BlockEncoder()
    enc.block(values, period=period, signed=signed)
    assert enc.finish() == expected
    dec = BlockDecoder(expected)
    assert (dec.block(*values.shape, period=period, signed=signed) == values).all()
    dec.close()


def test_entropy_example_trace_is_the_spec_pseudocode(text):
    """The decision listing in §5.7 is what the pure-Python transcription of §5 prints."""
    from mpz.tools.spec_example import ENTROPY_BLOCK, entropy_text
    values, *_ = _entropy_example(text)
    assert (values == ENTROPY_BLOCK).all()
    trace = entropy_text().rsplit("\n", 1)[0]
    assert trace in text


def _spec_encode_int(text):
    """§5.4's ``encode_int`` pseudo-code, read from the spec and run as Python: each
    ``encode_bit(MODEL[i][j]..., bit)`` appends ((MODEL, i, j, ...), bit) to a list."""
    m = re.search(r"```\n(encode_int\(a, c, signed, v\):.*?)```", text, re.S)
    assert m, "§5.4 has no encode_int block"
    lines = m.group(1).splitlines()
    body = []
    for line in lines[1:]:
        line = line.split("#")[0].rstrip()
        line = re.sub(r"for (\w) = 0 \.\. k-1:", r"for \1 in range(k):", line)
        line = line.replace("|v|", "abs(v)").replace("bitlen(u)", "u.bit_length()")
        if line.strip():
            body.append(line)
    src = "def encode_int(a, c, signed, v, encode_bit, Z, S, E, X):\n" + "\n".join(body)
    scope: dict = {}
    exec(compile(src, "spec §5.4 encode_int", "exec"), scope)

    class Models:
        def __init__(self, name, key=()):
            self.name, self.key = name, key

        def __getitem__(self, i):
            return Models(self.name, self.key + (i,))

    def trace(a, c, signed, v):
        calls: list = []
        scope["encode_int"](a, c, signed, v,
                            lambda model, bit: calls.append(((model.name, *model.key), bit)),
                            *(Models(n) for n in "ZSEX"))
        return calls
    return trace


def test_encode_int_is_the_transcription_the_tests_hold_the_coder_to(text):
    """The encoding side of §5.4 (added from a clean-room encoder's review, stop 60) codes
    the decisions that mpz.conformance.rangecoder.RefEncoder codes, to which
    tests/test_entropy.py holds mpz.entropy byte for byte."""
    from mpz.conformance.rangecoder import RefEncoder

    class Recorder(RefEncoder):
        def __init__(self):
            super().__init__()
            self.calls: list = []

        def bit(self, probs, key, b):
            self.calls.append((key, b))
    spec = _spec_encode_int(text)
    rng = np.random.default_rng(60)
    values = [0, 1, -1, 2, 3, (1 << 30) - 1, -((1 << 30) - 1), 1 << 29, -(1 << 29)]
    values += [int(rng.integers(0, 1 << int(rng.integers(1, 31)))) for _ in range(2000)]
    for i, v in enumerate(values):
        signed = i % 2 == 0 or v < 0
        a, c = i % 3, i % 8
        rec = Recorder()
        rec.integer({}, a, c, v if signed else abs(v), signed)
        assert spec(a, c, signed, v if signed else abs(v)) == rec.calls, v


# (5) limits ---------------------------------------------------------------------
def test_limits_table_matches_the_format_constants(text):
    rows = table_rows(block(text, "limits"))
    table = {}
    for name, value, expr, _ in rows:
        base, exp = expr.split("^")
        assert int(value) == int(base) ** int(exp), f"{name}: {value} != {expr}"
        table[name] = int(value)
    assert table == format.LIMITS


# further checks on numbers quoted in the text -------------------------------------
def test_crc_test_values(text):
    assert f"0x{zlib.crc32(b'123456789'):08X}" in text
    mend = container.build_chunk("MEND", b"")
    assert mend[-4:] == bytes.fromhex("d5f72021")
    assert f"0x{container.crc32(b'MEND', b''):08X}" in text
    assert mend.hex(" ").upper() in text


def test_signature_in_text(text):
    assert SIGNATURE.hex(" ").upper() in text


def test_decoding_steps_table_is_well_formed(text):
    rows = table_rows(block(text, "decoding-steps"))
    have = set(headings(text))
    assert [int(r[0]) for r in rows] == list(range(1, len(rows) + 1))
    secs = [r[1] for r in rows]
    assert all(s.startswith("§") and s[1:] in have for s in secs), secs
    # every subsection of §6 is a step
    assert {f"§6.{i}" for i in range(1, 9)} <= set(secs)


def test_mhdr_table_offsets_add_up(text):
    """§4.1's Offset column agrees with the grammar's field sizes."""
    sec = text.split("### 4.1.")[1].split("### 4.2.")[0]
    rows = table_rows(sec)
    sizes = {"u8": 1, "u16": 2, "u32": 4, "f64": 8}
    pos = 0
    for off, typ, *_ in rows:
        assert int(off) == pos
        pos += sizes[typ]
    from mpz.spec.grammar import MHDR
    assert pos == len(MHDR.build(MHDR.parse(bytes(31)))) == 31


def test_no_chunk_type_is_newer_than_the_version_written():
    """A chunk type of a later minor version than VERSION_MINOR is written by the encoder
    and skipped by its own decoder as unknown (§2.3): its data vanish with no error. A
    newcomer adding a chunk type found that nothing caught a forgotten version bump
    (stop 51). Every chunk an extension writes is in the table, at VERSION_MINOR or
    earlier."""
    from mpz.chunks import CHUNKS
    from mpz.extensions import EXTENSIONS
    from mpz.format import VERSION_MINOR
    newer = {t: c.MINOR for t, c in CHUNKS.items() if c.MINOR > VERSION_MINOR}
    assert not newer, f"chunk types of minor versions after {VERSION_MINOR}: {newer}; " \
        "raise VERSION_MINOR (spec/mpz/spec/grammar.py) with them"
    written = {t for ext in EXTENSIONS for t in ext.chunk_types}
    assert written <= set(CHUNKS), written - set(CHUNKS)


def test_every_ancillary_chunk_has_one_reader():
    """The decoder reads the summary and meta chunks itself and hands every other known
    ancillary chunk to the extension that owns it (``mpz.decoder.read_stream``). A chunk
    type in the table that no extension owns is checked and then dropped: its data would
    vanish from every decode with no error. Each owned chunk's § lies within its
    extension's family §, which the vectors' ``spec_sections`` take from the extension."""
    from mpz.chunks import CHUNKS
    from mpz.extensions import EXTENSIONS
    own = ("smry", "smrc", "meta")                  # read_stream's own (§3.4, §4.10, §4.15)
    for t, cls in CHUNKS.items():
        if t[:1].isupper() or t in own:
            continue
        owners = [e.name for e in EXTENSIONS if t in e.chunk_types]
        assert len(owners) == 1, f"chunk type {t} is owned by {owners or 'no extension'}"
        ext = next(e for e in EXTENSIONS if t in e.chunk_types)
        family = ext.sections[0]
        assert cls.SECTION == family or cls.SECTION.startswith(family + "."), \
            f"{t}'s {cls.SECTION} is not within {ext.name}'s {family}"
    assert {t for t, c in CHUNKS.items() if c.PART == "summary"} == {"smry", "smrc"}
