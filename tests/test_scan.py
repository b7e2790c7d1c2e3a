"""Tests for fuzzypos.scan (ROS LaserScan semantics, SPEC "Conventions")."""

from __future__ import annotations

import dataclasses
import math
import pickle

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fuzzypos.geometry import Pose2D
from fuzzypos.scan import LaserScan, ScanError

ONE_DEGREE = math.radians(1.0)


def make(ranges, angle_min=-math.pi / 2, angle_increment=ONE_DEGREE, **kw):
    return LaserScan(ranges, angle_min, angle_increment, **kw)


# -- construction & storage -----------------------------------------------------------------------
def test_fields_order_defaults_and_storage():
    src = [1, 2, 3]
    s = LaserScan(src, 0.0, 0.1)
    assert list(LaserScan.__dataclass_fields__) == [
        "ranges",
        "angle_min",
        "angle_increment",
        "range_min",
        "range_max",
        "stamp",
        "sensor_pose",
    ]
    assert s.ranges.dtype == np.float64
    assert s.ranges.shape == (3,)
    np.testing.assert_array_equal(s.ranges, [1.0, 2.0, 3.0])
    assert s.range_min == 0.0 and s.range_max == math.inf and s.stamp == 0.0
    assert s.sensor_pose == Pose2D(0.0, 0.0, 0.0)
    assert s.n_beams == 3


def test_ranges_are_a_read_only_copy():
    src = np.array([1.0, 2.0, 3.0])
    s = LaserScan(src, 0.0, 0.1)
    src[0] = 99.0
    assert s.ranges[0] == 1.0
    with pytest.raises(ValueError):
        s.ranges[1] = 5.0
    with pytest.raises(ValueError):
        s.angles[0] = 5.0
    with pytest.raises(ValueError):
        s.valid[0] = False


def test_a_pickled_scan_comes_back_equal_and_read_only():
    """Through pickle (a process pool's, Ray's) the scan is the same to the bit, and its
    arrays are read-only again, as the constructor makes them."""
    scan = LaserScan([1.0, np.inf, 2.5, 0.0], -0.5, 0.25, 0.1, 10.0, 3.5, Pose2D(0.1, 0.0, 0.2))
    back = pickle.loads(pickle.dumps(scan))
    for name in ("ranges", "angles", "valid"):
        a, b = getattr(scan, name), getattr(back, name)
        np.testing.assert_array_equal(a, b)
        assert a.dtype == b.dtype and not b.flags.writeable, name
    assert (back.angle_min, back.stamp, back.sensor_pose) == (-0.5, 3.5, Pose2D(0.1, 0.0, 0.2))
    with pytest.raises(ValueError, match="read-only"):
        back.ranges[0] = 5.0


def test_frozen():
    s = LaserScan([1.0], 0.0, 0.1)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.angle_min = 1.0  # type: ignore[misc]


def test_angles_ros_semantics():
    s = LaserScan([1.0] * 5, -0.2, 0.1)
    np.testing.assert_allclose(s.angles, [-0.2, -0.1, 0.0, 0.1, 0.2], atol=1e-15)
    assert s.angles.shape == (5,)
    neg = LaserScan([1.0] * 3, 1.0, -0.5)
    np.testing.assert_allclose(neg.angles, [1.0, 0.5, 0.0])


# -- validity -------------------------------------------------------------------------------------
def test_valid_mask():
    r = [1.0, math.nan, math.inf, -math.inf, 0.0, 10.0, 9.999, 0.05, 0.1, -1.0]
    s = LaserScan(r, 0.0, 0.01, range_min=0.1, range_max=10.0)
    expected = [True, False, False, False, False, False, True, False, True, False]
    np.testing.assert_array_equal(s.valid, expected)
    assert s.valid.dtype == np.bool_


def test_zero_invalid_even_with_zero_range_min():
    s = LaserScan([0.0, 1e-6, 3.0], 0.0, 0.1, range_min=0.0)
    np.testing.assert_array_equal(s.valid, [False, True, True])


def test_reading_at_range_max_is_invalid():
    # real scanners report "no return" as exactly range_max (SPEC: intel 81.83 m)
    s = LaserScan([81.83, 81.82, 81.83], 0.0, 0.1, range_max=81.83)
    np.testing.assert_array_equal(s.valid, [False, True, False])


def test_nan_inf_zero_are_not_errors():
    s = LaserScan([math.nan, math.inf, 0.0], 0.0, 0.1)
    assert not s.valid.any()
    assert np.isnan(s.points_sensor()).all()


# -- points ---------------------------------------------------------------------------------------
def test_points_known_beams():
    s = LaserScan([2.0, 3.0, 4.0], -math.pi / 2, math.pi / 2)
    np.testing.assert_allclose(s.points_sensor(), [[0.0, -2.0], [3.0, 0.0], [0.0, 4.0]], atol=1e-12)


def test_points_invalid_rows_are_nan():
    s = LaserScan([1.0, math.nan, 0.0, 2.0], 0.0, math.pi / 2, range_max=5.0)
    p = s.points_sensor()
    assert p.shape == (4, 2)
    np.testing.assert_array_equal(np.isnan(p).all(axis=1), [False, True, True, False])
    np.testing.assert_allclose(p[[0, 3]], [[1.0, 0.0], [0.0, -2.0]], atol=1e-12)
    assert np.isnan(s.points_robot()[[1, 2]]).all()


@given(st.floats(0.2, 50.0), st.integers(2, 400))
def test_points_of_a_wall_lie_on_the_wall(d, n):
    # wall x = d seen over bearings in (-80°, 80°): r = d / cos(bearing)
    a0, a1 = math.radians(-80.0), math.radians(80.0)
    inc = (a1 - a0) / (n - 1)
    ang = a0 + np.arange(n) * inc
    s = LaserScan(d / np.cos(ang), a0, inc)
    p = s.points_sensor()
    assert s.valid.all()
    np.testing.assert_allclose(p[:, 0], d, rtol=1e-9)
    np.testing.assert_allclose(p[:, 1], d * np.tan(ang), rtol=1e-9, atol=1e-9)


def test_negative_increment_mirrors_points():
    r = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    inc = math.radians(10.0)
    up = LaserScan(r, -2 * inc, inc)  # bearings -20..20
    down = LaserScan(r, 2 * inc, -inc)  # upside-down: bearings 20..-20
    pu, pd = up.points_sensor(), down.points_sensor()
    np.testing.assert_allclose(pd[:, 0], pu[:, 0], atol=1e-12)
    np.testing.assert_allclose(pd[:, 1], -pu[:, 1], atol=1e-12)
    assert pu[0, 1] < 0 < pd[0, 1]
    assert down.field_of_view == pytest.approx(up.field_of_view)


def test_sensor_pose_moves_points():
    s = LaserScan([1.0, 2.0], 0.0, math.pi / 2, sensor_pose=Pose2D(0.5, -0.25, math.pi / 2))
    # sensor frame: (1, 0), (0, 2); rotated by +90° -> (0, 1), (-2, 0); then translated
    np.testing.assert_allclose(s.points_robot(), [[0.5, 0.75], [-1.5, -0.25]], atol=1e-12)
    np.testing.assert_allclose(s.points_sensor(), [[1.0, 0.0], [0.0, 2.0]], atol=1e-12)


def test_default_sensor_pose_robot_equals_sensor():
    s = make(np.linspace(1.0, 3.0, 181))
    np.testing.assert_array_equal(s.points_robot(), s.points_sensor())


@given(
    st.floats(-5, 5),
    st.floats(-5, 5),
    st.floats(-math.pi, math.pi),
    st.lists(st.floats(0.1, 30.0), min_size=1, max_size=50),
)
def test_sensor_pose_preserves_distances_to_sensor(x, y, th, ranges):
    s = LaserScan(ranges, -1.0, 2.0 / max(len(ranges), 1), sensor_pose=Pose2D(x, y, th))
    pr = s.points_robot()
    np.testing.assert_allclose(np.hypot(pr[:, 0] - x, pr[:, 1] - y), ranges, rtol=1e-9, atol=1e-9)


# -- metadata validation --------------------------------------------------------------------------
BAD = [
    ("ranges", dict(ranges=[[1.0, 2.0], [3.0, 4.0]])),
    ("ranges", dict(ranges=5.0)),
    ("ranges", dict(ranges=["a", "b"])),
    ("ranges", dict(ranges=[1.0, None])),
    ("ranges", dict(ranges=[True, False])),
    ("ranges", dict(ranges=[1 + 2j])),
    ("ranges", dict(ranges=[[1.0], [2.0, 3.0]])),
    ("angle_min", dict(angle_min=math.nan)),
    ("angle_min", dict(angle_min=math.inf)),
    ("angle_min", dict(angle_min="0")),
    ("angle_increment", dict(angle_increment=0.0)),
    ("angle_increment", dict(angle_increment=math.nan)),
    ("angle_increment", dict(angle_increment=-math.inf)),
    ("angle_increment", dict(angle_increment=None)),
    ("stamp", dict(stamp=math.nan)),
    ("stamp", dict(stamp=math.inf)),
    ("range_min", dict(range_min=-0.1)),
    ("range_min", dict(range_min=math.nan)),
    ("range_max", dict(range_max=0.5, range_min=0.5)),
    ("range_max", dict(range_max=0.1, range_min=0.5)),
    ("range_max", dict(range_max=math.nan)),
    ("range_max", dict(range_max=-math.inf)),
    ("range_max", dict(range_min=math.inf)),
    ("sensor_pose", dict(sensor_pose=(0.0, 0.0, 0.0))),
    ("sensor_pose", dict(sensor_pose=None)),
]


@pytest.mark.parametrize("name, override", BAD, ids=[f"{n}-{i}" for i, (n, _) in enumerate(BAD)])
def test_malformed_field_raises_scan_error_naming_it(name, override):
    kw = dict(ranges=[1.0, 2.0, 3.0], angle_min=0.0, angle_increment=0.1)
    kw.update(override)
    with pytest.raises(ScanError, match=name) as info:
        LaserScan(**kw)
    assert isinstance(info.value, ValueError)


def test_more_than_one_turn_rejected():
    # 362 beams of 1° span 361° between first and last beam
    with pytest.raises(ScanError, match="angle_increment"):
        LaserScan(np.ones(362), 0.0, math.radians(1.0))
    with pytest.raises(ScanError, match="angle_increment"):
        LaserScan(np.ones(3), 0.0, -4.0)
    # exactly one turn from first to last beam (endpoint duplicated) is allowed
    s = LaserScan(np.ones(361), 0.0, 2 * math.pi / 360)
    assert s.n_beams == 361


def test_range_max_may_be_infinite_and_ints_accepted():
    r = np.array([1, 2, 3], dtype=np.int32)
    s = LaserScan(r, 0, 1, range_min=0, range_max=math.inf, stamp=5)
    assert s.ranges.dtype == np.float64
    assert isinstance(s.angle_min, float) and isinstance(s.stamp, float)
    assert s.stamp == 5.0
    assert s.valid.all()


def test_scan_error_is_value_error():
    assert issubclass(ScanError, ValueError)


# -- sizes ----------------------------------------------------------------------------------------
def test_single_beam_scan():
    s = LaserScan([2.0], 0.3, 0.01)
    assert s.n_beams == 1
    np.testing.assert_allclose(s.angles, [0.3])
    np.testing.assert_allclose(s.points_sensor(), [[2 * math.cos(0.3), 2 * math.sin(0.3)]])
    assert s.field_of_view == pytest.approx(0.01)
    assert not s.is_full_circle


def test_empty_scan():
    s = LaserScan([], 0.0, 0.1)
    assert s.n_beams == 0
    assert s.angles.shape == (0,)
    assert s.valid.shape == (0,) and s.valid.dtype == np.bool_ and not s.valid.any()
    assert s.points_sensor().shape == (0, 2)
    assert s.points_robot().shape == (0, 2)
    assert s.field_of_view == 0.0
    assert not s.is_full_circle


# -- field of view --------------------------------------------------------------------------------
def test_full_circle_360_beams_of_one_degree():
    s = LaserScan(np.ones(360), -math.pi, math.radians(1.0))
    assert s.field_of_view == pytest.approx(2 * math.pi)
    assert s.is_full_circle
    neg = LaserScan(np.ones(360), math.pi, -math.radians(1.0))
    assert neg.is_full_circle


@pytest.mark.parametrize(
    "n, inc_deg, full",
    [
        (180, 1.0, False),
        (181, 1.0, False),
        (359, 1.0, False),
        (360, 1.0, True),
        (361, 1.0, True),
        (1080, 0.25, False),
        (1440, 0.25, True),
        (720, 0.5, True),
        (541, 0.5, False),
    ],
)
def test_full_circle_detection(n, inc_deg, full):
    s = LaserScan(np.ones(n), 0.0, math.radians(inc_deg))
    assert s.is_full_circle is full
    assert s.field_of_view == pytest.approx(n * math.radians(inc_deg))


# -- with_ranges / from_angles --------------------------------------------------------------------
def test_with_ranges():
    s = LaserScan(
        [1.0, 2.0, 3.0],
        0.1,
        0.2,
        range_min=0.5,
        range_max=4.0,
        stamp=7.5,
        sensor_pose=Pose2D(1.0, 0.0, 0.0),
    )
    t = s.with_ranges([3.0, 0.2, 4.0])
    assert t is not s
    np.testing.assert_array_equal(t.ranges, [3.0, 0.2, 4.0])
    np.testing.assert_array_equal(t.valid, [True, False, False])
    meta = (t.angle_min, t.angle_increment, t.range_min, t.range_max, t.stamp)
    assert meta == (0.1, 0.2, 0.5, 4.0, 7.5)
    assert t.sensor_pose == s.sensor_pose
    np.testing.assert_array_equal(s.ranges, [1.0, 2.0, 3.0])  # original untouched
    with pytest.raises(ScanError, match="ranges"):
        s.with_ranges([1.0, 2.0])
    with pytest.raises(ScanError, match="ranges"):
        s.with_ranges([[1.0, 2.0, 3.0]])


def test_from_angles_ros_increment():
    s = LaserScan.from_angles(np.ones(181), -math.pi / 2, math.pi / 2, range_max=30.0, stamp=1.0)
    assert s.angle_increment == pytest.approx(math.pi / 180)
    assert s.angles[-1] == pytest.approx(math.pi / 2)
    assert s.range_max == 30.0 and s.stamp == 1.0
    neg = LaserScan.from_angles([1.0, 1.0, 1.0], 1.0, -1.0)
    assert neg.angle_increment == pytest.approx(-1.0)
    np.testing.assert_allclose(neg.angles, [1.0, 0.0, -1.0])


def test_from_angles_increment_argument():
    with pytest.raises(ScanError, match="angle_increment"):
        LaserScan.from_angles([1.0], 0.0, 0.0)
    with pytest.raises(ScanError, match="angle_increment"):
        LaserScan.from_angles([], 0.0, 0.0)
    one = LaserScan.from_angles([1.0], 0.5, 0.5, angle_increment=0.01)
    assert one.angle_increment == 0.01 and one.n_beams == 1
    with pytest.raises(ScanError, match="angle_max"):
        LaserScan.from_angles([1.0], 0.5, 0.9, angle_increment=0.01)
    ok = LaserScan.from_angles([1.0, 1.0, 1.0], 0.0, 0.2, angle_increment=0.1)
    assert ok.angle_increment == pytest.approx(0.1)
    with pytest.raises(ScanError, match="angle_increment"):
        LaserScan.from_angles([1.0, 1.0, 1.0], 0.0, 0.2, angle_increment=0.3)
    with pytest.raises(ScanError, match="angle_increment"):
        LaserScan.from_angles([1.0, 1.0], 0.3, 0.3)  # zero increment
    with pytest.raises(ScanError, match="angle_max"):
        LaserScan.from_angles([1.0, 1.0], 0.0, math.nan)


def test_eq_is_identity():
    a = LaserScan([1.0], 0.0, 0.1)
    b = LaserScan([1.0], 0.0, 0.1)
    assert a == a and a != b
    assert len({a, b}) == 2
