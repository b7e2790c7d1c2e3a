"""Vectorised ray casting against line-segment worlds.

:func:`cast_rays` casts many rays against every segment at once (beams x segments
broadcasting, in chunks of beams to bound memory): no Python loop per beam.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .world import (
    ENDPOINT_TOL,
    PARALLEL_SIN,
    T_MIN,
    FloatArray,
    SimError,
    World,
    _point_segment_distance,
    _validate_segments,
)

__all__ = ["cast_rays"]

#: Upper bound on the beams x segments elements handled at once by :func:`cast_rays`.
_CHUNK_ELEMENTS = 1 << 20


def _cast_chunk(
    seg: FloatArray, p: FloatArray, d: FloatArray, max_range: float
) -> tuple[FloatArray, NDArray[np.intp]]:
    """Nearest hit of rays ``p + t d`` (``d`` unit, ``(n, 2)``) on segments ``(m, 4)``."""
    ax, ay = seg[None, :, 0], seg[None, :, 1]
    ex, ey = seg[None, :, 2] - seg[None, :, 0], seg[None, :, 3] - seg[None, :, 1]
    elen = np.hypot(ex, ey)
    dx, dy = d[:, 0:1], d[:, 1:2]
    wx, wy = ax - p[:, 0:1], ay - p[:, 1:2]  # segment start relative to the ray origin
    den = dx * ey - dy * ex  # cross(d, e) = |e| sin(angle between ray and segment)
    w_x_e = wx * ey - wy * ex  # cross(w, e)
    w_x_d = wx * dy - wy * dx  # cross(w, d): signed distance of the segment start off the ray
    parallel = np.abs(den) <= PARALLEL_SIN * elen
    safe = np.where(parallel, 1.0, den)
    t = w_x_e / safe
    u = w_x_d / safe
    utol = ENDPOINT_TOL / elen
    hit = ~parallel & (t > T_MIN) & (u >= -utol) & (u <= 1.0 + utol)
    t = np.where(hit, t, np.inf)
    # a ray running along a collinear segment first meets its nearer end ahead of the origin
    collinear = parallel & (np.abs(w_x_d) <= ENDPOINT_TOL)
    if collinear.any():
        ta = wx * dx + wy * dy
        tb = (wx + ex) * dx + (wy + ey) * dy
        ta = np.where(ta > T_MIN, ta, np.inf)
        tb = np.where(tb > T_MIN, tb, np.inf)
        t = np.where(collinear, np.minimum(t, np.minimum(ta, tb)), t)
    idx = np.argmin(t, axis=1)
    best = np.take_along_axis(t, idx[:, None], axis=1)[:, 0]
    miss = ~(best <= max_range)
    best = np.where(miss, np.inf, best)
    idx = np.where(miss, -1, idx)
    return best, idx


def cast_rays(
    world: World | ArrayLike,
    origins: ArrayLike,
    directions: ArrayLike,
    max_range: float = math.inf,
    *,
    return_segment: bool = False,
) -> FloatArray | tuple[FloatArray, NDArray[np.intp]]:
    """Range along each ray to the nearest wall, ``inf`` where none is hit within ``max_range``.

    ``origins`` is ``(2,)`` or ``(n, 2)`` (world frame), ``directions`` the rays' angles ``(n,)``
    (world frame, radians); the two broadcast. ``world`` is a :class:`World` or an ``(m, 4)``
    segment array. Segment endpoints count as hits; hits at ``t <= 1e-9`` are ignored (no
    self-hits); a ray parallel to a segment never hits it, except a ray along a collinear
    segment, which hits its nearer endpoint ahead. With ``return_segment`` also returns the
    index of the segment hit (``-1`` for none). Vectorised over beams x segments, in chunks.
    """
    seg = world.segments if isinstance(world, World) else _validate_segments(world)
    try:
        org = np.asarray(origins, dtype=float)
        ang = np.asarray(directions, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SimError("origins and directions must be numeric") from exc
    if org.shape[-1:] != (2,) or org.ndim > 2:
        raise SimError(f"origins must have shape (2,) or (n, 2), got {org.shape}")
    if ang.ndim > 1:
        raise SimError(f"directions must be angles of shape (n,), got {ang.shape}")
    ang = np.atleast_1d(ang)
    try:
        n = np.broadcast_shapes(org.shape[:-1], ang.shape)
    except ValueError:
        raise SimError(
            f"origins {org.shape} and directions {ang.shape} do not broadcast to one ray per beam"
        ) from None
    single = org.ndim == 1 or org.shape[0] == 1
    org = np.broadcast_to(org, (*n, 2))
    ang = np.broadcast_to(ang, n)
    if not (np.isfinite(org).all() and np.isfinite(ang).all()):
        raise SimError("origins and directions must be finite")
    max_range = float(max_range)
    if not max_range > 0.0:
        raise SimError(f"max_range must be positive, got {max_range}")
    nrays = n[0] if n else 1
    ranges = np.full(nrays, np.inf)
    index = np.full(nrays, -1, dtype=np.intp)
    keep: NDArray[np.intp] | None = None
    if len(seg) and single and math.isfinite(max_range) and org.size:
        # one origin: only walls within max_range of it can be hit (same hits, fewer pairs)
        near = _point_segment_distance(org.reshape(-1, 2)[:1], seg)[0] <= max_range + 1e-9
        if not near.all():
            keep = np.flatnonzero(near)
            seg = seg[keep]
    if len(seg) and nrays:
        d = np.stack([np.cos(ang), np.sin(ang)], axis=-1).reshape(nrays, 2)
        p = org.reshape(nrays, 2)
        step = max(1, _CHUNK_ELEMENTS // len(seg))
        for s in range(0, nrays, step):  # chunks bound memory; each chunk is fully vectorised
            sl = slice(s, s + step)
            ranges[sl], index[sl] = _cast_chunk(seg, p[sl], d[sl], max_range)
        if keep is not None:
            index = np.where(index >= 0, keep[np.maximum(index, 0)], -1)
    if return_segment:
        return ranges, index
    return ranges
