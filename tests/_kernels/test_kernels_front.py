"""The compiled front of feature extraction against its references: the beams' directions
computed once per scanner, eq. 4's bilinear interpolation to the bit of the numpy reference,
the lines' distance scale and the features the one compiled call leaves packed (taken out on
first use, each the staged chain's)."""

from __future__ import annotations

import copy
import dataclasses
import math
import pickle
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzypos import sim
from fuzzypos._kernels import packing
from fuzzypos.config import Config
from fuzzypos.features import extract as features_module
from fuzzypos.features import rule_bases
from fuzzypos.features import segmentation as seg
from fuzzypos.geometry import Pose2D
from fuzzypos.scan import LaserScan
from helpers import both, compiled_and_staged
from oracles import features as features_oracle

CFG = Config()
TOL = 1e-9
BUDGET = settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.filter_too_much]
)
WORLD = sim.office()
poses = st.tuples(st.floats(-9.0, 9.0), st.floats(-1.0, 1.0), st.floats(-math.pi, math.pi))


def scan_at(pose: tuple[float, float, float], seed: int, beams: int = 180) -> Any:
    model = sim.ScannerModel(
        n_beams=beams,
        field_of_view_deg=360.0 if beams == 360 else 180.0,
        angle_min_deg=-180.0 if beams == 360 else -90.0,
        range_max=8.0,
        range_noise_std=0.01,
    )
    return sim.simulate_scan(WORLD, Pose2D(*pose), model, rng=np.random.default_rng(seed))


def _front() -> Any:
    from fuzzypos._kernels import front

    return front


# -- the beams' directions ---------------------------------------------------------------------
@BUDGET
@given(
    angle_min=st.floats(-math.pi, math.pi),
    increment=st.floats(1e-3, 0.05) | st.floats(-0.05, -1e-3),
    n=st.integers(1, 120),
)
def test_the_beams_directions_are_the_cosines_and_sines_of_their_bearings(
    angle_min, increment, n
) -> None:
    """``beam_directions``: cos and sin of each bearing (libm's, as numba computes them; numpy's
    may differ in the last bit); and the ones of the scan's own bearings where the cache hands
    back the last scanner's."""
    scan = LaserScan(np.full(n, 2.0), angle_min, increment)
    table = packing.scanner(scan)[0]
    assert table.shape == (2, n)
    np.testing.assert_allclose(table[0], np.cos(scan.angles), rtol=0, atol=1e-15)
    np.testing.assert_allclose(table[1], np.sin(scan.angles), rtol=0, atol=1e-15)
    np.testing.assert_array_equal(table, _front().beam_directions(scan.angles))
    again, closed = packing.scanner(LaserScan(np.full(n, 3.0), angle_min, increment))
    assert again is table  # the same scanner: computed once
    assert closed == scan.is_full_circle


def test_the_beams_directions_follow_the_scanner() -> None:
    """Another bearing, increment, beam count or the sign of a zero ``angle_min`` (which a
    clockwise scan's bearings keep: sin(−0) = −0) is another table, and whether it closes a
    turn is the scan's."""
    base = LaserScan(np.full(181, 2.0), 0.0, -0.01)
    for other in (
        LaserScan(np.full(181, 2.0), -0.0, -0.01),
        LaserScan(np.full(181, 2.0), 0.001, -0.01),
        LaserScan(np.full(181, 2.0), 0.0, -0.011),
        LaserScan(np.full(180, 2.0), 0.0, -0.01),
        LaserScan(np.full(360, 2.0), 0.0, -math.tau / 360),  # (a full turn: closed)
    ):
        first = packing.scanner(base)[0]
        table, closed = packing.scanner(other)
        assert closed == other.is_full_circle
        assert table is not first
        expected = _front().beam_directions(other.angles)
        assert table.tobytes() == expected.tobytes()  # (signed zeros too)
    zero = packing.scanner(LaserScan(np.full(3, 2.0), -0.0, -0.01))[0]
    assert math.copysign(1.0, zero[1, 0]) == -1.0


def test_an_interlaced_scanners_two_geometries_are_each_computed_once() -> None:
    """An interlaced scanner alternates between two ``angle_min`` (a quarter of a degree
    apart): each one's table is computed once and handed back on its every scan, as long as
    no more than ``SCANNER_GEOMETRIES`` scanners come between."""
    inc = math.radians(1.0)
    a = LaserScan(np.full(181, 2.0), -math.pi / 2, inc)
    b = LaserScan(np.full(181, 2.0), -math.pi / 2 + inc / 4, inc)
    ta, tb = packing.scanner(a)[0], packing.scanner(b)[0]
    assert ta is not tb
    for _ in range(3):
        assert packing.scanner(a)[0] is ta and packing.scanner(b)[0] is tb
    np.testing.assert_array_equal(tb, _front().beam_directions(b.angles))
    for k in range(packing.SCANNER_GEOMETRIES):  # others in between: the oldest is dropped
        packing.scanner(LaserScan(np.full(10 + k, 2.0), 0.0, inc))
    again = packing.scanner(a)[0]
    assert again is not ta
    assert again.tobytes() == ta.tobytes()


@BUDGET
@given(pose=poses, seed=st.integers(0, 1000), offset=st.booleans(), clockwise=st.booleans())
def test_the_usable_points_are_the_numpy_ones(pose, seed, offset, clockwise) -> None:
    """``usable_points`` (from the beams' directions and the sensor's pose as three numbers)
    against the oracle's ``_valid_points`` in numpy."""
    scan = scan_at(pose, seed)
    if clockwise:
        ranges = np.asarray(scan.ranges)
        scan = dataclasses.replace(
            scan,
            ranges=ranges[::-1].copy(),
            angle_min=scan.angle_min + (ranges.shape[0] - 1) * scan.angle_increment,
            angle_increment=-scan.angle_increment,
        )
    if offset:
        scan = dataclasses.replace(scan, sensor_pose=Pose2D(0.12, -0.03, 0.05))
    lo, hi = seg._band_bounds_of(CFG.scanner)
    sp = scan.sensor_pose
    got = _front().usable_points(
        scan.ranges, packing.scanner(scan)[0], scan.valid, lo, hi,
        scan.angle_increment, sp.x, sp.y, sp.theta,
    )  # fmt: skip
    reference = features_oracle._valid_points(scan, CFG.scanner.no_return_bands)
    np.testing.assert_array_equal(got[0], reference[0])
    for x, y in zip(got[1:], reference[1:]):
        np.testing.assert_allclose(x, y, rtol=0, atol=TOL)


# -- eq. 4's bilinear interpolation ------------------------------------------------------------
@BUDGET
@given(
    pairs=st.lists(
        st.tuples(
            st.floats(-1.0, 40.0) | st.sampled_from([math.nan, math.inf, -math.inf]),
            st.floats(-1.0, 3.0) | st.sampled_from([math.nan, math.inf, -math.inf]),
        ),
        max_size=40,
    ),
    which=st.sampled_from(["points", "lines"]),
    peaks=st.booleans(),
)
def test_the_bilinear_interpolation_is_the_numpy_reference_to_the_bit(pairs, which, peaks) -> None:
    """The compiled interpolation (the sets with a membership only, np.interp's slopes once
    per call) gives the numpy reference's values to the bit: off the grids, on their peaks,
    past their ends, at infinities and NaN."""
    base = getattr(rule_bases(CFG.fuzzy), which)
    assert base._grids is not None
    g1, g2 = base._grids
    x1 = np.array([p[0] for p in pairs], dtype=np.float64)
    x2 = np.array([p[1] for p in pairs], dtype=np.float64)
    if peaks:  # every pair of peaks, where np.interp takes a value as it is
        a, b = np.meshgrid(g1, g2)
        x1, x2 = np.concatenate([x1, a.ravel()]), np.concatenate([x2, b.ravel()])
    compiled, reference = both(lambda: base(x1, x2))
    np.testing.assert_array_equal(compiled, reference)
    assert compiled.tobytes() == reference.tobytes()  # (NaN and the sign of a zero too)


def test_the_slopes_are_np_interps() -> None:
    """``slopes``: the rise of each consequent column over each step of the first grid, and
    the inverse steps of the second."""
    base = rule_bases(CFG.fuzzy).points
    g1, g2 = base._grids
    table = base._table
    s1, inverse = _fuzzy().slopes(g1, g2, table)
    np.testing.assert_array_equal(s1[:-1], np.diff(table, axis=0) / np.diff(g1)[:, None])
    np.testing.assert_array_equal(inverse[:-1], 1.0 / np.diff(g2))


def _fuzzy() -> Any:
    from fuzzypos._kernels import fuzzy

    return fuzzy


# -- the lines' distance scale -----------------------------------------------------------------
@BUDGET
@given(
    ranges=st.lists(st.floats(0.05, 60.0), max_size=300),
    point_scale=st.floats(1.0, 4.0),
    quantile=st.floats(0.05, 0.95),
)
def test_the_lines_distance_scale_is_the_numpy_one(ranges, point_scale, quantile) -> None:
    """``line_distance_scale`` (sorting only where the quantile may pass the reference's
    stretch) against the oracle's ``line_distance_scale``: the point scale itself where no
    line point is beyond the stretch or the quantile is short of it."""
    fz = dataclasses.replace(CFG.fuzzy, distance_scale_quantile=quantile)
    r = np.array(ranges, dtype=np.float64)
    got = _front().line_distance_scale(
        r, point_scale, fz.distance_scale_reference, fz.distance_scale_quantile
    )
    expected = features_oracle.line_distance_scale(r, point_scale, fz)
    assert got == pytest.approx(expected, rel=1e-12)
    if r.size == 0 or r.max() <= fz.distance_scale_reference * point_scale:
        assert got == point_scale
    if expected == point_scale:  # (the numpy quantile short of the stretch)
        assert got == point_scale


@BUDGET
@given(
    values=st.lists(st.floats(-1e3, 1e3) | st.sampled_from([0.0, -0.0, 1.0, math.inf]),
                    max_size=300),
    shape=st.sampled_from(["as drawn", "sorted", "reversed", "waves"]),
)  # fmt: skip
def test_the_sort_is_numpys(values, shape) -> None:
    """``_sorted`` (a natural merge sort) is ``np.sort``, on values as drawn, sorted, reversed
    and in rising and falling runs as a scan's ranges along walls are."""
    x = np.array(values, dtype=np.float64)
    if shape == "sorted":
        x = np.sort(x)
    elif shape == "reversed":
        x = np.sort(x)[::-1].copy()
    elif shape == "waves":
        x = np.abs(np.sin(0.1 * np.arange(x.shape[0]))) * 10.0 + x * 1e-3
    got = _front()._sorted(x)
    assert got.shape == x.shape
    np.testing.assert_array_equal(got, np.sort(x))  # (−0 and 0 in either order)


# -- the packed features -----------------------------------------------------------------------
def _fields(obj: Any) -> list[str]:
    return [f.name for f in dataclasses.fields(obj)]


def _assert_same(x: Any, y: Any, name: str) -> None:
    if isinstance(x, np.ndarray):
        assert isinstance(y, np.ndarray), name
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert x.tobytes() == y.tobytes(), name
    elif isinstance(x, float | int):
        assert x == y, name
    elif x is None:
        assert y is None, name


@BUDGET
@given(pose=poses, seed=st.integers(0, 1000), beams=st.sampled_from([180, 360]))
def test_the_packed_features_are_the_staged_ones(pose, seed, beams) -> None:
    """The one compiled call's features (views of its three packed arrays, most taken out on
    first use) against the staged chain's, field by field to the bit, the lines' lengths
    (the call's own, for line matching) and normals' angles, and their point features too."""
    scan = scan_at(pose, seed, beams)
    packed, staged = compiled_and_staged(scan, CFG)
    assert "_packed" in vars(packed) and "kept_index" not in vars(packed)  # (not yet taken)
    for f, g in ((packed, staged), (packed.lines, staged.lines)):
        for name in _fields(f):
            _assert_same(getattr(f, name), getattr(g, name), name)
    assert "length" in vars(packed.lines)  # (the call's, not the cached property's)
    for name in ("length", "normal_angle"):
        _assert_same(getattr(packed.lines, name), getattr(staged.lines, name), name)
    for name in _fields(packed._corners):
        _assert_same(getattr(packed._corners, name), getattr(staged._corners, name), name)
    for kind in ("angular_points", "virtual_points", "break_points", "points_of_interest"):
        for part in ("xy", "uncertainty", "kind"):
            x, y = getattr(getattr(packed, kind), part), getattr(getattr(staged, kind), part)
            _assert_same(x, y, f"{kind}.{part}")
    _assert_same(packed.virtual_lines, staged.virtual_lines, "virtual_lines")


def test_packed_features_copy_pickle_and_refuse_unknown_names() -> None:
    """The packed features are plain dataclass instances to the rest of the code: a copy, a
    pickled round trip and ``dataclasses.replace`` keep every field, an unknown name is an
    AttributeError (and ``hasattr`` False), and the arrays taken out are kept."""
    scan = scan_at((0.5, 0.2, 0.3), 3)
    f = features_module._extract_compiled(scan, rule_bases(CFG.fuzzy), CFG)
    assert f is not None and len(f.lines) > 0
    assert f.kept_index is f.kept_index  # taken out once
    for other in (copy.copy(f), pickle.loads(pickle.dumps(f)), dataclasses.replace(f)):
        for name in _fields(f):
            _assert_same(getattr(other, name), getattr(f, name), name)
        for name in _fields(f.lines):
            _assert_same(getattr(other.lines, name), getattr(f.lines, name), name)
    with pytest.raises(AttributeError, match="no_such_field"):
        _ = f.no_such_field  # type: ignore[attr-defined]
    assert not hasattr(f.lines, "no_such_field")
    assert not hasattr(f._corners, "kept_index")  # (another class's field)


def test_a_scan_without_lines_has_the_empty_lines() -> None:
    """A few scattered readings: no line, the empty lines (without variances) as the staged
    chain's."""
    scan = scan_at((0.0, 0.0, 0.0), 1)
    ranges = np.full(np.asarray(scan.ranges).shape, np.inf)
    ranges[::40] = 2.0
    sparse = dataclasses.replace(scan, ranges=ranges)
    f = features_module._extract_compiled(sparse, rule_bases(CFG.fuzzy), CFG)
    assert f is not None and len(f.lines) == 0 and f.lines.angle_variance is None
    assert f.lines.normal.shape == (0, 2) and f.kept_index.shape == f.cluster.shape


# -- the chain's settings in one array ----------------------------------------------------------
def _floats(n: int) -> st.SearchStrategy[np.ndarray]:
    return st.lists(st.floats(-1e3, 1e3), min_size=n, max_size=n).map(np.array)


@st.composite
def _tables(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    rows, cols, n2 = draw(st.integers(1, 6)), draw(st.integers(1, 6)), draw(st.integers(1, 6))
    table = draw(_floats(rows * cols)).reshape(rows, cols)
    return draw(_floats(rows)), draw(_floats(n2)), table, draw(st.floats()), draw(st.floats())


@BUDGET
@given(
    bands=st.integers(0, 3).flatmap(lambda k: st.tuples(_floats(k), _floats(k))),
    front=_floats(12),
    line=_floats(6),
    sine=st.floats(-1.0, 1.0),
    point_tables=_tables(),
    line_tables=_tables(),
)
def test_the_chains_settings_are_taken_apart_as_they_were_put_together(
    bands, front, line, sine, point_tables, line_tables
) -> None:
    """``packing.chain_settings`` and ``_kernels.front.settings_of``: every array and number
    back, to the bit and in its shape (NaN bounds included)."""
    settings = packing.chain_settings(
        bands[0], bands[1], front, line, sine, point_tables, line_tables
    )
    got = _front().settings_of(settings)
    want = (bands[0], bands[1], front, line, sine, point_tables, line_tables)
    for x, y in zip(got, want, strict=True):
        for a, b in zip(x, y, strict=True) if isinstance(x, tuple) else ((x, y),):
            assert np.shape(a) == np.shape(b)
            assert np.asarray(a, dtype=np.float64).tobytes() == np.asarray(b).tobytes()


# -- eq. 14's interior angles ------------------------------------------------------------------
@BUDGET
@given(
    arms=st.lists(
        st.tuples(st.floats(-10.0, 10.0), st.floats(-10.0, 10.0), st.booleans()),
        min_size=1,
        max_size=40,
    ),
    threshold=st.floats(0.01, math.pi - 0.01),
    near=st.booleans(),
)
def test_the_interior_angles_are_atan2s_where_within_the_threshold(arms, threshold, near):
    """Each angle is |atan2(cross, dot)| to the bit where the point is inside its cluster and
    the angle within the threshold (or close to it); π outside, or where atan2's angle is
    wider than the threshold (``near``: arms at the threshold's angle itself, to the last
    bits)."""
    if near:  # arms at the threshold (give or take a few ulps): the exact path
        arms = [(r * math.sin(threshold + e), r * math.cos(threshold + e), True)
                for (r, e) in ((abs(c) + 0.1, d * 1e-15) for c, d, _ in arms)]  # fmt: skip
    cross = np.array([a[0] for a in arms])
    dot = np.array([a[1] for a in arms])
    inside = np.array([a[2] for a in arms])
    got = _front().interior_angles(cross, dot, inside, threshold)
    for c, d, i, g in zip(cross, dot, inside, got, strict=True):
        exact = abs(math.atan2(c, d))  # (libm's, as the kernel's)
        if not i:
            assert g == math.pi
        elif g != exact:
            assert g == math.pi and exact > threshold
        if i and exact <= threshold:
            assert g == exact
