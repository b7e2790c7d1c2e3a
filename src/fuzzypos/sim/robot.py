"""A synchronous-drive robot (iRobot B21r-like) following a commanded path on a slippery floor.

- :class:`CommandedPath`: piecewise-constant velocity commands ``(v, ω)`` over time, with
  constructors for a circle, a square, a figure eight and a list of waypoints.
- :class:`SlipModel`: how the true motion departs from the commands (outward skid, longitudinal
  and angular slip) and how noisy the wheel encoders are.
- :func:`simulate_run`: drive a path in a world, returning the true poses, the odometry and the
  laser scans at the scanner's rate (:class:`SimulatedRun`).

The paper's robot (§5) followed a circle in a gym; "because of the evenly slippery floor, the
actual path of the mobile robot is a spiral curve", while its odometry, which integrates what
the wheels report, believes in the circle. The slip model reproduces that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..geometry import Pose2D, relative, wrap_angle
from ..scan import LaserScan
from .scanner import ScannerModel, _as_pose, simulate_scan
from .world import FloatArray, SimError, World, _readonly

__all__ = ["CommandedPath", "SlipModel", "SimulatedRun", "simulate_run"]

#: default cruising speed of the path constructors, m/s (the B21r's top speed is 1 m/s)
DEFAULT_SPEED = 0.3
#: default rate of turns on the spot, rad/s (45°/s)
DEFAULT_TURN_RATE = math.radians(45.0)
#: largest internal integration step of :func:`simulate_run`, s (100 Hz)
MAX_STEP = 0.01


def _positive(name: str, value: Any) -> float:
    if isinstance(value, (bool, np.bool_)):
        raise SimError(f"{name} must be a positive number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SimError(f"{name} must be a positive number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0.0):
        raise SimError(f"{name} must be a positive finite number, got {value!r}")
    return v


def _whole_laps(laps: Any) -> int:
    if isinstance(laps, (bool, np.bool_)) or int(laps) != laps or laps < 1:
        raise SimError(f"laps must be a positive whole number, got {laps!r}")
    return int(laps)


def _sinc(x: FloatArray) -> FloatArray:
    """``sin(x) / x`` (1 at 0)."""
    return np.sinc(x / math.pi)


def _arc(v: FloatArray, w: FloatArray, tau: FloatArray) -> FloatArray:
    """Body-frame displacement ``(n, 3)`` after driving the twist ``(v, 0, w)`` for ``tau``."""
    s = v * tau
    h = 0.5 * w * tau
    k = s * _sinc(h)
    return np.stack([k * np.cos(h), k * np.sin(h), 2.0 * h], axis=-1)


def _compose_many(p: FloatArray, d: FloatArray) -> FloatArray:
    """``p ⊕ d`` row by row for ``(n, 3)`` arrays (``p`` may be ``(3,)``); headings wrapped."""
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    x = p[..., 0] + c * d[..., 0] - s * d[..., 1]
    y = p[..., 1] + s * d[..., 0] + c * d[..., 1]
    return np.stack(np.broadcast_arrays(x, y, wrap_angle(p[..., 2] + d[..., 2])), axis=-1)


# --------------------------------------------------------------------------------------------
# Commanded paths
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class CommandedPath:
    """Velocity commands for the robot: ``segments`` rows ``[duration (s), v (m/s), ω (rad/s)]``,
    each command held for its duration, one after the other from time 0; after the last one the
    robot stands still. ``start`` is the pose the commands are laid out from (the constructors
    put the path where their docstrings say; :func:`simulate_run` can start elsewhere).

    Every constructor drives at a constant ``speed`` along the path (default 0.3 m/s) and turns
    on the spot, where it turns at all, at ``turn_rate`` (default 45°/s).
    """

    segments: FloatArray
    start: Pose2D = field(default_factory=Pose2D)
    name: str = "path"

    if TYPE_CHECKING:
        # Derived in __post_init__; declared for the type checker only (not a dataclass field).
        _bounds: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        try:
            seg = np.array(self.segments, dtype=float)
        except (TypeError, ValueError) as exc:
            raise SimError(f"path segments must be numeric, got {self.segments!r}") from exc
        if seg.ndim != 2 or seg.shape[1] != 3 or len(seg) == 0:
            raise SimError(
                f"path segments must have shape (k >= 1, 3) as [duration, v, omega] rows, "
                f"got {seg.shape}"
            )
        if not np.isfinite(seg).all():
            raise SimError("path segments must be finite")
        if (seg[:, 0] <= 0.0).any():
            i = int(np.flatnonzero(seg[:, 0] <= 0.0)[0])
            raise SimError(f"path segment {i} has a non-positive duration {seg[i, 0]}")
        object.__setattr__(self, "segments", _readonly(seg))
        object.__setattr__(self, "start", _as_pose(self.start))
        object.__setattr__(self, "name", str(self.name))
        bounds = np.concatenate([[0.0], np.cumsum(seg[:, 0])])
        object.__setattr__(self, "_bounds", _readonly(bounds))

    # ---- constructors ----------------------------------------------------------------------

    @classmethod
    def circle(
        cls,
        radius: float,
        laps: float = 1.0,
        speed: float = DEFAULT_SPEED,
        centre: tuple[float, float] = (0.0, 0.0),
        clockwise: bool = False,
    ) -> CommandedPath:
        """``laps`` (any positive number) of a circle of ``radius`` round ``centre``: one
        command ``v = speed``, ``ω = ±speed / radius``. It starts at ``centre + (radius, 0)``
        heading +y (anticlockwise) or -y (``clockwise``)."""
        r = _positive("radius", radius)
        n = _positive("laps", laps)
        v = _positive("speed", speed)
        sign = -1.0 if clockwise else 1.0
        cx, cy = (float(c) for c in centre)
        start = Pose2D(cx + r, cy, sign * math.pi / 2)
        seg = [[n * 2.0 * math.pi * r / v, v, sign * v / r]]
        return cls(np.array(seg), start, name=f"circle(r={r:g} m, {n:g} laps)")

    @classmethod
    def square(
        cls,
        side: float,
        laps: int = 1,
        speed: float = DEFAULT_SPEED,
        turn_rate: float = DEFAULT_TURN_RATE,
        centre: tuple[float, float] = (0.0, 0.0),
    ) -> CommandedPath:
        """``laps`` anticlockwise laps of a square of ``side`` centred on ``centre``: each side a
        straight leg at ``speed``, each corner a 90° turn on the spot (``v = 0``) at
        ``turn_rate`` (a synchronous drive turns in place). It starts at the south-west corner
        heading +x and ends there, after its last turn, with the same heading."""
        s = _positive("side", side)
        n = _whole_laps(laps)
        v = _positive("speed", speed)
        w = _positive("turn_rate", turn_rate)
        cx, cy = (float(c) for c in centre)
        lap = [[s / v, v, 0.0], [0.5 * math.pi / w, 0.0, w]] * 4
        return cls(
            np.array(lap * n),
            Pose2D(cx - s / 2, cy - s / 2, 0.0),
            name=f"square({s:g} m, {n} laps)",
        )

    @classmethod
    def figure8(
        cls,
        radius: float,
        laps: float = 1,
        speed: float = DEFAULT_SPEED,
        centre: tuple[float, float] = (0.0, 0.0),
    ) -> CommandedPath:
        """``laps`` figure eights of two circles of ``radius`` touching at ``centre``: from
        ``centre`` heading +x, a full anticlockwise circle round ``centre + (0, radius)``, then a
        full clockwise one round ``centre - (0, radius)``; the robot is back at ``centre``, with
        its start heading, after each circle (twice per lap). ``laps`` is a positive whole
        number, ``2`` or ``2.0`` (the command line's ``--laps`` is a float); a fraction is an
        error."""
        r = _positive("radius", radius)
        n = _whole_laps(laps)
        v = _positive("speed", speed)
        cx, cy = (float(c) for c in centre)
        t = 2.0 * math.pi * r / v
        lap = [[t, v, v / r], [t, v, -v / r]]
        return cls(np.array(lap * n), Pose2D(cx, cy, 0.0), name=f"figure8(r={r:g} m, {n} laps)")

    @classmethod
    def waypoints(
        cls,
        points: ArrayLike,
        speed: float = DEFAULT_SPEED,
        turn_rate: float = DEFAULT_TURN_RATE,
        heading: float | None = None,
    ) -> CommandedPath:
        """Drive straight from point to point of ``points`` ``(k >= 2, 2)``, turning on the spot
        (the shorter way, at ``turn_rate``) to face each next point. It starts at ``points[0]``
        facing ``points[1]``, or with ``heading`` (radians) and a first turn on the spot."""
        try:
            p = np.asarray(points, dtype=float)
        except (TypeError, ValueError) as exc:
            raise SimError(f"waypoints must be numeric, got {points!r}") from exc
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2:
            raise SimError(f"waypoints must have shape (k >= 2, 2), got {p.shape}")
        if not np.isfinite(p).all():
            raise SimError("waypoints must be finite")
        v = _positive("speed", speed)
        w = _positive("turn_rate", turn_rate)
        step = np.diff(p, axis=0)
        length = np.hypot(step[:, 0], step[:, 1])
        if (length <= 1e-9).any():
            i = int(np.flatnonzero(length <= 1e-9)[0])
            raise SimError(f"waypoints {i} and {i + 1} coincide at {p[i].tolist()}")
        bearing = np.arctan2(step[:, 1], step[:, 0])
        h0 = float(bearing[0]) if heading is None else float(heading)
        if not math.isfinite(h0):
            raise SimError(f"heading must be finite, got {heading!r}")
        seg: list[list[float]] = []
        current = h0
        for b, d in zip(bearing, length):
            turn = float(wrap_angle(b - current))
            if abs(turn) > 1e-12:
                seg.append([abs(turn) / w, 0.0, math.copysign(w, turn)])
            seg.append([float(d) / v, v, 0.0])
            current = float(b)
        start = Pose2D(float(p[0, 0]), float(p[0, 1]), h0)
        return cls(np.array(seg), start, name=f"waypoints({len(p)} points)")

    # ---- properties ------------------------------------------------------------------------

    @property
    def duration(self) -> float:
        """Total time of the commands, s."""
        return float(self._bounds[-1])

    @property
    def boundaries(self) -> FloatArray:
        """Times ``(k + 1,)`` at which the commands change: 0, ends of each segment."""
        return self._bounds

    @property
    def length(self) -> float:
        """Length of the commanded path, ``Σ |v| · duration``, m."""
        return float(np.sum(np.abs(self.segments[:, 1]) * self.segments[:, 0]))

    def _index(self, t: FloatArray) -> NDArray[np.intp]:
        i: NDArray[np.intp] = np.searchsorted(self._bounds, t, side="right") - 1
        return i

    def commands(self, t: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Commanded ``(v, ω)`` at times ``t`` (segment ``i`` holds on ``[T_i, T_{i+1})``;
        before 0 and from the end on, ``(0, 0)``)."""
        ts = np.asarray(t, dtype=float)
        i = self._index(ts)
        ok = (i >= 0) & (i < len(self.segments))
        j = np.clip(i, 0, len(self.segments) - 1)
        v = np.where(ok, self.segments[j, 1], 0.0)
        w = np.where(ok, self.segments[j, 2], 0.0)
        return v, w

    def segment_poses(self, start: Pose2D | ArrayLike | None = None) -> FloatArray:
        """Commanded poses ``(k + 1, 3)`` at :attr:`boundaries`, from ``start`` (default
        :attr:`start`)."""
        p = (self.start if start is None else _as_pose(start)).as_array()
        out = [p]
        for d, v, w in self.segments:
            out.append(_compose_many(out[-1], _arc(np.array(v), np.array(w), np.array(d))))
        return np.array(out)

    def poses(self, t: ArrayLike, start: Pose2D | ArrayLike | None = None) -> FloatArray:
        """Commanded (ideal, slip-free) poses ``(n, 3)`` at times ``t`` (clipped to
        ``[0, duration]``), from ``start`` (default :attr:`start`)."""
        ts: FloatArray = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, self.duration)
        bp = self.segment_poses(start)
        i = np.clip(self._index(ts), 0, len(self.segments) - 1)
        seg = self.segments[i]
        return _compose_many(bp[i], _arc(seg[:, 1], seg[:, 2], ts - self._bounds[i]))


# --------------------------------------------------------------------------------------------
# Slip
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SlipModel:
    """Wheel slip on an evenly slippery floor, and wheel-encoder noise.

    A synchronous-drive robot's wheels execute the commanded ``(v, ω)`` and its encoders report
    that, with noise; the odometry integrates the reports. The robot itself moves differently:

    - ``longitudinal`` (default 0.02): the wheels turn 2% more than the robot moves,
      ``v_true = v · (1 − longitudinal)``.
    - ``angular`` (default 0.02): the robot turns 2% less than the wheels say,
      ``ω_true = ω · (1 − angular)`` at the start of each command. (Equal longitudinal and
      angular slip keep the curvature: a circle's true centre is the commanded one.)
    - ``radial_gain`` (s, default 0.05): while the robot drives a curve it skids outward, away
      from its centre of curvature, at a speed ``radial_gain · |v_true · ω_true|`` (the
      centripetal acceleration times a time constant; 0.05 s gives 0.37% of the speed on a 4 m
      circle at 0.3 m/s). The skid accumulates: the robot keeps turning round the same centre
      while it slides away from it, so its turning radius grows, ``R(t)² = R₀² + 2 ·
      radial_gain · v_true² · t`` with ``R₀ = |v_true / ω_true|``, and a commanded circle
      becomes an outward spiral whose radius grows by about ``2π · radial_gain · v_true`` per
      lap (9 cm at 0.3 m/s). The centre is where the command puts it when the command starts;
      a new command (a corner, a waypoint, the other loop of an eight) starts afresh from the
      pose reached, with the displacement kept. Turns on the spot and straight legs do not skid.
      (A skid that were a fixed fraction of the motion would only turn a circle into another,
      closed circle; the paper saw a spiral, hence the accumulation.)
    - ``translation_noise`` (√m, default 0.002) and ``rotation_noise`` (√rad, default 0.002):
      encoder noise, independent Gaussian errors on every integration step whose variances grow
      with the distance and the angle turned: the odometry's distance is off by
      ``translation_noise · √(distance in m)`` (2 mm after 1 m, 1.7 cm after 75 m), its
      heading by ``rotation_noise · √(angle turned in rad)`` (0.5° after three full turns).

    The defaults are a few percent, a B21r on a polished gym floor; :meth:`ideal` turns
    everything off (truth = odometry = the commanded path). With them, three laps of a 4 m
    circle at 0.3 m/s (251 s, 75.4 m commanded) become a spiral whose radius grows from 4.00 m
    to 4.26 m (mean distances from the centre 4.04, 4.13 and 4.22 m lap by lap); the robot
    travels 73.9 m and sweeps 2.85 laps, ending about 3.9 m from where its odometry, still on
    the 4 m circle, puts it, and 55° off in heading.
    """

    radial_gain: float = 0.05
    longitudinal: float = 0.02
    angular: float = 0.02
    translation_noise: float = 0.002
    rotation_noise: float = 0.002

    def __post_init__(self) -> None:
        for name in (
            "radial_gain",
            "longitudinal",
            "angular",
            "translation_noise",
            "rotation_noise",
        ):
            raw = getattr(self, name)
            if isinstance(raw, (bool, np.bool_)):
                raise SimError(f"SlipModel.{name} must be a number, got {raw!r}")
            try:
                v = float(raw)
            except (TypeError, ValueError):
                raise SimError(f"SlipModel.{name} must be a number, got {raw!r}") from None
            if not math.isfinite(v):
                raise SimError(f"SlipModel.{name} must be finite, got {v}")
            object.__setattr__(self, name, v)
        for name in ("radial_gain", "translation_noise", "rotation_noise"):
            if getattr(self, name) < 0.0:
                raise SimError(f"SlipModel.{name} must be >= 0, got {getattr(self, name)}")
        for name in ("longitudinal", "angular"):
            if not -1.0 < getattr(self, name) < 1.0:
                raise SimError(f"SlipModel.{name} must be in (-1, 1), got {getattr(self, name)}")

    @classmethod
    def ideal(cls) -> SlipModel:
        """No slip and no encoder noise: the robot does exactly what it is told."""
        return cls(0.0, 0.0, 0.0, 0.0, 0.0)

    def replace(self, **changes: Any) -> SlipModel:
        """A copy with some fields changed (``dataclasses.replace``, validated again)."""
        return replace(self, **changes)

    def circle_radius(self, radius: float, speed: float, t: ArrayLike) -> FloatArray:
        """The true turning radius ``R(t)`` after ``t`` seconds of a commanded circle of
        ``radius`` at ``speed``: ``sqrt(R₀² + 2 · radial_gain · v_true² · t)``, ``R₀ = radius ·
        (1 − longitudinal) / (1 − angular)``. Round the commanded centre, the robot's distance
        from it stays within ``|R₀ − radius|`` of this."""
        vt = float(speed) * (1.0 - self.longitudinal)
        r0 = float(radius) * (1.0 - self.longitudinal) / (1.0 - self.angular)
        return np.sqrt(r0 * r0 + 2.0 * self.radial_gain * vt * vt * np.asarray(t, dtype=float))

    def true_motion(self, v: float, w: float, tau: ArrayLike) -> FloatArray:
        """Body-frame displacement ``(n, 3)`` of the robot after ``tau`` seconds of the command
        ``(v, w)`` started afresh (see the class docstring), closed form."""
        tau = np.asarray(tau, dtype=float)
        vt = float(v) * (1.0 - self.longitudinal)
        wt = float(w) * (1.0 - self.angular)
        if vt == 0.0 or wt == 0.0 or self.radial_gain == 0.0:
            return _arc(np.full_like(tau, vt), np.full_like(tau, wt), tau)
        r0 = abs(vt / wt)
        r = np.sqrt(r0 * r0 + 2.0 * self.radial_gain * vt * vt * tau)
        frac = 2.0 * r0 / (r + r0)  # mean of R0 / R(t') over [0, τ]: the turn rate falls as R grows
        dth = wt * tau * frac  # θ(τ) = ω_true·τ·2R₀/(R + R₀), exact for the growing radius
        h = 0.5 * dth
        s = vt * tau * frac  # arc length on the starting circle for that angle
        chord = s * _sinc(h)
        skid = 2.0 * self.radial_gain * vt * vt * tau / (r + r0)  # R - R0, outward
        side = math.copysign(1.0, vt * wt)  # the centre is on the left (+1) or right (-1)
        x = chord * np.cos(h) + side * skid * np.sin(dth)
        y = chord * np.sin(h) - side * skid * np.cos(dth)
        return np.stack([x, y, dth], axis=-1)


# --------------------------------------------------------------------------------------------
# Runs
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class SimulatedRun:
    """One simulated run: at each of ``n`` scan times ``stamps`` (s, from 0 at the scanner's
    rate), the true pose and the odometry pose (``(n, 3)`` arrays ``[x, y, θ]``, world frame,
    both starting at the start pose) and the scan taken there (``scans``, stamps set; empty when
    the run was made without scans). Arrays are read-only. The inputs are kept for reference."""

    stamps: FloatArray
    true_poses: FloatArray
    odometry_poses: FloatArray
    scans: list[LaserScan]
    world: World
    path: CommandedPath
    scanner: ScannerModel
    slip: SlipModel
    seed: int

    def __len__(self) -> int:
        return int(self.stamps.shape[0])

    @property
    def distance_travelled(self) -> FloatArray:
        """Distance along the true path from the start to each stamp, ``(n,)`` m (the last
        entry is the whole run's): the sum of the straight steps between consecutive scans,
        short of the arc by ``(step angle)² / 24`` (1e-5 on a 3 m circle at 10 Hz)."""
        step = np.hypot(*np.diff(self.true_poses[:, :2], axis=0).T)
        return np.concatenate([[0.0], np.cumsum(step)])

    @property
    def true_increments(self) -> FloatArray:
        """True increments ``⊖x_k ⊕ x_{k+1}`` between consecutive scans, ``(n − 1, 3)``."""
        return relative(self.true_poses[:-1], self.true_poses[1:])

    @property
    def odometry_increments(self) -> FloatArray:
        """Odometry increments ``⊖o_k ⊕ o_{k+1}`` between consecutive scans, ``(n − 1, 3)``."""
        return relative(self.odometry_poses[:-1], self.odometry_poses[1:])

    def true_pose(self, k: int) -> Pose2D:
        return Pose2D.from_array(self.true_poses[k])

    def odometry_pose(self, k: int) -> Pose2D:
        return Pose2D.from_array(self.odometry_poses[k])


def _seed(seed: Any) -> int:
    if isinstance(seed, (bool, np.bool_)) or int(seed) != seed or seed < 0:
        raise SimError(f"seed must be a non-negative integer, got {seed!r}")
    return int(seed)


def simulate_run(
    world: World,
    path: CommandedPath,
    scanner: ScannerModel | None = None,
    slip: SlipModel | None = None,
    seed: int = 0,
    start: Pose2D | ArrayLike | None = None,
    duration: float | None = None,
    *,
    with_scans: bool = True,
    max_step: float = MAX_STEP,
) -> SimulatedRun:
    """Drive ``path`` in ``world`` and record the truth, the odometry and the scans.

    ``scanner`` defaults to :meth:`ScannerModel.sick_lms200`, ``slip`` to :class:`SlipModel`'s
    B21r defaults. The robot starts at ``start`` (default ``path.start``) at time 0 and runs for
    ``duration`` seconds (default the path's; beyond it the robot stands still); scans are taken
    at ``k / scanner.rate_hz`` for every such time within the duration, at the true pose (so
    a path that does not last a whole number of scan periods ends after the last scan); scan
    ``k`` is the scanner's scan ``index=k`` (an interlaced scanner's start angles cycle).

    The true pose follows the slip model in closed form (exact, whatever the step). The
    odometry integrates the encoder reports on a grid of at most ``max_step`` seconds (100 Hz),
    subdivided at command changes, each step an exact arc of the reported distance and turn.
    ``seed`` seeds independent streams for the encoder noise and the scanner, so the same seed
    gives a bitwise identical run and ``with_scans=False`` the same truth and odometry.
    """
    if not isinstance(world, World):
        raise SimError(f"world must be a World, got {type(world).__name__}")
    if not isinstance(path, CommandedPath):
        raise SimError(f"path must be a CommandedPath, got {type(path).__name__}")
    scanner = ScannerModel.sick_lms200() if scanner is None else scanner
    slip = SlipModel() if slip is None else slip
    if not isinstance(scanner, ScannerModel):
        raise SimError(f"scanner must be a ScannerModel, got {type(scanner).__name__}")
    if not isinstance(slip, SlipModel):
        raise SimError(f"slip must be a SlipModel, got {type(slip).__name__}")
    seed = _seed(seed)
    x0 = (path.start if start is None else _as_pose(start)).as_array()
    total = path.duration if duration is None else _positive("duration", duration)
    max_step = _positive("max_step", max_step)

    # scan times k / rate and the integration grid: each scan period cut into m equal steps
    rate = scanner.rate_hz
    n = math.floor(total * rate + 1e-9) + 1
    m = max(1, math.ceil(1.0 / (rate * max_step) - 1e-9))
    fine = np.arange((n - 1) * m + 1) / (rate * m)
    stamps = fine[::m].copy()
    inner = path.boundaries[(path.boundaries > 0.0) & (path.boundaries < fine[-1])]
    grid = np.union1d(fine, inner)
    at_stamp = np.searchsorted(grid, stamps)

    ss_odo, ss_scan = np.random.SeedSequence(seed).spawn(2)
    true_poses = _true_poses(path, slip, x0, stamps)
    odo_poses = _odometry(path, slip, x0, grid, np.random.default_rng(ss_odo))[at_stamp]

    scans: list[LaserScan] = []
    if with_scans:
        rng = np.random.default_rng(ss_scan)
        scans = [
            simulate_scan(world, Pose2D.from_array(p), scanner, rng, float(t), index=k)
            for k, (p, t) in enumerate(zip(true_poses, stamps))
        ]
    return SimulatedRun(
        stamps=_readonly(stamps),
        true_poses=_readonly(true_poses),
        odometry_poses=_readonly(odo_poses),
        scans=scans,
        world=world,
        path=path,
        scanner=scanner,
        slip=slip,
        seed=seed,
    )


def _true_poses(path: CommandedPath, slip: SlipModel, x0: FloatArray, t: FloatArray) -> FloatArray:
    """True poses at times ``t`` (sorted): each command from the pose the last one reached."""
    out = np.empty((len(t), 3))
    pose = x0
    bounds = path.boundaries
    for i, (d, v, w) in enumerate(path.segments):
        t0, t1 = bounds[i], bounds[i + 1]
        sel = (t >= t0) & (t < t1)
        if sel.any():
            out[sel] = _compose_many(pose, slip.true_motion(v, w, t[sel] - t0))
        pose = _compose_many(pose, slip.true_motion(v, w, np.array([d]))[0])
    out[t >= bounds[-1]] = pose  # standing still after the last command
    return out


def _odometry(
    path: CommandedPath,
    slip: SlipModel,
    x0: FloatArray,
    grid: FloatArray,
    rng: np.random.Generator,
) -> FloatArray:
    """Odometry poses on ``grid``: the encoder reports (the commands, plus noise whose variance
    grows with the distance and the angle of each step) integrated as exact arcs."""
    dt = np.diff(grid)
    v, w = path.commands(0.5 * (grid[:-1] + grid[1:]))
    ds = v * dt
    dth = w * dt
    z = rng.standard_normal((len(dt), 2))
    if slip.translation_noise > 0.0:
        ds = ds + slip.translation_noise * np.sqrt(np.abs(ds)) * z[:, 0]
    if slip.rotation_noise > 0.0:
        dth = dth + slip.rotation_noise * np.sqrt(np.abs(dth)) * z[:, 1]
    heading = x0[2] + np.concatenate([[0.0], np.cumsum(dth)])
    h = 0.5 * dth
    mid = heading[:-1] + h
    chord = ds * _sinc(h)
    x = x0[0] + np.concatenate([[0.0], np.cumsum(chord * np.cos(mid))])
    y = x0[1] + np.concatenate([[0.0], np.cumsum(chord * np.sin(mid))])
    return np.stack([x, y, wrap_angle(heading)], axis=-1)
