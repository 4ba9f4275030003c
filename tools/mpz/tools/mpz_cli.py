"""``mpz``: encode, decode, inspect and analyse motion-capture data.

Each subcommand lives in its own module ``mpz.tools.cmd_<name>`` exposing
``add_parser(subparsers)`` and ``run(args) -> int``; this module only
dispatches (an explicit table, no getattr magic).

Exit codes (all subcommands; the table shared with ``mpzinfo`` and
``mpz-conformance`` is in :mod:`mpz.tools._cli`): 0 ok, 1 warnings only, 2
errors in the input or the data (in a batch: some input failed), 3 out of
memory, 64 usage error (argparse's own errors too, reported by the
subcommand with a "did you mean" hint), 130 interrupted (Ctrl-C).
"""
from __future__ import annotations

import argparse
import importlib
import sys

from mpz.errors import MPZError
from mpz.tools._cli import (
    EXIT_CODES_HELP,
    EXIT_ERROR,
    EXIT_MEMORY,
    Parser,
    add_version,
    document_started,
    forget_documents,
    json_failure,
    memory_message,
    print_json,
    printable,
    quiet_broken_pipe,
    reports_ctrl_c,
    running,
)

#: subcommand name -> module implementing it
SUBCOMMANDS = {
    "encode": "mpz.tools.cmd_encode",
    "decode": "mpz.tools.cmd_decode",
    "compare": "mpz.tools.cmd_compare",
    "show": "mpz.tools.cmd_show",
    "summary": "mpz.tools.cmd_summary",
    "bench": "mpz.tools.cmd_bench",
    "search": "mpz.tools.cmd_search",
}


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="mpz", description="MPZ motion-capture compression tools.",
                    epilog=EXIT_CODES_HELP)
    add_version(parser)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for modname in SUBCOMMANDS.values():
        mod = importlib.import_module(modname)
        mod.add_parser(sub)
    for sp in sub.choices.values():     # each subcommand's --help gives the exit codes too
        if sp.epilog is None and "Exit 0" not in (sp.description or ""):
            sp.epilog = EXIT_CODES_HELP
    return parser


@quiet_broken_pipe
@reports_ctrl_c("interrupted")
def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    running(f"mpz {args.command}")
    forget_documents()
    # a failing command run with --json says so on stdout too (mpz-error/1, docs/json.md;
    # encode prints its own: one input's error document, or a batch's failures)
    failure_doc = getattr(args, "json", False) and args.command != "encode"
    try:
        return int(args.func(args))
    except MPZError as exc:
        print(f"mpz {args.command}: error: {printable(str(exc))}", file=sys.stderr)
        _failure_document(failure_doc, args.command, exc)
        return EXIT_ERROR
    except MemoryError as exc:      # a resource error, not a verdict on the input (spec §8)
        said = memory_message(exc, args.command)
        print(f"mpz {args.command}: {said}", file=sys.stderr)
        _failure_document(failure_doc, args.command, said, "memory")
        return EXIT_MEMORY


def _failure_document(wanted: bool, command: str, exc: BaseException | str,
                      status: str = "error") -> None:
    """Print the ``mpz-error/1`` document of a failed ``--json`` command, unless its own
    report was begun on standard output (:func:`document_started`): then standard error
    says that the report there is cut short."""
    if not wanted:
        return
    begun = document_started()
    if begun is None:
        print_json(json_failure(command, exc, status))
    elif begun:
        print(f"mpz {command}: the --json report on standard output is complete; this "
              "error came after it", file=sys.stderr)
    else:
        print(f"mpz {command}: the --json report on standard output is cut short there, "
              "and is not valid JSON", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
