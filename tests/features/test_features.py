"""Tests of feature extraction (SPEC steps 1–7, paper §2.2–§3.6) against known geometry.

Every scene is noise-free simulated (or hand-built) geometry whose answer is known exactly: the
incidence angle of a beam on a wall, the walls' normal forms, the corners of a room, the
edges of a doorway. Frames: features are in the robot frame, so the truth is the world
geometry moved by ``⊖robot_pose``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from fuzzypos import sim
from fuzzypos.config import Config
from fuzzypos.features import extract as F
from fuzzypos.features import segmentation as segmentation
from fuzzypos.geometry import Pose2D
from fuzzypos.scan import LaserScan
from oracles import features as features_oracle

FULL = sim.ScannerModel(n_beams=360, field_of_view_deg=360.0, angle_min_deg=-180.0)
HALF = sim.ScannerModel()  # 180 beams, -90°..+89°, 1° apart, range_max 8 m
CFG = Config()
PAPER = Config.preset("paper")
XI = CFG.filtering.detection_angle_threshold  # 22.5°


# ---------------------------------------------------------------------------------------------
# helpers: the truth
# ---------------------------------------------------------------------------------------------
def wall_world(d: float = 2.0, half: float = 8.0) -> sim.World:
    """One wall across the x axis at x = d, from y = -half to y = +half."""
    return sim.World.from_segments([[d, -half, d, half]])


def true_walls(world: sim.World, pose: Pose2D) -> tuple[np.ndarray, np.ndarray]:
    """Every wall segment's line in normal form ``n·p = d`` (d >= 0) in the robot frame."""
    seg = world.segments
    inv = pose.inverse()
    a = inv.transform_points(seg[:, :2])
    b = inv.transform_points(seg[:, 2:])
    t = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
    n = np.column_stack([-t[:, 1], t[:, 0]])
    d = np.sum(n * a, axis=1)
    n = np.where(d[:, None] < 0, -n, n)
    return n, np.abs(d)


def line_to_wall_error(lines: F.Lines, n_true: np.ndarray, d_true: np.ndarray) -> np.ndarray:
    """(lines, walls) error |Δnormal| + |Δdistance| (both sides in normal form with d >= 0)."""
    dn = np.linalg.norm(lines.normal[:, None, :] - n_true[None], axis=2)
    dd = np.abs(lines.distance[:, None] - d_true[None])
    return dn + dd


def robot_corners(world: sim.World, pose: Pose2D, scanner: sim.ScannerModel) -> np.ndarray:
    """The corners the scanner sees, in the robot frame."""
    return pose.inverse().transform_points(sim.visible_corners(world, pose, scanner))


def mirrored(scan: LaserScan) -> LaserScan:
    """The same readings in reverse order: angle_min' = angle_max, increment negated."""
    n = scan.n_beams
    return LaserScan(
        scan.ranges[::-1].copy(),
        scan.angle_min + (n - 1) * scan.angle_increment,
        -scan.angle_increment,
        scan.range_min,
        scan.range_max,
        scan.stamp,
        scan.sensor_pose,
    )


def nearest(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """For each row of a, the distance to the nearest row of b."""
    if len(a) == 0:
        return np.zeros(0)
    if len(b) == 0:
        return np.full(len(a), np.inf)
    return np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2).min(axis=1)


def open_end(n: int) -> np.ndarray:
    """``gap_after`` of an open scan without gaps: only after its last point (as
    extract_features passes it: the end of an open scan is a cut)."""
    g = np.zeros(n, bool)
    g[-1] = True
    return g


def wall_points(psi: float, d: float, bearings: np.ndarray) -> np.ndarray:
    """Points where beams at ``bearings`` meet the line ``(cos ψ, sin ψ)·p = d``."""
    r = d / np.cos(bearings - psi)
    return np.column_stack([r * np.cos(bearings), r * np.sin(bearings)])


# ---------------------------------------------------------------------------------------------
# 1. detection angle (eq. 3 as SPEC fixes it)
# ---------------------------------------------------------------------------------------------
def test_detection_angle_square_on_wall() -> None:
    """Wall x = 3 (eq. 3's bare quotient divides by zero here: Δx = 0): β = 90° − |φ|."""
    phi = np.radians(np.arange(-40, 41, 1.0))
    pts = wall_points(0.0, 3.0, phi)
    beta = F.detection_angles(pts, open_end(len(pts)))
    mid = int(np.flatnonzero(phi == 0.0)[0])
    assert beta[mid] == pytest.approx(math.pi / 2, abs=1e-12)
    np.testing.assert_allclose(beta, math.pi / 2 - np.abs(phi), rtol=0, atol=1e-9)


@pytest.mark.parametrize("psi_deg", [-150.0, -90.0, -35.0, 0.0, 20.0, 90.0, 135.0, 180.0])
@pytest.mark.parametrize("d", [0.7, 3.0, 7.5])
def test_detection_angle_equals_incidence_on_any_wall(psi_deg: float, d: float) -> None:
    """β is the angle between the beam and the wall, folded into [0°, 90°], whatever the wall's
    direction (vertical and horizontal walls included) and whichever way the scan runs."""
    psi = math.radians(psi_deg)
    phi = psi + np.radians(np.arange(-70.0, 70.5, 1.0))
    pts = wall_points(psi, d, phi)
    expected = math.pi / 2 - np.abs(phi - psi)
    beta = F.detection_angles(pts, open_end(len(pts)))
    np.testing.assert_allclose(beta, expected, rtol=0, atol=1e-9)
    # the same points scanned the other way (negative increment) see the same incidence
    beta_rev = F.detection_angles(pts[::-1].copy(), open_end(len(pts)))
    np.testing.assert_allclose(beta_rev[::-1], expected, rtol=0, atol=1e-9)


def test_detection_angle_takes_the_previous_neighbour_across_a_gap() -> None:
    """SPEC step 1: where i+1 lies across a gap (or does not exist) the surface runs to i−1;
    a point with gaps on both sides has no surface and gets β = 0."""
    phi_a = np.radians(np.arange(-40.0, -9.5, 1.0))  # wall A: x = 2
    phi_b = np.radians(np.arange(-9.0, 20.5, 1.0))  # wall B: x = 5, behind a gap
    a = wall_points(0.0, 2.0, phi_a)
    b = wall_points(0.0, 5.0, phi_b)
    lone = wall_points(0.0, 1.0, np.radians([25.0]))  # a lone point, gaps on both sides
    pts = np.vstack([a, b, lone])
    phi = np.concatenate([phi_a, phi_b, np.radians([25.0])])
    gap_after = np.zeros(len(pts), bool)
    gap_after[len(a) - 1] = True  # between A and B
    gap_after[len(a) + len(b) - 1] = True  # between B and the lone point
    gap_after[-1] = True  # the end of an open scan
    beta = F.detection_angles(pts, gap_after)
    expected = math.pi / 2 - np.abs(phi)
    expected[-1] = 0.0
    np.testing.assert_allclose(beta, expected, rtol=0, atol=1e-9)
    # without the gap flag, A's last point would take the step across the gap: not its wall
    beta_nogap = F.detection_angles(pts, open_end(len(pts)))
    assert abs(beta_nogap[len(a) - 1] - expected[len(a) - 1]) > math.radians(10.0)


@given(
    st.lists(
        st.tuples(st.floats(-10, 10, allow_nan=False), st.floats(-10, 10, allow_nan=False)),
        min_size=1,
        max_size=30,
    ),
    st.data(),
)
def test_detection_angle_is_folded_into_0_90(xy: list[tuple[float, float]], data) -> None:
    pts = np.array(xy, dtype=float)
    gaps = np.array(data.draw(st.lists(st.booleans(), min_size=len(pts), max_size=len(pts))))
    closed = data.draw(st.booleans())
    if not closed:
        gaps[-1] = True  # an open scan ends in a cut
    beta = F.detection_angles(pts, gaps, closed)
    assert beta.shape == (len(pts),)
    assert np.all(np.isfinite(beta))
    assert np.all((beta >= 0.0) & (beta <= math.pi / 2 + 1e-15))


def test_detection_angle_last_point_of_an_open_scan_uses_its_previous_neighbour() -> None:
    """The docstring: the surface runs to i−1 where i+1 'does not exist' — the last point of an
    open scan, whether or not ``gap_after`` flags it."""
    phi = np.radians(np.arange(-20.0, 20.5, 1.0))
    pts = wall_points(0.0, 3.0, phi)
    beta = F.detection_angles(pts, np.zeros(len(pts), bool), closed=False)
    np.testing.assert_allclose(beta, math.pi / 2 - np.abs(phi), rtol=0, atol=1e-9)


def test_detection_angle_closed_scan_wraps() -> None:
    """A closed scan: the last point's neighbour is the first one."""
    phi = np.radians(np.arange(0.0, 360.0, 1.0))
    pts = np.column_stack([2.0 * np.cos(phi), 2.0 * np.sin(phi)])  # a circle around the sensor
    beta = F.detection_angles(pts, np.zeros(len(pts), bool), closed=True)
    # the chord between neighbours on a circle is at 90° − Δφ/2 to the beam
    np.testing.assert_allclose(beta, math.pi / 2 - math.radians(0.5), rtol=0, atol=1e-9)


def test_detection_angle_through_extract_features() -> None:
    """A simulated wall x = 2 (±8 m) seen by a 180° scanner: β of every valid point is the
    analytic incidence 90° − |φ|, in the sensor frame."""
    scan = sim.simulate_scan(wall_world(2.0, 8.0), Pose2D(), HALF)
    f = F.extract_features(scan)
    phi = scan.angles[f.beam_index]
    assert f.n_valid > 100
    np.testing.assert_allclose(f.detection_angle, math.pi / 2 - np.abs(phi), rtol=0, atol=1e-9)
    mid = int(np.flatnonzero(np.abs(phi) < 1e-12)[0])
    assert f.detection_angle[mid] == pytest.approx(math.pi / 2, abs=1e-12)


# ---------------------------------------------------------------------------------------------
# 3. filtering (§3.1)
# ---------------------------------------------------------------------------------------------
def test_filtering_removes_grazing_points() -> None:
    """A long wall at x = 2 seen from -75° to +75°: points with β <= 22.5° (|φ| >= 67.5°)
    are removed."""
    scan = sim.simulate_scan(wall_world(2.0, 8.0), Pose2D(), HALF)
    f = F.extract_features(scan)
    phi_deg = np.degrees(scan.angles[f.beam_index])
    assert phi_deg.min() < -74 and phi_deg.max() > 74  # grazing points are there to remove
    np.testing.assert_array_equal(f.kept, f.detection_angle > XI)
    np.testing.assert_array_equal(f.kept, np.abs(phi_deg) < 67.5)
    np.testing.assert_array_equal(f.kept_index, np.flatnonzero(f.kept))
    assert (~f.kept).sum() == 16  # 68..75 on both sides
    # the direct stage agrees, and a stricter threshold removes more
    np.testing.assert_array_equal(F.filter_points(f.detection_angle, XI), f.kept)
    strict = CFG.with_overrides({"filtering": {"detection_angle_threshold": math.radians(40.5)}})
    g = F.extract_features(scan, strict)
    np.testing.assert_array_equal(g.kept, np.abs(phi_deg) < 49.5)
    # the line fitted to the kept points is the wall
    assert len(f.lines) == 1
    np.testing.assert_allclose(f.lines.normal[0], [1.0, 0.0], atol=1e-9)
    assert f.lines.distance[0] == pytest.approx(2.0, abs=1e-9)


def test_filter_points_threshold_is_exclusive() -> None:
    beta = np.array([0.0, XI - 1e-9, XI, XI + 1e-9, math.pi / 2])
    np.testing.assert_array_equal(F.filter_points(beta, XI), [False, False, False, True, True])


# ---------------------------------------------------------------------------------------------
# 4. break points and clusters (§3.2–3.3, eq. 13)
# ---------------------------------------------------------------------------------------------
def _gap_border_points(world_pts: np.ndarray, x_wall: float, gap_half: float) -> np.ndarray:
    """The valid points of the wall at x = x_wall that border the doorway |y| < gap_half."""
    on = np.abs(world_pts[:, 0] - x_wall) < 1e-9
    y = world_pts[on, 1]
    lo = y[y < -gap_half].max()
    hi = y[y > gap_half].min()
    return np.array([[x_wall, lo], [x_wall, hi]])


@pytest.mark.parametrize("pose", [Pose2D(), Pose2D(0.3, 0.2, 0.15)])
def test_break_points_at_the_edges_of_a_doorway(pose: Pose2D) -> None:
    world = sim.doorway_wall(distance=2.0, gap=1.0, length=10.0)
    f = F.extract_features(sim.simulate_scan(world, pose, HALF))
    kp_world = pose.transform_points(f.kept_points)
    border = _gap_border_points(kp_world, 2.0, 0.5)
    is_border = nearest(kp_world, border) < 1e-9
    assert is_border.sum() == 2
    inner = f.is_break_point & ~f.is_field_of_view_edge
    # exactly the two gap-border points are (non-edge) break points; interior wall points not
    np.testing.assert_array_equal(inner, is_border)
    # the field-of-view edges are the ends of the scan, break points too (eq. 13: i = 1, 180)
    assert f.is_field_of_view_edge[0] and f.is_field_of_view_edge[-1]
    assert f.is_field_of_view_edge.sum() == 2
    assert f.is_break_point[0] and f.is_break_point[-1]
    # the scan splits at the doorway: two clusters, one on each side of the gap
    assert f.n_clusters == 2
    y = kp_world[:, 1]
    assert set(f.cluster[y < 0]) == {0} and set(f.cluster[y > 0]) == {1}
    # the break-point features are the two doorway edges (robot frame)
    expected = pose.inverse().transform_points(border)
    assert len(f.break_points) == 2
    assert np.all(nearest(f.break_points.xy, expected) < 1e-9)
    assert np.all(f.break_points.kind == F.BREAK_POINT)
    # and each side of the doorway is one line on the wall
    n_true, d_true = true_walls(world, pose)
    assert len(f.lines) == 2
    assert np.all(line_to_wall_error(f.lines, n_true, d_true).min(axis=1) < 1e-9)


def test_break_points_with_a_wall_behind_the_doorway() -> None:
    """Through the doorway the back wall is seen: its two visible ends are break points too."""
    world = sim.doorway_wall(distance=2.0, gap=1.0, length=10.0, back_wall_distance=4.0)
    f = F.extract_features(sim.simulate_scan(world, Pose2D(), HALF))
    kp = f.kept_points
    front = _gap_border_points(kp, 2.0, 0.5)
    back_y = kp[np.abs(kp[:, 0] - 4.0) < 1e-9, 1]
    back = np.array([[4.0, back_y.min()], [4.0, back_y.max()]])
    expected = np.vstack([front, back])
    inner = f.is_break_point & ~f.is_field_of_view_edge
    np.testing.assert_array_equal(inner, nearest(kp, expected) < 1e-9)
    assert inner.sum() == 4
    assert f.n_clusters == 3
    assert len(f.lines) == 3


def test_break_points_uniformly_sparse_surface_is_not_all_break_points() -> None:
    """Points 0.5 m apart (> T2 = 0.2 m) on a straight line: every step exceeds T2, but the
    steps on both sides of an interior point are equal (< T1 apart), so it is no break point."""
    pts = np.column_stack([np.full(12, 3.0), np.arange(12) * 0.5 - 2.75])
    t2 = np.full(len(pts), 0.2)
    for closed in (False, True):
        is_break, split = F.break_points(pts, t2, 0.1, closed=closed)
        assert not is_break[2:-2].any()
        assert not split[1:-2].any()
        assert is_break.sum() <= 4
    # a uniformly dense surface has no interior break point either
    dense = np.column_stack([np.full(12, 3.0), np.arange(12) * 0.05])
    is_break_d, split_d = F.break_points(dense, t2, 0.1)
    np.testing.assert_array_equal(np.flatnonzero(is_break_d), [0, 11])
    np.testing.assert_array_equal(np.flatnonzero(split_d), [11])


def test_uniformly_sparse_surface_at_the_ends_of_an_open_scan() -> None:
    """A sparse surface that ends at the field-of-view edges is one cluster of all its points."""
    pts = np.column_stack([np.full(12, 3.0), np.arange(12) * 0.5 - 2.75])
    t2 = np.full(len(pts), 0.2)
    is_break, split = F.break_points(pts, t2, 0.1, closed=False)
    np.testing.assert_array_equal(np.flatnonzero(is_break), [0, 11])
    np.testing.assert_array_equal(np.flatnonzero(split), [11])
    np.testing.assert_array_equal(F.clusters(split, 4), np.zeros(12, dtype=np.int64))


def test_sparse_surfaces_beside_a_gap_break_only_at_the_gap() -> None:
    """Eq. 13: only the two points that border the gap are break points (and the FOV ends);
    each sparse wall stays one cluster with its edge point in it."""
    y = np.concatenate([np.arange(6) * 0.5, 5.5 + np.arange(6) * 0.5])
    pts = np.column_stack([np.full(12, 3.0), y])
    t2 = np.full(12, 0.2)
    is_break, split = F.break_points(pts, t2, 0.1, closed=False)
    np.testing.assert_array_equal(np.flatnonzero(is_break), [0, 5, 6, 11])
    np.testing.assert_array_equal(np.flatnonzero(split), [5, 11])
    np.testing.assert_array_equal(F.clusters(split, 4), [0] * 6 + [1] * 6)
    # closed: 11 points 0.5 m apart, the step from the last back to the first (5 m) is the gap
    ring = np.column_stack([np.full(11, 3.0), np.arange(11) * 0.5 - 2.75])
    is_break_c, split_c = F.break_points(ring, t2[:11], 0.1, closed=True)
    np.testing.assert_array_equal(np.flatnonzero(is_break_c), [0, 10])
    np.testing.assert_array_equal(np.flatnonzero(split_c), [10])


def test_break_points_both_sides_of_a_gap() -> None:
    y = np.concatenate([np.arange(10) * 0.05, 1.5 + np.arange(10) * 0.05])
    pts = np.column_stack([np.full(len(y), 2.0), y])
    is_break, split = F.break_points(pts, np.full(len(y), 0.2), 0.1)
    np.testing.assert_array_equal(np.flatnonzero(is_break), [0, 9, 10, 19])
    np.testing.assert_array_equal(np.flatnonzero(split), [9, 19])
    labels = F.clusters(split, 4)
    np.testing.assert_array_equal(labels, [0] * 10 + [1] * 10)
    # a cluster smaller than the minimum is dropped (-1)
    np.testing.assert_array_equal(F.clusters(split, 11), [-1] * 20)


def test_break_points_empty_input() -> None:
    is_break, split = F.break_points(np.zeros((0, 2)), np.zeros(0), 0.1)
    assert is_break.shape == (0,) and split.shape == (0,)


# ---------------------------------------------------------------------------------------------
# 5. angular points (§3.4, eq. 14)
# ---------------------------------------------------------------------------------------------
ROOM = sim.rectangular_room()  # 8 m x 6 m, corners (±4, ±3)
ROOM_VIEWS = [
    pytest.param(Pose2D(0.3, -0.2, 0.1), FULL, 4, id="360-inside"),
    pytest.param(Pose2D(-0.6, 0.4, 2.3), FULL, 4, id="360-turned"),
    pytest.param(Pose2D(1.0, 1.0, math.radians(20.0)), HALF, 2, id="180-facing-corners"),
    pytest.param(Pose2D(-0.5, -0.4, math.radians(-140.0)), HALF, 2, id="180-facing-back"),
]


@pytest.mark.parametrize(("pose", "scanner", "n_corners"), ROOM_VIEWS)
def test_refined_angular_points_are_the_true_corners(
    pose: Pose2D, scanner: sim.ScannerModel, n_corners: int
) -> None:
    """Default config (refine=True): each angular point within 2 cm of a true corner."""
    assert CFG.angular_points.refine
    f = F.extract_features(sim.simulate_scan(ROOM, pose, scanner))
    truth = robot_corners(ROOM, pose, scanner)
    assert len(truth) == n_corners
    assert len(f.angular_points) == n_corners
    assert np.all(nearest(truth, f.angular_points.xy) < 0.02)
    assert np.all(nearest(f.angular_points.xy, truth) < 0.02)
    assert np.all(f.angular_points.kind == F.ANGULAR_POINT)


@pytest.mark.parametrize(("pose", "scanner", "n_corners"), ROOM_VIEWS)
@pytest.mark.parametrize(
    "config",
    [PAPER, CFG.with_overrides({"angular_points": {"refine": False}})],
    ids=["paper", "refine-off"],
)
def test_sampled_angular_points_within_one_beam_spacing(
    pose: Pose2D, scanner: sim.ScannerModel, n_corners: int, config: Config
) -> None:
    """refine=False: the angular points are sampled scan points, each within one beam spacing
    (ρ·Δφ, plus 1 cm) of the true corner (SPEC step 5)."""
    assert not config.angular_points.refine
    f = F.extract_features(sim.simulate_scan(ROOM, pose, scanner), config)
    truth = robot_corners(ROOM, pose, scanner)
    ap = f.angular_points.xy
    assert len(ap) == n_corners == f.is_angular_point.sum()
    # they are the sampled points themselves
    np.testing.assert_array_equal(ap, f.kept_points[f.is_angular_point])
    spacing = np.linalg.norm(truth, axis=1) * abs(scanner.angle_increment)
    assert np.all(nearest(truth, ap) <= spacing + 0.01)
    # and not already exact (the refinement is what makes them so)
    assert nearest(truth, ap).max() > 1e-6


def test_angular_points_interior_angle_on_a_constructed_corner() -> None:
    """An L of points: the corner vertex is the one angular point; its interior angle is 90°,
    and a straight wall's interior angle is 180°."""
    a = np.column_stack([np.full(15, 3.0), np.linspace(-1.4, 0.0, 15)])  # up the wall x = 3
    b = np.column_stack([3.0 - np.linspace(0.1, 1.4, 14), np.zeros(14)])  # along y = 0
    pts = np.vstack([a, b])
    cluster = np.zeros(len(pts), dtype=np.int64)
    steps = segmentation._steps(pts, closed=False)
    is_corner, angle = F.angular_points(pts, cluster, steps, CFG)
    np.testing.assert_array_equal(np.flatnonzero(is_corner), [14])
    assert angle[14] == pytest.approx(math.pi / 2, abs=1e-12)
    assert angle[7] == pytest.approx(math.pi, abs=1e-12)
    # nothing is a corner where the cluster is dropped
    is_corner_dropped, _ = F.angular_points(pts, np.full(len(pts), -1), steps, CFG)
    assert not is_corner_dropped.any()


# ---------------------------------------------------------------------------------------------
# 6. lines (§3.5, §2.3)
# ---------------------------------------------------------------------------------------------
LINE_VIEWS = [
    pytest.param(Pose2D(0.0, 0.0, 0.0), FULL, id="360-axis-aligned"),
    pytest.param(Pose2D(0.5, -0.3, 0.4), FULL, id="360-rotated"),
    pytest.param(Pose2D(-1.2, 0.7, -2.9), FULL, id="360-rotated-2"),
    pytest.param(Pose2D(1.0, 1.0, math.radians(20.0)), HALF, id="180-rotated"),
    pytest.param(Pose2D(0.2, -0.1, math.pi / 2), HALF, id="180-axis-aligned"),
]


@pytest.mark.parametrize(("pose", "scanner"), LINE_VIEWS)
def test_lines_are_the_true_walls(pose: Pose2D, scanner: sim.ScannerModel) -> None:
    f = F.extract_features(sim.simulate_scan(ROOM, pose, scanner))
    n_true, d_true = true_walls(ROOM, pose)
    err = line_to_wall_error(f.lines, n_true, d_true)
    assert len(f.lines) >= (4 if scanner is FULL else 2)
    assert np.all(err.min(axis=1) < 1e-3)  # every line is a wall, within 1 mm
    if scanner is FULL:
        assert set(err.argmin(axis=1)) == {0, 1, 2, 3}  # and every wall is seen
    # unit normals, n·p = d at both endpoints, centre the midpoint
    np.testing.assert_allclose(np.linalg.norm(f.lines.normal, axis=1), 1.0, atol=1e-12)
    for p in (f.lines.start, f.lines.end, f.lines.centre):
        np.testing.assert_allclose(np.sum(f.lines.normal * p, axis=1), f.lines.distance, atol=1e-9)
    np.testing.assert_allclose(f.lines.centre, 0.5 * (f.lines.start + f.lines.end), atol=1e-12)
    # noise-free walls: points on the line, low uncertainty
    assert np.all(f.lines.sigma < 1e-9)
    assert np.all(f.lines.uncertainty < 0.2)
    assert np.all(f.lines.n_points >= CFG.lines.min_points)


def test_axis_aligned_room_gives_vertical_and_horizontal_lines() -> None:
    """Heading 0 in the axis-aligned room: normals (±1, 0) (vertical lines x = ±4) and (0, ±1)
    (horizontal lines y = ±3), the case slope–intercept fits (eq. 15–16) cannot represent."""
    f = F.extract_features(sim.simulate_scan(ROOM, Pose2D(), FULL))
    expected = {(1, 0, 4.0), (-1, 0, 4.0), (0, 1, 3.0), (0, -1, 3.0)}
    got = {
        (round(n[0]), round(n[1]), round(float(d), 9))
        for n, d in zip(f.lines.normal, f.lines.distance)
    }
    assert got == expected
    np.testing.assert_allclose(np.abs(f.lines.normal).max(axis=1), 1.0, atol=1e-12)


@pytest.mark.parametrize(("pose", "scanner", "n_corners"), ROOM_VIEWS)
def test_lines_meeting_at_a_corner_share_the_corner_as_endpoint(
    pose: Pose2D, scanner: sim.ScannerModel, n_corners: int
) -> None:
    """§3.5 b): the endpoints of two lines that meet at an angular point are their
    intersection, which on noise-free walls is the true corner."""
    f = F.extract_features(sim.simulate_scan(ROOM, pose, scanner))
    truth = robot_corners(ROOM, pose, scanner)
    for c in truth:
        ends = np.flatnonzero(np.linalg.norm(f.lines.end - c, axis=1) < 1e-6)
        starts = np.flatnonzero(np.linalg.norm(f.lines.start - c, axis=1) < 1e-6)
        assert len(ends) == 1 and len(starts) == 1, f"corner {c} is not a joined endpoint"
        i, j = int(ends[0]), int(starts[0])
        assert i != j
        # the two lines are perpendicular walls
        assert abs(float(f.lines.normal[i] @ f.lines.normal[j])) < 1e-9


def test_line_endpoints_without_a_corner_are_projections_of_the_extreme_points() -> None:
    """A lone wall (no angular point): endpoints are the projections of its extreme points."""
    scan = sim.simulate_scan(wall_world(2.0, 8.0), Pose2D(), HALF)
    f = F.extract_features(scan)
    kp = f.kept_points
    assert len(f.lines) == 1
    ends = {tuple(np.round(f.lines.start[0], 9)), tuple(np.round(f.lines.end[0], 9))}
    assert ends == {tuple(np.round(kp[0], 9)), tuple(np.round(kp[-1], 9))}


# ---------------------------------------------------------------------------------------------
# intersections (SPEC's fix of eq. 15–16)
# ---------------------------------------------------------------------------------------------
def _unit(a: float) -> np.ndarray:
    return np.array([[math.cos(a), math.sin(a)]])


def test_intersect_vertical_and_horizontal_lines() -> None:
    pts, s = features_oracle.intersect_lines(
        np.array([[1.0, 0.0]]), np.array([2.0]), np.array([[0.0, 1.0]]), np.array([-3.0])
    )
    np.testing.assert_allclose(pts, [[2.0, -3.0]], atol=1e-15)
    assert s[0] == pytest.approx(1.0)


def test_intersect_two_oblique_lines() -> None:
    n1, n2 = _unit(math.radians(30.0)), _unit(math.radians(100.0))
    d1, d2 = np.array([1.7]), np.array([-0.4])
    pts, s = features_oracle.intersect_lines(n1, d1, n2, d2)
    expected = np.linalg.solve(np.vstack([n1, n2]), np.concatenate([d1, d2]))
    np.testing.assert_allclose(pts[0], expected, atol=1e-12)
    assert s[0] == pytest.approx(math.sin(math.radians(70.0)), abs=1e-12)


def test_intersect_parallel_lines_is_flagged() -> None:
    n = np.vstack([_unit(0.3), _unit(0.3), _unit(1.2)])
    m = np.vstack([_unit(0.3), _unit(0.3 + math.pi), _unit(1.2 + 1e-14)])
    pts, s = features_oracle.intersect_lines(
        n, np.array([1.0, 1.0, 2.0]), m, np.array([2.0, 1.0, 2.0])
    )
    np.testing.assert_allclose(s, 0.0, atol=1e-12)
    assert np.all(np.isfinite(pts))


@given(
    st.floats(-20, 20),
    st.floats(-20, 20),
    st.floats(-math.pi, math.pi),
    st.floats(-math.pi, math.pi),
)
def test_intersect_recovers_the_common_point(x: float, y: float, a1: float, a2: float) -> None:
    sin = abs(math.sin(a1 - a2))
    assume(sin > 0.05)
    p = np.array([x, y])
    n1, n2 = _unit(a1), _unit(a2)
    pts, s = features_oracle.intersect_lines(n1, n1 @ p, n2, n2 @ p)
    assert s[0] == pytest.approx(sin, abs=1e-12)
    np.testing.assert_allclose(pts[0], p, atol=1e-11 * (1 + abs(x) + abs(y)) / sin)


# ---------------------------------------------------------------------------------------------
# 7. virtual angular points (§3.6)
# ---------------------------------------------------------------------------------------------
FURNISHED = sim.furnished_room()
FURNISHED_VIEWS = [
    pytest.param(Pose2D(0.2, 0.1, 0.3), HALF, id="180"),
    pytest.param(Pose2D(0.2, 0.1, 0.3), FULL, id="360"),
    pytest.param(Pose2D(-1.0, -0.5, 2.0), FULL, id="360-b"),
]


@pytest.mark.parametrize(("pose", "scanner"), FURNISHED_VIEWS)
def test_virtual_points_are_intersections_of_their_lines(
    pose: Pose2D, scanner: sim.ScannerModel
) -> None:
    f = F.extract_features(sim.simulate_scan(FURNISHED, pose, scanner))
    vp, vl, lines = f.virtual_points, f.virtual_lines, f.lines
    assert len(vp) > 0
    assert vl.shape == (len(vp), 2)
    assert np.all((vl >= 0) & (vl < len(lines))) and np.all(vl[:, 0] != vl[:, 1])
    assert len({tuple(sorted(r)) for r in vl.tolist()}) == len(vl)  # each pair once
    for k, (i, j) in enumerate(vl):
        for li in (i, j):
            assert lines.normal[li] @ vp.xy[k] == pytest.approx(lines.distance[li], abs=1e-9)
        sin = abs(lines.normal[i, 0] * lines.normal[j, 1] - lines.normal[i, 1] * lines.normal[j, 0])
        assert sin >= math.sin(CFG.virtual_points.min_intersection_angle) - 1e-12
    assert np.all(vp.uncertainty <= CFG.virtual_points.max_uncertainty)
    assert np.all((vp.uncertainty >= 0) & (vp.uncertainty <= 1))
    assert np.all(vp.kind == F.VIRTUAL_ANGULAR_POINT)
    # two lines that meet at a real angular point give that angular point, not a virtual one
    joined = {
        tuple(sorted((int(a), int(b))))
        for a in range(len(lines))
        for b in range(len(lines))
        if a != b
        and np.linalg.norm(lines.end[a] - lines.start[b]) < 1e-9
        and nearest(lines.end[a][None], f.angular_points.xy)[0] < 1e-9
    }
    assert joined  # the scene has such corners
    assert not joined & {tuple(sorted(r)) for r in vl.tolist()}


def test_virtual_point_thresholds_select_subsets() -> None:
    """Raising the minimum angle or lowering the maximum uncertainty keeps exactly the virtual
    points of the default that pass the stricter rule (and no new ones)."""
    scan = sim.simulate_scan(FURNISHED, Pose2D(0.2, 0.1, 0.3), FULL)
    f = F.extract_features(scan)
    n = f.lines.normal
    i, j = f.virtual_lines[:, 0], f.virtual_lines[:, 1]
    sin = np.abs(n[i, 0] * n[j, 1] - n[i, 1] * n[j, 0])

    g = F.extract_features(
        scan, CFG.with_overrides({"virtual_points": {"min_intersection_angle": math.radians(70.0)}})
    )
    want = f.virtual_points.xy[sin >= math.sin(math.radians(70.0))]
    assert 0 < len(want) < len(f.virtual_points)
    assert len(g.virtual_points) == len(want)
    assert np.all(nearest(g.virtual_points.xy, want) < 1e-12)

    h = F.extract_features(scan, CFG.with_overrides({"virtual_points": {"max_uncertainty": 0.3}}))
    want = f.virtual_points.xy[f.virtual_points.uncertainty <= 0.3]
    assert 0 < len(want) < len(f.virtual_points)
    assert len(h.virtual_points) == len(want)
    assert np.all(nearest(h.virtual_points.xy, want) < 1e-12)


def test_virtual_points_of_parallel_and_near_parallel_lines_do_not_exist() -> None:
    """virtual_angular_points on hand-made lines: parallel lines and lines 20° apart (< 30°) give
    nothing; a 90° pair gives its intersection."""

    def lines(angles_deg: list[float], dists: list[float]) -> F.Lines:
        k = len(angles_deg)
        nrm = np.vstack([_unit(math.radians(a)) for a in angles_deg])
        d = np.array(dists)
        tangent = np.column_stack([-nrm[:, 1], nrm[:, 0]])
        start = nrm * d[:, None] - tangent
        end = nrm * d[:, None] + tangent
        return F.Lines(
            nrm,
            d,
            start,
            end,
            0.5 * (start + end),
            np.full(k, 10),
            np.zeros(k),
            np.zeros(k),
            np.zeros(k),
            np.arange(k),
            np.zeros(k, dtype=np.int64),
        )

    bases = F.rule_bases(CFG.fuzzy)
    vp, vl, _ = F.virtual_angular_points(lines([0.0, 0.0, 180.0, 20.0], [1, 2, 1, 1]), bases, CFG)
    assert len(vp) == 0
    vp, vl, _ = F.virtual_angular_points(lines([0.0, 90.0], [1.0, 1.5]), bases, CFG)
    assert len(vp) == 1
    np.testing.assert_allclose(vp.xy[0], [1.0, 1.5], atol=1e-12)
    np.testing.assert_array_equal(vl, [[0, 1]])


# ---------------------------------------------------------------------------------------------
# sensor mounting
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "sensor_pose", [Pose2D(0.3, 0.0, 0.0), Pose2D(0.3, 0.1, 0.5), Pose2D(-0.2, 0.05, math.pi)]
)
def test_sensor_pose_puts_features_where_they_are_in_the_robot_frame(sensor_pose: Pose2D) -> None:
    robot = Pose2D(0.4, -0.3, 0.6)
    scanner = sim.ScannerModel(sensor_pose=sensor_pose)
    scan = sim.simulate_scan(ROOM, robot, scanner)
    assert scan.sensor_pose == sensor_pose
    f = F.extract_features(scan)
    # the points are in the robot frame: they lie on the room's walls once moved by the pose
    assert np.all(ROOM.distance(robot.transform_points(f.points)) < 1e-9)
    # lines and corners where they truly are (robot frame)
    n_true, d_true = true_walls(ROOM, robot)
    assert len(f.lines) >= 2
    assert np.all(line_to_wall_error(f.lines, n_true, d_true).min(axis=1) < 1e-6)
    truth = robot_corners(ROOM, robot, scanner)
    assert len(truth) >= 1 and len(f.angular_points) == len(truth)
    assert np.all(nearest(f.angular_points.xy, truth) < 0.02)
    # β is measured from the sensor's beam, not from the robot's origin
    laser = robot.compose(sensor_pose)
    world_pts = robot.transform_points(f.points)
    bearing_rel = scan.angles[f.beam_index]  # beam direction in the sensor frame
    # incidence on the wall hit: angle between the beam and that wall
    _, seg = sim.cast_rays(
        ROOM, (laser.x, laser.y), laser.theta + bearing_rel, 100.0, return_segment=True
    )
    s = ROOM.segments[seg]
    t = (s[:, 2:] - s[:, :2]) / np.linalg.norm(s[:, 2:] - s[:, :2], axis=1)[:, None]
    beam = np.column_stack([np.cos(laser.theta + bearing_rel), np.sin(laser.theta + bearing_rel)])
    cross = np.abs(beam[:, 0] * t[:, 1] - beam[:, 1] * t[:, 0])
    incidence = np.arctan2(cross, np.abs(np.sum(beam * t, axis=1)))
    # points next to a corner take their step across it: compare away from the corners
    far = nearest(world_pts, ROOM.corner_points()) > 0.5
    assert far.sum() > 100
    np.testing.assert_allclose(f.detection_angle[far], incidence[far], atol=1e-9)


# ---------------------------------------------------------------------------------------------
# bad input, odd scans
# ---------------------------------------------------------------------------------------------
def _assert_empty(f: F.Features, n_valid: int) -> None:
    assert f.n_valid == n_valid
    assert len(f.lines) == 0
    assert len(f.angular_points) == 0 and len(f.virtual_points) == 0
    assert len(f.break_points) == 0 and len(f.points_of_interest) == 0
    assert f.virtual_lines.shape == (0, 2)
    assert f.points.shape == (n_valid, 2)
    assert f.points_of_interest.xy.shape == (0, 2)
    n_kept = len(f.kept_index)
    per_kept = (f.is_break_point, f.cluster, f.is_angular_point, f.segment, f.is_field_of_view_edge)
    for arr in per_kept:
        assert arr.shape == (n_kept,)


@pytest.mark.parametrize(
    ("ranges", "n_valid"),
    [
        ([], 0),
        ([np.nan] * 50, 0),
        ([0.0] * 50, 0),
        ([np.inf, -np.inf, np.nan, 0.0, -1.0, 8.0], 0),
        ([3.0], 1),
        ([3.0, 3.0], 2),
        ([3.0, 3.0, 3.0], 3),
    ],
    ids=["empty", "all-nan", "all-zero", "all-invalid-mixed", "one-beam", "two-beams", "three"],
)
def test_degenerate_scans_give_empty_features(ranges: list[float], n_valid: int) -> None:
    scan = LaserScan(np.array(ranges, dtype=float), -0.3, 0.01, range_min=0.02, range_max=8.0)
    f = F.extract_features(scan)
    _assert_empty(f, n_valid)
    g = F.extract_features(scan, PAPER)
    _assert_empty(g, n_valid)


def test_invalid_readings_are_not_used() -> None:
    """NaN, ±inf, 0, negative and max-range readings in the middle of a wall: those beams are
    not valid points, and the wall is still found exactly."""
    scan = sim.simulate_scan(wall_world(2.0, 8.0), Pose2D(), HALF)
    bad_beams = {80: np.nan, 85: np.inf, 90: -np.inf, 95: 0.0, 100: -2.0, 105: scan.range_max}
    r = scan.ranges.copy()
    for i, v in bad_beams.items():
        r[i] = v
    f = F.extract_features(scan.with_ranges(r))
    assert not set(bad_beams) & set(f.beam_index.tolist())
    assert f.n_valid == F.extract_features(scan).n_valid - len(bad_beams)
    assert np.all(np.isfinite(f.points)) and np.all(np.isfinite(f.detection_angle))
    assert np.all(np.isfinite(f.uncertainty))
    assert len(f.lines) == 1
    np.testing.assert_allclose(f.lines.normal[0], [1.0, 0.0], atol=1e-9)
    assert f.lines.distance[0] == pytest.approx(2.0, abs=1e-9)


def test_full_circle_scan() -> None:
    scan = sim.simulate_scan(ROOM, Pose2D(0.3, -0.2, 0.1), FULL)
    assert scan.is_full_circle
    f = F.extract_features(scan)
    assert f.n_valid == 360 and f.kept.all()
    assert not f.is_field_of_view_edge.any()  # a full circle has no field-of-view edge
    assert len(f.break_points) == 0  # a closed room has no gap
    assert len(f.angular_points) == 4


@pytest.mark.parametrize(
    ("world", "pose", "scanner"),
    [
        (ROOM, Pose2D(0.5, -0.3, 0.4), HALF),
        (ROOM, Pose2D(0.3, -0.2, 0.1), FULL),
        (FURNISHED, Pose2D(0.2, 0.1, 0.3), HALF),
        (FURNISHED, Pose2D(0.2, 0.1, 0.3), FULL),
    ],
    ids=["room-180", "room-360", "furnished-180", "furnished-360"],
)
def test_negative_increment_is_mirror_consistent(
    world: sim.World, pose: Pose2D, scanner: sim.ScannerModel
) -> None:
    scan = sim.simulate_scan(world, pose, scanner)
    a = F.extract_features(scan)
    b = F.extract_features(mirrored(scan))
    _assert_same_lines_and_points(a, b)


def _assert_same_lines_and_points(a: F.Features, b: F.Features) -> None:
    assert len(a.lines) == len(b.lines) > 0
    ka = np.column_stack([a.lines.normal, a.lines.distance])
    kb = np.column_stack([b.lines.normal, b.lines.distance])
    assert np.all(nearest(ka, kb) < 1e-9) and np.all(nearest(kb, ka) < 1e-9)
    for name in ("angular_points", "virtual_points", "points_of_interest"):
        pa, pb = getattr(a, name).xy, getattr(b, name).xy
        assert len(pa) == len(pb), name
        assert np.all(nearest(pa, pb) < 1e-9) and np.all(nearest(pb, pa) < 1e-9), name


def test_negative_increment_is_mirror_consistent_at_a_cluster_end_corner() -> None:
    """office(), robot (-2, 0, 0.1 rad), 360 beams: the SW desk's corner sits at the start of a
    cluster. Same readings reversed must give the same lines."""
    scan = sim.simulate_scan(sim.office(), Pose2D(-2.0, 0.0, 0.1), FULL)
    a = F.extract_features(scan)
    b = F.extract_features(mirrored(scan))
    _assert_same_lines_and_points(a, b)


# ---------------------------------------------------------------------------------------------
# full-circle wrap-around (SPEC: a 360° scan wraps around, indices modulo m)
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("extra_deg", [0.5, 2.9], ids=["corner-at-wrap", "corner-near-wrap"])
def test_corner_behind_a_full_circle_scanner(extra_deg: float) -> None:
    pose = Pose2D(0.0, 0.0, math.atan2(3.0, 4.0) + math.radians(extra_deg))
    f = F.extract_features(sim.simulate_scan(ROOM, pose, FULL))
    truth = robot_corners(ROOM, pose, FULL)
    assert len(truth) == 4
    assert np.all(nearest(truth, f.angular_points.xy) < 0.02)


def test_full_circle_room_gives_one_line_per_wall() -> None:
    f = F.extract_features(sim.simulate_scan(ROOM, Pose2D(), FULL))
    assert len(f.lines) == 4


# ---------------------------------------------------------------------------------------------
# the intermediates extract_features keeps
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("world", "pose", "scanner", "config"),
    [
        (ROOM, Pose2D(0.3, -0.2, 0.1), FULL, CFG),
        (FURNISHED, Pose2D(0.2, 0.1, 0.3), HALF, CFG),
        (FURNISHED, Pose2D(-1.0, -0.5, 2.0), FULL, PAPER),
        (sim.office(), Pose2D(-6.0, 0.2, 0.2), HALF, PAPER),
        (sim.doorway_wall(back_wall_distance=4.0), Pose2D(0.1, 0.1, 0.1), HALF, CFG),
    ],
    ids=["room", "furnished", "furnished-paper", "office-paper", "doorway"],
)
def test_intermediates_are_consistent(
    world: sim.World, pose: Pose2D, scanner: sim.ScannerModel, config: Config
) -> None:
    scan = sim.simulate_scan(world, pose, scanner, stamp=12.5)
    f = F.extract_features(scan, config)
    n = f.n_valid
    assert f.stamp == 12.5
    # per valid reading
    np.testing.assert_array_equal(f.beam_index, np.flatnonzero(scan.valid))
    for arr in (f.ranges, f.detection_angle, f.uncertainty, f.kept):
        assert arr.shape == (n,)
    assert f.points.shape == (n, 2)
    np.testing.assert_array_equal(f.ranges, scan.ranges[f.beam_index])
    ang = scan.angles[f.beam_index]
    sensor_pts = np.column_stack([f.ranges * np.cos(ang), f.ranges * np.sin(ang)])
    np.testing.assert_allclose(f.points, scan.sensor_pose.transform_points(sensor_pts), atol=1e-12)
    assert np.all((f.uncertainty >= 0) & (f.uncertainty <= 1))
    # per kept point, in processing order: counter-clockwise, a 360° scan starting after a gap
    # (or at its sharpest corner), so kept_index is flatnonzero(kept) rotated
    ordered = np.flatnonzero(f.kept)
    shift = int(np.flatnonzero(ordered == f.kept_index[0])[0]) if len(ordered) else 0
    np.testing.assert_array_equal(f.kept_index, np.roll(ordered, -shift))
    m = len(f.kept_index)
    assert m > 0 and np.all((f.kept_index >= 0) & (f.kept_index < n))
    per_kept = (f.is_break_point, f.is_field_of_view_edge, f.cluster, f.is_angular_point, f.segment)
    for arr in per_kept:
        assert arr.shape == (m,)
    np.testing.assert_array_equal(f.kept_points, f.points[f.kept_index])
    # clusters: -1 or 0..k-1, contiguous runs, each at least the minimum size
    labels = f.cluster[f.cluster >= 0]
    assert np.all(np.diff(labels) >= 0)
    np.testing.assert_array_equal(np.unique(labels), np.arange(f.n_clusters))
    assert np.all(np.bincount(labels) >= config.segmentation.min_cluster_points)
    # angular points and segments only inside kept clusters; an angular point is in no segment
    assert np.all(f.cluster[f.is_angular_point] >= 0)
    assert np.all(f.segment[f.cluster < 0] == -1)
    assert np.all(f.segment[f.is_angular_point] == -1)
    # lines: fitted to their segment's points, which lie on the line (noise-free)
    L = f.lines
    k = len(L)
    for arr in (L.distance, L.n_points, L.sigma, L.delta, L.uncertainty, L.segment, L.cluster):
        assert arr.shape == (k,)
    for arr in (L.normal, L.start, L.end, L.centre):
        assert arr.shape == (k, 2)
    kp = f.kept_points
    for li in range(k):
        members = f.segment == L.segment[li]
        assert members.sum() == L.n_points[li]
        assert np.all(f.cluster[members] == L.cluster[li])
        resid = np.abs(kp[members] @ L.normal[li] - L.distance[li])
        assert L.sigma[li] == pytest.approx(resid.mean(), abs=1e-12)  # eq. 8
        assert L.delta[li] == pytest.approx(f.uncertainty[f.kept_index[members]].mean(), abs=1e-12)
    assert np.all((L.uncertainty >= 0) & (L.uncertainty <= 1))
    # feature points
    assert len(f.angular_points) == int(f.is_angular_point.sum())
    assert f.virtual_lines.shape == (len(f.virtual_points), 2)
    bp = f.break_points.xy
    assert np.all(nearest(bp, kp[f.is_break_point & ~f.is_field_of_view_edge]) == 0.0)
    if not config.angular_points.refine:
        np.testing.assert_array_equal(f.angular_points.xy, kp[f.is_angular_point])
    # points of interest come from the kinds the config uses
    poi = f.points_of_interest
    allowed = []
    if config.matching.use_break_points:
        allowed.append(f.break_points.xy)
    if config.matching.use_angular_points:
        allowed.append(f.angular_points.xy)
    if config.matching.use_virtual_points:
        allowed.append(f.virtual_points.xy)
    assert np.all(nearest(poi.xy, np.vstack(allowed)) == 0.0)
    kinds = set(poi.kind.tolist())
    assert (F.BREAK_POINT in kinds) <= config.matching.use_break_points
    # no two points of interest closer than the merge distance
    if len(poi) > 1:
        d = np.linalg.norm(poi.xy[:, None] - poi.xy[None], axis=2) + np.eye(len(poi)) * 1e9
        assert d.min() >= config.virtual_points.merge_distance
