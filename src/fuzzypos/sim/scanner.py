"""The scanning laser rangefinder: :class:`ScannerModel` and scan synthesis.

:func:`simulate_scan` turns a world and a robot pose into a :class:`~fuzzypos.scan.LaserScan`.
The range error follows the paper's error model (§2, eq. 1): the uncertainty grows with the
detection distance ``ρ`` and as the detection angle ``β`` (the angle between the beam and the
surface it hits; 90° = square-on, 0° = grazing) leaves 90°. Here that is a zero-mean Gaussian
with standard deviation

    σ(ρ, β) = range_noise_std + range_noise_per_metre · ρ + incidence_noise · (1 − sin β)

(:meth:`ScannerModel.range_std`), plus two kinds of outlier: dropouts (a beam reads "no return",
exactly ``range_max``) and spurious short returns (uniform between ``range_min`` and the true
range, e.g. dust, a passer-by or a mixed pixel). Every term is zero by default, so a plain
``ScannerModel()`` is an exact scanner; :meth:`ScannerModel.sick_lms200` gives realistic values.

Conventions (SPEC): SI units, radians inside the code (degrees only in ``*_deg`` fields), frames
as in ROS REP-103. A beam with no return reads exactly ``range_max``, which
:class:`~fuzzypos.scan.LaserScan` treats as invalid.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..geometry import Pose2D, wrap_angle
from ..scan import LaserScan
from .raycast import cast_rays
from .world import FloatArray, SimError, World, _readonly

__all__ = [
    "ScannerModel",
    "laser_pose",
    "simulate_scan",
    "simulate_scans",
    "visible_corners",
]


def _as_pose(pose: Pose2D | ArrayLike) -> Pose2D:
    if isinstance(pose, Pose2D):
        return pose
    try:
        return Pose2D.from_array(pose)
    except ValueError as exc:
        raise SimError(f"a pose must be a Pose2D or (x, y, theta), got {pose!r}: {exc}") from None


@dataclass(frozen=True)
class ScannerModel:
    """A scanning laser rangefinder, its error model and its mounting on the robot.

    Beam ``i`` points at ``angle_min + i * increment`` in the laser frame, with
    ``increment = field_of_view / n_beams`` (so 180 beams over 180° cover -90°..+89°; a 360°
    scanner closes the circle without a duplicated beam). A negative field of view scans
    clockwise (an upside-down mount). A beam with no return reads exactly ``range_max``.

    Error model (all zero by default: an exact scanner), applied to each beam independently:

    - ``range_noise_std`` (m), ``range_noise_per_metre`` (m per m of range) and
      ``incidence_noise`` (m): Gaussian range noise of std
      ``σ(ρ, β) = range_noise_std + range_noise_per_metre·ρ + incidence_noise·(1 − sin β)``
      for a return at true range ``ρ`` off a surface hit at detection angle ``β``
      (90° = square-on, where the last term vanishes; grazing adds the full
      ``incidence_noise``). Noisy readings are clipped to ``[range_min, range_max]``.
    - ``dropout_probability``: the beam reads "no return" (``range_max``).
    - ``spurious_probability``: the beam reads a short return, uniform in
      ``[range_min, min(true range, range_max))`` (noise-free).

    Dropout and spurious return exclude each other, so ``dropout_probability +
    spurious_probability`` must be at most 1 and each happens at exactly its own rate.
    ``rate_hz`` is the scan rate (scans per second), which sets the stamps of the scans of a
    simulated run (:func:`fuzzypos.sim.simulate_run`).

    Interlacing and no-return codes (off by default; scan ``k`` of a sequence is the ``index``
    of :func:`simulate_scan`, the scan number in :func:`simulate_scans` and a run):

    - ``start_angle_offsets_deg``: a cycle of offsets added to ``angle_min_deg`` scan by scan,
      ``offsets[k % len(offsets)]`` (a SICK LMS in interlaced mode: ``(0, 0.25, 0.5, 0.75)``
      with 1° between beams, so four scans together sample every 0.25°). The increment stays
      ``field_of_view / n_beams``.
    - ``beam_counts``: a cycle of beam counts, ``beam_counts[k % len(beam_counts)]`` instead of
      ``n_beams`` (the interlaced SICK: 181 beams at offset 0, -90°..+90°, 180 at the others);
      when both cycles are given they must have the same length.
    - ``no_return_value``: what a beam with no return reads (nothing within ``range_max``, or a
      dropout); None (default) is ``range_max``, which :class:`~fuzzypos.scan.LaserScan` treats
      as invalid. A SICK reports a no-return code below its maximum range (81.83 m under
      81.9 m), which a scan sees as a valid reading: a consumer has to recognise the code.
    """

    n_beams: int = 180
    field_of_view_deg: float = 180.0
    angle_min_deg: float = -90.0
    range_max: float = 8.0
    range_min: float = 0.02
    range_noise_std: float = 0.0
    sensor_pose: Pose2D = field(default_factory=Pose2D)
    range_noise_per_metre: float = 0.0
    incidence_noise: float = 0.0
    dropout_probability: float = 0.0
    spurious_probability: float = 0.0
    rate_hz: float = 10.0
    start_angle_offsets_deg: tuple[float, ...] = ()
    beam_counts: tuple[int, ...] = ()
    no_return_value: float | None = None

    def __post_init__(self) -> None:
        if isinstance(self.n_beams, bool) or int(self.n_beams) != self.n_beams or self.n_beams < 1:
            raise SimError(f"n_beams must be a positive integer, got {self.n_beams!r}")
        object.__setattr__(self, "n_beams", int(self.n_beams))
        names = (
            "field_of_view_deg",
            "angle_min_deg",
            "range_max",
            "range_min",
            "range_noise_std",
            "range_noise_per_metre",
            "incidence_noise",
            "dropout_probability",
            "spurious_probability",
            "rate_hz",
        )
        for name in names:
            raw = getattr(self, name)
            if isinstance(raw, (bool, np.bool_)):
                raise SimError(f"ScannerModel.{name} must be a number, got {raw!r}")
            try:
                v = float(raw)
            except (TypeError, ValueError):
                raise SimError(f"ScannerModel.{name} must be a number, got {raw!r}") from None
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
        for name in ("range_noise_std", "range_noise_per_metre", "incidence_noise"):
            if getattr(self, name) < 0.0:
                raise SimError(f"{name} must be >= 0, got {getattr(self, name)}")
        for name in ("dropout_probability", "spurious_probability"):
            p = getattr(self, name)
            if not 0.0 <= p <= 1.0:
                raise SimError(f"{name} must be in [0, 1], got {p}")
        if self.dropout_probability + self.spurious_probability > 1.0:
            raise SimError(
                "dropout_probability + spurious_probability must be at most 1, got "
                f"{self.dropout_probability} + {self.spurious_probability}"
            )
        if not self.rate_hz > 0.0:
            raise SimError(f"rate_hz must be positive, got {self.rate_hz}")
        object.__setattr__(self, "sensor_pose", _as_pose(self.sensor_pose))
        self._check_cycles()

    def _check_cycles(self) -> None:
        """Validate the interlacing cycles and the no-return code (class docstring)."""
        try:
            offsets = tuple(float(v) for v in self.start_angle_offsets_deg)
            counts = tuple(self.beam_counts)
        except (TypeError, ValueError):
            raise SimError(
                "start_angle_offsets_deg and beam_counts must be sequences of numbers, got "
                f"{self.start_angle_offsets_deg!r}, {self.beam_counts!r}"
            ) from None
        if not all(math.isfinite(v) for v in offsets):
            raise SimError(f"start_angle_offsets_deg must be finite, got {offsets}")
        for c in counts:
            if isinstance(c, (bool, np.bool_)) or int(c) != c or c < 1:
                raise SimError(f"beam_counts must be positive integers, got {counts}")
        counts = tuple(int(c) for c in counts)
        if offsets and counts and len(offsets) != len(counts):
            raise SimError(
                f"start_angle_offsets_deg ({len(offsets)}) and beam_counts ({len(counts)}) "
                "must have the same length"
            )
        object.__setattr__(self, "start_angle_offsets_deg", offsets)
        object.__setattr__(self, "beam_counts", counts)
        v = self.no_return_value
        if v is not None:
            if isinstance(v, (bool, np.bool_)):
                raise SimError(f"no_return_value must be a number or None, got {v!r}")
            try:
                v = float(v)
            except (TypeError, ValueError):
                raise SimError(f"no_return_value must be a number or None, got {v!r}") from None
            if not (math.isfinite(v) and self.range_min < v <= self.range_max):
                raise SimError(
                    f"no_return_value must be in (range_min, range_max] = ({self.range_min}, "
                    f"{self.range_max}], got {v}"
                )
            object.__setattr__(self, "no_return_value", v)

    @classmethod
    def sick_lms200(cls, **overrides: Any) -> ScannerModel:
        """A SICK LMS200 as on the paper's iRobot B21r, in a gym; ``overrides`` replace fields.

        - 180 beams over 180° (1° apart, -90°..+89°), ``range_max`` 8.0 m: the LMS200's
          millimetre mode (8 m range), and the SPEC's ρ_max = 8 m; ``range_min`` 0.02 m.
        - ``range_noise_std`` 0.01 m + ``range_noise_per_metre`` 0.005 m/m: σ grows from 1 cm
          near the scanner to 3 cm at 4 m and 5 cm at 8 m (the SPEC's σ_max = 5 cm); more than
          the datasheet's few millimetres for bright targets, allowing for dull and glossy
          surfaces in a real hall.
        - ``incidence_noise`` 0.02 m: up to 2 cm more at grazing incidence (1 cm at β = 30°).
        - ``dropout_probability`` 0.01 (1% of beams return nothing: black or mirror-like
          surfaces), ``spurious_probability`` 0.002 (0.2% short returns).
        - ``rate_hz`` 10: ten scans a second (the mirror turns faster; how many scans arrive
          depends on the serial link, from a few to a few tens a second).
        """
        values: dict[str, Any] = {
            "n_beams": 180,
            "field_of_view_deg": 180.0,
            "angle_min_deg": -90.0,
            "range_max": 8.0,
            "range_min": 0.02,
            "range_noise_std": 0.01,
            "range_noise_per_metre": 0.005,
            "incidence_noise": 0.02,
            "dropout_probability": 0.01,
            "spurious_probability": 0.002,
            "rate_hz": 10.0,
        }
        values.update(overrides)
        return cls(**values)

    def replace(self, **changes: Any) -> ScannerModel:
        """A copy with some fields changed (``dataclasses.replace``, validated again)."""
        return replace(self, **changes)

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

    @property
    def scan_period(self) -> float:
        """Seconds between scans, ``1 / rate_hz``."""
        return 1.0 / self.rate_hz

    @property
    def has_range_noise(self) -> bool:
        """Whether any Gaussian range-noise term is non-zero."""
        return (
            self.range_noise_std > 0.0
            or self.range_noise_per_metre > 0.0
            or self.incidence_noise > 0.0
        )

    @property
    def has_outliers(self) -> bool:
        """Whether dropouts or spurious returns can happen."""
        return self.dropout_probability > 0.0 or self.spurious_probability > 0.0

    @property
    def is_noisy(self) -> bool:
        """Whether a scan draws random numbers (any noise or outlier term is non-zero)."""
        return self.has_range_noise or self.has_outliers

    def range_std(self, rho: ArrayLike, beta: ArrayLike) -> FloatArray:
        """σ(ρ, β) = ``range_noise_std + range_noise_per_metre·ρ + incidence_noise·(1 − sin β)``
        for true ranges ``rho`` (m) and detection angles ``beta`` (radians, 90° = square-on);
        ``beta`` is folded into [0, π/2] (only ``|sin β|`` matters)."""
        rho = np.asarray(rho, dtype=float)
        sin_beta = np.abs(np.sin(np.asarray(beta, dtype=float)))
        return self._range_std(rho, sin_beta)

    def _range_std(self, rho: FloatArray, sin_beta: FloatArray) -> FloatArray:
        sigma = self.range_noise_std + self.range_noise_per_metre * rho
        if self.incidence_noise > 0.0:
            sigma = sigma + self.incidence_noise * (1.0 - sin_beta)
        return np.broadcast_to(sigma, np.broadcast_shapes(rho.shape, sin_beta.shape))

    @property
    def no_return(self) -> float:
        """What a beam with no return reads: ``no_return_value``, else ``range_max``."""
        return self.range_max if self.no_return_value is None else self.no_return_value

    @property
    def is_interlaced(self) -> bool:
        """Whether the start angle or the beam count changes from scan to scan."""
        return bool(self.start_angle_offsets_deg) or bool(self.beam_counts)

    def scan_angle_min(self, index: int = 0) -> float:
        """Bearing of the first beam of scan ``index`` of a sequence (radians): ``angle_min``
        plus that scan's start-angle offset."""
        offsets = self.start_angle_offsets_deg
        if not offsets:
            return self.angle_min
        return math.radians(self.angle_min_deg + offsets[index % len(offsets)])

    def scan_n_beams(self, index: int = 0) -> int:
        """The beam count of scan ``index`` of a sequence."""
        counts = self.beam_counts
        return counts[index % len(counts)] if counts else self.n_beams

    def angles(self, index: int = 0) -> FloatArray:
        """Beam bearings in the laser frame of scan ``index`` of a sequence (radians; the same
        for every scan unless interlaced), ``(scan_n_beams(index),)``."""
        n = self.scan_n_beams(index)
        return self.scan_angle_min(index) + np.arange(n, dtype=np.float64) * self.angle_increment

    def covers(self, bearings: ArrayLike) -> NDArray[np.bool_]:
        """Whether laser-frame bearings lie within the swept beams (first to last beam; scan 0's
        beams for an interlaced scanner)."""
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


def _true_ranges(
    world: World, lp: Pose2D, scanner: ScannerModel, index: int = 0
) -> tuple[FloatArray, FloatArray]:
    """True ranges (``inf`` for no return within ``range_max``) and ``sin β`` of every beam of
    scan ``index`` (``|sin|`` of the angle between the beam and the wall it hits; 0 for no
    return)."""
    ang = lp.theta + scanner.angles(index)
    r, idx = cast_rays(world, (lp.x, lp.y), ang, scanner.range_max, return_segment=True)
    sin_beta = np.zeros(ang.shape[0])
    hit = idx >= 0
    if hit.any():
        seg = world.segments[idx[hit]]
        ex, ey = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
        dx, dy = np.cos(ang[hit]), np.sin(ang[hit])
        sin_beta[hit] = np.abs(dx * ey - dy * ex) / np.hypot(ex, ey)
    return r, sin_beta


def simulate_scan(
    world: World,
    robot_pose: Pose2D | ArrayLike,
    scanner: ScannerModel = ScannerModel(),
    rng: np.random.Generator | None = None,
    stamp: float = 0.0,
    *,
    index: int = 0,
) -> LaserScan:
    """Simulate one scan of ``world`` by ``scanner`` on a robot at ``robot_pose``; ``index`` is
    the scan's number in a sequence, which picks an interlaced scanner's start angle and beam
    count (:class:`ScannerModel`).

    Beams with no return within ``range_max`` read ``range_max`` (the scanner's
    ``no_return_value`` when set, here and for dropouts). Gaussian noise of std
    σ(ρ, β) (:meth:`ScannerModel.range_std`) is added to hits at or beyond ``range_min`` and the
    result clipped to ``[range_min, range_max]``; a hit nearer than ``range_min`` is reported
    noise-free at its true range (below ``range_min``, so invalid). Then each beam drops out
    (reads ``range_max``) with ``dropout_probability`` or else reads a spurious short return,
    uniform in ``[range_min, min(true range, range_max))``, with ``spurious_probability``.

    Random numbers: with range noise on, one standard normal per beam; with outliers on, two
    uniforms per beam after it. So the stream advances by a fixed amount per scan whatever is
    hit, and with only ``range_noise_std`` set the draws are those of earlier versions. ``rng``
    defaults to a fresh unseeded generator when the scanner is noisy. The scan's
    ``sensor_pose`` is the scanner's.
    """
    lp = laser_pose(robot_pose, scanner)
    r, sin_beta = _true_ranges(world, lp, scanner, index)
    n = int(r.shape[0])
    hit = np.isfinite(r)
    ranges = np.where(hit, r, scanner.range_max)
    no_return: NDArray[np.bool_] = np.logical_not(hit)  # the beams that read "no return"
    if scanner.is_noisy and rng is None:
        rng = np.random.default_rng()
    if scanner.has_range_noise:
        assert rng is not None
        z = rng.standard_normal(n)
        noise = scanner._range_std(ranges, sin_beta) * z
        noisy = hit & (r >= scanner.range_min)
        ranges = np.where(
            noisy, np.clip(ranges + noise, scanner.range_min, scanner.range_max), ranges
        )
    if scanner.has_outliers:
        assert rng is not None
        u = rng.random(n)
        w = rng.random(n)
        p_drop = scanner.dropout_probability
        drop = u < p_drop
        top = np.minimum(r, scanner.range_max)  # the true range, range_max for no return
        spurious = (u >= p_drop) & (u < p_drop + scanner.spurious_probability)
        spurious &= top > scanner.range_min
        short = scanner.range_min + w * (top - scanner.range_min)
        ranges = np.where(drop, scanner.range_max, np.where(spurious, short, ranges))
        no_return = (no_return & np.logical_not(spurious)) | drop
    if scanner.no_return_value is not None:
        ranges = np.where(no_return, scanner.no_return_value, ranges)
    return LaserScan(
        ranges,
        angle_min=scanner.scan_angle_min(index),
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
    """One :func:`simulate_scan` per pose, sharing ``rng`` (pose ``i`` is scan ``index=i``);
    ``stamps`` default to 0, 1, 2, ..."""
    pose_list = [_as_pose(p) for p in poses]
    if stamps is None:
        stamp_list = [float(i) for i in range(len(pose_list))]
    else:
        stamp_list = [float(s) for s in stamps]
        if len(stamp_list) != len(pose_list):
            raise SimError(f"got {len(pose_list)} poses but {len(stamp_list)} stamps")
    if rng is None and scanner.is_noisy:
        rng = np.random.default_rng()
    return [
        simulate_scan(world, p, scanner, rng, s, index=i)
        for i, (p, s) in enumerate(zip(pose_list, stamp_list))
    ]


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
