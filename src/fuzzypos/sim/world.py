"""Line-segment worlds: :class:`World`, its validation, true corners and distances.

A :class:`World` is a set of wall segments ``[x1, y1, x2, y2]`` in metres (usually built from
polygons, whose vertex lists are kept so the true corners are known). Worlds load from and save
to small TOML or JSON files (:meth:`World.from_file`, :meth:`World.to_file`; the format is in
:mod:`fuzzypos.sim.worldfile`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from .base import FloatArray, SimError, _polygon_segments
from .worldfile import read_world_file, save_world

__all__ = [
    "SimError",
    "World",
    "T_MIN",
    "ENDPOINT_TOL",
    "PARALLEL_SIN",
    "VERTEX_TOL",
]

#: Hits nearer than this along the ray are ignored (no self-hits on the surface a ray starts on).
T_MIN = 1e-9
#: Slack (metres) by which a hit may lie beyond a segment's end and still count (endpoints hit).
ENDPOINT_TOL = 1e-9
#: A ray is treated as parallel to a segment when |sin(angle between them)| is below this.
PARALLEL_SIN = 1e-12
#: Points closer than this (metres) are the same vertex when corners are computed.
VERTEX_TOL = 1e-7


# --------------------------------------------------------------------------------------------
# World
# --------------------------------------------------------------------------------------------


def _readonly(a: FloatArray) -> FloatArray:
    a = np.array(a, dtype=float, copy=True)
    a.setflags(write=False)
    return a


def _validate_segments(segments: ArrayLike, what: str = "segments") -> FloatArray:
    try:
        seg = np.asarray(segments, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SimError(f"{what} must be numeric, got {segments!r}") from exc
    if seg.ndim == 1 and seg.shape == (4,):
        seg = seg[None, :]
    if seg.ndim != 2 or seg.shape[1] != 4:
        raise SimError(f"{what} must have shape (m, 4) as [x1, y1, x2, y2] rows, got {seg.shape}")
    bad = ~np.isfinite(seg).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise SimError(f"{what}: segment {i} has a non-finite coordinate: {seg[i].tolist()}")
    lengths = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    zero = lengths <= 1e-12
    if zero.any():
        i = int(np.flatnonzero(zero)[0])
        raise SimError(f"{what}: segment {i} has zero length: {seg[i].tolist()}")
    return seg


def _validate_polygon(poly: ArrayLike, index: int, closed: bool) -> FloatArray:
    try:
        v = np.asarray(poly, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SimError(f"polygon {index} must be numeric vertices, got {poly!r}") from exc
    if v.ndim != 2 or v.shape[1] != 2:
        raise SimError(f"polygon {index} must have shape (k, 2) vertices, got {v.shape}")
    if not np.isfinite(v).all():
        j = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
        raise SimError(f"polygon {index}: vertex {j} has a non-finite coordinate: {v[j].tolist()}")
    # a closed polygon given with its first vertex repeated at the end: drop the repeat
    if closed and len(v) >= 2 and np.array_equal(v[0], v[-1]):
        v = v[:-1]
    need = 3 if closed else 2
    if len(v) < need:
        kind = "closed" if closed else "open"
        raise SimError(
            f"polygon {index}: a {kind} polygon needs at least {need} vertices, got {len(v)}"
        )
    step = np.diff(np.vstack([v, v[:1]]) if closed else v, axis=0)
    zero = np.hypot(step[:, 0], step[:, 1]) <= 1e-12
    if zero.any():
        j = int(np.flatnonzero(zero)[0])
        raise SimError(
            f"polygon {index}: edge {j} (vertex {j} to {(j + 1) % len(v)}) has zero length "
            f"(repeated vertex {v[j].tolist()})"
        )
    return v


@dataclass(frozen=True, eq=False, repr=False)
class World:
    """A 2D world of wall segments.

    ``segments`` is a read-only ``(m, 4)`` array of ``[x1, y1, x2, y2]`` rows. ``polygons`` keeps
    the vertex lists the world was built from (``closed[i]`` tells whether polygon ``i`` has its
    closing edge); worlds built straight from segments have none. Equality is identity.
    """

    segments: FloatArray
    name: str = "world"
    polygons: tuple[FloatArray, ...] = ()
    closed: tuple[bool, ...] = ()

    def __post_init__(self) -> None:
        seg = _validate_segments(self.segments)
        object.__setattr__(self, "segments", _readonly(seg))
        object.__setattr__(self, "name", str(self.name))
        polys = tuple(self.polygons)
        closed = tuple(bool(c) for c in self.closed)
        if len(closed) != len(polys):
            raise SimError(
                f"closed must give one flag per polygon: {len(polys)} polygons, {len(closed)} flags"
            )
        checked = tuple(
            _readonly(_validate_polygon(p, i, c)) for i, (p, c) in enumerate(zip(polys, closed))
        )
        object.__setattr__(self, "polygons", checked)
        object.__setattr__(self, "closed", closed)

    # ---- constructors ----------------------------------------------------------------------

    @classmethod
    def from_segments(cls, segs: ArrayLike, name: str = "world") -> World:
        """A world of the given ``(m, 4)`` segments ``[x1, y1, x2, y2]``."""
        return cls(_validate_segments(segs), name=name)

    @classmethod
    def from_polygons(
        cls,
        polygons: Iterable[ArrayLike],
        closed: bool | Sequence[bool] = True,
        name: str = "world",
    ) -> World:
        """A world whose walls are the edges of ``polygons`` (each a ``(k, 2)`` vertex list).

        ``closed`` (one flag, or one per polygon) adds the edge from the last vertex back to the
        first; open polygons are polylines (e.g. walls with doorway gaps between pieces).
        """
        polys = list(polygons)
        if isinstance(closed, (bool, np.bool_)):
            flags = [bool(closed)] * len(polys)
        else:
            flags = [bool(c) for c in closed]
            if len(flags) != len(polys):
                raise SimError(
                    "closed must give one flag per polygon: "
                    f"{len(polys)} polygons, {len(flags)} flags"
                )
        verts = [_validate_polygon(p, i, c) for i, (p, c) in enumerate(zip(polys, flags))]
        segs = [_polygon_segments(v, c) for v, c in zip(verts, flags)]
        seg = np.vstack(segs) if segs else np.empty((0, 4))
        return cls(seg, name=name, polygons=tuple(verts), closed=tuple(flags))

    @classmethod
    def from_file(cls, path: str | os.PathLike[str]) -> World:
        """Load a world from a TOML or JSON file (told apart by content, not by suffix).

        See :mod:`fuzzypos.sim.worldfile` for the format. A bad file raises :class:`SimError`
        naming the file and what is wrong with it.
        """
        parts = read_world_file(path)
        try:
            return cls(
                parts.segments, name=parts.name, polygons=parts.polygons, closed=parts.closed
            )
        except SimError as exc:  # pragma: no cover - read_world_file catches what World would
            raise SimError(f"world file {Path(path)}: {exc}") from None

    def to_file(self, path: str | os.PathLike[str]) -> None:
        """Write this world as TOML (``name``, ``[[polygon]]``, ``[[segment]]``) to ``path``;
        :meth:`from_file` reads it back with bit-identical coordinates."""
        save_world(self, path)

    # ---- properties ------------------------------------------------------------------------

    def __repr__(self) -> str:
        return (
            f"World(name={self.name!r}, n_segments={self.n_segments}, "
            f"n_polygons={len(self.polygons)})"
        )

    @property
    def n_segments(self) -> int:
        return int(self.segments.shape[0])

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of all segments (all zeros for an empty world)."""
        if self.n_segments == 0:
            return (0.0, 0.0, 0.0, 0.0)
        xs = self.segments[:, [0, 2]]
        ys = self.segments[:, [1, 3]]
        return (float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max()))

    @property
    def corners(self) -> FloatArray:
        """The true corners, :meth:`corner_points` at its default ``min_angle_deg`` (30°)."""
        return self.corner_points()

    def corner_points(self, min_angle_deg: float = 30.0) -> FloatArray:
        """Vertices where walls meet with a change of direction of at least ``min_angle_deg``.

        Every segment endpoint is a candidate (polygon vertices, and wall ends that abut another
        wall, e.g. T-junctions). The walls through a candidate split the plane around it into
        wedges of free space; it is a corner when two walls bound a wedge ``w`` with
        ``|180° - w| >= min_angle`` (an L gives 90° and 270°, a T gives 90°, 90°, 180°). A
        collinear vertex (180°, 180°), a free wall end (one wall) and a shallow bend of a round
        pillar are not corners. Returns a read-only ``(k, 2)`` array, one row per location.
        """
        return self._corner_geometry(min_angle_deg)[0]

    def corner_view_cones(self, min_angle_deg: float = 30.0) -> tuple[FloatArray, FloatArray]:
        """Corners and the directions from which a scanner sees them as corners.

        Returns ``(points (k, 2), cones (c, 4))``; each cone row is ``[corner index, start,
        lo, hi]``: a viewer in direction ``phi`` from the corner sees both walls that meet there
        when ``lo < (phi - start) mod 2π < hi``. Inside a concave wedge ``w`` that is the whole
        wedge; outside a convex one (``w > 180°``) only the ``360° - w`` cone where both faces
        are in front (elsewhere one face ends at the corner: a range jump, not an angle).
        """
        return self._corner_geometry(min_angle_deg)

    def _corner_geometry(self, min_angle_deg: float) -> tuple[FloatArray, FloatArray]:
        min_angle_deg = float(min_angle_deg)
        if not (0.0 < min_angle_deg <= 180.0):
            raise SimError(f"min_angle_deg must be in (0, 180], got {min_angle_deg}")
        cache: dict[float, tuple[FloatArray, FloatArray]] = self.__dict__.setdefault(
            "_corner_cache", {}
        )
        if min_angle_deg in cache:
            return cache[min_angle_deg]
        seg = self.segments
        points: list[FloatArray] = []
        cones: list[tuple[float, float, float, float]] = []
        if len(seg):
            a, b = seg[:, :2], seg[:, 2:]
            ends = np.vstack([a, b])
            # distinct candidates (shared polygon vertices are bit-identical; round off float dust)
            key = np.round(ends / VERTEX_TOL).astype(np.int64)
            _, first = np.unique(key, axis=0, return_index=True)
            cand = ends[np.sort(first)]
            e = b - a
            dir_ab = np.arctan2(e[:, 1], e[:, 0])
            dir_ba = np.arctan2(-e[:, 1], -e[:, 0])
            at_a = np.hypot(*(cand[:, None, :] - a[None]).transpose(2, 0, 1)) <= VERTEX_TOL
            at_b = np.hypot(*(cand[:, None, :] - b[None]).transpose(2, 0, 1)) <= VERTEX_TOL
            inner = (_point_segment_distance(cand, seg) <= VERTEX_TOL) & ~at_a & ~at_b
            min_change = math.radians(min_angle_deg) - 1e-9
            for k in range(len(cand)):
                rays = np.concatenate(
                    [dir_ab[at_a[k]], dir_ba[at_b[k]], dir_ab[inner[k]], dir_ba[inner[k]]]
                )
                r = np.unique(np.round(np.mod(rays, 2.0 * math.pi), 12))
                if len(r) < 2:
                    continue  # a free wall end: a jump in range, not an angle
                wedges = np.diff(np.append(r, r[0] + 2.0 * math.pi))
                mine = []
                for start, w in zip(r, wedges):  # the free wedge from ray `start` CCW by w
                    if abs(math.pi - w) >= min_change:
                        lo, hi = max(0.0, w - math.pi), min(w, math.pi)
                        mine.append((float(len(points)), float(start), lo, hi))
                if mine:
                    points.append(cand[k])
                    cones.extend(mine)
        result = (
            _readonly(np.array(points, dtype=float).reshape(-1, 2)),
            _readonly(np.array(cones, dtype=float).reshape(-1, 4)),
        )
        cache[min_angle_deg] = result
        return result

    def distance(self, points: ArrayLike) -> FloatArray:
        """Distance from each point ``(..., 2)`` to the nearest wall (``inf`` if no walls)."""
        pts = np.asarray(points, dtype=float)
        if pts.shape[-1:] != (2,):
            raise SimError(f"points must have a last axis of length 2, got shape {pts.shape}")
        flat = pts.reshape(-1, 2)
        if self.n_segments == 0:
            return np.full(pts.shape[:-1], np.inf)
        d: FloatArray = _point_segment_distance(flat, self.segments).min(axis=1)
        return d.reshape(pts.shape[:-1])


def _point_segment_distance(points: FloatArray, seg: FloatArray) -> FloatArray:
    """``(n, m)`` distances from ``points`` ``(n, 2)`` to segments ``(m, 4)``."""
    a = seg[None, :, :2]
    e = seg[None, :, 2:] - seg[None, :, :2]
    w = points[:, None, :] - a
    u = np.clip(np.sum(w * e, axis=-1) / np.sum(e * e, axis=-1), 0.0, 1.0)
    d = w - u[..., None] * e
    dist: FloatArray = np.hypot(d[..., 0], d[..., 1])
    return dist
