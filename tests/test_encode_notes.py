"""What `mpz encode` says about its input (QA of issue 15, stop 27): an assumed frame rate
(and --rate to give the true one), marker names made unique, and an MPZ input whose own
error adds to the new bound. Before, each went by without a word: an NPY became a 1 Hz
file, an AMC a 120 Hz one, and a re-encoded MPZ declared 1 mm while it was 1.98 mm from the
capture. Expected values come from the inputs built here."""
from __future__ import annotations

from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

import mpz
from mpz.io import write
from mpz.synth import generate


def _mpz(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    exe = Path(sys.executable).parent / "mpz"
    return subprocess.run([str(exe), *args], cwd=cwd, capture_output=True, text=True,
                          timeout=120)


def test_an_assumed_rate_is_said_and_rate_gives_the_true_one(tmp_path):
    np.save(tmp_path / "walk.npy", generate("walk", frames=30).as_nan())
    p = _mpz("encode", "walk.npy", "-o", "a.mpz", cwd=tmp_path)
    assert p.returncode == 0 and "NPY stores no frame rate: 1 Hz is assumed" in p.stderr
    assert mpz.info(tmp_path / "a.mpz").rate == 1.0
    p = _mpz("encode", "walk.npy", "-o", "b.mpz", "--rate", "60", cwd=tmp_path)
    assert p.returncode == 0 and "rate" not in p.stderr
    assert mpz.info(tmp_path / "b.mpz").rate == 60.0


def test_rate_does_not_override_a_rate_the_file_stores(tmp_path):
    write(generate("walk", frames=30), tmp_path / "walk.trc")
    p = _mpz("encode", "walk.trc", "-o", "a.mpz", "--rate", "50", cwd=tmp_path)
    assert p.returncode != 0 and "stores its rate (120 Hz)" in p.stderr
    assert not (tmp_path / "a.mpz").exists()


def test_rate_in_a_batch_beside_its_inputs_names_only_the_rateless_ones(tmp_path):
    """A batch without -o writes beside its inputs in this process, not as a corpus; --rate
    names the rate of its inputs without one there too, as the README says, and leaves the
    others (before, it failed every input that stores a rate: docs audit, finding 5)."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    write(generate("walk", frames=30), tmp_path / "a" / "walk.trc")
    np.save(tmp_path / "b" / "walk.npy", generate("walk", frames=30).as_nan())
    p = _mpz("encode", "a/walk.trc", "b/walk.npy", "--rate", "60", "-q", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert mpz.info(tmp_path / "a" / "walk.mpz").rate == 120.0      # the TRC's own
    assert mpz.info(tmp_path / "b" / "walk.mpz").rate == 60.0       # the NPY's, from --rate


def test_rate_in_a_batch_does_not_depend_on_how_many_files_it_finds(tmp_path):
    """-r over a folder of one TRC is a batch as over two (review of stop 35: one file was an
    error, two were silently left); a --rate that names no input's rate says so."""
    for n in (1, 2):
        d = tmp_path / f"d{n}"
        d.mkdir()
        for k in range(n):
            write(generate("walk", frames=20), d / f"w{k}.trc")
        p = _mpz("encode", "-r", d.name, "--rate", "60", cwd=tmp_path)
        assert p.returncode == 0, p.stderr
        assert "--rate 60 changes nothing: every input of this batch stores its rate" \
            in p.stderr
        assert {mpz.info(f).rate for f in d.glob("*.mpz")} == {120.0}
    p = _mpz("encode", "d1/w0.trc", "--rate", "60", "-f", cwd=tmp_path)     # one file: error
    assert p.returncode == 2 and "stores its rate (120 Hz)" in p.stderr


def test_meta_keeps_a_value_with_equals_signs_and_names_reader_keys(tmp_path):
    """--meta splits at the first '=' (a URL's query kept whole; before: key
    'url=http://x/?a', value 'b'). A key the readers set (subject) is no free metadata:
    no writer writes it back, so the note says so, in a batch too."""
    write(generate("walk", frames=30), tmp_path / "walk.trc")
    p = _mpz("encode", "walk.trc", "-o", "a.mpz", "--meta", "url=http://x/?a=b&c=d",
             "--meta", "subject=Bob", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    meta = mpz.decode((tmp_path / "a.mpz").read_bytes()).metadata
    assert meta["url"] == "http://x/?a=b&c=d" and meta["subject"] == "Bob"
    assert "--meta subject: a key the readers set" in p.stderr and "subject_name" in p.stderr
    assert "--meta url" not in p.stderr
    p = _mpz("show", "a.mpz", cwd=tmp_path)          # the text says they are there
    assert p.returncode == 0 and "subject:   Bob\n" in p.stdout
    free = [k for k in meta if k.startswith("trc.")] + ["url"]
    assert f"metadata:  {len(free)} entries: trc." in p.stdout and "(--json: the values)" \
        in p.stdout
    (tmp_path / "in").mkdir()
    write(generate("walk", frames=30), tmp_path / "in" / "w.trc")
    (tmp_path / "out").mkdir()
    p = _mpz("encode", "-r", "in", "-o", "out/", "--meta", "subject=x", cwd=tmp_path)
    assert p.returncode == 0 and "--meta subject: a key the readers set" in p.stdout  # summary


@pytest.mark.parametrize("meta", [["format=bvh"], ["source=x.c3d"], ["a=1", "a=2"],
                                  ["trc.Decimals=1"], ["csv.FirstFrame=99"]])
def test_meta_that_would_misdescribe_the_file_is_a_usage_error(tmp_path, meta):
    """QA (stop 45): --meta format=bvh was kept with a note, and every later mpz decode of
    the file tried to write BVH and failed; a key given twice kept its last value."""
    write(generate("walk", frames=30), tmp_path / "walk.trc")
    args = [a for m in meta for a in ("--meta", m)]
    p = _mpz("encode", "walk.trc", "-o", "a.mpz", *args, cwd=tmp_path)
    assert p.returncode == 64 and "--meta" in p.stderr, p.stderr
    assert not (tmp_path / "a.mpz").exists()
    if meta == ["trc.Decimals=1"]:        # a name that is not one too (a review of stop 56)
        assert "e.g. --meta note_trc_Decimals=..." in p.stderr, p.stderr


def test_renamed_markers_are_said(tmp_path):
    lines = ["PathFileType\t4\t(X/Y/Z)\tt.trc",
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
             "OrigDataStartFrame\tOrigNumFrames", "60\t60\t3\t2\tmm\t60\t1\t3",
             "Frame#\tTime\tKNE\t\t\tKNE\t\t", "\t\tX1\tY1\tZ1\tX2\tY2\tZ2", ""]
    lines += [f"{f}\t{(f - 1) / 60:.6f}\t1\t2\t3\t4\t5\t{f}" for f in (1, 2, 3)]
    (tmp_path / "dup.trc").write_text("\n".join(lines) + "\n")
    p = _mpz("encode", "dup.trc", "-o", "a.mpz", cwd=tmp_path)
    assert p.returncode == 0 and "made unique: KNE->KNE#2 (every format written back " \
        "gets these names)" in p.stderr     # a TRC has no C3D archive to keep labels in


def test_an_mpz_input_says_that_errors_add(tmp_path):
    write(generate("walk", frames=30), tmp_path / "walk.trc")
    assert _mpz("encode", "walk.trc", "-o", "a.mpz", "--max-error", "1mm",
                cwd=tmp_path).returncode == 0
    p = _mpz("encode", "a.mpz", "-o", "b.mpz", "--max-error", "1mm", cwd=tmp_path)
    assert p.returncode == 0
    assert "the input is an MPZ file, within 1 mm of its own source" in p.stderr


def test_a_grid_the_bound_cannot_use_is_said(tmp_path):
    """--grid 5mm with --max-error 1mm: rounding to a 5 mm grid alone errs by up to
    sqrt(3) x 2.5 mm, so the encoder takes a finer step, and says so."""
    write(generate("walk", frames=30), tmp_path / "walk.trc")
    p = _mpz("encode", "walk.trc", "-o", "a.mpz", "--max-error", "1mm", "--grid", "5mm",
             cwd=tmp_path)
    assert p.returncode == 0
    assert "--grid 5mm: the grid step is" in p.stderr and "the bound 1 mm needs" in p.stderr
    p = _mpz("encode", "walk.trc", "-o", "b.mpz", "--max-error", "1mm", "--grid", "0.1mm",
             cwd=tmp_path)
    assert p.returncode == 0 and "--grid" not in p.stderr          # taken as given


def test_a_skeletal_ratio_counts_the_channels_it_stores(tmp_path, two_joint_bvh):
    """A BVH's data are its 9 channels x 3 frames; the joint positions (3 joints with the
    End Site) are computed from them. The report's first ratio is against the channels as
    float32 (9 x 3 x 4 = 108 bytes), and the error line says it measures the marker layer."""
    import json
    (tmp_path / "two.bvh").write_text(two_joint_bvh)
    p = _mpz("encode", "two.bvh", "-o", "a.mpz", "--json", cwd=tmp_path)
    assert p.returncode == 0
    rep = json.loads(p.stdout)
    size = (tmp_path / "a.mpz").stat().st_size
    assert rep["channel_float32_bytes"] == 108
    assert rep["ratio_channels_float32"] == 108 / size
    assert rep["bytes_skeleton"] > 0
    p = _mpz("encode", "two.bvh", "-o", "b.mpz", cwd=tmp_path)
    assert "vs the 9 channels as float32 (108 B)" in p.stdout
    assert "error    marker layer" in p.stdout


def test_small_messages_say_the_right_thing(tmp_path):
    """QA's small ones: a CSV without units is not called a BVH; a FIFO as output is
    refused for what it is, not with 'use --force'; a MIPS or DEC source written back as
    C3D says that its byte order changed."""
    import os

    from mpz.io import writer_problems
    from mpz.tools.make_vectors import c3d_motion
    m = generate("walk", frames=10)
    write(mpz.Motion(m.positions, m.names, m.rate, "", m.valid), tmp_path / "w.csv")
    p = _mpz("encode", "w.csv", "-o", "a.mpz", "--max-error", "1mm", cwd=tmp_path)
    assert p.returncode != 0 and "(CSV stores none)" in p.stderr and "BVH" not in p.stderr
    os.mkfifo(tmp_path / "ff.mpz")
    p = _mpz("encode", "w.csv", "-o", "ff.mpz", cwd=tmp_path)
    assert p.returncode != 0 and "not a regular file" in p.stderr and "--force" not in p.stderr
    c = c3d_motion(2, storage=1, F=6, M=3, J=0, C=0, n=1)
    c.extras["c3d"].processor = 86
    _, notes = writer_problems(c, ".c3d")
    assert any("MIPS C3D (processor 86)" in n and "Intel byte order" in n for n in notes)


def test_show_tells_what_a_c3d_holds_beside_its_markers(tmp_path):
    import json

    from mpz.io.c3d import archive_bytes
    from mpz.tools.make_vectors import c3d_motion
    m = c3d_motion(3, storage=1, F=12, M=4, J=2, C=3, n=2)       # header first frame 10
    (tmp_path / "s.c3d").write_bytes(archive_bytes(m))
    p = _mpz("show", "s.c3d", "--json", cwd=tmp_path)
    c = json.loads(p.stdout)["c3d"]
    a = m.extras["c3d"]
    assert (c["model_outputs"], c["analog_channels"], c["analog_samples_per_frame"]) == (2, 3, 2)
    assert c["first_frame"] == 10 and c["parameter_records"] == len(a.records)
    assert c["model_gap_fraction"] == 3 / 24           # output 0 starts 3 frames late
    assert c["storage"] == "float32"
    p = _mpz("show", "s.c3d", cwd=tmp_path)
    assert "2 model outputs" in p.stdout and "3 analog channels x 2 samples" in p.stdout


def test_the_summary_line_gives_the_k_the_file_holds(tmp_path):
    """A 30-frame walk cannot have 300 segments: the file holds k = 30 (§4.15: each k at
    most F), and the report says so instead of repeating the request."""
    import json
    write(generate("walk", frames=30), tmp_path / "walk.trc")
    p = _mpz("encode", "walk.trc", "-o", "a.mpz", "--summary", "6,300", cwd=tmp_path)
    assert "k = 6, 30 (asked 6, 300" in p.stdout
    p = _mpz("encode", "walk.trc", "-o", "b.mpz", "--summary", "6,300", "--json",
             cwd=tmp_path)
    assert json.loads(p.stdout)["summary_levels"] == [6, 30]


def test_a_model_error_beyond_the_range_is_a_usage_error(tmp_path):
    """--model-error ANGLES=1e308 gave "bound inf is not finite" from inside the encoder
    (exit 2, QA stop 45): the value is a fraction of a channel's range, at most 1."""
    write(generate("walk", frames=30), tmp_path / "walk.trc")
    for v in ("1e308", "1.5"):
        p = _mpz("encode", "walk.trc", "-o", "a.mpz", "--model-error", f"ANGLES={v}",
                 cwd=tmp_path)
        assert p.returncode == 64 and "at most 1" in p.stderr, p.stderr
    p = _mpz("encode", "walk.trc", "-o", "a.mpz", "--model-error", "ANGLES=1", cwd=tmp_path)
    assert p.returncode == 0, p.stderr


def test_options_that_change_nothing_are_said(tmp_path, two_joint_bvh):
    """QA (stop 45): --asf and --no-skeleton on a TRC, --summary-format without --summary,
    and --angle-error with --no-skeleton were accepted without a word (exit 0)."""
    write(generate("walk", frames=30), tmp_path / "walk.trc")
    p = _mpz("encode", "walk.trc", "-o", "a.mpz", "--asf", "x.asf", "--no-skeleton",
             "--summary-format", "smry", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    for said in ("--asf changes nothing", "--no-skeleton changes nothing",
                 "--summary-format changes nothing without --summary"):
        assert said in p.stderr, p.stderr
    p = _mpz("encode", "walk.trc", "-o", "b.mpz", "--summary", "2", "--summary-format",
             "smry", cwd=tmp_path)
    assert p.returncode == 0 and "changes nothing" not in p.stderr
    assert "smry" in mpz.info(tmp_path / "b.mpz").chunk_bytes          # it did apply
    (tmp_path / "j.bvh").write_text(two_joint_bvh)
    p = _mpz("encode", "j.bvh", "-o", "j.mpz", "--no-skeleton", "--angle-error", "0.5",
             cwd=tmp_path)
    # the flag given alone is named (it said "--angle-error and --translation-error
    # change nothing": a docs QA run of stop 74)
    assert p.returncode == 0 and "note: --angle-error changes nothing with --no-skeleton" \
        in p.stderr and "--translation-error" not in p.stderr, p.stderr
    p = _mpz("encode", "j.bvh", "-o", "k.mpz", "--no-skeleton", "--angle-error", "0.5",
             "--translation-error", "0.1", cwd=tmp_path)
    assert p.returncode == 0 and "--angle-error and --translation-error change nothing " \
        "with --no-skeleton" in p.stderr, p.stderr


def test_a_model_error_too_fine_to_hold_is_said():
    """QA (stop 45): --model-error ANGLES=1e-10 was coded at the finest bound that holds
    and declared it, while the report said the outputs were within their bound. A model
    output of values 0 and 1000 has a range of 1000: 3e-10 of it is 3e-7, below 1000 /
    2^31 = 4.66e-7, the finest step 2^31 grid steps allow."""
    from mpz.encoder import EncodeOptions, encode_motion
    from mpz.tools.make_vectors import c3d_motion
    m = c3d_motion(7, storage=1, F=16, M=3, J=1, C=2, n=2)
    a = m.extras["c3d"]
    a.models[:] = 0.0
    a.models[8, 0, :] = 1000.0
    a.models[~a.model_valid] = np.nan
    # the library's report says it too (a docs QA run of stop 74: the command alone did)
    fine = EncodeOptions(max_error=1.0, model_errors={"ANGLES": 3e-10})
    notes = encode_motion(m, fine)[1].notes
    assert len(notes) == 1 and "model_errors['ANGLES']=3e-10" in notes[0] \
        and "cannot be held" in notes[0]
    ok = EncodeOptions(max_error=1.0, model_errors={"ANGLES": 1e-4})
    assert encode_motion(m, ok)[1].notes == []
    # the one bound for every kind, model_error, said the same (an API QA run of stop 74:
    # the same file, and no note)
    scalar = EncodeOptions(max_error=1.0, model_error=3e-10)
    data, rep = encode_motion(m, scalar)
    assert data == encode_motion(m, fine)[0]
    assert len(rep.notes) == 1 and rep.notes[0].startswith("model_error=3e-10 (ANGLES): ") \
        and "cannot be held" in rep.notes[0], rep.notes


def test_a_memory_limit_that_limits_nothing_is_said(tmp_path):
    """QA (stop 47): --memory-limit limits the local Dask workers of a corpus run only; with
    --jobs 0, or one file to one file, it was accepted without a word (exit 0). With
    --scheduler the same note is printed before the run (tests/test_corpus.py)."""
    write(generate("walk", frames=30), tmp_path / "walk.trc")
    p = _mpz("encode", "walk.trc", "-o", "a.mpz", "--memory-limit", "1GiB", cwd=tmp_path)
    assert p.returncode == 0 and "--memory-limit 1GiB changes nothing" in p.stderr, p.stderr
    (tmp_path / "out").mkdir()
    p = _mpz("encode", "walk.trc", "-o", "out/", "--jobs", "0", "--memory-limit", "1GiB",
             cwd=tmp_path)
    assert p.returncode == 0 and "--jobs 0 encodes in this process" in p.stderr, p.stderr
    assert (tmp_path / "out" / "walk.mpz").exists()
    p = _mpz("encode", "walk.trc", "-o", "b.mpz", cwd=tmp_path)        # the default: silent
    assert p.returncode == 0 and "memory" not in p.stderr, p.stderr



def test_a_c3d_of_joint_positions_notes_float32_against_position_bound(tmp_path,
                                                                       two_joint_bvh):
    """A QA of stop 48: BVH and AMC files decoded to C3D passed their position_bound by up
    to 6.7e-6 mm without a word. The positions written are the joints of the channels, so
    the float32 note weighs them against the skeleton chunk's position_bound (it quoted
    MHDR's bound), and C3D's rounding is said whatever its share of the bound (at 1 unit
    here it is below 10^-4 of it, which silenced the note). The rounding figure is
    measured here from the decoded joints."""
    import re

    from mpz.skeleton import report
    (tmp_path / "j.bvh").write_text(two_joint_bvh)
    for name, bound in (("d", []), ("one", ["--max-error", "1"])):
        assert _mpz("encode", "j.bvh", "-o", f"{name}.mpz", *bound,
                    cwd=tmp_path).returncode == 0
        pb = float(report((tmp_path / f"{name}.mpz").read_bytes())["position_bound"])
        if not bound:
            assert pb != mpz.info(tmp_path / f"{name}.mpz").error_bound
        p = _mpz("decode", f"{name}.mpz", "-o", f"{name}.npy", cwd=tmp_path)  # float64
        assert p.returncode == 0 and "float32" not in p.stderr, p.stderr
        joints = np.load(tmp_path / f"{name}.npy").reshape(-1, 3)
        err = np.sqrt(((joints.astype(np.float32).astype(np.float64) - joints) ** 2).sum(1))
        p = _mpz("decode", f"{name}.mpz", "-o", f"{name}.c3d", cwd=tmp_path)
        note = re.search(r"float32: values rounded by up to (\S+), which the file's "
                         r"declared (\S+) bound", p.stderr)
        assert p.returncode == 0 and note, p.stderr
        assert float(note[2]) == pytest.approx(pb, rel=1e-5)
        assert float(note[1]) == pytest.approx(err.max(), rel=0.05)
        if bound:
            assert err.max() < 1e-4 * pb


def test_a_source_grid_with_a_max_error_is_not_reported_exact():
    """QA, stop 49: source_grid=0.5 with max_error=1.0 coded 55 of 60 samples off the
    source (within 1.0, as declared) and reported "exact on the grid ... (error 0)"."""
    rng = np.random.default_rng(0)
    p = np.round(rng.normal(size=(20, 3, 3)) * 100) * 0.5
    m = mpz.Motion(p, ["a", "b", "c"], rate=10.0, units="mm")
    data, rep = mpz.encode_motion(m, mpz.EncodeOptions(max_error=1.0, source_grid=0.5))
    err = float(np.sqrt(((mpz.decode(data).positions - p) ** 2).sum(-1)).max())
    assert 0 < err <= 1.0                               # measured: not exact
    assert "error 0" not in rep.bound_rule and "exact" not in rep.bound_rule
    assert "max error 1 (given)" in rep.bound_rule and "0.5" in rep.bound_rule
    data, rep = mpz.encode_motion(m, mpz.EncodeOptions(source_grid=0.5))
    assert np.array_equal(mpz.decode(data).positions, p) and "error 0" in rep.bound_rule


def test_a_default_bound_too_fine_says_it_is_the_default():
    """QA, stop 49: with no option, a motion of tiny extent far from the origin was refused
    as 'max error 4.19e-13 is too fine', a max error the caller never gave."""
    rng = np.random.default_rng(0)
    m = mpz.Motion(1e6 + rng.normal(size=(20, 3, 3)) * 1e-9, ["a", "b", "c"], rate=10.0,
                   units="")
    with pytest.raises(mpz.EncoderError, match=r"default.*max_error|max_error.*default"):
        mpz.encode(m)
    assert mpz.info(mpz.encode(m, max_error=1e-6)).error_bound == 1e-6


def test_the_default_rule_names_what_gave_the_bound_when_there_is_no_extent():
    """QA, stop 49: a unitless motion without extent (constant, all gaps) declared 0.1 and
    said '0.0001 of the largest extent' (which is 0)."""
    for p in (np.full((5, 2, 3), 1234.5), np.full((5, 2, 3), np.nan)):
        m = mpz.Motion(p, ["a", "b"], rate=10.0, units="")
        data, rep = mpz.encode_motion(m)
        assert mpz.info(data).error_bound == 0.1
        assert "extent" in rep.bound_rule and "0.0001 of the largest extent" not in \
            rep.bound_rule, rep.bound_rule
    m = mpz.Motion(np.array([[[0.0, 0, 0]], [[1000.0, 0, 0]]]), ["a"], rate=10.0, units="")
    data, rep = mpz.encode_motion(m)
    assert mpz.info(data).error_bound == 0.1 and "0.0001 of the largest extent" in rep.bound_rule


def test_a_limit_refusal_names_the_limit():
    m = mpz.Motion(np.zeros((1, 4097, 3)), [f"m{i}" for i in range(4097)], rate=1.0)
    with pytest.raises(mpz.EncoderError, match="4096"):
        mpz.encode(m, max_error=1.0)


def test_a_file_that_breaks_its_declared_bound_is_a_bug_and_is_not_left(tmp_path, monkeypatch,
                                                                        capsys):
    """A maintainer's QA run (stop 50): an encoder broken on purpose reported "error max
    1.59963 mm (bound 1 mm)" and exited 0, the file kept. The command checks the bound on
    what it wrote: a breach is a bug (exit 70) and the file is removed. The breach is made
    here by shifting what the decode gives back by 2 mm."""
    import dataclasses

    import mpz
    from mpz.io import write
    from mpz.synth import generate
    from mpz.tools import mpz_cli
    write(generate("walk", frames=40, seed=3), tmp_path / "w.c3d")
    real = mpz.decode

    def shifted(data, **kw):
        m = real(data, **kw)
        return dataclasses.replace(m, positions=m.positions + 2.0)
    monkeypatch.setattr(mpz, "decode", shifted)
    out = tmp_path / "w.mpz"
    code = mpz_cli.main(["encode", str(tmp_path / "w.c3d"), "-o", str(out), "--max-error",
                         "1mm", "-q"])
    err = capsys.readouterr().err
    assert code == 70 and "breaks its declared bound: max error " in err, err
    assert " > 1.0 (" in err and "internal error: this is a bug" in err, err
    assert "the output was removed" in err and not out.exists()
    monkeypatch.setattr(mpz, "decode", real)
    assert mpz_cli.main(["encode", str(tmp_path / "w.c3d"), "-o", str(out), "--max-error",
                         "1mm", "-q"]) == 0 and out.exists()


def test_re_encoding_an_mpz_keeps_its_summary(tmp_path):
    """`mpz encode x.mpz` (stop 49's list): the input's summary chunk was dropped without a
    word unless --summary was given. It is made again with the same levels, space and
    chunk type, and said; --summary-format given with it is used, not called idle."""
    m = generate("walk", frames=120, seed=4)
    (tmp_path / "a.mpz").write_bytes(mpz.encode(m, max_error=0.5, summary=[3, 6],
                                                summary_format="smry"))
    p = _mpz("encode", "a.mpz", "-o", "b.mpz", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert "the input's summary (k = 3,6) is made again from its decoded motion, as smry " \
           "of the positions" in p.stderr
    info = mpz.info(tmp_path / "b.mpz")
    assert info.summary_levels == (3, 6) and "smry" in info.chunk_bytes
    p = _mpz("encode", "a.mpz", "-o", "c.mpz", "--summary-format", "smrc", cwd=tmp_path)
    assert p.returncode == 0 and "changes nothing" not in p.stderr, p.stderr
    assert "smrc" in mpz.info(tmp_path / "c.mpz").chunk_bytes
    p = _mpz("encode", "a.mpz", "-o", "d.mpz", "--summary", "2", cwd=tmp_path)
    assert p.returncode == 0 and "made again" not in p.stderr
    assert mpz.info(tmp_path / "d.mpz").summary_levels == (2,)


def test_re_encoding_an_mpz_from_standard_input_keeps_its_summary(tmp_path):
    """A review of stop 50: `cat a.mpz | mpz encode - -o b.mpz` dropped the summary
    without the note the code's docstring promised; it is kept as from a file."""
    m = generate("walk", frames=120, seed=4)
    data = mpz.encode(m, max_error=0.5, summary=[2, 4])
    p = subprocess.run([sys.executable, "-m", "mpz.tools.mpz_cli", "encode", "-", "-o",
                        "b.mpz"], input=data, cwd=tmp_path, capture_output=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert b"the input's summary (k = 2,4) is made again" in p.stderr
    assert mpz.info(tmp_path / "b.mpz").summary_levels == (2, 4)


def test_a_bad_output_on_the_null_device_is_not_removed(tmp_path):
    """The bound check and the decoder check remove a bad output; `-o /dev/null` was
    os.remove'd too, which as root unlinks the device (a review of stop 51). The helper
    that removes says what became of each kind of output."""
    import os

    from mpz.tools.cmd_encode import _remove_output
    assert _remove_output(os.devnull, False) == "it was written to a file that is not kept"
    assert os.path.exists(os.devnull)
    assert _remove_output("-", True) == "it was written to standard output"
    bad = tmp_path / "bad.mpz"
    bad.write_bytes(b"x")
    assert _remove_output(str(bad), False) == "the output was removed" and not bad.exists()


def test_grid_note_on_an_int16_c3d_names_its_grid_not_the_bound(shared_data, tmp_path):
    """--grid 0.2mm at a 0.5 mm bound on an int16 C3D: the step is its POINT:SCALE (1/12
    mm), and the note said "the bound 0.5 mm needs a finer one", which 0.2 mm does not (a
    QA run of stop 53)."""
    src = shared_data / "c3d" / "c3dorg_Eb015pi.c3d"
    p = _mpz("encode", str(src), "--max-error", "0.5mm", "--grid", "0.2mm", "-o", "/dev/null",
             cwd=tmp_path)
    assert p.returncode in (0, 1), p.stderr
    assert "the grid step is 0.0833333 mm instead (the source's int16 grid, POINT:SCALE " \
        "0.0833333)" in p.stderr, p.stderr
    assert "needs a finer one" not in p.stderr


def test_what_the_file_shows_of_the_options_is_said_by_the_library_and_corpus_runs(
        tmp_path, monkeypatch):
    """A --grid the bound overruled and a --weight without a pattern layer were noted by
    mpz encode alone: EncodeReport.notes and a corpus run's notes lacked them (a docs QA
    run of stop 74). The library says them in its own spelling, and a corpus run in the
    command's, of a file it encodes and again of one it finds up to date."""
    import json

    from mpz.encoder import EncodeOptions, encode_motion
    m = generate("walk", frames=30)
    name = m.names[0]
    rep = encode_motion(m, EncodeOptions(max_error=1.0, grid=5.0, weights={name: 8.0}))[1]
    assert [n.split(":")[0] for n in rep.notes] == ["grid=5", "weights"], rep.notes
    assert "the grid step is 0.57735 mm instead (the bound 1 mm needs a finer one)" \
        in rep.notes[0]
    # neither is given: nothing said, and the file is not parsed for them (an encode's
    # cost, issue 15)
    from mpz import encoder

    def parse(*_a, **_k):
        raise AssertionError("the encoded file was parsed")
    monkeypatch.setattr(encoder.container, "parse", parse)
    assert encode_motion(m, EncodeOptions(max_error=1.0))[1].notes == []
    monkeypatch.undo()
    src = tmp_path / "src"
    src.mkdir()
    write(m, src / "walk.trc")
    for status in ("encoded", "skipped", "kept"):
        if status == "kept":               # the row rebuilt from the output, not encoded
            (tmp_path / "out" / "index.sqlite").unlink()
        p = _mpz("encode", "-r", "src", "-o", "out/", "--jobs", "0", "--max-error", "1mm",
                 "--grid", "5mm", "--weight", f"{name}=8", "--json", cwd=tmp_path)
        assert p.returncode == 0, p.stderr
        (entry,) = json.loads(p.stdout)["files"]
        assert entry["status"] == status
        assert [n.split(":")[0] for n in entry["notes"]] == ["--grid 5mm", "--weight"], entry


def test_the_grid_note_names_the_flag_in_the_files_units_and_a_step_that_differs(
        tmp_path, shared_data):
    """--grid 0.5cm on a file in mm is --grid 5mm; and a step 3e-8 mm off the grid asked
    (60 steps of an int16 C3D's 1/12 mm, as float32) was said as "the grid step is 5 mm
    instead" of 5 mm (a review of stop 74): it is given to the digits that differ."""
    write(generate("walk", frames=30), tmp_path / "walk.trc")
    p = _mpz("encode", "walk.trc", "-o", "a.mpz", "--max-error", "1mm", "--grid", "0.5cm",
             cwd=tmp_path)
    assert p.returncode == 0
    assert "note: --grid 5mm: the grid step is 0.57735 mm instead (the bound 1 mm" \
        in p.stderr, p.stderr
    src = shared_data / "c3d" / "c3dorg_Eb015pi.c3d"
    p = _mpz("encode", str(src), "-o", "b.mpz", "--lossy", "--grid", "5mm", cwd=tmp_path)
    assert p.returncode in (0, 1), p.stderr
    from mpz import container
    step = next(c.record.step for c in container.parse((tmp_path / "b.mpz").read_bytes())
                if c.type == "QUNT")
    assert step != 5.0 and f"the grid step is {step:.9g} mm instead" in p.stderr, p.stderr


def test_pattern_options_without_a_pattern_layer_and_absent_model_kinds_are_said():
    """theta, k0, ... under a bound, where no node keeps a pattern layer, gave the default
    encode's bytes, and a model_errors kind the file holds no output of changed nothing,
    both unsaid, while weights were noted (an API QA run of stop 74)."""
    from mpz.encoder import EncodeOptions, encode_motion
    m = generate("walk", frames=40)
    plain = encode_motion(m, EncodeOptions(max_error=1.0))[0]
    data, rep = encode_motion(m, EncodeOptions(max_error=1.0, theta=0.5, k0=9,
                                               model_errors={"FORCES": 1e-3}))
    assert data == plain                             # they did change nothing
    assert rep.notes == [
        "model_errors['FORCES'] changes nothing: the file keeps no FORCES model output",
        "theta, k0: they act on the pattern layer only (the paper's segmentation, "
        "clustering, distortion control and boundary smoothing), and no node kept one "
        "(under a bound, key frames or per-sample residuals won): they do not change the "
        "decoded motion"]
    lossy = encode_motion(m, EncodeOptions(lossy=True, theta=0.5))
    assert lossy[0] != encode_motion(m, EncodeOptions(lossy=True))[0]
    assert lossy[1].notes == []


def test_smoothing_without_a_pattern_layer_is_said():
    """``smoothing`` under a bound writes MHDR's half-width, so the bytes differ from the
    default encode's, but §6.4 smooths pattern layers alone: the decoded motion is the
    same, and the option went unsaid (an API QA run of stop 74). In lossy mode, where a
    pattern layer is kept, it acts and gets no note."""
    from mpz.encoder import EncodeOptions, encode_motion
    m = generate("walk", frames=40)
    plain = encode_motion(m, EncodeOptions(max_error=1.0))[0]
    data, rep = encode_motion(m, EncodeOptions(max_error=1.0, smoothing=5))
    from mpz.decoder import read_stream
    assert data != plain and read_stream(data).header.smoothing == 5
    assert np.array_equal(mpz.decode(data).positions, mpz.decode(plain).positions)
    assert len(rep.notes) == 1 and rep.notes[0].startswith("smoothing: they act on the "
                                                           "pattern layer only")
    lossy = encode_motion(m, EncodeOptions(lossy=True, smoothing=5))
    assert not np.array_equal(mpz.decode(lossy[0]).positions,
                              mpz.decode(encode_motion(m, EncodeOptions(lossy=True))[0]).positions)
    assert lossy[1].notes == []


def test_what_is_dropped_unasked_is_what_no_option_or_reader_warning_said():
    """mpz.encoder.unasked, the rule of the warnings (exit 1) for dropped content: the
    reader's list of what it could not carry, yes; the skeleton --no-skeleton leaves out,
    no (asked for); a C3D archive its reader could not keep, no (the reader's warning
    says it: a corpus printed it twice, the review of stop 75)."""
    from mpz.corpus import CorpusReport, FileResult
    from mpz.encoder import EncodeOptions, not_kept, unasked
    from mpz.motion import READER_NOT_KEPT
    m = generate("walk", frames=5)
    m.metadata.update(format="c3d", warning="C3D archive not kept: bad parameter block")
    m.extras[READER_NOT_KEPT] = ["from the AMC: 1 comment"]
    dropped = not_kept(m, EncodeOptions())
    assert dropped[0].startswith("analog, parameters and residuals (C3D archive not kept")
    assert unasked(dropped) == ["from the AMC: 1 comment"]
    assert unasked(["joint angles and the skeleton", "x"]) == ["x"]
    table = CorpusReport([FileResult("a.c3d", "a.mpz", "encoded", warning=m.metadata[
        "warning"], not_kept=dropped)], 1.0, 1, "local", "").table().splitlines()
    assert [line.split(":")[0] for line in table if "a.c3d" in line] == \
        ["  WARNING a.c3d", "  WARNING a.c3d", "  NOTE a.c3d"]
    assert "  WARNING a.c3d: not kept: from the AMC: 1 comment" in table
