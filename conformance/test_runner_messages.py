"""What the runner's messages say, as an outside implementer reads them (a QA report of
stop 71, revB): the rule of the check that failed, the hint a 1.0 decoder needs, JSON terms
for the sidecar, the code points of strings that print alike, and so on.

The fake decoders are small scripts that import numpy alone: most copy a vector's expected
output and sidecar (the manifest's) and then break one thing, so a run takes a fraction of
a second where the reference decoder takes one or two.
"""
from __future__ import annotations

import json
from pathlib import Path
import subprocess
import sys
import textwrap

import pytest

from mpz.conformance import manifest as mf

PY = sys.executable
MAN = mf.load()
VEC = {v["name"]: v for v in MAN["vectors"]}
ONE = "v04-orders-residual-only"        # a decodable vector that probes neither R-6.8-x
BAD = "x01-bad-signature"


def script(path: Path, text: str) -> Path:
    path.write_text(text)
    path.chmod(0o755)
    return path


def copier(tmp_path: Path, name: str, body: str = "", *, sidecar: bool = True,
           file: str = "dec.py") -> Path:
    """A decoder that writes vector ``name``'s expected output (``x``) and sidecar (``side``),
    after ``body`` has changed them (IN, OUT, x, side, np, json, sys are bound)."""
    v = VEC[name]
    h = v["header"]
    side = {"names": h["names"], "rate": h["rate"], "units": h["units_code"], "meta": h["meta"]}
    exp = mf.DEFAULT_DIR / v["expected_output"]["file"]
    return script(tmp_path / file, f"#!{PY}\n" + textwrap.dedent(f'''\
        import json, sys
        import numpy as np
        IN, OUT = sys.argv[-2], sys.argv[-1]
        x = np.load({str(exp)!r})
        side = json.loads({json.dumps(side)!r})
        ''') + textwrap.dedent(body) + textwrap.dedent(f'''
        np.save(OUT, x)
        if {sidecar!r} and side is not None:
            with open(OUT + ".json", "w", encoding="utf-8") as fh:
                json.dump(side, fh)
        '''))


def python_script(path: Path, body: str) -> Path:
    return script(path, f"#!{PY}\nimport sys\n{textwrap.dedent(body)}")


def run(tmp_path: Path, *args: str) -> tuple[subprocess.CompletedProcess, dict]:
    out = tmp_path / "results.json"
    proc = subprocess.run([PY, "-m", "mpz.conformance.runner", *args, "--results", str(out)],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert out.exists(), proc.stdout + proc.stderr
    return proc, json.loads(out.read_text())


def one(tmp_path: Path, dec: Path, name: str = ONE, *extra: str) -> dict:
    _, doc = run(tmp_path, "--decoder", str(dec), "--only", name, *extra)
    return doc["results"][0]


# ------------------------------------------------ finding 2: the rule of the check --
@pytest.mark.parametrize("body, lead", [
    ('side["names"] = side["names"][::-1]', "R-6.8-2 (§6.8, §7.3): sidecar names[0] = "),
    ('x[0, 0, 0] += 1.0', "R-6.8-1 (§7.1 item 3): 1 coordinate(s) beyond max_abs"),
    ('x[0, 0, 0] = np.nan', "R-6.8-1 (§7.1 item 3): NaN pattern differs"),
    ('x = x.astype(np.float32)', "§7.3: output dtype float32 != float64"),
    ('open(OUT + ".intlayer", "w").write("0" * 64)', "§7.1 item 2: integer-layer digest '000"),
])
def test_a_failure_leads_with_the_rule_of_its_check(tmp_path, body, lead):
    """v04 probes R-5.2-1 .. R-6.8-1 and not R-6.8-2: a wrong name cited them alone."""
    r = one(tmp_path, copier(tmp_path, ONE, body))
    assert not r["passed"] and r["message"].startswith(lead), r["message"]
    assert r["message"].endswith(f"; vector probes: {', '.join(VEC[ONE]['rules'])} "
                                 "(spec §7.4)"), r["message"]
