"""fuzzypos.io.rosbag: ROS1 bags and ROS2 bag directories written here with rosbags' writers
(scans, odometry at its own rate, tf_static), errors, and the shared aces bag."""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from fuzzypos.geometry import Pose2D, compose, inverse, wrap_angle
from fuzzypos.io import LogFormatError
from fuzzypos.io.rosbag import (
    ODOMETRY_TYPE,
    BagFormatError,
    BagReader,
    BagTopicError,
    _interpolate_one,
    interpolate_poses,
    is_ros1_bag,
    is_ros2_bag,
    read_bag,
)
from helpers import (
    ANGLE_INC,
    ANGLE_MIN,
    DATA,
    MOUNT_POSE,
    N_BEAMS,
    ODOM_T,
    RANGE_MAX,
    SCAN_T,
    BagBuilder,
    make_bag,
    pipe_with,
    scan_ranges,
    standard,
    truth,
)

ACES_BAG = DATA / "aces" / "aces.bag"

KINDS = ["ros1", "ros2-sqlite3", "ros2-mcap"]


@pytest.fixture(params=KINDS)
def kind(request: pytest.FixtureRequest) -> str:
    return str(request.param)


# -- sniffing ----------------------------------------------------------------------------
def test_sniffs_by_content_not_name(tmp_path):
    ros1 = make_bag(tmp_path, "ros1", standard)
    renamed = ros1.rename(tmp_path / "recording.dat")
    ros2 = make_bag(tmp_path, "ros2-sqlite3", standard)
    text = tmp_path / "fake.bag"
    text.write_text("not a bag\n")
    assert is_ros1_bag(renamed) and not is_ros2_bag(renamed)
    assert is_ros2_bag(ros2) and not is_ros1_bag(ros2)
    assert not is_ros1_bag(text) and not is_ros2_bag(text)
    assert not is_ros1_bag(tmp_path / "missing.bag") and not is_ros2_bag(tmp_path)
    # and a ROS1 bag reads under any name
    assert BagReader(renamed).ros_version == 1
    assert len(list(BagReader(renamed))) == len(SCAN_T)
    assert BagReader(ros2).ros_version == 2


# -- the records -------------------------------------------------------------------------
def test_reads_scans_odometry_and_mounting(tmp_path, kind):
    path = make_bag(tmp_path, kind, standard)
    reader = BagReader(path)
    assert reader.scan_topic == "/scan" and reader.odom_topic == "/odom"
    assert reader.has_odometry and reader.scan_count == len(SCAN_T)
    assert reader.odometry_stamps.shape == (len(ODOM_T),)
    assert reader.base_frame == "base_link" and reader.scan_frame == "laser"
    assert reader.sensor_pose_source == "tf_static"
    np.testing.assert_allclose(reader.sensor_pose.as_array(), MOUNT_POSE, atol=1e-12)

    recs = list(reader.records())
    assert len(recs) == len(SCAN_T) == reader.messages
    for k, (rec, t) in enumerate(zip(recs, SCAN_T)):
        s = rec.scan
        assert s.stamp == pytest.approx(t, abs=1e-9)
        assert (s.angle_min, s.angle_increment) == pytest.approx((ANGLE_MIN, ANGLE_INC))
        assert (s.range_min, s.range_max) == (0.0, RANGE_MAX)
        assert s.ranges.dtype == np.float64
        np.testing.assert_array_equal(s.ranges, scan_ranges(k).astype(np.float64))
        assert s.valid[1:5].sum() == 0 and s.valid[5:].all() and s.valid[0]
        np.testing.assert_allclose(s.sensor_pose.as_array(), MOUNT_POSE, atol=1e-12)
        assert rec.truth is None
        assert rec.odometry is not None
        expect = truth(min(max(t, ODOM_T[0]), ODOM_T[-1]))  # nearest outside the span
        got = rec.odometry.as_array()
        np.testing.assert_allclose(got[:2], expect[:2], atol=1e-9)
        assert abs(float(wrap_angle(got[2] - expect[2]))) < 1e-9
    assert reader.extrapolated == 1  # the scan at 0.05 s, before the first odometry
    assert reader.zero_stamps == 0 and reader.angle_max_mismatches == 0
    # the odometry really is interpolated: scans fall between odometry stamps
    assert any(min(abs(t - u) for u in ODOM_T) > 0.02 for t in SCAN_T)


def test_read_bag_streams_and_records_rereads(tmp_path):
    path = make_bag(tmp_path, "ros1", standard)
    it = read_bag(path)
    first = next(it)
    it.close()  # stopping early closes the bag
    assert first.scan.stamp == pytest.approx(SCAN_T[0])
    reader = BagReader(path)
    a = [r.scan.stamp for r in reader]
    b = [r.scan.stamp for r in reader.records()]
    assert a == b and len(a) == len(SCAN_T) and reader.messages == len(SCAN_T)


def test_laser_offset_overrides_tf_static(tmp_path):
    path = make_bag(tmp_path, "ros1", standard)
    offset = Pose2D(-0.3, 0.1, 2.5)
    reader = BagReader(path, laser_offset=offset)
    assert reader.sensor_pose == offset and reader.sensor_pose_source == "laser_offset"
    assert all(r.scan.sensor_pose == offset for r in reader)
    with pytest.raises(TypeError, match="Pose2D"):
        BagReader(path, laser_offset=(0.1, 0.0, 0.0))  # type: ignore[arg-type]


def test_static_chain_walks_edges_backwards(tmp_path):
    # base_footprint is the root; odometry's child is base_link, so the chain goes
    # base_link -> base_footprint (inverted) -> laser
    tf = [
        ("/base_footprint", "base_link", 0.0, 0.1, 0.4, 0.0),  # leading "/" (ROS1 tf)
        ("base_footprint", "laser", 0.5, 0.0, -0.7, 0.0),
    ]
    path = make_bag(tmp_path, "ros2-sqlite3", lambda b: standard(b, tf=tf))
    reader = BagReader(path)
    expect = compose(inverse([0.0, 0.1, 0.4]), [0.5, 0.0, -0.7])
    np.testing.assert_allclose(reader.sensor_pose.as_array(), expect, atol=1e-12)
    assert reader.notes == []


def test_tilted_mount_is_noted(tmp_path):
    tf = [("base_link", "laser", 0.1, 0.0, 0.5, math.pi)]  # upside down
    path = make_bag(tmp_path, "ros1", lambda b: standard(b, tf=tf))
    reader = BagReader(path)
    assert reader.sensor_pose.x == pytest.approx(0.1)
    assert any("tilted by 180.0°" in n for n in reader.notes)


def test_no_tf_static_gives_identity_with_a_note(tmp_path):
    path = make_bag(tmp_path, "ros1", lambda b: standard(b, tf=None))
    reader = BagReader(path)
    assert reader.sensor_pose == Pose2D() and reader.sensor_pose_source == "identity"
    assert any("no /tf_static" in n for n in reader.notes)


def test_unconnected_frames_give_identity_with_a_note(tmp_path):
    tf = [("base_link", "camera", 0.1, 0.0, 0.0, 0.0)]
    path = make_bag(tmp_path, "ros1", lambda b: standard(b, tf=tf))
    reader = BagReader(path)
    assert reader.sensor_pose == Pose2D() and reader.sensor_pose_source == "identity"
    assert any("no static transform chain base_link -> laser" in n for n in reader.notes)


def test_base_frame_argument(tmp_path):
    path = make_bag(tmp_path, "ros1", standard)
    reader = BagReader(path, base_frame="laser_mount")
    np.testing.assert_allclose(reader.sensor_pose.as_array(), [0.1, -0.02, 0.2], atol=1e-12)


# -- topics ------------------------------------------------------------------------------
def test_two_scan_topics_need_a_choice(tmp_path, kind):
    path = make_bag(tmp_path, kind, lambda b: standard(b, scan_topics=("/scan", "/rear/scan")))
    with pytest.raises(BagTopicError) as info:
        BagReader(path)
    msg = str(info.value)
    assert "/scan" in msg and "/rear/scan" in msg and "scan_topic=" in msg
    assert str(path) in msg and isinstance(info.value, ValueError)
    reader = BagReader(path, scan_topic="/rear/scan")
    assert reader.scan_topic == "/rear/scan" and len(list(reader)) == len(SCAN_T)


def test_bad_topic_arguments(tmp_path):
    path = make_bag(tmp_path, "ros1", standard)
    with pytest.raises(BagTopicError, match=r"scan_topic='/nope': no such topic.*/scan"):
        BagReader(path, scan_topic="/nope")
    with pytest.raises(BagTopicError, match=r"is a nav_msgs/msg/Odometry topic, not"):
        BagReader(path, scan_topic="/odom")
    with pytest.raises(BagTopicError, match=r"odom_topic='/scan' is a sensor_msgs"):
        BagReader(path, odom_topic="/scan")


def test_two_odometry_topics_need_a_choice(tmp_path):
    def build(b: BagBuilder) -> list[tuple[str, float, Any]]:
        msgs = standard(b)
        msgs += [("/wheel_odom", t, b.odom(t, (0.0, 0.0, 0.0))) for t in ODOM_T]
        return sorted(msgs, key=lambda m: m[1])

    path = make_bag(tmp_path, "ros1", build)
    with pytest.raises(
        BagTopicError, match=r"2 nav_msgs/msg/Odometry topics \(/odom, /wheel_odom\)"
    ):
        BagReader(path)
    reader = BagReader(path, odom_topic="/wheel_odom")
    assert all(r.odometry == Pose2D() for r in reader)


def test_bag_without_scans(tmp_path):
    path = make_bag(tmp_path, "ros1", lambda b: [("/odom", 1.0, b.odom(1.0, (0, 0, 0)))])
    with pytest.raises(BagTopicError, match="no sensor_msgs/msg/LaserScan topic"):
        BagReader(path)


def test_bag_without_odometry(tmp_path, kind):
    path = make_bag(tmp_path, kind, lambda b: standard(b, odometry=False))
    reader = BagReader(path)
    assert not reader.has_odometry and reader.odom_topic is None
    assert any("without an odometry prior" in n for n in reader.notes)
    recs = list(reader)
    assert len(recs) == len(SCAN_T) and all(r.odometry is None for r in recs)
    # no odometry frame: base_link by default, so tf_static still gives the mounting
    np.testing.assert_allclose(recs[0].scan.sensor_pose.as_array(), MOUNT_POSE, atol=1e-12)


# -- odd messages ----------------------------------------------------------------------------
def test_zero_stamps_backwards_odometry_and_angle_max(tmp_path):
    def build(b: BagBuilder) -> list[tuple[str, float, Any]]:
        return [
            ("/odom", 1.0, b.odom(2.0, (2.0, 0.0, 0.0))),  # stamps backwards in bag order
            ("/odom", 1.1, b.odom(1.0, (1.0, 0.0, 0.0))),
            ("/scan", 1.2, b.scan(0.0, scan_ranges(0))),  # zero stamp: record time 1.2
            ("/scan", 1.3, b.scan(1.5, scan_ranges(1), angle_max=5.0)),
        ]

    reader = BagReader(make_bag(tmp_path, "ros1", build))
    np.testing.assert_array_equal(reader.odometry_stamps, [1.0, 2.0])
    assert any("backwards 1 times" in n for n in reader.notes)
    recs = list(reader)
    assert recs[0].scan.stamp == pytest.approx(1.2) and reader.zero_stamps == 1
    assert recs[0].odometry is not None and recs[0].odometry.x == pytest.approx(1.2)
    assert recs[1].odometry is not None and recs[1].odometry.x == pytest.approx(1.5)
    assert reader.angle_max_mismatches == 1


def test_malformed_scan_names_bag_topic_and_message(tmp_path):
    def build(b: BagBuilder) -> list[tuple[str, float, Any]]:
        return [
            ("/scan", 1.0, b.scan(1.0, scan_ranges(0))),
            ("/scan", 2.0, b.scan(2.0, scan_ranges(1), range_min=5.0, range_max=1.0)),
        ]

    path = make_bag(tmp_path, "ros1", build)
    it = iter(BagReader(path))
    assert next(it).scan.stamp == pytest.approx(1.0)
    with pytest.raises(BagFormatError) as info:
        next(it)
    err = info.value
    assert err.line == 2 and str(err).startswith(f"{path}:2: /scan: ")
    assert "range_max" in err.reason and isinstance(err, LogFormatError)


@pytest.mark.parametrize("kind", ["ros1", "ros2-mcap"])
def test_angle_max_on_the_wrong_side_of_angle_min_is_an_error(tmp_path, kind):
    """Beams at angle_min + i*increment that sweep away from angle_max (the issue's scan of
    57°…237°): an inconsistent message, named by bag, topic and index."""

    def build(b: BagBuilder) -> list[tuple[str, float, Any]]:
        return [
            ("/scan", 1.0, b.scan(1.0, scan_ranges(0))),
            ("/scan", 2.0, b.scan(2.0, scan_ranges(1), angle_min=1.0, angle_max=-1.0)),
            ("/scan", 3.0, b.scan(3.0, scan_ranges(2))),
        ]

    path = make_bag(tmp_path, kind, build)
    it = iter(BagReader(path))
    assert next(it).scan.stamp == pytest.approx(1.0)
    with pytest.raises(BagFormatError) as info:
        next(it)
    err = info.value
    assert err.line == 2 and str(err).startswith(f"{path}:2: /scan: angle_max -1 lies below")
    assert "57.3° to " in err.reason and isinstance(err, LogFormatError)
    # and says what a consistent clockwise scan looks like
    assert "negative increment" in err.reason


def test_a_clockwise_scan_with_a_negative_increment_is_consistent(tmp_path):
    """sensor_msgs/LaserScan: a scan may turn clockwise, angle_max < angle_min with a
    negative increment (an upside-down mount): read as it is, no mismatch."""

    def build(b: BagBuilder) -> list[tuple[str, float, Any]]:
        a1 = 1.2 - (N_BEAMS - 1) * 0.3
        return [("/scan", 1.0, b.scan(1.0, scan_ranges(0), angle_min=1.2, angle_max=a1,
                                       angle_increment=-0.3))]  # fmt: skip

    reader = BagReader(make_bag(tmp_path, "ros1", build))
    (rec,) = list(reader)
    np.testing.assert_allclose(rec.scan.angles, 1.2 - 0.3 * np.arange(N_BEAMS), atol=1e-6)
    assert reader.angle_max_mismatches == 0


@pytest.mark.parametrize("kind", KINDS)
def test_scan_stamps_from_the_headers_are_the_records_stamps(tmp_path, kind):
    def build(b: BagBuilder) -> list[tuple[str, float, Any]]:
        msgs = standard(b)
        msgs.append(("/scan", 9.5, b.scan(0.0, scan_ranges(0))))  # zero stamp: record time
        msgs.append(("/scan", 9.6, b.scan(1.0e9 + 0.123456789, scan_ranges(1))))
        return msgs

    reader = BagReader(make_bag(tmp_path, kind, build))
    stamps = reader.scan_stamps()
    assert stamps.tolist() == [r.scan.stamp for r in reader]
    assert len(stamps) == len(SCAN_T) + 2 and stamps[-2] == pytest.approx(9.5)
    assert not stamps.flags.writeable


def test_a_damaged_message_definition_is_a_format_error(tmp_path):
    """A bag stores its own message definitions: one whose Odometry lacks ``pose`` (a
    damaged definition) decodes, but its fields are not there."""
    fields = dict(get_typestore(Stores.ROS1_NOETIC).fielddefs)
    del fields[ODOMETRY_TYPE]
    store = get_typestore(Stores.EMPTY)
    store.register(fields)
    store.register(get_types_from_msg("std_msgs/Header header\nfloat64 speed", ODOMETRY_TYPE))
    b = BagBuilder(1)
    b.store, b.T = store, store.types
    header = b.header(1.0, "odom")
    msgs = [("/odom", 1.0, store.types[ODOMETRY_TYPE](header=header, speed=1.0))]
    path = b.write(tmp_path / "odd.bag", "", [*msgs, ("/scan", 1.1, b.scan(1.1, scan_ranges(0)))])
    with pytest.raises(BagFormatError, match=r"odd\.bag:1: /odom: malformed nav_msgs") as info:
        BagReader(path)
    assert isinstance(info.value.__cause__, AttributeError)


def test_a_ros1_bag_through_a_pipe_reads(tmp_path):
    path = make_bag(tmp_path, "ros1", standard)
    with pipe_with(path.read_bytes()) as pipe:
        reader = BagReader(pipe)
    assert reader.name == str(pipe) and reader.ros_version == 1
    assert [r.scan.stamp for r in reader] == [r.scan.stamp for r in BagReader(path)]


# -- not bags, broken bags ---------------------------------------------------------------------
def test_missing_path_is_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"missing\.bag"):
        BagReader(tmp_path / "missing.bag")


@pytest.mark.parametrize(
    "content", [b"", b"hello\n", b"\x89MCAP0\r\n" + bytes(40), b"#ROSBAG V1.2\n" + bytes(100)]
)
def test_non_bag_file_is_a_typed_error(tmp_path, content):
    path = tmp_path / "x.bag"
    path.write_bytes(content)
    with pytest.raises(BagFormatError, match=r"not a bag: a file that is neither a ROS1 bag"):
        BagReader(path)


def test_directory_without_metadata(tmp_path):
    with pytest.raises(BagFormatError, match=r"a directory without metadata\.yaml"):
        BagReader(tmp_path)


@pytest.mark.parametrize("cut", [13, 200, 0.5, -10])
def test_truncated_ros1_bag_is_a_typed_error(tmp_path, cut):
    data = make_bag(tmp_path, "ros1", standard).read_bytes()
    n = int(len(data) * cut) if isinstance(cut, float) else cut
    path = tmp_path / "cut.bag"
    path.write_bytes(data[:n])
    with pytest.raises(BagFormatError, match="cannot open the ROS1 bag") as info:
        BagReader(path)
    assert info.value.__cause__ is not None
    assert type(info.value.__cause__).__module__.startswith("rosbags")


def test_corrupt_message_is_a_typed_error(tmp_path):
    path = make_bag(tmp_path, "ros1", lambda b: standard(b, odometry=False, tf=None))
    data = bytearray(path.read_bytes())
    # damage the frame_id string length of the third scan ("laser": 5 bytes, then the text)
    where = [i for i in range(len(data)) if data[i : i + 9] == b"\x05\x00\x00\x00laser"]
    for k in range(where[2], where[2] + 4):
        data[k] = 0xFF
    path.write_bytes(bytes(data))
    reader = BagReader(path)
    with pytest.raises(BagFormatError, match=r":3: /scan: cannot decode") as info:
        list(reader)
    assert info.value.__cause__ is not None


def test_broken_ros2_metadata_is_a_typed_error(tmp_path):
    path = make_bag(tmp_path, "ros2-sqlite3", standard)
    (path / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed\n")
    with pytest.raises(BagFormatError, match="cannot open the ROS2 bag") as info:
        BagReader(path)
    assert info.value.__cause__ is not None


def test_lost_messages_warn(tmp_path):
    import sqlite3

    path = make_bag(tmp_path, "ros2-sqlite3", standard)
    (db,) = path.glob("*.db3")
    with sqlite3.connect(db) as con:  # metadata.yaml still lists every message
        con.execute(
            "DELETE FROM messages WHERE id IN (SELECT m.id FROM messages m JOIN topics t "
            "ON m.topic_id = t.id WHERE t.name = '/scan' ORDER BY m.timestamp DESC LIMIT 3)"
        )
        con.execute(
            "DELETE FROM messages WHERE id IN (SELECT m.id FROM messages m JOIN topics t "
            "ON m.topic_id = t.id WHERE t.name = '/odom' LIMIT 5)"
        )
    with pytest.warns(RuntimeWarning, match=r"/odom: read 75 odometry messages .* lists 80"):
        reader = BagReader(path)
    assert any("may be damaged" in n for n in reader.notes)
    with pytest.warns(RuntimeWarning, match=r"/scan: read 19 scans .* lists 22"):
        recs = list(reader)
    assert len(recs) == 19 and reader.missing == 3


def test_errors_pickle():
    import pickle

    err = BagTopicError("a.bag", 0, "2 topics")
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is BagTopicError and str(back) == str(err) == "a.bag: 2 topics"


# -- interpolation -----------------------------------------------------------------------------
finite = st.floats(-50.0, 50.0, allow_nan=False)
angle = st.floats(-math.pi, math.pi, allow_nan=False, exclude_max=True)


@st.composite
def trajectories(draw: Any) -> tuple[np.ndarray, np.ndarray]:
    n = draw(st.integers(1, 8))
    steps = draw(st.lists(st.floats(0.0, 2.0), min_size=n - 1, max_size=n - 1))
    t0 = draw(st.floats(-10.0, 10.0))
    t = t0 + np.concatenate([[0.0], np.cumsum(steps)])
    poses = np.array([[draw(finite), draw(finite), draw(angle)] for _ in range(n)])
    return t, poses


@given(
    trajectories(), st.lists(st.floats(-15.0, 30.0), min_size=1, max_size=6), finite, finite, angle
)
def test_interpolation_commutes_with_rigid_motions(traj, query, gx, gy, gth):
    t, poses = traj
    g = np.array([gx, gy, gth])
    moved = compose(g, poses)
    a = compose(g, interpolate_poses(t, poses, query))
    b = interpolate_poses(t, moved, query)
    np.testing.assert_allclose(a[:, :2], b[:, :2], atol=1e-9)
    assert np.all(np.abs(wrap_angle(a[:, 2] - b[:, 2])) < 1e-9)


@given(trajectories(), st.floats(-15.0, 30.0))
def test_interpolation_between_neighbours_on_the_short_arc(traj, q):
    t, poses = traj
    out = interpolate_poses(t, poses, q)
    assert out.shape == (3,) and -math.pi <= out[2] < math.pi
    one = _interpolate_one(t, poses, q)  # the per-scan path agrees
    np.testing.assert_allclose(one.as_array()[:2], out[:2], atol=1e-9)
    assert abs(float(wrap_angle(one.theta - out[2]))) < 1e-9
    if q < t[0]:
        np.testing.assert_allclose(out, poses[0], atol=1e-12)
        return
    if q >= t[-1]:
        np.testing.assert_allclose(out, poses[-1], atol=1e-12)
        return
    i = int(np.searchsorted(t, q, side="right"))
    a, b = poses[i - 1], poses[i]
    f = (q - t[i - 1]) / (t[i] - t[i - 1])
    np.testing.assert_allclose(out[:2], a[:2] + f * (b[:2] - a[:2]), atol=1e-9)
    # θ on the shorter arc: the two legs add up to the short way from a to b
    d_ab = abs(float(wrap_angle(b[2] - a[2])))
    d_a = abs(float(wrap_angle(out[2] - a[2])))
    d_b = abs(float(wrap_angle(b[2] - out[2])))
    assert d_a + d_b == pytest.approx(d_ab, abs=1e-9)
    assert d_a == pytest.approx(f * d_ab, abs=1e-9)


@given(trajectories())
def test_interpolation_hits_the_samples(traj):
    t, poses = traj
    out = interpolate_poses(t, poses, t)
    # at a repeated stamp, the last sample with that stamp
    last = np.array([np.flatnonzero(t == s)[-1] for s in t])
    np.testing.assert_allclose(out[:, :2], poses[last, :2], atol=1e-12)
    assert np.all(np.abs(wrap_angle(out[:, 2] - poses[last, 2])) < 1e-12)


def test_interpolation_crosses_pi_the_short_way():
    out = interpolate_poses([0.0, 1.0], [[0, 0, 3.0], [0, 0, -3.0]], 0.5)
    assert abs(out[2]) == pytest.approx(math.pi)  # through ±π, not through 0


def test_interpolation_rejects_bad_input():
    with pytest.raises(ValueError, match="non-decreasing"):
        interpolate_poses([1.0, 0.0], [[0, 0, 0], [1, 0, 0]], 0.5)
    with pytest.raises(ValueError, match="non-empty"):
        interpolate_poses([], np.zeros((0, 3)), 0.5)
    with pytest.raises(ValueError, match="shape"):
        interpolate_poses([0.0, 1.0], [[0, 0, 0]], 0.5)
    with pytest.raises(ValueError, match="finite"):
        interpolate_poses([0.0, 1.0], [[0, 0, 0], [1, 0, 0]], math.nan)


# -- the shared aces bag ----------------------------------------------------------------------
@pytest.mark.skipif(not ACES_BAG.exists(), reason=f"shared data {ACES_BAG} is absent")
def test_reads_the_aces_bag():
    t0 = time.perf_counter()
    reader = BagReader(ACES_BAG)
    assert reader.ros_version == 1 and reader.scan_topic == "/scan"
    assert reader.odom_topic == "/odom" and reader.has_odometry
    assert reader.odometry_stamps.shape == (7375,)
    assert reader.sensor_pose == Pose2D() and reader.sensor_pose_source == "tf_static"
    n = at_max = invalid = 0
    first = last = None
    for rec in reader:
        s = rec.scan
        assert s.n_beams == 180 and rec.odometry is not None
        at_max += int(np.count_nonzero(s.ranges == 50.0))
        invalid += int(np.count_nonzero(~s.valid))
        first = first or rec
        last = rec
        n += 1
    elapsed = time.perf_counter() - t0
    assert n == 7374 == reader.scan_count
    assert first is not None and last is not None
    s = first.scan
    assert s.angle_min == pytest.approx(-math.pi / 2, abs=1e-6)
    assert s.angles[-1] == pytest.approx(math.pi / 2, abs=1e-6)
    assert s.range_max == 50.0 and s.range_min == pytest.approx(0.3)
    assert at_max == 11139 == invalid  # "no return" is range_max: invalid, and nothing else
    assert last.scan.stamp > first.scan.stamp
    assert reader.extrapolated == 0 and reader.zero_stamps == 0 and reader.notes == []
    print(f"aces.bag: {n} scans read in {elapsed:.2f} s")
