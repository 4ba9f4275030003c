"""docs/api.md is the Python API reference (``python -m mpz.tools.make_api_doc`` writes it
from the signatures and docstrings): a changed docstring or signature without regenerating
the page fails here, and so does a name of ``mpz.__all__`` or of the README's Python example
that the page has no entry for. Unlike docs/cli.md, the page does not depend on the Python
version, so it is compared whole."""
from __future__ import annotations

import dataclasses
import re

import mpz
from mpz.tools import make_api_doc

README = make_api_doc.DOC.parents[1] / "README.md"
#: an entry of the page: ``## `mpz.io` ``, ``### `mpz.encode` ``, ``#### `mpz.Motion.n_frames` ``
ENTRY = re.compile(r"^#{2,4} `([\w.]+)`$", re.M)


def entries(page: str) -> set[str]:
    """The qualified names the page has an entry (a heading) for."""
    return set(ENTRY.findall(page))


def readme_names(readme: str) -> set[str]:
    """What the README's ```python blocks use of the package: each ``mpz.a.b`` (in code or
    in a comment) and each name imported ``from mpz.x import y`` (as ``mpz.x.y``)."""
    names: set[str] = set()
    for block in re.findall(r"^```python\n(.*?)^```", readme, re.S | re.M):
        names |= set(re.findall(r"(?<![\w.])(mpz(?:\.\w+)+)", block))
        for module, imported in re.findall(r"^\s*from (mpz(?:\.\w+)*) import ([\w ,]+)$",
                                           block, re.M):
            names |= {f"{module}.{n.strip()}" for n in imported.split(",") if n.strip()}
    return names


def missing_from_all(page: str) -> list[str]:
    """The names ``mpz`` and ``mpz.io`` export that the page has no entry for (mpz.io's
    per-format readers and writers and NodeReport were exported without one: a QA run of
    the API, stop 54)."""
    import mpz.io
    names = [f"mpz.{n}" for n in mpz.__all__] + [f"mpz.io.{n}" for n in mpz.io.__all__]
    return sorted(n for n in names if n not in entries(page))


def missing_from_readme(page: str, readme: str) -> list[str]:
    return sorted(readme_names(readme) - entries(page))


def test_the_page_is_up_to_date(tmp_path):
    fresh = tmp_path / "api.md"
    assert make_api_doc.main(["--out", str(fresh)]) == 0
    now = fresh.read_text(encoding="utf-8")
    page = make_api_doc.DOC.read_text(encoding="utf-8")
    assert page == now, make_api_doc._diff_summary(page, now, "docs/api.md")


def test_check_tells_a_stale_page(tmp_path, capsys):
    """``--check`` passes the page as written and fails a copy with a line changed,
    naming the command to run; it writes nothing."""
    copy = tmp_path / "api.md"
    assert make_api_doc.main(["--out", str(copy)]) == 0
    assert make_api_doc.main(["--check", "--out", str(copy)]) == 0
    copy.write_text(copy.read_text(encoding="utf-8").replace("mpz.encode(", "mpz.encode2(", 1),
                    encoding="utf-8")
    before = copy.read_bytes()
    capsys.readouterr()
    assert make_api_doc.main(["--check", "--out", str(copy)]) == 1
    out = capsys.readouterr().out
    assert "stale" in out and "python -m mpz.tools.make_api_doc" in out and "encode2" in out
    assert copy.read_bytes() == before


def test_every_name_of_mpz_all_is_on_the_page():
    page = make_api_doc.DOC.read_text(encoding="utf-8")
    missing = missing_from_all(page)
    assert not missing, f"{missing} missing from docs/api.md; run python -m mpz.tools.make_api_doc"


def test_every_name_the_readme_example_uses_is_on_the_page():
    readme = README.read_text(encoding="utf-8")
    names = readme_names(readme)
    # the parse finds the example's names at all (a renamed fence would find none)
    assert {"mpz.encode", "mpz.decode", "mpz.io.write", "mpz.synth.generate"} <= names
    missing = missing_from_readme(make_api_doc.DOC.read_text(encoding="utf-8"), readme)
    assert not missing, (f"{missing}: the README's Python example uses them, docs/api.md has "
                         "no entry; add them to make_api_doc.ENTRIES")


def _without(page: str, name: str) -> str:
    """``page`` without the entry of ``name`` (its heading down to the next entry)."""
    out = re.sub(rf"^(#{{2,4}}) `{re.escape(name)}`\n.*?(?=^#{{2,4}} `)", "", page,
                 count=1, flags=re.S | re.M)
    assert out != page, name
    return out


def test_the_checks_trip_on_a_page_missing_an_entry():
    """The checks above can fail: a page without one entry fails each."""
    page = make_api_doc.DOC.read_text(encoding="utf-8")
    readme = README.read_text(encoding="utf-8")
    assert missing_from_all(page) == [] and missing_from_readme(page, readme) == []
    assert missing_from_all(_without(page, "mpz.EncodeOptions")) == ["mpz.EncodeOptions"]
    assert missing_from_readme(_without(page, "mpz.io.write"), readme) == ["mpz.io.write"]
    assert missing_from_readme(_without(page, "mpz.synth.generate"), readme) == [
        "mpz.synth.generate"]


def test_the_page_shows_signatures_defaults_and_bases():
    """What the page is for: full signatures, every EncodeOptions field with its default,
    the exceptions' base classes; and nothing that changes between runs."""
    page = make_api_doc.DOC.read_text(encoding="utf-8")
    assert "mpz.encode(\n    motion: Motion,\n    *,\n    max_error: float | None = None," in page
    for f in dataclasses.fields(mpz.EncodeOptions):
        assert re.search(rf"^\| `{f.name}` \| `[^`]+` \| ", page, re.M), f.name
    assert "*exception*; bases: `mpz.FormatError`" in page        # ChecksumError
    assert "bases: `mpz.MPZError`, `ValueError`" in page
    assert not re.search(r"0x[0-9a-f]{6,}", page)
    header = page.split("\n## ", 1)[0]
    assert header.startswith("# Python API reference")
    assert "Written by `python -m mpz.tools.make_api_doc`" in header


def test_every_listed_name_and_parameter_is_documented():
    """No public object on the page lacks a docstring, and every parameter and dataclass
    field is named in its docstring or its ``#:`` comment (35 were not when the page was
    first written: FileInfo's and EncodeReport's fields, arms' and max_error's arguments)."""
    _, warnings = make_api_doc.render_with_warnings()
    assert warnings == []


def test_encode_keywords_has_a_row_per_keyword_of_encode():
    """``write_mpz``'s options are typed by ``mpz.encoder.EncodeKeywords``, which had no
    entry (a review at stop 75): the page lists it with one row per keyword of
    ``mpz.encode``, in its order, each with the type ``encode`` declares and its default."""
    import inspect
    page = make_api_doc.DOC.read_text(encoding="utf-8")
    assert "mpz.encoder.EncodeKeywords" in entries(page)
    section = page.split("### `mpz.encoder.EncodeKeywords`", 1)[1].split("\n#", 1)[0]
    rows = re.findall(r"^\| `(\w+)` \| `(.+?)` \| (.*) \|$", section, re.M)
    params = [p for p in inspect.signature(mpz.encode).parameters.values()
              if p.kind is p.KEYWORD_ONLY]
    assert [r[0] for r in rows] == [p.name for p in params]
    for (name, ann, default), p in zip(rows, params, strict=True):
        assert ann.replace("\\|", "|") == p.annotation, name
        assert default == f"`{p.default!r}`", name
