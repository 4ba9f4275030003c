"""The commands' JSON contract (docs/json.md): one object a run, ``schema`` first, and the
fields each schema's table lists, no more and no fewer.

A CLI audit of stop 58 found ``mpz encode --json`` printing an object, a list or ``[]``,
a schema that was an integer for ``show``, a name for ``search`` and absent for
``compare``, and most fields documented nowhere. The tables are read from the docs, so a
field added to a command without a row in its table fails here, and so does a row for a
field that is gone.
"""
from __future__ import annotations

import json
from pathlib import Path
import re

import pytest

import mpz
from mpz.io import write
from mpz.synth import generate
from mpz.tools import mpz_cli, mpzinfo

DOCS = Path(__file__).parents[1] / "docs"


def _names(cell: str) -> set[str]:
    """The field names of a table's first cell: "`a`, `b`" gives {"a", "b"}."""
    return set(re.findall(r"`([^`]+)`", cell))


def _table_after(text: str, start: int) -> set[str]:
    """The field names of the first table after ``start``."""
    names: set[str] = set()
    lines = text[start:].splitlines()
    i = next(n for n, line in enumerate(lines) if line.startswith("| field"))
    for line in lines[i + 2:]:
        if not line.startswith("|"):
            break
        names |= _names(line.split("|")[1])
    return names


def documented() -> dict[str, set[str]]:
    """Each schema's documented top-level fields: docs/json.md's sections, corpus.md's
    search table, mpzinfo.md's table of a file's entry (under ``files``)."""
    text = (DOCS / "json.md").read_text(encoding="utf-8")
    out = {m.group(1): _table_after(text, m.end())
           for m in re.finditer(r"^## `([a-z-]+/\d+)`$", text, re.M)}
    corpus = (DOCS / "corpus.md").read_text(encoding="utf-8")
    out["mpz-search/1"] = _table_after(corpus, corpus.index("schema `mpz-search/1`"))
    info = (DOCS / "mpzinfo.md").read_text(encoding="utf-8")
    out["mpzinfo/2 files"] = _table_after(info, 0)
    return out


DOC = documented()


def listed() -> set[str]:
    """The schemas of docs/json.md's first table."""
    text = (DOCS / "json.md").read_text(encoding="utf-8")
    head = text[:text.index("## ")]
    return {re.match(r"\| `([^`]+)`", line).group(1)          # type: ignore[union-attr]
            for line in head.splitlines() if re.match(r"\| `[a-z-]+/\d+`", line)}


def test_every_schema_listed_has_its_table() -> None:
    have = {k for k in DOC if " " not in k} | {"mpzinfo/2"}
    assert listed() == have, (listed() ^ have)
    for name, fields in DOC.items():
        assert "schema" in fields or name == "mpzinfo/2 files", name
        assert len(fields) > 3, name


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("json")
    paths = {}
    for name, kind, seed in (("a", "walk", 1), ("b", "jump", 2)):
        m = generate(kind, frames=50, seed=seed, gap_fraction=0.02)
        paths[name] = d / f"{name}.trc"
        write(m, paths[name])
    paths["mpz"] = d / "a.mpz"
    paths["bad"] = d / "bad.trc"
    paths["bad"].write_text("not a TRC\n")
    return paths


def _doc(capsys: pytest.CaptureFixture[str], main, argv: list[str], code: int) -> dict:
    assert main(argv) == code, capsys.readouterr().err
    out = capsys.readouterr().out
    doc = json.loads(out)
    assert isinstance(doc, dict), out[:200]
    assert next(iter(doc)) == "schema", list(doc)[:3]
    return doc


def _check(doc: dict, schema: str) -> None:
    assert doc["schema"] == schema
    assert set(doc) == DOC[schema], {"undocumented": set(doc) - DOC[schema],
                                     "documented, not printed": DOC[schema] - set(doc)}


def test_encode_one_input(files, capsys) -> None:
    doc = _doc(capsys, mpz_cli.main, ["encode", str(files["a"]), "-o", str(files["mpz"]), "-f",
                                      "--max-error", "1mm", "--summary", "4,8", "--json"], 0)
    _check(doc, "mpz-encode/1")
    assert doc["summary_levels"] == [4, 8] and doc["declared_bound"] == 1.0


def test_a_failed_input_gives_the_error_document(files, capsys) -> None:
    doc = _doc(capsys, mpz_cli.main, ["encode", str(files["bad"]), "-o",
                                      str(files["bad"].with_suffix(".mpz")), "--json"], 2)
    _check(doc, "mpz-error/1")
    assert doc["command"] == "mpz encode" and doc["status"] == "error"
    assert set(doc["error"]) == {"class", "message", "path", "offset", "chunk", "section"}
    assert doc["error"]["path"] == str(files["bad"])
    assert not files["bad"].with_suffix(".mpz").exists()


def test_a_batch_is_one_object_with_its_failures(files, tmp_path, capsys) -> None:
    for name in ("a", "b", "bad"):
        (tmp_path / f"{name}.trc").write_bytes(files[name].read_bytes())
    doc = _doc(capsys, mpz_cli.main, ["encode", "-r", str(tmp_path), "--max-error", "1mm",
                                      "--json"], 2)
    _check(doc, "mpz-encode-batch/1")
    assert (doc["inputs"], doc["encoded"], doc["failed"]) == (3, 2, 1)
    for report in doc["files"]:
        _check(report, "mpz-encode/1")
    (failure,) = doc["failures"]
    assert failure["input"].endswith("bad.trc") and failure["status"] == "error"
    assert set(failure["error"]) == {"class", "message", "path", "offset", "chunk",
                                     "section"}
    # the schema depends on the options, not on how many files a folder holds
    one = tmp_path / "one"
    one.mkdir()
    (one / "a.trc").write_bytes(files["a"].read_bytes())
    doc = _doc(capsys, mpz_cli.main, ["encode", "-r", str(one), "--max-error", "1mm",
                                      "--json"], 0)
    assert doc["schema"] == "mpz-encode-batch/1" and doc["encoded"] == 1


def test_corpus_run_and_search(files, tmp_path, capsys) -> None:
    pytest.importorskip("distributed")
    src = tmp_path / "src"
    src.mkdir()
    for name in ("a", "b"):
        (src / f"{name}.trc").write_bytes(files[name].read_bytes())
    out = tmp_path / "out"
    doc = _doc(capsys, mpz_cli.main, ["encode", "-r", str(src), "-o", f"{out}/", "--jobs",
                                      "0", "--max-error", "1mm", "--json"], 0)
    _check(doc, "mpz-corpus/1")
    assert doc["counts"]["encoded"] == 2
    doc = _doc(capsys, mpz_cli.main, ["search", str(src / "a.trc"), "--index", str(out),
                                      "--json"], 0)
    _check(doc, "mpz-search/1")
    assert doc["results"][0]["identical"] is True


def test_compare_show_summary(files, capsys) -> None:
    if not files["mpz"].exists():
        files["mpz"].write_bytes(mpz.encode(mpz.io.read(files["a"]), max_error=1.0,
                                            summary=(4, 8)))
    doc = _doc(capsys, mpz_cli.main, ["compare", str(files["a"]), str(files["mpz"]),
                                      "--json"], 0)
    _check(doc, "mpz-compare/1")
    assert doc["bound_check"]["beyond"] == 0
    doc = _doc(capsys, mpz_cli.main, ["show", str(files["mpz"]), "--json"], 0)
    _check(doc, "mpz-show/2")
    assert doc["format"] == "MPZ" and doc["error_bound"] == 1.0
    for argv in (["summary", str(files["mpz"]), "--json"],
                 ["summary", str(files["a"]), "--k", "3", "--json"]):
        doc = _doc(capsys, mpz_cli.main, argv, 0)
        _check(doc, "mpz-summary/1")


@pytest.mark.parametrize("argv", [["compare", "{bad}", "{a}"], ["show", "{bad}"],
                                  ["summary", "{bad}"], ["encode", "{missing}"]])
def test_every_failing_command_gives_the_error_document(files, capsys, argv) -> None:
    argv = [a.format(bad=files["bad"], a=files["a"], missing=files["a"].parent / "no.trc")
            for a in argv]
    doc = _doc(capsys, mpz_cli.main, [*argv, "--json"], 2)
    _check(doc, "mpz-error/1")
    assert doc["command"] == f"mpz {argv[0]}" and doc["error"]["message"]


def test_mpzinfo(files, capsys) -> None:
    if not files["mpz"].exists():
        files["mpz"].write_bytes(mpz.encode(mpz.io.read(files["a"]), max_error=1.0))
    doc = _doc(capsys, mpzinfo.main, ["--json", str(files["mpz"])], 0)
    assert doc["schema"] == "mpzinfo/2"
    assert set(doc) == {"schema", "tool_version", "tool_source", "files"}
    # the source of --version's "(source ...)", not the version alone (a note of stop 67)
    assert mpz.identity() == f"{doc['tool_version']} (source {doc['tool_source']})"
    (entry,) = doc["files"]
    assert set(entry) == DOC["mpzinfo/2 files"], set(entry) ^ DOC["mpzinfo/2 files"]


def test_bench_compare(tmp_path, capsys) -> None:
    row = {"file": "a", "E": 1.0, "mpz_ratio": 20.0, "max": 0.9, "enc_s": 1.0, "dec_s": 0.1}
    old, new = tmp_path / "old.json", tmp_path / "new.json"
    old.write_text(json.dumps({"schema": 1, "rows": [row]}))
    new.write_text(json.dumps({"schema": 1, "rows": [dict(row, mpz_ratio=10.0)]}))
    doc = _doc(capsys, mpz_cli.main, ["bench", "--compare", str(old), str(new), "--json"], 1)
    _check(doc, "mpz-bench-compare/1")
    assert doc["compared"] == 1 and "ratio dropped" in doc["regressions"][0]["problem"]


def test_the_error_class_is_one_a_caller_can_catch(files, capsys) -> None:
    """A misspelled --group-error node raised the encoder's private ``_NodeNameError``,
    and the document named it: ``EncoderError`` is the class a caller knows."""
    doc = _doc(capsys, mpz_cli.main, ["encode", str(files["a"]), "-o",
                                      str(files["a"].with_suffix(".x.mpz")), "--max-error",
                                      "1mm", "--group-error", "nonode=1mm", "--json"], 2)
    _check(doc, "mpz-error/1")
    assert doc["error"]["class"] == "EncoderError" and "nonode" in doc["error"]["message"]


def test_show_says_a_readers_warning_on_stderr_and_in_warnings(files, tmp_path,
                                                                capsys) -> None:
    """`mpz show --json` of a cut file exited 1 with nothing on stderr and the warning only
    inside ``metadata``; every other command gives it in ``warnings`` and on stderr."""
    text = files["a"].read_text()
    cut = tmp_path / "cut.trc"
    cut.write_text(text[:len(text) // 2])          # mid-row: the reader warns
    assert mpz_cli.main(["show", str(cut), "--json"]) == 1
    got = capsys.readouterr()
    doc = json.loads(got.out)
    _check(doc, "mpz-show/2")
    assert doc["warnings"] == [doc["metadata"]["warning"]] and doc["warnings"][0]
    assert f"mpz show: warning: {cut}: " in got.err
    assert _doc(capsys, mpz_cli.main, ["show", str(files["a"]), "--json"], 0)["warnings"] == []


@pytest.mark.parametrize("command", ["compare", "summary"])
def test_plot_without_matplotlib_is_an_error_with_its_document(files, tmp_path, capsys,
                                                               monkeypatch, command) -> None:
    """Without matplotlib, `mpz compare --plot` ended in a traceback (exit 70: "a bug") and
    `mpz summary --plot --json` exited 2 with nothing on stdout."""
    import sys
    for name in ("matplotlib", "matplotlib.backend_bases", "matplotlib.pyplot"):
        monkeypatch.setitem(sys.modules, name, None)        # import raises ImportError
    argv = ([command, str(files["a"]), str(files["a"])] if command == "compare"
            else [command, str(files["a"])])
    doc = _doc(capsys, mpz_cli.main, [*argv, "--plot", str(tmp_path / "p.png"), "--json"], 2)
    _check(doc, "mpz-error/1")
    assert doc["error"]["message"] == "--plot needs matplotlib: pip install 'mpz[plot]'"
    assert not (tmp_path / "p.png").exists()


def test_corpus_and_search_say_their_warnings_on_stderr_with_json(files, tmp_path,
                                                                 capsys) -> None:
    """With --json, a corpus run whose source its reader warned about, and a search whose
    listed output is gone, exited 1 with nothing on stderr: the warnings were only inside
    the document (a JSON audit of stop 59)."""
    pytest.importorskip("distributed")
    src = tmp_path / "src"
    src.mkdir()
    text = files["a"].read_text()
    (src / "cut.trc").write_text(text[:len(text) // 2])
    (src / "b.trc").write_bytes(files["b"].read_bytes())
    out = tmp_path / "out"
    assert mpz_cli.main(["encode", "-r", str(src), "-o", f"{out}/", "--jobs", "0",
                         "--max-error", "1mm", "--json"]) == 1
    got = capsys.readouterr()
    doc = json.loads(got.out)
    (warned,) = [f for f in doc["files"] if f["warning"]]
    assert f"mpz encode: warning: {warned['source']}: " in got.err
    (out / "b.mpz").unlink()
    assert mpz_cli.main(["search", str(src / "b.trc"), "--index", str(out), "--json"]) == 1
    got = capsys.readouterr()
    assert json.loads(got.out)["results"][0]["output_exists"] is False
    assert "mpz search: warning: 1 of the files listed is no longer" in got.err


def test_data_on_stdout_puts_the_document_last_on_stderr(files, tmp_path) -> None:
    """docs/json.md's one exception: with `-o -` the document goes to stderr, the last
    thing there, from a line that is "{" to the end; stdout holds the .mpz alone."""
    import subprocess
    import sys
    text = files["a"].read_text()
    cut = tmp_path / "cut.trc"
    cut.write_text(text[:len(text) // 2])          # a reader warning printed before it
    for source, code, schema in ((cut, 1, "mpz-encode/1"), (files["bad"], 2, "mpz-error/1")):
        p = subprocess.run([sys.executable, "-m", "mpz.tools.mpz_cli", "encode", str(source),
                            "-o", "-", "--max-error", "1mm", "--json"], capture_output=True,
                           timeout=300)
        assert p.returncode == code, p.stderr.decode()
        err = p.stderr.decode()
        start = err.rindex("\n{\n") + 1 if "\n{\n" in err else err.index("{\n")
        doc = json.loads(err[start:])
        assert doc["schema"] == schema and err[:start].strip(), err
        if code == 1:
            assert mpz.decode(p.stdout).n_frames == doc["frames"]
        else:
            assert p.stdout == b""


@pytest.mark.parametrize("stop, said", [(KeyboardInterrupt, "the interrupt"),
                                        (SystemExit(143), "SIGTERM")])
def test_an_interrupted_batch_says_which_outputs_it_wrote(files, tmp_path, capsys,
                                                          monkeypatch, stop, said) -> None:
    """A batch stopped by Ctrl-C printed no document (as documented) and, with --json,
    nothing said which outputs it had written whole (a JSON audit of stop 59)."""
    from mpz.tools import cmd_encode
    for name in ("a", "b"):
        (tmp_path / f"{name}.trc").write_bytes(files[name].read_bytes())
    real, calls = cmd_encode._encode_one, []

    def second_interrupted(job, *args, **kw):
        calls.append(job)
        if len(calls) == 2:
            raise stop
        return real(job, *args, **kw)
    monkeypatch.setattr(cmd_encode, "_encode_one", second_interrupted)
    argv = ["encode", str(tmp_path / "a.trc"), str(tmp_path / "b.trc"), "--max-error", "1mm",
            "--json"]
    if stop is KeyboardInterrupt:
        assert mpz_cli.main(argv) == 130
    else:
        with pytest.raises(SystemExit) as end:
            mpz_cli.main(argv)
        assert end.value.code == 143
    got = capsys.readouterr()
    assert got.out == ""
    assert (f"mpz encode: 1 of 2 inputs written before {said}: {tmp_path / 'a.mpz'}; "
            "the others are not (no partial file is left)") in got.err, got.err
    assert (tmp_path / "a.mpz").exists() and not (tmp_path / "b.mpz").exists()


def _json_values(streamed: bool):
    """JSON-like values; with ``streamed``, some arrays are Streamed (made as written)."""
    from hypothesis import strategies as st

    from mpz.tools._cli import Streamed
    leaf = (st.none() | st.booleans() | st.integers() | st.text(max_size=5)
            | st.floats(allow_nan=True, allow_infinity=True))

    def arrays(items):
        lists = st.lists(items, max_size=4)
        if not streamed:
            return lists
        return lists | lists.map(lambda xs: Streamed(lambda: iter(xs)))
    return st.recursive(leaf, lambda inner: arrays(inner) | st.dictionaries(
        st.text(max_size=4), inner, max_size=4), max_leaves=20)


def test_a_streamed_document_is_the_text_of_the_whole_one() -> None:
    """print_json writes a document holding Streamed arrays (mpz summary's segments) as
    it makes it; its text must be what json_text gives for the same document made whole,
    at every indent, in ASCII or not, with non-finite numbers as null."""
    import io

    from hypothesis import given, settings
    from hypothesis import strategies as st

    from mpz.tools._cli import Streamed, json_text, print_json

    def whole(v):
        if isinstance(v, Streamed):
            return [whole(x) for x in v._items()]
        if isinstance(v, dict):
            return {k: whole(x) for k, x in v.items()}
        if isinstance(v, list):
            return [whole(x) for x in v]
        return v

    class Ascii(io.StringIO):
        encoding = "ascii"

    @settings(max_examples=300, deadline=None)
    @given(doc=st.dictionaries(st.text(max_size=4), _json_values(True), max_size=4),
           indent=st.sampled_from([None, 1, 2]), ascii_out=st.booleans())
    def check(doc, indent, ascii_out):
        out = Ascii() if ascii_out else io.StringIO()
        print_json({"schema": "x", "rows": Streamed(lambda: iter([doc]))},
                   file=out, indent=indent)
        want = json_text({"schema": "x", "rows": [whole(doc)]}, indent=indent,
                         ascii_only=ascii_out) + "\n"
        assert out.getvalue() == want
        json.loads(out.getvalue())
        # and json_text, given the Streamed arrays, writes them whole: the same text
        assert json_text({"schema": "x", "rows": Streamed(lambda: iter([doc]))},
                         indent=indent, ascii_only=ascii_out) + "\n" == want
    check()
