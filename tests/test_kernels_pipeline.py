"""The pipeline's own small kernels (``fuzzypos._kernels.pipeline``) against their numpy
references beside their callers."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzypos._kernels.pipeline import move_surfaces
from fuzzypos.geometry import transform_points
from fuzzypos.matching import SurfacePoints
from fuzzypos.pipeline.local_map import _moved_numpy

coord = st.floats(-50.0, 50.0, allow_nan=False)
angle = st.floats(-math.pi, math.pi, allow_nan=False, exclude_max=True)


def _surface(rng: np.random.Generator, n: int) -> SurfacePoints:
    xy = rng.uniform(-10.0, 10.0, (n, 2))
    a = rng.uniform(-math.pi, math.pi, n)
    return SurfacePoints(xy, np.stack((np.cos(a), np.sin(a)), axis=1), rng.uniform(0, 1, n))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(coord, coord, angle, st.integers(0, 40)), min_size=1, max_size=4),
    st.integers(0, 2**32 - 1),
)
def test_the_moved_surfaces_are_the_numpy_ones(parts_spec, seed) -> None:
    """Every part's points and normals moved by its pose: the kernel gives the numpy
    reference's values (and the points are transform_points')."""
    rng = np.random.default_rng(seed)
    parts = [(_surface(rng, n), np.array([x, y, t])) for x, y, t, n in parts_spec]
    moves = [(x, y, math.cos(t), math.sin(t)) for x, y, t, _ in parts_spec]
    ends = np.cumsum([n for *_, n in parts_spec]).astype(np.int64)
    xy = np.concatenate([s.xy for s, _ in parts])
    normal = np.concatenate([s.normal for s, _ in parts])
    got_xy, got_normal = move_surfaces(xy, normal, np.array(moves), ends)
    want_xy, want_normal = _moved_numpy(parts, moves)
    np.testing.assert_allclose(got_xy, want_xy, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got_normal, want_normal, rtol=0, atol=1e-9)
    by_pose = [transform_points(pose, s.xy) for s, pose in parts]
    np.testing.assert_allclose(want_xy, np.concatenate(by_pose), rtol=0, atol=1e-9)
