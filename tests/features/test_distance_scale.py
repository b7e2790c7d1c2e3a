"""Range-aware uncertainty (``fuzzy.distance_scale``): the ρ and d_v sets and the virtual points'
distance limit stretched to a scan whose structure lies beyond the sets' 8 m, by known
geometry; the stretch computed as ρ / scale is the stretch of the sets; indoor scans unchanged.
"""

from __future__ import annotations

import math
import sys
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

from fuzzypos import sim
from fuzzypos.config import Config, ConfigError, FuzzyConfig
from fuzzypos.features import (
    Lines,
    distance_scale,
    extract_features,
    point_uncertainty,
    rule_bases,
    virtual_angular_points,
)
from fuzzypos.features.extract import virtual_candidates
from fuzzypos.features.segmentation import line_distance_scale
from fuzzypos.fuzzy import point_rule_base, virtual_point_rule_base
from fuzzypos.geometry import Pose2D

FIXED = Config(fuzzy=replace(Config().fuzzy, distance_scale="fixed"))

# a hall seen by a SICK scanner (81.9 m range): side walls 12 and 15 m away, the back wall at
# 45 m, and two free-standing walls about 20 m ahead whose lines meet at (20, 0), off both
# walls' ends (a gap between them shows the back wall): a virtual angular point only
HALL = sim.World.from_segments(
    [
        [45.0, -30.0, 45.0, 30.0],
        [-5.0, -12.0, 45.0, -12.0],
        [-5.0, 15.0, 45.0, 15.0],
        [20.0, 1.5, 20.0, 6.0],
        [19.0, -1.0, 15.0, -5.0],
    ]
)
VIRTUAL_XY = (20.0, 0.0)


def _sick(noise: float) -> sim.ScannerModel:
    return sim.ScannerModel(
        n_beams=181,
        field_of_view_deg=180.0,
        angle_min_deg=-90.0,
        range_max=81.9,
        range_noise_std=noise,
    )


def _hall_scan(noise: float = 0.0, seed: int = 0) -> sim.LaserScan:
    return sim.simulate_scan(HALL, Pose2D(0.0, 0.0, 0.0), _sick(noise), np.random.default_rng(seed))


def _load(text: str) -> Config:
    return Config.from_dict(tomllib.loads(text))


def _fuzzy(**kw: Any) -> FuzzyConfig:
    return replace(FuzzyConfig(), **kw)


# -- the scale ------------------------------------------------------------------------------
def test_scale_is_the_nearest_structure_over_the_reference() -> None:
    cfg = FuzzyConfig()
    assert cfg.distance_scale == "scan" and cfg.distance_scale_quantile == 0.05
    assert cfg.distance_scale_reference == 4.5
    assert distance_scale(np.full(50, 18.0), cfg) == pytest.approx(4.0, rel=1e-15)
    # the 5th percentile of 1..101 m is 6 m
    assert distance_scale(np.arange(1.0, 102.0), cfg) == pytest.approx(6.0 / 4.5, rel=1e-14)
    # a corridor: a tenth of the readings near, the rest far away: near structure, scale 1
    assert distance_scale(np.r_[np.full(10, 1.5), np.full(90, 60.0)], cfg) == 1.0
    # one stray reading near the robot does not undo the stretch of a far scan
    assert distance_scale(np.r_[0.5, np.full(99, 27.0)], cfg) == pytest.approx(6.0, rel=1e-12)
    # never below 1, 1 when fixed and for a scan without valid readings
    assert distance_scale(np.full(10, 2.0), cfg) == 1.0
    assert distance_scale(np.full(10, 40.0), _fuzzy(distance_scale="fixed")) == 1.0
    assert distance_scale(np.zeros(0), cfg) == 1.0


def test_quantile_and_reference_are_used() -> None:
    r = np.arange(1.0, 101.0)  # 1..100 m: the q-quantile is 1 + 99 q
    cfg = _fuzzy(distance_scale_quantile=0.9, distance_scale_reference=4.0)
    assert distance_scale(r, cfg) == pytest.approx((1.0 + 99.0 * 0.9) / 4.0, rel=1e-12)
    cfg = _fuzzy(distance_scale_quantile=1.0)
    assert distance_scale(r, cfg) == pytest.approx(100.0 / 4.5, rel=1e-12)


# -- the lines' scale: their own surface, not the nearest clutter --------------------------------
def test_line_scale_is_the_lines_length_by_distance() -> None:
    cfg = FuzzyConfig()
    assert cfg.line_distance_scale == "structure"
    # 12 beams on a small box 4.5 m away, 120 on walls 10 m away: the points' 5th percentile
    # is the box (scale 1), but the box is 54 of the lines' 1,254 beam-metres (4 %)
    r = np.r_[np.full(12, 4.5), np.full(120, 10.0)]
    assert distance_scale(r, cfg) == 1.0
    assert line_distance_scale(r, 1.0, cfg) == pytest.approx(10.0 / 4.5, rel=1e-12)
    # never below the points' scale; indoors (every line within the reference) it stays 1
    assert line_distance_scale(np.full(50, 18.0), 5.0, cfg) == 5.0
    assert line_distance_scale(np.full(50, 3.0), 1.0, cfg) == 1.0
    assert line_distance_scale(np.zeros(0), 1.5, cfg) == 1.5
    # "points" and "fixed" keep the points' scale
    assert line_distance_scale(r, 1.0, _fuzzy(line_distance_scale="points")) == 1.0
    assert line_distance_scale(r, 1.0, _fuzzy(distance_scale="fixed")) == 1.0


def test_line_scale_loads_and_rejects_unknown_values() -> None:
    cfg = _load('[fuzzy]\nline_distance_scale = "points"\n')
    assert cfg.fuzzy.line_distance_scale == "points"
    with pytest.raises(ConfigError, match="line_distance_scale"):
        _load('[fuzzy]\nline_distance_scale = "walls"\n')


# -- far structure: the default grades it, "fixed" calls every point all-uncertain ------------
@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_far_points_are_graded_by_default_and_all_uncertain_when_fixed(noise: float) -> None:
    scan = _hall_scan(noise)
    ranges = np.asarray(scan.ranges)[scan.valid]
    assert ranges.min() > 10.0  # the premise: every reading beyond the sets' 8 m
    fixed = extract_features(scan, FIXED)
    assert fixed.distance_scale == 1.0
    np.testing.assert_array_equal(fixed.uncertainty, 1.0)  # Table 1's GB row: "BBB"
    f = extract_features(scan)
    assert f.distance_scale == pytest.approx(np.quantile(ranges, 0.05) / 4.5, rel=1e-12)
    assert f.distance_scale > 2.5
    u = f.uncertainty
    assert u.max() <= 1.0 and u.min() < 0.6
    # graded by distance: the nearer half of the scan more certain than the farther half
    near = f.ranges < np.median(f.ranges)
    assert u[near].mean() < u[~near].mean() - 0.2
    assert (f.lines.uncertainty < fixed.lines.uncertainty - 0.05).any()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_virtual_point_between_far_lines_survives(seed: int) -> None:
    scan = _hall_scan(0.01, seed)  # a SICK's 1 cm
    f = extract_features(scan)
    xy = f.virtual_points.xy
    hit = np.hypot(xy[:, 0] - VIRTUAL_XY[0], xy[:, 1] - VIRTUAL_XY[1]) < 0.1
    assert hit.sum() == 1
    assert f.virtual_points.uncertainty[hit][0] <= Config().virtual_points.max_uncertainty
    # with SPEC's fixed sets its d_v (4 m) grades it "GB" and its lines are uncertain: dropped
    g = extract_features(scan, FIXED).virtual_points.xy
    assert not (np.hypot(g[:, 0] - VIRTUAL_XY[0], g[:, 1] - VIRTUAL_XY[1]) < 0.1).any()


def _two_lines(d_v: float) -> Lines:
    """Two certain lines y = 0 (x ∈ [d_v − 1, d_v + 1]) and x = 0 (y ∈ [d_v − 1, d_v + 1]):
    they meet at the origin, d_v from both centres."""
    normal = np.array([[0.0, 1.0], [1.0, 0.0]])
    start = np.array([[d_v - 1.0, 0.0], [0.0, d_v - 1.0]])
    end = np.array([[d_v + 1.0, 0.0], [0.0, d_v + 1.0]])
    z = np.zeros(2)
    i = np.arange(2)
    return Lines(normal, z, start, end, 0.5 * (start + end), i + 10, z, z, z, i, i)


def test_the_virtual_distance_limit_scales() -> None:
    cfg = Config()
    lines = _two_lines(12.0)  # d_v = 12 m: beyond the 8 m limit
    pts, _, _, dv = virtual_candidates(lines, cfg)
    assert pts.shape == (0, 2)
    pts, _, _, dv = virtual_candidates(lines, cfg, scale=1.6)  # limit 12.8 m
    np.testing.assert_allclose(pts, [[0.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(dv, [12.0], rtol=1e-12)
    assert virtual_candidates(lines, cfg, scale=1.49)[0].shape == (0, 2)  # limit 11.92 m


def test_virtual_points_are_graded_on_stretched_distance_sets() -> None:
    # certain lines (f_L = 0): Table 3 lower's column S: d_v GS, S → S; M → S; B → M; GB → B
    cfg = Config()
    bases = rule_bases(cfg.fuzzy)
    lines = _two_lines(6.0)  # d_v = 6 m: past the fixed sets' 4 m, so "GB": dropped
    fp, _, _ = virtual_angular_points(lines, bases, cfg)
    assert len(fp) == 0
    fp, _, dv = virtual_angular_points(lines, bases, cfg, scale=3.0)  # 6 m / 3 = 2 m: "M" → S
    assert len(fp) == 1 and fp.uncertainty[0] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(dv, [6.0])


# -- indoors nothing changes -----------------------------------------------------------------
@pytest.mark.parametrize("world", ["rectangular_room", "office"])
def test_an_indoor_scan_keeps_todays_uncertainties_exactly(world: str) -> None:
    w = sim.world_by_name(world)
    scan = sim.simulate_scan(w, Pose2D(0.3, -0.2, 0.4), _sick(0.01), np.random.default_rng(3))
    ranges = np.asarray(scan.ranges)[scan.valid]
    assert np.quantile(ranges, 0.05) < 4.5  # the premise: walls a few metres away
    f, g = extract_features(scan), extract_features(scan, FIXED)
    assert f.distance_scale == 1.0
    np.testing.assert_array_equal(f.uncertainty, g.uncertainty)
    np.testing.assert_array_equal(f.lines.uncertainty, g.lines.uncertainty)
    np.testing.assert_array_equal(f.virtual_points.xy, g.virtual_points.xy)
    np.testing.assert_array_equal(f.virtual_points.uncertainty, g.virtual_points.uncertainty)
    np.testing.assert_array_equal(f.points_of_interest.xy, g.points_of_interest.xy)
    np.testing.assert_array_equal(
        f.points_of_interest.uncertainty, g.points_of_interest.uncertainty
    )


def test_scale_one_is_the_unscaled_grade() -> None:
    bases = rule_bases(FuzzyConfig())
    rho = np.linspace(0.0, 12.0, 97)
    beta = np.linspace(0.0, math.pi / 2, 97)
    np.testing.assert_array_equal(
        point_uncertainty(rho, beta, bases, 1.0), point_uncertainty(rho, beta, bases)
    )


# -- ρ / s on the sets is the sets stretched by s -------------------------------------------
def _stretched(sets: tuple[tuple[float, float, float], ...], s: float) -> tuple:
    return tuple(tuple(s * v for v in t) for t in sets)


@given(
    s=st.floats(1.0, 25.0),
    rho=st.lists(st.floats(0.0, 300.0), min_size=1, max_size=20),
    beta_frac=st.floats(0.0, 1.0),
    mode=st.sampled_from(["product", "mamdani"]),
)
def test_scaling_rho_is_scaling_the_distance_sets(
    s: float, rho: list[float], beta_frac: float, mode: str
) -> None:
    cfg = _fuzzy(inference=mode, mamdani_resolution=201)
    scaled = replace(cfg, distance_sets=_stretched(cfg.distance_sets, s))
    r = np.asarray(rho)
    beta = np.full(r.shape, beta_frac * math.pi / 2)
    want = point_rule_base(scaled)(r, beta)
    np.testing.assert_allclose(point_rule_base(cfg)(r / s, beta), want, rtol=0, atol=1e-9)


@given(
    s=st.floats(1.0, 25.0),
    dv=st.lists(st.floats(0.0, 150.0), min_size=1, max_size=20),
    f1=st.floats(0.0, 1.0),
    f2=st.floats(0.0, 1.0),
    mode=st.sampled_from(["product", "mamdani"]),
)
def test_scaling_dv_is_scaling_the_virtual_distance_sets(
    s: float, dv: list[float], f1: float, f2: float, mode: str
) -> None:
    cfg = _fuzzy(inference=mode, mamdani_resolution=201)
    scaled = replace(cfg, virtual_distance_sets=_stretched(cfg.virtual_distance_sets, s))
    d = np.asarray(dv)
    a, b = np.full(d.shape, f1), np.full(d.shape, f2)
    want = virtual_point_rule_base(scaled)(a, b, d)
    np.testing.assert_allclose(virtual_point_rule_base(cfg)(a, b, d / s), want, rtol=0, atol=1e-9)


def test_a_stretch_of_asymmetric_sets_is_equivalent_too() -> None:
    # the equivalence does not need a partition: any triangles, stretched about 0
    sets = ((0.5, 0.5, 3.0), (0.5, 3.0, 4.0), (3.0, 4.5, 7.0), (4.0, 7.0, 9.0), (7.0, 9.5, 9.5))
    cfg = _fuzzy(distance_sets=sets)
    scaled = replace(cfg, distance_sets=_stretched(sets, 3.7))
    r = np.linspace(0.0, 50.0, 501)
    beta = np.linspace(0.1, 1.5, 501)
    np.testing.assert_allclose(
        point_rule_base(cfg)(r / 3.7, beta), point_rule_base(scaled)(r, beta), atol=1e-12
    )


# -- configuration ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ('[fuzzy]\ndistance_scale = "range_max"\n', r"fuzzy\.distance_scale"),
        ("[fuzzy]\ndistance_scale_quantile = 0\n", r"fuzzy\.distance_scale_quantile"),
        ("[fuzzy]\ndistance_scale_quantile = 1.5\n", r"fuzzy\.distance_scale_quantile"),
        ("[fuzzy]\ndistance_scale_reference = 0\n", r"fuzzy\.distance_scale_reference"),
        ("[fuzzy]\ndistance_scale_reference = -8\n", r"fuzzy\.distance_scale_reference"),
        ('[fuzzy]\ndistance_scale_reference = "8 m"\n', r"fuzzy\.distance_scale_reference"),
    ],
)
def test_invalid_settings_are_config_errors(text: str, needle: str) -> None:
    with pytest.raises(ConfigError, match=needle):
        _load(text)


def test_settings_round_trip_and_apply() -> None:
    text = (
        '[fuzzy]\ndistance_scale = "fixed"\ndistance_scale_quantile = 0.9\n'
        "distance_scale_reference = 6\n"
    )
    cfg = _load(text)
    assert cfg.fuzzy.distance_scale == "fixed"
    assert cfg.fuzzy.distance_scale_quantile == 0.9
    assert cfg.fuzzy.distance_scale_reference == 6.0
    assert _load(cfg.to_toml()) == cfg
    with pytest.raises(ConfigError, match=r"fuzzy\.distance_scale_quantile"):
        FuzzyConfig(distance_scale_quantile=0.0)
