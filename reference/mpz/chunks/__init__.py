"""The chunk table: one entry per chunk type of spec §4, holding everything about it.

Strategy (as mutagen's ``METADATA_BLOCKS``): each chunk type is a frozen dataclass, a
*typed record* of its payload (:class:`~mpz.chunks.base.Record`), with

- ``TYPE``, ``SECTION`` and ``GRAMMAR``: its four letters, its § and its construct
  layout from :mod:`mpz.spec.grammar`;
- ``load`` / ``dump``: payload bytes <-> record (the build side);
- ``check``: the rules of its § that need only the record and what the §3.4 order has
  already established (a :class:`~mpz.chunks.base.Context`);
- ``info``: the fields ``mpzinfo`` shows, in layout order, JSON-ready.

Records hold whatever the bytes say, valid or not (vectors are built from invalid
records); only ``check`` judges them. Checks raise :class:`~mpz.errors.MPZError` without a
location; :func:`mpz.container.locate` adds the chunk and its offset in one place.

Adding a chunk type: its layout in :mod:`mpz.spec.grammar`, one record class in the
module of its feature (``core`` for MPZ 1.0), its entry in :data:`CHUNKS` below, and its §
in ``spec/mpz-1.md``.
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
           "SummaryLevel", "load", "Chdr", "Cprm", "Cpnt", "Cana", "Bvhs", "Asfs", "Smrc"]

#: chunk type -> record class: the one registry, in the order of the spec's catalogue
CHUNKS: dict[str, type[Record]] = {cls.TYPE: cls for cls in (*CORE, *C3D, *SKELETON, *SUMMARY)}


def load(ctype: str, payload: bytes) -> Record:
    """The record of a payload of a known chunk type."""
    return CHUNKS[ctype].load(payload)
