"""The mutation table (conformance/mutation.py) still matches the code it mutates.

Each row is an exact text replacement; a refactor that moves or rewrites the code leaves
the row *stale*, and the mutation run only reports it at the end of 30-60 minutes (a stop
moved the smry head rules into a shared helper, and eleven rows went stale unnoticed).
This test reads the table and the files; it runs no mutant.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path
import sys

REPO = Path(__file__).resolve().parent.parent


def _table():
    spec = importlib.util.spec_from_file_location("mpz_mutation_table",
                                                  REPO / "conformance" / "mutation.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module          # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_every_mutant_finds_its_text_exactly_once():
    table = _table()
    mutants = table.MUTANTS                  # the 1.1 rows (MUTANTS_11) included
    assert len({m.id for m in mutants}) == len(mutants), "a mutant id is used twice"
    stale = [f"{m.id} ({m.file})" for m in mutants
             if table.applicable(m, (REPO / m.file).read_text(encoding="utf-8")) is None]
    assert not stale, f"stale mutants: {', '.join(stale)}: update conformance/mutation.py"
