"""The public API as a library user calls it (a review of the API at stop 36): every
function that reads an MPZ file takes what ``mpz.decode`` takes, misspelled options are
named, readers take their path by keyword, and the summary's lookups say what is there."""
from __future__ import annotations

import inspect
import io
from pathlib import Path
import re

import numpy as np
import pytest

import mpz
from mpz.errors import EncoderError, InputFormatError, MotionError
from mpz.motion import Motion
from mpz.synth import generate


@pytest.fixture(scope="module")
def summarised() -> bytes:
    return mpz.encode(generate("walk", frames=120, seed=2), max_error=1.0, summary=(4, 8))


def test_a_summary_level_cannot_be_written_through(summarised: bytes) -> None:
    """Summary.level() handed out its stored arrays, and writing into them changed every
    later level() and preview() (an API QA run of stop 74): they are read-only views."""
    summary = mpz.read_summary(summarised)
    assert summary is not None
    level = summary.level(4)
    before = summary.preview(4).positions.copy()
    for a in (level.starts, level.means):
        with pytest.raises(ValueError, match="read-only"):
            a[0] = 1
    mine = level.starts.copy()
    mine[0] = 1                                           # a copy is the caller's
    assert summary.level(4).starts[0] == 0
    assert np.array_equal(summary.preview(4).positions, before)


def test_read_summary_takes_what_decode_takes(summarised: bytes, tmp_path: Path) -> None:
    """A path (str or Path), the bytes, a bytearray or a binary file object: the same
    summary. Before, only bytes: a Path was read as the bytes of its own name."""
    path = tmp_path / "s.mpz"
    path.write_bytes(summarised)
    want = mpz.read_summary(summarised)
    assert want is not None and [lv.k for lv in want.levels] == [4, 8]
    for source in (str(path), path, bytearray(summarised), io.BytesIO(summarised)):
        got = mpz.read_summary(source)
        assert got is not None
        assert [(lv.k, lv.starts.tolist(), lv.means.tolist()) for lv in got.levels] == \
            [(lv.k, lv.starts.tolist(), lv.means.tolist()) for lv in want.levels]
    with pytest.raises(TypeError):
        mpz.read_summary(12)                            # type: ignore[arg-type]
    with pytest.raises(mpz.MPZError) as err:
        mpz.read_summary(tmp_path / "missing.mpz")
    assert "missing.mpz" in str(err.value)


def test_summary_lookups_say_what_is_there(summarised: bytes) -> None:
    s = mpz.read_summary(summarised)
    assert s is not None
    with pytest.raises(KeyError, match="no summary level of 3 segments; the file has 4, 8"):
        s.level(3)
    with pytest.raises(ValueError, match="mode must be 'constant' or 'linear'"):
        s.preview(mode="cubic")
    assert s.preview(8, mode="linear").n_frames == 120


def test_write_mpz_names_a_misspelled_option(tmp_path: Path) -> None:
    """As mpz.encode does: an EncoderError with the closest option, nothing written.
    Before, a TypeError from EncodeOptions' constructor left the API."""
    with pytest.raises(EncoderError, match="unknown option max_eror; did you mean max_error"):
        mpz.write_mpz(generate("walk", frames=24), tmp_path / "w.mpz", max_eror=1.0)
    assert not (tmp_path / "w.mpz").exists()
    report = mpz.write_mpz(generate("walk", frames=24), tmp_path / "w.mpz", max_error=1.0)
    assert report.file_bytes == (tmp_path / "w.mpz").stat().st_size


@pytest.mark.parametrize("name", ["w.c3d", "w.TRC", "w.bvh", "w.amc", "w.asf", "w.npy",
                                  "w.csv"])
def test_write_mpz_refuses_a_motion_formats_name(tmp_path: Path, name: str) -> None:
    """MPZ bytes in w.c3d would be read as a C3D by every tool (mpz's own too): the caller
    meant mpz.io.write. Nothing is encoded or written; any other name is allowed."""
    with pytest.raises(EncoderError, match=f"{name}: an MPZ file named "
                       f"{name[1:].lower()} would be read as {name[2:].upper()}"):
        mpz.write_mpz(generate("walk", frames=24), tmp_path / name, max_error=1.0)
    assert not (tmp_path / name).exists()
    mpz.write_mpz(generate("walk", frames=24), tmp_path / "w.bin", max_error=1.0)
    assert mpz.decode(tmp_path / "w.bin").n_frames == 24


@pytest.mark.parametrize("name", ["read_c3d", "read_trc", "read_bvh", "read_asf",
                                  "read_amc", "read_npy", "read_csv"])
def test_readers_take_their_path_by_keyword(name: str, tmp_path: Path) -> None:
    """The error boundary keeps each reader's own signature (type checkers took the path as
    positional-only), and a path given by keyword is named in the error."""
    fn = getattr(mpz.io, name)
    first = next(iter(inspect.signature(fn).parameters.values()))
    assert first.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD
    missing = tmp_path / "missing.x"
    with pytest.raises(InputFormatError) as err:
        fn(**{first.name: missing})
    assert "missing" in str(err.value)


@pytest.mark.parametrize("name", ["read_amc", "read_npy", "read_csv"])
@pytest.mark.parametrize("rate", ["x", -1, 0.0, float("nan"), True])
def test_a_bad_rate_argument_is_the_callers_not_the_files(name: str, rate: object,
                                                          tmp_path: Path) -> None:
    """read_amc, read_npy and read_csv gave "cannot read" or "inconsistent data" naming
    the file for a bad ``rate`` argument; it is a ValueError, as mpz.io.read gives, raised
    before the file is opened (this one does not exist)."""
    fn = getattr(mpz.io, name)
    with pytest.raises(ValueError, match="rate must be a finite number") as err:
        fn(tmp_path / "missing.x", rate=rate)
    assert not isinstance(err.value, mpz.MPZError)


def test_file_info_is_read_only_and_hashable(summarised: bytes) -> None:
    """FileInfo is a frozen dataclass: its metadata and chunk sizes are read-only too, and
    it hashes (API review F10: its dicts made hash() fail and let metadata change)."""
    import pickle
    fi = mpz.info(summarised)
    with pytest.raises(TypeError):
        fi.metadata["take"] = "2"                       # type: ignore[index]
    with pytest.raises(TypeError):
        fi.chunk_bytes["MHDR"] = 0                      # type: ignore[index]
    twin = pickle.loads(pickle.dumps(fi))
    assert twin == fi and hash(twin) == hash(fi)
    assert dict(fi.chunk_bytes) == fi.chunk_bytes and 0 < sum(fi.chunk_bytes.values()) <= fi.size
    assert {fi: 1}[mpz.info(summarised)] == 1


def test_wrong_argument_types_are_named(tmp_path: Path) -> None:
    """API review F7: these let an AttributeError, a bare TypeError or an
    IsADirectoryError out of the API."""
    import numpy as np
    m = generate("walk", frames=10)
    with pytest.raises(EncoderError, match="source_grid must be finite and > 0, got 'x'"):
        mpz.encode(m, source_grid="x")                  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="decoded must be an mpz.Motion, got ndarray"):
        mpz.max_error(m, np.zeros((10, 41, 3)))        # type: ignore[arg-type]
    with pytest.raises(mpz.MotionError, match="can only concatenate Motions, got int"):
        mpz.concatenate([1, m])                         # type: ignore[list-item]
    with pytest.raises(TypeError, match="head must be bytes"):
        mpz.io.detect_format(3)                         # type: ignore[arg-type]
    assert mpz.io.detect_format(memoryview(b"HIERARCHY\n")) == ".bvh"
    mpz.io.write(m, tmp_path / "m.trc")
    assert mpz.io.read_bytes(memoryview((tmp_path / "m.trc").read_bytes())).n_frames == 10
    (tmp_path / "x.trc").mkdir()
    with pytest.raises(InputFormatError, match="a folder has that name"):
        mpz.io.write(m, tmp_path / "x.trc")


# -- a QA of the Python API (stop 42) --------------------------------------------------------

DOCUMENTED = ["mpz", "mpz.api", "mpz.io", "mpz.encoder", "mpz.decoder", "mpz.corpus",
              "mpz.motion", "mpz.synth", "mpz.similarity", "mpz.metrics", "mpz.fisher",
              "mpz.io._common", "mpz.io.bvh", "mpz.io.kinematics"]


@pytest.mark.parametrize("name", DOCUMENTED)
def test_the_docstring_examples_run_as_written(name):
    """mpz.io's example printed the [] that write returns where it showed nothing: a
    reader copying it saw a failure. Every public module's examples run."""
    import doctest
    import importlib
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.failed == 0, result


def test_a_motion_refuses_a_str_of_names_and_ragged_positions():
    """Motion(..., "LFHD") had four markers L, F, H, D; ragged lists gave numpy's own
    ValueError."""
    from mpz.errors import MotionError
    with pytest.raises(MotionError, match="names must be a sequence of str"):
        Motion(np.zeros((2, 4, 3)), "LFHD", rate=100.0)
    for names in (None, 4):                  # a bare TypeError, "not iterable" (QA, stop 47)
        with pytest.raises(MotionError, match="names must be a sequence of str"):
            Motion(np.zeros((2, 4, 3)), names, rate=100.0)  # type: ignore[arg-type]
    with pytest.raises(MotionError, match=r"shape \(frames, markers, 3\)"):
        Motion([[[0.0, 0.0, 0.0]], [[0.0, 0.0]]], ["A"], rate=100.0)


def test_besides_markers_checks_its_arguments_and_the_rate():
    """channel_bounds of -1 or NaN made every channel 'differ', a str gave a TypeError deep
    inside, None an AttributeError; a motion at half the rate came back 'same'."""
    import dataclasses

    from mpz.metrics import besides_markers
    m = Motion(np.zeros((3, 2, 3)), ["A", "B"], rate=120.0)
    for bad in ((-1.0, 1.0), (float("nan"), 1.0), ("1", 1.0), (1.0,), 1.0):
        with pytest.raises(ValueError, match="channel_bounds must be two finite numbers"):
            besides_markers(m, m, channel_bounds=bad)
    with pytest.raises(TypeError, match="decoded must be an mpz.Motion"):
        besides_markers(m, None)
    assert besides_markers(m, m, channel_bounds=(0.0, 0.0)) == []
    (rate,) = besides_markers(m, dataclasses.replace(m, rate=60.0))
    assert (rate.name, rate.status, rate.detail) == ("rate", "differs", "60 Hz against 120 Hz")


def test_bad_corpus_workers_and_a_str_of_mpz_bytes_are_refused_at_once(tmp_path):
    """encode_corpus(workers=-1) waited 60 s, then blamed the memory limit; a file's bytes
    decoded to str were taken for a path ('embedded null byte')."""
    import time

    from mpz.corpus import encode_corpus
    t0 = time.monotonic()
    with pytest.raises(ValueError, match="workers must be an int >= 0"):
        encode_corpus([], tmp_path / "out", workers=-1)
    assert time.monotonic() - t0 < 5
    with pytest.raises(TypeError, match="jobs must be a sequence of"):
        encode_corpus(str(tmp_path), tmp_path / "out", workers=0)       # a folder's name
    with pytest.raises(TypeError, match="options must be EncodeOptions"):
        encode_corpus([], tmp_path / "out", {"max_error": 1.0}, workers=0)  # type: ignore
    (tmp_path / "afile").write_text("x")
    with pytest.raises(EncoderError, match="not a folder"):
        encode_corpus([], tmp_path / "afile", workers=0)
    rep = encode_corpus(iter([]), tmp_path / "out", workers=0)      # an iterator: fine
    assert rep.results == []
    data = mpz.encode(Motion(np.zeros((2, 1, 3)), ["A"], rate=10.0), max_error=1.0)
    with pytest.raises(TypeError, match="pass the MPZ data as bytes"):
        mpz.decode(data.decode("latin-1"))


@pytest.mark.parametrize("kw, said", [
    ({"seed": "a"}, "seed must be a whole number, got 'a'"),
    ({"seed": -1}, "seed must be at least 0, got -1"),
    ({"frames": "10"}, "frames must be a whole number, got '10'"),
    ({"frames": 2.5}, "frames must be a whole number, got 2.5"),
    ({"markers": 3.0}, "markers must be a whole number, got 3.0"),
])
def test_generate_refuses_what_is_not_a_whole_number(kw, said):
    """A QA run of stop 48: frames="10" was taken, 2.5 cut to 2, and a seed of "a" or -1
    failed inside numpy (TypeError, ValueError) where the docs promise MotionError."""
    from mpz.errors import MotionError
    from mpz.synth import generate
    with pytest.raises(MotionError, match=re.escape(said)):
        generate("walk", **kw)
    assert generate("walk", frames=np.int64(12), seed=np.int32(3)).n_frames == 12


def test_select_frames_refuses_bounds_that_are_not_whole_numbers():
    """A QA run of stop 48: select_frames(0.5, 3) and ("a", 3) raised numpy's TypeError."""
    from mpz.errors import MotionError
    from mpz.synth import generate
    m = generate("walk", frames=20)
    for bounds in ((0.5, 3), ("a", 3), (0, True)):
        with pytest.raises(MotionError, match="must be a whole number or None"):
            m.select_frames(*bounds)
    with pytest.raises(MotionError, match=r"select_frames\(5, 5\) holds no frame of the 20"):
        m.select_frames(5, 5)
    part = m.select_frames(-3, None)
    assert part.n_frames == 3 and np.array_equal(part.positions, m.positions[17:],
                                                 equal_nan=True)


@pytest.mark.parametrize("kw, said", [
    ({"parents": 5}, "parents must be a sequence of int"),
    ({"parents": ["a"]}, "parents must be whole indices, got 'a'"),
    ({"parents": [None]}, "parents must be whole indices, got None"),
    ({"parents": [0.7]}, "parents must be whole indices, got 0.7"),
    ({"parents": [0]}, "parents loop: marker 0 is its own ancestor"),
    ({"angles": [["x"], ["y"]]}, "angles must be real numbers"),
    ({"angles": [[1], [1, 2]]}, "angles must be an array of shape"),
    ({"angles": np.ones((2, 1)) * 1j}, "angles must be real numbers, got dtype complex128"),
    ({"angle_names": ["a"]}, "angle_names without angles"),
    ({"angles": np.ones((2, 1)), "angle_names": ["a", "b"]}, "2 angle_names for 1"),
    ({"extras": None}, "extras must be a mapping of str keys"),
    ({"extras": [1]}, "extras must be a mapping of str keys"),
    ({"rate": 10 ** 400}, "frame rate must be finite and positive"),
])
def test_motion_refuses_bad_parents_angles_extras_and_rate(kw, said):
    """A QA run of the library (stop 50): these raised TypeError, ValueError or
    OverflowError of their own, or were taken (0.7 as parent 0, a loop, complex angles
    without their imaginary part, names for channels that do not exist)."""
    kw = dict(kw)
    rate = kw.pop("rate", 1.0)
    with pytest.raises(MotionError, match=re.escape(said)):
        Motion(np.zeros((2, 1, 3)), ["A"], rate, **kw)


def test_motion_takes_a_two_level_skeleton():
    m = Motion(np.zeros((2, 3, 3)), ["R", "A", "B"], 1.0, parents=[-1, 0, np.int64(1)],
               angles=np.zeros((2, 2), np.float32), angle_names=["x", "y"])
    assert m.parents == [-1, 0, 1] and m.angles.dtype == np.float64


def test_wrong_argument_types_are_type_errors_not_attribute_errors(tmp_path):
    """A QA run of the library (stop 50): None for a motion or a hierarchy raised
    AttributeError deep inside; generate(rate="x") a bare ValueError of float(); frames
    of 10**9 ran until the kernel ended the process; Summary.level('2') a KeyError."""
    from mpz.hierarchy import write_hierarchy
    from mpz.io import check_writable, read_bytes
    from mpz.skeleton import with_joint_positions
    with pytest.raises(TypeError, match="expected an mpz.Motion, got NoneType"):
        check_writable(None, ".trc")
    with pytest.raises(TypeError, match="expected an mpz.Motion, got NoneType"):
        with_joint_positions(None)
    with pytest.raises(TypeError, match="expected an mpz Hierarchy, got NoneType"):
        write_hierarchy(None, tmp_path / "h.json", ["A"])
    for kw, said in (({"frames": 10 ** 9}, "frames must be at most 16777216"),
                     ({"rate": "x"}, "rate must be a number, got 'x'"),
                     ({"gap_fraction": None}, "gap_fraction must be a number")):
        with pytest.raises(MotionError, match=said):
            generate(**kw)
    summary = mpz.read_summary(mpz.encode(generate("walk", frames=60), summary=[2, 4]))
    with pytest.raises(TypeError, match=r"k must be an int \(a number of segments\), got .2."):
        summary.level("2")
    assert summary.level(np.int64(2)).k == 2
    m = generate("walk", frames=3)
    assert check_writable(m, ".TRC") == check_writable(m, ".trc")   # as write(m, "Z.TRC")
    with pytest.raises(ValueError, match="fmt must be an extension with its dot"):
        read_bytes(b"PathFileType\t4", fmt="trc")


def test_write_atomic_takes_force_as_a_bool_only(tmp_path):
    """write_atomic(p, data, force="no") replaced the file (a QA run of stop 50)."""
    p = tmp_path / "x.mpz"
    p.write_bytes(b"old")
    with pytest.raises(TypeError, match="force must be True or False, got 'no'"):
        mpz.write_atomic(p, b"new", force="no")
    assert p.read_bytes() == b"old"


def test_a_hierarchy_fifo_and_a_bytes_output_path_are_named_for_what_they_are(tmp_path):
    """A QA run of the library (stop 50): hierarchy=<a FIFO> said "does not exist", and
    write_mpz(m, b"/tmp/x.mpz") raised "Can't mix strings and bytes in path components"."""
    import os
    fifo = tmp_path / "h.json"
    os.mkfifo(fifo)
    m = generate("walk", frames=10)
    with pytest.raises(EncoderError, match="is not a regular file"):
        mpz.encode(m, hierarchy=str(fifo))
    with pytest.raises(TypeError, match="output path must be a str or an os.PathLike"):
        mpz.write_mpz(m, os.fsencode(tmp_path / "x.mpz"))
    assert not (tmp_path / "x.mpz").exists()


def test_any_bytes_like_object_is_a_source():
    """A QA run of the library (stop 50): array.array('B', data) was "expected a path, bytes
    or a binary file object, got array", while a NumPy uint8 array and a memoryview were
    taken; an array of wider items is refused, not read as its raw bytes."""
    import array
    data = mpz.encode(generate("walk", frames=20), max_error=1.0)
    assert mpz.info(array.array("B", data)).frames == 20
    assert mpz.decode(array.array("b", data)).n_frames == 20
    with pytest.raises(TypeError, match="must be single bytes"):
        mpz.decode(array.array("I", data[:len(data) // 4 * 4]))


def test_markers_only_decodes_as_a_1_0_decoder(two_joint_bvh, tmp_path):
    """A data loader training on markers paid for a C3D archive's analog data on every
    decode, about 90 % of it (an ML pipeline's QA run of stop 51). markers_only=True
    decodes as a 1.0 decoder (spec §2.1): the same markers, names, rate and units; the
    1.1 chunks are skipped unread, so a broken one inside goes unseen, as for a 1.0
    decoder; a full decode still refuses it."""
    from mpz.container import build, scan
    from mpz.errors import MPZError
    import mpz.io
    from mpz.tools.make_vectors import c3d_motion
    (tmp_path / "arm.bvh").write_text(two_joint_bvh)
    for m in (c3d_motion(5, storage=1, F=12, M=4, J=2, C=2, n=2),
              mpz.io.read(tmp_path / "arm.bvh")):
        data = mpz.encode(m, max_error=1.0, summary=[2], summary_format="smrc")
        full, marks = mpz.decode(data), mpz.decode(data, markers_only=True)
        assert np.array_equal(full.positions, marks.positions, equal_nan=True)
        assert (full.names, full.rate, full.units) == (marks.names, marks.rate, marks.units)
        assert full.extras and not marks.extras and marks.angles is None
        # a 1.1 chunk whose payload breaks its rules (CRC repaired): skipped unread
        chunks = scan(data).chunks
        bad = next(c for c in chunks if c.type in ("cpnt", "bvhs"))
        payload = bytearray(bad.payload)
        payload[0] ^= 0xFF
        broken = build([(c.type, bytes(payload) if c is bad else c.payload) for c in chunks])
        with pytest.raises(MPZError):
            mpz.decode(broken)
        assert np.array_equal(mpz.decode(broken, markers_only=True).positions,
                              marks.positions, equal_nan=True)
    with pytest.raises(TypeError, match="markers_only must be True or False"):
        mpz.decode(data, markers_only="yes")


@pytest.mark.parametrize("kind", [np.float16, np.float32, np.longdouble])
def test_numpy_scalar_options_encode_as_the_python_number(kind) -> None:
    """A numpy scalar option is the number it holds: a np.float16 max_error made the
    encoder's arithmetic float16, and the bound it declared was broken by up to 1.00025x
    on a real file; np.float32 gave other bytes than float(x) (a QA run of the API, stop
    54). The options and the report hold Python numbers."""
    m = generate("walk", frames=60, seed=3)
    for v in (1.1171875, 5.5, 0.3):
        x = kind(v)
        opts = mpz.EncodeOptions(max_error=x, group_errors={"head": x}, theta=kind(0.2),
                                 k0=np.int16(10), summary=(np.int64(3),))
        assert type(opts.max_error) is float and type(opts.group_errors["head"]) is float
        assert type(opts.theta) is float and type(opts.k0) is int
        assert type(opts.summary[0]) is int
        assert mpz.EncodeOptions(lossy=np.False_, keep_skeleton=np.True_).lossy is False
        data, report = mpz.encode_motion(m, opts)
        plain, _ = mpz.encode_motion(m, mpz.EncodeOptions(
            max_error=float(x), group_errors={"head": float(x)}, summary=(3,)))
        assert data == plain
        assert type(report.step) is float and type(report.bound) is float
        err = np.linalg.norm(mpz.decode(data).positions - m.positions, axis=2)[m.valid]
        assert err.max() <= float(x)


def test_write_refuses_an_asf_it_would_lose(tmp_path: Path, one_bone_asf) -> None:
    """``asf=`` the AMC output itself: the AMC replaced its skeleton, silently, and the
    AMC could not be read back; ``asf=`` with another format was ignored (a QA run of the
    API, stop 54; the CLI refused both)."""
    from mpz.io import read, write
    (tmp_path / "src.asf").write_text(one_bone_asf())
    (tmp_path / "src.amc").write_text(":FULLY-SPECIFIED\n:DEGREES\n1\nroot 0 0 0 0 0 0\n"
                                      "b1 10 20\n2\nroot 1 0 0 0 0 0\nb1 15 25\n")
    m = read(tmp_path / "src.amc")
    out = tmp_path / "c.amc"
    with pytest.raises(ValueError, match="is the AMC output itself"):
        write(m, out, asf=out)
    with pytest.raises(ValueError, match="is the AMC output itself"):
        write(m, out, asf=tmp_path / "." / "c.amc")
    assert not out.exists()
    with pytest.raises(ValueError, match="asf is where an AMC's ASF skeleton goes"):
        write(m, tmp_path / "c.trc", asf=tmp_path / "c.asf")
    assert write(m, out, asf=tmp_path / "c.asf") is not None
    assert read(out, asf=tmp_path / "c.asf").n_frames == m.n_frames


def test_a_set_of_names_is_refused() -> None:
    """A set's order changes with PYTHONHASHSEED: the markers got other names on another
    process (a QA run of the API, stop 54)."""
    pos = np.zeros((2, 3, 3))
    for names in ({"C7", "LFHD", "RFHD"}, frozenset({"C7", "LFHD", "RFHD"})):
        with pytest.raises(MotionError, match="a set has no order"):
            Motion(pos, names, 100.0)
    assert Motion(pos, {"C7": 0, "LFHD": 1, "RFHD": 2}, 100.0).names == ["C7", "LFHD", "RFHD"]


@pytest.mark.parametrize("attr,value,said", [
    ("valid", None, "valid is a NoneType"),
    ("positions", [[[0.0, 0.0, 0.0]]], "positions is a list"),
    ("valid", np.ones((2, 2)), "valid is a ndarray of float64"),
    ("metadata", {"n": 5}, "the value of 'n' is int"),
])
def test_a_motion_changed_after_it_was_made_is_refused_by_encode_and_write(
        tmp_path: Path, attr: str, value: object, said: str) -> None:
    """``m.valid = None`` made mpz.encode raise TypeError and mpz.io.write AttributeError
    (a QA run of the API, stop 54): both now say what is wrong."""
    from mpz.io import write
    m = generate("walk", frames=20, seed=1)
    setattr(m, attr, value)
    with pytest.raises(EncoderError, match=f"not consistent.*{said}"):
        mpz.encode(m)
    with pytest.raises(MotionError, match=said):
        write(m, tmp_path / "x.trc")
    assert not (tmp_path / "x.trc").exists()


def test_a_reader_rate_past_binary64_is_a_value_error(tmp_path: Path) -> None:
    """``read(p, rate=10**400)`` raised a raw OverflowError (a QA run of the API, stop 54);
    the docs promise ValueError for a bad rate."""
    from mpz.io import read, write
    path = tmp_path / "m.npy"
    write(generate("walk", frames=5), path)
    with pytest.raises(ValueError, match="rate must be a finite number"):
        read(path, rate=10 ** 400)


def test_generate_refuses_a_motion_too_long_to_make() -> None:
    """``generate(frames=50, rate=1e-9)`` asked numpy for 329 GiB (MemoryError, a QA run of
    the API, stop 54): 5e10 s of motion, whose random functions hold a knot a second."""
    from mpz.synth import MAX_SECONDS
    with pytest.raises(MotionError, match="frames / rate must be at most"):
        generate("walk", frames=50, rate=1e-9)
    assert MAX_SECONDS >= 2 ** 24                       # MAX_FRAMES at 1 Hz is allowed
    assert generate("walk", frames=3, rate=1e-6).n_frames == 3


def test_an_unknown_group_error_node_is_not_blamed_on_the_default_bound() -> None:
    """A misspelled node in ``group_errors`` was told to "give a max_error these
    coordinates allow" (a QA run of the API, stop 54)."""
    m = generate("walk", frames=30)
    with pytest.raises(EncoderError, match="unknown node 'nosuch'") as err:
        mpz.encode(m, group_errors={"nosuch": 1.0})
    assert "default bound" not in str(err.value) and "max_error" not in str(err.value)


def test_options_that_do_less_than_they_seem_are_in_the_report() -> None:
    """A group error looser than the bound, and channel bounds where no skeleton chunk is
    written, were accepted by the library without a word (a QA run of the API, stop 72;
    mpz encode noted the first only against a bound it was given). EncodeReport.notes
    names each, in the API's spelling, against the bound the file declares."""
    from mpz.encoder import EncodeOptions, encode_motion, option_notes
    m = generate("walk", frames=40, seed=3)
    assert m.units == "mm"
    nodes = [n.name for n in encode_motion(m, EncodeOptions(max_error=1.0,
                                                            hierarchy="auto"))[1].nodes]
    a, b = nodes[0], nodes[1]
    opts = EncodeOptions(max_error=1.0, hierarchy="auto", group_errors={a: 2.0, b: 0.5})
    _, rep = encode_motion(m, opts)
    assert rep.notes == [f"group_errors[{a!r}]: 2 is not tighter than the bound 1, so it "
                         "bounds that node no more tightly (a node is coded within the "
                         "smaller of the two)"]
    assert option_notes(m, opts) == rep.notes          # the same, before any encode
    # without max_error, against the default bound the file declares (0.1 mm)
    _, rep = encode_motion(m, EncodeOptions(hierarchy="auto", group_errors={a: 0.1}))
    assert rep.bound == pytest.approx(0.1) and len(rep.notes) == 1
    assert "not tighter than the bound 0.1," in rep.notes[0]
    _, rep = encode_motion(m, EncodeOptions(hierarchy="auto", group_errors={a: 0.05}))
    assert rep.notes == []
    # channel bounds on a motion without a skeleton, or with keep_skeleton=False
    _, rep = encode_motion(m, EncodeOptions(angle_error=0.1, translation_error=0.2))
    assert rep.notes == ["angle_error and translation_error change nothing: no skeleton "
                         "chunk is written (the motion has no skeleton), so no channel is "
                         "coded"]
    sk = _skeletal_source()
    _, rep = encode_motion(sk, EncodeOptions(angle_error=0.1, keep_skeleton=False))
    assert rep.notes == ["angle_error changes nothing: no skeleton chunk is written "
                         "(keep_skeleton=False), so no channel is coded"]
    _, rep = encode_motion(sk, EncodeOptions(angle_error=0.1))
    assert rep.notes == []


def test_group_errors_on_an_exact_int16_grid_are_said_to_bound_nothing() -> None:
    """Every sample of an int16 source on its grid is coded exactly (error 0) by default or
    under a bound finer than the grid allows: group errors then bound nothing, whatever
    their node, named or not."""
    from mpz.encoder import EncodeOptions, encode_motion
    m = generate("walk", frames=30, seed=4)
    step = 0.25
    m.positions[:] = np.rint(m.positions / step) * step
    for opts in (EncodeOptions(source_grid=step, group_errors={"nosuch": 1.0}),
                 EncodeOptions(source_grid=step, max_error=0.01,
                               group_errors={"nosuch": 1.0})):
        data, rep = encode_motion(m, opts)
        assert rep.notes == ["group_errors bound nothing: every position is coded exactly "
                             "on the source's grid of step 0.25 (error 0)"], rep.notes
        back = mpz.decode(data)
        assert np.array_equal(back.positions[m.valid], m.positions[m.valid])
    # a group error below the grid's rounding is what makes the file exact: no such note
    nodes = [n.name for n in encode_motion(m, EncodeOptions(
        source_grid=step, max_error=1.0, hierarchy="auto"))[1].nodes]
    _, rep = encode_motion(m, EncodeOptions(source_grid=step, max_error=1.0,
                                            hierarchy="auto", group_errors={nodes[0]: 0.01}))
    assert rep.bound == 1.0 and rep.notes == [], rep.notes


def test_write_atomic_names_the_python_argument_that_replaces(tmp_path):
    """mpz.write_atomic(path, data, force=False) on an existing file said only "use
    --force", an option of the commands that a Python caller does not have (a QA run of
    the API, stop 54); it then said both, "use --force (force=True)", to either reader (a
    newcomer's QA run, stop 62): a program is told force=True alone, and the file is kept."""
    from mpz.errors import EncoderError
    path = tmp_path / "a.mpz"
    path.write_bytes(b"old")
    with pytest.raises(EncoderError, match=r"exists; pass force=True to replace it$"):
        mpz.write_atomic(path, b"new", force=False)
    with pytest.raises(mpz.io.InputFormatError, match=r"given with asf=\)$"):
        mpz.io.read_bytes(b":version 1.10\n:name x\n")
    assert path.read_bytes() == b"old"
    mpz.write_atomic(path, b"new", force=True)
    assert path.read_bytes() == b"new"


def test_a_command_run_any_way_spells_its_options(tmp_path, capsys):
    """The command line's spelling (--force, --asf PATH) was chosen by the console script's
    name alone: `python -m mpz.tools.mpz_cli`, `main([...])` in a program and the workers of
    `--scheduler` were told force=True and asf= (the review of stop 62)."""
    import subprocess
    import sys

    from mpz import _worker
    from mpz.tools import mpz_cli
    src = tmp_path / "w.trc"
    mpz.io.write(generate("walk", frames=12, seed=1), src)
    (tmp_path / "w.mpz").write_bytes(b"old")
    p = subprocess.run([sys.executable, "-m", "mpz.tools.mpz_cli", "encode", str(src), "-o",
                        str(tmp_path / "w.mpz")], capture_output=True, text=True, timeout=300)
    assert p.returncode == 2 and "exists; use --force to replace it" in p.stderr, p.stderr
    assert mpz_cli.main(["encode", str(src), "-o", str(tmp_path / "w.mpz")]) == 2
    assert "exists; use --force to replace it" in capsys.readouterr().err
    assert _worker.spelled("--force", "force=True") == "force=True"   # main() is over
    with _worker.command_task(True):                 # a corpus task a command sent
        assert _worker.spelled("--force", "force=True") == "--force"
    assert _worker.spelled("--force", "force=True") == "force=True"


def _skeletal_source() -> Motion:
    """A small BVH read through mpz.io (no shared data needed)."""
    import tempfile
    text = ("HIERARCHY\nROOT hip\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition "
            "Zrotation Xrotation Yrotation\n JOINT knee\n {\n  OFFSET 0 -10 0\n  CHANNELS 3 "
            "Zrotation Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 -10 0\n  }\n }\n}\n"
            "MOTION\nFrames: 4\nFrame Time: 0.0333333\n"
            + "".join(f"{i} 90 {i} {5 * i} 0 0 {10 * i} 0 0\n" for i in range(4)))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "two.bvh"
        path.write_text(text)
        return mpz.io.read(path)


def test_a_skeleton_extra_of_the_wrong_type_is_an_encoder_error() -> None:
    """extras["skeleton"] that is not a Skeleton, on a motion with angles: an EncoderError
    naming it, as without angles. Before, AttributeError ('str' object has no attribute
    'joints') from the extension's limit check, which ran before its type check (an ML
    pipeline's QA run of the API)."""
    src = _skeletal_source()
    bad = Motion(src.positions, src.names, src.rate, src.units, angles=src.angles,
                 angle_names=src.angle_names, parents=src.parents, extras={"skeleton": "x"})
    with pytest.raises(EncoderError, match=r"motion.extras\['skeleton'\] is a str"):
        mpz.encode(bad, max_error=1.0)


def test_parents_that_the_file_does_not_keep_are_named() -> None:
    """A motion built with ``parents`` and no skeleton decodes without them: not_kept says
    so. Before, it was empty ("everything is kept") and the parents were lost silently."""
    m = generate("walk", frames=12, markers=4)
    m = Motion(m.positions, m.names, m.rate, m.units, parents=[-1, 0, 1, 2])
    data, report = mpz.encode_motion(m, mpz.EncodeOptions(max_error=1.0))
    assert mpz.decode(data).parents is None
    assert any("parents" in s for s in report.not_kept)
    src = _skeletal_source()
    assert mpz.encode_motion(src, mpz.EncodeOptions(max_error=1.0))[1].not_kept == []


def test_a_frame_cut_keeps_the_skeleton_and_gives_the_joints_of_its_frames() -> None:
    """A cut of a decoded skeletal motion keeps its skeleton with its angles: its joints
    are the whole motion's joints of those frames, and it encodes with its skeleton. It
    was dropped (an ML pipeline's QA run of the API): the cut gave no joint positions, and
    ``mpz.encode`` of it wrote a file of markers alone."""
    from mpz.skeleton import with_joint_positions
    back = mpz.decode(mpz.encode(_skeletal_source(), max_error=1.0))
    cut = back.select_frames(1, 3)
    assert cut.extras["skeleton"] is back.extras["skeleton"]
    np.testing.assert_array_equal(with_joint_positions(cut).positions,
                                  with_joint_positions(back).positions[1:3])
    data, report = mpz.encode_motion(cut, mpz.EncodeOptions(max_error=1.0))
    assert report.not_kept == []
    again = mpz.decode(data)
    assert again.angles is not None and again.extras["skeleton"].convention == "bvh"
    np.testing.assert_allclose(again.angles, cut.angles, atol=0.01)
    # angles whose skeleton was taken away: named, not three causes that do not apply
    import dataclasses
    with pytest.raises(MotionError, match=r"angles but no skeleton"):
        with_joint_positions(dataclasses.replace(back, extras={}))


def test_a_frame_cut_of_an_amc_keeps_its_frame_numbers(tmp_path: Path, one_bone_asf) -> None:
    """The cut's AMC is written with the source's frame numbers (its skeleton's first
    frame moves with the cut, as a TRC's FirstFrame does), and back through a file."""
    from mpz.io import read, write
    (tmp_path / "src.asf").write_text(one_bone_asf())
    (tmp_path / "src.amc").write_text(":FULLY-SPECIFIED\n:DEGREES\n" + "".join(
        f"{7 + i}\nroot {i} 0 0 0 0 0\nb1 {10 + i} 20\n" for i in range(5)))
    m = read(tmp_path / "src.amc")
    cut = m.select_frames(2, 4)
    assert cut.extras["skeleton"].first_frame == 9
    write(mpz.decode(mpz.encode(cut)), tmp_path / "cut.amc", asf=tmp_path / "cut.asf")
    text = (tmp_path / "cut.amc").read_text()
    assert "\n9\nroot 2" in text and "\n10\nroot 3" in text and "\n8\n" not in text
    assert m.select_frames(0, 2).extras["skeleton"].first_frame == 7


def test_a_frame_cut_names_the_c3d_archive_it_does_not_carry(tmp_path: Path) -> None:
    """A C3D archive belongs to the source's frames: a cut leaves it, and says so in the
    list that encode_motion reports (it was dropped without a word); what the reader did
    not keep and a key no extension owns are named too."""
    from mpz.io import read, write
    write(generate("walk", frames=12, markers=4), tmp_path / "w.c3d")
    m = read(tmp_path / "w.c3d")
    assert "c3d" in m.extras
    m.extras["mine"] = 1
    m.extras["not_kept"] = ["the reader's own note"]
    cut = m.select_frames(3, 6)
    assert "c3d" not in cut.extras and "mine" not in cut.extras
    kept = mpz.encode_motion(cut, mpz.EncodeOptions(max_error=1.0))[1].not_kept
    assert kept[0] == "the reader's own note"
    assert any(s.startswith("the C3D archive (analog data") and "cut" in s for s in kept)
    assert any("motion.extras['mine']" in s for s in kept)


def test_a_program_is_told_of_arguments_and_an_empty_input_as_such(tmp_path: Path) -> None:
    """A QA run of the API: a program was told of the command's options (--angle-error,
    ``mpz decode FILE.mpz -o``), and of "bad signature b''" for an empty stream (one that
    ``mpz.info`` had read to its end)."""
    from mpz.errors import FormatError
    with pytest.raises(EncoderError) as fine:
        mpz.encode(_skeletal_source(), angle_error=1e-12)
    assert "angle_error" in str(fine.value) and "--angle-error" not in str(fine.value)
    with pytest.raises(EncoderError) as named:
        mpz.api.write_mpz(generate("walk", frames=8, markers=3), tmp_path / "x.c3d")
    assert "mpz.io.write(mpz.decode(data)" in str(named.value)
    assert "mpz decode" not in str(named.value)
    for empty in (b"", io.BytesIO(b"")):
        with pytest.raises(FormatError, match=r"bad signature \(no bytes: an empty file, or a "
                                              r"stream read to its end\)"):
            mpz.decode(empty)


def test_the_public_functions_type_hints_resolve_at_run_time():
    """mpz.decode, read_mpz, write_mpz and Summary.preview named Motion and EncodeReport
    only under TYPE_CHECKING, so typing.get_type_hints raised NameError, and the tools that
    read hints at run time (pydantic's validate_call, typer, beartype) failed on them (an
    API user's QA run of stop 72). Every public function of the top-level package and
    every public method of its public classes resolves now."""
    import typing
    failed = []
    for name in mpz.__all__ if hasattr(mpz, "__all__") else dir(mpz):
        obj = getattr(mpz, name)
        if name.startswith("_") or inspect.ismodule(obj):
            continue
        found = [obj] if not inspect.isclass(obj) else [
            v for k, v in vars(obj).items() if not k.startswith("_") and callable(v)]
        for f in found:
            if callable(f) and (getattr(f, "__module__", "") or "").startswith("mpz"):
                try:
                    typing.get_type_hints(f)
                except NameError as exc:
                    failed.append(f"{name}.{getattr(f, '__name__', '')}: {exc}")
    assert not failed, failed


def test_api_messages_from_a_users_qa(tmp_path):
    """An API user's QA run of stop 72: a bad ``units`` argument was blamed on the file
    (InputFormatError "inconsistent data"), where a bad ``rate`` is a ValueError;
    read_bytes listed .mpz among what it reads, then refused MPZ content; and write_mpz to
    a .asf name advised ``mpz.io.write(..., 'x.asf')``, which refuses .asf."""
    import mpz.io
    np.save(tmp_path / "a.npy", np.zeros((4, 2, 3)))
    with pytest.raises(ValueError, match="units must be one of 'mm', 'cm', 'm', 'in', ''"):
        mpz.io.read_npy(tmp_path / "a.npy", units="MM")
    (tmp_path / "a.csv").write_text("frame,time,A_x,A_y,A_z\n0,0,1,2,3\n1,0.01,1,2,3\n")
    with pytest.raises(ValueError, match="units must be one of"):
        mpz.io.read_csv(tmp_path / "a.csv", units=None)    # type: ignore[arg-type]
    assert mpz.io.read_csv(tmp_path / "a.csv", units="cm").units == "cm"
    with pytest.raises(InputFormatError, match="can read .c3d, .trc, .bvh, .amc, .npy, "
                                               ".csv, and MPZ content is read by mpz.decode"):
        mpz.io.read_bytes(b"")
    with pytest.raises(InputFormatError, match="decode it with mpz.decode"):
        mpz.io.read_bytes(mpz.encode(generate("walk", frames=10)))
    with pytest.raises(EncoderError, match=r"mpz.io.write\(mpz.decode\(data\), '.*u.amc'\), "
                                           "which writes the ASF beside the AMC"):
        mpz.write_mpz(generate("walk", frames=10), tmp_path / "u.asf")


def test_a_closed_or_write_only_file_object_is_a_typeerror(tmp_path):
    """mpz.decode of a closed file object raised io's ValueError, and of one open for
    writing io.UnsupportedOperation; the API documents TypeError for a source it cannot
    take, as for a text file object (an API user's QA run of stop 72)."""
    path = tmp_path / "w.mpz"
    path.write_bytes(mpz.encode(generate("walk", frames=10)))
    with open(path, "ab") as fh, pytest.raises(TypeError, match="open for writing .mode 'ab'"):
        mpz.decode(fh)
    fh = open(path, "rb")
    fh.close()
    for call in (mpz.decode, mpz.info, mpz.read_summary):
        with pytest.raises(TypeError, match="a closed file object"):
            call(fh)
    with open(path, "rb") as fh:
        assert mpz.decode(fh).n_frames == 10


def test_consecutive_cuts_of_a_trc_motion_join_back(tmp_path: Path) -> None:
    """select_frames moves start_time and trc.FirstFrame, so two consecutive cuts of a TRC
    motion were refused by concatenate ("metadata differ at 'start_time'": an API QA run
    of stop 74). Cuts that each start where the one before ends join, to the motion they
    were cut from; cuts that do not are refused as before."""
    from mpz.io import read, write
    write(generate("walk", frames=60, seed=3), tmp_path / "w.trc")
    m = read(tmp_path / "w.trc")
    assert "start_time" in m.metadata and "trc.FirstFrame" in m.metadata
    parts = [m.select_frames(0, 20), m.select_frames(20, 45), m.select_frames(45, None)]
    joined = mpz.concatenate(parts)
    assert joined.metadata == m.metadata
    assert np.array_equal(joined.positions, m.positions, equal_nan=True)
    tail = m.select_frames(20, 40)
    assert mpz.concatenate([tail, m.select_frames(40, None)]).metadata == tail.metadata
    with pytest.raises(MotionError, match="metadata differ at .*starts where the one"):
        mpz.concatenate([parts[0], parts[2]])              # a gap of 25 frames between


def test_consecutive_cuts_of_an_amc_motion_join_back(shared_data: Path) -> None:
    """The same for an AMC, whose skeleton's first frame number moves with a cut."""
    from mpz.io import read
    m = read(shared_data / "amc" / "35_01.amc")
    parts = [m.select_frames(0, 100), m.select_frames(100, 250), m.select_frames(250, 300)]
    joined, want = mpz.concatenate(parts), m.select_frames(0, 300)
    assert joined.extras["skeleton"] == want.extras["skeleton"]
    assert joined.angles is not None and want.angles is not None
    assert np.array_equal(joined.angles, want.angles)
    with pytest.raises(MotionError, match=r"extras\['skeleton'\] differ at 'first_frame'"):
        mpz.concatenate([parts[0], parts[2]])


def test_write_mpz_takes_encode_s_keywords_with_their_types(tmp_path):
    """``write_mpz``'s options were typed ``Any``, so a misspelt or mistyped option passed a
    type checker (an API user's QA run of stop 74), and a mapping given as None, which
    ``encode`` takes as empty, was refused ("group_errors must be a mapping"). They are
    typed as :class:`mpz.encoder.EncodeKeywords`, whose names and types must be
    ``encode``'s, and passed on as ``encode`` takes them."""
    import typing

    from mpz.encoder import EncodeKeywords
    hints = typing.get_type_hints(mpz.encode)
    keywords = {n: hints[n] for n, p in inspect.signature(mpz.encode).parameters.items()
                if p.kind is inspect.Parameter.KEYWORD_ONLY}
    assert typing.get_type_hints(EncodeKeywords) == keywords
    assert typing.get_type_hints(mpz.write_mpz)["options"] == typing.Unpack[EncodeKeywords]
    m = generate("walk", frames=12, markers=5, seed=3)
    given = {"max_error": 1.0, "group_errors": None, "metadata": None, "model_errors": None,
             "weights": None}
    mpz.write_mpz(m, tmp_path / "w.mpz", **given)
    assert (tmp_path / "w.mpz").read_bytes() == mpz.encode(m, max_error=1.0)
    with pytest.raises(EncoderError, match="unknown option max_eror; did you mean max_error"):
        mpz.write_mpz(m, tmp_path / "x.mpz", max_eror=1.0)  # type: ignore[call-arg]
    assert not (tmp_path / "x.mpz").exists()


def test_decode_s_hint_takes_the_uint8_array_it_reads():
    """``decode`` reads a uint8 numpy array of MPZ bytes, and its hint said it did not (an
    API user's QA run of stop 74)."""
    import typing
    source = typing.get_type_hints(mpz.decode)["source"]
    arrays = [a for a in typing.get_args(source) if typing.get_origin(a) is np.ndarray]
    assert len(arrays) == 1 and typing.get_args(typing.get_args(arrays[0])[1]) == (np.uint8,)
    data = mpz.encode(generate("walk", frames=10))
    assert np.array_equal(mpz.decode(np.frombuffer(data, np.uint8)).positions,
                          mpz.decode(data).positions)
