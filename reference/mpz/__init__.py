"""MPZ: compressed human motion-capture data.

The public API is re-exported here; see README.md for a tour and
``spec/mpz-1.md`` for the format.

>>> import mpz
>>> from mpz.synth import generate
>>> m = generate("walk", frames=48)
>>> data = mpz.encode(m, max_error=1.0)
>>> back = mpz.decode(data)
>>> back.n_frames, back.names == m.names
(48, True)

``mpz.decode`` and ``mpz.info`` take a path, the bytes or a binary file object;
``mpz.encode`` takes plain numbers in the motion's units (``help(mpz.encode)``);
``mpz.io`` reads and writes C3D, TRC, BVH, AMC, NPY and CSV.
"""
from mpz import (
                        _worker,  # noqa: F401  (first: a worker process's SIGINT, mpz._worker)
                        io,
)
from mpz._identity import identity
from mpz.api import (
    FileInfo,
    Summary,
    SummaryLevel,
    decode,
    info,
    read_mpz,
    read_summary,
    write_atomic,
    write_mpz,
)
from mpz.encoder import EncodeOptions, EncodeReport, NodeReport, encode, encode_motion
from mpz.errors import (
                        ChecksumError,
                        EncoderError,
                        FormatError,
                        InputFormatError,
                        LimitExceededError,
                        MotionError,
                        MPZError,
                        UnsupportedVersionError,
)
from mpz.metrics import arms, max_error
from mpz.motion import Motion, concatenate

#: the package version; the bitstream version is separate (spec Appendix B, CHANGELOG.md).
#: Every development checkout between two releases has the same one: :func:`identity`
#: tells them apart
__version__ = "0.2.0.dev0"   # pyproject.toml's (tests/test_packaging.py)

__all__ = ["MPZError", "FormatError", "ChecksumError", "UnsupportedVersionError",
           "LimitExceededError", "InputFormatError", "MotionError", "EncoderError",
           "Motion", "concatenate", "decode", "info", "FileInfo", "io", "encode",
           "encode_motion", "EncodeOptions", "EncodeReport", "NodeReport",
           "arms", "max_error", "read_mpz", "write_mpz", "read_summary",
           "Summary", "SummaryLevel", "write_atomic", "__version__", "identity"]
