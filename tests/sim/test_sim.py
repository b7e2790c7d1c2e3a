"""Tests of the simulator core: worlds, ray casting, scan synthesis, visible corners."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzypos import sim
from fuzzypos.geometry import Pose2D
from fuzzypos.scan import LaserScan
from fuzzypos.sim import (
    ScannerModel,
    SimError,
    World,
    cast_rays,
    doorway_wall,
    furnished_room,
    office,
    rectangular_room,
    simulate_scan,
    simulate_scans,
    visible_corners,
)

FULL = ScannerModel(n_beams=360, field_of_view_deg=360.0, angle_min_deg=-180.0)


def wall_ahead(d: float = 3.0, half: float = 50.0) -> World:
    """A single wall across the x axis at x = d."""
    return World.from_segments([[d, -half, d, half]])


# ---------------------------------------------------------------------------------------------
# ranges against known geometry
# ---------------------------------------------------------------------------------------------


def test_wall_straight_ahead_and_at_an_angle() -> None:
    d = 3.0
    world = wall_ahead(d)
    assert cast_rays(world, (0.0, 0.0), [0.0])[0] == pytest.approx(d, abs=1e-9)
    alphas = np.radians([-75.0, -45.0, -10.0, 0.0, 1.0, 30.0, 60.0, 80.0])
    r = cast_rays(world, (0.0, 0.0), alphas)
    np.testing.assert_allclose(r, d / np.cos(alphas), rtol=0, atol=1e-9)
    # the same through a simulated scan: every beam of a 180° scanner that can reach the wall
    scanner = ScannerModel(range_max=100.0, range_min=0.0)
    scan = simulate_scan(world, Pose2D(0.0, 0.0, 0.0), scanner)
    ang = scanner.angles()
    ahead = (np.cos(ang) > d / 100.0 + 1e-6) & (np.abs(d * np.tan(ang)) < 50.0)  # range, wall ends
    np.testing.assert_allclose(scan.ranges[ahead], d / np.cos(ang[ahead]), rtol=0, atol=1e-9)
    assert scan.ranges[90] == pytest.approx(d, abs=1e-9)  # beam 90 of -90..89 is 0°


def test_robot_pose_moves_and_turns_the_scan() -> None:
    world = wall_ahead(3.0)
    # the robot at (1, 0.7) facing -60°: the wall is 2 m ahead along x, the beam at +60° is 0°
    scanner = ScannerModel(range_max=100.0)
    scan = simulate_scan(world, Pose2D(1.0, 0.7, math.radians(-60.0)), scanner)
    i = int(np.argmin(np.abs(scanner.angles() - math.radians(60.0))))
    assert scan.ranges[i] == pytest.approx(2.0, abs=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_no_ray_passes_through_a_closed_room(seed: int) -> None:
    rng = np.random.default_rng(seed)
    w, h = 8.0, 6.0
    world = rectangular_room(w, h)
    corners = world.corners
    scanner = ScannerModel(
        n_beams=1440, field_of_view_deg=360.0, angle_min_deg=-180.0, range_max=50.0
    )
    for _ in range(20):
        x, y, th = rng.uniform(-3.9, 3.9), rng.uniform(-2.9, 2.9), rng.uniform(-math.pi, math.pi)
        pose = Pose2D(x, y, th)
        scan = simulate_scan(world, pose, scanner)
        assert scan.valid.all(), "every beam inside a closed room must hit a wall"
        far = np.max(np.hypot(corners[:, 0] - pose.x, corners[:, 1] - pose.y))
        assert np.all(scan.ranges <= far + 1e-9)
        pts = pose.transform_points(scan.points_robot())
        assert np.all(np.abs(pts[:, 0]) <= w / 2 + 1e-9)
        assert np.all(np.abs(pts[:, 1]) <= h / 2 + 1e-9)
        assert np.max(world.distance(pts)) <= 1e-9


@pytest.mark.parametrize("make", [furnished_room, office])
def test_hits_lie_on_segments_in_built_in_worlds(make) -> None:
    world = make()
    rng = np.random.default_rng(7)
    origins = np.column_stack([rng.uniform(-1.5, 1.5, 300), rng.uniform(-0.9, 0.9, 300)])
    dirs = rng.uniform(-math.pi, math.pi, 300)
    r, idx = cast_rays(world, origins, dirs, 30.0, return_segment=True)
    assert np.isfinite(r).all() and (idx >= 0).all()  # both worlds are closed
    pts = origins + r[:, None] * np.column_stack([np.cos(dirs), np.sin(dirs)])
    assert np.max(world.distance(pts)) <= 1e-9
    # the index names the segment hit
    seg = world.segments[idx]
    d = sim._point_segment_distance(pts, seg)[np.arange(len(pts)), np.arange(len(pts))]
    assert np.max(d) <= 1e-9


def test_ray_parallel_to_a_wall() -> None:
    world = World.from_segments([[0.0, 1.0, 10.0, 1.0]])  # along x, 1 m to the left
    r = cast_rays(world, (0.0, 0.0), [0.0, math.pi, 1e-13])
    assert np.isinf(r).all()
    # parallel but collinear: the ray meets the nearer end of the wall ahead, not the one behind
    world = World.from_segments([[2.0, 0.0, 5.0, 0.0]])
    r = cast_rays(world, (0.0, 0.0), [0.0, math.pi])
    assert r[0] == pytest.approx(2.0, abs=1e-12)
    assert np.isinf(r[1])
    # inside a room, rays at exactly ±90° (cos not exactly 0) are parallel to the side walls
    room = rectangular_room(8.0, 6.0)
    r = cast_rays(room, (0.0, 0.0), [math.pi / 2, -math.pi / 2, 0.0, math.pi])
    np.testing.assert_allclose(r, [3.0, 3.0, 4.0, 4.0], rtol=0, atol=1e-12)


def test_ray_through_a_segment_endpoint_hits() -> None:
    world = World.from_segments([[2.0, -1.0, 2.0, 1.0]])
    a = math.atan2(1.0, 2.0)
    r = cast_rays(world, (0.0, 0.0), [a, -a, a + 1e-6, -a - 1e-6])
    assert r[0] == pytest.approx(math.sqrt(5.0), abs=1e-9)
    assert r[1] == pytest.approx(math.sqrt(5.0), abs=1e-9)
    assert np.isinf(r[2]) and np.isinf(r[3])
    # a room corner hit exactly from the centre
    room = rectangular_room(8.0, 6.0)
    r = cast_rays(room, (0.0, 0.0), [math.atan2(3.0, 4.0), math.atan2(-3.0, -4.0)])
    np.testing.assert_allclose(r, [5.0, 5.0], rtol=0, atol=1e-9)


def test_no_self_hit_from_a_point_on_a_wall() -> None:
    world = World.from_segments([[2.0, -1.0, 2.0, 1.0]])
    r = cast_rays(world, (2.0, 0.0), [0.0, math.pi, 0.3])
    assert np.isinf(r).all()


def test_max_range_and_no_return() -> None:
    world = wall_ahead(3.0)
    assert np.isinf(cast_rays(world, (0.0, 0.0), [0.0], max_range=2.5)[0])
    assert cast_rays(world, (0.0, 0.0), [0.0], max_range=3.0)[0] == pytest.approx(3.0)
    scanner = ScannerModel(range_max=2.5)
    scan = simulate_scan(world, Pose2D(), scanner)
    assert np.all(scan.ranges == 2.5)  # no return reads exactly range_max ...
    assert not scan.valid.any()  # ... which the scan treats as invalid
    assert scan.range_max == 2.5 and scan.range_min == scanner.range_min


def test_cast_rays_shapes_and_chunking(monkeypatch: pytest.MonkeyPatch) -> None:
    world = furnished_room()
    rng = np.random.default_rng(3)
    origins = np.column_stack([rng.uniform(-2, 2, 500), rng.uniform(-1.5, 1.5, 500)])
    dirs = rng.uniform(-math.pi, math.pi, 500)
    full = cast_rays(world, origins, dirs, 20.0)
    assert full.shape == (500,)
    monkeypatch.setattr(sim.raycast, "_CHUNK_ELEMENTS", 100)  # chunks of 2 beams
    np.testing.assert_array_equal(cast_rays(world, origins, dirs, 20.0), full)
    # a single origin broadcasts over the directions, a segment array works as a world
    one = cast_rays(world.segments, origins[0], dirs, 20.0)
    np.testing.assert_array_equal(one, cast_rays(world, np.tile(origins[0], (500, 1)), dirs, 20.0))
    assert cast_rays(world, origins[0], 0.5).shape == (1,)
    empty = World.from_segments(np.empty((0, 4)))
    assert cast_rays(empty, origins, dirs).tolist() == [math.inf] * 500
    with pytest.raises(SimError):
        cast_rays(world, np.zeros((3, 3)), [0.0, 1.0, 2.0])
    with pytest.raises(SimError):
        cast_rays(world, np.zeros((3, 2)), [0.0, 1.0])
    with pytest.raises(SimError):
        cast_rays(world, (0.0, np.nan), [0.0])
    with pytest.raises(SimError):
        cast_rays(world, (0.0, 0.0), [0.0], max_range=0.0)


# ---------------------------------------------------------------------------------------------
# noise, sensor offset, doorway
# ---------------------------------------------------------------------------------------------


def test_noise_statistics() -> None:
    sigma = 0.02
    world = rectangular_room(8.0, 6.0)
    clean = ScannerModel(n_beams=360, field_of_view_deg=360.0, angle_min_deg=-180.0)
    noisy = ScannerModel(
        n_beams=360, field_of_view_deg=360.0, angle_min_deg=-180.0, range_noise_std=sigma
    )
    pose = Pose2D(0.5, -0.3, 0.2)
    truth = simulate_scan(world, pose, clean).ranges
    n_scans = 200
    scans = simulate_scans(world, [pose] * n_scans, noisy, np.random.default_rng(42))
    err = np.concatenate([s.ranges - truth for s in scans])
    n = err.size
    assert abs(err.mean()) < 5.0 * sigma / math.sqrt(n)
    assert abs(err.std(ddof=1) - sigma) < 5.0 * sigma / math.sqrt(2.0 * (n - 1))
    # scans sharing one generator differ; the same seed reproduces them exactly
    assert not np.array_equal(scans[0].ranges, scans[1].ranges)
    again = simulate_scans(world, [pose] * 2, noisy, np.random.default_rng(42))
    np.testing.assert_array_equal(again[0].ranges, scans[0].ranges)
    np.testing.assert_array_equal(again[1].ranges, scans[1].ranges)


def test_noise_only_on_hits_and_clipped() -> None:
    world = doorway_wall(distance=2.0, gap=1.0)
    scanner = ScannerModel(range_noise_std=0.5, range_max=5.0, range_min=1.9)
    rng = np.random.default_rng(0)
    truth = simulate_scan(world, Pose2D(), ScannerModel(range_max=5.0, range_min=1.9)).ranges
    for _ in range(20):
        r = simulate_scan(world, Pose2D(), scanner, rng).ranges
        miss = truth == 5.0
        assert miss.any() and np.all(r[miss] == 5.0)  # no-return beams stay exactly range_max
        assert np.all(r >= 1.9) and np.all(r <= 5.0)


def test_sensor_pose_offset() -> None:
    world = rectangular_room(8.0, 6.0)  # front wall at x = 4
    base = simulate_scan(world, Pose2D(), ScannerModel())
    mounted = ScannerModel(sensor_pose=Pose2D(0.2, 0.0, 0.0))
    scan = simulate_scan(world, Pose2D(), mounted)
    assert scan.sensor_pose == Pose2D(0.2, 0.0, 0.0)
    assert base.ranges[90] == pytest.approx(4.0, abs=1e-9)
    assert scan.ranges[90] == pytest.approx(3.8, abs=1e-9)
    # points moved into the robot frame land on the walls whatever the mount
    np.testing.assert_allclose(scan.points_robot()[90], [4.0, 0.0], atol=1e-9)
    pts = scan.points_robot()[scan.valid]
    assert np.max(world.distance(pts)) <= 1e-9
    # turned robot, turned mount: robot at (1, 0.5) facing +y, laser 0.2 m ahead facing its left
    pose = Pose2D(1.0, 0.5, math.pi / 2)
    fwd = simulate_scan(world, pose, mounted)
    assert fwd.ranges[90] == pytest.approx(3.0 - 0.5 - 0.2, abs=1e-9)
    left = ScannerModel(sensor_pose=Pose2D(0.2, 0.0, math.pi / 2))
    s = simulate_scan(world, pose, left)  # the laser looks along -x from (1, 0.7)
    assert s.ranges[90] == pytest.approx(1.0 + 4.0, abs=1e-9)
    world_pts = pose.transform_points(s.points_robot()[s.valid])
    assert np.max(world.distance(world_pts)) <= 1e-9


def test_doorway_gap() -> None:
    scanner = ScannerModel(n_beams=360, field_of_view_deg=180.0, range_max=10.0)
    ang = scanner.angles()
    y_at_wall = 2.0 * np.tan(ang)
    through = np.abs(y_at_wall) < 0.5 - 1e-6
    on_wall = (np.abs(y_at_wall) > 0.5 + 1e-6) & (np.abs(y_at_wall) <= 5.0) & (np.cos(ang) > 0.2)
    assert through.sum() > 10 and on_wall.sum() > 100
    scan = simulate_scan(doorway_wall(distance=2.0, gap=1.0), Pose2D(), scanner)
    assert np.all(scan.ranges[through] == 10.0) and not scan.valid[through].any()
    np.testing.assert_allclose(scan.ranges[on_wall], 2.0 / np.cos(ang[on_wall]), atol=1e-9)
    # with a wall behind the doorway, the beams through the gap reach it
    world = doorway_wall(distance=2.0, gap=1.0, back_wall_distance=5.0)
    behind = simulate_scan(world, Pose2D(), scanner)
    np.testing.assert_allclose(behind.ranges[through], 5.0 / np.cos(ang[through]), atol=1e-9)
    np.testing.assert_allclose(behind.ranges[on_wall], 2.0 / np.cos(ang[on_wall]), atol=1e-9)


def test_simulate_scan_returns_laser_scan_metadata() -> None:
    scanner = ScannerModel(
        n_beams=181, field_of_view_deg=181.0, angle_min_deg=-90.0, range_max=6.0, range_min=0.1
    )
    scan = simulate_scan(rectangular_room(), [0.1, 0.2, 0.3], scanner, stamp=12.5)
    assert isinstance(scan, LaserScan)
    assert scan.n_beams == 181 and scan.stamp == 12.5
    assert scan.angle_min == pytest.approx(-math.pi / 2)
    assert scan.angle_increment == pytest.approx(math.radians(1.0))
    np.testing.assert_allclose(scan.angles, scanner.angles())
    assert scan.range_min == 0.1 and scan.range_max == 6.0
    poses = [Pose2D(), Pose2D(0.5, 0, 0)]
    scans = simulate_scans(rectangular_room(), poses, scanner, stamps=[1.0, 2.0])
    assert [s.stamp for s in scans] == [1.0, 2.0]
    scans = simulate_scans(rectangular_room(), [Pose2D()] * 3, scanner)
    assert [s.stamp for s in scans] == [0.0, 1.0, 2.0]
    with pytest.raises(SimError):
        simulate_scans(rectangular_room(), [Pose2D()] * 2, scanner, stamps=[1.0])


def test_clockwise_scanner() -> None:
    """A negative field of view (upside-down mount) scans clockwise and sees the same world."""
    world = furnished_room()
    ccw = ScannerModel(n_beams=360, field_of_view_deg=360.0, angle_min_deg=-180.0)
    cw = ScannerModel(n_beams=360, field_of_view_deg=-360.0, angle_min_deg=180.0)
    a = simulate_scan(world, Pose2D(0.3, 0.1, 0.4), ccw)
    b = simulate_scan(world, Pose2D(0.3, 0.1, 0.4), cw)
    assert b.angle_increment < 0
    np.testing.assert_allclose(b.ranges[1:], a.ranges[1:][::-1], atol=1e-9)


# ---------------------------------------------------------------------------------------------
# scanner model
# ---------------------------------------------------------------------------------------------


def test_scanner_model_angles() -> None:
    s = ScannerModel()
    a = s.angles()
    assert a.shape == (180,)
    assert a[0] == pytest.approx(-math.pi / 2)
    assert a[-1] == pytest.approx(math.radians(89.0))
    assert s.angle_increment == pytest.approx(math.pi / 180)
    assert not s.is_full_circle and FULL.is_full_circle
    assert s.covers([0.0, math.radians(-90.0), math.radians(89.0)]).all()
    assert not s.covers([math.radians(89.5), math.radians(-91.0), math.pi]).any()
    assert FULL.covers([math.pi, -math.pi, 0.0]).all()


@pytest.mark.parametrize(
    "kw",
    [
        {"n_beams": 0},
        {"n_beams": 2.5},
        {"field_of_view_deg": 0.0},
        {"field_of_view_deg": 400.0},
        {"range_max": 0.01},
        {"range_min": -0.1},
        {"range_noise_std": -0.01},
        {"range_max": math.inf},
    ],
)
def test_scanner_model_validation(kw: dict) -> None:
    with pytest.raises(SimError):
        ScannerModel(**kw)


# ---------------------------------------------------------------------------------------------
# visible corners
# ---------------------------------------------------------------------------------------------


def _as_set(points: np.ndarray) -> set[tuple[float, float]]:
    return {(round(float(x), 6), round(float(y), 6)) for x, y in points}


def test_visible_corners_rectangular_room() -> None:
    room = rectangular_room(8.0, 6.0)
    assert _as_set(room.corners) == {(-4.0, -3.0), (4.0, -3.0), (4.0, 3.0), (-4.0, 3.0)}
    assert len(visible_corners(room, Pose2D(), FULL)) == 4
    front = visible_corners(room, Pose2D(), ScannerModel())  # 180° facing the x = 4 wall
    assert _as_set(front) == {(4.0, -3.0), (4.0, 3.0)}
    up = visible_corners(room, Pose2D(0.0, 0.0, math.pi / 2), ScannerModel())
    assert _as_set(up) == {(4.0, 3.0), (-4.0, 3.0)}
    # out of range
    assert len(visible_corners(room, Pose2D(), ScannerModel(range_max=4.9))) == 0


def test_visible_corners_occlusion_and_convex_corners() -> None:
    box = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
    world = World.from_polygons([box])
    # from (2, -1) both faces meeting at (1, 0) are seen; (0, 0) and (1, 1) show one face
    # only (a range jump, not an angle) and (0, 1) is behind the box
    assert _as_set(visible_corners(world, Pose2D(2.0, -1.0, 0.0), FULL)) == {(1.0, 0.0)}
    # a pillar between the robot and a room corner hides it
    room = rectangular_room(8.0, 6.0)
    pillar = [[1.9, 1.4], [2.1, 1.4], [2.1, 1.6], [1.9, 1.6]]
    world = World.from_polygons([room.polygons[0], pillar])
    seen = _as_set(visible_corners(world, Pose2D(), FULL))
    assert (4.0, 3.0) not in seen and {(4.0, -3.0), (-4.0, 3.0), (-4.0, -3.0)} <= seen


def test_thin_wall_junction_is_a_corner_from_one_side_only() -> None:
    world = office()
    assert (-3.5, 1.0) in _as_set(world.corners)  # partition meets corridor wall (a T)
    assert (-3.5, 1.0) not in _as_set(visible_corners(world, Pose2D(-5.0, 0.0, 0.0), FULL))
    assert (-3.5, 1.0) in _as_set(visible_corners(world, Pose2D(-4.0, 4.0, 0.0), FULL))


def test_corner_points() -> None:
    # an L-shaped open wall, a collinear vertex and a free end
    world = World.from_polygons([[[0, 0], [2, 0], [4, 0], [4, 3]]], closed=False)
    assert _as_set(world.corners) == {(4.0, 0.0)}
    # a 20° bend is a corner only for thresholds up to 20°
    c, s = math.cos(math.radians(20)), math.sin(math.radians(20))
    bend = World.from_polygons([[[0, 0], [1, 0], [1 + c, s]]], closed=False)
    assert len(bend.corner_points(15.0)) == 1 and len(bend.corner_points(30.0)) == 0
    # a round pillar (16-gon) has no corners; a square one has four
    assert len(World.from_polygons([sim.circle_polygon(0, 0, 0.2)]).corners) == 0
    assert len(World.from_polygons([sim.box_polygon(0, 0, 0.3, 0.3, 0.4)]).corners) == 4
    # from_segments finds the same corners as from_polygons
    room = rectangular_room()
    assert _as_set(World.from_segments(room.segments).corners) == _as_set(room.corners)


# ---------------------------------------------------------------------------------------------
# worlds
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "segs, match",
    [
        ([[0, 0, 1, np.nan]], "non-finite"),
        ([[0, 0, np.inf, 1]], "non-finite"),
        ([[0, 0, 1, 1], [2, 2, 2, 2]], "segment 1 has zero length"),
        ([[0, 0, 1]], "shape"),
        (np.zeros((2, 2, 4)), "shape"),
        ("walls", "numeric"),
    ],
)
def test_world_segment_validation(segs, match: str) -> None:
    with pytest.raises(SimError, match=match):
        World.from_segments(segs)
    assert issubclass(SimError, ValueError)


def test_world_polygon_validation() -> None:
    with pytest.raises(SimError, match="polygon 1: edge 1"):
        World.from_polygons([[[0, 0], [1, 0], [1, 1]], [[0, 0], [2, 0], [2, 0], [0, 2]]])
    with pytest.raises(SimError, match="at least 3 vertices"):
        World.from_polygons([[[0, 0], [1, 0]]])
    with pytest.raises(SimError, match="shape"):
        World.from_polygons([[0, 0, 1, 0]])
    with pytest.raises(SimError, match="non-finite"):
        World.from_polygons([[[0, 0], [1, np.nan], [1, 1]]])
    with pytest.raises(SimError, match="one flag per polygon"):
        World.from_polygons([[[0, 0], [1, 0], [1, 1]]], closed=[True, False])
    # an open polyline of two vertices is fine; a repeated closing vertex is dropped
    assert World.from_polygons([[[0, 0], [1, 0]]], closed=False).n_segments == 1
    assert World.from_polygons([[[0, 0], [1, 0], [1, 1], [0, 0]]]).n_segments == 3


def test_world_is_read_only() -> None:
    world = rectangular_room()
    assert world.segments.shape == (4, 4)
    with pytest.raises(ValueError):
        world.segments[0, 0] = 1.0
    with pytest.raises(ValueError):
        world.polygons[0][0, 0] = 1.0
    with pytest.raises(AttributeError):
        world.name = "x"  # type: ignore[misc]
    assert world.bounds == (-4.0, -3.0, 4.0, 3.0)
    assert "rectangular_room" in repr(world)


@pytest.mark.parametrize("seed", [0, 1, 2, 5])
def test_furnished_room_layout(seed: int) -> None:
    world = furnished_room(seed)
    assert world.bounds == (-5.0, -4.0, 5.0, 4.0)
    # the central 4 m x 3 m area is free, with room to spare
    gx, gy = np.meshgrid(np.linspace(-2, 2, 41), np.linspace(-1.5, 1.5, 31))
    assert world.distance(np.column_stack([gx.ravel(), gy.ravel()])).min() > 0.2
    # furniture: axis-aligned and rotated boxes, a round pillar (many sides) and a square one
    furniture = world.polygons[1:]
    assert len(furniture) == 8
    four = [p for p in furniture if len(p) == 4]
    rotated = [p for p in four if not np.isclose(p[1, 1], p[0, 1])]
    assert 0 < len(rotated) < len(four)
    assert any(len(p) > 8 for p in furniture)
    # deterministic
    np.testing.assert_array_equal(furnished_room(seed).segments, world.segments)


def test_furnished_room_seeds_differ_and_see_corners_from_the_centre() -> None:
    assert not np.array_equal(furnished_room(0).segments, furnished_room(1).segments)
    seen = _as_set(visible_corners(furnished_room(0), Pose2D(), FULL))
    assert {(5.0, 4.0), (-5.0, 4.0), (5.0, -4.0), (-5.0, -4.0)} <= seen


def test_office() -> None:
    world = office()
    xmin, ymin, xmax, ymax = world.bounds
    assert (xmax - xmin, ymax - ymin) == (20.0, 10.0)
    # up through the north doorway at x in [-0.5, 0.5] to the desk at y = 4; beside it, the wall
    r = cast_rays(world, [(0.0, 0.0), (1.5, 0.0)], [math.pi / 2, math.pi / 2])
    np.testing.assert_allclose(r, [4.0, 1.0], atol=1e-9)
    # from the corridor the scanner sees corners
    assert len(visible_corners(world, Pose2D(-7.0, 0.0, 0.0), FULL)) >= 2
