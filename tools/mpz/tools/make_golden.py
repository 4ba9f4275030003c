"""Freeze the golden regression files: ``python -m mpz.tools.make_golden``.

For every conformance vector it records the ``mpzinfo --json`` report (the
tool version and file paths masked, since they vary between builds and
machines) and, for decodable vectors, the SHA-256 of the decoded float64
output and of the integer layer (spec §7.1), and of the channel values of a
skeletal file (§6.10). conformance/test_golden.py
fails when a codec change alters any of them.

Regenerating is an explicit decision: this command prints a golden id, and
the test requires CHANGELOG.md to mention it, so the changelog must say why
the golden output changed.
"""
from __future__ import annotations

import argparse
import hashlib
import json
from pathlib import Path
import sys

import numpy as np

# tools/mpz/tools/make_golden.py -> the repository root is three folders up
GOLDEN_DIR = Path(__file__).resolve().parents[3] / "conformance" / "golden"
GOLDEN_FILE = "golden.json"


def compute(vectors_dir=None) -> dict:
    import mpz
    from mpz.conformance import manifest as mf
    from mpz.decoder import decode_layers
    from mpz.errors import MPZError
    from mpz.tools.mpzinfo import inspect
    man = mf.load(vectors_dir)
    root = Path(vectors_dir) if vectors_dir else mf.DEFAULT_DIR
    out = {}
    for v in man["vectors"]:
        data = (root / v["file"]).read_bytes()
        info = inspect(data, v["name"])
        entry: dict[str, object] = {"mpzinfo": info, "decoded_sha256": None,
                                    "integer_layer_digest": None, "error_class": None}
        try:
            m = mpz.decode(data)
            entry["decoded_sha256"] = hashlib.sha256(
                np.ascontiguousarray(m.as_nan(), "<f8").tobytes()).hexdigest()
            if m.angles is not None:   # issue 13: the skeleton's channel values (spec §6.10)
                entry["channels_sha256"] = hashlib.sha256(
                    np.ascontiguousarray(m.angles, "<f8").tobytes()).hexdigest()
            d = decode_layers(data)
            entry["integer_layer_digest"] = mf.intlayer_digest(d.q, d.valid)
        except MPZError as exc:
            entry["error_class"] = type(exc).__name__
        out[v["name"]] = entry
    body = json.dumps(out, sort_keys=True)
    golden_id = hashlib.sha256(body.encode()).hexdigest()[:12]
    return {"schema": 1, "golden_id": golden_id, "masked": ["tool_version", "file paths"],
            "vectors": out}


#: the parts of a vector's golden entry that are its decoded result (the rest, ``mpzinfo``,
#: is the report)
DECODED_PARTS = ("decoded_sha256", "integer_layer_digest", "error_class", "channels_sha256")


#: how :func:`describe_changes` names each of :data:`DECODED_PARTS`
PART_NAMES = {"decoded_sha256": "the output", "integer_layer_digest": "the integer layer",
              "error_class": "the verdict", "channels_sha256": "the skeleton channels"}


def describe_changes(old: dict, new: dict) -> list[str]:
    """Lines that say which vectors' golden entries changed, the decoded result (a decoder's
    output or its verdict) apart from the mpzinfo report alone (a QA run of stop 48: 120
    vectors "changed", of which 17 decoded otherwise and 103 only reported otherwise)."""
    names = sorted(set(old.get("vectors", {})) | set(new["vectors"]))
    decoded, report, added, removed = [], [], [], []
    for name in names:
        a, b = old.get("vectors", {}).get(name), new["vectors"].get(name)
        if a == b:
            continue
        # a vector added or removed was told as one that "decodes otherwise", which sent a
        # maintainer after a decoder change (a QA run of stop 53: u47's addition)
        if a is None:
            added.append(name)
        elif b is None:
            removed.append(name)
        elif any(a.get(k) != b.get(k) for k in DECODED_PARTS):
            decoded.append(name)
        else:
            report.append(name)
    out = []
    if added:
        out.append(f"{len(added)} vector(s) added, e.g. {', '.join(added[:5])}")
    if removed:
        out.append(f"{len(removed)} vector(s) removed, e.g. {', '.join(removed[:5])}")
    if decoded:
        # which part moved: "output, integer layer, skeleton channels or verdict" left a
        # maintainer to find out that only the float conversion had changed (a QA run of
        # stop 55); the integer layer the same says the change is past it (§6.8)
        moved = {k: sum(old["vectors"][n].get(k) != new["vectors"][n].get(k) for n in decoded)
                 for k in DECODED_PARTS}
        what = "; ".join(f"{PART_NAMES[k]} of {moved[k]}" for k in DECODED_PARTS if moved[k])
        after = ("; the integer layer is the same in each: the change is past it, in the "
                 "conversion to binary64 (spec §6.8) or later"
                 if moved["decoded_sha256"] and not moved["integer_layer_digest"]
                 and not moved["error_class"] else "")
        out.append(f"{len(decoded)} vector(s) decode otherwise ({what}{after}), e.g. "
                   f"{', '.join(decoded[:5])}")
    # a verdict that flips is named with its direction: "the verdict of 1" with the advice
    # "if intended, run make_golden" sent a decoder that accepted x46 (a spec check dropped)
    # towards regeneration (a QA run of regression checks)
    flips = [n for n in decoded
             if old["vectors"][n].get("error_class") != new["vectors"][n].get("error_class")]
    if flips:
        def verdict(entry: dict) -> str:
            return f"rejected ({entry['error_class']})" if entry.get("error_class") else "decoded"
        said = ", ".join(f"{n}: {verdict(old['vectors'][n])} -> {verdict(new['vectors'][n])}"
                         for n in flips[:5])
        accepts = sum(not new["vectors"][n].get("error_class") for n in flips)
        out.append(f"{len(flips)} vector(s) change verdict: {said}"
                   + (f"; {accepts} now decode(s) what was rejected: where the manifest "
                      f"says reject, that is a decoder bug (test_manifest.py checks each "
                      f"vector's expected outcome), not a golden change" if accepts else ""))
    if report:
        out.append(f"{len(report)} vector(s) only report otherwise (mpzinfo --json), e.g. "
                   f"{', '.join(report[:5])}")
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m mpz.tools.make_golden", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default=str(GOLDEN_DIR),
                   help="folder to write golden.json into (default: conformance/golden; "
                        "another folder to see what changed without touching it)")
    args = p.parse_args(argv)
    out = Path(args.out)
    from mpz.tools._common import is_clone
    if out.resolve() == GOLDEN_DIR.resolve() and not is_clone(GOLDEN_DIR.resolve().parents[1]):
        # installed from a wheel, the default was a folder beside site-packages that
        # uninstall left behind (a release QA run, stop 74)
        print(f"make_golden: error: {GOLDEN_DIR} is not in a clone of the repository "
              "(this mpz is installed): run this in a clone, or give --out", file=sys.stderr)
        return 64
    if out.exists() and not out.is_dir():        # found after the 5 s of computing (QA)
        print(f"make_golden: error: --out {out}: not a folder (golden.json is written into "
              "it)", file=sys.stderr)
        return 64
    doc = compute()
    # compared with the shipped file wherever it is written: "--out /tmp/golden, see what
    # changed first" compared with the empty /tmp/golden (a QA run of stop 50: "was None")
    shipped = GOLDEN_DIR / GOLDEN_FILE
    old_id = None
    if shipped.exists():
        old = json.loads(shipped.read_text())
        old_id = old.get("golden_id")
        for line in describe_changes(old, doc):
            print(f"{line} (against {shipped})")
    out.mkdir(parents=True, exist_ok=True)
    (out / GOLDEN_FILE).write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    print(f"wrote {out / GOLDEN_FILE}: {len(doc['vectors'])} vectors, golden id {doc['golden_id']}")
    if doc["golden_id"] == old_id:
        print("the golden id is unchanged: nothing for CHANGELOG.md")
    elif out.resolve() != GOLDEN_DIR.resolve():
        print(f"the golden id would change from {old_id} to {doc['golden_id']}; "
              f"{GOLDEN_DIR} is untouched (run without --out to write it)")
    else:
        print(f"add a CHANGELOG.md entry that names golden id {doc['golden_id']} "
              f"(was {old_id}) and says why")
    return 0


if __name__ == "__main__":
    sys.exit(main())
