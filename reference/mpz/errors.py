"""The MPZ error hierarchy.

Contract: what the data holds (a file, a motion, the options' values) fails
with a subclass of :class:`MPZError` and nothing else. A call itself made
wrongly fails as Python's own calls do: an argument of the wrong type (a
bytes path, a number where a Motion goes) with ``TypeError``, a bad argument
value that is not data (a reader's ``rate``, a ``fmt`` no reader has, an
``asf`` for another format than AMC) with ``ValueError``; the docstrings say
which. Errors about bad input also subclass :class:`ValueError`, so callers
that already catch ``ValueError`` keep working. Each error carries what a caller needs to
act on it as attributes (byte offset, chunk type, spec section, file name).
"""
from __future__ import annotations

#: the longest message an error keeps: a reader's message that quotes the input (a BVH
#: joint name, an ASF token) quoted a 100 MB token whole, 100 MB on standard error and
#: twice that with --json (a security QA run, stop 73)
MAX_MESSAGE_CHARS = 10_000


def _bounded(message: str) -> str:
    """``message``, or its first and last characters around a count of those left out
    when it is longer than :data:`MAX_MESSAGE_CHARS`."""
    if not isinstance(message, str) or len(message) <= MAX_MESSAGE_CHARS:
        return message
    head, tail = MAX_MESSAGE_CHARS * 7 // 10, MAX_MESSAGE_CHARS // 5
    return (f"{message[:head]} ... ({len(message) - head - tail} characters left out) ... "
            f"{message[-tail:]}")


class MPZError(Exception):
    """Root of every error MPZ raises on purpose.

    Attributes
    ----------
    message : str
        What is wrong, without the location (``str(exc)`` adds path, chunk, offset and §).
    offset : int or None
        Byte offset in the bitstream where the problem was found.
    chunk : str or None
        Four-character chunk type being read, if any.
    section : str or None
        Spec section that states the violated rule, e.g. ``"§4.3"``.
    path : str or None
        File the data came from, if known.
    """

    def __init__(self, message: str, *, offset: int | None = None,
                 chunk: str | None = None, section: str | None = None,
                 path: str | None = None) -> None:
        self.message = _bounded(message)
        self.offset = offset
        self.chunk = chunk
        self.section = section
        self.path = path
        super().__init__(self._render())

    def _render(self) -> str:
        where: list[str] = []
        if self.path:
            where.append(str(self.path))
        if self.chunk:
            where.append(f"chunk {self.chunk}")
        if self.offset is not None:
            where.append(f"offset {self.offset} (0x{self.offset:x})")
        text = self.message
        if self.section and self.section not in text:
            text = f"{text} ({self.section})"
        return f"{': '.join([', '.join(where), text]) if where else text}"

    def __str__(self) -> str:  # keep str() in step with attributes set later
        return self._render()


class FormatError(MPZError, ValueError):
    """The data does not follow the MPZ specification (or an input format)."""


class ChecksumError(FormatError):
    """A stored CRC-32 does not match the computed one (spec §3.3)."""


class UnsupportedVersionError(FormatError):
    """The major version is not one this decoder implements (spec §2.1)."""


class LimitExceededError(FormatError):
    """A count or length is beyond a limit of spec §8, or beyond the bytes left."""


class InputFormatError(FormatError):
    """A motion-capture input file (C3D, TRC, BVH, AMC/ASF, ...) cannot be read."""


class MotionError(MPZError, ValueError):
    """A :class:`mpz.Motion` is inconsistent (shape, names, values)."""


class EncoderError(MPZError, ValueError):
    """The encoder was given options it cannot honour."""
