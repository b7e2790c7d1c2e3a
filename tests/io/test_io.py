"""fuzzypos.io: CARMEN logs (write, stream back, errors) and TUM trajectories."""

from __future__ import annotations

import gzip
import itertools
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fuzzypos.geometry import Pose2D
from fuzzypos.io import (
    CarmenFormatError,
    CarmenReader,
    CarmenRecord,
    CarmenWriter,
    LogFormatError,
    TumFormatError,
    carmen_beam_geometry,
    read_carmen,
    read_tum,
    write_carmen,
    write_tum,
)
from fuzzypos.scan import LaserScan
from helpers import DATA, fifo_with, pipe_with

ACES = DATA / "aces" / "aces.clf.gz"
DEG = math.pi / 180.0


# -- helpers -------------------------------------------------------------------------------
def make_scan(n=180, *, stamp=0.0, range_max=8.0, seed=0, convention="auto", fov=180.0, **kw):
    a0, inc = carmen_beam_geometry(n, fov, convention)
    rng = np.random.default_rng(seed)
    ranges = (
        rng.uniform(0.05, range_max - 0.01, n)
        if math.isfinite(range_max)
        else rng.uniform(0.05, 30.0, n)
    )
    return LaserScan(ranges, a0, inc, range_max=range_max, stamp=stamp, **kw)


def _num(v):
    """A field as text: numbers at full precision, strings as they are (to break lines)."""
    return v if isinstance(v, str) else repr(float(v))


def flaser(ranges, odom=(0.0, 0.0, 0.0), stamp=1.0, xyt=None, host="h"):
    xyt = odom if xyt is None else xyt
    r = " ".join(str(v) for v in ranges)
    p = " ".join(_num(v) for v in xyt)
    o = " ".join(_num(v) for v in odom)
    return f"FLASER {len(ranges)} {r} {p} {o} {_num(stamp)} {host} {_num(stamp)}"


def truepos(pose, odom=(0.0, 0.0, 0.0), stamp=1.0):
    p = " ".join(_num(v) for v in pose)
    o = " ".join(_num(v) for v in odom)
    return f"TRUEPOS {p} {o} {_num(stamp)} h {_num(stamp)}"


def write_lines(path: Path, lines, newline_at_end=True):
    text = "\n".join(lines) + ("\n" if newline_at_end else "")
    path.write_text(text)
    return path


R5 = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]  # 6 beams: "resolution" convention (even)


# -- beam geometry -------------------------------------------------------------------------
@pytest.mark.parametrize(
    "n, first_deg, last_deg",
    [(180, -90.0, 89.0), (181, -90.0, 90.0), (360, -90.0, 89.5), (361, -90.0, 90.0)],
)
def test_beam_geometry_conventions(n, first_deg, last_deg):
    a0, inc = carmen_beam_geometry(n)
    assert a0 == pytest.approx(first_deg * DEG, abs=1e-12)
    assert a0 + (n - 1) * inc == pytest.approx(last_deg * DEG, abs=1e-12)


def test_beam_geometry_explicit_conventions_and_errors():
    a0, inc = carmen_beam_geometry(180, convention="span")
    assert a0 + 179 * inc == pytest.approx(math.pi / 2, abs=1e-12)
    a0, inc = carmen_beam_geometry(181, convention="resolution")
    assert inc == pytest.approx(math.pi / 181)
    a0, inc = carmen_beam_geometry(360, field_of_view_deg=360.0)
    assert a0 == pytest.approx(-math.pi) and inc == pytest.approx(DEG)
    with pytest.raises(ValueError, match="convention"):
        carmen_beam_geometry(180, convention="sideways")
    with pytest.raises(ValueError, match="field_of_view_deg"):
        carmen_beam_geometry(180, field_of_view_deg=0.0)
    with pytest.raises(ValueError, match="beam count"):
        carmen_beam_geometry(1)


# -- write -> read round trip --------------------------------------------------------------
OFFSET = Pose2D(0.25, 0.0, 0.0)


def _records(n=180, count=6, with_truth=True, sensor_pose=OFFSET, **kw):
    recs = []
    stamps = [100.0, 100.1, 100.05, 100.3, 1e9 + 0.123456789, 1e9 + 0.1234568]  # goes back
    for k in range(count):
        scan = make_scan(n, stamp=stamps[k % len(stamps)], seed=k, sensor_pose=sensor_pose, **kw)
        r = np.array(scan.ranges)
        r[[3, 10, 11]] = [np.nan, 0.0, np.inf]  # invalid readings
        r[20] = scan.range_max  # "no return"
        r[21] = scan.range_max + 5.0
        r[22] = 1.23456789  # more digits than the file keeps
        scan = scan.with_ranges(r)
        odom = Pose2D(1.0 / 3.0 + k, -2.0 / 7.0 * k, -math.pi + 0.1 * k)
        truth = (
            Pose2D(odom.x + 0.01, odom.y - 0.02, math.pi / 7) if with_truth and k % 2 == 0 else None
        )
        recs.append(CarmenRecord(scan, odom, truth))
    return recs


def _assert_same(got, want):
    assert len(got) == len(want)
    for g, w in zip(got, want):
        assert g.scan.n_beams == w.scan.n_beams
        assert g.scan.angle_min == pytest.approx(w.scan.angle_min, abs=1e-12)
        assert g.scan.angle_increment == pytest.approx(w.scan.angle_increment, abs=1e-12)
        np.testing.assert_array_equal(g.scan.valid, w.scan.valid)
        np.testing.assert_allclose(
            g.scan.ranges[w.scan.valid], w.scan.ranges[w.scan.valid], atol=1e-3, rtol=0
        )
        assert g.scan.stamp == w.scan.stamp
        assert g.scan.sensor_pose == w.scan.sensor_pose
        assert g.odometry == w.odometry
        assert g.truth == w.truth


@pytest.mark.parametrize("n", [180, 181, 360, 361])
def test_round_trip(tmp_path, n):
    recs = _records(n)
    path = tmp_path / "sim.clf"
    assert write_carmen(path, recs) == len(recs)
    got = list(read_carmen(path))
    _assert_same(got, recs)
    assert all(g.scan.range_max == 8.0 for g in got)
    assert [g.scan.stamp for g in got] == [r.scan.stamp for r in recs]  # backwards kept
    assert [g.truth is not None for g in got] == [True, False, True, False, True, False]


def test_round_trip_file_layout(tmp_path):
    path = tmp_path / "sim.clf"
    write_carmen(path, _records(count=2), hostname="robo", header_comment="run 7\nseed 3")
    lines = path.read_text().splitlines()
    header = [ln for ln in lines if ln.startswith("#")]
    assert any("fuzzypos" in ln for ln in header)
    assert "# run 7" in header and "# seed 3" in header
    body = [ln.split() for ln in lines if not ln.startswith("#")]
    assert [t[0] for t in body] == ["PARAM", "PARAM", "FLASER", "TRUEPOS", "FLASER"]
    assert body[0][:3] == ["PARAM", "robot_frontlaser_offset", "0.25"]
    assert body[1][:3] == ["PARAM", "robot_front_laser_max", "8.0"]
    fl = body[2]
    assert fl[1] == "180" and len(fl) == 180 + 11
    assert fl[2 + 180 : 2 + 183] == fl[2 + 183 : 2 + 186]  # x y θ repeat the odometry
    assert fl[-2] == "robo" and fl[-1] == fl[-3]
    assert fl[2 + 3] == "8.0" and fl[2 + 10] == "8.0"  # invalid readings written as range_max
    assert len(body[3]) == 10


def test_round_trip_infinite_range_max_and_no_offset(tmp_path):
    recs = _records(count=3, range_max=math.inf, sensor_pose=Pose2D())
    path = tmp_path / "sim.clf"
    write_carmen(path, recs)
    text = path.read_text()
    assert not any(ln.startswith("PARAM") for ln in text.splitlines())
    got = list(read_carmen(path, max_range=math.inf))
    _assert_same(got, recs)


def test_round_trip_gzip_output_and_span_convention(tmp_path):
    recs = _records(180, count=3, convention="span")
    path = tmp_path / "sim.clf.gz"
    write_carmen(path, recs, convention="span")
    assert path.read_bytes()[:2] == b"\x1f\x8b"
    _assert_same(list(read_carmen(path, convention="span")), recs)


@given(
    x=st.floats(-1e6, 1e6),
    y=st.floats(-1e6, 1e6),
    theta=st.floats(-math.pi, math.pi, exclude_max=True),
    stamp=st.floats(-1e10, 1e10),
)
def test_poses_and_stamps_exact(tmp_path_factory, x, y, theta, stamp):
    path = tmp_path_factory.mktemp("h") / "p.clf"
    scan = make_scan(180, stamp=stamp)
    rec = CarmenRecord(scan, Pose2D(x, y, theta), Pose2D(y, x, theta))
    write_carmen(path, [rec])
    (got,) = read_carmen(path)
    assert got.odometry == rec.odometry and got.truth == rec.truth and got.scan.stamp == stamp


# -- writer refuses what FLASER cannot say --------------------------------------------------
def test_writer_rejects_geometry_off_convention(tmp_path):
    path = tmp_path / "bad.clf"
    a0, inc = carmen_beam_geometry(180, convention="span")  # -90..+90 with 180 beams
    scan = LaserScan(np.ones(180), a0, inc)
    with pytest.raises(ValueError, match="does not fit FLASER"):
        write_carmen(path, [CarmenRecord(scan, Pose2D())])
    assert not path.exists() and list(tmp_path.iterdir()) == []  # nothing left behind
    flipped = LaserScan(np.ones(180), math.pi / 2, -DEG)  # upside-down mount
    with pytest.raises(ValueError, match="does not fit FLASER"):
        write_carmen(path, [CarmenRecord(flipped, Pose2D())])


def test_writer_rejects_sensor_pose_and_mixed_lasers(tmp_path):
    path = tmp_path / "bad.clf"
    side = make_scan(sensor_pose=Pose2D(0.1, 0.2, 0.0))
    with pytest.raises(ValueError, match="forward laser offset"):
        write_carmen(path, [CarmenRecord(side, Pose2D())])
    a, b = make_scan(range_max=8.0), make_scan(range_max=10.0)
    with pytest.raises(ValueError, match="range_max"):
        write_carmen(path, [CarmenRecord(a, Pose2D()), CarmenRecord(b, Pose2D())])
    with pytest.raises(ValueError, match="hostname"):
        write_carmen(path, [CarmenRecord(a, Pose2D())], hostname="two words")
    assert not path.exists()


def test_writer_keeps_an_existing_file_on_error(tmp_path):
    path = tmp_path / "log.clf"
    write_carmen(path, _records(count=1))
    before = path.read_bytes()

    def recs():
        yield from _records(count=2)
        raise RuntimeError("simulation died")

    with pytest.raises(RuntimeError):
        write_carmen(path, recs())
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.clf"]


# -- CarmenWriter: the one writer behind write_carmen and the run's trajectory.clf ----------
def test_carmen_writer_streams_what_write_carmen_writes(tmp_path):
    recs = _records(count=4)
    whole, streamed = tmp_path / "whole.clf.gz", tmp_path / "streamed.clf.gz"
    write_carmen(whole, recs, hostname="robo", header_comment="run 7")
    with CarmenWriter(streamed, hostname="robo", header_comment="run 7") as w:
        for rec in recs:
            w.write(rec.scan, rec.odometry, rec.truth)
            assert not streamed.exists()  # a temporary file until closed
    assert w.written == len(recs)
    assert streamed.read_bytes() == whole.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["streamed.clf.gz", "whole.clf.gz"]


def test_carmen_writer_pose_fields_and_abort(tmp_path):
    scan = make_scan(stamp=2.5, sensor_pose=Pose2D())
    path = tmp_path / "est.clf"
    w = CarmenWriter(path)
    w.write(scan, Pose2D(1.0, 2.0, 0.5), Pose2D(3.0, 4.0, 0.25), pose=Pose2D(7.0, 8.0, 0.125))
    w.write(scan, None, pose=Pose2D(9.0, 9.5, 0.0))  # no odometry: the pose in both
    with pytest.raises(ValueError, match="no pose"):
        w.write(scan, None)
    assert w.close() and w.written == 2
    lines = [ln.split() for ln in path.read_text().splitlines() if not ln.startswith(("#", "P"))]
    assert [t[0] for t in lines] == ["FLASER", "TRUEPOS", "FLASER"]
    assert lines[0][182:188] == ["7.0", "8.0", "0.125", "1.0", "2.0", "0.5"]
    assert lines[1][1:7] == ["3.0", "4.0", "0.25", "1.0", "2.0", "0.5"]
    assert lines[2][182:188] == ["9.0", "9.5", "0.0", "9.0", "9.5", "0.0"]
    with pytest.raises(ValueError, match="closed"):
        w.write(scan, Pose2D())
    w2 = CarmenWriter(tmp_path / "gone.clf")
    w2.write(scan, Pose2D())
    w2.abort()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["est.clf"]


def test_carmen_writer_estimate_mode_follows_the_first_scan(tmp_path):
    a0, inc = carmen_beam_geometry(180, convention="span")
    mount = Pose2D(0.2, 0.05, 0.1)
    first = LaserScan(np.full(180, 2.0), a0, inc, range_max=8.0, stamp=1.0, sensor_pose=mount)
    other = make_scan(stamp=2.0)  # 1° steps: does not fit the first scan's span geometry
    path = tmp_path / "trajectory.clf"
    w = CarmenWriter(path, estimate_of="some.log", field_of_view_deg=90.0)  # fov not used
    w.write(first, Pose2D(), pose=Pose2D(1.0, 0.0, 0.0))
    w.write(other, Pose2D(), pose=Pose2D(2.0, 0.0, 0.0))
    # a mount off the robot's x axis: FLASER cannot hold it, so every scan is ROBOTLASER1
    assert w.close() and (w.written, w.robotlaser1) == (2, 2) and w.notes == []
    text = path.read_text()
    assert "from some.log" in text and "convention 'span'" not in text
    a, b = read_carmen(path, odometry="interpolated")
    assert (a.scan.stamp, b.scan.stamp) == (1.0, 2.0) and a.odometry == Pose2D()
    np.testing.assert_allclose(a.scan.angles, first.angles, atol=1e-15)
    np.testing.assert_allclose(b.scan.angles, other.angles, atol=1e-15)
    np.testing.assert_allclose(a.scan.sensor_pose.as_array(), mount.as_array(), atol=1e-12)
    # a forward mount: FLASER in the first scan's geometry, ROBOTLASER1 for the other
    forward = LaserScan(np.full(180, 2.0), a0, inc, range_max=8.0, stamp=1.0)
    w = CarmenWriter(path, estimate_of="some.log")
    w.write(forward, Pose2D(), pose=Pose2D(1.0, 0.0, 0.0))
    w.write(other, Pose2D(), pose=Pose2D(2.0, 0.0, 0.0))
    assert w.close() and (w.written, w.robotlaser1) == (2, 1)
    assert "convention 'span'" in path.read_text() and "1 of 2 scans" in w.notes[0]
    assert [r.scan.n_beams for r in read_carmen(path, convention="span")] == [180, 180]
    empty = CarmenWriter(tmp_path / "none.clf", estimate_of="x")
    assert not empty.close() and not (tmp_path / "none.clf").exists()


@pytest.mark.parametrize("compress", [False, True])
def test_estimate_log_takes_other_poses_at_close(tmp_path, compress):
    """poses_at_close: close(poses) writes each scan at its pose (FLASER's x y θ; ROBOTLASER1's
    robot pose and its laser pose, the mount kept), the odometry, ranges and truth as given;
    a writer that streams takes no poses at close."""
    a0, inc = -math.pi / 2, math.pi / 179
    mount = Pose2D(0.1, 0.0, 0.0)
    forward = LaserScan(np.linspace(1.0, 3.0, 180), a0, inc, range_max=8.0, stamp=1.0,
                        sensor_pose=mount)  # fmt: skip
    other = make_scan(stamp=2.0, sensor_pose=mount)  # another geometry: ROBOTLASER1
    odom = [Pose2D(5.0, 6.0, 0.5), Pose2D(5.5, 6.0, 0.6)]
    path = tmp_path / "trajectory.clf"
    w = CarmenWriter(path, estimate_of="some.log", compress=compress, poses_at_close=True)
    w.write(forward, odom[0], Pose2D(9.0, 9.0, 0.0), pose=Pose2D(1.0, 0.0, 0.0))
    w.write(other, odom[1], pose=Pose2D(2.0, 0.0, 0.0))
    new = np.array([[1.5, -0.25, 0.3], [2.5, 0.75, -3.0]])
    bad = CarmenWriter(tmp_path / "x.clf", estimate_of="y", poses_at_close=True)
    bad.write(forward, odom[0])
    with pytest.raises(ValueError, match="expected 1 finite poses"):
        bad.close(new, "")  # one row per scan written
    assert not (tmp_path / "x.clf").exists()
    assert w.close(new, "the optimised poses") and w.robotlaser1 == 1
    text = (gzip.decompress(path.read_bytes()) if compress else path.read_bytes()).decode()
    assert "# the optimised poses\n" in text
    flaser = next(ln.split() for ln in text.splitlines() if ln.startswith("FLASER"))
    n = int(flaser[1])
    assert [float(v) for v in flaser[2 + n : 8 + n]] == [*new[0], *odom[0].as_array()]
    np.testing.assert_allclose([float(v) for v in flaser[2 : 2 + n]], forward.ranges, atol=1e-4)
    assert "TRUEPOS 9.0 9.0 0.0" in text  # the truth as written
    robot = next(ln.split() for ln in text.splitlines() if ln.startswith("ROBOTLASER1"))
    i = 10 + int(robot[8])
    laser, at = np.array(robot[i : i + 3], float), np.array(robot[i + 3 : i + 6], float)
    np.testing.assert_allclose(at, new[1], atol=1e-12)
    np.testing.assert_allclose(laser, Pose2D.from_array(new[1]).compose(mount).as_array(),
                               atol=1e-12)  # fmt: skip
    odom_line = next(ln.split() for ln in text.splitlines() if ln.startswith("ODOM"))
    assert [float(v) for v in odom_line[1:4]] == list(odom[1].as_array())  # as written
    streams = CarmenWriter(tmp_path / "s.clf", estimate_of="y")
    streams.write(forward, odom[0])
    with pytest.raises(ValueError, match="poses_at_close"):
        streams.close(new[:1], "")
    assert not (tmp_path / "s.clf").exists()
    held = CarmenWriter(tmp_path / "h.clf", estimate_of="y", poses_at_close=True)
    plain = CarmenWriter(tmp_path / "p.clf", estimate_of="y")
    for wr in (held, plain):
        wr.write(forward, odom[0], pose=Pose2D(1.0, 0.0, 0.0))
        wr.write(other, None, pose=Pose2D(2.0, 0.0, 0.0))
        assert wr.close()
    assert (tmp_path / "h.clf").read_bytes() == (tmp_path / "p.clf").read_bytes()


# -- reader: formats and skipping ----------------------------------------------------------
def test_gzip_detected_by_magic_not_name(tmp_path):
    recs = _records(count=3)
    plain = tmp_path / "a.clf"
    write_carmen(plain, recs)
    packed = tmp_path / "b.log"  # no .gz in the name
    packed.write_bytes(gzip.compress(plain.read_bytes()))
    _assert_same(list(read_carmen(packed)), recs)
    misnamed = tmp_path / "c.clf.gz"  # .gz name, plain content
    misnamed.write_bytes(plain.read_bytes())
    _assert_same(list(read_carmen(misnamed)), recs)


def test_comments_blank_lines_and_unknown_messages_skipped(tmp_path):
    lines = [
        "# CARMEN Logfile",
        "#no space comment",
        "",
        "   ",
        "PARAM robot_length 0.5 0.0 h 0.0",
        "PARAM lonely",
        "SYNC tag 0.5 h 0.5",
        "ODOM 1 2 3 0 0 0 0.9 h 0.9",
        flaser(R5, odom=(1.0, 2.0, 0.5), stamp=1.0),
        "NEFF 12 0.5 h 1.05",
        "RLASER 3 1 2 3 0 0 0 0 0 0 1.1 h 1.1",
        "RAWLASER1 garbage of a type we do not read",
        "FLASERX 6 1 2 3",  # only exact message names count
        "flaser 6 1 2 3",
        "#FLASER 6 1 2 3",
        "whatever else",
        "\t" + flaser(R5, odom=(1.5, 2.0, 0.5), stamp=2.0) + "   ",
    ]
    path = write_lines(tmp_path / "log.clf", lines)
    rd = CarmenReader(path)
    recs = list(rd.records())
    assert [r.scan.stamp for r in recs] == [1.0, 2.0]
    assert recs[1].odometry == Pose2D(1.5, 2.0, 0.5)
    assert rd.bad_lines == 0 and rd.lines == len(lines)
    assert rd.params["robot_length"] == "0.5"


def test_odometry_from_odom_fields_never_xyt(tmp_path):
    line = flaser(R5, odom=(1.0, 2.0, 0.3), xyt=(9.0, 9.0, -1.0), stamp=5.5)
    (rec,) = read_carmen(write_lines(tmp_path / "log.clf", [line]))
    assert rec.odometry == Pose2D(1.0, 2.0, 0.3)
    assert rec.scan.stamp == 5.5
    assert rec.truth is None


def test_truepos_attaches_to_preceding_flaser(tmp_path):
    lines = [
        truepos((7.0, 7.0, 0.0)),  # before any FLASER: ignored
        flaser(R5, stamp=1.0),
        "ODOM 1 2 3 0 0 0 0.9 h 0.9",
        truepos((1.0, 2.0, 0.1)),
        truepos((5.0, 5.0, 0.5)),  # a second one: the first after the FLASER wins
        flaser(R5, stamp=2.0),
        flaser(R5, stamp=3.0),
        truepos((3.0, 4.0, -0.2)),
    ]
    recs = list(read_carmen(write_lines(tmp_path / "log.clf", lines)))
    assert [r.truth for r in recs] == [Pose2D(1.0, 2.0, 0.1), None, Pose2D(3.0, 4.0, -0.2)]


def test_param_frontlaser_offset_sets_sensor_pose(tmp_path):
    lines = [
        flaser(R5, stamp=1.0),
        "PARAM robot_frontlaser_offset 0.3 0.0 h 0.0",
        flaser(R5, stamp=2.0),
    ]
    recs = list(read_carmen(write_lines(tmp_path / "log.clf", lines)))
    assert recs[0].scan.sensor_pose == Pose2D() and recs[1].scan.sensor_pose == Pose2D(0.3, 0, 0)


def test_all_invalid_scan_is_fine(tmp_path):
    lines = [flaser([0.0] * 6), flaser([50.0] * 6, stamp=2.0), flaser(["nan"] * 6, stamp=3.0)]
    recs = list(read_carmen(write_lines(tmp_path / "log.clf", lines)))
    assert len(recs) == 3 and all(not r.scan.valid.any() for r in recs)


def test_timestamps_going_backwards_keep_file_order(tmp_path):
    stamps = [10.0, 9.1, 9.5, 3.0, 11.0]
    lines = [flaser(R5, stamp=s) for s in stamps]
    recs = list(read_carmen(write_lines(tmp_path / "log.clf", lines)))
    assert [r.scan.stamp for r in recs] == stamps


def test_fov_parameter_sets_angles(tmp_path):
    path = write_lines(tmp_path / "log.clf", [flaser([1.0] * 361)])
    (rec,) = read_carmen(path, field_of_view_deg=360.0, convention="resolution")
    assert rec.scan.angle_min == pytest.approx(-math.pi)
    assert rec.scan.angle_increment == pytest.approx(2 * math.pi / 361)


# -- maximum range -------------------------------------------------------------------------
def test_max_range_learned_from_repeated_maximum(tmp_path):
    lines = [
        flaser([1.0, 30.0, 2.0, 3.0, 4.0, 5.0], stamp=1.0),  # lone max, nothing learned: inf
        flaser([1.0, 50.0, 2.0, 50.0, 4.0, 5.0], stamp=2.0),  # 50 repeats: the no-return value
        flaser([1.0, 50.0, 2.0, 3.0, 4.0, 5.0], stamp=3.0),  # a lone 50 is no return too
        flaser([1.0, 27.0, 27.0, 3.0, 4.0, 5.0], stamp=4.0),  # repeated 27 < 50 stays valid
        flaser([1.0, 60.0, 2.0, 3.0, 4.0, 5.0], stamp=5.0),  # above 50, alone: valid, inf
    ]
    rd = CarmenReader(write_lines(tmp_path / "log.clf", lines))
    recs = list(rd.records())
    assert [r.scan.range_max for r in recs] == [math.inf, 50.0, 50.0, 50.0, math.inf]
    assert [int(r.scan.valid.sum()) for r in recs] == [6, 4, 5, 6, 6]
    assert rd.no_return_value == 50.0


def test_max_range_argument_and_param(tmp_path):
    lines = [flaser([1.0, 30.0, 2.0, 3.0, 4.0, 5.0])]
    path = write_lines(tmp_path / "log.clf", lines)
    (rec,) = read_carmen(path, max_range=4.0)
    assert rec.scan.range_max == 4.0 and int(rec.scan.valid.sum()) == 3
    path = write_lines(tmp_path / "p.clf", ["PARAM robot_front_laser_max 5.0 0 h 0", *lines])
    (rec,) = read_carmen(path)
    assert rec.scan.range_max == 5.0 and int(rec.scan.valid.sum()) == 4
    (rec,) = read_carmen(path, max_range=math.inf)  # the argument wins
    assert int(rec.scan.valid.sum()) == 6
    with pytest.raises(ValueError, match="max_range"):
        read_carmen(path, max_range=0.0)


# -- malformed lines -----------------------------------------------------------------------
GOOD = flaser(R5, stamp=1.0)
BAD_LINES = [
    (GOOD.replace("FLASER 6 1.0", "FLASER 6", 1), "FLASER: expected 6 ranges, got 5"),
    (GOOD.replace("FLASER 6", "FLASER 7", 1), "FLASER: expected 7 ranges, got 6"),
    (GOOD.replace("FLASER 6", "FLASER six", 1), "beam count is not an integer: 'six'"),
    (GOOD.replace("FLASER 6", "FLASER 1", 1), "beam count must be >= 2"),
    ("FLASER", "missing the beam count"),
    (GOOD.replace(" 3.0 ", " 3.o ", 1), "FLASER: range 3 of 6 is not a number: '3.o'"),
    (flaser(R5, odom=("abc", 0.0, 0.0), xyt=(0, 0, 0)), "odom_x is not a number"),
    (flaser(R5, xyt=("abc", 0, 0)), "FLASER: x is not a number"),
    (flaser(R5, stamp="x1"), "ipc_timestamp is not a number"),
    (flaser(R5, stamp="nan"), "ipc_timestamp must be finite"),
    (truepos((1.0, 2.0, 3.0)).rsplit(" ", 1)[0], "TRUEPOS: expected 10 fields"),
    (truepos((1.0, float("nan"), 3.0)), "TRUEPOS: true_y must be finite"),
    ("PARAM robot_frontlaser_offset abc 0 h 0", "robot_frontlaser_offset is not a number"),
    ("PARAM robot_front_laser_max -3 0 h 0", "robot_front_laser_max must be > 0"),
    ("PARAM robot_front_laser_max", "missing its value"),
]


@pytest.mark.parametrize("bad, what", BAD_LINES)
def test_malformed_line_raises_with_file_line_and_what(tmp_path, bad, what):
    path = write_lines(tmp_path / "broken.clf", ["# header", GOOD, bad, GOOD])
    with pytest.raises(CarmenFormatError) as info:
        list(read_carmen(path))
    err = info.value
    msg = str(err)
    assert msg.startswith(f"{path}:3: ")
    assert "broken.clf" in msg and what in msg
    assert err.line == 3 and err.path == str(path) and what in err.reason
    assert isinstance(err, ValueError) and isinstance(err, LogFormatError)


@pytest.mark.parametrize("odom", [(math.nan, 0.0, 0.0), (0.0, 0.0, math.inf)])
def test_non_finite_odometry_keeps_the_scan_without_odometry(tmp_path, odom):
    """Issue 35: a non-finite odometry field is a bad value of that scan, not a bad line."""
    path = write_lines(tmp_path / "odom.clf", [GOOD, flaser(R5, odom=odom), GOOD])
    reader = CarmenReader(path)
    records = list(reader.records())
    assert [r.odometry is None for r in records] == [False, True, False]
    assert reader.bad_odometry == 1 and reader.first_bad_odometry_line == 2
    assert reader.bad_lines == 0 and "line 2" in reader.notes[0]


def test_format_errors_pickle():
    import pickle

    err = pickle.loads(pickle.dumps(CarmenFormatError("log.clf", 17, "FLASER: bad")))
    assert isinstance(err, CarmenFormatError) and str(err) == "log.clf:17: FLASER: bad"
    assert err.line == 17 and err.reason == "FLASER: bad"


def test_error_message_example_form(tmp_path):
    lines = ["#"] * 16 + [flaser([1.0] * 179).replace("FLASER 179", "FLASER 180", 1)]
    path = write_lines(tmp_path / "log.clf", lines)
    with pytest.raises(
        CarmenFormatError, match=r"log\.clf:17: FLASER: expected 180 ranges, got 179"
    ):
        list(read_carmen(path))


def test_skip_bad_lines_counts(tmp_path):
    bad = [b for b, _ in BAD_LINES[:5]]
    lines = [GOOD, bad[0], flaser(R5, stamp=2.0), BAD_LINES[13][0], truepos((1, 2, 3), stamp=2.0)]
    lines += [bad[1], bad[2], flaser(R5, stamp=3.0), BAD_LINES[12][0]]
    path = write_lines(tmp_path / "log.clf", lines)
    rd = CarmenReader(path, skip_bad_lines=True)
    recs = list(rd)
    assert [r.scan.stamp for r in recs] == [1.0, 2.0, 3.0]
    assert recs[1].truth == Pose2D(1, 2, 3) and recs[2].truth is None
    assert rd.bad_lines == 5
    assert [e.line for e in rd.errors] == [2, 4, 6, 7, 9]
    assert not rd.truncated
    # the reader restarts cleanly
    assert len(list(rd.records())) == 3 and rd.bad_lines == 5
    # read_carmen passes the option through
    assert len(list(read_carmen(path, skip_bad_lines=True))) == 3


def test_truepos_after_skipped_flaser_attaches_to_nothing(tmp_path):
    lines = [GOOD, BAD_LINES[0][0], truepos((1.0, 2.0, 3.0)), flaser(R5, stamp=2.0)]
    rd = CarmenReader(write_lines(tmp_path / "log.clf", lines), skip_bad_lines=True)
    recs = list(rd)
    assert [r.truth for r in recs] == [None, None] and rd.bad_lines == 1


def test_missing_file_fails_at_once(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_carmen(tmp_path / "nope.clf")


def test_truncated_last_line_warns_not_raises(tmp_path):
    cut = flaser(R5, stamp=3.0)[:40]
    lines = [GOOD, flaser(R5, stamp=2.0), truepos((1, 1, 1), stamp=2.0), cut]
    path = write_lines(tmp_path / "cut.clf", lines, newline_at_end=False)
    rd = CarmenReader(path)
    with pytest.warns(RuntimeWarning, match=r"cut\.clf.*truncated last line 4"):
        recs = list(rd)
    assert [r.scan.stamp for r in recs] == [1.0, 2.0] and rd.truncated and rd.bad_lines == 0
    assert recs[1].truth == Pose2D(1, 1, 1)


def test_complete_last_line_without_newline_is_read(tmp_path):
    path = write_lines(tmp_path / "log.clf", [GOOD, flaser(R5, stamp=2.0)], newline_at_end=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        recs = list(read_carmen(path))
    assert [r.scan.stamp for r in recs] == [1.0, 2.0]


def test_malformed_line_with_newline_at_end_still_raises(tmp_path):
    path = write_lines(tmp_path / "log.clf", [GOOD, GOOD[:40]])
    with pytest.raises(CarmenFormatError, match=r"log\.clf:2:"):
        list(read_carmen(path))


def test_truncated_gzip_stream_warns(tmp_path):
    plain = "\n".join(flaser([float(k % 7 + 1)] * 180, stamp=float(k)) for k in range(400)) + "\n"
    data = gzip.compress(plain.encode())
    path = tmp_path / "cut.clf.gz"
    path.write_bytes(data[: len(data) // 2])
    with pytest.warns(RuntimeWarning, match=r"cut\.clf\.gz"):
        recs = list(read_carmen(path))
    assert 0 < len(recs) < 400
    assert [r.scan.stamp for r in recs] == [float(k) for k in range(len(recs))]


def test_streaming_yields_before_the_end(tmp_path):
    lines = [flaser(R5, stamp=float(k)) for k in range(3)] + ["FLASER broken"]
    it = read_carmen(write_lines(tmp_path / "log.clf", lines))
    assert next(it).scan.stamp == 0.0 and next(it).scan.stamp == 1.0
    with pytest.raises(CarmenFormatError):
        next(it)


# -- TUM -----------------------------------------------------------------------------------
def test_tum_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    n = 200
    stamps = np.concatenate([[1.3e9 + 0.000123, 1.3e9 + 0.000124], rng.uniform(0, 1e4, n - 2)])
    thetas = np.concatenate(
        [
            [-math.pi, math.pi - 1e-15, 0.0, -0.0, 1e-300, math.pi / 2],
            rng.uniform(-math.pi, math.pi, n - 6),
        ]
    )
    poses = np.column_stack([rng.normal(0, 100, n), rng.normal(0, 1e-3, n), thetas])
    path = tmp_path / "traj.tum"
    write_tum(path, stamps, poses, header_comment="t x y z qx qy qz qw")
    t2, p2 = read_tum(path)
    np.testing.assert_array_equal(t2, stamps)
    np.testing.assert_array_equal(p2[:, :2], poses[:, :2])
    dtheta = np.angle(np.exp(1j * (p2[:, 2] - thetas)))
    assert np.max(np.abs(dtheta)) < 1e-12
    assert np.all((p2[:, 2] >= -math.pi) & (p2[:, 2] < math.pi))
    first = next(ln for ln in path.read_text().splitlines() if not ln.startswith("#")).split()
    assert len(first) == 8 and float(first[3]) == 0.0
    # what evo's reader does: numpy loadtxt with '#' comments
    arr = np.loadtxt(path, comments="#")
    assert arr.shape == (n, 8)
    np.testing.assert_allclose(arr[:, 6] ** 2 + arr[:, 7] ** 2, 1.0, atol=1e-15)


def test_tum_accepts_pose2d_sequence_and_empty(tmp_path):
    path = tmp_path / "t.tum"
    write_tum(path, [1.0, 2.0], [Pose2D(1, 2, 0.5), Pose2D(3, 4, -3.0)])
    t, p = read_tum(path)
    assert t.tolist() == [1.0, 2.0]
    np.testing.assert_allclose(p, [[1, 2, 0.5], [3, 4, -3.0]], atol=1e-12)
    write_tum(path, [], np.zeros((0, 3)))
    t, p = read_tum(path)
    assert t.shape == (0,) and p.shape == (0, 3)
    with pytest.raises(ValueError, match="2 stamps for 1 poses"):
        write_tum(path, [1.0, 2.0], [[0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="finite"):
        write_tum(path, [1.0], [[0.0, math.nan, 0.0]])


def test_tum_reads_general_quaternions_and_comments(tmp_path):
    q = [0.0, 0.0, math.sin(0.35), math.cos(0.35)]
    text = "# evo-style header\n\n1.5 1 2 0.7 {} {} {} {}\n  \n".format(*q)
    path = tmp_path / "t.tum"
    path.write_text(text)
    t, p = read_tum(path)
    assert t.tolist() == [1.5] and p[0, :2].tolist() == [1.0, 2.0]
    assert p[0, 2] == pytest.approx(0.7, abs=1e-12)
    gz = tmp_path / "t.bin"
    gz.write_bytes(gzip.compress(text.encode()))
    assert read_tum(gz)[0].tolist() == [1.5]


@pytest.mark.parametrize(
    "line, what",
    [
        ("1 2 3 0 0 0 0 1 9", "expected 8 fields (t x y z qx qy qz qw), got 9"),
        ("1 2 3 0 0 0 0", "expected 8 fields (t x y z qx qy qz qw), got 7"),
        ("1 2 y 0 0 0 0 1", "y is not a number: 'y'"),
        ("nan 2 3 0 0 0 0 1", "t must be finite"),
        ("1 2 3 0 0 0 0 inf", "qw must be finite"),
        ("1 2 3 0 0 0 0.5 0.5", "not a unit quaternion"),
        ("1 2 3 0 0 0 0 0", "not a unit quaternion"),
    ],
)
def test_tum_errors(tmp_path, line, what):
    path = tmp_path / "bad.tum"
    path.write_text(f"# header\n1 0 0 0 0 0 0 1\n{line}\n")
    with pytest.raises(TumFormatError) as info:
        read_tum(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}:3: ") and "bad.tum" in msg and what in msg
    assert info.value.line == 3 and isinstance(info.value, ValueError)


# -- the shared log ------------------------------------------------------------------------
@pytest.mark.skipif(not ACES.exists(), reason=f"shared data {ACES} is absent")
def test_reads_aces_log_head():
    it = read_carmen(ACES)
    recs = list(itertools.islice(it, 200))
    it.close()
    assert len(recs) == 200
    assert all(r.scan.n_beams == 180 for r in recs)
    assert all(math.isfinite(r.scan.stamp) for r in recs)
    assert recs[0].scan.angle_min == pytest.approx(-math.pi / 2)
    assert recs[0].scan.angle_increment == pytest.approx(DEG)
    assert all(r.scan.range_max == 50.0 for r in recs)  # its "no return" value, learned
    assert all(r.truth is None for r in recs)


# -- ROBOTLASER1 ---------------------------------------------------------------------------
def robotlaser1(
    ranges,
    *,
    robot=(0.0, 0.0, 0.0),
    offset=(0.0, 0.0, 0.0),
    laser=None,
    start=-math.pi / 2,
    res=DEG,
    fov=None,
    max_range=50.0,
    remissions=(),
    n=None,
    n_rem=None,
    stamp=1.0,
    vel=(0.1, 0.2, 0.3, 0.4, 0.5),
    host="h",
):
    """A ROBOTLASER1 line; the laser pose is ``robot ⊕ offset`` unless ``laser`` is given.
    Any field may be a string (to break the line)."""
    if laser is None:
        laser = tuple(Pose2D(*robot).compose(Pose2D(*offset)))
    n = len(ranges) if n is None else n
    n_rem = len(remissions) if n_rem is None else n_rem
    fov = len(ranges) * res if fov is None else fov
    fields = [
        "ROBOTLASER1",
        "0",
        _num(start),
        _num(fov),
        _num(res),
        _num(max_range),
        "0.01",
        "0",
        str(n),
        *(_num(r) for r in ranges),
        str(n_rem),
        *(_num(r) for r in remissions),
        *(_num(v) for v in laser),
        *(_num(v) for v in robot),
        *(_num(v) for v in vel),
        _num(stamp),
        host,
        _num(stamp),
    ]
    return " ".join(fields)


def write_robotlaser1_log(path: Path, records):
    """A tiny ROBOTLASER1 writer: ``records`` are ``(scan, robot_pose)``; the scan's geometry,
    ``range_max`` and stamp go on the line and its laser pose is ``robot ⊕ sensor_pose``."""
    lines = ["# ROBOTLASER1 test log"]
    for scan, robot in records:
        lines.append(
            robotlaser1(
                scan.ranges.tolist(),
                robot=tuple(robot),
                laser=tuple(robot.compose(scan.sensor_pose)),
                start=scan.angle_min,
                res=scan.angle_increment,
                max_range=scan.range_max,
                remissions=[0.5] * scan.n_beams,
                stamp=scan.stamp,
            )
        )
    return write_lines(path, lines)


def test_robotlaser1_own_geometry_range_and_poses(tmp_path):
    robot = (1.0, 2.0, math.pi / 2)
    offset = (0.3, 0.1, 0.2)
    line = robotlaser1(
        [1.0, 4.0, 5.0, 3.999, "nan"],
        robot=robot,
        offset=offset,
        start=-1.0,
        res=0.01,
        max_range=4.0,
        remissions=[7.0] * 5,
        stamp=12.5,
    )
    laser = [float(v) for v in line.split()[20:23]]  # robot ⊕ offset, as the helper wrote it
    assert laser == pytest.approx([0.9, 2.3, math.pi / 2 + 0.2], abs=1e-12)
    (rec,) = read_carmen(write_lines(tmp_path / "rl.clf", [line]))
    scan = rec.scan
    assert scan.n_beams == 5 and scan.stamp == 12.5
    assert scan.angle_min == -1.0 and scan.angle_increment == 0.01
    assert scan.range_max == 4.0
    assert scan.valid.tolist() == [True, False, False, True, False]  # >= max_range: invalid
    assert rec.odometry == Pose2D(*robot)  # the estimate is of the robot ...
    np.testing.assert_allclose(tuple(scan.sensor_pose), offset, atol=1e-12)  # ... laser on it
    assert rec.truth is None


def test_robotlaser1_pose_fields_swapped_would_be_caught(tmp_path):
    # robot and laser poses differ by a pure rotation: a reader mixing them up gives a
    # sensor_pose of the wrong sign or the laser's pose as odometry
    line = robotlaser1(R5, robot=(5.0, -1.0, 0.5), laser=(5.0, -1.0, 1.0))
    (rec,) = read_carmen(write_lines(tmp_path / "rl.clf", [line]))
    assert rec.odometry == Pose2D(5.0, -1.0, 0.5)
    assert rec.scan.sensor_pose.theta == pytest.approx(0.5, abs=1e-12)
    assert rec.scan.sensor_pose.translation_norm < 1e-12


pose_st = st.builds(
    Pose2D,
    st.floats(-1e4, 1e4),
    st.floats(-1e4, 1e4),
    st.floats(-math.pi, math.pi, exclude_max=True),
)
offset_st = st.builds(
    Pose2D,
    st.floats(-2.0, 2.0),
    st.floats(-2.0, 2.0),
    st.floats(-math.pi, math.pi, exclude_max=True),
)


@given(robot=pose_st, offset=offset_st, n=st.sampled_from([1, 2, 180, 181, 361, 541]))
def test_robotlaser1_write_read_round_trip(tmp_path_factory, robot, offset, n):
    """write (laser = robot ⊕ offset) -> read: sensor_pose = ⊖robot ⊕ laser gives offset back."""
    rng = np.random.default_rng(n)
    res = math.pi / max(n, 2)
    scan = LaserScan(
        rng.uniform(0.1, 7.9, n), -math.pi / 2, res, range_max=8.0, stamp=3.25, sensor_pose=offset
    )
    path = write_robotlaser1_log(tmp_path_factory.mktemp("rl") / "rt.clf", [(scan, robot)])
    (rec,) = read_carmen(path)
    assert rec.odometry == robot
    got = rec.scan.sensor_pose
    # the laser pose was written with 17 digits at up to 1e4 m: composition loses ~1e-12 rel
    assert got.x == pytest.approx(offset.x, abs=1e-8)
    assert got.y == pytest.approx(offset.y, abs=1e-8)
    assert math.remainder(got.theta - offset.theta, math.tau) == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_array_equal(rec.scan.ranges, scan.ranges)
    assert rec.scan.angle_min == scan.angle_min and rec.scan.angle_increment == res
    assert rec.scan.range_max == 8.0 and rec.scan.stamp == 3.25


def test_robotlaser1_ignores_flaser_options_and_params(tmp_path):
    lines = [
        "PARAM robot_front_laser_max 2.0 0 h 0",
        "PARAM robot_frontlaser_offset 0.7 0 h 0",
        robotlaser1([1.0, 3.0, 3.0, 9.0], max_range=9.0, res=0.5 * DEG, start=-0.3),
        flaser(R5),
    ]
    path = write_lines(tmp_path / "mix.clf", lines)
    rd = CarmenReader(path, field_of_view_deg=90.0, convention="span")
    rl, fl = list(rd)
    assert rl.scan.range_max == 9.0 and rl.scan.valid.tolist() == [True, True, True, False]
    assert rl.scan.angle_min == -0.3 and rl.scan.angle_increment == 0.5 * DEG
    assert rl.scan.sensor_pose == Pose2D()
    assert fl.scan.range_max == 2.0 and fl.scan.sensor_pose == Pose2D(0.7, 0.0, 0.0)
    assert fl.scan.angle_min == pytest.approx(-math.pi / 4)
    # an explicit max_range wins over the line's own field
    (rl2, _) = read_carmen(path, max_range=2.5)
    assert rl2.scan.range_max == 2.5 and rl2.scan.valid.tolist() == [True, False, False, False]


def test_robotlaser1_does_not_teach_the_no_return_value(tmp_path):
    lines = [robotlaser1([1.0, 9.0, 9.0, 2.0], max_range=10.0), flaser([1.0, 9.0, 2, 3, 4, 5])]
    rd = CarmenReader(write_lines(tmp_path / "log.clf", lines))
    rl, fl = list(rd)
    assert rd.no_return_value is None
    assert rl.scan.valid.all() and fl.scan.valid.all() and fl.scan.range_max == math.inf


GOOD_RL = robotlaser1([1.0, 2.0, 3.0], remissions=[0.1, 0.2, 0.3], stamp=1.5)
BAD_RL_LINES = [
    ("ROBOTLASER1 0 -1.5 3.1 0.01", "ROBOTLASER1: line has 5 fields, too few"),
    (robotlaser1(R5, start="abc"), "ROBOTLASER1: start_angle is not a number: 'abc'"),
    (robotlaser1(R5, start="inf"), "ROBOTLASER1: start_angle must be finite"),
    (robotlaser1(R5, fov="wide"), "ROBOTLASER1: fov is not a number"),
    (robotlaser1(R5, res=0.0), "ROBOTLASER1: angular_res must be non-zero"),
    (robotlaser1(R5, max_range=0.0), "ROBOTLASER1: max_range must be > 0"),
    (robotlaser1(R5, max_range="nan"), "ROBOTLASER1: max_range must be > 0"),
    (robotlaser1(R5, n="six"), "ROBOTLASER1: beam count n is not an integer: 'six'"),
    (robotlaser1(R5, n=0), "ROBOTLASER1: beam count n must be >= 1"),
    (
        robotlaser1(R5, n=7, remissions=[0.5] * 6),
        "ROBOTLASER1: n_rem (field 17, after 7 ranges) is not an integer: '0.5'",
    ),
    (robotlaser1(R5, n=7), "ROBOTLASER1: expected at least 31 fields for 7 ranges"),
    (robotlaser1(R5, n=5), "ROBOTLASER1: n_rem (field 15, after 5 ranges) is not an integer"),
    (robotlaser1(R5, n=60), "ROBOTLASER1: expected at least 84 fields for 60 ranges"),
    (robotlaser1(R5, remissions=[1.0] * 6, n_rem=5), "n_rem is 5 but the line has 6 fields"),
    (robotlaser1(R5, remissions=[1.0] * 6, n_rem=7), "n_rem is 7 but the line has 6 fields"),
    (robotlaser1(R5, n_rem="x"), "n_rem (field 16, after 6 ranges) is not an integer: 'x'"),
    (robotlaser1([1, 2, "3.o", 4, 5, 6]), "ROBOTLASER1: range 3 of 6 is not a number: '3.o'"),
    (robotlaser1(R5, remissions=[1, "q"]), "ROBOTLASER1: remission 2 of 2 is not a number"),
    (robotlaser1(R5, laser=(0.0, "nan", 0.0)), "ROBOTLASER1: laser_y must be finite"),
    (robotlaser1(R5, robot=(0, 0, "inf"), laser=(0, 0, 0)), "ROBOTLASER1: robot_θ must be finite"),
    (robotlaser1(R5, robot=("x", 0, 0), laser=(0, 0, 0)), "ROBOTLASER1: robot_x is not a number"),
    (robotlaser1(R5, vel=(0, 0, 0, "s", 0)), "ROBOTLASER1: side_safety is not a number"),
    (robotlaser1(R5, stamp="t"), "ROBOTLASER1: ipc_timestamp is not a number"),
    (robotlaser1([1.0] * 400, res=DEG), "ROBOTLASER1: LaserScan.angle_increment"),
]
BAD_ODOM_LINES = [
    ("ODOM 1 2 3 0 0 0 0.9 h", "ODOM: expected 10 fields (ODOM x y θ tv rv accel"),
    ("ODOM 1 2 3 0 0 0 0.9 h 0.9 extra", "ODOM: expected 10 fields"),
    ("ODOM one 2 3 0 0 0 0.9 h 0.9", "ODOM: x is not a number: 'one'"),
    ("ODOM 1 2 nan 0 0 0 0.9 h 0.9", "ODOM: θ must be finite"),
    ("ODOM 1 2 3 0 0 a 0.9 h 0.9", "ODOM: accel is not a number"),
    ("ODOM 1 2 3 0 0 0 t h 0.9", "ODOM: ipc_timestamp is not a number"),
    ("ODOM 1 2 3 0 0 0 0.9 h inf", "ODOM: logger_timestamp must be finite"),
]


@pytest.mark.parametrize("odometry", ["scan", "interpolated"])
@pytest.mark.parametrize("bad, what", BAD_RL_LINES + BAD_ODOM_LINES)
def test_malformed_robotlaser1_and_odom_raise(tmp_path, bad, what, odometry):
    lines = ["# header", "ODOM 0 0 0 0 0 0 0.5 h 0.5", GOOD_RL, bad, GOOD_RL]
    path = write_lines(tmp_path / "broken.clf", lines)
    it = read_carmen(path, odometry=odometry)
    with pytest.raises(CarmenFormatError) as info:
        list(it)
    err = info.value
    assert str(err).startswith(f"{path}:4: ") and what in str(err)
    assert err.line == 4 and what in err.reason
    assert isinstance(err, LogFormatError) and isinstance(err, ValueError)


def test_good_robotlaser1_helper_line_reads(tmp_path):
    # the BAD_RL_LINES above differ from this good line in one field each
    (rec,) = read_carmen(write_lines(tmp_path / "ok.clf", [robotlaser1(R5, remissions=[1] * 6)]))
    assert rec.scan.n_beams == 6 and rec.scan.valid.all()


def test_skipped_bad_robotlaser1_ends_its_record(tmp_path):
    bad = BAD_RL_LINES[1][0]
    lines = [GOOD_RL, bad, truepos((1.0, 2.0, 3.0)), "ODOM x", robotlaser1(R5, stamp=2.0)]
    rd = CarmenReader(write_lines(tmp_path / "log.clf", lines), skip_bad_lines=True)
    recs = list(rd)
    assert [r.scan.stamp for r in recs] == [1.5, 2.0]
    assert [r.truth for r in recs] == [None, None]  # the TRUEPOS was the skipped scan's
    assert rd.bad_lines == 2 and [e.line for e in rd.errors] == [2, 4]
    assert rd.odom_messages == 0


def test_truepos_attaches_to_robotlaser1(tmp_path):
    lines = [GOOD_RL, truepos((1.0, 2.0, 0.5), stamp=1.5), robotlaser1(R5, stamp=2.0)]
    recs = list(read_carmen(write_lines(tmp_path / "log.clf", lines)))
    assert [r.truth for r in recs] == [Pose2D(1.0, 2.0, 0.5), None]


# -- laser_offset ----------------------------------------------------------------------------
def test_laser_offset_overrides_param_and_robotlaser1_fields(tmp_path):
    lines = [
        "PARAM robot_frontlaser_offset 0.3 0 h 0",
        flaser(R5, stamp=1.0),
        robotlaser1(R5, robot=(1.0, 1.0, 1.0), offset=(0.2, 0.1, 0.05), stamp=2.0),
    ]
    path = write_lines(tmp_path / "log.clf", lines)
    fl, rl = read_carmen(path)
    assert fl.scan.sensor_pose == Pose2D(0.3, 0.0, 0.0)
    np.testing.assert_allclose(tuple(rl.scan.sensor_pose), (0.2, 0.1, 0.05), atol=1e-12)
    mount = Pose2D(-0.1, 0.05, math.pi)
    rd = CarmenReader(path, laser_offset=mount)
    assert rd.laser_offset == mount
    fl, rl = list(rd)
    assert fl.scan.sensor_pose == mount and rl.scan.sensor_pose == mount
    assert rl.odometry == Pose2D(1.0, 1.0, 1.0)  # the odometry stays the robot's
    (fl,) = itertools.islice(read_carmen(path, laser_offset=(0.5, 0.0, 0.0)), 1)
    assert fl.scan.sensor_pose == Pose2D(0.5, 0.0, 0.0)  # a 3-sequence is taken too


@pytest.mark.parametrize(
    "bad, exc, what",
    [
        ("0.3", TypeError, "laser_offset must be a Pose2D"),
        ((0.3, 0.0), ValueError, "laser_offset: a pose array needs 3 values"),
        ((0.3, math.nan, 0.0), ValueError, "laser_offset: Pose2D.y must be finite"),
        (object(), TypeError, "laser_offset must be a Pose2D"),
    ],
)
def test_laser_offset_validated(tmp_path, bad, exc, what):
    path = write_lines(tmp_path / "log.clf", [flaser(R5)])
    with pytest.raises(exc, match=what):
        CarmenReader(path, laser_offset=bad)
    with pytest.raises(exc, match=what):
        read_carmen(path, laser_offset=bad)


# -- any FLASER beam count -------------------------------------------------------------------
@pytest.mark.parametrize(
    "n, fov, first_deg, inc_deg",
    [(541, 180.0, -90.0, 1 / 3), (361, 180.0, -90.0, 0.5), (541, 270.0, -135.0, 0.5)],
)
def test_flaser_541_and_361_beams(tmp_path, n, fov, first_deg, inc_deg):
    ranges = np.round(np.linspace(0.5, 20.0, n), 4)
    ranges[[7, 100]] = 81.83  # "no return", repeated: learned
    line = flaser(ranges.tolist(), odom=(1.0, 0.0, 0.1), stamp=4.0)
    rd = CarmenReader(write_lines(tmp_path / "wide.clf", [line]), field_of_view_deg=fov)
    (rec,) = list(rd)
    assert rec.scan.n_beams == n
    assert rec.scan.angle_min == pytest.approx(first_deg * DEG, abs=1e-12)
    assert rec.scan.angle_increment == pytest.approx(inc_deg * DEG, abs=1e-12)
    assert rec.scan.angles[-1] == pytest.approx(-first_deg * DEG, abs=1e-12)  # odd: span
    np.testing.assert_array_equal(rec.scan.ranges, ranges)
    assert rd.no_return_value == 81.83 and int((~rec.scan.valid).sum()) == 2


# -- message types skipped, order kept -------------------------------------------------------
def test_other_messages_skipped_between_scans_and_file_order_kept(tmp_path):
    lines = [
        "# a comment FLASER 6 1 2 3",
        "RLASER 6 1 2 3 4 5 6 0 0 0 0 0 0 5.0 h 5.0",
        robotlaser1(R5, stamp=9.0),
        "SYNC tag 0.5 h 0.5",
        flaser(R5, stamp=5.0),  # earlier than the scan before it
        "NEFF 12 0.5 h 1.05",
        "RAWLASER3 1 2 3",
        "  # indented comment",
        robotlaser1(R5, stamp=5.0),  # same stamp
        flaser(R5, stamp=4.5),
        "GPSNMEA whatever",
    ]
    rd = CarmenReader(write_lines(tmp_path / "log.clf", lines))
    recs = list(rd)
    assert [r.scan.stamp for r in recs] == [9.0, 5.0, 5.0, 4.5]
    assert [r.scan.n_beams for r in recs] == [6, 6, 6, 6]
    assert [r.scan.angle_min == -math.pi / 2 for r in recs] == [True] * 4
    assert rd.bad_lines == 0 and rd.lines == len(lines)


# -- odometry="interpolated" -----------------------------------------------------------------
def odom(x, y, th, stamp):
    return f"ODOM {_num(x)} {_num(y)} {_num(th)} 0.1 0.0 0 {_num(stamp)} h {_num(stamp)}"


def _interp(path, **kw):
    return list(read_carmen(path, odometry="interpolated", **kw))


def test_interpolated_linear_in_xy_shortest_angle_in_theta(tmp_path):
    lines = [
        odom(0.0, 0.0, 3.0, 10.0),
        flaser(R5, odom=(9.0, 9.0, 0.0), stamp=10.25),
        odom(1.0, 2.0, -3.0, 11.0),  # +3 rad -> -3 rad: the short way is through pi
        robotlaser1(R5, robot=(8.0, 8.0, 0.0), offset=(0.2, 0.0, 0.0), stamp=10.5),
        odom(1.0, 2.0, -3.0, 12.0),
    ]
    path = write_lines(tmp_path / "log.clf", lines)
    own = list(read_carmen(path))
    assert [r.odometry for r in own] == [Pose2D(9.0, 9.0, 0.0), Pose2D(8.0, 8.0, 0.0)]
    rd = CarmenReader(path, odometry="interpolated")
    a, b = list(rd)
    assert rd.odometry == "interpolated" and rd.odom_messages == 3
    dth = 2 * math.pi - 6.0
    assert a.odometry.x == pytest.approx(0.25) and a.odometry.y == pytest.approx(0.5)
    assert a.odometry.theta == pytest.approx(3.0 + 0.25 * dth, abs=1e-12)
    assert b.odometry.x == pytest.approx(0.5) and b.odometry.y == pytest.approx(1.0)
    assert abs(math.remainder(b.odometry.theta - math.pi, math.tau)) < 1e-12
    np.testing.assert_allclose(tuple(b.scan.sensor_pose), (0.2, 0.0, 0.0), atol=1e-12)


def test_interpolated_nearest_outside_the_odom_stream(tmp_path):
    lines = [
        flaser(R5, stamp=0.5),  # before any ODOM line and before the first stamp
        odom(1.0, 0.0, 0.1, 1.0),
        odom(2.0, 0.0, 0.2, 2.0),
        flaser(R5, stamp=0.9),  # written after, stamped before the first ODOM
        flaser(R5, stamp=2.0),  # exactly on one
        flaser(R5, stamp=7.0),  # after the last
    ]
    recs = _interp(write_lines(tmp_path / "log.clf", lines))
    want = [(1.0, 0.1), (1.0, 0.1), (2.0, 0.2), (2.0, 0.2)]
    assert [(r.odometry.x, r.odometry.theta) for r in recs] == want


def test_interpolated_scan_lines_out_of_time_order_with_odom(tmp_path):
    # increasing stamps in each stream, but the lines interleave out of time order (aces)
    lines = [
        odom(0.0, 0.0, 0.0, 0.0),
        odom(1.0, 0.0, 0.0, 1.0),
        flaser(R5, stamp=0.5),  # written after the ODOM at t=1
        flaser(R5, stamp=1.5),  # written before the ODOM at t=1.2 and t=2
        odom(1.2, 0.0, 0.0, 1.2),
        odom(2.0, 0.0, 0.0, 2.0),
    ]
    recs = _interp(write_lines(tmp_path / "log.clf", lines))
    assert [r.odometry.x for r in recs] == pytest.approx([0.5, 1.2 + 0.3 / 0.8 * 0.8])


def test_interpolated_with_timestamps_going_backwards(tmp_path):
    """Two clocks (intel): the pose is interpolated in time between the ODOM lines of the
    window (16 before the scan, those after it up to the first stamped at or after it) that
    bracket the scan's stamp; records stay in file order."""
    lines = [
        odom(0.0, 0.0, 0.0, 10.0),
        odom(1.0, 0.0, 0.0, 11.0),
        flaser(R5, stamp=11.5),
        odom(5.0, 0.0, 0.0, 10.2),  # the clock jumps back
        odom(7.0, 0.0, 0.0, 10.4),
        flaser(R5, stamp=10.3),  # this scan's stamp went back too
        odom(3.0, 0.0, 0.0, 12.0),  # releases both
        flaser(R5, stamp=13.0),  # after every ODOM stamp: the nearest, the one at t=12
    ]
    recs = _interp(write_lines(tmp_path / "log.clf", lines))
    assert [r.scan.stamp for r in recs] == [11.5, 10.3, 13.0]
    # 11.5: between t=11 (x=1) and t=12 (x=3), skipping the lines of the other clock
    # 10.3: between t=10.2 (x=5) and t=10.4 (x=7), not the t=10 line written first
    assert [r.odometry.x for r in recs] == pytest.approx([2.0, 6.0, 3.0])


def test_interpolated_never_uses_odom_lines_far_back_in_the_file(tmp_path):
    lines = [
        flaser(R5, stamp=1e6),  # held (no ODOM reaches its stamp): keeps old lines in memory
        odom(100.0, 0.0, 0.0, 10.25),  # brackets 10.3 in time, but 21 ODOM lines before it
        *(odom(0.0, 0.0, 0.0, float(t)) for t in range(11, 31)),
        flaser(R5, stamp=10.3),  # the clock went back
        odom(7.0, 0.0, 0.0, 10.4),
    ]
    recs = _interp(write_lines(tmp_path / "log.clf", lines))
    assert [r.scan.stamp for r in recs] == [1e6, 10.3]
    assert recs[0].odometry.x == 0.0  # the latest stamp of its window (t=30)
    assert recs[1].odometry.x == 7.0  # the nearest after, not interpolated from x=100


def test_interpolated_streams_holding_a_scan_until_its_odom(tmp_path):
    lines = [
        odom(0.0, 0.0, 0.0, 0.0),
        flaser(R5, stamp=0.5),
        flaser(R5, stamp=0.7),  # ends the first record (no TRUEPOS for it)
        "ODOM broken",
    ]
    it = read_carmen(write_lines(tmp_path / "a.clf", lines), odometry="interpolated")
    with pytest.raises(CarmenFormatError, match=r"a\.clf:4:"):  # the scan is still held
        next(it)
    it = read_carmen(write_lines(tmp_path / "a.clf", lines), odometry="scan")
    assert next(it).scan.stamp == 0.5  # without interpolation it comes out
    lines = [
        odom(0.0, 0.0, 0.0, 0.0),
        flaser(R5, stamp=0.5),
        odom(1.0, 0.0, 0.0, 1.0),
        flaser(R5, stamp=1.5),
        odom(2.0, 0.0, 0.0, 2.0),
        "FLASER broken",
    ]
    it = read_carmen(write_lines(tmp_path / "b.clf", lines), odometry="interpolated")
    assert next(it).odometry.x == 0.5  # released by the ODOM at t=1 (and the next scan)
    with pytest.raises(CarmenFormatError, match=r"b\.clf:6:"):
        next(it)


def test_interpolated_memory_is_bounded(tmp_path):
    # a scan stamped after every ODOM line is released after 100 ODOM lines, not at the end
    lines = [odom(0.0, 0.0, 0.0, 0.0), flaser(R5, stamp=1e6)]
    lines += [odom(float(k), 0.0, 0.0, float(k)) for k in range(1, 3000)]
    lines += [flaser(R5, stamp=2e6), "FLASER broken"]
    rd = CarmenReader(write_lines(tmp_path / "log.clf", lines), odometry="interpolated")
    it = rd.records()
    (rec,) = itertools.islice(it, 1)  # comes out before the broken last line
    assert rec.odometry.x == 100.0  # the latest of the window: ODOM lines 1..100 after it
    assert len(rd._odoms) <= 116
    with pytest.raises(CarmenFormatError, match=":3003:"):
        next(it)


def test_interpolated_releases_scans_when_too_many_wait(tmp_path):
    # no ODOM line after the first: the scans wait, until more than 1000 do
    lines = [odom(1.0, 2.0, 0.5, 0.0)] + [flaser(R5, stamp=1.0 + k) for k in range(1100)]
    lines.append("FLASER broken")
    it = read_carmen(write_lines(tmp_path / "log.clf", lines), odometry="interpolated")
    recs = list(itertools.islice(it, 50))  # before the broken last line
    assert [r.scan.stamp for r in recs] == [1.0 + k for k in range(50)]
    assert all(r.odometry == Pose2D(1.0, 2.0, 0.5) for r in recs)  # the nearest: the last
    with pytest.raises(CarmenFormatError, match=":1102:"):
        list(it)


def test_interpolated_without_odom_lines_raises_naming_the_scan(tmp_path):
    lines = ["# no ODOM here", flaser(R5, stamp=1.0), flaser(R5, stamp=2.0)]
    path = write_lines(tmp_path / "log.clf", lines)
    with pytest.raises(CarmenFormatError, match=r"log\.clf:2: odometry='interpolated', but no"):
        _interp(path)
    assert len(list(read_carmen(path))) == 2  # fine with the scans' own fields


def test_interpolated_keeps_truepos_and_skip_bad_lines(tmp_path):
    lines = [
        odom(0.0, 0.0, 0.0, 0.0),
        flaser(R5, stamp=0.5),
        truepos((4.0, 4.0, 0.0), stamp=0.5),
        "ODOM broken",
        odom(2.0, 0.0, 0.0, 1.0),
    ]
    rd = CarmenReader(
        write_lines(tmp_path / "log.clf", lines), odometry="interpolated", skip_bad_lines=True
    )
    (rec,) = list(rd)
    assert rec.truth == Pose2D(4.0, 4.0, 0.0) and rec.odometry.x == 1.0
    assert rd.bad_lines == 1 and rd.odom_messages == 2


def test_odometry_option_validated(tmp_path):
    path = write_lines(tmp_path / "log.clf", [flaser(R5)])
    with pytest.raises(ValueError, match="odometry must be one of"):
        CarmenReader(path, odometry="odom")
    with pytest.raises(ValueError, match="odometry must be one of"):
        read_carmen(path, odometry="Interpolated")


def _reference_interpolation(odom_t, odom_p, t):
    """Independent: ``searchsorted`` on increasing ODOM stamps (ties: the latest line at or
    before, the earliest at or after), theta along the shorter arc."""
    i = np.searchsorted(odom_t, t, side="right") - 1
    j = np.searchsorted(odom_t, t, side="left")
    out = np.empty((len(t), 3))
    for k in range(len(t)):
        lo, hi = i[k], j[k]
        if lo < 0:
            out[k] = odom_p[0]
        elif hi >= len(odom_t) or odom_t[hi] == odom_t[lo]:
            out[k] = odom_p[lo]
        else:
            s = (t[k] - odom_t[lo]) / (odom_t[hi] - odom_t[lo])
            d = odom_p[hi] - odom_p[lo]
            d[2] = math.remainder(d[2], math.tau)
            out[k] = odom_p[lo] + s * d
    out[:, 2] = np.angle(np.exp(1j * out[:, 2]))
    return out


@given(
    odom_dt=st.lists(st.sampled_from([0.0, 0.05, 0.1, 0.13]), min_size=1, max_size=30),
    scan_t=st.lists(st.floats(-0.5, 4.0), min_size=1, max_size=10),
    seed=st.integers(0, 2**16),
)
def test_interpolated_matches_reference_on_monotone_streams(
    tmp_path_factory, odom_dt, scan_t, seed
):
    rng = np.random.default_rng(seed)
    ot = np.cumsum(odom_dt)
    op = np.column_stack([rng.normal(0, 3, ot.size), rng.normal(0, 3, ot.size)])
    op = np.column_stack([op, rng.uniform(-math.pi, math.pi, ot.size)])
    # lines in time order, scans written just after the last ODOM at or before them
    events = [(t, 0, k) for k, t in enumerate(ot)] + [(t, 1, k) for k, t in enumerate(scan_t)]
    lines = []
    for t, kind, k in sorted(events):
        lines.append(odom(*op[k], t) if kind == 0 else flaser(R5, stamp=t))
    path = tmp_path_factory.mktemp("i") / "log.clf"
    recs = _interp(write_lines(path, lines))
    got = np.array([tuple(r.odometry) for r in recs])
    stamps = np.array([r.scan.stamp for r in recs])
    want = _reference_interpolation(ot, op, stamps)
    np.testing.assert_allclose(got[:, :2], want[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (got[:, 2] - want[:, 2]))), 0.0, atol=1e-9)


# -- pipes and damaged gzip streams ----------------------------------------------------------
PIPED_LINES = [
    "PARAM robot_front_laser_max 7.5",
    flaser(R5, stamp=10.0),
    robotlaser1([1.0, 2.0, 3.0], stamp=10.5),
    flaser(R5, odom=(0.1, 0.0, 0.0), stamp=11.0),
    flaser(R5, odom=(0.2, 0.0, 0.0), stamp=11.0),
]


@pytest.mark.parametrize("compress", [False, True])
def test_carmen_reads_a_fifo_whole_every_pass(tmp_path, compress):
    """A FIFO (``<(zcat log.gz)``) can be read once: the reader copies it and every pass,
    and the stamp pass, reads all of it, from its first byte."""
    text = ("\n".join(PIPED_LINES) + "\n").encode()
    data = gzip.compress(text) if compress else text
    with fifo_with(tmp_path, data) as fifo:
        reader = CarmenReader(fifo)
        first = [r.scan.stamp for r in reader]
        again = [r.scan.stamp for r in reader.records()]
        stamps = reader.scan_stamps().tolist()
    assert first == again == stamps == [10.0, 10.5, 11.0, 11.0]
    assert reader.name == str(fifo) and reader.params["robot_front_laser_max"] == "7.5"


def test_carmen_errors_from_a_fifo_name_it(tmp_path):
    text = ("\n".join([*PIPED_LINES, "FLASER 3 1 2", flaser(R5)]) + "\n").encode()
    with fifo_with(tmp_path, text) as fifo, pytest.raises(CarmenFormatError) as info:
        list(CarmenReader(fifo))
    assert str(info.value).startswith(f"{fifo}:{len(PIPED_LINES) + 1}: FLASER")


def test_scan_stamps_are_the_records_stamps(tmp_path):
    lines = [*PIPED_LINES, "ODOM 0 0 0 0 0 0 12 h 12", flaser(R5, stamp=9.0), "FLASER x"]
    path = write_lines(tmp_path / "log.clf", lines)
    reader = CarmenReader(path, skip_bad_lines=True)
    assert reader.scan_stamps().tolist() == [r.scan.stamp for r in reader]
    assert reader.bad_lines == 1


@pytest.mark.parametrize("compress", [False, True])
def test_tum_reads_a_pipe_from_its_first_byte(tmp_path, compress):
    """``/dev/stdin`` or ``<(…)``: opening the path twice would lose what the first open
    read (the magic bytes)."""
    path = tmp_path / "t.tum"
    write_tum(path, [1.25, 2.5], [[1.0, 2.0, 0.5], [3.0, 4.0, -3.0]])
    data = path.read_bytes()
    with pipe_with(gzip.compress(data) if compress else data) as pipe:
        t, p = read_tum(pipe)
    assert t.tolist() == [1.25, 2.5]
    np.testing.assert_allclose(p, [[1, 2, 0.5], [3, 4, -3.0]], atol=1e-12)


def _damaged_gzip(text: str, how: str) -> bytes:
    data = bytearray(gzip.compress(text.encode(), mtime=0))
    if how == "truncated":
        return bytes(data[: len(data) - 12])
    if how == "corrupt":
        data[12] ^= 0xFF  # inside the deflate stream
        return bytes(data)
    data[-8:-4] = b"\0\0\0\0"  # how == "crc": the stored CRC-32
    return bytes(data)


DAMAGE = ["truncated", "corrupt", "crc"]


@pytest.mark.parametrize("how", DAMAGE)
def test_a_damaged_gzip_tum_file_is_a_format_error(tmp_path, how):
    text = "".join(f"{k}.5 {k} 0 0 0 0 0 1\n" for k in range(50))
    path = tmp_path / "traj.tum.gz"
    path.write_bytes(_damaged_gzip(text, how))
    with pytest.raises(TumFormatError) as info:
        read_tum(path)
    assert str(info.value).startswith(f"{path}:") and "gzip stream" in info.value.reason
    assert info.value.line >= 1


@pytest.mark.parametrize("how", ["corrupt", "crc"])
def test_a_corrupt_gzip_carmen_log_is_a_format_error(tmp_path, how):
    text = "\n".join(flaser(R5, stamp=float(k)) for k in range(50)) + "\n"
    path = tmp_path / "log.clf.gz"
    path.write_bytes(_damaged_gzip(text, how))
    with pytest.raises(CarmenFormatError, match=r"log\.clf\.gz:\d+: corrupt gzip stream"):
        list(read_carmen(path))


# -- the ranges' text: one byte matrix per scan, the very text of the per-reading loop -------
_READINGS = st.one_of(
    st.floats(0.0, 100.0),
    st.floats(-1.0, 1e7),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(0, 10**6).map(lambda k: (k + 0.5) / 1e4),  # ties at the last decimal
    st.sampled_from([0.0, -0.0, 5e-5, -1e-5, 0.03125, 7.99996, 8.0, 8.00004, 1e12]),
)


@given(st.lists(_READINGS, max_size=60), st.sampled_from([8.0, 81.91, math.inf]))
def test_ranges_text_is_the_per_reading_text(values, range_max):
    from fuzzypos.io import carmen_write as cw

    scan = LaserScan(np.array(values, dtype=float), -1.0, 0.01, range_max=range_max)
    assert cw._ranges_raw(scan) == cw._ranges_raw_exact(scan)
    fill = repr(range_max) if math.isfinite(range_max) else "0"
    assert cw._ranges_filled(scan, fill) == cw._ranges_filled_exact(scan, fill)
    finite = np.array([v for v in values if math.isfinite(v)], dtype=float)
    fast = cw._fixed_text(finite)
    per_value = " ".join(f"{v:.4f}".rstrip("0").removesuffix(".") for v in finite.tolist())
    assert fast is None or fast == per_value
