"""Write docs/cli.md, every command's ``--help``: ``python -m mpz.tools.make_cli_doc``.

The options of ``mpz`` (each subcommand), ``mpzinfo`` and ``mpz-conformance`` are
documented where argparse documents them, in their help texts; this page collects those
texts verbatim, so that a reader finds every option and its default in one place without
running the tools. tests/test_cli_doc.py fails when a command has an option the page does
not name: run this command after adding one. The text is argparse's, 100 columns wide;
Python 3.13 formats an option's metavar once (``-o, --output OUTPUT``), earlier versions
twice, so the page says which Python wrote it.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import os
from pathlib import Path
import platform
import sys

# tools/mpz/tools/make_cli_doc.py -> the repository root is three folders up
DOC = Path(__file__).resolve().parents[3] / "docs" / "cli.md"
WIDTH = "100"


def _help(main, argv: list[str]) -> str:
    """What ``main(argv + ["--help"])`` prints, at :data:`WIDTH` columns."""
    out = io.StringIO()
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH
    try:
        with contextlib.redirect_stdout(out):
            try:
                main([*argv, "--help"])
            except SystemExit:
                pass
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old
    return out.getvalue().rstrip() + "\n"


def helps() -> dict[str, str]:
    """{command line: its --help text}, for every command and subcommand."""
    from mpz.conformance import runner
    from mpz.tools import mpz_cli, mpzinfo
    out = {"mpz": _help(mpz_cli.main, [])}
    for name in mpz_cli.SUBCOMMANDS:
        out[f"mpz {name}"] = _help(mpz_cli.main, [name])
    out["mpzinfo"] = _help(mpzinfo.main, [])
    out["mpz-conformance"] = _help(runner.main, [])
    return out


def render() -> str:
    parts = ["# Command-line reference", "",
             "Every option of every command, with its default, as the command's `--help` "
             "prints it. Written by `python -m mpz.tools.make_cli_doc` "
             f"(Python {platform.python_version()}, {WIDTH} columns); do not edit by hand. "
             "The README says what the commands are for; exit codes are in its "
             "[table](../README.md#command-exit-codes).", ""]
    for cmd, text in helps().items():
        parts += [f"## `{cmd}`", "", "```", text.rstrip(), "```", ""]
    return "\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m mpz.tools.make_cli_doc",
                                description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=DOC, help=f"default: {DOC}")
    args = p.parse_args(argv)
    if not args.out.parent.is_dir():      # installed from a wheel: a traceback (a QA run)
        p.error(f"{args.out.parent}: no such folder: run this in a clone of the repository "
                "(its docs/), or give --out")
    from mpz.tools._cli import printable
    args.out.write_text(render(), encoding="utf-8")
    print(f"wrote {printable(str(args.out))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
