"""MPZ: compressed human motion-capture data.

The public API is re-exported here; see README.md for a tour and
``spec/mpz-1.md`` for the format.
"""
from mpz.errors import (MPZError, FormatError, ChecksumError, UnsupportedVersionError,
                        LimitExceededError, InputFormatError, MotionError, EncoderError)
from mpz.motion import Motion, concatenate

__version__ = "0.1.0"

__all__ = ["MPZError", "FormatError", "ChecksumError", "UnsupportedVersionError",
           "LimitExceededError", "InputFormatError", "MotionError", "EncoderError",
           "Motion", "concatenate", "__version__"]
