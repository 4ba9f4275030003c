"""What a decoded file's ancillary chunks rebuild, written into memory.

``mpz decode -o X.c3d / X.bvh / X.amc`` writes the source file back from the C3D archive
(spec §4.13, §6.9) or the skeleton chunk (§4.14, §6.10). The fuzz target
(``conformance/fuzz/fuzz_decoder.py``) and the corpus replay (``conformance/test_corpus.py``)
run those writers on every file they decode, through this one function.
"""
from __future__ import annotations

from mpz.motion import Motion


def rebuild_sources(m: Motion) -> dict[str, bytes | str]:
    """The source files ``m`` carries, by extension: ``.c3d`` bytes, ``.bvh`` text, or the
    ``.asf`` and ``.amc`` texts (empty when it carries none).

    Raises
    ------
    MPZError
        An :class:`~mpz.errors.InputFormatError` when a valid file holds what the format
        cannot express (for example coordinates beyond float32 in a C3D). Any other
        exception is a bug of the writer.
    """
    from mpz.io import amc, bvh, c3d
    from mpz.io.kinematics import Skeleton
    out: dict[str, bytes | str] = {}
    if m.extras.get("c3d") is not None:
        out[".c3d"] = c3d.archive_bytes(m)
    skel = m.extras.get("skeleton")
    if isinstance(skel, Skeleton):
        if skel.convention == "bvh":
            out[".bvh"] = bvh.format_bvh(m)
        else:
            out[".asf"] = amc.format_asf(skel)
            out[".amc"] = amc.format_amc(m)
    return out
