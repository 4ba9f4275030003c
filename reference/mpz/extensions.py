"""What a source file holds besides marker positions: the extension table.

Strategy: MPZ 1.0 codes marker trajectories. Everything else a source file holds (a
C3D's analog channels, parameters and events; a BVH or ASF skeleton and its channels)
travels in *ancillary* chunks owned by an extension, so that a 1.0 decoder skips them
(spec §2.3) and still decodes every marker (§2.1). Each extension

- names the key it uses in :attr:`mpz.Motion.extras` and the chunk types it owns
  (their records are in :mod:`mpz.chunks`, like every other chunk);
- turns its part of a Motion into chunk records when encoding (:meth:`Extension.records`);
- turns the checked records back into its part of a Motion when decoding
  (:meth:`Extension.attach`).

:data:`EXTENSIONS` is the one table the encoder and decoder consult; adding an
extension is adding one entry here.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

from mpz.c3darchive import C3D_EXTENSION
from mpz.skeleton import EXTENSION as SKELETON_EXTENSION

if TYPE_CHECKING:
    from mpz.chunks import Record
    from mpz.encoder import EncodeOptions
    from mpz.motion import Motion


class Extension(Protocol):
    """One feature carried in ancillary chunks (see the module docstring)."""

    #: the key of :attr:`mpz.Motion.extras` this extension reads and writes
    name: str
    #: the ancillary chunk types it owns, in the order it writes them
    chunk_types: tuple[str, ...]
    #: the spec's § of its chunks as a family and of their decoding (each chunk's own §
    #: is its record's ``SECTION``): what a file holding them exercises (the vectors'
    #: ``sections``)
    sections: tuple[str, ...]
    #: True when its part of a Motion holds values per frame (a C3D archive's point words
    #: and analog samples), so that motions holding it cannot be joined end to end
    #: (:func:`mpz.concatenate`); False when it describes every frame alike (a skeleton,
    #: whose channel values are ``Motion.angles``)
    per_frame: bool
    #: what its part of a Motion holds, in words, for the messages that name it
    held: str

    def check(self, motion: Motion, opts: EncodeOptions) -> None:
        """Raise EncoderError if ``motion``'s part for this extension is past a §8 limit of
        its chunks: the encoder calls it before anything is encoded (and before
        :meth:`records`), so that no work is spent on a file the decoder would refuse."""
        ...

    def records(self, motion: Motion, opts: EncodeOptions) -> list[Record]:
        """The chunk records for ``motion`` (empty when the motion has nothing for it)."""
        ...

    def attach(self, records: dict[str, list[Record]], motion: Motion) -> None:
        """Rebuild ``motion.extras[name]`` (and whatever else it owns) from checked records."""
        ...

    def cut(self, part: object, start: int) -> object | None:
        """What a cut of a motion from its frame ``start`` on (:meth:`mpz.Motion.select_frames`)
        keeps of this extension's ``part``: the part, with any frame number it holds moved
        to the cut's first frame; None when it belongs to the source's own frames (then the
        cut names it among what it does not keep)."""
        ...


#: every extension, in the order their chunks are written
EXTENSIONS: tuple[Extension, ...] = (C3D_EXTENSION, SKELETON_EXTENSION)


def owner(ctype: str) -> Extension | None:
    """The extension that owns chunk type ``ctype``, if any."""
    for ext in EXTENSIONS:
        if ctype in ext.chunk_types:
            return ext
    return None
