"""Beyond the paper: the point-to-line refinement, and how far the positioner trusts odometry
(jumps no robot makes, standing still). Checked on simulated rooms and corridors whose motion is
known."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzypos import sim
from fuzzypos.config import Config
from fuzzypos.features import extract_features
from fuzzypos.geometry import Pose2D, compose, relative, transform_points
from fuzzypos.matching import refine_point_to_line, surface_points
from fuzzypos.pipeline import Positioner, Reason
from fuzzypos.pipeline.prior import OdometryPrior
from oracles.matching import _converged, kd_tree

CFG = Config()
R = CFG.refinement


def scanner(noise: float = 0.0) -> sim.ScannerModel:
    return sim.ScannerModel(
        n_beams=360,
        field_of_view_deg=360.0,
        angle_min_deg=-180.0,
        range_max=20.0,
        range_noise_std=noise,
    )


def refine(ref_scan, scan, start, prior, max_distance=0.5, **kw):
    """The refinement of ``scan`` against ``ref_scan`` from ``start`` (held to ``prior``),
    with the default refinement settings but for ``kw`` (30 iterations, pairing down to
    0.3 m unless given)."""
    fr, fc = extract_features(ref_scan, CFG), extract_features(scan, CFG)
    surf = surface_points(fr.points, fr.ranges, fr.uncertainty, R)
    settings = replace(R, **{"min_distance": 0.3, "iterations": 30, **kw})
    return refine_point_to_line(
        surf,
        fc.points,
        np.ones(len(fc.points)),
        np.asarray(start),
        np.asarray(prior),
        np.asarray(start),
        settings,
        max_distance=max_distance,
        prior_scale=1.0,
    )


def test_surface_normals_are_the_walls_normals() -> None:
    room = sim.rectangular_room(8.0, 6.0)
    scan = sim.simulate_scan(room, Pose2D(0.5, -0.3, 0.2), scanner())
    f = extract_features(scan, CFG)
    s = surface_points(f.points, f.ranges, f.uncertainty, R)
    assert len(s) > 300
    # in the robot frame the walls' normals are at -0.2 + k·90°: |n · wall direction| ~ 0
    ang = np.arctan2(s.normal[:, 1], s.normal[:, 0]) + 0.2
    off = np.abs((ang + math.pi / 4) % (math.pi / 2) - math.pi / 4)
    # all but the points at the four corners, whose chord cuts across the corner
    assert np.mean(off < 1e-6) > 0.95
    assert np.allclose(np.hypot(s.normal[:, 0], s.normal[:, 1]), 1.0)


@settings(max_examples=25, deadline=None)
@given(
    dx=st.floats(-0.3, 0.3),
    dy=st.floats(-0.3, 0.3),
    dth=st.floats(-0.15, 0.15),
    ex=st.floats(-0.1, 0.1),
    ey=st.floats(-0.1, 0.1),
    eth=st.floats(-0.05, 0.05),
)
def test_recovers_a_known_motion_from_a_wrong_start(dx, dy, dth, ex, ey, eth) -> None:
    world = sim.furnished_room(seed=1)
    a = Pose2D(0.0, 0.0, 0.1)
    motion = np.array([dx, dy, dth])
    b = Pose2D.from_array(compose(a.as_array(), motion))
    sa, sb = (sim.simulate_scan(world, p, scanner()) for p in (a, b))
    start = motion + np.array([ex, ey, eth])
    res = refine(sa, sb, start, start, prior_sigma=10.0, prior_sigma_angle=10.0)
    assert res is not None and res.inlier_fraction > 0.9
    err = relative(motion, res.increment)
    assert math.hypot(err[0], err[1]) < 2e-3 and abs(err[2]) < math.radians(0.05), (motion, res)


def test_noise_and_the_prior_along_a_corridor() -> None:
    """Two parallel walls: across the corridor and in heading the points decide, along it the
    prior does (the start is 0.4 m off along the corridor and 5 cm across)."""
    walls = sim.World.from_segments([[-30.0, -1.0, 30.0, -1.0], [-30.0, 1.0, 30.0, 1.0]])
    rng = np.random.default_rng(3)
    a, b = Pose2D(0.0, 0.1, 0.0), Pose2D(0.5, -0.1, 0.05)
    sa = sim.simulate_scan(walls, a, scanner(0.01), rng)
    sb = sim.simulate_scan(walls, b, scanner(0.01), rng)
    motion = relative(a.as_array(), b.as_array())
    prior = motion + np.array([0.4, 0.05, 0.0])
    res = refine(sa, sb, prior, prior)
    assert res is not None
    across = abs(res.increment[1] - motion[1])
    along = res.increment[0] - motion[0]
    assert across < 0.01 and abs(res.increment[2] - motion[2]) < math.radians(0.3), res
    # unobservable along the corridor: the prior's 0.4 m stays (no drift toward anything else)
    assert abs(along - 0.4) < 0.05, res


def test_nothing_to_pair_gives_none() -> None:
    room = sim.rectangular_room(8.0, 6.0)
    sa = sim.simulate_scan(room, Pose2D(), scanner())
    far = np.array([30.0, 30.0, 0.0])  # every point lands far outside the room
    assert refine(sa, sa, far, far, max_distance=0.5, min_distance=0.1) is None


# -- the positioner's trust in odometry ---------------------------------------------------------
SEARCH_SCANS = tuple(
    extract_features(sim.simulate_scan(sim.furnished_room(seed=1), p, scanner()), CFG)
    for p in (Pose2D(0.0, 0.0, 0.0), Pose2D(0.05, 0.0, math.radians(-40.0)))
)


def room_run(poses, odom, noise=0.0, stamps=None, config=None):
    world = sim.furnished_room(seed=2)
    rng = np.random.default_rng(0)
    pos = Positioner(config or Config())
    out = []
    for k, (p, o) in enumerate(zip(poses, odom)):
        scan = sim.simulate_scan(
            world, p, scanner(noise), rng, stamp=0.2 * k if stamps is None else stamps[k]
        )
        out.append(pos.update(scan, o))
    return pos, out


def test_an_odometry_jump_is_rejected_and_the_motion_found() -> None:
    truth = sim.arc_path(Pose2D(-1.0, -0.5, 0.2), 12, 0.05, 1.0)
    odom = list(truth)
    jump = np.array([0.38, 0.0, math.radians(-60.6)])  # aces: 0.38 m and -60.6° in 0.16 s
    odom = odom[:6] + [Pose2D.from_array(compose(p.as_array(), jump)) for p in odom[6:]]
    pos, est = room_run(truth, odom, noise=0.005)
    assert pos.odometry_jumps == 1
    assert est[6].odometry_rejected and not any(e.odometry_rejected for e in est[:6] + est[7:])
    final = relative(truth[-1].as_array(), est[-1].pose.as_array())
    assert math.hypot(final[0], final[1]) < 0.02 and abs(final[2]) < math.radians(0.5), est[-1]
    # without the check and without the wider search the estimate follows the jump
    trusting = Config().with_overrides(
        {
            "odometry": {"max_jump_angle": math.pi, "max_jump_distance": 5.0},
            "search": {"angle": math.radians(1.0)},
        }
    )
    pos2, est2 = room_run(truth, odom, noise=0.005, config=trusting)
    assert pos2.odometry_jumps == 0
    bad = relative(truth[-1].as_array(), est2[-1].pose.as_array())
    assert math.hypot(bad[0], bad[1]) > 0.1 or abs(bad[2]) > math.radians(5)


def test_plausible_fast_motion_is_not_a_jump() -> None:
    prior = OdometryPrior(
        CFG.odometry, CFG.odometry_noise.stale_periods, CFG.odometry_noise.stale_quantile
    )
    # 0.3 m and 25° in 0.5 s: 0.6 m/s and 0.87 rad/s
    assert not prior.is_jump(np.array([0.3, 0.0, math.radians(25.0)]), 0.5)
    assert prior.is_jump(np.array([0.38, 0.0, math.radians(-60.6)]), 0.16)
    assert prior.is_jump(np.array([2.0, 0.0, 0.0]), 0.5)  # 4 m/s


def test_standing_still_does_not_drift() -> None:
    still = [Pose2D(0.3, -0.2, 0.4)] * 40
    _, est = room_run(still, still, noise=0.02)
    poses = np.array([e.pose.as_array() for e in est])
    assert np.ptp(poses, axis=0).max() == 0.0
    assert est[0].reason is Reason.FIRST_SCAN
    assert all(e.reason is Reason.STANDING_STILL for e in est[1:])
    # the same noisy scans without trusting the stand-still jitter
    cfg = Config().with_overrides({"odometry": {"trust_stand_still": False}})
    _, est2 = room_run(still, still, noise=0.02, config=cfg)
    poses2 = np.array([e.pose.as_array() for e in est2])
    assert np.ptp(poses2[:, :2], axis=0).max() < 0.03  # small (2 cm noise), but not zero
    assert np.ptp(poses2, axis=0).max() > 0.0


def test_refinement_beats_features_alone_with_noise() -> None:
    truth = sim.arc_path(Pose2D(-1.0, -0.5, 0.2), 30, 0.06, 1.5)
    odom = sim.drifting_odometry(truth, scale=1.03, rotation_bias_deg=0.3)
    errs = {}
    for name, on in (("refined", True), ("features", False)):
        cfg = Config().with_overrides({"refinement": {"enabled": on}})
        _, est = room_run(truth, odom, noise=0.01, config=cfg)
        d = relative(truth[-1].as_array(), est[-1].pose.as_array())
        errs[name] = math.hypot(d[0], d[1])
    assert errs["refined"] < 0.03, errs
    assert errs["refined"] <= errs["features"] + 0.005, errs


@pytest.mark.parametrize(
    "key, value",
    [
        ("iterations", 0),
        ("min_points", 2),
        ("min_inlier_fraction", 1.5),
        ("residual_scale", 0.0),
        ("neighbour_step", 0),
        ("min_distance", 9.0),
        ("length_weight_max", 0.5),
        ("length_weight_max", float("nan")),
        ("length_cap", 0.0),
    ],
)
def test_refinement_config_is_validated(key, value) -> None:
    from fuzzypos.config import ConfigError

    with pytest.raises(ConfigError, match=key):
        Config().with_overrides({"refinement": {key: value}})


@pytest.mark.parametrize(
    "key, value",
    [
        ("distance_penalty", -0.1),
        ("distance_penalty", float("inf")),
    ],
)
def test_search_config_is_validated(key, value) -> None:
    from fuzzypos.config import ConfigError

    with pytest.raises(ConfigError, match=key):
        Config().with_overrides({"search": {key: value}})


def test_search_start_finds_a_large_rotation() -> None:
    from fuzzypos.matching import search_start

    world = sim.furnished_room(seed=1)
    a, b = Pose2D(0.0, 0.0, 0.0), Pose2D(0.05, 0.0, math.radians(-40.0))
    fa, fb = (extract_features(sim.simulate_scan(world, p, scanner()), CFG) for p in (a, b))
    surf = surface_points(fa.points, fa.ranges, fa.uncertainty, R)
    search = replace(CFG.search, angle_step=math.radians(1.0), gate=0.3, distance_penalty=0.0)
    start, score = search_start(
        surf,
        fb.points,
        np.zeros(3),
        search,
        half_width=math.radians(60.0),
        translation_half_width=0.0,
    )
    assert abs(math.degrees(start[2]) + 40.0) <= 2.0 and score > 0.8, (start, score)
    # the prior's own rotation scores far worse
    _, at_prior = search_start(
        surf, fb.points, np.zeros(3), search, half_width=0.0, translation_half_width=0.0
    )
    assert at_prior < score - 0.3


@settings(max_examples=25, deadline=None)
@given(st.floats(0.0, 0.5), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-180.0, 180.0))
def test_search_start_scores_the_fraction_of_points_that_land(penalty, x, y, start_deg) -> None:
    """The start found lies on the searched grid; its score is the fraction of the (evenly
    picked) points within the gate of a reference point there, without the penalty (checked
    against a direct KD-tree query); with a penalty the found start is never further from the
    search's start than without one."""
    from fuzzypos.matching import search_start

    fa, fb = SEARCH_SCANS
    surf = surface_points(fa.points, fa.ranges, fa.uncertainty, R)
    start = np.array([x * 0.1, y * 0.1, math.radians(start_deg)])
    search = replace(
        CFG.search, angle_step=math.radians(3.0), gate=0.25, translation_step=0.2, max_points=60
    )

    def run(distance_penalty: float):
        return search_start(
            surf,
            fb.points,
            start,
            replace(search, distance_penalty=distance_penalty),
            half_width=math.pi,
            translation_half_width=0.2,
        )

    found, score = run(penalty)
    steps = (found - start) / np.array([0.2, 0.2, math.radians(3.0)])
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    assert np.all(np.abs(found[:2] - start[:2]) <= 0.2 + 1e-9)
    pts = fb.points[:: max(1, fb.points.shape[0] // 60)]
    dist, _ = kd_tree(surf).query(transform_points(found, pts), distance_upper_bound=0.25)
    assert score == pytest.approx(float(np.isfinite(dist).mean()), abs=1e-12)
    free, _ = run(0.0)
    assert np.hypot(*(found[:2] - start[:2])) <= np.hypot(*(free[:2] - start[:2])) + 1e-9


def test_a_local_map_of_keyframes_tracks_a_known_arc() -> None:
    truth = sim.arc_path(Pose2D(-1.0, -0.5, 0.2), 40, 0.06, 2.0)
    odom = sim.drifting_odometry(truth, scale=1.03, rotation_bias_deg=0.3)
    for k in (1, 3):
        cfg = Config().with_overrides(
            {"refinement": {"local_map_keyframes": k}, "matching": {"keyframe_distance": 0.5}}
        )
        pos, est = room_run(truth, odom, noise=0.01, config=cfg)
        assert 1 <= pos.local_map.keyframes <= k
        d = relative(truth[-1].as_array(), est[-1].pose.as_array())
        assert math.hypot(d[0], d[1]) < 0.03 and abs(d[2]) < math.radians(0.5), (k, d)


def test_a_turn_during_a_gap_is_found_by_the_wide_search() -> None:
    """The robot turns 70° during a 3 s gap while the odometry says 20° (aces, scan 2,945)."""
    truth = [Pose2D(0.0, 0.0, 0.0), Pose2D(0.02, 0.0, 0.0), Pose2D(0.05, 0.02, math.radians(70.0))]
    odom = [truth[0], truth[1], Pose2D(0.05, 0.02, math.radians(20.0))]
    stamps = [0.0, 0.2, 3.2]
    _, est = room_run(truth, odom, noise=0.005, stamps=stamps)
    d = relative(truth[-1].as_array(), est[-1].pose.as_array())
    assert (
        not est[-1].degraded and abs(math.degrees(d[2])) < 0.5 and math.hypot(d[0], d[1]) < 0.02
    ), d
    # without the gap the failure search stays within 30° of the odometry and cannot find it
    _, est2 = room_run(truth, odom, noise=0.005, stamps=[0.0, 0.2, 0.4])
    d2 = relative(truth[-1].as_array(), est2[-1].pose.as_array())
    assert abs(math.degrees(d2[2])) > 10.0


def ribbed_corridor(period: float = 0.2) -> sim.World:
    """A corridor 2 m wide with a small rib every ``period`` along both walls: seen from
    anywhere it looks the same one period further on."""
    polys = [np.array([[-40.0, 1.0], [40.0, 1.0]]), np.array([[-40.0, -1.0], [40.0, -1.0]])]
    for x in np.arange(-39.0, 39.0, period):
        polys.append(sim.box_polygon(x, 0.95, 0.05, 0.1))
        polys.append(sim.box_polygon(x, -0.95, 0.05, 0.1))
    return sim.World.from_polygons(polys, closed=[False, False] + [True] * (len(polys) - 2))


def test_a_failed_match_keeps_the_odometry_translation_along_a_ribbed_corridor(monkeypatch) -> None:
    """The odometry turns 25° too far in one step (no jump: a robot can turn that fast), so
    the match from it fails and the narrower search runs. Along a corridor whose ribs repeat
    every 0.2 m the search finds the rotation, and the odometry's translation keeps the scan
    from sliding one rib along (aces, scan 2,738: 0.3 m backwards along a corridor)."""
    import fuzzypos.pipeline.search as search_module

    calls: list[float] = []
    real = search_module.search_start

    def spy(*args, **kwargs):
        calls.append(kwargs["half_width"])  # the half-width of the rotations searched
        return real(*args, **kwargs)

    monkeypatch.setattr(search_module, "search_start", spy)
    world = ribbed_corridor()
    truth = sim.arc_path(Pose2D(-1.0, 0.0, 0.0), 10, 0.05, 0.0)
    error = np.array([0.0, 0.0, math.radians(25.0)])
    odom = truth[:6] + [Pose2D.from_array(compose(p.as_array(), error)) for p in truth[6:]]

    def run(config: Config) -> tuple[Positioner, list]:
        rng = np.random.default_rng(1)
        pos = Positioner(config)
        return pos, [
            pos.update(sim.simulate_scan(world, p, scanner(0.005), rng, stamp=0.2 * k), o)
            for k, (p, o) in enumerate(zip(truth, odom))
        ]

    pos, est = run(Config())
    assert pos.odometry_jumps == 0
    assert any(abs(w - CFG.search.failure_angle) < 1e-9 for w in calls), calls
    for t, e in zip(truth, est):
        d = relative(t.as_array(), e.pose.as_array())
        assert math.hypot(d[0], d[1]) < 0.03 and abs(d[2]) < math.radians(1.0), (t, e.pose)
    # without the search's pull toward the start the scan slides a rib along
    _, slid = run(Config().with_overrides({"search": {"distance_penalty": 0.0}}))
    d = relative(truth[6].as_array(), slid[6].pose.as_array())
    assert math.hypot(d[0], d[1]) > 0.1, slid[6].pose


def test_length_weighting_keeps_moving_clutter_next_to_the_robot_from_outvoting_the_walls() -> None:
    """A box 0.5 m × 1.2 m right in front of the robot (a person, a trolley) moves 15 cm and
    turns 8° between two scans: it takes a fifth of the beams. Weighing each point by the
    stretch of surface it stands for lets the room's walls decide; weighing every beam alike
    lets the box drag the estimate along (measured: 9 mm / 0.02° against 53 mm / 0.7°)."""
    room = sim.rectangular_room(10.0, 8.0)

    def with_box(cx: float, cy: float, theta: float) -> sim.World:
        box = sim.World.from_polygons([sim.box_polygon(cx, cy, 0.5, 1.2, theta)])
        return sim.World.from_segments(np.vstack([room.segments, box.segments]))

    a, b = Pose2D(0.0, 0.0, 0.0), Pose2D(0.10, 0.02, math.radians(2.0))
    world_a, world_b = with_box(0.7, 0.0, 0.0), with_box(0.75, 0.15, math.radians(8.0))
    odom_b = Pose2D(0.12, 0.0, 0.0)
    errors = {}
    for limit in (R.length_weight_max, 1.0):
        rng = np.random.default_rng(0)
        pos = Positioner(Config().with_overrides({"refinement": {"length_weight_max": limit}}))
        pos.update(sim.simulate_scan(world_a, a, scanner(0.005), rng, stamp=0.0), a)
        est = pos.update(sim.simulate_scan(world_b, b, scanner(0.005), rng, stamp=0.2), odom_b)
        assert est.refined and not est.degraded
        d = relative(b.as_array(), est.pose.as_array())
        errors[limit] = (math.hypot(d[0], d[1]), abs(math.degrees(d[2])))
    weighted, alike = errors[R.length_weight_max], errors[1.0]
    assert weighted[0] < 0.02 and weighted[1] < 0.1, errors
    assert alike[0] > 2 * weighted[0] and alike[1] > 2 * weighted[1], errors


def test_surface_lengths_of_a_wall_seen_square_on_and_at_grazing_incidence() -> None:
    """A straight wall 2 m ahead: a point's stretch is the distance to its nearer neighbour,
    which grows as 1/cos² of the incidence; capped at ``cap`` beam spacings at its range; at
    a jump edge the nearer neighbour decides."""
    from fuzzypos.matching import surface_lengths

    inc = math.radians(1.0)
    a = inc * np.arange(-60, 61)
    ranges = 2.0 / np.cos(a)
    pts = np.stack((2.0 * np.ones_like(a), 2.0 * np.tan(a)), axis=1)
    length = surface_lengths(pts, ranges, inc, cap=100.0)
    # exact: the nearer of the two chords to the neighbours
    chords = np.diff(pts[:, 1])
    np.testing.assert_allclose(length[1:-1], np.minimum(chords[:-1], chords[1:]), rtol=1e-12)
    assert length[60] == pytest.approx(2.0 * math.tan(inc), rel=1e-9)
    assert length[0] / length[60] == pytest.approx(
        1.0 / math.cos(math.radians(59.5)) ** 2, rel=0.05
    )
    capped = surface_lengths(pts, ranges, inc, cap=1.5)
    np.testing.assert_allclose(capped, np.minimum(length, 1.5 * ranges * inc))
    # a point alone stands for one beam spacing; two points for their distance
    assert surface_lengths(pts[:1], ranges[:1], inc, cap=3.0)[0] == pytest.approx(ranges[0] * inc)
    two = surface_lengths(pts[59:61], ranges[59:61], -inc, cap=3.0)
    np.testing.assert_allclose(two, [np.hypot(*(pts[60] - pts[59]))] * 2)


@settings(max_examples=50, deadline=None)
@given(
    st.integers(1, 40),
    st.floats(-math.pi, math.pi),
    st.floats(-5.0, 5.0),
    st.floats(-5.0, 5.0),
    st.integers(0, 2**31 - 1),
)
def test_surface_lengths_are_bounded_and_do_not_depend_on_the_frame(n, th, tx, ty, seed) -> None:
    from fuzzypos.matching import surface_lengths

    rng = np.random.default_rng(seed)
    ranges = rng.uniform(0.2, 20.0, n)
    a = np.sort(rng.uniform(-math.pi / 2, math.pi / 2, n))
    pts = np.stack((ranges * np.cos(a), ranges * np.sin(a)), axis=1)
    inc = math.radians(0.5)
    length = surface_lengths(pts, ranges, inc, cap=3.0)
    assert length.shape == (n,) and np.all(length >= 0.0)
    assert np.all(length <= 3.0 * ranges * inc + 1e-12)
    moved = pts @ np.array([[math.cos(th), math.sin(th)], [-math.sin(th), math.cos(th)]]) + [tx, ty]
    np.testing.assert_allclose(surface_lengths(moved, ranges, inc, cap=3.0), length, atol=1e-9)


def test_sparse_far_structure_pairs_within_the_points_own_beam_spacing() -> None:
    """Walls 10-50 m away sampled every degree (0.6 m apart at 36 m): with the pairing reach
    of two beam spacings at each point's range the refinement pairs the scan and recovers a
    known motion; with the fixed distances alone too few points pair to trust it."""
    world = sim.outdoor_yard()
    sc = sim.sick_interlaced_scanner(
        start_angle_offsets_deg=(0.0,),
        beam_counts=(181,),
        dropout_probability=0.0,
        range_noise_std=0.01,
    )
    a = Pose2D(0.0, 0.0, 0.3)
    motion = np.array([0.25, 0.02, math.radians(1.0)])
    b = Pose2D.from_array(compose(a.as_array(), motion))
    rng = np.random.default_rng(1)
    fa, fb = (extract_features(sim.simulate_scan(world, p, sc, rng), CFG) for p in (a, b))
    assert np.median(fa.ranges) > 10.0
    surf = surface_points(fa.points, fa.ranges, fa.uncertainty, R)
    start = motion + np.array([0.05, -0.04, math.radians(0.5)])
    spacing = fb.ranges * math.radians(1.0)

    def fit(settings):
        return refine_point_to_line(
            surf,
            fb.points,
            np.ones(len(fb.points)),
            start,
            start,
            start,
            settings,
            max_distance=settings.max_distance,
            prior_scale=1.0,
            spacing=spacing,
        )

    far = fit(R)
    assert far is not None and far.inlier_fraction > 0.8, far
    err = relative(motion, far.increment)
    assert math.hypot(err[0], err[1]) < 0.03 and abs(err[2]) < math.radians(0.1), err
    fixed = fit(replace(R, pairing_spacing=0.0))
    assert fixed is None or fixed.inlier_fraction < R.min_inlier_fraction, fixed


def _turn_in_place(config: Config) -> list:
    """A 30° scanner turning on the spot 8° per scan in a furnished room, its odometry
    over-reading the turns by 8 %: by the fourth scan (24° from the keyframe) a fifth of
    the scan overlaps the keyframe's, two thirds the previous scan's."""
    world = sim.furnished_room(1)
    model = sim.ScannerModel(
        n_beams=60, field_of_view_deg=30.0, angle_min_deg=-15.0, range_max=8.0,
        range_noise_std=0.005,
    )  # fmt: skip
    rng = np.random.default_rng(0)
    truth = [Pose2D(0.5, 0.2, math.radians(8.0 * k)) for k in range(5)]
    odom = [Pose2D(0.5, 0.2, math.radians(8.0 * 1.08 * k)) for k in range(5)]
    pos = Positioner(config)
    out = []
    for k, (p, o) in enumerate(zip(truth, odom)):
        out.append((p, pos.update(sim.simulate_scan(world, p, model, rng, stamp=0.2 * k), o)))
    return out


def test_where_the_keyframe_is_out_of_sight_the_previous_scan_is_refined_against() -> None:
    off = _turn_in_place(CFG)  # (off by default)
    on = _turn_in_place(CFG.with_overrides({"refinement": {"with_previous_scan": True}}))
    assert all(e.refined for _, e in on[1:])
    assert not off[3][1].refined and off[3][1].keyframe  # it fell back and became the keyframe
    truth, est = on[3]
    err_on = abs(relative(truth.as_array(), est.pose.as_array())[2])
    err_off = abs(relative(truth.as_array(), off[3][1].pose.as_array())[2])
    assert err_on < 0.8 * err_off and math.degrees(err_on) < 1.0, (err_on, err_off)
    # its pose relative to the keyframe carries the previous scan's error too
    assert est.keyframe_covariance[2, 2] > on[2][1].keyframe_covariance[2, 2]


@settings(max_examples=200, deadline=None)
@given(
    st.floats(-1e-2, 1e-2), st.floats(-1e-2, 1e-2), st.floats(-1e-3, 1e-3),
    st.floats(-1e-2, 1e-2), st.floats(-1e-2, 1e-2), st.floats(-1e-3, 1e-3),
)  # fmt: skip
def test_gauss_newton_has_converged_on_a_small_step_or_a_two_cycle(
    dx, dy, dth, lx, ly, lth
) -> None:
    """A step below the convergence thresholds has converged; so has one that undoes the step
    before it (a two-cycle: a point at the gate's edge paired and unpaired by turns would put
    the pose back and forth to the last iteration); two steps that do not cancel have not."""
    conv_t, conv_r = R.converged_translation, R.converged_rotation

    def small(x: float, y: float, t: float) -> bool:
        return abs(x) + abs(y) < conv_t and abs(t) < conv_r

    step, last = np.array([dx, dy, dth]), np.array([lx, ly, lth])
    assert _converged(step, None, R) == small(dx, dy, dth)
    assert _converged(step, -step, R)
    back = step + last
    assert _converged(step, last, R) == (small(dx, dy, dth) or small(*back))
    # the same step twice: back twice as far (only a small step has converged)
    assert _converged(step, step, R) == small(dx, dy, dth)
