"""The localisation kernels (``fuzzypos._kernels.localize``) against their numpy references
(``tests/oracles/localization.py``) on random maps, scans and poses; the branch and bound
against the exhaustive search; the fit against known geometry."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzypos._kernels.localize import branch_and_bound, fit, likelihood
from fuzzypos.config import Config
from fuzzypos.io.occupancy_map import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from fuzzypos.localization.field import compute_field, field_of
from fuzzypos.localization.search import GlobalSearch
from oracles import localization as oracle

BUDGET = settings(max_examples=40, deadline=None)
CFG = Config().localization


def random_map(seed: int, shape: tuple[int, int] = (60, 70)) -> OccupancyMap:
    """A box room with random blocks and a few unknown cells, 5 cm cells."""
    rng = np.random.default_rng(seed)
    cells = np.full(shape, FREE, dtype=np.int8)
    cells[[0, -1], :] = OCCUPIED
    cells[:, [0, -1]] = OCCUPIED
    for _ in range(rng.integers(1, 6)):
        r, c = rng.integers(2, shape[0] - 8), rng.integers(2, shape[1] - 8)
        cells[r : r + rng.integers(1, 6), c : c + rng.integers(1, 6)] = OCCUPIED
    cells[rng.random(shape) < 0.02] = UNKNOWN
    return OccupancyMap(cells, 0.05, (rng.normal(), rng.normal(), 0.0))


def scan_points(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    a = rng.uniform(-math.pi, math.pi, n)
    r = rng.uniform(0.2, 2.0, n)
    return np.ascontiguousarray(np.column_stack((r * np.cos(a), r * np.sin(a))))


@BUDGET
@given(
    seed=st.integers(0, 2**31),
    n=st.integers(1, 80),
    x=st.floats(-0.5, 4.0),
    y=st.floats(-0.5, 3.5),
    th=st.floats(-4, 4),
)
def test_likelihood_is_the_oracles(seed: int, n: int, x: float, y: float, th: float) -> None:
    field = field_of(random_map(seed), CFG).walls
    pts = scan_points(seed + 1, n)
    pose = np.array([x, y, th])
    got = likelihood(pts, pose, field, 0.1, 0.2)
    want = oracle.likelihood(pts, pose, field, 0.1, 0.2)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)


@BUDGET
@given(
    seed=st.integers(0, 2**31),
    n=st.integers(8, 120),
    x=st.floats(0.8, 2.5),
    y=st.floats(0.8, 2.0),
    th=st.floats(-3, 3),
)
def test_the_fit_is_the_oracles(seed: int, n: int, x: float, y: float, th: float) -> None:
    field = field_of(random_map(seed), CFG).walls
    pts = scan_points(seed + 2, n)
    start = np.array([x, y, th])
    info = np.diag([100.0, 100.0, 30.0])
    settings_ = np.array([0.5, 0.05, 8.0])
    got = fit(pts, start, start, info, field, settings_)
    want = oracle.fit(pts, start, start, info, field, settings_)
    assert got[4:] == want[4:]
    np.testing.assert_allclose(got[0], want[0], atol=1e-7)
    np.testing.assert_allclose(got[1], want[1], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(got[2:4], want[2:4], rtol=1e-6, atol=1e-9)


def test_the_fit_finds_a_known_pose_in_a_box() -> None:
    """A 3 m × 2 m box seen from a known pose: the fit from 10 cm and 3° off lands on it."""
    cells = np.full((50, 70), UNKNOWN, dtype=np.int8)
    cells[5:45, 5:65] = FREE
    cells[5, 5:65] = cells[44, 5:65] = OCCUPIED
    cells[5:45, 5] = cells[5:45, 64] = OCCUPIED
    m = OccupancyMap(cells, 0.05, (0.0, 0.0, 0.0))
    field = field_of(m, CFG).walls
    truth = np.array([1.3, 1.1, 0.4])
    walls = np.concatenate(
        [
            np.column_stack((np.linspace(0.3, 3.2, 60), np.full(60, 0.275))),
            np.column_stack((np.linspace(0.3, 3.2, 60), np.full(60, 2.225))),
            np.column_stack((np.full(40, 0.275), np.linspace(0.3, 2.2, 40))),
            np.column_stack((np.full(40, 3.225), np.linspace(0.3, 2.2, 40))),
        ]
    )
    c, s = math.cos(truth[2]), math.sin(truth[2])
    local = (walls - truth[:2]) @ np.array([[c, -s], [s, c]])
    start = truth + np.array([0.1, -0.07, math.radians(3.0)])
    pose, *_, status = fit(
        np.ascontiguousarray(local),
        start,
        start,
        np.eye(3) * 1e-6,
        field,
        np.array([0.5, 0.05, 20.0]),
    )
    assert status == 0
    np.testing.assert_allclose(pose, truth, atol=2e-3)


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    n=st.integers(5, 30),
    ratio=st.floats(0.3, 1.0),
    min_score=st.floats(0.05, 0.6),
)
def test_branch_and_bound_is_the_exhaustive_search(
    seed: int, n: int, ratio: float, min_score: float
) -> None:
    m = random_map(seed, (40, 48))
    search = GlobalSearch(field_of(m, CFG), CFG)
    grids, cell = search.grids()
    _, rows, cols = grids.score.shape
    rng = np.random.default_rng(seed)
    angles = np.linspace(-math.pi, math.pi, 7, endpoint=False)
    pts = scan_points(seed + 3, n)
    x = np.cos(angles)[:, None] * pts[None, :, 0] - np.sin(angles)[:, None] * pts[None, :, 1]
    y = np.sin(angles)[:, None] * pts[None, :, 0] + np.cos(angles)[:, None] * pts[None, :, 1]
    offsets = np.ascontiguousarray(
        np.stack((np.floor(x / cell + 0.5), np.floor(y / cell + 0.5)), -1).astype(np.int64)
    )
    c0, r0 = int(rng.integers(0, cols // 2)), int(rng.integers(0, rows // 2))
    window = np.array([c0, cols, r0, rows, min(3, grids.score.shape[0] - 1)], dtype=np.int64)
    got = branch_and_bound(offsets, grids, window, min_score, ratio, 100_000)
    want = oracle.exhaustive_search(offsets, grids, window, min_score, ratio)
    key = lambda t: sorted(map(tuple, np.round(t, 9)))  # noqa: E731
    assert key(got) == key(want)


def test_the_walls_lie_along_a_straight_wall() -> None:
    """An L of occupied cells: the straight parts' normals are the axes, points on the cells'
    centre line."""
    cells = np.full((30, 30), FREE, dtype=np.int8)
    cells[10, 3:27] = OCCUPIED
    m = OccupancyMap(cells, 0.05, (0.0, 0.0, 0.0))
    arrays = compute_field(m, CFG)
    wall = arrays["wall"]
    mid = wall[5:-5]
    np.testing.assert_allclose(np.abs(mid[:, 3]), 1.0, atol=1e-9)
    np.testing.assert_allclose(mid[:, 1], 10.5 * 0.05, atol=1e-9)
