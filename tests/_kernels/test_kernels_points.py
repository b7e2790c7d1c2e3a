"""The point features' compiled call (``fuzzypos._kernels.points``) against its numpy
reference (``point_features`` of ``tests/oracles/features.py``): the same angular, virtual
angular and break points, the same virtual points' line pairs and the same merged points of
interest, to 1e-9 (kinds and pairs exactly), on simulated scans from anywhere in several
worlds and with every switch of the angular points and the matching; its fuzzy grading
against ``RuleBase``'s own (eq. 4) and its merge against the oracle's ``merge_duplicates``;
and the kernel where the numpy chain meets a NaN, a Mamdani rule base (graded between two
calls) and a context whose arrays disagree."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzypos import sim
from fuzzypos.config import Config
from fuzzypos.features import FeaturePoints, rule_bases
from fuzzypos.features import extract as F
from fuzzypos.features import points as P
from fuzzypos.geometry import Pose2D
from oracles.features import merge_duplicates
from oracles.features import point_features as numpy_point_features

TOL = 1e-9
BUDGET = settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.filter_too_much]
)
WORLDS = {name: sim.world_by_name(name) for name in ("office", "gym")}
poses = st.tuples(st.floats(-6.0, 6.0), st.floats(-1.0, 1.0), st.floats(-math.pi, math.pi))


def _context(world: str, pose: tuple[float, float, float], seed: int, cfg: Config) -> Any:
    """The corner context of a simulated 180-beam scan (the compiled chain's packed one)."""
    model = sim.ScannerModel(
        n_beams=180, field_of_view_deg=180.0, angle_min_deg=-90.0, range_max=8.0,
        range_noise_std=0.01,
    )  # fmt: skip
    scan = sim.simulate_scan(WORLDS[world], Pose2D(*pose), model, rng=np.random.default_rng(seed))
    return F.extract_features(scan, cfg)._corners


def _assert_same(got: Any, want: Any) -> None:
    angular, virtual, virtual_lines, breaks, poi = got
    for a, b in zip((angular, virtual, breaks, poi), want[:2] + want[3:], strict=True):
        assert isinstance(a, FeaturePoints)
        assert a.xy.shape == b.xy.shape and a.uncertainty.shape == b.uncertainty.shape
        assert a.kind.dtype == np.int8 and np.array_equal(a.kind, b.kind)
        np.testing.assert_allclose(a.xy, b.xy, rtol=0, atol=TOL)
        np.testing.assert_allclose(a.uncertainty, b.uncertainty, rtol=0, atol=TOL)
    assert virtual_lines.dtype == np.int64
    np.testing.assert_array_equal(virtual_lines, want[2])


SWITCHES = [
    {},
    {"angular_points": {"refine": False}},
    {"angular_points": {"pair_unrefined": True}},
    {"matching": {"use_break_points": True}},
    {"matching": {"use_break_points": True, "use_angular_points": False}},
    {"matching": {"use_virtual_points": False}},
    {"virtual_points": {"merge_distance": 0.0}},
    {"virtual_points": {"merge_distance": 0.5, "max_uncertainty": 1.0}},
]


@BUDGET
@given(
    world=st.sampled_from(sorted(WORLDS)), pose=poses, seed=st.integers(0, 1000),
    switch=st.sampled_from(range(len(SWITCHES))),
)  # fmt: skip
def test_the_compiled_point_features_are_the_numpy_ones(world, pose, seed, switch) -> None:
    cfg = Config().with_overrides(SWITCHES[switch])
    c = _context(world, pose, seed, cfg)
    got = P.point_features(c)
    _assert_same(got, numpy_point_features(c))


def test_a_scan_with_corners_and_crossings_has_every_kind() -> None:
    """The drive through the office meets angular points, virtual ones and break points (the
    property test above covers more than empty sets), each the numpy chain's."""
    cfg = Config()
    seen = np.zeros(3, dtype=int)
    for k, x in enumerate(np.linspace(-6.0, 6.0, 13)):
        c = _context("office", (float(x), 0.2, 0.3 * k), k, cfg)
        got = P.point_features(c)
        _assert_same(got, numpy_point_features(c))
        seen += [len(got[0]), len(got[1]), len(got[3])]
    assert (seen > 0).all(), seen


def _office_views(cfg: Config) -> Any:
    return (_context("office", (float(x), 0.2, 0.3 * k), k, cfg)
            for k, x in enumerate(np.linspace(-6.0, 6.0, 13)))  # fmt: skip


@pytest.mark.parametrize("where", ["line uncertainty", "corner", "range", "kept uncertainty"])
def test_a_nan_on_the_way_is_the_numpy_chains(where) -> None:
    """NaN where the numpy chain carries it through (a line's uncertainty into the grading, a
    corner's intersection into the refinement, a range into the beam spacing, a point's
    uncertainty into the merge's order): the kernel's points are the oracle's, NaNs in the
    same places."""
    cfg = Config().with_overrides({"matching": {"use_break_points": True}})
    c = next(v for v in _office_views(cfg) if len(numpy_point_features(v)[1]) and v.joined.any())
    if where == "line uncertainty":
        u = c.lines.uncertainty.copy()
        u[::2] = np.nan
        bad = dataclasses.replace(c, lines=dataclasses.replace(c.lines, uncertainty=u))
    elif where == "corner":
        xy = c.corner_xy.copy()
        k = int(c.joined.nonzero()[0][0])
        xy[k] = np.nan  # (its gap then taken from the origin, as np.nan_to_num has it)
        bad = dataclasses.replace(c, corner_xy=xy)
    elif where == "range":
        r = c.kept_ranges.copy()
        r[c.corner_index] = np.nan
        bad = dataclasses.replace(c, kept_ranges=r)
    else:
        ku = c.kept_uncertainty.copy()
        ku[::3] = np.nan
        bad = dataclasses.replace(c, kept_uncertainty=ku)
    got, want = P.point_features(bad), numpy_point_features(bad)
    _assert_same(got, want)
    if where in ("line uncertainty", "kept uncertainty"):  # (the others drop a refinement)
        assert any(np.isnan(part.uncertainty).any() for part in got if hasattr(part, "xy"))


def test_a_mamdani_rule_base_grades_between_two_calls() -> None:
    """A Mamdani rule base (no grading tables): the kernel's inputs graded by the rule base
    itself, the points those of the numpy chain."""
    cfg = Config().with_overrides({"fuzzy": {"inference": "mamdani"}})
    seen = 0
    for c in _office_views(cfg):
        assert P.grading_tables(c.bases.virtual_points) is None
        got, want = P.point_features(c), numpy_point_features(c)
        _assert_same(got, want)
        seen += len(got[1])
    assert seen > 0


def test_a_context_whose_arrays_disagree_is_a_feature_error() -> None:
    """A corner context built by hand with a segment id past the lines' (numpy's IndexError)
    or a corner grade too few: a typed error, not a wrong answer."""
    from fuzzypos.features.types import FeatureError

    c = next(v for v in _office_views(Config()) if v.joined.any() and v.seg_before.size)
    far = dataclasses.replace(c, seg_before=c.seg_before - 10 * (c.seg_before.max() + 2))
    with pytest.raises(IndexError):
        numpy_point_features(far)
    with pytest.raises(FeatureError, match="inconsistent"):
        P.point_features(far)
    short = dataclasses.replace(c, corner_a=c.corner_a[:-1], corner_b=c.corner_b[:-1],
                                corner_dv=c.corner_dv[:-1])  # fmt: skip
    with pytest.raises(ValueError):
        numpy_point_features(short)
    with pytest.raises(FeatureError, match="inconsistent"):
        P.point_features(short)


def test_a_rule_base_the_kernel_does_not_evaluate_has_no_tables() -> None:
    """A Mamdani rule base (or one of other than three inputs) has no grading tables."""
    bases = rule_bases(Config().fuzzy)
    assert P.grading_tables(bases.virtual_points) is not None
    mamdani = dataclasses.replace(bases.virtual_points, mode="mamdani")
    assert P.grading_tables(mamdani) is None
    assert P.grading_tables(bases.points) is None  # two inputs


@BUDGET
@given(
    x=st.lists(
        st.tuples(
            st.floats(-0.5, 1.5) | st.just(math.nan), st.floats(-0.5, 1.5),
            st.floats(-1.0, 10.0) | st.just(math.nan),
        ),
        min_size=0, max_size=30,
    )
)  # fmt: skip
def test_the_kernels_grading_is_the_rule_bases_own(x) -> None:
    """``grade``: eq. 4's centre average of the three-input product rule base, clamped to its
    centres, as ``RuleBase.__call__`` computes it (to rounding: numpy sums in its own order),
    inputs beyond the sets' range included, and a NaN input graded NaN as numpy has it."""
    from fuzzypos._kernels.points import grade

    rb = rule_bases(Config().fuzzy).virtual_points
    tables = P.grading_tables(rb)
    assert tables is not None
    a = np.array(x, dtype=float).reshape(-1, 3)
    got = grade(
        a[:, 0].copy(), a[:, 1].copy(), a[:, 2].copy(), *tables, rb._centre_lo, rb._centre_hi
    )
    np.testing.assert_allclose(got, rb(a[:, 0], a[:, 1], a[:, 2]), rtol=0, atol=1e-12)


@BUDGET
@given(
    pts=st.lists(
        st.tuples(
            st.integers(0, 12), st.integers(0, 12),
            st.sampled_from([0.0, 0.1, 0.25, 0.5, math.nan]),
            st.integers(0, 2),
        ),
        min_size=0, max_size=25,
    ),
    radius=st.sampled_from([0.0, 0.05, 0.12, 0.3]),
)  # fmt: skip
def test_the_kernels_merge_keeps_what_merge_duplicates_keeps(pts, radius) -> None:
    """``_merge``: the kept indices of ``merge_duplicates`` (most certain first, ties: virtual,
    angular, break; stable; a NaN uncertainty last, as ``np.lexsort`` puts it), on points on
    a 0.1 m lattice with repeated uncertainties."""
    from fuzzypos._kernels.points import _merge

    a = np.array(pts, dtype=float).reshape(-1, 4)
    xy, u, kind = 0.1 * a[:, :2], a[:, 2].copy(), a[:, 3].astype(np.int8)
    want = merge_duplicates(FeaturePoints(xy, u, kind), radius)
    keep = _merge(np.ascontiguousarray(xy), u, kind, radius)
    np.testing.assert_array_equal(xy[keep], want.xy)
    np.testing.assert_array_equal(u[keep], want.uncertainty)
    np.testing.assert_array_equal(kind[keep], want.kind)


@pytest.mark.parametrize("shift", [0.0, 0.04, 0.2, 0.4, 0.6, 1.0])
def test_refined_angular_points_keep_the_sample_where_the_intersection_lies_far(shift) -> None:
    """A joined corner whose lines' intersection lies more than three beam spacings and 5 cm
    from the sampled angular point keeps the sample (and is not paired unless
    ``pair_unrefined``): the corners' intersections moved by ``shift`` metres, each the numpy
    chain's."""
    for cfg in (Config(), Config().with_overrides({"angular_points": {"pair_unrefined": True}})):
        views = (_context("office", (float(x), 0.2, 0.3 * k), k, cfg)
                 for k, x in enumerate(np.linspace(-6.0, 6.0, 13)))  # fmt: skip
        c = next(v for v in views if v.joined.any())
        moved = dataclasses.replace(c, corner_xy=c.corner_xy + np.array([shift, -0.5 * shift]))
        got = P.point_features(moved)
        want = numpy_point_features(moved)
        _assert_same(got, want)
        if shift == 1.0:  # every joined corner is back at its sample (8 m range at most)
            idx = c.corner_index[c.joined]
            assert not np.isin(want[0].xy, moved.corner_xy).all(axis=1).any()
            np.testing.assert_array_equal(want[0].xy[c.joined], c.kept_points[idx])
