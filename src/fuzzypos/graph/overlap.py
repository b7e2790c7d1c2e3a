"""What part of a scan a submap saw: the share of a loop closure's scan that could pair with
the submap at all (``[loop_closure]``'s ``min_inlier_fraction`` is asked of that share).

A keyframe's scan sees the space in front of its returns, out to them along each beam: a
point of another scan placed at the fit's pose lies in that seen space where, in the
keyframe's frame, some beam of the keyframe's within ``beam_tolerance`` beam spacings of the
point's bearing returned at a range no shorter than the point's less ``margin``. Such a point
either lies on a surface the keyframe saw (it pairs, where the match is true) or in space the
keyframe saw empty (a false match, or something that moved). A point beyond every submap
keyframe's returns, behind what they saw or in a direction none of them looked, can pair with
nothing whether the match is true or not: in a large hall seen from a viewpoint metres away,
with a scanner reaching tens of metres, that is half of a true closure's scan, where in an
office most of a scan lies within the walls the submap saw."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ..geometry import relative, transform_points

__all__ = ["seen_fraction", "seen_mask"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def seen_mask(
    points: FloatArray,
    views: Sequence[tuple[FloatArray, FloatArray]],
    margin: float,
    beam_tolerance: float = 1.5,
) -> BoolArray:
    """Which of ``points`` ``(n, 2)`` (in some frame) lie in the space seen by one of
    ``views``: ``(pose, scan)``, a keyframe's pose in that frame and its scan's points
    ``(m, 2)`` in its own frame, one a beam (module docstring). A point is seen where a
    beam of the view within ``beam_tolerance`` beam spacings of its bearing returned at least
    as far as the point's range less ``margin`` (m)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    seen = np.zeros(pts.shape[0], dtype=bool)
    for pose, own in views:
        if own.shape[0] < 2:
            continue
        bearing = np.arctan2(own[:, 1], own[:, 0])
        order = np.argsort(bearing, kind="stable")
        bearing, reach = bearing[order], np.hypot(own[order, 0], own[order, 1])
        steps = np.diff(bearing)
        spacing = float(np.median(steps[steps > 0])) if np.any(steps > 0) else math.radians(1)
        local = transform_points(relative(np.asarray(pose, dtype=float), np.zeros(3)), pts)
        b = np.arctan2(local[:, 1], local[:, 0])
        r = np.hypot(local[:, 0], local[:, 1])
        k = np.searchsorted(bearing, b)
        best = np.full(pts.shape[0], -np.inf)
        for idx in (np.clip(k - 1, 0, len(bearing) - 1), np.clip(k, 0, len(bearing) - 1)):
            near = np.abs(np.remainder(b - bearing[idx] + math.pi, math.tau) - math.pi)
            ok = near <= beam_tolerance * spacing
            best = np.where(ok, np.maximum(best, reach[idx]), best)
        seen |= r <= best + margin
    return seen


def seen_fraction(
    points: FloatArray,
    views: Sequence[tuple[FloatArray, FloatArray]],
    margin: float,
    beam_tolerance: float = 1.5,
) -> float:
    """The fraction of ``points`` in the space ``views`` saw (:func:`seen_mask`); 0 for no
    points."""
    if len(points) == 0:
        return 0.0
    return float(np.mean(seen_mask(points, views, margin, beam_tolerance)))
