"""2D laser scans shaped like ROS ``sensor_msgs/LaserScan`` (SPEC, "Conventions").

Beam ``i`` is at bearing ``angle_min + i*angle_increment`` (radians, counter-clockwise, x
forward as in REP-103); a negative increment (upside-down mount) is allowed. A reading is
valid iff it is finite, ``> 0`` and ``range_min <= r < range_max``: 0, NaN and ±inf are invalid
(REP-117), and so is a reading at the maximum ("no return"). A reading of
:data:`ABSURD_RANGE_M` (100 km) or more is invalid whatever ``range_max`` says (a log's
``range_max`` may be unknown, i.e. infinite): no 2D lidar measures that far, such values are
corrupt (``1e308``), and their squares would overflow. Invalid readings are data, not
errors; malformed metadata raises :class:`ScanError`.

Some scanners also report "no return" as codes below their maximum (SICK in cm mode: 81.83 …
81.91 m). :func:`no_return_mask` marks the readings inside such bands (``config.scanner``),
:func:`usable` is ``valid`` without them: the readings that become points.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import FuzzyposError
from .geometry import Pose2D, transform_points

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = [
    "ABSURD_RANGE_M",
    "ScanError",
    "LaserScan",
    "no_return_mask",
    "no_return_counts",
    "usable",
]

#: slack on the "at most one turn" check, radians (float round-off of n*increment)
_TURN_TOL = 1e-9

#: a "no return" band's bounds widen by this fraction of themselves: one float32 epsilon, twice
#: the rounding of a float32 reading (ROS bags), so that 81.91 stored as 81.9100037 still matches
NO_RETURN_SLACK = 2.0**-23


#: a reading this far (metres) or further is no lidar's measurement: invalid (module docstring)
ABSURD_RANGE_M = 1.0e5


class ScanError(FuzzyposError, ValueError):
    """A malformed :class:`LaserScan` (the message names the offending field)."""


def _as_ranges(ranges: ArrayLike, name: str = "ranges") -> FloatArray:
    """A read-only 1-D float64 copy of ``ranges``; ScanError if not 1-D and numeric."""
    try:
        arr = np.asarray(ranges)
    except (TypeError, ValueError) as exc:  # ragged sequences etc.
        raise ScanError(f"LaserScan.{name} must be a 1-D numeric array: {exc}") from None
    if arr.ndim != 1:
        raise ScanError(f"LaserScan.{name} must be 1-D, got shape {arr.shape}")
    if arr.dtype.kind not in "iuf":
        raise ScanError(f"LaserScan.{name} must be numeric (int or float), got dtype {arr.dtype}")
    out = np.array(arr, dtype=np.float64, copy=True)
    out.setflags(write=False)
    return out


def _as_real(name: str, value: Any) -> float:
    """``value`` as a Python float; ScanError naming ``name`` if it is not a real number."""
    if isinstance(value, (bool, np.bool_, str, bytes)):
        raise ScanError(f"LaserScan.{name} must be a real number, got {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ScanError(f"LaserScan.{name} must be a real number, got {value!r}") from None


@dataclass(frozen=True, eq=False)
class LaserScan:
    """One 2D laser scan (ROS ``LaserScan`` semantics, SPEC "Conventions").

    ``ranges`` are metres, angles radians, ``stamp`` float seconds; ``sensor_pose`` is the
    sensor's pose on the robot (default the origin). ``angles`` and ``valid`` are computed
    once at construction; all arrays are read-only.
    """

    ranges: FloatArray
    angle_min: float
    angle_increment: float
    range_min: float = 0.0
    range_max: float = math.inf
    stamp: float = 0.0
    sensor_pose: Pose2D = field(default=Pose2D(0.0, 0.0, 0.0))

    if TYPE_CHECKING:
        # Derived in __post_init__; declared for the type checker only (not dataclass fields).
        _angles: FloatArray = field(init=False, repr=False)
        _valid: BoolArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        ranges = _as_ranges(self.ranges)
        object.__setattr__(self, "ranges", ranges)

        for name in ("angle_min", "angle_increment", "stamp"):
            v = _as_real(name, getattr(self, name))
            if not math.isfinite(v):
                raise ScanError(f"LaserScan.{name} must be finite, got {v}")
            object.__setattr__(self, name, v)
        if self.angle_increment == 0.0:
            raise ScanError("LaserScan.angle_increment must be non-zero")

        rmin = _as_real("range_min", self.range_min)
        if math.isnan(rmin) or rmin < 0.0:
            raise ScanError(f"LaserScan.range_min must be >= 0, got {rmin}")
        rmax = _as_real("range_max", self.range_max)
        if math.isnan(rmax) or rmax <= rmin:
            raise ScanError(f"LaserScan.range_max must be > range_min ({rmin}), got {rmax}")
        object.__setattr__(self, "range_min", rmin)
        object.__setattr__(self, "range_max", rmax)

        if not isinstance(self.sensor_pose, Pose2D):
            raise ScanError(
                f"LaserScan.sensor_pose must be a Pose2D, got {type(self.sensor_pose).__name__}"
            )

        n = ranges.shape[0]
        inc = self.angle_increment
        if n > 1 and abs(inc) * (n - 1) > 2.0 * math.pi + _TURN_TOL:
            raise ScanError(
                f"LaserScan.angle_increment {inc} spans {abs(inc) * (n - 1)} rad over "
                f"{n} beams, more than one turn (2*pi)"
            )

        angles = self.angle_min + np.arange(n, dtype=np.float64) * inc
        angles.setflags(write=False)
        with np.errstate(invalid="ignore"):
            valid = (
                np.isfinite(ranges)
                & (ranges > 0.0)
                & (ranges >= rmin)
                & (ranges < min(rmax, ABSURD_RANGE_M))
            )
        valid.setflags(write=False)
        object.__setattr__(self, "_angles", angles)
        object.__setattr__(self, "_valid", valid)

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickled (a process pool's, Ray's): the arrays read-only again, as constructed
        (pickle hands them back writable, which the compiled kernels would also take for
        another type, compiled anew)."""
        for value in state.values():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
        self.__dict__.update(state)

    # -- construction ------------------------------------------------------------------
    @classmethod
    def from_angles(
        cls,
        ranges: ArrayLike,
        angle_min: float,
        angle_max: float,
        *,
        angle_increment: float | None = None,
        **kw: Any,
    ) -> LaserScan:
        """Build from ROS ``angle_min``/``angle_max``: ``angle_max = angle_min + (n-1)*inc``.

        With fewer than 2 beams the increment cannot be derived and ``angle_increment`` must be
        given (then ``angle_max`` must equal ``angle_min`` for one beam). With 2 or more beams a
        given ``angle_increment`` must agree with the derived one. ``kw`` go to the constructor.
        """
        r = _as_ranges(ranges)
        n = r.shape[0]
        a0 = _as_real("angle_min", angle_min)
        a1 = _as_real("angle_max", angle_max)
        if not math.isfinite(a1):
            raise ScanError(f"LaserScan.angle_max must be finite, got {a1}")
        if n < 2:
            if angle_increment is None:
                raise ScanError(
                    f"LaserScan.angle_increment must be given explicitly for a scan of {n} beam(s)"
                )
            if n == 1 and not math.isclose(a0, a1, rel_tol=0.0, abs_tol=1e-9):
                raise ScanError(
                    f"LaserScan.angle_max must equal angle_min for a single beam, got {a1} != {a0}"
                )
            inc = angle_increment
        else:
            inc = (a1 - a0) / (n - 1)
            if angle_increment is not None:
                given = _as_real("angle_increment", angle_increment)
                if not math.isclose(given, inc, rel_tol=1e-9, abs_tol=1e-12):
                    raise ScanError(
                        f"LaserScan.angle_increment {given} disagrees with "
                        f"(angle_max - angle_min)/(n-1) = {inc}"
                    )
        return cls(r, a0, inc, **kw)

    def with_ranges(self, new_ranges: ArrayLike) -> LaserScan:
        """A copy with other ranges (same beam count) and the same metadata."""
        r = _as_ranges(new_ranges)
        if r.shape != self.ranges.shape:
            raise ScanError(f"LaserScan.ranges must keep {self.n_beams} beams, got {r.shape[0]}")
        return dataclasses.replace(self, ranges=r)

    # -- derived quantities ------------------------------------------------------------
    @property
    def n_beams(self) -> int:
        return int(self.ranges.shape[0])

    @property
    def angles(self) -> FloatArray:
        """Bearings ``angle_min + i*angle_increment`` (not wrapped), shape ``(n,)``."""
        return self._angles

    @property
    def valid(self) -> BoolArray:
        """``finite & r > 0 & range_min <= r < range_max``, shape ``(n,)``."""
        return self._valid

    @property
    def field_of_view(self) -> float:
        """``n * |angle_increment|`` radians (each beam covers one increment)."""
        return self.n_beams * abs(self.angle_increment)

    @property
    def is_full_circle(self) -> bool:
        """True when the beams close a turn (``n*|inc| >= 2*pi - |inc|/2``): indices wrap."""
        inc = abs(self.angle_increment)
        return self.n_beams * inc >= 2.0 * math.pi - inc / 2.0

    def points_sensor(self, no_return_bands: Sequence[tuple[float, float]] = ()) -> FloatArray:
        """All beams as ``(n, 2)`` points in the sensor frame; NaN rows for invalid beams and
        for readings in ``no_return_bands`` (see :func:`usable`)."""
        r = np.where(usable(self, no_return_bands), self.ranges, np.nan)
        return np.stack([r * np.cos(self.angles), r * np.sin(self.angles)], axis=-1)

    def points_robot(self, no_return_bands: Sequence[tuple[float, float]] = ()) -> FloatArray:
        """:meth:`points_sensor` moved into the robot frame by ``sensor_pose``."""
        return transform_points(self.sensor_pose.as_array(), self.points_sensor(no_return_bands))


# -- "no return" codes below range_max ------------------------------------------------------
def _band_bounds(bands: Sequence[tuple[float, float]]) -> tuple[FloatArray, FloatArray]:
    """The bands' widened ``(low, high)`` as arrays; ScanError for a malformed band."""
    lo, hi = [], []
    for i, band in enumerate(bands):
        try:
            low, high = (float(b) for b in band)
        except (TypeError, ValueError):
            raise ScanError(
                f"no-return band {i} must be a (low, high) pair, got {band!r}"
            ) from None
        if not (math.isfinite(low) and math.isfinite(high) and 0.0 <= low <= high):
            raise ScanError(f"no-return band {i} needs finite 0 <= low <= high, got {band!r}")
        lo.append(low * (1.0 - NO_RETURN_SLACK))
        hi.append(high * (1.0 + NO_RETURN_SLACK))
    return np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64)


@functools.lru_cache(maxsize=16)
def _band_bounds_cached(bands: tuple[tuple[float, float], ...]) -> tuple[FloatArray, FloatArray]:
    """:func:`_band_bounds` of a configuration's (hashable) bands, computed once (read-only)."""
    lo, hi = _band_bounds(bands)
    lo.setflags(write=False)
    hi.setflags(write=False)
    return lo, hi


def _in_bands(ranges: ArrayLike, bands: Sequence[tuple[float, float]]) -> BoolArray:
    """``(n_bands, n)``: reading ``j`` lies in band ``i`` (bounds widened, NaN in none)."""
    r = np.asarray(ranges, dtype=np.float64).reshape(-1)
    try:
        lo, hi = _band_bounds_cached(bands) if isinstance(bands, tuple) else _band_bounds(bands)
    except TypeError:  # a tuple holding something unhashable: as given
        lo, hi = _band_bounds(bands)
    with np.errstate(invalid="ignore"):
        return (r[None, :] >= lo[:, None]) & (r[None, :] <= hi[:, None])


def no_return_mask(ranges: ArrayLike, bands: Sequence[tuple[float, float]]) -> BoolArray:
    """Which readings lie in a "no return" band: ``low·(1-s) <= r <= high·(1+s)`` for some
    ``(low, high)`` of ``bands`` (metres, inclusive; ``s`` = :data:`NO_RETURN_SLACK`).

    Shape ``(n,)``; NaN and readings outside every band are False; no bands, all False.
    ScanError for a band that is not a finite ``0 <= low <= high`` pair."""
    return np.asarray(_in_bands(ranges, bands).any(axis=0), dtype=np.bool_)


def no_return_counts(
    ranges: ArrayLike, bands: Sequence[tuple[float, float]], among: ArrayLike | None = None
) -> list[int]:
    """How many readings (of those where ``among`` is True, default all) each band holds; a
    reading in several bands counts for the first of them only, so the counts add up to
    ``no_return_mask(ranges, bands)[among].sum()``."""
    inside = _in_bands(ranges, bands)
    if among is not None:
        inside &= np.asarray(among, dtype=np.bool_).reshape(-1)[None, :]
    first = inside & (np.cumsum(inside, axis=0) == 1)
    return [int(c) for c in first.sum(axis=1)]


def usable(scan: LaserScan, bands: Sequence[tuple[float, float]]) -> BoolArray:
    """The readings that become points: :attr:`LaserScan.valid` and in no "no return" band."""
    if not bands:
        return scan.valid
    return scan.valid & ~no_return_mask(scan.ranges, bands)
