"""Relations files of the Freiburg benchmark: reading, validation, the shared logs' files."""

from __future__ import annotations

import gzip
import math
from pathlib import Path

import numpy as np
import pytest

from fuzzypos.io import LogFormatError
from fuzzypos.io.relations import Relations, RelationsFormatError, read_relations
from helpers import DATA, pipe_with

GOOD = """\
# t1 t2 x y z roll pitch yaw
976052905.167303 976052911.885496 -0.056990 -0.128430 0.000000 0.000000 0.000000 -1.682210

976052896.784509 976052905.167303 -0.153130 -0.051420 0.000000 0.000000 0.000000 -2.405850
10.5 10.0 1.0 2.0 0 0 0 3.5
"""


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_reads_values_in_file_order(tmp_path: Path) -> None:
    rel = read_relations(write(tmp_path / "r.relations", GOOD))
    assert len(rel) == 3
    np.testing.assert_array_equal(rel.t1, [976052905.167303, 976052896.784509, 10.5])
    np.testing.assert_array_equal(rel.t2, [976052911.885496, 976052905.167303, 10.0])
    np.testing.assert_array_equal(rel.motion[0], [-0.056990, -0.128430, -1.682210])
    # yaw wrapped to [-pi, pi); values inside stay bit-exact
    assert rel.motion[2, 2] == pytest.approx(3.5 - 2 * math.pi)
    assert rel.motion[1, 2] == -2.405850
    # t2 < t1 is kept (intel has 6 such relations) and is local
    np.testing.assert_allclose(rel.dt, [6.718193, 8.382794, -0.5], atol=1e-6)
    np.testing.assert_array_equal(rel.is_local(), [True, True, True])
    np.testing.assert_array_equal(rel.is_local(7.0), [True, False, True])


def test_reads_gzip_by_magic(tmp_path: Path) -> None:
    path = tmp_path / "r.txt"  # no .gz in the name
    with gzip.open(path, "wt", encoding="utf-8") as f:
        f.write(GOOD)
    assert len(read_relations(path)) == 3


def test_empty_file_gives_no_relations(tmp_path: Path) -> None:
    rel = read_relations(write(tmp_path / "r.relations", "# nothing\n\n"))
    assert len(rel) == 0
    assert rel.motion.shape == (0, 3)


def test_arrays_are_read_only(tmp_path: Path) -> None:
    rel = read_relations(write(tmp_path / "r.relations", GOOD))
    with pytest.raises(ValueError):
        rel.motion[0, 0] = 1.0
    with pytest.raises(AttributeError):
        rel.t1 = np.zeros(3)  # type: ignore[misc]


@pytest.mark.parametrize(
    ("line", "what"),
    [
        ("1 2 3 4 0 0 0", "expected 8 fields (t1 t2 x y z roll pitch yaw), got 7"),
        ("1 2 3 4 0 0 0 0 0", "got 9"),
        ("1 2 abc 4 0 0 0 0", "x is not a number: 'abc'"),
        ("1 nan 3 4 0 0 0 0", "t2 must be finite"),
        ("1 2 3 4 0 0 0 inf", "yaw must be finite"),
        ("1 2 3 4 0.5 0 0 0", "relation is not planar: z = 0.5"),
        ("1 2 3 4 0 0.01 0 0", "not planar: roll"),
        ("1 2 3 4 0 0 -0.01 0", "not planar: pitch"),
    ],
)
def test_bad_lines_name_file_line_and_what(tmp_path: Path, line: str, what: str) -> None:
    path = write(tmp_path / "bad.relations", f"# header\n1 2 0.1 0 0 0 0 0\n{line}\n")
    with pytest.raises(RelationsFormatError) as info:
        read_relations(path)
    err = info.value
    assert isinstance(err, LogFormatError) and isinstance(err, ValueError)
    assert err.line == 3
    assert str(err).startswith(f"{path}:3: ")
    assert what in str(err)


def test_tiny_z_roll_pitch_are_planar(tmp_path: Path) -> None:
    rel = read_relations(write(tmp_path / "r.relations", "1 2 3 4 1e-9 -1e-9 0.0000001 0\n"))
    np.testing.assert_array_equal(rel.motion, [[3.0, 4.0, 0.0]])


@pytest.mark.parametrize(
    ("args", "what"),
    [
        (([1.0], [2.0, 3.0], np.zeros((1, 3))), "same shape"),
        (([1.0], [2.0], np.zeros((2, 3))), r"shape \(1, 3\)"),
        (([1.0], [2.0], np.zeros((1, 2))), r"shape \(1, 3\)"),
        (([np.nan], [2.0], np.zeros((1, 3))), "finite"),
    ],
)
def test_relations_validate(args, what) -> None:
    with pytest.raises(ValueError, match=what):
        Relations(*args)


def test_relations_copy_their_input() -> None:
    m = np.zeros((1, 3))
    rel = Relations(np.array([1.0]), np.array([2.0]), m)
    m[0, 0] = 5.0
    assert rel.motion[0, 0] == 0.0
    assert m.flags.writeable


@pytest.mark.parametrize(
    ("name", "count", "local", "backwards"),
    [("intel", 2984, 1770, 6), ("aces", 1279, 1178, 0)],
)
def test_shared_relations(name: str, count: int, local: int, backwards: int) -> None:
    path = DATA / name / f"{name}.relations"
    if not path.exists():
        pytest.skip(f"shared data {path} is absent")
    rel = read_relations(path)
    assert len(rel) == count
    assert int(rel.is_local(10.0).sum()) == local
    assert int((rel.dt < 0).sum()) == backwards


@pytest.mark.parametrize("how", ["truncated", "corrupt", "crc"])
def test_a_damaged_gzip_file_is_a_format_error(tmp_path: Path, how: str) -> None:
    data = bytearray(gzip.compress((GOOD * 20).encode(), mtime=0))
    if how == "truncated":
        data = data[: len(data) - 12]
    elif how == "corrupt":
        data[12] ^= 0xFF
    else:
        data[-8:-4] = b"\0\0\0\0"  # the stored CRC-32
    path = tmp_path / "log.relations.gz"
    path.write_bytes(bytes(data))
    with pytest.raises(RelationsFormatError) as info:
        read_relations(path)
    assert str(info.value).startswith(f"{path}:") and "gzip stream" in info.value.reason


def test_reads_a_pipe_whole(tmp_path: Path) -> None:
    with pipe_with(gzip.compress(GOOD.encode())) as pipe:
        rel = read_relations(pipe)
    assert len(rel) == 3 and rel.t1[-1] == 10.5
