"""Tests of the robot simulator: commanded paths, the slip model (a commanded circle becomes an
outward spiral while the odometry stays on the circle) and simulated runs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzypos import sim
from fuzzypos.geometry import Pose2D, compose, inverse, wrap_angle
from fuzzypos.sim import CommandedPath, ScannerModel, SimError, SlipModel, simulate_run

WORLD = sim.gym()
IDEAL = SlipModel.ideal()
EXACT = ScannerModel.sick_lms200(
    range_noise_std=0.0,
    range_noise_per_metre=0.0,
    incidence_noise=0.0,
    dropout_probability=0.0,
    spurious_probability=0.0,
)


def angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(wrap_angle(np.asarray(a) - np.asarray(b)))


def assert_poses_close(a: np.ndarray, b: np.ndarray, tol: float) -> None:
    np.testing.assert_allclose(a[..., :2], b[..., :2], rtol=0, atol=tol)
    assert np.max(angle_diff(a[..., 2], b[..., 2])) <= tol


def lap_means(run: sim.SimulatedRun, poses: np.ndarray, lap_time: float, laps: int) -> np.ndarray:
    r = np.hypot(poses[:, 0], poses[:, 1])
    return np.array(
        [
            r[(run.stamps >= k * lap_time) & (run.stamps < (k + 1) * lap_time)].mean()
            for k in range(laps)
        ]
    )


# ---------------------------------------------------------------------------------------------
# commanded paths
# ---------------------------------------------------------------------------------------------


def test_circle_commands() -> None:
    p = CommandedPath.circle(4.0, laps=2.5, speed=0.5, centre=(1.0, -2.0))
    assert p.start == Pose2D(5.0, -2.0, math.pi / 2)
    assert p.duration == pytest.approx(2.5 * 2 * math.pi * 4.0 / 0.5)
    assert p.length == pytest.approx(2.5 * 2 * math.pi * 4.0)
    v, w = p.commands([0.0, 10.0, p.duration, p.duration + 1.0, -1.0])
    np.testing.assert_allclose(v, [0.5, 0.5, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(w, [0.125, 0.125, 0.0, 0.0, 0.0])
    t = np.linspace(0.0, p.duration, 333)
    poses = p.poses(t)
    np.testing.assert_allclose(np.hypot(poses[:, 0] - 1.0, poses[:, 1] + 2.0), 4.0, atol=1e-9)
    # heading is the tangent, anticlockwise
    tangent = np.arctan2(poses[:, 1] + 2.0, poses[:, 0] - 1.0) + math.pi / 2
    assert np.max(angle_diff(poses[:, 2], tangent)) < 1e-9
    cw = CommandedPath.circle(2.0, clockwise=True)
    assert cw.start == Pose2D(2.0, 0.0, -math.pi / 2) and cw.segments[0, 2] < 0
    assert_poses_close(cw.poses([cw.duration / 4])[0], np.array([0.0, -2.0, math.pi]), 1e-9)


def test_square_is_four_legs_and_turns_on_the_spot() -> None:
    p = CommandedPath.square(3.0, laps=2, speed=0.25, turn_rate=math.radians(30.0), centre=(1, 1))
    assert p.start == Pose2D(-0.5, -0.5, 0.0)
    assert len(p.segments) == 16
    straight, turns = p.segments[0::2], p.segments[1::2]
    assert np.all(straight[:, 2] == 0.0) and np.all(straight[:, 1] == 0.25)
    assert np.all(turns[:, 1] == 0.0) and np.allclose(turns[:, 0] * turns[:, 2], math.pi / 2)
    corners = p.segment_poses()
    want = [(-0.5, -0.5), (2.5, -0.5), (2.5, -0.5), (2.5, 2.5), (2.5, 2.5), (-0.5, 2.5)]
    np.testing.assert_allclose(corners[:6, :2], want, atol=1e-12)
    assert np.max(angle_diff(corners[:6, 2], np.radians([0, 0, 90, 90, 180, 180]))) < 1e-9
    assert_poses_close(corners[-1], p.start.as_array(), 1e-9)  # closes after its last turn
    assert p.length == pytest.approx(24.0)
    # every commanded pose lies on the square's outline
    q = p.poses(np.linspace(0.0, p.duration, 1000))
    dx, dy = np.abs(q[:, 0] - 1.0), np.abs(q[:, 1] - 1.0)
    assert np.all(np.abs(np.maximum(dx, dy) - 1.5) < 1e-9)


def test_figure8_passes_the_centre_twice_per_lap() -> None:
    r, v = 2.0, 0.4
    p = CommandedPath.figure8(r, laps=2, speed=v, centre=(1.0, 0.5))
    loop = 2 * math.pi * r / v
    assert p.duration == pytest.approx(4 * loop)
    at_centre = p.poses(np.arange(5) * loop)
    assert_poses_close(at_centre, np.tile([1.0, 0.5, 0.0], (5, 1)), 1e-9)
    # the first loop is the anticlockwise circle north of the centre, the second the clockwise
    # one south of it; between the loops the robot is never at the centre
    t = np.linspace(0.0, 2 * loop, 2001)
    q = p.poses(t)
    north = t < loop
    np.testing.assert_allclose(np.hypot(q[north, 0] - 1.0, q[north, 1] - 2.5), r, atol=1e-9)
    np.testing.assert_allclose(np.hypot(q[~north, 0] - 1.0, q[~north, 1] + 1.5), r, atol=1e-9)
    assert np.all(q[north, 1] >= 0.5 - 1e-9) and np.all(q[~north, 1] <= 0.5 + 1e-9)
    far = np.abs(((t + loop / 4) % loop) - loop / 4) > 0.05 * loop
    assert np.all(np.hypot(q[far, 0] - 1.0, q[far, 1] - 0.5) > 0.5)
    assert p.poses([loop / 2])[0, 1] == pytest.approx(4.5)


def test_waypoints() -> None:
    pts = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 2.0], [-1.0, 2.0], [-1.0, 2.0 - 1e-3]])
    p = CommandedPath.waypoints(pts, speed=0.5, turn_rate=1.0)
    assert p.start == Pose2D(0.0, 0.0, 0.0)
    bp = p.segment_poses()
    drive = np.flatnonzero(p.segments[:, 1] != 0.0)
    np.testing.assert_allclose(bp[drive + 1, :2], pts[1:], atol=1e-12)  # every waypoint reached
    spins = p.segments[p.segments[:, 1] == 0.0]
    np.testing.assert_allclose(spins[:, 0] * spins[:, 2], [math.pi / 2, math.pi / 2, math.pi / 2])
    assert p.length == pytest.approx(3.0 + 2.0 + 4.0 + 1e-3)
    # with a start heading, a first turn on the spot (the shorter way)
    q = CommandedPath.waypoints([[0, 0], [0, -1]], heading=math.pi)
    assert q.segments[0, 1] == 0.0 and q.segments[0, 2] > 0  # from 180° to -90°: turn left 90°
    assert q.segments[0, 0] * q.segments[0, 2] == pytest.approx(math.pi / 2)
    assert_poses_close(q.segment_poses()[-1], np.array([0.0, -1.0, -math.pi / 2]), 1e-9)


@pytest.mark.parametrize(
    "make",
    [
        lambda: CommandedPath(np.zeros((0, 3))),
        lambda: CommandedPath([[1.0, 0.1]]),
        lambda: CommandedPath([[0.0, 0.1, 0.0]]),
        lambda: CommandedPath([[1.0, np.nan, 0.0]]),
        lambda: CommandedPath.circle(0.0),
        lambda: CommandedPath.circle(1.0, laps=-1),
        lambda: CommandedPath.circle(1.0, speed=math.inf),
        lambda: CommandedPath.square(2.0, laps=1.5),
        lambda: CommandedPath.square(2.0, turn_rate=0.0),
        lambda: CommandedPath.figure8(1.0, laps=0),
        lambda: CommandedPath.waypoints([[0, 0]]),
        lambda: CommandedPath.waypoints([[0, 0], [1, 1], [1, 1]]),
        lambda: CommandedPath.waypoints([[0, 0], [1, np.inf]]),
        lambda: CommandedPath.waypoints([[0, 0], [1, 1]], heading=math.nan),
    ],
)
def test_path_validation(make) -> None:
    with pytest.raises(SimError):
        make()


# ---------------------------------------------------------------------------------------------
# the slip model
# ---------------------------------------------------------------------------------------------


def test_slip_defaults() -> None:
    s = SlipModel()
    assert (s.radial_gain, s.longitudinal, s.angular) == (0.05, 0.02, 0.02)
    assert (s.translation_noise, s.rotation_noise) == (0.002, 0.002)
    i = SlipModel.ideal()
    assert (i.radial_gain, i.longitudinal, i.angular, i.translation_noise, i.rotation_noise) == (
        0,
    ) * 5
    for kw in (
        {"radial_gain": -0.1},
        {"longitudinal": 1.0},
        {"angular": -1.5},
        {"translation_noise": -1e-3},
        {"rotation_noise": math.nan},
        {"radial_gain": True},
    ):
        with pytest.raises(SimError):
            SlipModel(**kw)


def test_ideal_run_follows_the_commanded_circle_and_closes() -> None:
    r, T = 3.0, 40.0  # a lap of exactly 40 s, so the last scan is at the end of the path
    path = CommandedPath.circle(r, laps=1, speed=2 * math.pi * r / T)
    run = simulate_run(WORLD, path, slip=IDEAL, with_scans=False)
    assert len(run) == 401 and run.stamps[-1] == 40.0
    cmd = path.poses(run.stamps)
    assert_poses_close(run.true_poses, cmd, 1e-9)
    assert_poses_close(run.odometry_poses, cmd, 1e-9)
    assert_poses_close(run.true_poses[-1], path.start.as_array(), 1e-9)  # closes on itself
    # the distance sums the chords between scans: 1e-5 short of the arc at 10 Hz on this circle
    assert run.distance_travelled[-1] == pytest.approx(path.length, rel=2e-5)


@pytest.mark.parametrize(
    "path",
    [
        CommandedPath.square(2.0, laps=1, speed=0.4),
        CommandedPath.figure8(1.5, laps=1, speed=0.5),
        CommandedPath.waypoints([[0, 0], [2, 1], [0, 2], [1, -1]], speed=0.6, heading=2.0),
    ],
    ids=["square", "figure8", "waypoints"],
)
def test_ideal_runs_follow_every_path(path: CommandedPath) -> None:
    run = simulate_run(WORLD, path, slip=IDEAL, with_scans=False)
    assert_poses_close(run.true_poses, path.poses(run.stamps), 1e-9)
    assert_poses_close(run.odometry_poses, path.poses(run.stamps), 1e-9)


def test_commanded_circle_becomes_an_outward_spiral() -> None:
    r, laps, v = 4.0, 3, 0.3
    path = CommandedPath.circle(r, laps=laps, speed=v)
    slip = SlipModel()
    run = simulate_run(WORLD, path, slip=slip, seed=1, with_scans=False)
    lap_time = path.duration / laps
    true_r = lap_means(run, run.true_poses, lap_time, laps)
    odo_r = lap_means(run, run.odometry_poses, lap_time, laps)
    # the truth moves out lap over lap, about 2π·k·v_true = 9 cm per lap
    growth = np.diff(true_r)
    per_lap = 2 * math.pi * slip.radial_gain * v * (1 - slip.longitudinal)
    assert np.all(growth > 0.7 * per_lap) and np.all(growth < 1.3 * per_lap)
    end_r = math.hypot(*run.true_poses[-1, :2])
    assert end_r == pytest.approx(float(slip.circle_radius(r, v, run.stamps[-1])), abs=1e-6)
    assert 4.2 < end_r < 4.35
    # the odometry stays on the commanded circle within its noise (a few centimetres)
    odo_dist = np.hypot(run.odometry_poses[:, 0], run.odometry_poses[:, 1])
    assert np.max(np.abs(odo_dist - r)) < 0.15
    assert np.all(np.abs(odo_r - r) < 0.05)
    # without encoder noise the odometry is exactly the commanded circle
    quiet = simulate_run(
        WORLD, path, slip=slip.replace(translation_noise=0.0, rotation_noise=0.0), with_scans=False
    )
    assert_poses_close(quiet.odometry_poses, path.poses(quiet.stamps), 1e-9)
    np.testing.assert_array_equal(quiet.true_poses, run.true_poses)  # the truth is not random


def test_slip_kinematics() -> None:
    """The true motion, differentiated: forward speed v(1 − longitudinal), an outward sideways
    skid of radial_gain · |v ω_true|, and a turn rate that starts at ω(1 − angular) and falls as
    the radius grows round a fixed centre."""
    slip = SlipModel(
        radial_gain=0.2, longitudinal=0.05, angular=0.1, translation_noise=0.0, rotation_noise=0.0
    )
    v, w = 0.5, 0.25
    tau = np.linspace(0.0, 60.0, 6001)
    d = slip.true_motion(v, w, tau)
    dt = tau[1] - tau[0]
    # body-frame velocities over each step, in the frame at its middle (second-order accurate)
    step = np.diff(d, axis=0)
    mid = d[:-1, 2] + 0.5 * wrap_angle(step[:, 2])
    c, s = np.cos(mid), np.sin(mid)
    inc = (
        np.column_stack(
            [
                c * step[:, 0] + s * step[:, 1],
                -s * step[:, 0] + c * step[:, 1],
                wrap_angle(step[:, 2]),
            ]
        )
        / dt
    )
    vt, w0 = v * (1 - slip.longitudinal), w * (1 - slip.angular)
    r0 = vt / w0
    centre = np.array([0.0, r0])  # on the left, where the command puts it
    radius = np.hypot(d[:, 0] - centre[0], d[:, 1] - centre[1])
    np.testing.assert_allclose(
        radius, np.sqrt(r0**2 + 2 * slip.radial_gain * vt**2 * tau), rtol=1e-9
    )
    wt = inc[:, 2]
    mid_r = 0.5 * (radius[:-1] + radius[1:])
    np.testing.assert_allclose(wt, vt / mid_r, rtol=1e-4)
    assert wt[0] == pytest.approx(w0, rel=1e-3)
    np.testing.assert_allclose(inc[:, 0], vt, rtol=1e-4)
    np.testing.assert_allclose(inc[:, 1], -slip.radial_gain * vt * wt, rtol=1e-3)  # outward = right
    # heading stays tangent to the circle round the fixed centre
    tangent = np.arctan2(d[:, 1] - centre[1], d[:, 0] - centre[0]) + math.pi / 2
    assert np.max(angle_diff(d[:, 2], tangent)) < 1e-9
    # turning right, the skid is to the left (still outward); driving straight or turning on
    # the spot there is none
    right = slip.true_motion(v, -w, tau)
    np.testing.assert_allclose(right[:, :2] * [1, -1], d[:, :2], atol=1e-12)
    np.testing.assert_allclose(slip.true_motion(v, 0.0, [2.0])[0], [2.0 * vt, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(slip.true_motion(0.0, w, [2.0])[0], [0.0, 0.0, 2.0 * w0], atol=1e-15)


def test_slip_on_other_paths() -> None:
    """On a square the robot turns less than commanded and covers less ground; each loop of an
    eight starts afresh from where the last one ended."""
    slip = SlipModel(translation_noise=0.0, rotation_noise=0.0)
    sq = CommandedPath.square(3.0, laps=1)
    truth = simulate_run(WORLD, sq, slip=slip, with_scans=False).true_poses
    true_corners = np.array([_pose_at(slip, sq, t) for t in sq.boundaries])
    assert true_corners[1, 0] - true_corners[0, 0] == pytest.approx(3.0 * 0.98)
    assert wrap_angle(true_corners[2, 2]) == pytest.approx(math.pi / 2 * 0.98)
    assert np.hypot(*(truth[-1, :2] - sq.start.as_array()[:2])) > 0.1
    eight = CommandedPath.figure8(2.0, laps=1)
    run = simulate_run(WORLD, eight, slip=slip, with_scans=False)
    assert np.all(np.isfinite(run.true_poses))
    assert np.hypot(*run.true_poses[-1, :2]) > 0.1  # it does not come back to the centre


def _pose_at(slip: SlipModel, path: CommandedPath, t: float) -> np.ndarray:
    pose = path.start.as_array()
    for (d, v, w), t0 in zip(path.segments, path.boundaries[:-1]):
        if t <= t0 + 1e-12:
            break
        pose = compose(pose, slip.true_motion(v, w, [min(d, t - t0)])[0])
    return pose


# ---------------------------------------------------------------------------------------------
# runs
# ---------------------------------------------------------------------------------------------


def test_run_stamps_scans_and_duration() -> None:
    path = CommandedPath.circle(4.0, laps=1)
    run = simulate_run(WORLD, path, scanner=EXACT, slip=SlipModel(), duration=3.05, seed=3)
    assert len(run) == 31 and len(run.scans) == 31
    np.testing.assert_array_equal(run.stamps, np.arange(31) / 10.0)
    assert [s.stamp for s in run.scans] == list(run.stamps)
    assert run.true_poses.shape == run.odometry_poses.shape == (31, 3)
    assert_poses_close(run.true_poses[0], path.start.as_array(), 0.0)
    assert_poses_close(run.odometry_poses[0], path.start.as_array(), 0.0)
    # each scan is taken at the true pose
    for k in (0, 17, 30):
        want = sim.simulate_scan(WORLD, run.true_pose(k), EXACT).ranges
        np.testing.assert_array_equal(run.scans[k].ranges, want)
    assert run.odometry_pose(30) == Pose2D.from_array(run.odometry_poses[30])
    with pytest.raises(ValueError):
        run.stamps[0] = 1.0  # read-only
    # the scanner's rate sets the stamps; the robot stands still after the path
    fast = simulate_run(
        WORLD,
        CommandedPath([[1.0, 0.5, 0.0]]),
        scanner=EXACT.replace(rate_hz=4.0),
        slip=IDEAL,
        duration=2.0,
        start=(1.0, 2.0, math.pi / 2),
    )
    np.testing.assert_array_equal(fast.stamps, [0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0])
    np.testing.assert_allclose(fast.true_poses[4:, :2], np.tile([1.0, 2.5], (5, 1)), atol=1e-12)
    np.testing.assert_allclose(
        fast.distance_travelled, [0, 0.125, 0.25, 0.375, 0.5, 0.5, 0.5, 0.5, 0.5]
    )


def test_run_from_another_start_is_the_same_run_moved() -> None:
    path = CommandedPath.figure8(1.0, laps=1, speed=0.5)
    slip = SlipModel(translation_noise=0.0, rotation_noise=0.0)
    here = simulate_run(WORLD, path, slip=slip, with_scans=False)
    start = Pose2D(2.0, -1.0, 0.7)
    there = simulate_run(WORLD, path, slip=slip, start=start, with_scans=False)
    moved = compose(
        compose(start.as_array(), inverse(path.start.as_array()))[None, :], here.true_poses
    )
    assert_poses_close(there.true_poses, moved, 1e-9)


def test_same_seed_same_run_different_seed_different_noise() -> None:
    path = CommandedPath.circle(4.0, laps=1)
    scanner = ScannerModel.sick_lms200()
    a = simulate_run(WORLD, path, scanner, SlipModel(), seed=7, duration=4.0)
    b = simulate_run(WORLD, path, scanner, SlipModel(), seed=7, duration=4.0)
    c = simulate_run(WORLD, path, scanner, SlipModel(), seed=8, duration=4.0)
    for x, y in [
        (a.stamps, b.stamps),
        (a.true_poses, b.true_poses),
        (a.odometry_poses, b.odometry_poses),
    ]:
        np.testing.assert_array_equal(x, y)
    assert all(np.array_equal(s.ranges, t.ranges) for s, t in zip(a.scans, b.scans))
    np.testing.assert_array_equal(a.true_poses, c.true_poses)  # the truth has no noise
    assert not np.array_equal(a.odometry_poses[1:], c.odometry_poses[1:])
    assert not any(np.array_equal(s.ranges, t.ranges) for s, t in zip(a.scans, c.scans))
    # scans or not, the same truth and odometry
    d = simulate_run(WORLD, path, scanner, SlipModel(), seed=7, duration=4.0, with_scans=False)
    np.testing.assert_array_equal(d.odometry_poses, a.odometry_poses)
    assert d.scans == []


def test_increments_and_distance() -> None:
    path = CommandedPath.circle(4.0, laps=1)
    run = simulate_run(WORLD, path, slip=SlipModel(), duration=20.0, with_scans=False, seed=2)
    np.testing.assert_allclose(
        compose(run.odometry_poses[:-1], run.odometry_increments),
        run.odometry_poses[1:],
        atol=1e-12,
    )
    np.testing.assert_allclose(
        compose(run.true_poses[:-1], run.true_increments), run.true_poses[1:], atol=1e-12
    )
    # the odometry believes the commanded 3 cm per scan; the robot covers 2% less
    assert np.median(run.odometry_increments[:, 0]) == pytest.approx(0.03, rel=0.01)
    assert run.distance_travelled[-1] == pytest.approx(0.98 * 0.3 * 20.0, rel=1e-3)


@pytest.mark.parametrize(
    "kw",
    [
        {"seed": -1},
        {"seed": 1.5},
        {"duration": 0.0},
        {"duration": -2.0},
        {"max_step": 0.0},
        {"scanner": "sick"},
        {"slip": 0.1},
        {"start": (0.0, 0.0)},
    ],
)
def test_run_validation(kw: dict) -> None:
    with pytest.raises(SimError):
        simulate_run(WORLD, CommandedPath.circle(1.0), **kw)
    with pytest.raises(SimError):
        simulate_run("gym", CommandedPath.circle(1.0))  # type: ignore[arg-type]
    with pytest.raises(SimError):
        simulate_run(WORLD, [[1.0, 0.1, 0.0]])  # type: ignore[arg-type]
