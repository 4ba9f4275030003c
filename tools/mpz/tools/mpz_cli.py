"""``mpz``: encode, decode, inspect and analyse motion-capture data.

Each subcommand lives in its own module ``mpz.tools.cmd_<name>`` exposing
``add_parser(subparsers)`` and ``run(args) -> int``; this module only
dispatches (an explicit table, no getattr magic).

Exit codes (all subcommands): 0 ok, 1 warnings only, 2 errors in the input
or the data, 64 usage error (argparse's own errors are mapped to 64 too).
"""
from __future__ import annotations

import argparse
import importlib
import sys

from mpz.errors import MPZError

EXIT_OK, EXIT_WARN, EXIT_ERROR, EXIT_USAGE = 0, 1, 2, 64

#: subcommand name -> module implementing it
SUBCOMMANDS = {
    "encode": "mpz.tools.cmd_encode",
    "decode": "mpz.tools.cmd_decode",
    "compare": "mpz.tools.cmd_compare",
    "show": "mpz.tools.cmd_show",
    "summary": "mpz.tools.cmd_summary",
    "bench": "mpz.tools.cmd_bench",
}


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # usage errors get their own exit code
        self.print_usage(sys.stderr)
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        raise SystemExit(EXIT_USAGE)


def build_parser() -> argparse.ArgumentParser:
    from mpz import __version__
    parser = _Parser(prog="mpz", description="MPZ motion-capture compression tools.")
    parser.add_argument("--version", action="version", version=f"mpz {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name, modname in SUBCOMMANDS.items():
        mod = importlib.import_module(modname)
        mod.add_parser(sub)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except MPZError as exc:
        print(f"mpz {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into e.g. head: stop quietly
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
