"""``mpzinfo``: look inside MPZ files.

Default: one line per file (pngcheck style)::

    OK: walk.mpz (MPZ 1.0, 120 Hz, 5202 frames, 41 markers, 9 nodes, 312 patterns,
        markers 1.8 MB as float32 -> file 71 KB, 35.2:1, max error <= 2.0 mm)

The ratio compares the markers as float32 with the whole file (``ratio_of`` in
``--json``), as ``mpz encode``'s "ratio vs float32" does; a file that keeps more
(analog channels, a skeleton, C3D parameters) also gets its bytes by part, and the
markers' chunks against the markers (``bytes_by_part``, ``ratio_markers``). A file with a
skeleton leads with its channels as float32 against the whole file (``ratio_channels``):
they are what a BVH or AMC source holds. A file in error gets
no ratio, and fields from an MHDR whose CRC failed are marked unverified
(``header_crc_ok``).

``-v`` adds one line per chunk (type, offset, length, CRC ok or bad with the
computed and stored values); ``-vv`` adds every field of every chunk, a chunk's own
fields with their byte offset (a value of more than 100 characters cut: ``--json``
has it whole; a list of records, such as asfs's bones, one record a line), and the
fields the grammar decodes further (MNAM's front-coded names, HIER's weight codes,
meta's and the skeleton chunks' texts) also as stored, one line per entry at its
offset (``stored`` in ``--json``); ``--json`` prints a versioned document (schema
``mpzinfo/2``). mpzinfo keeps going past a bad CRC and shows what can still be read;
it also runs the full integer decoding (``--no-decode`` skips it) so that a file
that cannot be decoded never passes.

``-`` reads standard input (bounded: chunk by chunk, stopping at MEND). A
device, FIFO or socket given by name is refused without being read. File
names and every string from a file are printed escaped
(:func:`mpz.tools._cli.printable`).

Exit codes: 0 ok, 1 warnings only, 2 errors in a file, 3 out of memory (the
file may be valid), 64 usage error.
"""
from __future__ import annotations

import sys
from typing import Any

from mpz._identity import source_fingerprint
from mpz.chunks import Mhdr, Patt, Segs, Smrc, Smry
from mpz.chunks.base import infinite_as_text
from mpz.container import scan
from mpz.decoder import decode_layers, read_stream
from mpz.errors import MPZError
from mpz.format import MAX_SAMPLES, UNIT_NAMES, Units
from mpz.tools._cli import (
    EXIT_CODES_HELP,
    EXIT_ERROR,
    EXIT_MEMORY,
    EXIT_OK,
    EXIT_WARN,
    MAX_SAMPLES_HELP,
    Parser,
    add_version,
    bound_text,
    found,
    json_text,
    jsonable,
    max_samples,
    memory_message,
    print_json,
    printable,
    quiet_broken_pipe,
    reports_ctrl_c,
)
from mpz.tools._common import human_size, ratio_text

#: the --json document's version: 2 since stop 53, when non-finite field values became
#: texts (null in 1; docs/mpzinfo.md lists the versions)
SCHEMA = "mpzinfo/2"


def _err(e: MPZError) -> dict:
    return {"class": type(e).__name__, "message": e.message, "offset": e.offset,
            "chunk": e.chunk, "section": e.section}


#: JSON has no NaN or infinity: such values are null (errors[] says why); the shared encoder
_finite = jsonable


def inspect(data: bytes, name: str = "-", *, decode: bool = True,
            max_samples: int = MAX_SAMPLES) -> dict:
    """Everything mpzinfo knows about one file, as a JSON-ready dict (``max_samples``: a
    lower F x M limit, spec §8)."""
    res = scan(data)
    info = _blank(name, len(data))
    for c in res.chunks:
        entry: dict[str, Any] = {
            "type": c.type, "offset": c.offset, "length": c.length, "critical": c.critical,
            "crc_ok": c.crc_ok, "crc_stored": c.crc_stored, "crc_computed": c.crc_computed,
            "fields": None}
        if c.record is not None:
            # each chunk's entry in the chunk table says what to show (mpz.chunks)
            entry["fields"] = c.record.info()
            base = (c.offset or 0) + 8      # scanned chunks always have an offset
            entry["field_offsets"] = {n: base + o for n, o in
                                      type(c.record).field_offsets(c.payload)}
            stored = type(c.record).stored_fields(c.payload)
            if stored:                      # MNAM's shared/suffix, HIER's weight codes
                entry["stored"] = {n: _at_file(infinite_as_text(v), base)
                                   for n, v in stored.items()}
        info["chunks"].append(entry)
    errors = list(res.errors)
    warnings = list(res.warnings)
    records = [c.record for c in res.chunks if c.record is not None]
    hdr = records[0] if records and isinstance(records[0], Mhdr) else None
    if hdr is not None:
        info.update(version=f"{hdr.version_major}.{hdr.version_minor}", rate=hdr.rate,
                    frames=hdr.frame_count, markers=hdr.marker_count, nodes=hdr.node_count,
                    units=(UNIT_NAMES.get(Units(hdr.units)) or None) if hdr.units in set(Units)
                    else None,   # unknown: null, as in every --json output (README)
                    error_metric=hdr.error_metric,
                    error_bound=hdr.error_bound if hdr.error_metric else None,
                    raw_size=12 * hdr.frame_count * hdr.marker_count)
        info["header_crc_ok"] = bool(res.chunks[0].crc_ok)
    patt = [r for r in records if isinstance(r, Patt)]
    segs = [r for r in records if isinstance(r, Segs)]
    if patt:
        info["patterns"] = sum(p.pattern_count for p in patt)
    if segs or patt:
        info["segments"] = sum(s.segment_count for s in segs)
    smry = [r for r in records if isinstance(r, (Smry, Smrc))]
    if smry:
        info["summary_levels"] = [lv.k for lv in smry[0].levels]
    if not errors:
        try:
            if decode:
                decode_layers(data, max_samples=max_samples)
            else:
                read_stream(data, max_samples=max_samples)
        except MPZError as exc:
            errors.append(exc)
    info["errors"] = [_err(e) for e in errors]
    info["warnings"] = [_err(w) for w in warnings]
    info["status"] = "error" if errors else ("warning" if warnings else "ok")
    if hdr is not None and not errors:
        # no ratio for a file in error: its sizes say nothing of what a valid one keeps
        parts = _parts(res.chunks, len(data))
        info["bytes_by_part"] = parts
        info["ratio"] = info["raw_size"] / len(data) if data else None
        info["ratio_markers"] = (info["raw_size"] / parts["markers"] if parts["markers"]
                                 else None)
        # the figures of spec §7.3's features.skeleton, which says mpzinfo reports them
        # (it did not: a QA run of stop 53)
        from mpz.chunks import Asfs, Bvhs
        from mpz.skeleton import record_report
        for c in res.chunks:
            if isinstance(c.record, (Asfs, Bvhs)):
                info["skeleton"] = record_report(c.record, c.length, end_sites=True)
                # what a BVH or AMC source holds is its channels: the ratio against the
                # joint positions alone was 1.3-1.5x the one mpz encode leads with (a QA
                # run of stop 55: "reports never flatter")
                info["ratio_channels"] = (4 * hdr.frame_count * c.record.channel_count
                                          / len(data))
                break
    return _finite(info)


#: what ``ratio`` compares (the yardstick of mpz encode's "ratio ... vs float32")
RATIO_OF = "markers as float32 (12 bytes a marker-frame) / the whole file"


def _parts(chunks: list, size: int) -> dict[str, int]:
    """Bytes of the file by part, as mpz encode counts them (:func:`parts_of`)."""
    from mpz.tools._common import parts_of
    framed: dict[str, int] = {}
    for c in chunks:
        framed[c.type] = framed.get(c.type, 0) + c.length + 12
    return parts_of(framed, size)


def _where(e: dict) -> str:
    """`` in chunk MASK at offset 178 (§4.5)``: as much of the place as the error names."""
    chunk = f" in chunk {printable(e['chunk'])}" if e.get("chunk") else ""
    offset = f" at offset {e['offset']}" if e.get("offset") is not None else ""
    return chunk + offset + (f" ({e['section']})" if e.get("section") else "")


def summary_line(info: dict) -> str:
    tag = {"ok": "OK", "warning": "WARN", "error": "ERROR", "memory": "MEMORY"}[info["status"]]
    name = printable(info["file"])
    if info["frames"] is None:
        if not info["errors"]:
            return f"{tag}: {name} (unreadable)"
        e = info["errors"][0]
        return f"{tag}: {name} ({printable(e['message'])}{_where(e)})"
    rate = "unknown rate" if info["rate"] is None else f"{info['rate']:g} Hz"
    parts = [f"MPZ {info['version']}", rate, f"{info['frames']} frames",
             f"{info['markers']} markers", f"{info['nodes']} nodes"]
    if info.get("header_crc_ok") is False:     # fields from an MHDR whose CRC failed
        parts[0] = f"MHDR CRC bad, unverified: {parts[0]}"
    if info["patterns"] is not None:
        parts.append(f"{info['patterns']} patterns")
    if info.get("ratio") is None:              # a file in error: its size, no ratio
        parts.append(f"{human_size(info['size'])}")
    else:
        if info.get("ratio_channels") is not None:    # a skeleton: the source's channels
            c = info["skeleton"]["channels"]
            parts.append(f"{c} channels {human_size(4 * info['frames'] * c)} as float32 "
                         f"\u2192 file {human_size(info['size'])}, "
                         f"{ratio_text(info['ratio_channels'])}:1 (the joint positions "
                         f"{human_size(info['raw_size'])}: {ratio_text(info['ratio'])}:1)")
        else:
            parts.append(f"markers {human_size(info['raw_size'])} as float32 \u2192 file "
                         f"{human_size(info['size'])}, {ratio_text(info['ratio'])}:1")
        b = info.get("bytes_by_part") or {}
        if b.get("analog") or b.get("skeleton") or b.get("rest", 0) > 200:
            more = [f"parts: markers {human_size(b['markers'])}"
                    + (f" ({ratio_text(info['ratio_markers'])}:1)" if info["ratio_markers"]
                       else "")]
            for key, what in (("analog", "analog"), ("skeleton", "skeleton and channels"),
                              ("rest", "the rest")):
                if b.get(key):
                    more.append(f"{what} {human_size(b[key])}")
            parts.append(" + ".join(more))
    units = f" {info['units']}" if info["units"] else ""
    if info["error_bound"] is not None:
        parts.append(f"max error \u2264 {bound_text(info['error_bound'])}{units}")
    else:
        parts.append("no error bound declared")
    sk = info.get("skeleton")
    if sk:
        joints = (f"joints within {bound_text(sk['position_bound'], 3)}{units}"
                  if sk["position_bound"] else "no joint bound declared")
        from mpz.skeleton import joints_text
        parts.append(f"{sk['chunk']} skeleton of "
                     f"{joints_text(sk['joints'], sk.get('end_sites', 0))}, {sk['channels']} "
                     f"channels within {bound_text(sk['angle_bound'], 3)} deg and "
                     f"{bound_text(sk['translation_bound'], 3)}, {joints}")
    line = f"{tag}: {name} ({', '.join(parts)})"
    if info["errors"]:
        e = info["errors"][0]
        line += f"\n  error: {printable(e['message'])}{_where(e)}"
    elif info["warnings"]:                     # a WARN says why, as an ERROR does
        w = info["warnings"][0]
        n_more = len(info["warnings"]) - 1
        line += (f"\n  warning: {printable(w['message'])}{_where(w)}"
                 + (f" (and {n_more} more; -v lists them)" if n_more else ""))
    return line


def _at_file(v: Any, base: int) -> Any:
    """:meth:`mpz.chunks.base.Record.stored_fields` with each ``at`` a file offset."""
    if isinstance(v, dict):
        return {k: (x + base if k == "at" else _at_file(x, base)) for k, x in v.items()}
    if isinstance(v, list):
        return [_at_file(x, base) for x in v]
    return v


def _print_stored(c: dict, out) -> None:
    """``-vv``: each struct of a field the grammar adapts, as stored, at its offset (the
    decoded view alone hid MNAM's front coding and HIER's weight codes)."""
    for name, items in c.get("stored", {}).items():
        listed = isinstance(items, list)            # a string of asfs is one dict
        for i, item in enumerate(items if listed else [items]):
            if not isinstance(item, dict):
                continue
            parts = ", ".join(f"{k} = {_shown(x)}" for k, x in item.items() if k != "at")
            label = f"{name}[{i}]" if listed else name
            print(f"      0x{item['at']:05x}  {label}, as stored: {printable(parts)}",
                  file=out)


def _shown(value: object) -> str:
    """A field's value as JSON (:func:`json_text` on one line), its characters as they are
    (``-vv`` printed a name "H\u00fcfte_links" as JSON's escape: an animation studio's QA
    run of stop 75); the caller's :func:`printable` escapes what a terminal must not get."""
    return json_text(value, indent=None)


def _print_chunks(info: dict, verbose: int, out):
    for i, c in enumerate(info["chunks"]):
        crc = ("CRC ok" if c["crc_ok"] else
               f"CRC bad (computed 0x{c['crc_computed']:08x}, stored 0x{c['crc_stored']:08x})")
        kind = "critical" if c["critical"] else "ancillary"
        print(f"  chunk #{i} {printable(c['type'])} ({kind}) at offset 0x{c['offset']:05x}, "
              f"length {c['length']}, {crc}", file=out)
        if verbose >= 2 and c["fields"] is not None:
            if not c["crc_ok"]:
                print("      (CRC bad: the fields below are as read, unverified)", file=out)
            offs = c.get("field_offsets", {})
            for k, v in c["fields"].items():
                at = f"0x{offs[k]:05x}" if k in offs else "       "
                shown = jsonable(v)
                if isinstance(shown, list) and shown and all(isinstance(x, dict)
                                                             for x in shown):
                    # records (cprm's, cpnt's channels and models, asfs's bones ...): one line
                    # each, whole; cut at 100 characters, most fields of a record never
                    # showed (a QA audit of stop 49: cprm's type, dims and data)
                    print(f"      {at}  {k} = [{len(shown)} record"
                          f"{'s' * (len(shown) != 1)}]", file=out)
                    for j, x in enumerate(shown):
                        print(f"               {k}[{j}] = {printable(_shown(x))}", file=out)
                    continue
                text = _shown(v) if not isinstance(v, str) else repr(v)
                if len(text) > 100:
                    text = text[:97] + "..."
                print(f"      {at}  {k} = {printable(text)}", file=out)
            _print_stored(c, out)
    for w in info["warnings"]:
        print(f"  warning: {printable(w['message'])}", file=out)
    for e in info["errors"]:
        print(f"  error: {e['class']}: {printable(e['message'])}{_where(e)}", file=out)


def _read(name: str) -> bytes:
    """The bytes of one FILE argument: ``-`` is standard input, read with a bound."""
    from mpz.api import read_source
    if name == "-":
        from mpz.tools._common import read_stdin
        return read_stdin()[0]
    return read_source(name)[0]


def _blank(name: str, size: int | None) -> dict[str, Any]:
    """A file's entry before anything is known: every field of docs/mpzinfo.md."""
    return {"file": name, "size": size, "status": "ok", "version": None, "rate": None,
            "frames": None, "markers": None, "nodes": None, "patterns": None,
            "segments": None, "units": None, "error_metric": None, "error_bound": None,
            "raw_size": None, "ratio": None, "ratio_of": RATIO_OF, "ratio_channels": None,
            "bytes_by_part": None,
            "ratio_markers": None, "header_crc_ok": None, "summary_levels": None,
            "skeleton": None, "chunks": [], "errors": [], "warnings": []}


def _unreadable(name: str, cls: str, message: str, section: str | None) -> dict:
    """The entry of a file that could not be read at all: every field, null or empty."""
    info = _blank(name, None)
    info["status"] = "error"
    info["errors"] = [{"class": cls, "message": message, "offset": None, "chunk": None,
                       "section": section}]
    return info


@quiet_broken_pipe
@reports_ctrl_c("mpzinfo: interrupted")
def main(argv: list[str] | None = None) -> int:
    return _main(argv)


def _main(argv: list[str] | None = None) -> int:
    from mpz import __version__
    p = Parser(prog="mpzinfo", description="Dump and check MPZ files.", epilog=EXIT_CODES_HELP)
    p.add_argument("files", nargs="+", metavar="FILE", help="MPZ files; - reads standard input")
    p.add_argument("-v", "--verbose", action="count", default=0,
                   help="-v: one line per chunk; -vv: every field, a chunk's own fields "
                        "with their byte offset, a value of more than 100 characters cut "
                        "(--json has it whole), a list of records one line each")
    p.add_argument("--json", action="store_true", help=f"machine-readable output ({SCHEMA})")
    p.add_argument("--no-decode", action="store_true",
                   help="check structure only: skip decoding the marker layer (the 1.1 chunks' "
                        "payloads are still decoded: their rules need it)")
    p.add_argument("--max-samples", type=max_samples, default=MAX_SAMPLES, metavar="N",
                   help=MAX_SAMPLES_HELP)
    add_version(p)
    args = p.parse_args(argv)
    if args.files.count("-") > 1:       # the second read nothing: "bad signature b''"
        p.error("- (standard input) can be given once")
    infos = []
    for f in args.files:
        try:
            data = _read(f)
            infos.append(inspect(data, f, decode=not args.no_decode,
                                 max_samples=args.max_samples))
        except MPZError as exc:                # unreadable: missing, a device, too long
            infos.append(_unreadable(f, type(exc).__name__, exc.message, exc.section))
        except MemoryError as exc:             # a resource error, not a verdict (spec §8)
            info = _unreadable(f, "MemoryError", memory_message(exc, "mpzinfo"), "§8")
            info["status"] = "memory"
            infos.append(info)
    statuses = {i["status"] for i in infos}
    code = found(EXIT_MEMORY if "memory" in statuses else EXIT_ERROR if "error" in statuses
                 else EXIT_WARN if "warning" in statuses else EXIT_OK)
    if args.json:
        # the source fingerprint of --version too: development checkouts share a version
        print_json({"schema": SCHEMA, "tool_version": __version__,
                    "tool_source": source_fingerprint(), "files": infos})
    else:
        for info in infos:
            print(summary_line(info))
            if args.verbose:
                _print_chunks(info, args.verbose, sys.stdout)
    return code


if __name__ == "__main__":
    sys.exit(main())
