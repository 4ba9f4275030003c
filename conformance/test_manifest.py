"""The conformance manifest agrees with the vectors, the reference and the spec.

Nothing here regenerates vectors (``python -m mpz.tools.make_vectors`` does).
"""
from __future__ import annotations

import json
from pathlib import Path
import re

import numpy as np
import pytest

import mpz
from mpz.chunks import CHUNKS
from mpz.conformance import manifest as mf
from mpz.container import scan
from mpz.decoder import decode_layers, read_stream

VDIR = mf.DEFAULT_DIR
MAN = mf.load(VDIR)
DECODABLE = [v for v in MAN["vectors"] if v["expected"] == "decode"]
INVALID = [v for v in MAN["vectors"] if v["expected"] == "reject"]
SPEC = Path(__file__).resolve().parents[1] / "spec" / "mpz-1.md"


def _ids(vs):
    return [v["name"] for v in vs]


def test_manifest_structure():
    assert MAN["schema_version"] == mf.SCHEMA_VERSION == 2
    assert {v["group"] for v in MAN["vectors"]} == set(mf.GROUPS)
    assert len(INVALID) >= 30 and len(DECODABLE) >= 15


def test_hashes_match_files():
    assert mf.check_hashes(MAN, VDIR) == []


def test_no_stray_files():
    listed = {v["file"] for v in MAN["vectors"]}
    listed |= {v["expected_output"]["file"] for v in DECODABLE}
    listed |= {e[k] for e in MAN["encoder_inputs"] for k in ("input", "sidecar")}
    listed |= {mf.MANIFEST_NAME, mf.SPEC_EXAMPLE, "__init__.py"}   # the data-package marker
    present = {str(p.relative_to(VDIR)) for p in VDIR.rglob("*")
               if p.is_file() and "__pycache__" not in p.parts}
    assert present - listed == set()


def test_suite_is_small():
    """The suite stays small enough to ship in the wheel and clone in seconds. 3 MiB held
    81 to 403 vectors; stop 71's reviews needed more (a vector per rule that no vector
    showed), so the limit is 4 MiB, about 30 % above what the 408 vectors of stop 71 took
    (the 436 of stop 73 take 3.30 MB)."""
    assert sum(p.stat().st_size for p in VDIR.rglob("*") if p.is_file()) < 4 * 2 ** 20


@pytest.mark.parametrize("vec", DECODABLE, ids=_ids(DECODABLE))
def test_tolerances_follow_spec_7_1(vec):
    tol = vec["tolerances"]
    assert tol["rms"] <= tol["max_abs"]
    exp = np.load(VDIR / vec["expected_output"]["file"])
    ok = ~np.isnan(exp)
    assert tol == mf.tolerances(vec["header"]["step"], float(np.abs(exp[ok]).max(initial=0.0)))
    # one grid step must be far outside the tolerance, or the float tier proves nothing
    assert tol["max_abs"] < vec["header"]["step"] / 1000


@pytest.mark.parametrize("vec", DECODABLE, ids=_ids(DECODABLE))
def test_decodable_vector_matches_reference(vec):
    data = (VDIR / vec["file"]).read_bytes()
    d = decode_layers(data)
    s, q, valid, x = d.stream, d.q, d.valid, d.positions()
    exp = np.load(VDIR / vec["expected_output"]["file"], allow_pickle=False)
    assert exp.dtype == np.dtype("<f8") and exp.shape == x.shape
    assert x.tobytes() == exp.tobytes()             # bit-exact, NaN at the same places
    assert mf.intlayer_digest(q, valid) == vec["integer_layer_digest"]
    m = mpz.decode(data)
    h = vec["header"]
    assert (h["frames"], h["markers"]) == (m.n_frames, m.n_markers)
    assert h["names"] == m.names and h["rate"] == m.rate and h["units"] == m.units
    assert h["error_bound"] == s.header.error_bound and h["step"] == s.quant.step
    assert np.array_equal(np.isnan(m.as_nan()), np.isnan(exp))


@pytest.mark.parametrize("vec", INVALID, ids=_ids(INVALID))
def test_invalid_vector_is_rejected_with_named_error(vec):
    data = (VDIR / vec["file"]).read_bytes()
    with pytest.raises(mpz.MPZError) as info:
        mpz.decode(data)
    assert type(info.value).__name__ == vec["expected_error"], str(info.value)
    assert vec["corruption"] and vec["risk"]


def test_every_chunk_type_is_decoded_somewhere():
    seen = set()
    for v in DECODABLE:
        seen |= {c.type for c in scan((VDIR / v["file"]).read_bytes()).chunks}
    missing = set(CHUNKS) - seen
    assert not missing, f"no valid/uncommon vector contains {sorted(missing)}"


def test_every_decoding_step_of_the_spec_is_exercised():
    if not SPEC.is_file():
        pytest.skip("spec/mpz-1.md missing")
    steps = mf.spec_decoding_steps(SPEC.read_text(encoding="utf-8"))
    exercised = set()
    for v in DECODABLE:
        exercised |= set(mf.exercised_sections(read_stream((VDIR / v["file"]).read_bytes())))
    missing = [f"step {n} {sec} ({name})" for n, sec, name in steps if sec not in exercised]
    assert not missing, "no vector exercises " + ", ".join(missing)


def test_every_digest_in_the_manifest_is_defined_by_the_spec():
    """Spec §7.3 defines each digest the manifest gives an implementer to check a layer
    with (`*_sha256` in `features`) and its `*_digest_rule`; `summary_sha256` was defined
    in conformance/README.md alone (a clean-room review of stop 54), and so is `rules`."""
    if not SPEC.is_file():
        pytest.skip("spec/mpz-1.md missing")
    text = SPEC.read_text(encoding="utf-8")
    section = text[text.index("### 7.3."):text.index("### 7.4.")]
    keys = {"rules"}
    for v in MAN["vectors"]:
        features = v.get("features", {})
        for part in (features, *(x for x in features.values() if isinstance(x, dict))):
            keys |= {k for k in part if k.endswith(("_sha256", "_digest_rule"))}
    assert {"summary_sha256", "c3d_file_sha256", "channels_sha256"} <= keys
    missing = sorted(k for k in keys if f"`{k}`" not in section)
    assert not missing, f"spec §7.3 does not define {missing}"


def test_declared_sections_include_exercised_ones():
    for v in DECODABLE:
        got = set(mf.exercised_sections(read_stream((VDIR / v["file"]).read_bytes())))
        assert got <= set(v["spec_sections"]), v["name"]


def test_field_values_that_change_decoding_are_all_covered():
    orders = {"ROOT": set(), "PATT": set(), "RESI": set()}
    base, g, pscale, smoothing, units = set(), set(), set(), set(), set()
    residual = set()
    for v in DECODABLE:
        s = read_stream((VDIR / v["file"]).read_bytes())
        orders["ROOT"].add(s.root.record.order)
        orders["PATT"] |= {c.record.order for c in s.patt.values() if c.record.pattern_count}
        orders["RESI"] |= {c.record.order for c in s.resi.values()}
        base |= {c.record.base for c in s.resi.values()}
        g |= {c.record.scale for c in s.resi.values()}
        pscale |= {c.record.scale for c in s.patt.values() if c.record.pattern_count}
        smoothing.add(s.header.smoothing)
        units.add(s.header.units)
        residual.add(s.residual)
    assert all(o == {0, 1, 2} for o in orders.values()), orders
    assert {0, 1} <= base and max(g) > 1 and max(pscale) > 1
    assert 0 in smoothing and 16 in smoothing and len(smoothing) > 2
    assert units == {0, 1, 2, 3, 4} and residual == {True, False}


def test_spec_step_table_parser():
    text = ("x\n<!-- mpz:decoding-steps -->\n| Step | Section | Name | Rule |\n|---|---|---|---|\n"
            "| 1 | §3.1 | signature | s |\n| 2 | §6.4 | smoothing | a \\| b |\n"
            "<!-- /mpz:decoding-steps -->\n")
    assert mf.spec_decoding_steps(text) == [(1, "§3.1", "signature"), (2, "§6.4", "smoothing")]
    with pytest.raises(mf.ManifestError):
        mf.spec_decoding_steps("no table")


def test_validate_catches_rms_above_max_abs():
    import copy
    bad = copy.deepcopy(MAN)
    bad["vectors"][0]["tolerances"] = {"max_abs": 1e-9, "rms": 1e-8}
    with pytest.raises(mf.ManifestError, match="rms"):
        mf.validate(bad)


def _decode_vector(man):
    return next(v for v in man["vectors"] if v["expected"] == "decode")


def _reject_vector(man):
    return next(v for v in man["vectors"] if v["expected"] == "reject")


@pytest.mark.parametrize("edit, said", [
    (lambda m: _reject_vector(m).__setitem__("file", "invalid/../../../etc/passwd"),
     "is not a path inside the suite's folder"),
    (lambda m: _decode_vector(m)["expected_output"].__setitem__("file", "/etc/passwd"),
     "expected_output file: '/etc/passwd' is not a path inside"),
    (lambda m: _reject_vector(m).__setitem__("file", 5), "file: 5 is not a path"),
    (lambda m: _reject_vector(m).__setitem__("group", ["invalid"]), "unknown group"),
    (lambda m: _reject_vector(m).__setitem__("sha256", 5), "is not 64 lower-case hex"),
    (lambda m: _decode_vector(m).__setitem__("tolerances", [1, 2]),
     "tolerances is not an object"),
    (lambda m: _decode_vector(m).__setitem__("header", 7), "header is not an object"),
    (lambda m: _decode_vector(m).__setitem__("expected_output", "x.npy"), "not an object"),
    (lambda m: _decode_vector(m).__setitem__("features", [1]), "features an object"),
    (lambda m: _reject_vector(m).__setitem__("expected_error", 5), "expected_error is not"),
    (lambda m: m.__setitem__("encoder_inputs", 5), "encoder_inputs is not a list"),
    (lambda m: m.__setitem__("encoder_inputs", [5]), "an encoder input is not an object"),
    (lambda m: m["encoder_inputs"][0].__setitem__("sidecar", "../x.json"),
     "sidecar: '../x.json' is not a path inside"),
    (lambda m: m["encoder_inputs"][0].__setitem__("max_errors", ["1"]), "max_errors"),
    # it said "sidecar: sha256 None is not 64 lower-case hex digits" (a docs QA run, stop 74)
    (lambda m: m["encoder_inputs"][0].pop("sidecar_sha256"), "missing 'sidecar_sha256'"),
])
def test_a_field_of_another_type_or_a_path_outside_the_suite_is_a_manifest_error(edit, said):
    """A security QA run (stop 73): a manifest whose fields had another JSON type made the
    runner fail with a traceback (exit 70), and a vector's "file" of invalid/../../.. or an
    absolute expected_output was read from outside the suite's folder. validate() checks
    every field the runner reads; the runner turns its error into exit 64."""
    import copy
    bad = copy.deepcopy(MAN)
    edit(bad)
    with pytest.raises(mf.ManifestError, match=re.escape(said)):
        mf.validate(bad)
    mf.validate(copy.deepcopy(MAN))                      # the shipped one passes


def test_readme_counts_the_vectors_there_are():
    """The README's count for decoder authors is the manifest's, group by group (it said
    81 from 1.0 until 1.1 had 332)."""
    readme = (SPEC.parents[1] / "README.md").read_text()
    groups = {g: sum(v["group"] == g for v in MAN["vectors"])
              for g in ("valid", "uncommon", "invalid")}
    said = (f"the {len(MAN['vectors'])} vectors ({groups['valid']} valid, with the Appendix A "
            f"example, {groups['uncommon']} uncommon and {groups['invalid']} invalid;")
    assert said in " ".join(readme.split())


def _last_bits_only(made: Path, files: list[str]) -> list[float]:
    """The largest relative difference of each of ``files`` (NPY, in ``made`` and in the
    frozen set) when every one has the frozen shape, gaps and values to 1e-12; else []."""
    worst = []
    for f in files:
        a, b = np.load(made / f), np.load(VDIR / f)
        if a.shape != b.shape or not np.array_equal(np.isnan(a), np.isnan(b)):
            return []
        ok = ~np.isnan(a)
        rel = np.abs(a[ok] - b[ok]) / np.maximum(np.abs(b[ok]), 1e-300)
        if rel.size and rel.max() > 1e-12:
            return []
        worst.append(float(rel.max(initial=0.0)))
    return worst


def test_make_vectors_reproduces_every_frozen_vector(tmp_path):
    """The generator, run into a temporary folder, writes every frozen vector byte for byte
    (about 4 s: the manifest's slow part, its digests, is not rebuilt here). An encoder
    change that moves an encoder-made vector now fails here, at the commit that makes it,
    rather than surfacing at the next regeneration mixed with other changes: stop 22's
    forward-kinematics kernel moved the skeleton vectors by a few ulps and a later change
    made make_vectors crash on them, and neither was seen until stop 27 ran it. Vectors are
    still changed only by `python -m mpz.tools.make_vectors`, with a CHANGELOG entry."""
    from mpz.tools import make_vectors as mv
    vs = mv.VectorSet(tmp_path)
    for build in mv.BUILDERS:
        if build is not mv.spec_example:     # Appendix A's file is hand-made and frozen
            build(vs)
    made = {str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file()}
    frozen = {v["file"] for v in MAN["vectors"]} - {mf.SPEC_EXAMPLE}
    assert frozen <= made
    differ = sorted(f for f in made if (tmp_path / f).read_bytes() != (VDIR / f).read_bytes())
    last_bits = _last_bits_only(tmp_path, [f for f in differ if f.endswith(".npy")])
    assert not last_bits, (
        f"the synthetic inputs differ from the frozen ones in their last bits only (at most "
        f"{max(last_bits):.3g} relative, numpy {np.__version__} here): numpy's sin and cos "
        "give other last bits than where the vectors were made (numpy 2.4.6 makes them), and "
        "every vector made from them moves. Not a codec change: do not regenerate the "
        "vectors for it; conformance/test_encoder_pinned.py still pins the encoder")
    assert not differ, (f"{len(differ)} vector files differ from what make_vectors writes, "
                        f"e.g. {differ[:4]}: if the change is intended, run python -m "
                        "mpz.tools.make_vectors and python -m mpz.tools.make_golden, and say "
                        "why in CHANGELOG.md")


def test_the_readme_vector_table_is_the_manifest():
    """conformance/README.md's table of the vectors is written by make_vectors from the
    manifest (it had 210 of 334 rows and stale sizes)."""
    from mpz.tools.make_vectors import TABLE_BEGIN, TABLE_END, vector_table
    text = (Path(__file__).parent / "README.md").read_text(encoding="utf-8")
    table = text[text.index(TABLE_BEGIN) + len(TABLE_BEGIN): text.index(TABLE_END)].strip()
    entries = json.loads((Path(__file__).parent / "vectors" / "manifest.json").read_text())
    assert table == vector_table(entries["vectors"])
    assert table.count("\n") - 1 == len(entries["vectors"])


def _stored_means(path):
    """The integer means q [k, D] of each level as the file stores them (smry) or codes
    them (smrc, §4.15 steps 1-5), for the levels whose means overflow to ±∞ in units."""
    from mpz.decoder import read_stream
    s = read_stream(path.read_bytes())
    rec = s.summary.record
    if rec.TYPE == "smry":
        return [np.frombuffer(lv.means, "<i4").reshape(lv.k, rec.dims) for lv in rec.levels]
    return [q for _, q in rec.levels_decoded(s.header.frame_count)]


def test_summary_digests_match_the_public_api():
    """A review of stop 49: an implementer could not check decoded summary values without
    the reference. ``features.summary_sha256`` is recomputed here from ``mpz.read_summary``
    (means in units, divided back by the step) by the rule the manifest states; every
    decodable vector with a summary chunk has one."""
    import hashlib
    with_summary = [v for v in DECODABLE
                    if {"smry", "smrc"} & set(v["features"].get("chunks", []))]
    assert len(with_summary) >= 10
    for v in with_summary:
        feats = v["features"]
        assert "int64 little-endian" in feats["summary_digest_rule"]
        summary = mpz.read_summary(VDIR / v["file"])
        h = hashlib.sha256()
        for i, lv in enumerate(summary.levels):
            means = np.asarray(lv.means, np.float64)
            finite = np.isfinite(means)
            q = np.rint(np.where(finite, means, 0.0) / lv.step)
            assert np.array_equal(q[finite] * lv.step, means[finite]), v["name"]  # §4.10
            if not finite.all():        # ±∞ at a finite step (R-4.10-2, R-4.15-7): the
                stored = _stored_means(VDIR / v["file"])[i]     # integer is the stored one
                assert np.array_equal(np.sign(stored[~finite]), np.sign(means[~finite]))
                assert np.all(np.abs(stored[~finite].astype(float) * lv.step) > 1.7e308)
                q[~finite] = stored[~finite]
            h.update(np.asarray(lv.starts, "<i8").tobytes())
            h.update(np.ascontiguousarray(q.astype("<i8")).tobytes())
        assert h.hexdigest() == feats["summary_sha256"], v["name"]
    assert not [v["name"] for v in MAN["vectors"] if "summary_sha256" in v["features"]
                and v not in with_summary]


def test_c3d_archive_digests_match_the_public_api():
    """A mutation run: a decoder that rounded the model-output values to float32 (or lost a
    word's bits) passed every test, because nothing compared a decoded archive with the
    manifest. ``features.c3d_archive_sha256`` is recomputed here from ``mpz.decode(path)
    .extras["c3d"]`` by the rule the manifest states beside it (spec §7.3): the words [F, P]
    and the analog words [F n, C] as stored (int16 or float32, little-endian), then the
    model values [F, J, 3] as float64 little-endian with the quiet NaN at gaps."""
    import hashlib
    with_archive = [v for v in DECODABLE if "c3d_archive_sha256" in v["features"]]
    assert len(with_archive) >= 4
    for v in with_archive:
        feats = v["features"]
        rule = feats["c3d_archive_digest_rule"]
        assert "words [F, P]" in rule and "analog words [F n, C]" in rule, v["name"]
        assert "model values [F, J, 3]" in rule and "float64 LE, NaN at gaps" in rule, v["name"]
        a = mpz.decode(VDIR / v["file"]).extras["c3d"]
        F, J = a.models.shape[0], a.models.shape[1]
        assert feats["c3d_points"] == a.words.shape[1] == len(a.slots), v["name"]
        assert feats["c3d_model_outputs"] == J and a.words.shape[0] == F, v["name"]
        assert feats["c3d_analog_channels"] == a.channels, v["name"]
        h = hashlib.sha256()
        for x, storage in ((a.words, a.word_storage), (a.analog, a.analog_storage)):
            want = np.dtype("<i2") if storage == 0 else np.dtype("<f4")
            assert x.size == 0 or x.dtype == want, (v["name"], x.dtype, storage)
            h.update(np.ascontiguousarray(x, want).tobytes())
        models = np.array(a.models, dtype="<f8")
        gaps = ~np.asarray(a.model_valid, bool)
        assert np.isnan(models[gaps]).all() and np.isfinite(models[~gaps]).all(), v["name"]
        models[gaps] = np.nan                     # the quiet NaN 0x7FF8000000000000
        assert (models.view("<u8")[gaps] == 0x7FF8000000000000).all()
        h.update(np.ascontiguousarray(models).tobytes())
        assert h.hexdigest() == feats["c3d_archive_sha256"], v["name"]


#: The SHA-256 of the C3D file that an independent writer, written from spec §6.9 alone
#: (a clean-room review of stop 53, its own decoder and range coder, no mpz code), made of
#: each C3D vector: expected values that do not come from the code under test.
INDEPENDENT_C3D_FILES = {
    "v10-c3d-archive-float32":
        "5be0e0c61151b3ac9427885bfa06a468ef9f9376e0aae02984d6392372408b23",
    "u32-c3d-int16-exact-on-grid":
        "fc91a2b9e4b25531519c2aa4ca9b158587faec0dbd8a23ec3a1b556339eb14f8",
    "u33-c3d-no-analog-no-models":
        "f4a2d3ed0cb279627823fa17c230e02d333b6da26493fe49e2293aa5ee7f0ac6",
    "u41-c3d-stored-header-and-parameters":
        "bffde36e04e54338abc769fd00019ed14db7d526a3ac08b50f6e0ecfe72f0d65",
    "u42-c3d-header-counts-stale":
        "c2e3d84bed9eb2d559a5bc33aea3b8611b4c026e6f896d7546bfd232ac1be0eb",
    "u46-c3d-analog-shift-minus-128":
        "6f6b2b9eb8497165a8a7360094c51a69436ca2e010d028af6ce52dcc9b6ea6f8",
    # u41's header and parameters, deflated otherwise (test_deflate_streams.py checks that
    # each inflates to u41's content): the independent writer's file of u41
    "u48-cprm-deflate-padding-ones":
        "bffde36e04e54338abc769fd00019ed14db7d526a3ac08b50f6e0ecfe72f0d65",
    "u49-chdr-deflate-one-distance-code":
        "bffde36e04e54338abc769fd00019ed14db7d526a3ac08b50f6e0ecfe72f0d65",
    "u50-cprm-deflate-no-distance-codes":
        "bffde36e04e54338abc769fd00019ed14db7d526a3ac08b50f6e0ecfe72f0d65",
}

#: The same for the C3D vectors added after that review (stop 70): the reference's digests,
#: pinned so that a change shows, until an independent writer makes these files too.
REFERENCE_C3D_FILES = {
    "u51-cprm-dims-255-255-0":
        "cfc2bc60fe6cce13f8be11c3884d9211626ab9a7802cc7a73d3d501695ef28cd",
    "u52-cprm-group-128-non-ascii":
        "170d2680e4393a507242087903dd2465db3628fc228858604758032e79d1dfb4",
    "u53-c3d-cana-float32-cpnt-int16":
        "f2e47e4dd71ead926adba3987328367119a3daed419a7b9301d54dfc9806378d",
}

#: The C3D vectors of make_vectors.c3d_writer_vectors (stop 72), one per branch of §6.9's
#: writer that no vector reached: digests that test_c3d_writer_vectors.py's writer, written
#: from §6.9 alone (struct and numpy, no mpz C3D code), makes too; None where §6.9's writer
#: refuses the archive (``c3d_file_refused`` says which refusal).
SPEC_WRITER_C3D_FILES = {
    "u67-c3d-parameter-section-of-2-blocks":
        "15a774cb1a2230ee8f5914d00dd6e306bd45b552b75834fdcdee4a24f8c1327b",
    "u68-c3d-no-point-scale":
        "22ce203e39bca2b0e60006c483f70ab3e325f05cfe35ba92070c4a6da47a7e5b",
    "u69-c3d-point-scale-int16-then-float32":
        "53a431394290808db1dd4f33f11e50de304168392f8626b4c10fef79a5b51f19",
    "u70-c3d-point-scale-no-element":
        "5fd81423d9b7ccfe030397ea09251bc8c39d7ef46390c118f8214518d6961083",
    "u71-c3d-point-scale-zero":
        "f6c06970115d800a4f912d306986e4ca88ad172e410d04d44945e0900dc37821",
    "u72-c3d-point-scale-minus-infinity":
        "f6c06970115d800a4f912d306986e4ca88ad172e410d04d44945e0900dc37821",
    "u73-c3d-point-scale-nan-element":
        "1063f62958b503f511099f1501475d575365e1392693e97f8c573e2aecde6de2",
    "u74-c3d-point-scale-magnitudes-differ":
        "42b088c494e6941f8599ee5681f63efb5b6ecf919dbb61c3f509e06f0c7faf7e",
    "u75-c3d-point-scale-signs-differ-int16":
        "e8721978a71d6385185c62df87ea13c3efc87c2ce808157a2b3a3bc9346c88d4",
    "u76-c3d-int16-off-grid-written-float32":
        "387f364d46a642c83d5394502787b7bd351614ea57f6d6e5a23b9d929545d2d0",
    "u77-c3d-int16-on-grid-beyond-32767":
        "e22479bd77452397d1c3b03830986f2bce47a672defb960f3a9583753095f1f4",
    "u78-c3d-analog-format-unsigned":
        "2db3f1df1acadc18f708b7dee7f7054c43e733ff11d7e75dfef8ee0123491525",
    "u79-c3d-analog-format-unsigned-not-first":
        "a927b649b8c5d7ccce6f877b33a333efff7ac6b2bc9c6b10dc20176232196f9c",
    "u80-c3d-last-frame-65535":
        "9809b39cdcafd64af1cf4e7a2d20e25424b6a5c260780363d24e9afc64ac7014",
    "u81-c3d-group-point-lowercase":
        "6fd1c453a02d249b2ca3f7474bc2325f27087951d30bf9ae7e4b01d938d22cfd",
    "u82-c3d-group-point-trailing-space":
        "d777f459c2972cdf06cef3f7f95891601dfc05265b55588e333425eab6cf715a",
    "u83-c3d-next-record-offset-above-32767":
        "4ed434087658aed492e55ba2863c55f05777ac176a5b63f514148126649ee73d",
    "u84-c3d-last-record-above-65535":
        "b90754aa064528c968d55b40f3a812fd5ae1b05efba3865d3184362f4ea7c8e7",
    "u85-c3d-writer-refuses-coordinate-beyond-float32":
        None,
    "u86-c3d-writer-refuses-section-of-256-blocks":
        None,
    "u87-c3d-writer-refuses-next-record-offset-65536":
        None,
    # the clean-room writer of a review of stop 72, from §6.9's text alone
    "u88-c3d-point-scale-zero-then-other-magnitude":
        "53eea49a30cd2acb74e62623d71f685d718d2a599bbdb0331239d5097e86616b",
    "u89-c3d-no-point-scale-header-scale-zero":
        "89d2a79cb00d150d058399f482b5ead5aa57dfcf0e7ecc5e2e5c22e64fded3bd",
    "u90-c3d-writer-refuses-coordinate-just-beyond-float32":
        None,
    # stop 73: a DEC and a MIPS source, a POINT group record after its parameters, and the
    # three refusals at once (the first in §6.9's order, the next-record offset)
    "u91-c3d-dec-source-processor-85":
        "406eb2236d7886d3b38f8a32fc3855e9a5110f53093d6ca45f25dcb354b4909b",
    "u92-c3d-mips-source-processor-86":
        "71c8d3b84973bc66036851016a574f0852894ee96a929a7c5bd95e739930c986",
    "u93-c3d-point-group-record-after-its-parameters":
        "47e523ff8d310f2b4b3813c8efd29c0959010104b157e73dcc4395e3790f8343",
    "u94-c3d-writer-refuses-next-record-offset-first-of-three":
        None,
}


def test_c3d_file_digests_are_an_independent_writers_and_the_references():
    """Nothing pinned the bytes of the C3D that §6.9 writes (a clean-room review of stop 53):
    ``features.c3d_file_sha256`` of every C3D vector is the digest of an independent
    writer's file (or, for the vectors in ``REFERENCE_C3D_FILES``, the reference's, pinned),
    and ``mpz.io.write_c3d`` of the decoded vector writes those bytes."""
    import hashlib

    from mpz.io.c3d import archive_bytes
    pinned = {**INDEPENDENT_C3D_FILES, **REFERENCE_C3D_FILES, **SPEC_WRITER_C3D_FILES}
    with_file = {Path(v["file"]).stem: v for v in DECODABLE
                 if "c3d_file_sha256" in v["features"]}
    assert set(with_file) == set(pinned)
    assert set(with_file) == {Path(v["file"]).stem for v in DECODABLE
                              if "c3d_archive_sha256" in v["features"]}
    for stem, v in with_file.items():
        assert v["features"]["c3d_file_sha256"] == pinned[stem], (
            f"{stem}: the C3D written from this vector is no longer the pinned one; after an "
            f"intended encoder change that regenerated the vectors, see conformance/README.md "
            f"'Regenerating the vectors' (INDEPENDENT_C3D_FILES)")
        if pinned[stem] is None:          # §6.9's writer refuses it (the file is valid)
            assert v["features"]["c3d_file_refused"], stem
            continue
        written = archive_bytes(mpz.decode(VDIR / v["file"]))
        assert hashlib.sha256(written).hexdigest() == pinned[stem], stem


def test_a_manifest_nested_too_deeply_is_a_manifest_error(tmp_path):
    """A manifest of 100,000 nested brackets raised RecursionError through the runner's
    report of a bad manifest (a QA run of stop 53)."""
    (tmp_path / "manifest.json").write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(mf.ManifestError, match="nested too deeply"):
        mf.load(tmp_path)


def _frames(data: bytes) -> list[tuple[str, int, int]]:
    """(type, first byte, last byte) of every chunk frame of ``data`` (§3.2), walked
    without any check of the types, CRCs or payloads, up to the first frame whose length
    passes the end of the file, which is listed up to the end."""
    out, pos = [], 8
    while len(data) - pos >= 8:
        n = int.from_bytes(data[pos + 4:pos + 8], "little")
        ctype = data[pos:pos + 4].decode("latin-1")
        if n > len(data) - pos - 12:
            out.append((ctype, pos, len(data) - 1))
            break
        out.append((ctype, pos, pos + 12 + n - 1))
        pos += 12 + n
    return out


def test_every_reference_message_offset_lies_in_its_chunk():
    """Spec §8 (Error reports): the offset of a chunk's error is a byte of that chunk. The
    text did not say which byte, and the reference gives the frame's first byte for some
    errors and the payload's for others (a clean-room review of stop 54): checked here on
    every invalid vector whose message names a chunk."""
    import re
    checked = 0
    for v in MAN["vectors"]:
        m = re.match(r"chunk (\S{4}), offset (\d+) ", v.get("reference_message") or "")
        if v["expected"] != "reject" or m is None:
            continue
        ctype, at = m.group(1), int(m.group(2))
        frames = _frames((VDIR / v["file"]).read_bytes())
        assert any(t == ctype and lo <= at <= hi for t, lo, hi in frames), (
            v["name"], v["reference_message"], frames)
        checked += 1
    assert checked >= 250
