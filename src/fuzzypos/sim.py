"""2D laser simulator core: line-segment worlds, vectorised ray casting, scan synthesis.

A :class:`World` is a set of wall segments ``[x1, y1, x2, y2]`` in metres (usually built from
polygons, whose vertex lists are kept so the true corners are known). :func:`cast_rays` casts
many rays against every segment at once (beams x segments broadcasting, in chunks of beams to
bound memory). :class:`ScannerModel` describes a scanning laser rangefinder and where it is
mounted on the robot; :func:`simulate_scan` turns a world and a robot pose into a
:class:`~fuzzypos.scan.LaserScan`.

Conventions (SPEC): SI units, radians inside the code (degrees only in ``*_deg`` fields), frames
as in ROS REP-103 (x forward, y left, angles counter-clockwise). A beam with no return reads
exactly ``range_max``, which :class:`~fuzzypos.scan.LaserScan` treats as invalid.

Built-in worlds: :func:`rectangular_room`, :func:`furnished_room`, :func:`office` and
:func:`doorway_wall`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .geometry import Pose2D, compose, relative, wrap_angle
from .scan import LaserScan

FloatArray = NDArray[np.float64]

__all__ = [
    "SimError",
    "World",
    "ScannerModel",
    "cast_rays",
    "simulate_scan",
    "simulate_scans",
    "visible_corners",
    "laser_pose",
    "rectangular_room",
    "furnished_room",
    "office",
    "doorway_wall",
    "box_polygon",
    "circle_polygon",
    "arc_path",
    "drifting_odometry",
    "MotionTrial",
    "random_motions",
]

#: Hits nearer than this along the ray are ignored (no self-hits on the surface a ray starts on).
T_MIN = 1e-9
#: Slack (metres) by which a hit may lie beyond a segment's end and still count (endpoints hit).
ENDPOINT_TOL = 1e-9
#: A ray is treated as parallel to a segment when |sin(angle between them)| is below this.
PARALLEL_SIN = 1e-12
#: Points closer than this (metres) are the same vertex when corners are computed.
VERTEX_TOL = 1e-7
#: Upper bound on the beams x segments elements handled at once by :func:`cast_rays`.
_CHUNK_ELEMENTS = 1 << 20


class SimError(ValueError):
    """Invalid simulator input: a malformed world, scanner model or ray query."""


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


def _polygon_segments(v: FloatArray, closed: bool) -> FloatArray:
    end = np.roll(v, -1, axis=0) if closed else v[1:]
    start = v if closed else v[:-1]
    return np.hstack([start, end])


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
    def from_segments(cls, segs: ArrayLike, name: str = "world") -> "World":
        """A world of the given ``(m, 4)`` segments ``[x1, y1, x2, y2]``."""
        return cls(_validate_segments(segs), name=name)

    @classmethod
    def from_polygons(
        cls,
        polygons: Iterable[ArrayLike],
        closed: bool | Sequence[bool] = True,
        name: str = "world",
    ) -> "World":
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
        return _point_segment_distance(flat, self.segments).min(axis=1).reshape(pts.shape[:-1])


def _point_segment_distance(points: FloatArray, seg: FloatArray) -> FloatArray:
    """``(n, m)`` distances from ``points`` ``(n, 2)`` to segments ``(m, 4)``."""
    a = seg[None, :, :2]
    e = seg[None, :, 2:] - seg[None, :, :2]
    w = points[:, None, :] - a
    u = np.clip(np.sum(w * e, axis=-1) / np.sum(e * e, axis=-1), 0.0, 1.0)
    d = w - u[..., None] * e
    return np.hypot(d[..., 0], d[..., 1])


# --------------------------------------------------------------------------------------------
# Ray casting
# --------------------------------------------------------------------------------------------


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
    org = np.broadcast_to(org, n + (2,))
    ang = np.broadcast_to(ang, n)
    if not (np.isfinite(org).all() and np.isfinite(ang).all()):
        raise SimError("origins and directions must be finite")
    max_range = float(max_range)
    if not max_range > 0.0:
        raise SimError(f"max_range must be positive, got {max_range}")
    nrays = n[0] if n else 1
    ranges = np.full(nrays, np.inf)
    index = np.full(nrays, -1, dtype=np.intp)
    if len(seg) and nrays:
        d = np.stack([np.cos(ang), np.sin(ang)], axis=-1).reshape(nrays, 2)
        p = org.reshape(nrays, 2)
        step = max(1, _CHUNK_ELEMENTS // len(seg))
        for s in range(0, nrays, step):  # chunks bound memory; each chunk is fully vectorised
            sl = slice(s, s + step)
            ranges[sl], index[sl] = _cast_chunk(seg, p[sl], d[sl], max_range)
    if return_segment:
        return ranges, index
    return ranges


# --------------------------------------------------------------------------------------------
# Scanner and scans
# --------------------------------------------------------------------------------------------


def _as_pose(pose: Pose2D | ArrayLike) -> Pose2D:
    if isinstance(pose, Pose2D):
        return pose
    try:
        return Pose2D.from_array(pose)
    except ValueError as exc:
        raise SimError(f"a pose must be a Pose2D or (x, y, theta), got {pose!r}: {exc}") from None


@dataclass(frozen=True)
class ScannerModel:
    """A scanning laser rangefinder and its mounting on the robot.

    Beam ``i`` points at ``angle_min + i * increment`` in the laser frame, with
    ``increment = field_of_view / n_beams`` (so 180 beams over 180° cover -90°..+89°; a 360°
    scanner closes the circle without a duplicated beam). A negative field of view scans
    clockwise (an upside-down mount). ``range_noise_std`` is the std of additive Gaussian range
    noise (metres); a beam with no return reads exactly ``range_max``.
    """

    n_beams: int = 180
    field_of_view_deg: float = 180.0
    angle_min_deg: float = -90.0
    range_max: float = 8.0
    range_min: float = 0.02
    range_noise_std: float = 0.0
    sensor_pose: Pose2D = field(default_factory=Pose2D)

    def __post_init__(self) -> None:
        if isinstance(self.n_beams, bool) or int(self.n_beams) != self.n_beams or self.n_beams < 1:
            raise SimError(f"n_beams must be a positive integer, got {self.n_beams!r}")
        object.__setattr__(self, "n_beams", int(self.n_beams))
        names = ("field_of_view_deg", "angle_min_deg", "range_max", "range_min", "range_noise_std")
        for name in names:
            v = float(getattr(self, name))
            if not math.isfinite(v):
                raise SimError(f"ScannerModel.{name} must be finite, got {v}")
            object.__setattr__(self, name, v)
        if self.field_of_view_deg == 0.0 or abs(self.field_of_view_deg) > 360.0:
            raise SimError(
                f"field_of_view_deg must be non-zero and within ±360, got {self.field_of_view_deg}"
            )
        if not (0.0 <= self.range_min < self.range_max):
            raise SimError(
                "need 0 <= range_min < range_max, got "
                f"range_min={self.range_min}, range_max={self.range_max}"
            )
        if self.range_noise_std < 0.0:
            raise SimError(f"range_noise_std must be >= 0, got {self.range_noise_std}")
        object.__setattr__(self, "sensor_pose", _as_pose(self.sensor_pose))

    @property
    def angle_min(self) -> float:
        """Bearing of the first beam in the laser frame (radians)."""
        return math.radians(self.angle_min_deg)

    @property
    def angle_increment(self) -> float:
        """Angle between consecutive beams (radians; negative for a clockwise scan)."""
        return math.radians(self.field_of_view_deg) / self.n_beams

    @property
    def is_full_circle(self) -> bool:
        return abs(self.field_of_view_deg) >= 360.0

    def angles(self) -> FloatArray:
        """Beam bearings in the laser frame, ``(n_beams,)`` radians."""
        return self.angle_min + np.arange(self.n_beams) * self.angle_increment

    def covers(self, bearings: ArrayLike) -> NDArray[np.bool_]:
        """Whether laser-frame bearings lie within the swept beams (first to last beam)."""
        b = np.asarray(bearings, dtype=float)
        if self.is_full_circle:
            return np.ones(b.shape, dtype=bool)
        inc = self.angle_increment
        rel = np.mod((b - self.angle_min) * math.copysign(1.0, inc), 2.0 * math.pi)
        span = (self.n_beams - 1) * abs(inc)
        return (rel <= span + 1e-12) | (rel >= 2.0 * math.pi - 1e-12)


def laser_pose(robot_pose: Pose2D | ArrayLike, scanner: ScannerModel) -> Pose2D:
    """The laser's world pose: ``robot_pose ⊕ scanner.sensor_pose``."""
    return _as_pose(robot_pose).compose(scanner.sensor_pose)


def simulate_scan(
    world: World,
    robot_pose: Pose2D | ArrayLike,
    scanner: ScannerModel = ScannerModel(),
    rng: np.random.Generator | None = None,
    stamp: float = 0.0,
) -> LaserScan:
    """Simulate one scan of ``world`` by ``scanner`` on a robot at ``robot_pose``.

    Noise ``N(0, range_noise_std)`` is added to hits only (one draw per beam, so the random
    stream advances by ``n_beams`` per scan whatever is hit) and the result clipped to
    ``[range_min, range_max]``; beams with no return within ``range_max`` read ``range_max``.
    A hit nearer than ``range_min`` is reported noise-free at its true range (below
    ``range_min``, so invalid). ``rng`` defaults to a fresh unseeded generator when noise is on.
    The scan's ``sensor_pose`` is the scanner's.
    """
    lp = laser_pose(robot_pose, scanner)
    r = cast_rays(world, (lp.x, lp.y), lp.theta + scanner.angles(), scanner.range_max)
    assert isinstance(r, np.ndarray)
    hit = np.isfinite(r)
    ranges = np.where(hit, r, scanner.range_max)
    if scanner.range_noise_std > 0.0:
        if rng is None:
            rng = np.random.default_rng()
        noise = rng.normal(0.0, scanner.range_noise_std, size=scanner.n_beams)
        noisy = hit & (r >= scanner.range_min)
        ranges = np.where(
            noisy, np.clip(ranges + noise, scanner.range_min, scanner.range_max), ranges
        )
    return LaserScan(
        ranges,
        angle_min=scanner.angle_min,
        angle_increment=scanner.angle_increment,
        range_min=scanner.range_min,
        range_max=scanner.range_max,
        stamp=float(stamp),
        sensor_pose=scanner.sensor_pose,
    )


def simulate_scans(
    world: World,
    poses: Iterable[Pose2D | ArrayLike],
    scanner: ScannerModel = ScannerModel(),
    rng: np.random.Generator | None = None,
    stamps: Iterable[float] | None = None,
) -> list[LaserScan]:
    """One :func:`simulate_scan` per pose, sharing ``rng``; ``stamps`` default to 0, 1, 2, ..."""
    pose_list = [_as_pose(p) for p in poses]
    if stamps is None:
        stamp_list = [float(i) for i in range(len(pose_list))]
    else:
        stamp_list = [float(s) for s in stamps]
        if len(stamp_list) != len(pose_list):
            raise SimError(f"got {len(pose_list)} poses but {len(stamp_list)} stamps")
    if rng is None and scanner.range_noise_std > 0.0:
        rng = np.random.default_rng()
    return [simulate_scan(world, p, scanner, rng, s) for p, s in zip(pose_list, stamp_list)]


def visible_corners(
    world: World,
    robot_pose: Pose2D | ArrayLike,
    scanner: ScannerModel = ScannerModel(),
    min_angle_deg: float = 30.0,
    tol: float = 0.05,
) -> FloatArray:
    """The world's corners (world frame, ``(k, 2)``) the scanner sees from ``robot_pose``.

    A corner is visible when its distance from the laser is in ``[range_min, range_max)``, its
    bearing lies within the swept beams, the laser is on the side from which both walls meeting
    there face it (:meth:`World.corner_view_cones`: a thin wall's T-junction is a corner from
    the room behind it only, a box corner only where both its faces are seen), and a ray cast
    towards it is not blocked before ``distance - tol``.
    """
    corners, cones = world.corner_view_cones(min_angle_deg)
    if len(corners) == 0:
        return _readonly(np.empty((0, 2)))
    lp = laser_pose(robot_pose, scanner)
    v = corners - np.array([lp.x, lp.y])
    dist = np.hypot(v[:, 0], v[:, 1])
    bearing = np.arctan2(v[:, 1], v[:, 0])
    ok = (dist >= scanner.range_min) & (dist < scanner.range_max)
    ok &= scanner.covers(wrap_angle(bearing - lp.theta))
    # the direction from each corner back to the laser must fall inside one of its view cones
    idx = cones[:, 0].astype(np.intp)
    rel = np.mod(bearing[idx] + math.pi - cones[:, 1], 2.0 * math.pi)
    in_cone = (rel > cones[:, 2]) & (rel < cones[:, 3])
    ok &= np.bincount(idx[in_cone], minlength=len(corners)) > 0
    if ok.any():
        r = cast_rays(world, (lp.x, lp.y), bearing[ok], scanner.range_max)
        assert isinstance(r, np.ndarray)
        ok[ok] = r >= dist[ok] - tol
    return _readonly(corners[ok])


# --------------------------------------------------------------------------------------------
# Built-in worlds
# --------------------------------------------------------------------------------------------


def box_polygon(
    cx: float, cy: float, length: float, width: float, theta: float = 0.0
) -> FloatArray:
    """Vertices (CCW) of a ``length`` x ``width`` rectangle centred at ``(cx, cy)``, rotated
    by ``theta`` (``length`` along the rotated x axis)."""
    if not (length > 0 and width > 0):
        raise SimError(f"box sides must be positive, got {length} x {width}")
    hx, hy = length / 2.0, width / 2.0
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    c, s = math.cos(theta), math.sin(theta)
    return local @ np.array([[c, s], [-s, c]]) + np.array([cx, cy])


def circle_polygon(cx: float, cy: float, radius: float, n: int = 16) -> FloatArray:
    """A regular ``n``-gon approximating a round pillar (16 sides bend by 22.5°, below the
    default 30° corner threshold, so a round pillar has no corners)."""
    if not radius > 0 or n < 3:
        raise SimError(f"a circle needs radius > 0 and n >= 3, got radius={radius}, n={n}")
    a = 2.0 * math.pi * np.arange(n) / n
    return np.column_stack([cx + radius * np.cos(a), cy + radius * np.sin(a)])


def rectangular_room(width: float = 8.0, height: float = 6.0) -> World:
    """An empty ``width`` (along x) by ``height`` (along y) room centred on the origin."""
    if not (width > 0 and height > 0):
        raise SimError(f"room sides must be positive, got {width} x {height}")
    return World.from_polygons([box_polygon(0.0, 0.0, width, height)], name="rectangular_room")


#: furnished_room: room half-sizes, the free central area's half-sizes, and the fixed layout.
_ROOM_HALF = (5.0, 4.0)
_FREE_HALF = (2.0, 1.5)
#: (cx, cy, length, width, theta_deg) of the pieces of furniture in the seed-0 layout
_FURNITURE = (
    (1.8, 3.0, 1.2, 0.8, 0.0),  # table
    (-4.2, 1.5, 1.0, 0.5, 90.0),  # cabinet along the left wall
    (4.0, -1.0, 0.6, 0.6, 30.0),  # box, rotated
    (-2.0, -3.2, 1.2, 0.6, -20.0),  # desk, rotated
    (-0.5, 3.1, 0.5, 0.8, 45.0),  # box, rotated
    (1.0, -3.2, 0.7, 0.5, 0.0),  # crate
)
#: pillars: ("round", cx, cy, radius) or ("square", cx, cy, side)
_PILLARS = (("round", -3.2, -0.6, 0.15), ("square", 3.0, 1.0, 0.3))


def _piece_fits(
    cx: float, cy: float, radius: float, placed: list[tuple[float, float, float]]
) -> bool:
    """Bounding-circle check: inside the room with a margin, clear of the free central area and
    of the pieces already placed."""
    margin = 0.25
    if abs(cx) + radius > _ROOM_HALF[0] - margin or abs(cy) + radius > _ROOM_HALF[1] - margin:
        return False
    gx = max(abs(cx) - _FREE_HALF[0], 0.0)
    gy = max(abs(cy) - _FREE_HALF[1], 0.0)
    if math.hypot(gx, gy) < radius + margin:
        return False
    return all(math.hypot(cx - x, cy - y) >= radius + r + margin for x, y, r in placed)


def furnished_room(seed: int = 0) -> World:
    """A 10 m x 8 m room centred on the origin with six pieces of furniture (axis-aligned and
    rotated boxes of 0.5-1.2 m sides), a round pillar and a square pillar.

    The central 4 m x 3 m area (``|x| <= 2``, ``|y| <= 1.5``) is free. ``seed=0`` is a fixed
    layout chosen so that the room's four corners are visible from the origin; any other seed
    places the same pieces at random (deterministically, from ``np.random.default_rng(seed)``),
    inside the room, clear of the central area and of each other.
    """
    hx, hy = _ROOM_HALF
    polys: list[FloatArray] = [box_polygon(0.0, 0.0, 2 * hx, 2 * hy)]
    pieces = [(cx, cy, l, w, math.radians(th)) for cx, cy, l, w, th in _FURNITURE]
    pillars = list(_PILLARS)
    if seed != 0:
        rng = np.random.default_rng(seed)
        placed: list[tuple[float, float, float]] = []
        new_pieces = []
        sizes = [(l, w) for _, _, l, w, _ in _FURNITURE] + [
            (2 * s, 2 * s) if kind == "round" else (s, s) for kind, _, _, s in _PILLARS
        ]
        for k, (l, w) in enumerate(sizes):
            radius = 0.5 * math.hypot(l, w)
            for _attempt in range(10_000):
                cx = float(rng.uniform(-hx, hx))
                cy = float(rng.uniform(-hy, hy))
                if _piece_fits(cx, cy, radius, placed):
                    break
            else:  # pragma: no cover - the room has ample space for these pieces
                raise SimError(f"furnished_room(seed={seed}): could not place piece {k}")
            placed.append((cx, cy, radius))
            # half the boxes axis-aligned, half rotated
            theta = 0.0 if k % 2 == 0 else float(rng.uniform(-math.pi / 2, math.pi / 2))
            new_pieces.append((cx, cy, l, w, theta))
        n_f = len(_FURNITURE)
        pieces = new_pieces[:n_f]
        pillars = [
            (kind, cx, cy, s)
            for (kind, _, _, s), (cx, cy, _, _, _) in zip(_PILLARS, new_pieces[n_f:])
        ]
    polys += [box_polygon(*p) for p in pieces]
    for kind, cx, cy, s in pillars:
        polys.append(circle_polygon(cx, cy, s) if kind == "round" else box_polygon(cx, cy, s, s))
    return World.from_polygons(polys, name=f"furnished_room(seed={seed})")


def _wall_with_gaps(
    start: tuple[float, float], end: tuple[float, float], gaps: Sequence[tuple[float, float]]
) -> list[FloatArray]:
    """Pieces of the straight wall ``start``-``end`` with the ``gaps`` (as ``(from, to)``
    distances along the wall) cut out, each piece a 2-vertex open polyline."""
    p0, p1 = np.asarray(start, float), np.asarray(end, float)
    length = float(np.hypot(*(p1 - p0)))
    u = (p1 - p0) / length
    cuts = [0.0]
    for g0, g1 in sorted(gaps):
        cuts += [g0, g1]
    cuts.append(length)
    return [
        np.array([p0 + a * u, p0 + b * u]) for a, b in zip(cuts[::2], cuts[1::2]) if b - a > 1e-9
    ]


def office() -> World:
    """A 20 m x 10 m office: a 2 m corridor along the x axis (``|y| <= 1``) with three rooms
    north of it and two south, each entered by a 1 m doorway, and furniture in the rooms.

    Walls are thin segments; the doorway jambs are free wall ends (range jumps, not corners)
    while wall junctions (T and L) are corners.
    """
    X, Y, C = 10.0, 5.0, 1.0
    polys: list[FloatArray] = []
    flags: list[bool] = []

    def add(poly: ArrayLike, closed: bool) -> None:
        polys.append(np.asarray(poly, float))
        flags.append(closed)

    add(box_polygon(0.0, 0.0, 2 * X, 2 * Y), True)  # outer walls
    # corridor walls with doorways: north rooms' doors at x in [-7.5,-6.5], [-0.5,0.5], [6,7]
    for piece in _wall_with_gaps((-X, C), (X, C), [(2.5, 3.5), (9.5, 10.5), (16.0, 17.0)]):
        add(piece, False)
    # south rooms' doors at x in [-4,-3] and [5,6]
    for piece in _wall_with_gaps((-X, -C), (X, -C), [(6.0, 7.0), (15.0, 16.0)]):
        add(piece, False)
    # partitions: north rooms split at x = -3.5 and x = 3.5, south rooms at x = 1
    add([[-3.5, C], [-3.5, Y]], False)
    add([[3.5, C], [3.5, Y]], False)
    add([[1.0, -C], [1.0, -Y]], False)
    # furniture
    for piece in (
        (-8.5, 4.2, 1.2, 0.6, 0.0),  # desk, NW room
        (-5.0, 2.5, 0.8, 0.8, math.radians(25.0)),  # box, NW room
        (0.0, 4.3, 1.2, 0.6, 0.0),  # desk, N room
        (2.5, 2.2, 0.6, 0.5, math.radians(-30.0)),  # box, N room
        (8.5, 3.0, 0.6, 1.2, 0.0),  # cabinet, NE room
        (-8.0, -3.8, 1.0, 0.6, math.radians(15.0)),  # desk, SW room
        (-1.5, -2.8, 0.5, 0.5, 0.0),  # box, SW room
        (5.5, -4.2, 1.2, 0.6, 0.0),  # desk, SE room
        (8.3, -2.4, 0.7, 0.7, math.radians(40.0)),  # box, SE room
    ):
        add(box_polygon(*piece), True)
    add(box_polygon(-5.0, -3.0, 0.3, 0.3), True)  # square pillar, SW room
    return World.from_polygons(polys, closed=flags, name="office")


def doorway_wall(
    distance: float = 2.0,
    gap: float = 1.0,
    length: float = 10.0,
    back_wall_distance: float | None = None,
) -> World:
    """A straight wall across the x axis at ``x = distance`` (``length`` long, centred on
    ``y = 0``) with a ``gap`` wide doorway centred on ``y = 0``; optionally a second, unbroken
    wall at ``x = back_wall_distance`` behind it."""
    if not (distance > 0 and 0 < gap < length):
        raise SimError(f"need distance > 0 and 0 < gap < length, got {distance}, {gap}, {length}")
    half = length / 2.0
    polys = _wall_with_gaps((distance, -half), (distance, half), [(half - gap / 2, half + gap / 2)])
    if back_wall_distance is not None:
        if not back_wall_distance > distance:
            raise SimError(
                f"back_wall_distance must exceed distance ({distance}), got {back_wall_distance}"
            )
        polys.append(np.array([[back_wall_distance, -half], [back_wall_distance, half]]))
    return World.from_polygons(polys, closed=False, name="doorway_wall")


def arc_path(start: Pose2D, n: int, step: float, turn_deg: float) -> list[Pose2D]:
    """``n`` poses from ``start``, each ``step`` metres forward and ``turn_deg`` degrees left of
    the previous one (a constant-curvature arc; ``turn_deg=0`` is a straight line)."""
    if n < 1:
        raise SimError(f"arc_path needs at least one pose, got n={n}")
    inc = np.array([step, 0.0, math.radians(turn_deg)])
    poses = [start.as_array()]
    for _ in range(n - 1):
        poses.append(compose(poses[-1], inc))
    return [Pose2D.from_array(p) for p in poses]


def drifting_odometry(
    true_poses: Sequence[Pose2D],
    scale: float = 1.0,
    rotation_bias_deg: float = 0.0,
    noise_std: tuple[float, float] = (0.0, 0.0),
    rng: np.random.Generator | None = None,
) -> list[Pose2D]:
    """Odometry that integrates distorted true increments: translation scaled by ``scale``,
    ``rotation_bias_deg`` added to every increment's rotation, plus Gaussian noise
    ``(metres, degrees)`` per increment. It starts at the first true pose."""
    if not true_poses:
        return []
    rng = rng if rng is not None else np.random.default_rng(0)
    arr = np.array([p.as_array() for p in true_poses])
    odo = [arr[0]]
    for k in range(1, len(arr)):
        u = relative(arr[k - 1], arr[k])
        u[:2] *= scale
        u[2] += math.radians(rotation_bias_deg)
        u[:2] += rng.normal(0.0, noise_std[0], 2)
        u[2] += math.radians(rng.normal(0.0, noise_std[1]))
        odo.append(compose(odo[-1], u))
    return [Pose2D.from_array(p) for p in odo]


@dataclass(frozen=True, eq=False)
class MotionTrial:
    """One simulated motion: the world poses of two scans, the true increment between them
    (``⊖start ⊕ end``) and an odometry increment (the true one composed with an error)."""

    start: FloatArray
    end: FloatArray
    increment: FloatArray
    odometry: FloatArray


def random_motions(
    world: World,
    scanner: ScannerModel,
    n: int,
    seed: int,
    area: tuple[float, float] = (1.5, 1.0),
    max_translation: float = 0.5,
    max_rotation_deg: float = 20.0,
    odometry_error: tuple[float, float] = (0.07, 5.0),
    min_corners: int = 2,
) -> list[MotionTrial]:
    """``n`` random rigid motions (|t| ≤ ``max_translation``, uniform over the disc; |θ| ≤
    ``max_rotation_deg``) from random start poses in ``|x| ≤ area[0], |y| ≤ area[1]`` (any
    heading), keeping only those where both poses see at least ``min_corners`` corners
    (:func:`visible_corners`). The odometry increment is the true one composed with an error
    uniform within ±``odometry_error[0]`` metres per axis and ±``odometry_error[1]`` degrees.
    """
    rng = np.random.default_rng(seed)
    trials: list[MotionTrial] = []
    for _ in range(50 * n):
        if len(trials) == n:
            break
        start = np.array([rng.uniform(-area[0], area[0]), rng.uniform(-area[1], area[1]),
                          rng.uniform(-math.pi, math.pi)])
        t = max_translation * math.sqrt(rng.uniform())
        phi = rng.uniform(-math.pi, math.pi)
        inc = np.array([t * math.cos(phi), t * math.sin(phi),
                        math.radians(rng.uniform(-max_rotation_deg, max_rotation_deg))])
        ex, ey = odometry_error[0], odometry_error[0]
        err = np.array([rng.uniform(-ex, ex), rng.uniform(-ey, ey),
                        math.radians(rng.uniform(-odometry_error[1], odometry_error[1]))])
        end = compose(start, inc)
        if (len(visible_corners(world, start, scanner)) < min_corners
                or len(visible_corners(world, end, scanner)) < min_corners):
            continue
        trials.append(MotionTrial(start, end, inc, compose(inc, err)))
    if len(trials) < n:
        raise SimError(f"random_motions: only {len(trials)} of {n} motions see {min_corners} corners")
    return trials
