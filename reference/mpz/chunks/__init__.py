"""The chunk table: one entry per chunk type of spec §4, holding everything about it.

Strategy (as mutagen's ``METADATA_BLOCKS``): each chunk type is a frozen dataclass, a
*typed record* of its payload (:class:`~mpz.chunks.base.Record`), with

- ``TYPE``, ``SECTION`` and ``GRAMMAR``: its four letters, its § and its construct
  layout from :mod:`mpz.spec.grammar`; ``MINOR``, the 1.x that added it (§2.1), and
  ``PART``, the part of a file its bytes count in (what ``mpzinfo`` and the corpus index
  report);
- ``load`` / ``dump``: payload bytes <-> record (the build side);
- ``check``: the rules of its § that need only the record and what the §3.4 order has
  already established (a :class:`~mpz.chunks.base.Context`);
- ``info``: the fields ``mpzinfo`` shows, in layout order, JSON-ready.

Records hold whatever the bytes say, valid or not (vectors are built from invalid
records); only ``check`` judges them. Checks raise :class:`~mpz.errors.MPZError` without a
location; :func:`mpz.container.locate` adds the chunk and its offset in one place.

Adding a chunk type (each step has a test that fails when it is missed):

1. its § in ``spec/mpz-1.md`` (layout table, checks each with a rule ID listed in §7.4,
   decoding) and its layout in :mod:`mpz.spec.grammar`; the first chunk of a new minor
   version raises ``VERSION_MINOR`` there (``tests/test_spec_text.py``);
2. one record class in the module of its feature (``core`` for MPZ 1.0), with ``TYPE``,
   ``SECTION``, ``GRAMMAR``, ``MINOR``, ``PART`` and ``check`` (each rule's ID in a comment
   at its check), in that module's tuple, which :data:`CHUNKS` below collects;
3. an ancillary chunk other than the summary and meta: its type in the ``chunk_types`` of
   the extension that writes and reads it (:data:`mpz.extensions.EXTENSIONS`), or its
   data is dropped by every decode;
4. vectors for it in :mod:`mpz.tools.make_vectors`, then the vectors and the golden files
   regenerated (``make_vectors``, ``make_golden``) and a CHANGELOG entry. ``mpzinfo``
   shows the fields from ``info`` with nothing more.
"""
from __future__ import annotations

from mpz.chunks.base import JSON, Context, Record
from mpz.chunks.c3d import C3D, Cana, Chdr, Cpnt, Cprm
from mpz.chunks.core import (
    CORE,
    Hier,
    HierNode,
    Mask,
    Mend,
    Meta,
    MetaEntry,
    Mhdr,
    Mnam,
    Patt,
    Qunt,
    Resi,
    Root,
    Segs,
    Smry,
    SummaryLevel,
)
from mpz.chunks.skeleton import SKELETON, Asfs, Bvhs
from mpz.chunks.summary import SUMMARY, Smrc

__all__ = ["CHUNKS", "JSON", "Context", "Record", "Hier", "HierNode", "Mask", "Meta",
           "MetaEntry", "Mend", "Mhdr", "Mnam", "Patt", "Qunt", "Resi", "Root", "Segs", "Smry",
           "SummaryLevel", "load", "types_of_part", "Chdr", "Cprm", "Cpnt", "Cana", "Bvhs",
           "Asfs", "Smrc"]

#: chunk type -> record class: the one registry, in the order of the spec's catalogue
CHUNKS: dict[str, type[Record]] = {cls.TYPE: cls for cls in (*CORE, *C3D, *SKELETON, *SUMMARY)}


def types_of_part(part: str) -> tuple[str, ...]:
    """The chunk types whose :attr:`~mpz.chunks.base.Record.PART` is ``part`` ("analog",
    "skeleton", "summary"), in :data:`CHUNKS` order: what a report by part adds up."""
    return tuple(t for t, cls in CHUNKS.items() if cls.PART == part)


def load(ctype: str, payload: bytes) -> Record:
    """The record of a payload of a known chunk type."""
    return CHUNKS[ctype].load(payload)
