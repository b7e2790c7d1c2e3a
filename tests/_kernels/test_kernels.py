"""The compiled kernels (``fuzzypos._kernels``) against their pure-numpy references, to 1e-9 on
inputs where nothing lies within 1e-6 of a threshold (a gate, Huber's scale, the trimming cut,
a corner's angle): the margins are measured on the reference's own intermediate values, and an
example too close to one is left out (``assume``). Neither the import of fuzzypos nor these
tests time anything."""

from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

import fuzzypos._kernels as kernels
from fuzzypos import sim
from fuzzypos.config import Config
from fuzzypos.features import extract as features_module
from fuzzypos.features import extract_features, rule_bases
from fuzzypos.features import segmentation as seg
from fuzzypos.features.extract import fit_lines
from fuzzypos.geometry import Pose2D
from fuzzypos.matching import lines as line_matching
from fuzzypos.matching import search as search_module
from fuzzypos.matching import surface as surface_module
from fuzzypos.matching import surface_points
from fuzzypos.matching.surface import SurfacePoints
from fuzzypos.pipeline import Positioner
from helpers import both, compiled_and_staged, numpy_kernels
from oracles import features as features_oracle
from oracles import io as io_oracle
from oracles import matching as matching_oracle
from oracles import pipeline as pipeline_oracle
from oracles.matching import kd_tree

CFG = Config()
R = CFG.refinement
MARGIN = 1e-6
TOL = 1e-9
BUDGET = settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.filter_too_much]
)


def scanner(beams: int = 360, noise: float = 0.01) -> sim.ScannerModel:
    return sim.ScannerModel(
        n_beams=beams,
        field_of_view_deg=360.0 if beams == 360 else 180.0,
        angle_min_deg=-180.0 if beams == 360 else -90.0,
        range_max=8.0,
        range_noise_std=noise,
    )


WORLD = sim.office()
poses = st.tuples(st.floats(-9.0, 9.0), st.floats(-1.0, 1.0), st.floats(-math.pi, math.pi))


def scan_at(pose: tuple[float, float, float], seed: int, beams: int = 360) -> Any:
    return sim.simulate_scan(WORLD, Pose2D(*pose), scanner(beams), rng=np.random.default_rng(seed))


# -- the grid ----------------------------------------------------------------------------------
@BUDGET
@given(
    n=st.integers(1, 400),
    spread=st.floats(0.5, 200.0),
    cell=st.floats(0.05, 1.0),
    radius=st.floats(0.01, 3.0),
    seed=st.integers(0, 2**31),
)
def test_the_grid_finds_the_kd_trees_nearest_point(n, spread, cell, radius, seed) -> None:
    """Nearest within a radius, and whether any lies within it, as a KD-tree says (from a
    guess too, with a lower bound on the other points' distance); far-flung points (a grid
    over the budget) get larger cells, queries off the grid find nothing."""
    from fuzzypos._kernels.grid import any_within, build_grid, nearest, nearest_bounded

    rng = np.random.default_rng(seed)
    xy = rng.uniform(-spread, spread, (n, 2)) * np.array([1.0, rng.uniform(0.0, 1.0)])
    near = xy[: min(n, 50)] + rng.normal(0, radius, (min(n, 50), 2))
    queries = np.concatenate([near, rng.uniform(-1.5 * spread, 1.5 * spread, (50, 2))])
    tree = cKDTree(xy)
    d, j = tree.query(queries, k=min(2, n))
    d, j = d.reshape(len(queries), -1), j.reshape(len(queries), -1)
    assume(np.all(np.abs(d[:, 0] - radius) > MARGIN))
    if n > 1:
        assume(np.all(d[:, 1] - d[:, 0] > MARGIN))
    grid = build_grid(xy, cell)
    assert grid.start[-1] == n and sorted(grid.order) == list(range(n))
    assert grid.start.size - 1 == grid.shape[0] * grid.shape[1] <= 64 * n + 4096
    geometry, shape, start, order, gxy = grid
    for q, dq, jq in zip(queries, d[:, 0], j[:, 0]):
        k, d2 = nearest(q[0], q[1], radius, geometry, shape, start, gxy)
        if dq < radius:
            assert order[k] == jq and math.sqrt(d2) == pytest.approx(dq, abs=TOL)
        else:
            assert k == -1
        assert any_within(q[0], q[1], radius, geometry, shape, start, gxy) == (dq < radius)
        # from no guess and from a guess (the distance to some point): the same point within
        # the radius (else one at least that far), the next nearest it saw, and a lower
        # bound on how far every point but those two lies (at least the radius where none
        # is within it)
        some = gxy[int(rng.integers(0, n))]
        dx, dy = gxy[:, 0] - q[0], gxy[:, 1] - q[1]
        dist2 = dx * dx + dy * dy
        for guess in (math.inf, math.hypot(some[0] - q[0], some[1] - q[1])):
            k2, d2b, other, far = nearest_bounded(
                q[0], q[1], radius, guess, geometry, shape, start, gxy
            )
            if dq < radius:
                assert k2 == k and d2b == d2
            else:
                assert not d2b < radius**2 and radius <= far
            if k2 >= 0:
                assert d2b == dist2[k2] and (other < 0 or dist2[other] >= d2b)
            else:
                assert other == -1 and d2b == math.inf
            rest = np.delete(np.sqrt(dist2), [i for i in (k2, other) if i >= 0])
            assert np.all(rest >= far - TOL)


@BUDGET
@given(
    values=st.lists(
        st.tuples(
            st.floats(allow_nan=True, allow_infinity=True),
            st.floats(allow_nan=True, allow_infinity=True),
        ),
        min_size=1,
        max_size=40,
    )
)
def test_the_grids_extent_is_numpys(values) -> None:
    """The least and greatest x and y, as numpy's ``min``/``max`` along the points (a NaN
    among them too)."""
    from fuzzypos._kernels.grid import _extent

    xy = np.array(values, dtype=np.float64).reshape(-1, 2)
    lo, hi = _extent(xy)
    np.testing.assert_array_equal(np.array(lo), xy.min(axis=0))
    np.testing.assert_array_equal(np.array(hi), xy.max(axis=0))


@BUDGET
@given(pose=poses, seed=st.integers(0, 1000))
def test_the_surface_table_is_the_surface_in_the_grids_order(pose, seed) -> None:
    """The refinement's table: each grid entry's point, normal and weight (those of the
    surface point ``order`` gives), bit for bit."""
    f = extract_features(scan_at(pose, seed), CFG)
    surface = surface_points(f.points, f.ranges, f.uncertainty, R)
    order = surface.grid.order
    want = np.column_stack((surface.xy[order], surface.normal[order], surface.weight[order]))
    assert surface.table.tobytes() == np.ascontiguousarray(want).tobytes()
    assert surface.table.shape == (len(surface), 5)


def test_a_dense_scans_grid_keeps_few_points_a_cell() -> None:
    """A surface sampled a millimetre apart (a scanner of 10,000 beams at a few metres) gets
    cells of a few points, not the hundreds a 15 cm cell would hold (each query near a wall
    would look at all of them: a scan's cost growing with the square of its beams), and its
    nearest points are still the KD-tree's; a sparse one keeps the cell it was given."""
    from fuzzypos._kernels.grid import POINTS_PER_CELL, build_grid, nearest

    t = np.arange(0.0, 4.0, 0.001)
    xy = np.concatenate([np.column_stack((t, 0.5 * t)), np.column_stack((t, 3.0 - 0.2 * t))])
    grid = build_grid(xy, 0.15)
    occupied = np.count_nonzero(np.diff(grid.start))
    assert len(xy) / occupied <= 2 * POINTS_PER_CELL
    assert grid.geometry[3] < 0.15
    rng = np.random.default_rng(0)
    queries = xy[rng.integers(0, len(xy), 200)] + rng.normal(0.0, 0.05, (200, 2))
    d, j = cKDTree(xy).query(queries)
    for q, dq, jq in zip(queries, d, j):
        k, d2 = nearest(q[0], q[1], 0.5, grid.geometry, grid.shape, grid.start, grid.xy)
        assert math.sqrt(d2) == pytest.approx(dq, abs=TOL)
        assert np.allclose(xy[grid.order[k]], xy[jq])  # (the same point, or one as near)
    sparse = xy[::100]  # 10 cm apart
    assert build_grid(sparse, 0.15).geometry[3] == 0.15


def test_an_empty_grid_finds_nothing() -> None:
    from fuzzypos._kernels.grid import any_within, build_grid, nearest, nearest_bounded

    geometry, shape, start, _order, gxy = build_grid(np.zeros((0, 2)), 0.2)
    assert nearest(0.0, 0.0, 1.0, geometry, shape, start, gxy)[0] == -1
    assert not any_within(0.0, 0.0, 1.0, geometry, shape, start, gxy)
    k, d2, other, far = nearest_bounded(0.0, 0.0, 1.0, math.inf, geometry, shape, start, gxy)
    assert (k, d2, other) == (-1, math.inf, -1) and far >= 1.0
    assert nearest(np.nan, 0.0, 1.0, *build_grid(np.ones((3, 2)), 0.2)[:3], gxy)[0] == -1


@BUDGET
@given(
    values=st.one_of(
        st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=1, max_size=300),
        st.lists(st.sampled_from([-1.0, 0.0, 0.5, 2.0]), min_size=1, max_size=300),
    ),
    k=st.integers(0, 299),
)
def test_the_order_statistics_are_numpys(values, k) -> None:
    """The k-th smallest value and the median without a sort, as numpy's sort gives them
    (many equal values too)."""
    from fuzzypos._kernels._select import kth_smallest, median

    v = np.array(values)
    k = min(k, v.size - 1)
    assert kth_smallest(v, k) == np.sort(v)[k]
    assert median(v) == np.median(v)
    np.testing.assert_array_equal(v, np.array(values))  # the input is left as it was


# -- the refinement ----------------------------------------------------------------------------
def _surface_margin(xy: np.ndarray, ranges: np.ndarray, r) -> float:
    """The smallest distance of a scan's steps to the link limit, and of its chords' bends to
    the largest (as tan · dot against |cross|), over every pair of chords the surface's
    normals are chosen from."""
    n, k = xy.shape[0], r.neighbour_step
    step = np.hypot(*np.diff(xy, axis=0).T)
    limit = np.maximum(
        r.neighbour_distance, r.neighbour_ratio * np.minimum(ranges[1:], ranges[:-1])
    )
    margins = [np.abs(step - limit)]
    run = np.concatenate(([0], np.cumsum(~(step <= limit))))
    first = np.searchsorted(run, run, side="left")
    last = np.searchsorted(run, run, side="right") - 1
    idx = np.arange(n)
    p, q = np.maximum(idx - k, first), np.minimum(idx + k, last)
    p2, q2 = np.maximum(p - k, first), np.minimum(q + k, last)
    tan_bend = math.tan(r.max_bend_angle)
    for a, b in (
        (xy - xy[p], xy[q] - xy),
        (xy[p] - xy[p2], xy - xy[p]),
        (xy[q] - xy, xy[q2] - xy[q]),
    ):
        cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        dot = a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]
        margins += [np.abs(np.abs(cross) - tan_bend * dot), np.abs(dot)]
    used = [m[np.isfinite(m) & (m > 0)] for m in margins]  # 0: a chord of a point to itself
    return float(min((m.min() for m in used if m.size), default=math.inf))


@BUDGET
@given(
    pose=poses,
    seed=st.integers(0, 1000),
    step=st.integers(1, 3),
    bend=st.floats(5.0, 60.0),
    beams=st.sampled_from([180, 360]),
)
def test_the_compiled_surfaces_are_the_numpy_ones(pose, seed, step, bend, beams) -> None:
    """A keyframe's surface points, their normals and weights, either way."""
    f = extract_features(scan_at(pose, seed, beams), CFG)
    r = replace(R, neighbour_step=step, max_bend_angle=math.radians(bend))
    assume(_surface_margin(f.points, f.ranges, r) > MARGIN)
    a, b = both(lambda: surface_points(f.points, f.ranges, f.uncertainty, r))
    assert len(a) == len(b)
    for name in ("xy", "normal", "weight"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=0, atol=TOL)


@BUDGET
@given(pose=poses, seed=st.integers(0, 1000), weight=st.sampled_from([1.0, 2.0, 5.0]))
def test_the_scan_points_weights_are_the_numpy_ones(pose, seed, weight) -> None:
    """Each point's certainty times the stretch of surface it stands for (capped, over the
    median), as the refinement weighs it."""
    from fuzzypos.pipeline.refine import Refiner

    scan = scan_at(pose, seed)
    f = extract_features(scan, CFG)
    refiner = Refiner(replace(R, length_weight_max=weight), CFG.search)
    points = refiner.points(f, scan.angle_increment)
    assert points is not None
    reference = pipeline_oracle.weights(refiner, f, scan.angle_increment)
    np.testing.assert_allclose(points.weights, reference, rtol=TOL, atol=0)
    with numpy_kernels():
        again = refiner.points(f, scan.angle_increment)
    assert again is not None
    np.testing.assert_array_equal(again.weights, reference)
    np.testing.assert_array_equal(points.spacing, again.spacing)


def test_the_points_weighed_on_first_use_are_the_weighed_ones_and_can_be_replaced() -> None:
    """``Refiner.points`` leaves the weights to first use (the fused refinement weighs them
    in its own call): read, they are ``scan_weights``' own; ``dataclasses.replace`` gives
    already weighed points; the fused refinement of either is the same to the bit."""
    from fuzzypos._kernels.refine import scan_weights
    from fuzzypos.pipeline.refine import Refiner, Starts

    a, b = scan_at((0.3, -0.2, 0.4), 5), scan_at((0.45, -0.2, 0.43), 6)
    fa, fb = extract_features(a, CFG), extract_features(b, CFG)
    refiner = Refiner(R, CFG.search)
    lazy = refiner.points(fb, b.angle_increment)
    weighed = refiner.points(fb, b.angle_increment)
    assert lazy is not None and weighed is not None
    copied = replace(weighed, xy=weighed.xy.copy())  # (reads the weights: weighed now)
    weights, spacing = scan_weights(
        np.ascontiguousarray(fb.points), np.ascontiguousarray(fb.ranges),
        np.ascontiguousarray(fb.uncertainty), b.angle_increment, R.weight_floor,
        R.length_weight_max, R.length_cap,
    )  # fmt: skip
    for points in (weighed, copied):
        np.testing.assert_array_equal(points.weights, weights)
        np.testing.assert_array_equal(points.spacing, spacing)
    surface = surface_points(fa.points, fa.ranges, fa.uncertainty, R)
    motion = np.array([0.15, 0.0, 0.03])
    starts = Starts(motion, motion, motion + np.array([0.1, 0.0, 0.02]))
    fits = [refiner.refine(surface, p, starts, False) for p in (lazy, weighed, copied)]
    assert all(f is not None for f in fits)
    for other in fits[1:]:
        np.testing.assert_array_equal(other.increment, fits[0].increment)
        np.testing.assert_array_equal(other.gradient_covariance, fits[0].gradient_covariance)


class Margins:
    """The smallest distance of the reference's own values to the thresholds they are tested
    against, recorded by wrapping the reference's helpers."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.value = math.inf
        pair, trimmed = matching_oracle._pair, matching_oracle._trimmed
        hold, linearise = matching_oracle._hold_degenerate, matching_oracle._linearise

        def _pair(reference, qx, qy, gate, reach):
            d, _ = kd_tree(reference).query(np.stack((qx, qy), axis=1), k=2)
            bound = np.full(qx.shape, gate) if reach is None else np.maximum(reach, gate)
            self.note(d[:, 0] - bound)
            return pair(reference, qx, qy, gate, reach)

        def _linearise(reference, points, pose, gate, reach):
            out = linearise(reference, points, pose, gate, reach)
            if out is not None:
                absr = np.abs(out[3])
                self.note(absr - R.residual_scale, absr - 0.5 * R.residual_scale)
            return out

        def _trimmed(w, absr, trim_floor):
            m = absr.size // 2
            cut = max(3.0 * 1.4826 * float(np.partition(absr, m)[m]), trim_floor)
            self.note(absr - cut)
            return trimmed(w, absr, trim_floor)

        def _hold(H, g, block, pose, start_xy, hold_xy, ratio, tolerance):
            a, b, c = block
            half = math.hypot(0.5 * (a - c), b)
            lo, hi = 0.5 * (a + c) - half, 0.5 * (a + c) + half
            self.note(np.array([(lo - ratio * hi) / max(hi, 1e-300)]))
            term, on_start = hold(H, g, block, pose, start_xy, hold_xy, ratio, tolerance)
            if term.any():
                v = np.linalg.eigh(term[:2, :2])[1][:, 1]
                self.note(np.array([abs(float(v @ (start_xy - hold_xy))) - tolerance]))
            return term, on_start

        monkeypatch.setattr(matching_oracle, "_pair", _pair)
        monkeypatch.setattr(matching_oracle, "_linearise", _linearise)
        monkeypatch.setattr(matching_oracle, "_trimmed", _trimmed)
        monkeypatch.setattr(matching_oracle, "_hold_degenerate", _hold)

    def note(self, *values: np.ndarray) -> None:
        for v in values:
            if v.size:
                self.value = min(self.value, float(np.min(np.abs(v))))


def assert_refinements_agree(a, b) -> None:
    assert (a is None) == (b is None)
    if a is None:
        return
    np.testing.assert_allclose(a.increment, b.increment, rtol=0, atol=TOL)
    assert a.n_paired == b.n_paired and a.hold_on_start == b.hold_on_start
    assert a.inlier_fraction == b.inlier_fraction and a.close_fraction == b.close_fraction
    for name in ("information", "prior_information", "hold_information", "gradient_covariance"):
        x, y = getattr(a, name), getattr(b, name)
        np.testing.assert_allclose(x, y, rtol=TOL, atol=TOL * (1.0 + np.abs(y).max()))
    np.testing.assert_array_equal(a.start, b.start)
    np.testing.assert_array_equal(a.prior, b.prior)


@BUDGET
@given(
    pose=poses,
    motion=st.tuples(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3), st.floats(-0.2, 0.2)),
    error=st.tuples(st.floats(-0.1, 0.1), st.floats(-0.1, 0.1), st.floats(-0.05, 0.05)),
    seed=st.integers(0, 1000),
    spacing=st.booleans(),
    learned=st.booleans(),
    weak=st.booleans(),
    corridor=st.booleans(),
)
def test_the_compiled_refinement_is_the_numpy_one(
    pose, motion, error, seed, spacing, learned, weak, corridor
) -> None:
    """Simulated scans of the office (its corridor where ``corridor``: the hold along it),
    every option of the refinement: the pairing by beam spacing, a learned prior's full
    information, the weak prior of a search."""
    if corridor:
        pose = (pose[0], 0.0, 0.1 * pose[2])
    a = scan_at(pose, seed)
    moved = Pose2D(*pose).compose(Pose2D(*motion))
    b = scan_at((moved.x, moved.y, moved.theta), seed + 1)
    fa, fb = extract_features(a, CFG), extract_features(b, CFG)
    surface = surface_points(fa.points, fa.ranges, fa.uncertainty, R)
    start = np.array(motion) + np.array(error)
    hold = np.array(motion) + 0.5 * np.array(error)
    information = np.array([[400.0, 30.0, 5.0], [30.0, 900.0, -8.0], [5.0, -8.0, 2000.0]])
    weights = np.clip(1.0 - fb.uncertainty, 0.05, 1.0)

    def run():
        return surface_module.refine_point_to_line(
            surface, fb.points, weights, start, np.array(motion), hold, R,
            max_distance=1.0 if weak else R.max_distance,
            prior_scale=100.0 if weak else 1.0,
            prior_information=information if learned else None,
            spacing=fb.ranges * abs(b.angle_increment) if spacing else None,
        )  # fmt: skip

    with pytest.MonkeyPatch.context() as patch:
        margins = Margins(patch)
        compiled, reference = both(run)
    assume(margins.value > MARGIN)
    assert_refinements_agree(compiled, reference)


@BUDGET
@given(
    pose=poses,
    motion=st.tuples(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3), st.floats(-0.2, 0.2)),
    error=st.tuples(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5), st.floats(-0.3, 0.3)),
    odometry_error=st.tuples(
        st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.floats(-0.03, 0.03)
    ),
    seed=st.integers(0, 1000),
    learned=st.booleans(),
    wide=st.booleans(),
)
def test_the_fused_refinement_stage_is_the_staged_one(
    pose, motion, error, odometry_error, seed, learned, wide
) -> None:
    """``Refiner.refine`` in one compiled call (both fits, their checks and the choice)
    against the staged fits: the very same result as fit by fit with the compiled kernel, and
    the numpy references' to 1e-9; the fit from the odometry's motion where it differs from
    the features' (the start), none after an odometry jump (``wide``)."""
    from fuzzypos.pipeline.refine import Refiner, Starts

    a = scan_at(pose, seed)
    moved = Pose2D(*pose).compose(Pose2D(*motion))
    b = scan_at((moved.x, moved.y, moved.theta), seed + 1)
    fa, fb = extract_features(a, CFG), extract_features(b, CFG)
    surface = surface_points(fa.points, fa.ranges, fa.uncertainty, R)
    refiner = Refiner(R, CFG.search)
    points = refiner.points(fb, b.angle_increment)
    assume(points is not None)
    start = np.array(motion) + np.array(error)
    hold = np.array(motion) + np.array(odometry_error)
    information = np.array([[400.0, 30.0, 5.0], [30.0, 900.0, -8.0], [5.0, -8.0, 2000.0]])
    info = information if learned else None
    starts = Starts(start, hold, hold, info, info)
    max_distance = CFG.search.jump_distance if wide else R.max_distance

    def fused():
        return refiner.refine(surface, points, starts, wide)

    def staged():
        return pipeline_oracle.refine_staged(refiner, surface, points, starts, max_distance, wide)

    one, each = fused(), staged()
    assert (one is None) == (each is None)
    if one is not None:
        for name in ("increment", "information", "prior_information", "hold_information",
                     "gradient_covariance", "start", "prior"):  # fmt: skip
            np.testing.assert_array_equal(getattr(one, name), getattr(each, name))
        assert (one.n_paired, one.hold_on_start) == (each.n_paired, each.hold_on_start)
        assert (one.inlier_fraction, one.close_fraction) == (
            each.inlier_fraction,
            each.close_fraction,
        )
    with pytest.MonkeyPatch.context() as patch:
        margins = Margins(patch)
        compiled, reference = both(fused)
    assume(margins.value > MARGIN)
    if reference is not None and one is not None:  # (the checks' own thresholds: far off)
        gain = abs(reference.close_fraction - one.close_fraction)
        assume(gain == 0.0 or gain > MARGIN)
    assert_refinements_agree(compiled, reference)


@pytest.mark.parametrize(
    ("pose", "seed", "error"),
    [
        ((4.5066, -0.4392, -0.0889), 134, (0.3846, 0.3693, 0.0899)),
        ((8.1747, 0.5931, 1.0295), 650, (0.3510, -0.3819, -0.1528)),
        ((-8.0608, -0.5772, -2.1731), 947, (0.3870, -0.3978, -0.0537)),
    ],
)
def test_the_fused_refinement_keeps_the_odometrys_fit_where_the_start_was_far_off(
    pose, seed, error
) -> None:
    """A start 0.4 m off and the odometry's motion right: the fit from the odometry's motion
    is the one kept, in one compiled call as fit by fit."""
    from fuzzypos.pipeline.refine import Refiner, Starts

    motion = np.array([0.2, 0.0, 0.05])
    a = scan_at(pose, seed)
    moved = Pose2D(*pose).compose(Pose2D(*motion))
    b = scan_at((moved.x, moved.y, moved.theta), seed + 1)
    fa, fb = extract_features(a, CFG), extract_features(b, CFG)
    surface = surface_points(fa.points, fa.ranges, fa.uncertainty, R)
    refiner = Refiner(R, CFG.search)
    points = refiner.points(fb, b.angle_increment)
    assert points is not None
    starts = Starts(motion + np.array(error), motion, motion)
    one = refiner.refine(surface, points, starts, False)
    each = pipeline_oracle.refine_staged(refiner, surface, points, starts, R.max_distance, False)
    assert one is not None and each is not None
    np.testing.assert_array_equal(one.start, motion)  # the odometry's fit
    np.testing.assert_array_equal(one.increment, each.increment)
    np.testing.assert_array_equal(one.gradient_covariance, each.gradient_covariance)
    assert np.abs(one.increment - motion).max() < 0.02


def test_a_refinement_with_too_few_pairs_or_a_singular_system_is_none() -> None:
    """Both return None where fewer than 3 points pair (far from every surface) and where the
    normal equations are singular (points all at the origin, no prior)."""
    fa = extract_features(scan_at((0.0, 0.0, 0.0), 1), CFG)
    surface = surface_points(fa.points, fa.ranges, fa.uncertainty, R)
    far = fa.points + 100.0

    def refine(points: np.ndarray) -> Any:
        zero = np.zeros(3)
        return surface_module.refine_point_to_line(
            surface, points, np.ones(len(points)), zero, zero, zero, R,
            max_distance=0.3, prior_scale=1.0,
        )  # fmt: skip

    for points in (far, far[:0]):
        assert both(lambda p=points: refine(p)) == (None, None)
    # every point on one spot of one flat surface, no prior: θ is not fixed
    pts = np.zeros((5, 2))
    flat = surface_module.SurfacePoints(np.zeros((5, 2)), np.tile([1.0, 0.0], (5, 1)), np.ones(5))
    args = (flat, pts, np.ones(5), np.zeros(3), np.zeros(3), np.zeros(3), R, 0.3, 1.0)
    for fn in (surface_module._refine_compiled, matching_oracle.refine):
        assert fn(*args, np.zeros((3, 3)), None) is None


# -- the search --------------------------------------------------------------------------------
@BUDGET
@given(
    pose=poses,
    motion=st.tuples(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5), st.floats(-0.6, 0.6)),
    penalty=st.floats(0.0, 0.5),
    seed=st.integers(0, 1000),
)
def test_the_compiled_search_is_the_numpy_one(pose, motion, penalty, seed) -> None:
    """The same best start and fraction, where no scored point lands within 1e-6 of the
    gate (checked with a KD-tree over every candidate)."""
    fa = extract_features(scan_at(pose, seed, 180), CFG)
    moved = Pose2D(*pose).compose(Pose2D(*motion))
    fb = extract_features(scan_at((moved.x, moved.y, moved.theta), seed + 1, 180), CFG)
    surface = surface_points(fa.points, fa.ranges, fa.uncertainty, R)
    search = replace(CFG.search, angle_step=math.radians(4.0), distance_penalty=penalty)
    start = np.zeros(3)
    pts, thetas, tx, ty, _ = search_module._candidates(fb.points, start, search, 0.8, 0.4)
    c, s = np.cos(thetas)[:, None], np.sin(thetas)[:, None]
    qx = (c * pts[:, 0] - s * pts[:, 1])[:, None, :] + tx[None, :, None]
    qy = (s * pts[:, 0] + c * pts[:, 1])[:, None, :] + ty[None, :, None]
    d, _ = kd_tree(surface).query(np.stack((qx.ravel(), qy.ravel()), axis=1))
    assume(np.all(np.abs(d - search.gate) > MARGIN))
    compiled, reference = both(
        lambda: search_module.search_start(
            surface, fb.points, start, search, half_width=0.8, translation_half_width=0.4
        )
    )
    np.testing.assert_allclose(compiled.start, reference.start, rtol=0, atol=TOL)
    assert compiled.score == reference.score


@BUDGET
@given(
    seed=st.integers(0, 10_000),
    penalty=st.sampled_from([0.0, 0.05]),
    sides=st.sampled_from([(4, 2), (2, 1), (6, 3), (1, 1)]),
)
def test_the_search_finds_the_same_best_in_any_order(seed, penalty, sides) -> None:
    """The kernel scores the candidates in the order it is given (the likeliest first),
    blocks of translations before their members, and leaves those that cannot win: the best
    is the brute force's, equal scores included (a symmetric room, a penalty symmetric about
    the start: ties abound), whatever the order and the blocks' sizes."""
    from fuzzypos._kernels.search import best_candidate

    rng = np.random.default_rng(seed)
    side = np.linspace(-2.0, 2.0, 41)
    rows = [np.column_stack((side, np.full(41, y))) for y in (-2.0, 2.0)]
    cols = [np.column_stack((np.full(41, x), side)) for x in (-2.0, 2.0)]
    wall = np.concatenate(rows + cols)
    surface = SurfacePoints(wall, np.zeros_like(wall), np.ones(len(wall)))
    pts = wall[rng.choice(len(wall), 40, replace=False)] + rng.normal(0.0, 0.02, (40, 2))
    thetas = np.radians(np.arange(-6.0, 6.5, 3.0))
    k = np.arange(-3, 4)
    lattice = np.column_stack([a.ravel() for a in np.meshgrid(k, k, indexing="ij")])
    tx, ty = 0.1 * lattice[:, 0], 0.1 * lattice[:, 1]
    pen = penalty * np.hypot(tx, ty)
    args = (surface.grid, pts, thetas, tx, ty, pen, 0.05)

    def best(rotations, priority):
        blocks = search_module.translation_blocks(lattice, tx, ty, pen, priority, sides)
        return best_candidate(*args, rotations, blocks)

    natural = best(np.arange(len(thetas)), np.arange(len(tx), dtype=float))
    shuffled = best(rng.permutation(len(thetas)), rng.permutation(len(tx)).astype(float))
    likeliest = best(np.argsort(np.abs(thetas), kind="stable"), pen)
    assert natural == shuffled == likeliest
    # the best by brute force: the highest score, the first of equal ones
    hits = np.array([[np.mean(kd_tree(surface).query(
        np.column_stack((np.cos(a) * pts[:, 0] - np.sin(a) * pts[:, 1] + x,
                         np.sin(a) * pts[:, 0] + np.cos(a) * pts[:, 1] + y)))[0] < 0.05)
        for x, y in zip(tx, ty)] for a in thetas])  # fmt: skip
    score = hits - pen[None, :]
    r, t = divmod(int(np.argmax(score)), len(tx))
    assert natural[:2] == (r, t)
    assert natural[2] == hits[r, t]


@given(
    m=st.integers(0, 8),
    sides=st.sampled_from([(4, 2), (2, 1), (6, 3), (8, 4)]),
    seed=st.integers(0, 1000),
)
def test_the_translation_blocks_cover_the_lattice_once_and_bound_their_members(
    m, sides, seed
) -> None:
    """Every translation in exactly one inner block inside one outer block; each block's
    radius reaches its every member from its centre; its penalty and first index are its
    members' least; members and blocks come in the order of their least priority."""
    rng = np.random.default_rng(seed)
    k = np.arange(-m, m + 1)
    lattice = np.column_stack([a.ravel() for a in np.meshgrid(k, k, indexing="ij")])
    tx, ty = 0.2 * lattice[:, 0] + 1.3, 0.2 * lattice[:, 1] - 4.1
    pen = 0.1 * np.hypot(tx - 1.3, ty + 4.1)
    priority = rng.permutation(len(tx)).astype(float)
    b = search_module.translation_blocks(lattice, tx, ty, pen, priority, sides)
    assert sorted(b.members.tolist()) == list(range(len(tx)))
    assert b.outer_start[0] == 0 and b.outer_start[-1] == len(b.inner_penalty)
    assert b.inner_start[0] == 0 and b.inner_start[-1] == len(tx)
    outer_rank, inner_rank = [], []
    for o in range(len(b.outer_penalty)):
        inner_blocks = range(b.outer_start[o], b.outer_start[o + 1])
        mine = b.members[b.inner_start[inner_blocks[0]] : b.inner_start[inner_blocks[-1] + 1]]
        cells = {tuple(c) for c in (lattice[mine] + m) // sides[0]}
        assert len(cells) == 1 and len(mine) <= sides[0] ** 2
        for members, centre, radius, least, first in [
            (mine, b.outer_centre[o], b.outer_radius[o], b.outer_penalty[o], b.outer_first[o])
        ] + [
            (
                b.members[b.inner_start[q] : b.inner_start[q + 1]], b.inner_centre[q],
                b.inner_radius[q], b.inner_penalty[q], b.inner_first[q],
            )
            for q in inner_blocks
        ]:  # fmt: skip
            assert np.all(np.hypot(tx[members] - centre[0], ty[members] - centre[1]) <= radius)
            assert radius <= np.hypot(*(sides[0] * 0.2 / 2,) * 2) + 1e-6
            assert least == pen[members].min() and first == members.min()
        outer_rank.append(priority[mine].min())
        for q in inner_blocks:
            members = b.members[b.inner_start[q] : b.inner_start[q + 1]]
            assert len({tuple(c) for c in (lattice[members] + m) // sides[1]}) == 1
            assert list(priority[members]) == sorted(priority[members])
            inner_rank.append(priority[members].min())
        ranks = inner_rank[-len(inner_blocks) :]
        assert ranks == sorted(ranks)
    assert outer_rank == sorted(outer_rank)


def test_the_translation_blocks_refuse_sides_that_do_not_nest() -> None:
    lattice = np.zeros((1, 2), dtype=np.int64)
    with pytest.raises(ValueError, match="no multiple"):
        search_module.translation_blocks(lattice, np.zeros(1), np.zeros(1), np.zeros(1),
                                         np.zeros(1), (4, 3))  # fmt: skip


# -- line matching -----------------------------------------------------------------------------
def _line_scans(pose, motion, seed):
    fa = extract_features(scan_at(pose, seed, 180), CFG)
    moved = Pose2D(*pose).compose(Pose2D(*motion))
    fb = extract_features(scan_at((moved.x, moved.y, moved.theta), seed + 1, 180), CFG)
    return fa.lines, fb.lines


def _second_gap(cost: np.ndarray, axis: int) -> float:
    """The smallest gap between the least and the next finite cost along ``axis``."""
    c = np.sort(np.where(np.isfinite(cost), cost, np.inf), axis=axis)
    if c.shape[axis] < 2:
        return math.inf
    least = np.take(c, 0, axis=axis)
    gap = np.take(c, 1, axis=axis)[np.isfinite(least)] - least[np.isfinite(least)]
    return float(np.nanmin(gap)) if gap.size else math.inf


class LineMargins:
    """The smallest distance of the line matching's own values (numpy reference) to their
    thresholds: the gates and the overlap, the robust cut, the consensus's sine and inlier
    distance, and the gaps between the least costs and scores that pick a pair."""

    def __init__(self, patch: pytest.MonkeyPatch) -> None:
        self.values: list[float] = [math.inf]
        pair, keep = matching_oracle.pair_lines, matching_oracle.robust_keep
        consensus = matching_oracle._translation_consensus

        def _pair_lines_numpy(prev, curr, pose, angle_gate, distance_gate, overlap_margin):
            ang, dd, along, reach = matching_oracle._line_geometry(prev, curr, pose, overlap_margin)
            out = (ang >= angle_gate) | (dd >= distance_gate) | (np.abs(along) > reach)
            cost = np.where(out, np.inf, ang / angle_gate + dd / distance_gate)
            self.values += [
                np.abs(ang - angle_gate).min(), np.abs(dd - distance_gate).min(),
                np.abs(np.abs(along) - reach).min(), _second_gap(cost, 0), _second_gap(cost, 1),
            ]  # fmt: skip
            return pair(prev, curr, pose, angle_gate, distance_gate, overlap_margin)

        def robust_keep(values, floor, center=None):
            dev = np.abs(values - np.median(values))
            cut = max(3.0 * 1.4826 * float(np.median(dev)), floor)
            self.values.append(float(np.abs(dev - cut).min()))
            return keep(values, floor, center)

        def translation_consensus(nx, ny, rhs, candidates, tau, min_sine):
            idx = candidates.nonzero()[0]
            i, j = np.triu_indices(idx.size, 1)
            det = nx[idx[i]] * ny[idx[j]] - ny[idx[i]] * nx[idx[j]]
            if det.size and idx.size >= 3:
                self.values.append(float(np.abs(np.abs(det) - min_sine).min()))
                ok = np.abs(det) > min_sine
                ii, jj, dt = idx[i][ok], idx[j][ok], det[ok]
                tx = (rhs[ii] * ny[jj] - ny[ii] * rhs[jj]) / dt
                ty = (nx[ii] * rhs[jj] - rhs[ii] * nx[jj]) / dt
                r = np.abs(tx[:, None] * nx[idx] + ty[:, None] * ny[idx] - rhs[idx])
                if r.size:
                    self.values.append(float(np.abs(r - tau).min()))
                    score = np.sort(np.minimum(r * r, tau * tau).sum(axis=1))
                    self.values.append(float(score[1] - score[0]) if score.size > 1 else math.inf)
            return consensus(nx, ny, rhs, candidates, tau, min_sine)

        patch.setattr(matching_oracle, "pair_lines", _pair_lines_numpy)
        patch.setattr(matching_oracle, "robust_keep", robust_keep)
        patch.setattr(matching_oracle, "_translation_consensus", translation_consensus)

    @property
    def value(self) -> float:
        return float(min(self.values))


@BUDGET
@given(
    pose=poses,
    motion=st.tuples(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3), st.floats(-0.2, 0.2)),
    error=st.tuples(st.floats(-0.1, 0.1), st.floats(-0.1, 0.1), st.floats(-0.05, 0.05)),
    seed=st.integers(0, 1000),
    from_points=st.booleans(),
)
def test_the_compiled_line_matching_is_the_numpy_one(pose, motion, error, seed, from_points):
    """The same line pairs, the same increment from them, and the same motion from the
    stage's passes (from the prior with its wider gates, or from a point features' motion)."""
    from fuzzypos.pipeline import FeatureMatcher

    prev, curr = _line_scans(pose, motion, seed)
    assume(len(prev) >= 2 and len(curr) >= 2)
    m = CFG.matching
    start = np.array(motion) + np.array(error)
    prior = np.array(motion)
    gates = (m.line_angle_gate_prior, m.line_distance_gate_prior, m.line_overlap_margin)
    args = (m.line_prior_sigma, m.line_trim_angle, m.line_inlier_distance)
    args = (*args, m.line_consensus_angle)
    matcher = FeatureMatcher(m, CFG.fusion)
    with pytest.MonkeyPatch.context() as patch:
        margins = LineMargins(patch)
        pairs, ref_pairs = both(lambda: line_matching.pair_lines(prev, curr, start, *gates))
        increments = both(
            lambda: line_matching.increment_from_lines(prev, curr, ref_pairs, start, prior, *args)
        )
        staged = both(
            lambda: matcher.match_lines(prev, curr, start if from_points else None, prior)
        )
    assume(margins.value > MARGIN)
    np.testing.assert_array_equal(pairs.prev_index, ref_pairs.prev_index)
    np.testing.assert_array_equal(pairs.curr_index, ref_pairs.curr_index)
    if len(ref_pairs) < 2:
        assert increments == (None, None)
    else:
        np.testing.assert_allclose(increments[0], increments[1], rtol=0, atol=TOL)
    (est, n), (ref_est, ref_n) = staged
    assert n == ref_n and (est is None) == (ref_est is None)
    if est is not None:
        np.testing.assert_allclose(est, ref_est, rtol=0, atol=TOL)


# -- the segmentation stages -------------------------------------------------------------------
def _sequence(rng: np.random.Generator, n: int) -> np.ndarray:
    """A scan-like sequence: a random polygon's walls seen from inside (corners), some
    stretches pushed back (gaps), range noise."""
    angles = np.linspace(-math.pi, math.pi, n, endpoint=False)
    k = int(rng.integers(3, 9))
    corner_angles = np.sort(rng.uniform(-math.pi, math.pi, k))
    corners = rng.uniform(1.0, 8.0, k)[:, None] * np.stack(
        (np.cos(corner_angles), np.sin(corner_angles)), axis=1
    )
    ranges = np.empty(n)
    for i, a in enumerate(angles):  # the ray against the polygon's edge that spans it
        e = int(np.searchsorted(corner_angles, a)) % k
        p, q = corners[e - 1], corners[e]
        d = np.array([math.cos(a), math.sin(a)])
        edge = q - p
        den = d[0] * edge[1] - d[1] * edge[0]
        t = (p[0] * edge[1] - p[1] * edge[0]) / den if abs(den) > 1e-12 else 5.0
        ranges[i] = min(max(t, 0.3), 20.0)
    pushed = np.repeat(rng.uniform(0.0, 1.0, 8) < 0.3, -(-n // 8))[:n]
    ranges = np.where(pushed, ranges * 1.5, ranges) + rng.normal(0, 0.01, n)
    return np.stack((ranges * np.cos(angles), ranges * np.sin(angles)), axis=1)


@BUDGET
@given(n=st.integers(0, 200), seed=st.integers(0, 2**31), closed=st.booleans())
def test_the_compiled_segmentation_stages_are_the_numpy_ones(n, seed, closed) -> None:
    """Break points (eq. 13), detection angles (eq. 3), clusters, angular points (eq. 14),
    segment ids and the lines' fits on random sequences, where no step, angle or arm lies
    within 1e-6 of its threshold."""
    rng = np.random.default_rng(seed)
    p = _sequence(rng, n)
    thresholds = rng.uniform(0.05, 0.5, n)
    gap_difference = float(rng.uniform(0.0, 0.3))
    steps = features_oracle.steps(p, closed)
    prev, nxt = np.roll(steps, 1), np.roll(steps, -1)
    finite = np.isfinite(steps)
    near = [np.abs(steps[finite] - thresholds[finite])]
    for other in (prev, nxt):
        with np.errstate(invalid="ignore"):  # inf − inf past an open end
            diff = steps - other
        near.append(np.abs(diff[np.isfinite(diff)] - gap_difference))
    assume(all(np.all(v > MARGIN) for v in near))
    is_break, split = seg.break_points(p, thresholds, gap_difference, closed)
    ref_break, ref_split = features_oracle.break_points(p, thresholds, gap_difference, closed)
    np.testing.assert_array_equal(is_break, ref_break)
    np.testing.assert_array_equal(split, ref_split)
    np.testing.assert_allclose(seg._steps(p, closed), steps, rtol=TOL, atol=0)

    beta = seg.detection_angles(p, split, closed)
    np.testing.assert_allclose(
        beta, features_oracle.detection_angles(p, split, closed), rtol=0, atol=TOL, equal_nan=True
    )
    min_points = int(rng.integers(1, 8))
    cluster = seg.clusters(split, min_points)
    np.testing.assert_array_equal(cluster, features_oracle.clusters(split, min_points))

    cfg = CFG.with_overrides({"angular_points": {"neighbour_step": int(rng.integers(1, 4))}})
    ap = cfg.angular_points
    spacing = features_oracle.steps(p, False)
    corner, angle = seg.angular_points(p, cluster, spacing, cfg)
    ref_corner, ref_angle = features_oracle.angular_points(p, cluster, spacing, cfg)
    assume(np.all(np.abs(ref_angle - ap.interior_angle_threshold) > MARGIN))
    np.testing.assert_allclose(angle, ref_angle, rtol=0, atol=TOL)
    np.testing.assert_array_equal(corner, ref_corner)

    exclusion = int(rng.integers(0, 3))
    raw, segment = seg.segment_ids(cluster, corner, exclusion, closed)
    ref_raw, ref_segment = features_oracle.segment_ids(cluster, corner, exclusion, closed)
    np.testing.assert_array_equal(raw, ref_raw)
    np.testing.assert_array_equal(segment, ref_segment)

    u = rng.uniform(0.0, 1.0, n)
    bases = rule_bases(cfg.fuzzy)
    lines, ref = (
        f(p, u, segment, cluster, bases, cfg) for f in (fit_lines, features_oracle.fit_lines)
    )
    assert len(lines) == len(ref)
    for name in ("normal", "distance", "start", "end", "centre", "sigma", "delta",
                 "uncertainty", "angle_variance", "distance_variance"):  # fmt: skip
        x, y = getattr(lines, name), getattr(ref, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_allclose(x, y, rtol=TOL, atol=TOL, err_msg=name)
    for name in ("n_points", "segment", "cluster"):
        np.testing.assert_array_equal(getattr(lines, name), getattr(ref, name), err_msg=name)

    # the lines joined at the angular points (§3.5 b)), where they meet steeply enough
    corners = corner.nonzero()[0]
    before, after = ref_raw[(corners - 1) % max(n, 1)], ref_raw[(corners + 1) % max(n, 1)]
    if len(ref) >= 2 and corners.size:
        a, b = features_oracle._lines_around_corners(ref, before, after)
        both_sides = (a >= 0) & (b >= 0)
        det = ref.normal[a[both_sides], 0] * ref.normal[b[both_sides], 1]
        det = det - ref.normal[a[both_sides], 1] * ref.normal[b[both_sides], 0]
        min_sine = math.sin(cfg.virtual_points.min_intersection_angle)
        assume(np.all(np.abs(np.abs(det) - min_sine) > MARGIN))
    joined, ref_joined = both(lambda: features_module.join_at_corners(ref, before, after, cfg))
    for x, y in zip(joined[1:], ref_joined[1:]):
        np.testing.assert_allclose(x, y, rtol=0, atol=TOL)
        assert x.dtype == y.dtype
    for name in ("start", "end", "centre"):
        x, y = getattr(joined[0], name), getattr(ref_joined[0], name)
        np.testing.assert_allclose(x, y, rtol=0, atol=TOL, err_msg=name)


# -- whole scans and runs ----------------------------------------------------------------------
@settings(max_examples=50, deadline=None)
@given(pose=poses, seed=st.integers(0, 1000), beams=st.sampled_from([180, 360]))
def test_the_features_of_a_scan_are_the_same_either_way(pose, seed, beams) -> None:
    """extract_features with the kernels and with the numpy references: the same points,
    clusters, corners, segments and lines (noisy simulated scans: no value sits on a
    threshold)."""
    scan = scan_at(pose, seed, beams)
    f, g = both(lambda: extract_features(scan, CFG))
    for name in ("kept", "is_break_point", "cluster", "is_angular_point", "segment"):
        np.testing.assert_array_equal(getattr(f, name), getattr(g, name), err_msg=name)
    np.testing.assert_allclose(f.detection_angle, g.detection_angle, rtol=0, atol=TOL)
    for name in ("normal", "distance", "start", "end", "uncertainty"):
        np.testing.assert_allclose(getattr(f.lines, name), getattr(g.lines, name), atol=TOL)


@BUDGET
@given(
    pose=poses,
    seed=st.integers(0, 1000),
    beams=st.sampled_from([180, 360]),
    clockwise=st.booleans(),
    offset=st.booleans(),
    bands=st.booleans(),
)
def test_the_compiled_front_of_the_chain_is_the_staged_one(
    pose, seed, beams, clockwise, offset, bands
) -> None:
    """The compiled front of feature extraction (usable points to segment ids, two compiled
    calls) against the staged chain in numpy (the oracle's ``segment_scan``), on scans read
    clockwise, with the scanner off the robot's centre and with "no return" bands that take
    some of the readings."""
    scan = scan_at(pose, seed, beams)
    ranges = np.asarray(scan.ranges)
    if clockwise:  # the same beams, listed from the other end
        scan = replace(
            scan, ranges=ranges[::-1].copy(),
            angle_min=scan.angle_min + (ranges.shape[0] - 1) * scan.angle_increment,
            angle_increment=-scan.angle_increment,
        )  # fmt: skip
    if offset:
        scan = replace(scan, sensor_pose=Pose2D(0.12, -0.03, 0.05))
    cfg = CFG
    if bands:  # the band around the median range drops a stretch of readings
        mid = float(np.median(ranges[np.isfinite(ranges)]))
        band = ((max(mid - 0.2, 0.0), mid + 0.2),)
        cfg = CFG.with_overrides({"scanner": {"no_return_bands": band}})
    bases = features_module.rule_bases(cfg.fuzzy)
    fused = seg.segment_scan(scan, bases, cfg)
    staged = features_oracle.segment_scan(scan, bases, cfg)
    th = cfg.filtering.detection_angle_threshold
    assume(np.abs(staged[4] - th).min(initial=1.0) > MARGIN)
    for k, (x, y) in enumerate(zip(fused, staged)):
        if isinstance(y, np.ndarray) and y.dtype == np.float64:
            np.testing.assert_allclose(x, y, rtol=0, atol=TOL, err_msg=str(k))
        elif isinstance(y, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=str(k))
        else:
            assert x == pytest.approx(y, abs=TOL), k


def _same_features(f: Any, g: Any) -> None:
    """Two scans' features equal to the bit: every array of the features, of their lines and
    of the corners' context, and the scales (every field: the compiled chain's are taken
    from its packed arrays on first use)."""
    import dataclasses

    for obj_f, obj_g in ((f, g), (f.lines, g.lines), (f._corners, g._corners)):
        for name in (field.name for field in dataclasses.fields(obj_f)):
            x, y = getattr(obj_f, name), getattr(obj_g, name)
            if isinstance(x, np.ndarray):
                assert x.dtype == y.dtype, name
                np.testing.assert_array_equal(x, y, err_msg=name)
            elif isinstance(x, float | int):
                assert x == y, name
            elif x is None:
                assert y is None, name


@BUDGET
@given(
    pose=poses,
    seed=st.integers(0, 1000),
    beams=st.sampled_from([180, 360]),
    clockwise=st.booleans(),
    offset=st.booleans(),
    bands=st.booleans(),
)
def test_the_whole_compiled_chain_is_its_calls_one_by_one(
    pose, seed, beams, clockwise, offset, bands
) -> None:
    """extract_features in one compiled call (``_kernels.front.scan_features``) against the
    compiled front, line stage and corner joins called one by one with numpy between them
    (themselves checked against the numpy references above): the same features to the bit,
    on scans read clockwise, off the robot's centre and with "no return" bands."""
    scan = scan_at(pose, seed, beams)
    ranges = np.asarray(scan.ranges)
    if clockwise:
        scan = replace(
            scan, ranges=ranges[::-1].copy(),
            angle_min=scan.angle_min + (ranges.shape[0] - 1) * scan.angle_increment,
            angle_increment=-scan.angle_increment,
        )  # fmt: skip
    if offset:
        scan = replace(scan, sensor_pose=Pose2D(0.12, -0.03, 0.05))
    cfg = CFG
    if bands:
        mid = float(np.median(ranges[np.isfinite(ranges)]))
        cfg = CFG.with_overrides(
            {"scanner": {"no_return_bands": ((max(mid - 0.2, 0.0), mid + 0.2),)}}
        )
    fused, one_by_one = compiled_and_staged(scan, cfg)
    _same_features(fused, one_by_one)


def test_the_whole_compiled_chain_without_lines() -> None:
    """A scan of a few scattered readings (an angular point, no line) is the calls' one by
    one too; a gapless ring is the one compiled call's as well."""
    scan = scan_at((0.0, 0.0, 0.0), 1, 180)
    ranges = np.full(np.asarray(scan.ranges).shape, np.inf)
    ranges[::40] = 2.0
    sparse = replace(scan, ranges=ranges)
    f = features_module._extract_compiled(sparse, rule_bases(CFG.fuzzy), CFG)
    assert f is not None and len(f.lines) == 0 and f.lines.angle_variance is None
    with pytest.MonkeyPatch.context() as m:
        m.setattr(features_module, "_extract_compiled", lambda *args: None)
        _same_features(f, extract_features(sparse, CFG))
    room = sim.World.from_polygons([sim.worlds.box_polygon(0.0, 0.0, 6.0, 6.0)])
    ring = sim.simulate_scan(room, Pose2D(0.3, -0.2, 0.4), scanner(360, noise=0.002),
                             rng=np.random.default_rng(1))  # fmt: skip
    fused, one_by_one = compiled_and_staged(ring, CFG)
    _same_features(fused, one_by_one)
    assert fused.is_angular_point[0] and not fused.is_break_point.any()  # the seam, no gap


GYM = sim.gym()


@BUDGET
@given(
    x=st.floats(-10.0, 10.0),
    y=st.floats(-5.0, 5.0),
    theta=st.floats(-math.pi, math.pi),
    seed=st.integers(0, 1000),
    grading=st.sampled_from(["structure", "points", "fixed"]),
)
def test_the_compiled_line_stage_is_the_staged_one(x, y, theta, seed, grading) -> None:
    """The lines' grading scale, the re-graded points and the line fits in one compiled call
    against the oracle's staged functions in numpy, in a gym seen out to 30 m (so the lines' scale
    differs from the points'), for each way of grading the distances."""
    model = sim.ScannerModel(n_beams=360, field_of_view_deg=360.0, angle_min_deg=-180.0,
                             range_max=30.0, range_noise_std=0.01)  # fmt: skip
    scan = sim.simulate_scan(GYM, Pose2D(x, y, theta), model, rng=np.random.default_rng(seed))
    fuzzy = {"structure": {}, "points": {"line_distance_scale": "points"},
             "fixed": {"distance_scale": "fixed"}}[grading]  # fmt: skip
    cfg = CFG.with_overrides({"fuzzy": fuzzy}) if fuzzy else CFG
    bases = features_module.rule_bases(cfg.fuzzy)
    front = features_oracle.segment_scan(scan, bases, cfg)
    _, ranges, points, scale, beta, u, _, kept_index = front[:8]
    segment, cluster = front[13], front[10]
    kp, kr, ku, kb = points[kept_index], ranges[kept_index], u[kept_index], beta[kept_index]
    lines, fused_scale = features_module._graded_lines(
        kp, kr, kb, ku, segment, cluster, scale, bases, cfg
    )
    lu, line_scale = features_oracle.graded_for_lines(kr, kb, ku, segment, scale, bases, cfg)
    staged = features_oracle.fit_lines(kp, lu, segment, cluster, bases, cfg)
    assert fused_scale == pytest.approx(line_scale, rel=TOL)
    assume(np.abs(lu - 0.5).min(initial=1.0) > MARGIN)  # (no grading sits on a tie)
    for name in ("normal", "distance", "start", "end", "sigma", "delta", "uncertainty",
                 "angle_variance", "distance_variance"):  # fmt: skip
        np.testing.assert_allclose(
            getattr(lines, name), getattr(staged, name), rtol=TOL, atol=TOL, err_msg=name
        )
    for name in ("n_points", "segment", "cluster"):
        np.testing.assert_array_equal(getattr(lines, name), getattr(staged, name), err_msg=name)


def test_a_gapless_ring_has_its_seam_on_its_sharpest_corner() -> None:
    """A 360° scan inside a closed square room has no gap: the compiled front puts the seam
    on the sharpest corner as the numpy chain does, for a rule base it interpolates and for
    a Mamdani one (graded by the rule base itself between the compiled stages)."""
    room = sim.World.from_polygons([sim.worlds.box_polygon(0.0, 0.0, 6.0, 6.0)])
    scan = sim.simulate_scan(room, Pose2D(0.3, -0.2, 0.4), scanner(360, noise=0.002),
                             rng=np.random.default_rng(1))  # fmt: skip
    for cfg in (CFG, CFG.with_overrides({"fuzzy": {"inference": "mamdani"}})):
        bases = features_module.rule_bases(cfg.fuzzy)
        front = seg.segment_scan(scan, bases, cfg)
        assert front.ring_corner and front.is_angular_point[0]
        reference = features_oracle.segment_scan(scan, bases, cfg)
        for k, (x, y) in enumerate(zip(front, reference, strict=True)):
            if isinstance(y, np.ndarray) and y.dtype == np.float64:
                np.testing.assert_allclose(x, y, rtol=0, atol=TOL, err_msg=str(k))
            elif isinstance(y, np.ndarray):
                np.testing.assert_array_equal(x, y, err_msg=str(k))
            else:
                assert x == pytest.approx(y, abs=TOL), k
        f, g = both(lambda cfg=cfg: extract_features(scan, cfg))
        np.testing.assert_array_equal(f.is_angular_point, g.is_angular_point)
        np.testing.assert_array_equal(f.segment, g.segment)
        assert f.is_angular_point[0]  # the seam on a corner
        assert f.lines.normal.shape[0] == g.lines.normal.shape[0] >= 4
        np.testing.assert_allclose(f.uncertainty, g.uncertainty, rtol=0, atol=TOL)
        np.testing.assert_allclose(f.lines.uncertainty, g.lines.uncertainty, rtol=0, atol=TOL)
        np.testing.assert_allclose(f.lines.distance, g.lines.distance, rtol=0, atol=TOL)


def test_a_simulated_run_is_the_same_either_way() -> None:
    """A drive through the office with drifting odometry: the same trajectory, step by step."""
    truth = sim.arc_path(Pose2D(-8.0, 0.0, 0.0), 60, step=0.08, turn_deg=1.0)
    odom = sim.drifting_odometry(truth, scale=1.02, rotation_bias_deg=0.1)
    scans = sim.simulate_scans(WORLD, truth, scanner(180), rng=np.random.default_rng(3))

    def run() -> np.ndarray:
        return np.array([e.pose.as_array() for e in Positioner(CFG).run(scans, odom)])

    compiled, reference = both(run)
    np.testing.assert_allclose(compiled, reference, rtol=0, atol=TOL)


# -- laziness ----------------------------------------------------------------------------------
def test_importing_fuzzypos_loads_no_compiler() -> None:
    """``import fuzzypos`` neither imports numba nor compiles anything (first use does), nor
    scipy's KD-tree (the numpy references' index, imported where one is built)."""
    code = (
        "import sys, fuzzypos\n"
        "print('numba' in sys.modules, 'fuzzypos._kernels.grid' in sys.modules,"
        " 'scipy.spatial' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False", "False"]


def test_only_numbas_own_switch_turns_the_compilation_off(monkeypatch) -> None:
    """numba is a dependency and the kernels the one implementation: they are compiled unless
    numba's own ``NUMBA_DISABLE_JIT`` runs them as Python (the warm-up then has nothing to
    compile); ``FUZZYPOS_KERNELS`` is gone."""
    monkeypatch.setenv("FUZZYPOS_KERNELS", "numpy")
    assert kernels.compiled()
    monkeypatch.setenv("NUMBA_DISABLE_JIT", "1")
    assert not kernels.compiled()
    monkeypatch.setenv("NUMBA_DISABLE_JIT", "0")
    assert kernels.compiled()


# -- the CARMEN writer's ranges as text -------------------------------------------------------
@given(
    st.lists(
        st.one_of(
            st.floats(-100.0, 100.0),
            st.floats(allow_nan=True, allow_infinity=True),
            st.integers(-(10**6), 10**6).map(lambda k: (k + 0.5) / 1e4),  # ties
            st.integers(0, 10**9).map(lambda k: k / 1e4),  # whole decimals
            st.sampled_from([0.0, -0.0, 5e-5, -1e-5, 0.03125, 99999.99995, 1e5, 1e12]),
        ),
        max_size=50,
    )
)
def test_fixed_text_kernel_is_its_reference(values):
    from fuzzypos.io import carmen_write

    v = np.array(values, dtype=np.float64)
    fast, reference = both(lambda: carmen_write._fixed_text(v))
    assert fast == reference == io_oracle.fixed_text(v)
    if reference is not None:
        assert reference == " ".join(f"{x:.4f}".rstrip("0").removesuffix(".") for x in values)


# -- the CARMEN reader's numbers from text ---------------------------------------------------
_DECIMAL_TOKENS = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False).map(repr),  # shortest round-trip
    st.floats(-1e6, 1e6).map(lambda v: f"{v:.4f}"),  # a logger's fixed decimals
    st.floats(0.0, 100.0).map(lambda v: f"{v:.2f}".rstrip("0")),  # "3." too
    st.floats(-1e3, 1e3).map(lambda v: f"{v:g}"),  # exponents
    st.floats(-1e3, 1e3).map(lambda v: f"{v:.17e}"),  # too many digits for the fast path
    st.integers(-(10**18), 10**18).map(str),
    st.decimals(allow_nan=False, allow_infinity=False, places=6).map(str),
    st.from_regex(r"\A[+-]?[0-9]{0,20}\.?[0-9]{0,20}([eE][+-]?[0-9]{1,3})?\Z"),
    st.sampled_from(
        [
            "-0",
            "+0.0",
            ".5",
            "5.",
            "1e22",
            "1e23",
            "9007199254740993",
            "nan",
            "-inf",
            "1_000",
            "0x10",
            "1e",
            "--1",
            "1.2.3",
            "",
            "١",
        ]
    ),
)


@given(st.lists(_DECIMAL_TOKENS, min_size=1, max_size=40))
def test_the_compiled_parser_gives_floats_own_doubles(tokens):
    """Where the kernel parses a list of numbers, each is the double ``float()`` makes of its
    text, bit for bit (-0.0 too); what it does not take (not a plain decimal, beyond the exact
    fast path) it leaves to the reference: ``_numbers`` gives numpy's values or its error,
    with the kernels as without."""
    from fuzzypos._kernels.text import parse_decimals
    from fuzzypos.io import carmen

    tokens = [t for t in tokens if t and not any(c.isspace() for c in t)]
    assume(tokens)
    text = np.frombuffer(" ".join(tokens).encode("ascii", "replace"), dtype=np.uint8)
    ok, values = parse_decimals(text, len(tokens))
    if ok:
        assert [v.hex() for v in values.tolist()] == [float(t).hex() for t in tokens]
    many = tokens * (carmen._PARSED_FROM // len(tokens) + 1)  # long enough for the kernel
    try:
        reference = np.array(many, dtype=np.float64)
    except ValueError:
        with pytest.raises(carmen._Bad):
            carmen._numbers(many, "range")
        with numpy_kernels(), pytest.raises(carmen._Bad):
            carmen._numbers(many, "range")
        return
    fast, ref = both(lambda: carmen._numbers(many, "range"))
    assert fast.tobytes() == ref.tobytes() == reference.tobytes()


def test_the_compiled_parser_takes_a_loggers_numbers():
    """The numbers of a CARMEN log's lines (fixed decimals, integers, exponents, signs) are
    all the kernel's to parse, not left to the reference; a malformed separator is not."""
    from fuzzypos._kernels.text import parse_decimals

    tokens = ["81.83", "0.02", "-3.1415", "12", "1e-3", "+7.", "-0", "1203.5523", "1.5E+2"]
    text = np.frombuffer(" ".join(tokens).encode(), dtype=np.uint8)
    ok, values = parse_decimals(text, len(tokens))
    assert ok and [v.hex() for v in values.tolist()] == [float(t).hex() for t in tokens]
    for bad, count in (("1.5  2.5", 2), (" 1.5 2.5", 2), ("1.5 2.5 ", 2), ("1.5 2.5", 3),
                       ("1.5 2.5", 1), ("1.5,2.5", 2)):  # fmt: skip
        ok, values = parse_decimals(np.frombuffer(bad.encode(), dtype=np.uint8), count)
        assert not ok and values.size == 0


# -- the fuzzy rule bases' bilinear interpolation ---------------------------------------------
@BUDGET
@given(
    st.lists(st.tuples(st.floats(-1.0, 40.0), st.floats(-1.0, 3.0)), max_size=40),
    st.sampled_from(["points", "lines"]),
)
def test_rule_base_interpolation_kernel_is_its_reference(pairs, which):
    base = getattr(rule_bases(CFG.fuzzy), which)
    assert base._grids is not None  # the fast path
    x1 = np.array([p[0] for p in pairs], dtype=np.float64)
    x2 = np.array([p[1] for p in pairs], dtype=np.float64)
    # the grids' own peaks too: where np.interp takes a point's value as it is
    g1, g2 = base._grids
    x1 = np.concatenate([x1, g1])
    x2 = np.concatenate([x2, np.resize(g2, g1.shape)])
    compiled, reference = both(lambda: base(x1, x2))
    np.testing.assert_allclose(compiled, reference, rtol=0, atol=TOL)


# -- the uncertainty stage's 3×3 arithmetic ---------------------------------------------------
def _spd(rng: np.random.Generator, scale: float) -> np.ndarray:
    """A random symmetric positive definite 3×3 of about ``scale``."""
    a = rng.normal(size=(3, 3))
    return scale * (a @ a.T + 0.3 * np.eye(3))


def _fit(rng: np.random.Generator, hold: bool, prior_differs: bool, across: bool = False) -> Any:
    """A random fit; ``across``: its heading near π, its prior's across ±π from it."""
    from fuzzypos.matching import Refinement

    heading = math.pi - 0.01 * rng.uniform() if across else rng.uniform(-math.pi, math.pi)
    increment = np.array([*rng.normal(scale=0.3, size=2), heading])
    prior = increment + (rng.normal(scale=0.02, size=3) if prior_differs else 0.0)
    if across:
        prior[2] = increment[2] + 0.02
    prior[2] = (prior[2] + math.pi) % math.tau - math.pi  # wrapped: across ±π from increment's
    return Refinement(
        increment, 150, 0.9, 0.8,
        information=_spd(rng, 1e5),
        prior_information=_spd(rng, 1e3),
        hold_information=_spd(rng, 1e4) if hold else np.zeros((3, 3)),
        hold_on_start=bool(rng.integers(2)),
        start=increment + rng.normal(scale=0.01, size=3),
        prior=prior,
        gradient_covariance=_spd(rng, 1e3),
    )  # fmt: skip


@BUDGET
@given(
    seed=st.integers(0, 10**6),
    with_fit=st.booleans(),
    hold=st.booleans(),
    prior_differs=st.booleans(),
    gate_open=st.booleans(),
)
def test_the_compiled_assessment_is_the_numpy_one(
    seed, with_fit, hold, prior_differs, gate_open
) -> None:
    """``Uncertainty.assess`` of random fits (a hold or none, a prior at the odometry's motion
    or off it, the gate open or closed), compiled and in numpy, from the same previous
    covariance: the covariances, the gate, the rejection and the state the next scan inherits."""
    from fuzzypos.pipeline.uncertainty import Uncertainty

    rng = np.random.default_rng(seed)
    t_prev = rng.normal(scale=[0.5, 0.5, 1.0])
    prior = rng.normal(scale=[0.1, 0.1, 0.2])
    prior_cov = _spd(rng, 1e-4)
    previous = _spd(rng, 1e-5)
    fit = _fit(rng, hold, prior_differs) if with_fit else None
    from_key = fit.increment if fit is not None else rng.normal(scale=[0.3, 0.3, 0.5])
    if fit is not None and not prior_differs:
        # the prior at the odometry's motion from the keyframe, as the positioner gives it
        key = np.array(Pose2D(*t_prev).compose(Pose2D(*prior)).as_array())
        fit = replace(fit, prior=key)

    def run() -> Any:
        u = Uncertainty(CFG.covariance, CFG.gate)
        u._previous = previous.copy()
        out = u.assess(t_prev, prior, prior_cov, from_key, fit, gate_open)
        return out, u._previous

    (a, prev_a), (b, prev_b) = both(run)
    if b.gate is not None:
        assume(abs(b.gate - Uncertainty(CFG.covariance, CFG.gate).threshold) > MARGIN)
    assert a.rejected == b.rejected
    assert (a.gate is None) == (b.gate is None)
    if b.gate is not None:
        assert a.gate == pytest.approx(b.gate, rel=TOL, abs=TOL)
    for x, y in ((a.covariance, b.covariance), (a.keyframe_covariance, b.keyframe_covariance)):
        np.testing.assert_allclose(x, y, rtol=TOL, atol=TOL * np.abs(y).max())
    np.testing.assert_allclose(prev_a, prev_b, rtol=TOL, atol=TOL * np.abs(prev_b).max())


@BUDGET
@given(seed=st.integers(0, 10**6), singular=st.booleans(), hold=st.booleans(), across=st.booleans())
def test_the_compiled_scan_only_motion_is_the_numpy_one(seed, singular, hold, across) -> None:
    """``Uncertainty.scan_only`` of random fits, compiled and in numpy: the same motion and
    covariance, and None alike where a hold was used or the points' information is too
    ill-conditioned (a corridor's); the prior's heading unwrapped near the fit's across ±π."""
    from fuzzypos.pipeline.uncertainty import Uncertainty

    rng = np.random.default_rng(seed)
    fit = _fit(rng, hold, True, across)
    if singular:
        info = fit.information.copy()
        info[0] = info[1] * (1.0 + 1e-12)  # rank deficient to rounding
        info[:, 0] = info[:, 1] * (1.0 + 1e-12)
        fit = replace(fit, information=info)
    t_prev = rng.normal(scale=[0.5, 0.5, 1.0])
    previous = _spd(rng, 1e-5)

    def run() -> Any:
        u = Uncertainty(CFG.covariance, CFG.gate)
        u._previous = previous.copy()
        return u.scan_only(fit, t_prev)

    a, b = both(run)
    if hold or singular:
        assert b is None
    assert (a is None) == (b is None)
    if b is not None:
        np.testing.assert_allclose(a[0], b[0], rtol=TOL, atol=TOL)
        np.testing.assert_allclose(a[1], b[1], rtol=TOL, atol=TOL * np.abs(b[1]).max())
