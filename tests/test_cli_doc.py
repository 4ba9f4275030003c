"""docs/cli.md names every option of every command (``python -m mpz.tools.make_cli_doc``
writes it from the commands' --help): an option added to a command without regenerating
the page fails here. The page's text is argparse's, whose layout differs between Python
versions, so what is checked is the options and the commands, not the layout."""
from __future__ import annotations

import re

from mpz.tools import make_cli_doc

OPTION = re.compile(r"(?<![\w-])--?[A-Za-z][\w-]*")


def test_every_command_and_option_is_on_the_page():
    page = make_cli_doc.DOC.read_text(encoding="utf-8")
    sections = dict(re.findall(r"^## `([^`]+)`\n\n```\n(.*?)\n```", page, re.S | re.M))
    helps = make_cli_doc.helps()
    assert set(helps) == set(sections), "run python -m mpz.tools.make_cli_doc"
    for cmd, text in helps.items():
        now = set(OPTION.findall(text.split("\noptions:", 1)[-1]))
        shown = set(OPTION.findall(sections[cmd]))
        assert now <= shown, (f"{cmd}: {sorted(now - shown)} missing from docs/cli.md; run "
                              "python -m mpz.tools.make_cli_doc")


def test_the_page_covers_the_subcommands_and_the_other_tools():
    helps = make_cli_doc.helps()
    assert {"mpz", "mpz encode", "mpz decode", "mpz search", "mpzinfo",
            "mpz-conformance"} <= set(helps)
    assert "--max-error" in helps["mpz encode"] and "--max-samples" in helps["mpzinfo"]


def test_mpzinfo_json_fields_are_documented_and_always_present(tmp_path, capsys):
    """docs/mpzinfo.md names every field of an mpzinfo --json entry, and an unreadable
    file's entry has the same fields as a valid one's (it had six: a script reading
    entry["ratio"] failed on a missing file)."""
    import json

    import mpz
    from mpz.synth import generate
    from mpz.tools import mpzinfo
    (tmp_path / "w.mpz").write_bytes(mpz.encode(generate("walk", frames=20, seed=1),
                                                max_error=1.0))
    mpzinfo.main(["--json", str(tmp_path / "w.mpz"), str(tmp_path / "missing.mpz")])
    ok, missing = json.loads(capsys.readouterr().out)["files"]
    assert ok["status"] == "ok" and missing["status"] == "error"
    assert set(ok) == set(missing)
    page = (make_cli_doc.DOC.parent / "mpzinfo.md").read_text(encoding="utf-8")
    named = set(re.findall(r"`(\w+)`", page))
    assert set(ok) <= named, sorted(set(ok) - named)


def test_the_page_is_the_help_as_it_is_now():
    """Only the options were checked: a help text changed without a new page passed (a
    stale description of --time-floor's default at stop 53). The page is the generator's
    output, whole."""
    assert make_cli_doc.DOC.read_text(encoding="utf-8") == make_cli_doc.render(), \
        "docs/cli.md is stale: run python -m mpz.tools.make_cli_doc"
