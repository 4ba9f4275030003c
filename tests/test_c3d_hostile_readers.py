"""C3D files that contradict themselves (found by a QA run of mutated files): each is read
with a warning in ``metadata["warning"]`` or refused with an InputFormatError that says
what is wrong, never a crash of ezc3d, a leaked internal exception or a silent misread.

The files are built from the synthetic generator (``make_vectors.c3d_motion`` written by
``archive_bytes``) and then edited byte by byte, or from the real recordings when
``../shared/data`` is present. A run that can crash the process (ezc3d) is in a
subprocess, so that a segmentation fault fails the test instead of ending the run.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
import struct
import subprocess
import sys
import types
import warnings

from hypothesis import example, given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from mpz.errors import InputFormatError
from mpz.io import read

INTEL, DEC = 84, 85


def _records(change: Callable[[list, dict, type], None] | None = None) -> bytes:
    """A synthetic float C3D of 10 frames (first frame 10) with ANALOG:SCALE, OFFSET,
    POINT:FRAMES and POINT:UNITS, its records edited by ``change``."""
    from mpz.io import c3dbin
    from mpz.io.c3d import archive_bytes, archive_describes
    from mpz.tools.make_vectors import c3d_motion
    m = c3d_motion(4, storage=1, F=10, M=4, J=1, C=2, n=2)
    a = m.extras["c3d"]
    gid = {r.name: -r.group for r in a.records if r.group < 0}
    R = c3dbin.ParamRecord
    a.records += [R(gid[b"ANALOG"], False, b"SCALE", b"", 4, (2,), struct.pack("<2f", 1, 1)),
                  R(gid[b"ANALOG"], False, b"OFFSET", b"", 2, (2,), struct.pack("<2h", 0, 0)),
                  R(gid[b"POINT"], False, b"FRAMES", b"", 2, (), struct.pack("<h", 10)),
                  R(gid[b"POINT"], False, b"UNITS", b"", -1, (2,), b"mm")]
    if change is not None:
        change(a.records, gid, R)
    # the markers as the edited labels name them: the writer refuses an archive whose
    # labels contradict the motion's names
    return archive_bytes(replace(m, names=archive_describes(a, m.n_markers)[0]))


def _type_at(data: bytes, group: bytes, name: bytes) -> int:
    """The offset of the type byte of parameter ``group:name`` in Intel C3D bytes, found by
    walking the next-record offsets (written here, not taken from the reader)."""
    pos = (data[0] - 1) * 512 + 4
    groups: dict[int, bytes] = {}
    found: dict[tuple[int, bytes], int] = {}
    while True:
        n, g = struct.unpack("<bb", data[pos:pos + 2])
        if n == 0 or g == 0:
            break
        off = pos + 2 + abs(n)
        nxt = struct.unpack("<H", data[off:off + 2])[0]
        if g < 0:
            groups[-g] = data[pos + 2:off]
        else:
            found[(g, data[pos + 2:off])] = off + 2
        if nxt == 0:
            break
        pos = off + nxt
    gid = next(k for k, v in groups.items() if v == group)
    return found[(gid, name)]


def _write(tmp_path: Path, name: str, data: bytes | bytearray) -> Path:
    path = tmp_path / name
    path.write_bytes(bytes(data))
    return path


def _mpz(args: list[str], cwd: Path) -> subprocess.CompletedProcess[bytes]:
    """The mpz command line in a subprocess (a crash is a return code, not the end of the
    test run)."""
    return subprocess.run([sys.executable, "-c", "from mpz.tools.mpz_cli import main; "
                           "raise SystemExit(main())", *args], cwd=cwd, capture_output=True,
                          timeout=120)


# -- 1. a parameter whose data runs past its record: ezc3d 1.7 segfaults -----------------

@pytest.mark.parametrize("group, name, dim, value", [
    (b"ANALOG", b"SCALE", 0, 3),        # 12 bytes where the record holds 8: into OFFSET
    (b"ANALOG", b"SCALE", 0, 255),
    (b"POINT", b"LABELS", 0, 128),      # the QA file's LABELS, first dimension 4 -> 128
])
def test_a_parameter_whose_data_runs_into_the_next_record_is_read_without_ezc3d(
        tmp_path: Path, group: bytes, name: bytes, dim: int, value: int) -> None:
    """ezc3d 1.7 (with ignore_bad_formatting) ends the process on these; `mpz show` runs
    in a subprocess, so a crash is a return code of -11 here."""
    data = bytearray(_records())
    at = _type_at(bytes(data), group, name)
    data[at + 2 + dim] = value
    path = _write(tmp_path, "overlap.c3d", data)
    p = _mpz(["show", str(path)], tmp_path)
    assert p.returncode == 1, (p.returncode, p.stderr[-400:])       # read, with a warning
    assert f"{group.decode()}:{name.decode()}".encode() in p.stdout
    assert b"runs into the next record" in p.stdout and b"Traceback" not in p.stderr
    m = read(path)
    assert m.metadata["reader"] == "mpz.io.c3dbin" and m.n_frames == 10


@pytest.mark.parametrize("dims, ezc3d", [((0, 255, 255, 2), False), ((0, 255, 255), True),
                                         ((1, 255, 255, 2), True)])
def test_a_char_parameter_of_many_empty_strings_is_read_without_ezc3d(
        tmp_path: Path, dims: tuple, ezc3d: bool) -> None:
    """A char parameter whose first dimension is 0 holds no data byte, whatever its other
    dimensions say, and ezc3d makes every string they count: one byte of a real file (a
    LABEL_PREFIXES of dimensions (0, 1) given 7) made 2 x 10^9 of them, a read of 157 s
    and 16.9 GB (a fuzzing QA run of the readers). Past 65535 strings c3dbin reads the
    file, with a note; up to them, and with characters (whose data the record bounds),
    ezc3d does."""
    from mpz.io import c3dbin

    def add(records: list, gid: dict, R: type) -> None:
        # no data byte: (1, ...) says 130050, which run into the next record (rule 8)
        records.append(R(gid[b"POINT"], False, b"EMPTY", b"", -1, dims, b""))

    blob = _records(add)
    hazard = c3dbin.ezc3d_hazard(blob)
    if ezc3d:
        assert hazard is None or "strings of no character" not in hazard
        return
    assert hazard == (f"a char parameter of 130050 strings of no character (dimensions "
                      f"{dims}), more than 65535 (files like it crash ezc3d 1.7)")
    m = read(_write(tmp_path, "empty.c3d", blob))
    assert m.metadata["reader"] == "mpz.io.c3dbin" and m.n_frames == 10
    assert "strings of no character" in m.metadata["reader_note"]


def test_a_group_name_declared_twice_is_read_without_ezc3d(tmp_path: Path) -> None:
    """Two ANALOG groups, the first holding POINT's parameters (USED 4, no OFFSET): the
    hazard rules looked parameters up in the last group of a name and ezc3d in the
    first, so `mpz show`, `encode`, `compare` and `summary` ended in a segmentation
    fault (a QA run of stop 54, from a valid MPZ file whose cprm renames POINT). Run in
    a subprocess: a crash is a return code here."""
    from mpz.io import c3dbin

    def rename(records: list, gid: dict, R: type) -> None:
        i = next(i for i, r in enumerate(records) if r.group == -gid[b"POINT"])
        r = records[i]
        records[i] = R(r.group, r.locked, b"ANALOG", r.description, r.type, r.dims, r.data)
        records.sort(key=lambda r: r.group != -gid[b"POINT"])   # that group first

    data = _records(rename)
    assert c3dbin.ezc3d_hazard(data) == ("a group name declared twice (ANALOG) (files like "
                                         "it crash ezc3d 1.7)")
    path = _write(tmp_path, "twice.c3d", data)
    for args in (["show", str(path)], ["encode", "-q", str(path), "-o", "out.mpz"]):
        p = _mpz(args, tmp_path)
        assert p.returncode in (0, 1, 2), (args, p.returncode, p.stderr[-400:])
        assert b"Traceback" not in p.stderr


# -- 2. internal exception texts -------------------------------------------------------

@pytest.mark.parametrize("name, ptype", [(b"LABELS", 1), (b"LABELS", 4), (b"UNITS", 1)])
def test_a_label_or_unit_parameter_stored_as_numbers_is_said_not_a_valueerror(
        tmp_path: Path, name: bytes, ptype: int) -> None:
    """POINT:LABELS or UNITS whose type byte says numbers: the motion is read (unnamed
    points, unknown units) and the warning names the parameter."""
    from mpz.io import c3dbin

    def retype(rs, g, R):
        i = next(i for i, r in enumerate(rs) if r.group == g[b"POINT"] and r.name == name)
        r = rs[i]
        raw = r.data.ljust(-(-len(r.data) // ptype) * ptype, b"\x00")
        rs[i] = R(r.group, False, name, b"", ptype, (len(raw) // ptype,), raw)
    assert c3dbin.ezc3d_hazard(_records(retype)) is None
    m = read(_write(tmp_path, "numeric.c3d", _records(retype)))
    assert f"POINT:{name.decode()} stored as numbers" in m.metadata["warning"]
    if name == b"LABELS":
        assert all(n.startswith("_unnamed_") for n in m.names)
    else:
        assert m.units == "" and m.names[0] != "_unnamed_0"


def test_a_header_first_frame_0_is_not_called_truncated(tmp_path: Path) -> None:
    """Header frames 0..19 (20) while POINT:FRAMES and the data say 10: the file is
    whole, so the message is about the header's frame words, not truncation."""
    data = bytearray(_records())
    data[6:8] = struct.pack("<H", 0)                   # header word 4: first frame
    path = _write(tmp_path, "first0.c3d", data)
    with pytest.raises(InputFormatError) as err:
        read(path)
    assert "truncated" not in str(err.value)
    assert "POINT:FRAMES 10" in str(err.value) and "0..19" in str(err.value)


def test_a_point_frames_below_the_header_and_the_data_is_read_whole(tmp_path: Path) -> None:
    """POINT:FRAMES 5 where the header and the data hold 10: ezc3d stops at 5. The file
    was refused ("POINT:FRAMES is wrong"); it is read whole by c3dbin, and the warning
    gives that cause, not another (the review of stop 52)."""
    def five(rs: list, gid: dict, R: type) -> None:
        i = next(i for i, r in enumerate(rs) if r.name == b"FRAMES")
        rs[i] = R(gid[b"POINT"], False, b"FRAMES", b"", 2, (), struct.pack("<h", 5))
    m = read(_write(tmp_path, "frames5.c3d", _records(five)))
    assert m.n_frames == 10
    assert "ezc3d found 5 of the 10 frames" in m.metadata["warning"]
    assert "disagrees with POINT:FRAMES 5" in m.metadata["warning"]
    assert "POINT:FRAMES is wrong" in m.metadata["warning"]


# -- 3. header word 9 against POINT:DATA_START -----------------------------------------

@pytest.mark.parametrize("word9", [0, 1, 2])
def test_a_header_data_start_inside_the_parameters_is_not_followed(tmp_path: Path,
                                                                   word9: int) -> None:
    sound = _records()
    good = read(_write(tmp_path, "sound.c3d", sound))
    data = bytearray(sound)
    data[16:18] = struct.pack("<H", word9)
    m = read(_write(tmp_path, "dstart.c3d", data))
    assert np.array_equal(m.positions, good.positions, equal_nan=True)
    assert np.array_equal(m.valid, good.valid)
    stated = struct.unpack("<H", sound[16:18])[0]      # where the writer put the data
    assert f"data start (word 9) is block {word9}, POINT:DATA_START {stated}" in \
        m.metadata["warning"]


def test_a_data_start_neither_pointer_fits_is_refused(tmp_path: Path) -> None:
    data = bytearray(_records())
    data[16:18] = struct.pack("<H", 1)
    at = _type_at(bytes(data), b"POINT", b"DATA_START")
    data[at + 2:at + 4] = struct.pack("<h", 900)       # past the end of the file
    with pytest.raises(InputFormatError, match="neither leaves room"):
        read(_write(tmp_path, "nowhere.c3d", data))


# -- 4. the processor byte -------------------------------------------------------------

def test_an_intel_file_marked_dec_is_refused_naming_the_processor_byte(tmp_path: Path) -> None:
    data = bytearray(_records())
    pstart = (data[0] - 1) * 512
    assert data[pstart + 3] == INTEL
    data[pstart + 3] = DEC
    path = _write(tmp_path, "dec.c3d", data)
    with warnings.catch_warnings():
        warnings.simplefilter("error")                 # no numpy RuntimeWarning either
        with pytest.raises(InputFormatError, match="processor byte") as err:
            read(path)
    assert "as Intel (84) it reads 120 Hz" in str(err.value)
    p = _mpz(["encode", str(path), "-o", "out.mpz"], tmp_path)
    assert p.returncode == 2 and b"RuntimeWarning" not in p.stderr, p.stderr[-400:]


# -- 5. header last frame 1: the same reading for MIPS and Intel ------------------------

@pytest.mark.parametrize("name, fmt", [("c3dorg_Eb015sr.c3d", ">H"),
                                       ("c3dorg_Eb015pi.c3d", "<H")])
def test_a_header_last_frame_1_reads_the_frames_point_frames_and_the_data_hold(
        shared_data: Path, tmp_path: Path, name: str, fmt: str) -> None:
    src = shared_data / "c3d" / name
    if not src.exists():
        pytest.skip(f"{name} is not in the shared data")
    whole = read(src)
    data = bytearray(src.read_bytes())
    data[8:10] = struct.pack(fmt, 1)                   # header word 5: last frame
    m = read(_write(tmp_path, name, data))
    assert m.n_frames == whole.n_frames
    assert np.array_equal(m.positions, whole.positions, equal_nan=True)
    assert "POINT:FRAMES 450" in m.metadata["warning"]


@pytest.mark.parametrize("header_scale", [0.0, float("nan"), float("inf"), 0.05])
def test_a_header_scale_that_contradicts_point_scale_is_not_given_to_ezc3d(tmp_path,
                                                                           header_scale):
    """ezc3d 1.7.2 reads this float file as other numbers when its header's scale (words
    7-8) says 0, NaN, inf or a positive scale (Sample_Jump2 moved by 2 m; yet it reads
    cmu_02_01 with a positive header scale right, and with a positive POINT:SCALE wrong).
    POINT:SCALE decides, as in c3dbin, and the warning says so."""
    good = _records()
    bad = bytearray(good)
    bad[12:16] = struct.pack("<f", header_scale)
    (tmp_path / "good.c3d").write_bytes(good)
    (tmp_path / "bad.c3d").write_bytes(bytes(bad))
    a, b = read(tmp_path / "good.c3d"), read(tmp_path / "bad.c3d")
    assert np.array_equal(a.valid, b.valid)
    assert np.array_equal(a.positions[a.valid], b.positions[b.valid])
    assert "header's scale" in b.metadata["warning"]


def _flip_scale(data: bytes, where: str) -> bytes:
    """Intel C3D bytes with the sign of the header's scale (words 7-8, ``where`` "header")
    or of POINT:SCALE's first element ("parameter") turned, the other left as it is."""
    out = bytearray(data)
    at = 12 if where == "header" else _type_at(data, b"POINT", b"SCALE") + 2 + data[
        _type_at(data, b"POINT", b"SCALE") + 1]               # past type, dims count, dims
    (v,) = struct.unpack("<f", out[at:at + 4])
    out[at:at + 4] = struct.pack("<f", -v)
    return bytes(out)


@pytest.mark.parametrize("where", ["header", "parameter"])
@pytest.mark.parametrize("storage", [0, 1])
def test_a_scale_sign_conflict_reads_the_storage_the_file_size_fits(tmp_path, storage,
                                                                     where):
    """When the header's scale and POINT:SCALE disagree in sign, the storage whose frames
    fit the file is read: a POINT:SCALE of the wrong sign made an int16 file "truncated"
    and a float one int16 garbage (QA of C3D vendors, stop 63). The warning says which was
    read and why; a C3D written back states the storage read in both places."""
    from mpz.io import write
    from mpz.io.c3d import archive_bytes
    from mpz.tools.make_vectors import c3d_motion
    # 40 frames: int16 frames are half the size of float32 ones, so only one storage fits
    good = archive_bytes(c3d_motion(7, storage=storage, F=40, M=4, J=1, C=2, n=2))
    a = read(_write(tmp_path, "good.c3d", good))
    b = read(_write(tmp_path, "bad.c3d", _flip_scale(good, where)))
    assert b.extras["c3d"].word_storage == a.extras["c3d"].word_storage == (storage == 1)
    assert b.n_frames == 40
    assert np.array_equal(a.valid, b.valid)
    assert np.array_equal(a.positions[a.valid], b.positions[b.valid])
    assert np.array_equal(a.extras["c3d"].analog, b.extras["c3d"].analog, equal_nan=True)
    warning = b.metadata["warning"]
    assert "header's scale" in warning
    if where == "parameter":                 # the header's storage, against POINT:SCALE
        said = "int16" if storage == 0 else "float32"
        assert f"fits 40 frames of {said} points, as the header says" in warning
    out = tmp_path / "back.c3d"
    write(b, out)
    back = out.read_bytes()
    (header,) = struct.unpack("<f", back[12:16])
    at = _type_at(back, b"POINT", b"SCALE")
    (param,) = struct.unpack("<f", back[at + 2 + back[at + 1]:at + 6 + back[at + 1]])
    assert header == param and (header < 0) == (storage == 1)


@pytest.mark.parametrize("name", ["c3dorg_Eb015pi.c3d", "cmu_02_01.c3d"])
def test_a_real_file_with_point_scale_of_the_other_sign_reads_as_it_is(
        shared_data: Path, tmp_path: Path, name: str) -> None:
    """Eb015pi (int16) and cmu_02_01 (float32) with POINT:SCALE's sign turned read as the
    files themselves: the first was refused as truncated, the second read as int16."""
    src = shared_data / "c3d" / name
    if not src.exists():
        pytest.skip(f"{name} is not in the shared data")
    a = read(src)
    b = read(_write(tmp_path, name, _flip_scale(src.read_bytes(), "parameter")))
    assert np.array_equal(a.valid, b.valid)
    assert np.array_equal(a.positions[a.valid], b.positions[b.valid])
    assert "as the header says" in b.metadata["warning"]


@pytest.mark.parametrize("hazard", [False, True])
def test_a_header_word_10_of_0_takes_the_samples_from_analog_used(tmp_path, hazard):
    """Header word 10 (analog samples a frame) 0: 2 channels of 2 samples were read as 4
    channels of 1 (``mpz show`` printed them). ANALOG:USED (2) divides word 3's 4 words,
    so the channels are read as written; the words are the same either way. Read by ezc3d
    and, without ANALOG:SCALE (``hazard``), by c3dbin."""
    good = _records(None if not hazard else lambda recs, gid, R: recs.__delitem__(
        next(i for i, r in enumerate(recs) if r.name == b"SCALE" and r.group == gid[b"ANALOG"])))
    bad = bytearray(good)
    assert struct.unpack("<H", bad[18:20]) == (2,)
    bad[18:20] = struct.pack("<H", 0)
    a = read(_write(tmp_path, "good.c3d", good))
    b = read(_write(tmp_path, "bad.c3d", bad))
    assert (a.metadata["reader"] == "mpz.io.c3dbin") == hazard
    assert a.extras["c3d"].analog.shape == b.extras["c3d"].analog.shape == (20, 2)
    assert b.extras["c3d"].analog_samples == 2
    assert np.array_equal(a.extras["c3d"].analog, b.extras["c3d"].analog, equal_nan=True)


@pytest.mark.parametrize("scale", [0.0, float("nan"), float("inf")])
def test_a_point_scale_of_zero_nan_or_inf_is_refused(tmp_path, scale):
    """It made every point a gap, silently (int16 words times 0 or NaN)."""
    data = bytearray(_records())
    at = _type_at(bytes(data), b"POINT", b"SCALE")   # the writer sets it from the header:
    assert data[at:at + 2] == bytes([4, 0])          # edited here, a float32, no dimension
    data[at + 2:at + 6] = struct.pack("<f", scale)
    data[12:16] = struct.pack("<f", scale)          # the header says the same
    p = tmp_path / "s.c3d"
    p.write_bytes(bytes(data))
    with pytest.raises(InputFormatError, match="POINT:SCALE"):
        read(p)


def _outcome(f: Callable[[], object]) -> object:
    try:
        return f()
    except InputFormatError as e:
        return ("InputFormatError", str(e))


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 1535), st.integers(0, 255)), max_size=4))
@example([(16, 0), (590, 0)])          # data start 0: the layout's error, frames declared
def test_the_reader_checks_are_the_four_checks_from_one_parse(edits) -> None:
    """The C3D reader parses the parameter section once for its checks before ezc3d
    (c3dbin.reader_checks); each field, and each error, must be what the function that
    parses the section on its own gives, on files edited byte by byte in the header and
    the parameter section."""
    from mpz.io import c3dbin
    data = bytearray(_records())
    for at, value in edits:
        data[at] = value
    blob = bytes(data)
    got = _outcome(lambda: c3dbin.reader_checks(blob))
    declared = _outcome(lambda: c3dbin.declared_frames(blob))
    if isinstance(got, tuple):          # an error: the frame range's, or else the layout's
        # declared_frames returns a tuple too, (first, frames): an error is the one that
        # starts with the class name (hypothesis found data start 0 taken for one, stop 52)
        if declared[0] == "InputFormatError":
            assert got == declared
        else:
            assert c3dbin.ezc3d_hazard(blob) is None and c3dbin.scale_conflict(blob) is None
            assert got == _outcome(lambda: c3dbin.data_start(blob))
        return
    assert isinstance(got, c3dbin.ReaderChecks)
    assert (got.first, got.declared) == declared
    assert got.hazard == c3dbin.ezc3d_hazard(blob)
    if got.hazard is not None:
        return
    assert got.conflict == c3dbin.scale_conflict(blob)
    if got.conflict is None:
        assert (got.data_start, got.word9, got.note) == c3dbin.data_start(blob)


def test_the_reader_checks_of_the_real_files(shared_data: Path) -> None:
    from mpz.io import c3dbin
    files = sorted((shared_data / "c3d").glob("*.c3d"))
    assert files
    for f in files:
        blob = f.read_bytes()
        got = c3dbin.reader_checks(blob)
        assert (got.first, got.declared) == c3dbin.declared_frames(blob)
        assert got.hazard is None and got.conflict is None, f.name
        assert (got.data_start, got.word9, got.note) == c3dbin.data_start(blob), f.name


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS and /proc: Linux")
def test_a_read_that_may_not_fit_the_address_space_limit_is_not_given_to_ezc3d(
        tmp_path: Path) -> None:
    """Under ``ulimit -v``, ezc3d's ``std::bad_alloc`` can terminate the process (SIGABRT,
    QA stop 34 finding 08): such a read goes to c3dbin, whose failures are MemoryErrors. The
    child's limit is 300 MB above its own use: ezc3d needs about 330 MB for this file, and
    the abort happened there before."""
    from mpz.io import write
    from mpz.synth import generate
    path = tmp_path / "long.c3d"
    write(generate("walk", frames=40000), path)
    child = (
        "import resource, sys\n"
        "import mpz.io\n"
        "status = dict(l.split(':', 1) for l in open('/proc/self/status'))\n"
        "used = int(status['VmSize'].split()[0]) * 1024\n"
        "resource.setrlimit(resource.RLIMIT_AS, (used + (300 << 20), resource.RLIM_INFINITY))\n"
        "try:\n"
        "    m = mpz.io.read(sys.argv[1])\n"
        "except MemoryError:\n"
        "    print('MemoryError')\n"
        "else:\n"
        "    print(m.positions.shape, m.metadata.get('reader_note'))\n")
    r = subprocess.run([sys.executable, "-c", child, str(path)], capture_output=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr.decode(errors="replace")[-2000:]
    out = r.stdout.decode()
    assert out.startswith("MemoryError") or (
        out.startswith("(40000, 41, 3)") and "not read with ezc3d, which aborts" in out), out


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS and /proc: Linux")
def test_a_write_that_may_not_fit_the_address_space_limit_is_not_given_to_ezc3d(
        tmp_path: Path) -> None:
    """The writer's side of the same abort (review of stop 35): a motion without an archive
    goes to our own writer when ezc3d may not have the address space; the file holds the
    same points."""
    child = (
        "import resource, sys\n"
        "import numpy as np\n"
        "import mpz.io\n"
        "from mpz.synth import generate\n"
        "m = generate('walk', frames=40000)\n"
        "status = dict(l.split(':', 1) for l in open('/proc/self/status'))\n"
        "used = int(status['VmSize'].split()[0]) * 1024\n"
        "resource.setrlimit(resource.RLIMIT_AS, (used + (250 << 20), resource.RLIM_INFINITY))\n"
        "try:\n"
        "    mpz.io.write(m, sys.argv[1])\n"
        "except MemoryError:\n"
        "    print('MemoryError')\n"
        "else:\n"
        "    np.save(sys.argv[1] + '.npy', m.as_nan())\n"
        "    print('written')\n")
    out = tmp_path / "long.c3d"
    r = subprocess.run([sys.executable, "-c", child, str(out)], capture_output=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr.decode(errors="replace")[-2000:]
    if r.stdout.decode().startswith("written"):
        back = read(out)
        want = np.load(str(out) + ".npy")
        assert back.n_frames == 40000
        np.testing.assert_allclose(back.as_nan(), want.astype(np.float32), rtol=0, atol=1e-3)


def test_memory_short_compares_the_need_with_the_limit_and_the_use(monkeypatch) -> None:
    import resource

    from mpz.io import c3d
    if not Path("/proc/self/status").exists():
        pytest.skip("no /proc/self/status")
    limits = {resource.RLIMIT_AS: resource.RLIM_INFINITY,
              resource.RLIMIT_DATA: resource.RLIM_INFINITY}
    monkeypatch.setattr(resource, "getrlimit", lambda which: (limits[which], limits[which]))
    assert c3d.memory_short(1 << 60) is None               # no limit: ezc3d may try
    status = dict(line.split(":", 1) for line in open("/proc/self/status"))
    vm = int(status["VmSize"].split()[0]) * 1024
    limits[resource.RLIMIT_AS] = vm + (100 << 20)
    assert c3d.memory_short(10 << 20) is None
    said = c3d.memory_short(400 << 20)
    assert said is not None and "ulimit -v" in said and "about 400 MB" in said
    limits[resource.RLIMIT_AS] = resource.RLIM_INFINITY
    limits[resource.RLIMIT_DATA] = 1 << 20                 # below any process's data
    said = c3d.memory_short(0)
    assert said is not None and "ulimit -d" in said


def test_a_repeated_point_used_is_named_not_called_truncation(tmp_path: Path) -> None:
    """POINT:RATE renamed USED (one byte pattern in a real file): the last POINT:USED set
    the frame size, and the error said "truncated point data" of a whole file (a fuzzing
    QA run of stop 54). It now names the repeated parameter and its values."""
    def rename(records: list, gid: dict, R: type) -> None:
        i = next(i for i, r in enumerate(records)
                 if r.group == gid[b"POINT"] and r.name == b"RATE")
        r = records[i]
        records[i] = R(r.group, r.locked, b"USED", r.description, r.type, r.dims, r.data)

    path = _write(tmp_path, "used.c3d", _records(rename))
    with pytest.raises(InputFormatError) as err:
        read(path)
    text = str(err.value)
    assert "POINT:USED given 2 times (5, " in text and "truncated" not in text, text


def test_frames_past_the_header_range_are_said(tmp_path: Path) -> None:
    """The header's frame range is authoritative (frame_range), so frames the data holds
    past it are not read: u42's C3D (a stale header kept by §4.13.1, written back) read
    as 2 of its 24 frames with no word (a CLI fuzzing QA run of stop 54). A file padded by
    up to a whole block more gets no such warning (mpz.tools.make_example's walk.c3d has
    one); one with three blocks more does."""
    import mpz
    from mpz.io import write
    vec = Path(__file__).resolve().parents[1] / "conformance" / "vectors" / "uncommon"
    u42 = mpz.decode(next(vec.glob("u42-*.mpz")).read_bytes())
    write(u42, tmp_path / "u42.c3d")
    m = read(tmp_path / "u42.c3d")
    assert m.n_frames == 2
    assert "past the 2 frames of the header's frame range (words 4-5)" in \
        m.metadata["warning"]
    data = _records()
    path = _write(tmp_path, "whole.c3d", data)
    assert "frame range" not in read(path).metadata.get("warning", "")
    block = _write(tmp_path, "block.c3d", data + bytes(512))    # a block of padding more,
    assert "frame range" not in read(block).metadata.get("warning", "")   # as walk.c3d
    longer = _write(tmp_path, "longer.c3d", data + data[-512:] * 3)     # 3 blocks more
    w = read(longer).metadata.get("warning", "")
    assert "bytes past the 10 frames of the header's frame range" in w, w


def test_a_record_ezc3d_refuses_is_not_read_leniently_where_that_walk_meets_a_hazard(
        tmp_path: Path, monkeypatch) -> None:
    """A fuzzing run of the readers (stop 57): a 7.7 KB C3D whose POINT:LABELS description
    ran past its record. ezc3d refuses such a file, and the reader asked it again with
    ``ignore_bad_formatting``; ezc3d then reads on from where the description ends, not
    from the next record, and there it read the point data as parameters (12 GB and 3 s;
    where memory is short, the process ends). The walk ezc3d then makes is checked first
    (``ezc3d_hazard(ignore_bad_formatting=True)``), and c3dbin reads the file."""
    import ezc3d

    from mpz.io import c3dbin
    data = bytearray(_records())
    at = _type_at(bytes(data), b"POINT", b"LABELS")
    ptype, ndim = struct.unpack("<bB", data[at:at + 2])
    dims = data[at + 2:at + 2 + ndim]
    desc = at + 2 + ndim + abs(ptype) * int(np.prod(list(dims)))
    # the writer's records follow each other (the next-record offset counts from its own
    # two bytes, just before the type): 5 bytes more run into the next record
    assert desc + 1 + data[desc] == at - 2 + struct.unpack("<H", data[at - 2:at])[0]
    data[desc] += 5
    blob = bytes(data)
    assert c3dbin.ezc3d_hazard(blob) is None          # walked by the records' offsets
    lenient = c3dbin.ezc3d_hazard(blob, ignore_bad_formatting=True)
    assert lenient is not None and lenient.endswith("(files like it crash ezc3d 1.7)")
    calls: list[dict] = []

    def recorded(*args, **kwargs):
        calls.append(kwargs)
        if kwargs.get("ignore_bad_formatting"):        # the read this test is about: it
            raise AssertionError("asked leniently")    # would take gigabytes, or crash
        return ezc3d.c3d(*args, **kwargs)

    # the reader imports ezc3d where it reads; ezc3d's own code keeps its module
    seen = types.ModuleType("ezc3d")
    seen.__dict__.update(vars(ezc3d))
    seen.c3d = recorded
    monkeypatch.setitem(sys.modules, "ezc3d", seen)
    m = read(_write(tmp_path, "overrun.c3d", blob))
    assert calls and not any(c.get("ignore_bad_formatting") for c in calls), calls
    assert m.metadata["reader"] == "mpz.io.c3dbin" and m.n_frames == 10
    assert f"told to ignore that it would meet {lenient}" in m.metadata["warning"]


def test_the_lenient_walk_finds_nothing_in_the_real_files_ezc3d_reads(
        shared_data: Path) -> None:
    """No false alarm: of the 18 real C3D files, ezc3d reads 16 as they are, so the walk
    it would make with ignore_bad_formatting must find nothing there; Facial-Sing, which
    ezc3d refuses, and refuses again with ignore_bad_formatting ("Parameter type
    unrecognized"), holds a parameter of type 0 on that walk."""
    from mpz.io import c3dbin
    files = sorted((shared_data / "c3d").glob("*.c3d"))
    if not files:
        pytest.skip("no C3D files in the shared data")
    found = {f.name: c3dbin.ezc3d_hazard(f.read_bytes(), ignore_bad_formatting=True)
             for f in files}
    assert {k: v for k, v in found.items() if v is not None} == {
        "c3dorg_Facial-Sing.c3d": "a parameter of type 0 (files like it crash ezc3d 1.7)"}


def _group_at(data: bytes, group: bytes) -> int:
    """The offset of group record ``group``'s next-record offset in Intel C3D bytes (found
    by walking the offsets, as :func:`_type_at`)."""
    pos = (data[0] - 1) * 512 + 4
    while True:
        n, g = struct.unpack("<bb", data[pos:pos + 2])
        off = pos + 2 + abs(n)
        if g < 0 and data[pos + 2:off] == group:
            return off
        pos = off + struct.unpack("<H", data[off:off + 2])[0]


def test_a_group_offset_past_the_file_hides_no_hazard_from_the_lenient_walk(
        tmp_path: Path) -> None:
    """A fuzzing run of the readers (stop 57): an ANALOG group whose next-record offset
    pointed past the file. Walked by the offsets, the section ends there, so no rule saw
    its parameters; ezc3d refuses the file, and with ignore_bad_formatting reads on from
    the group's description into them: an ANALOG:RATE without element, a segmentation
    fault. The lenient walk reads the records ezc3d then reads."""
    from mpz.io import c3dbin

    def empty_rate(records: list, gid: dict, R: type) -> None:
        i = next(i for i, r in enumerate(records)
                 if r.group == gid[b"ANALOG"] and r.name == b"RATE")
        records[i] = R(gid[b"ANALOG"], False, b"RATE", b"", 4, (0,), b"")

    data = bytearray(_records(empty_rate))
    assert c3dbin.ezc3d_hazard(bytes(data)) == ("ANALOG:RATE with no element (files like it "
                                                "crash ezc3d 1.7)")
    at = _group_at(bytes(data), b"ANALOG")
    data[at:at + 2] = struct.pack("<H", 0xFFF0)           # the next record: past the file
    blob = bytes(data)
    assert c3dbin.ezc3d_hazard(blob) is None               # the walk by offsets ends there
    assert c3dbin.ezc3d_hazard(blob, ignore_bad_formatting=True) == (
        "ANALOG:RATE with no element (files like it crash ezc3d 1.7)")
    path = _write(tmp_path, "hidden.c3d", blob)
    lenient = subprocess.run([sys.executable, "-c", "import sys, ezc3d; "
                              "ezc3d.c3d(sys.argv[1], ignore_bad_formatting=True)",
                              str(path)], capture_output=True, timeout=120)
    assert lenient.returncode < 0, lenient.returncode       # what the reader must not ask
    p = _mpz(["show", str(path)], tmp_path)
    assert p.returncode == 1, (p.returncode, p.stderr[-400:])      # read, with a warning
    assert b"told to ignore that it would meet ANALOG:RATE with no element" in p.stdout


# -- a parameter record no C3D has, in the middle of the section ---------------------------

@pytest.mark.parametrize("group, name, edit, why", [
    (b"ANALOG", b"SCALE", (0, 5), "(type 5; a C3D parameter's is -1, 1, 2 or 4)"),
    (b"POINT", b"FRAMES", (1, 9), "(9 dimensions; a C3D parameter has at most 7)"),
])
def test_a_record_of_a_type_or_dimensions_no_c3d_has_is_left_out_alone_and_said(
        tmp_path: Path, group: bytes, name: bytes, edit: tuple[int, int], why: str) -> None:
    """The walk of the records ended at such a record, so every record after it left the
    archive without a word, and the C3D written back crashed ezc3d (a QA run of stop 72:
    ANALOG:GEN_SCALE given type 5 lost 27 of 48 parameters, ANALOG:SCALE and EVENT among
    them). The record is now skipped by its next-record offset, the others are kept, and
    the warning names it."""
    from mpz.io import c3dbin
    data = bytearray(_records())
    whole = read(_write(tmp_path, "whole.c3d", data))
    at = _type_at(bytes(data), group, name)
    data[at + edit[0]] = edit[1]
    path = _write(tmp_path, "odd.c3d", data)
    m = read(path)
    said = m.metadata.get("warning") or ""
    assert (f"1 parameter record cannot be read and is not kept: "
            f"{group.decode()}:{name.decode()} {why}") in said, said
    before = [(r.group, r.name) for r in whole.extras["c3d"].records]
    after = [(r.group, r.name) for r in m.extras["c3d"].records]
    lost = [k for k in before if k not in after]
    assert len(lost) == 1 and lost[0][1] == name and len(after) == len(before) - 1
    assert m.names == whole.names and m.n_frames == whole.n_frames
    assert np.array_equal(m.positions, whole.positions, equal_nan=True)
    # the CLI says it too, with exit 1 (a warning)
    p = _mpz(["encode", str(path), "-o", str(tmp_path / "odd.mpz")], tmp_path)
    assert p.returncode == 1 and b"is not kept" in p.stderr, p.stderr[-600:]
    assert len(c3dbin.parse_records(bytes(data), (data[0] - 1) * 512,
                                    c3dbin._Codec(INTEL))) == len(after)


def test_the_markers_are_read_from_records_past_the_declared_blocks_without_ezc3d(
        tmp_path: Path) -> None:
    """mpz.io.c3dbin read the parameters it takes the markers from only within the
    declared block count, while its archive went on to the data start (as ezc3d reads
    them): a section that declares 1 block gave markers named ``_unnamed_0`` ... beside
    an archive holding their labels (a QA run of stop 72). Both now come from one walk."""
    from mpz.io.c3d import motion_from_c3d_bytes

    def long_first(records: list, gid: dict, R: type) -> None:
        at = next(i for i, r in enumerate(records) if r.group == -gid[b"POINT"]) + 1
        records.insert(at, R(gid[b"POINT"], False, b"NOTES", b"", -1, (225, 4), b"n" * 900))
    data = bytearray(_records(long_first))
    pstart = (data[0] - 1) * 512
    assert data[pstart + 2] == 3
    whole = motion_from_c3d_bytes(bytes(data))
    assert _type_at(bytes(data), b"POINT", b"LABELS") > pstart + 512   # past block 1
    data[pstart + 2] = 1
    one = motion_from_c3d_bytes(bytes(data))
    assert one.names == whole.names and not any(n.startswith("_unnamed") for n in one.names)
    assert one.units == whole.units == "mm"
    assert "declares 1 block but its records go on" in one.metadata["warning"]
