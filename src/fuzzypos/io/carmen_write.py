"""Writing CARMEN logs: one streaming writer, :class:`CarmenWriter`, for both of fuzzypos's
uses.

- :func:`write_carmen` (``estimate_of=None``): a log the way CARMEN's simulator writes it
  (``x y θ`` repeat the odometry); every scan must fit one given FLASER beam geometry and
  share one laser (a pure forward mounting offset, one ``range_max``), else ``ValueError``.
- the run job's ``trajectory.clf`` (``estimate_of=<the log's name>``, see
  :func:`fuzzypos.jobs.run.write_estimate_clf`): ``x y θ`` carry the estimate and
  ``odom_x odom_y odom_θ`` the log's odometry; the FLASER beam geometry is taken from the
  first scan, and a scan FLASER cannot describe (other beam angles, a laser mounted off the
  robot's x axis, a mount that changes) gets a ``ROBOTLASER1`` line instead, with its own
  angles and mount, the estimate as ``robot_x robot_y robot_θ`` and the log's odometry in an
  ``ODOM`` line with the same stamp just before it.

One ``FLASER n r_1 … r_n x y θ odom_x odom_y odom_θ ipc_timestamp hostname
logger_timestamp`` (or ``ROBOTLASER1``) line per scan (both timestamps the scan's stamp,
``repr``), then ``TRUEPOS`` where the truth is given; poses at full precision (``repr``),
ranges to 0.1 mm.
The file is written to a temporary file next to where ``path`` points (through symlinks)
that :meth:`CarmenWriter.close` renames over it (:meth:`CarmenWriter.abort` removes it), so a
failure leaves no partial log; a pipe or character device is written to directly
(:func:`~fuzzypos.io._common.output_target`). One scan is held at a time (but with
``poses_at_close``, which holds them all for poses known at the end); a failure to write is
an :class:`~fuzzypos.io._common.OutputWriteError` naming ``path``.
"""

from __future__ import annotations

import contextlib
import gzip
import io
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import IO, Any, cast

import numpy as np
from numpy.typing import NDArray

from .._version import __version__
from ..errors import Argument, ArgumentError, Words
from ..geometry import Pose2D
from ..scan import ABSURD_RANGE_M, LaserScan
from ._common import LogRecord, OutputWriteError, PathLike, _naming, output_target
from ._flaser import GEOMETRY_TOL, RANGE_DECIMALS, carmen_beam_geometry, check_convention, check_fov

__all__ = ["CarmenWriter", "flaser_geometry", "write_carmen"]

FloatArray = NDArray[np.float64]


# -- beam geometry and ranges ----------------------------------------------------------------
def flaser_geometry(scan: LaserScan) -> tuple[float, str] | None:
    """``(field_of_view_deg, convention)`` under which FLASER's beam angles are this scan's,
    preferring ``"auto"``; None when no FLASER convention gives them."""
    n, inc, a0 = scan.n_beams, scan.angle_increment, scan.angle_min
    if n < 2 or inc <= 0.0:
        return None
    for convention, span in (("resolution", n * inc), ("span", (n - 1) * inc)):
        fov = math.degrees(span)
        if not 0.0 < fov <= 360.0:
            continue
        if abs(a0 + span / 2.0) > GEOMETRY_TOL:
            continue
        fov = round(fov, 9)
        auto = "resolution" if n % 2 == 0 else "span"
        return (fov, "auto" if convention == auto else convention)
    return None


def _misfit(scan: LaserScan, fov: float, convention: str) -> tuple[float, float] | None:
    """FLASER's ``(angle_min, angle_increment)`` for the scan's beam count when the scan's own
    differ from them; None when they agree (the scan needs >= 2 beams)."""
    n = scan.n_beams
    a0, inc = carmen_beam_geometry(n, fov, convention)
    if (
        abs(scan.angle_min - a0) > GEOMETRY_TOL
        or abs(scan.angle_increment - inc) * n > GEOMETRY_TOL
    ):
        return a0, inc
    return None


_SCALE = 10**RANGE_DECIMALS
#: the integer parts the tables cover (beyond them, the per-value path)
_INT_WIDTH = 5


def _fixed_text(values: FloatArray) -> str | None:
    """The finite ``values`` as ``f"{v:.4f}".rstrip("0").removesuffix(".")`` each (to
    ``RANGE_DECIMALS``), space-separated, in one compiled loop (``fuzzypos._kernels.text``);
    None where that cannot be sure of the same text (a value within rounding error of a tie at
    the last decimal, or of ``10**_INT_WIDTH`` or more), for the caller's exact per-value
    path."""
    from .._kernels.text import fixed_text

    ok, text = fixed_text(
        np.ascontiguousarray(values, dtype=np.float64), _SCALE, RANGE_DECIMALS, _INT_WIDTH
    )
    return text.tobytes().decode("ascii") if ok else None


def _ranges_filled(scan: LaserScan, fill: str) -> str:
    """:func:`write_carmen`'s ranges: valid readings to 0.1 mm (full precision where rounding
    would move them across 0 or ``range_max``), invalid ones as ``fill``."""
    r = scan.ranges
    valid = scan.valid
    rounded = _rounded(r)
    exact = valid & ((rounded >= scan.range_max) | (rounded <= 0.0))
    if not exact.any() and fill in ("0", _fixed_text(np.array([scan.range_max]))):
        fast = _fixed_text(np.where(valid, r, 0.0 if fill == "0" else scan.range_max))
        if fast is not None:
            return fast
    return _ranges_filled_exact(scan, fill)


def _ranges_filled_exact(scan: LaserScan, fill: str) -> str:
    """:func:`_ranges_filled` one reading at a time (and the reference of the vectorised one)."""
    r, valid = scan.ranges, scan.valid
    rounded = _rounded(r)
    exact = valid & ((rounded >= scan.range_max) | (rounded <= 0.0))
    out: list[str] = []
    for v, ok, ex in zip(r.tolist(), valid.tolist(), exact.tolist()):
        if not ok:
            out.append(fill)
        elif ex:
            out.append(repr(v))
        else:
            out.append(f"{v:.{RANGE_DECIMALS}f}".rstrip("0").removesuffix("."))
    return " ".join(out)


def _rounded(r: FloatArray) -> FloatArray:
    """``r`` rounded to ``RANGE_DECIMALS`` (values too large to scale stay as they are)."""
    with np.errstate(over="ignore", invalid="ignore"):
        rounded = np.round(r, RANGE_DECIMALS)
    return np.where(np.isfinite(rounded), rounded, r)


def _odd(v: float) -> bool:
    """A reading written as read (``repr``): NaN, ±inf, or absurdly far (invalid, never
    rounded into hundreds of digits)."""
    return not math.isfinite(v) or abs(v) >= ABSURD_RANGE_M


def _ranges_raw(scan: LaserScan) -> str:
    """The estimate log's ranges: the raw readings (as the log gave them) to 0.1 mm; a valid
    reading that rounding would move onto ``range_max`` or 0 at full precision; NaN, ±inf
    and readings of :data:`~fuzzypos.scan.ABSURD_RANGE_M` or more as read (``repr``:
    ``nan``, ``inf``, ``1e+308``), which read back invalid."""
    r = scan.ranges
    with np.errstate(invalid="ignore"):
        odd = ~(np.abs(r) < ABSURD_RANGE_M)
    rounded = _rounded(r)
    if not odd.any() and not (scan.valid & ((rounded >= scan.range_max) | (rounded <= 0.0))).any():
        fast = _fixed_text(r)
        if fast is not None:
            return fast
    return _ranges_raw_exact(scan)


def _ranges_raw_exact(scan: LaserScan) -> str:
    """:func:`_ranges_raw` one reading at a time (and the reference of the vectorised one)."""
    out: list[str] = []
    rmax = scan.range_max
    for v, ok in zip(scan.ranges.tolist(), scan.valid.tolist()):
        if _odd(v):
            out.append(repr(v))
            continue
        r = round(v, RANGE_DECIMALS)
        if ok and (r >= rmax or r <= 0.0):
            out.append(repr(v))
        else:
            out.append(f"{r:.{RANGE_DECIMALS}f}".rstrip("0").removesuffix("."))
    return " ".join(out)


def _pose_text(p: Pose2D) -> str:
    return f"{p.x!r} {p.y!r} {p.theta!r}"


@dataclass(frozen=True, slots=True)
class _Held:
    """A scan's lines held for its pose (:class:`CarmenWriter` with ``poses_at_close``): the
    text before and after the estimate's fields, the laser's mount (ROBOTLASER1, whose laser
    pose comes first) or None (FLASER), and the pose it was given."""

    before: str
    mount: Pose2D | None
    after: str
    pose: Pose2D


def _held_text(held: _Held, pose: Pose2D) -> str:
    """A held scan's lines at ``pose``: FLASER's ``x y θ``; ROBOTLASER1's laser pose (``pose``
    composed with the mount) and robot pose."""
    at = _pose_text(pose)
    if held.mount is None:
        return f"{held.before}{at}{held.after}"
    return f"{held.before}{_pose_text(pose.compose(held.mount))} {at}{held.after}"


# -- the writer ------------------------------------------------------------------------------
_FORMATS = "# message formats defined: PARAM FLASER TRUEPOS\n"
_FLASER_FORMAT = "# FLASER num_readings [range_readings] x y theta odom_x odom_y odom_theta\n"
_TRUEPOS_FORMAT = "# TRUEPOS true_x true_y true_theta odom_x odom_y odom_theta\n"
_ESTIMATE_FORMATS = "# message formats defined: PARAM FLASER ROBOTLASER1 ODOM TRUEPOS\n"
_ROBOTLASER1_FORMAT = (
    "# ROBOTLASER1 laser_type start_angle field_of_view angular_resolution maximum_range "
    "accuracy remission_mode num_readings [range_readings] num_remissions [remissions] "
    "laser_pose_x laser_pose_y laser_pose_theta robot_pose_x robot_pose_y robot_pose_theta "
    "laser_tv laser_rv forward_safety_dist side_safty_dist turn_axis\n"
)
_ODOM_FORMAT = "# ODOM x y theta tv rv accel\n"
#: ROBOTLASER1's laser_type for a scanner fuzzypos does not know (CARMEN's UMKNOWN_PROXIMITY_SENSOR)
_UNKNOWN_LASER = 99


class CarmenWriter:
    """Stream scans into the CARMEN log ``path`` (module docstring): :meth:`write` per scan,
    then :meth:`close` (or :meth:`abort`); also a context manager (closes, or aborts on an
    exception).

    ``estimate_of=None`` (:func:`write_carmen`): the header (``#`` comments: what wrote it, the
    beam convention, ``header_comment``) is written at once, then ``PARAM
    robot_frontlaser_offset x`` when the first scan's laser sits ``x`` ahead of the robot
    centre and ``PARAM robot_front_laser_max r`` when its ``range_max`` is finite. Every scan
    must fit :func:`~fuzzypos.io.carmen_beam_geometry` with ``field_of_view_deg`` and
    ``convention`` and have the first scan's ``sensor_pose`` (a pure forward offset) and
    ``range_max``, else :meth:`write` raises ``ValueError`` naming the file and the record;
    invalid readings are written as ``range_max`` (``0`` when it is infinite).

    ``estimate_of=<source>`` (the run job): the header names ``source`` and is written with
    the first scan, whose FLASER beam geometry (:func:`flaser_geometry`) and forward mounting
    offset the log keeps; a scan they do not describe (another geometry or mount, or a first
    scan whose laser sits off the robot's x axis) is written as ``ROBOTLASER1`` (its own
    start angle, resolution, maximum range and mount; counted in :attr:`robotlaser1`), after
    an ``ODOM`` line carrying the odometry (the estimate where there is none). Ranges are
    the raw readings; :attr:`notes` says where the two kinds mix. ``field_of_view_deg``,
    ``convention`` and ``header_comment`` are not used.

    ``poses_at_close`` (estimate mode): the scans' lines are held (as text, about the
    file's size in memory) and written once by :meth:`close`, at the poses it is given (loop
    closure's optimised poses) or else at those :meth:`write` had.

    ``compress``: gzip the file (None: when the name ends in ``.gz``). :attr:`written`: the
    scans written so far.
    """

    def __init__(
        self,
        path: PathLike,
        *,
        hostname: str = "fuzzypos",
        field_of_view_deg: float = 180.0,
        convention: str = "auto",
        header_comment: str | None = None,
        estimate_of: str | None = None,
        compress: bool | None = None,
        poses_at_close: bool = False,
    ) -> None:
        self.estimate_of = estimate_of
        self.geometry: tuple[float, str] | None = None
        if estimate_of is None:
            self.geometry = (check_fov(field_of_view_deg), convention)
            check_convention(convention)
        if not isinstance(hostname, str) or not hostname or any(c.isspace() for c in hostname):
            raise ValueError(
                f"hostname must be a non-empty word without whitespace, got {hostname!r}"
            )
        self.hostname = hostname
        self.name = os.fspath(path)
        self.path = Path(path)
        target, self.streamed = output_target(path)
        self.tmp = (
            target if self.streamed else target.with_name(f".{target.name}.{os.getpid()}.tmp")
        )
        self._target = target
        self.written = 0
        self.robotlaser1 = 0
        self.notes: list[str] = []
        self.first: LaserScan | None = None
        self._fill = "0"
        self._raw: IO[bytes] | None = None
        if poses_at_close and estimate_of is None:
            raise ValueError(f"{self.name}: poses_at_close is for an estimate's log (estimate_of)")
        #: poses_at_close: the header and the scans' lines, held for :meth:`close`
        self._held: list[_Held] | None = [] if poses_at_close else None
        self._header: list[str] = []
        gz = self.path.name.endswith(".gz") if compress is None else compress
        self._gz = gz
        self._fh: IO[str] | None = self._open(gz)
        if estimate_of is None:
            for line in self._log_header(header_comment):
                self._fh.write(line)

    def _open(self, compress: bool) -> IO[str]:
        if not compress:
            return open(self.tmp, "w", encoding="utf-8", newline="\n")
        self._raw = open(self.tmp, "wb")  # noqa: SIM115 - closed by close()/abort()
        try:
            gz = gzip.GzipFile(filename="", mode="wb", fileobj=self._raw, mtime=0)
            return io.TextIOWrapper(gz, encoding="utf-8", newline="\n")
        except BaseException:
            self._raw.close()
            raise

    # -- headers ---------------------------------------------------------------------------
    def _log_header(self, header_comment: str | None) -> list[str]:
        assert self.geometry is not None
        fov, convention = self.geometry
        lines = [
            "# CARMEN Logfile\n",
            f"# written by fuzzypos {__version__} (fuzzypos.io.write_carmen)\n",
            "# file format is one message per line\n",
            "# message_name [message contents] ipc_timestamp ipc_hostname logger_timestamp\n",
            _FORMATS,
            "# PARAM param_name param_value\n",
            _FLASER_FORMAT,
            _TRUEPOS_FORMAT,
            (
                f"# FLASER beams: field of view {fov:g} deg from -{fov / 2:g} deg, convention "
                f"{convention!r} (fov/n for even n, fov/(n-1) for odd n when 'auto'); read with "
                f"the same\n"
            ),
        ]
        if header_comment:
            lines.extend(f"# {ln}\n" if ln else "#\n" for ln in str(header_comment).splitlines())
        return lines

    def _estimate_header(self, first: LaserScan) -> list[str]:
        sp = first.sensor_pose
        forward = sp.y == 0.0 and sp.theta == 0.0  # what FLASER's PARAM can store
        self.geometry = flaser_geometry(first) if forward else None
        lines = [
            "# CARMEN Logfile\n",
            f"# written by fuzzypos {__version__} (fuzzypos run) from {self.estimate_of}\n",
            (
                "# FLASER x y theta: the fuzzypos estimate; odom_x odom_y odom_theta: the log's "
                "odometry (the estimate where the log has none)\n"
            ),
            (
                "# ROBOTLASER1 (scans FLASER cannot describe) robot_pose: the fuzzypos estimate; "
                "the log's odometry: the ODOM line before it (read with --odometry "
                "interpolated)\n"
            ),
            _ESTIMATE_FORMATS,
            _FLASER_FORMAT,
            _ROBOTLASER1_FORMAT,
            _ODOM_FORMAT,
            _TRUEPOS_FORMAT,
        ]
        if self.geometry is not None:
            fov, conv = self.geometry
            lines.append(
                f"# FLASER beams: field of view {fov:g} deg from -{fov / 2:g} deg, convention "
                f"{conv!r}; read with the same (fuzzypos: --fov {fov:g} --convention {conv})\n"
            )
            lines.extend(self._params(first, range_max=False))
        return lines

    def _params(self, first: LaserScan, *, range_max: bool) -> list[str]:
        """The PARAM lines of the first scan's laser: its forward offset, its maximum range."""
        trailer = f"{first.stamp!r} {self.hostname} {first.stamp!r}"
        out = []
        if first.sensor_pose.x != 0.0:
            out.append(f"PARAM robot_frontlaser_offset {first.sensor_pose.x!r} {trailer}\n")
        if range_max and math.isfinite(first.range_max):
            out.append(f"PARAM robot_front_laser_max {first.range_max!r} {trailer}\n")
        return out

    # -- the scans -------------------------------------------------------------------------
    def _check_log_scan(self, scan: LaserScan) -> list[str]:
        """:func:`write_carmen`'s checks of the next scan; the PARAM lines before the first."""
        assert self.geometry is not None
        fov, convention = self.geometry
        name, index, n = self.name, self.written, scan.n_beams
        if n < 2:
            raise ValueError(f"{name}: record {index}: a FLASER scan needs >= 2 beams, got {n}")
        expected = _misfit(scan, fov, convention)
        if expected is not None:
            a0, inc = expected
            raise ArgumentError(
                Words(
                    f"{name}: record {index}: scan geometry (angle_min "
                    f"{math.degrees(scan.angle_min):.6g}°, increment "
                    f"{math.degrees(scan.angle_increment):.6g}°, {n} beams) does not fit "
                    "FLASER with ",
                    Argument.given("field_of_view_deg"),
                    f"{fov:g}, ",
                    Argument.given("convention"),
                    f"{convention!r} (expects angle_min {math.degrees(a0):.6g}°, increment "
                    f"{math.degrees(inc):.6g}°)",
                )
            )
        first = self.first
        if first is None:
            sp = scan.sensor_pose
            if sp.y != 0.0 or sp.theta != 0.0:
                raise ValueError(
                    f"{name}: record {index}: FLASER logs store only a forward laser offset "
                    f"(robot_frontlaser_offset), got sensor_pose {sp}"
                )
            self.first = scan
            self._fill = repr(scan.range_max) if math.isfinite(scan.range_max) else "0"
            return self._params(scan, range_max=True)
        if scan.sensor_pose != first.sensor_pose:
            raise ValueError(
                f"{name}: record {index}: sensor_pose {scan.sensor_pose} differs from the "
                f"first scan's {first.sensor_pose}; a CARMEN log has one front laser"
            )
        if scan.range_max != first.range_max:
            raise ValueError(
                f"{name}: record {index}: range_max {scan.range_max} differs from the "
                f"first scan's {first.range_max}; a CARMEN log has one front laser"
            )
        return []

    def _estimate_lines(
        self,
        fh: IO[str],
        scan: LaserScan,
        at: Pose2D,
        odometry: Pose2D | None,
        odo: str,
        trailer: str,
        truepos: str,
    ) -> _Held:
        """A scan's lines in the estimate's log, around the estimate ``at``: FLASER, or ODOM
        and ROBOTLASER1 where FLASER cannot describe the scan; ``truepos`` after them."""
        if self._is_flaser(fh, scan):
            before = f"FLASER {scan.n_beams} {_ranges_raw(scan)} "
            return _Held(before, None, f" {odo} {trailer}\n{truepos}", at)
        self.robotlaser1 += 1
        before, after = self._robotlaser1(scan, at, odometry, trailer)
        return _Held(before, scan.sensor_pose, after + truepos, at)

    def _is_flaser(self, fh: IO[str], scan: LaserScan) -> bool:
        """Whether the estimate log's FLASER geometry and mount describe the scan (else it is
        written as ROBOTLASER1); the header goes out (or is held) with the first scan."""
        if self.first is None:
            self.first = scan
            self._header = self._estimate_header(scan)
            if self._held is None:
                fh.write("".join(self._header))
        return (
            self.geometry is not None
            and scan.n_beams >= 2
            and scan.sensor_pose == self.first.sensor_pose
            and _misfit(scan, *self.geometry) is None
        )

    @staticmethod
    def _robotlaser1(
        scan: LaserScan, pose: Pose2D, odometry: Pose2D | None, trailer: str
    ) -> tuple[str, str]:
        """The ``ODOM`` (``odometry``, else ``pose``) and ``ROBOTLASER1`` lines of a scan,
        before and after its laser pose (in the world: ``pose`` composed with the mount) and
        robot pose (:func:`_held_text`)."""
        odom = f"ODOM {_pose_text(odometry if odometry is not None else pose)} 0 0 0 {trailer}\n"
        n, res = scan.n_beams, scan.angle_increment
        head = f"{_UNKNOWN_LASER} {scan.angle_min!r} {abs(res) * (n - 1)!r} {res!r}"
        before = f"{odom}ROBOTLASER1 {head} {scan.range_max!r} 0 0 {n} {_ranges_raw(scan)} 0 "
        return before, f" 0 0 0 0 0 {trailer}\n"

    def write(
        self,
        scan: LaserScan,
        odometry: Pose2D | None,
        truth: Pose2D | None = None,
        *,
        pose: Pose2D | None = None,
    ) -> None:
        """Write one scan: ``FLASER`` with ``pose`` (default: ``odometry``) as ``x y θ`` and
        ``odometry`` (default: ``pose``) as ``odom_x odom_y odom_θ`` (in estimate mode
        ``ROBOTLASER1`` where FLASER cannot describe the scan, see the class), then
        ``TRUEPOS`` when ``truth`` is given; the scan's lines go out in one write. Does nothing
        after :meth:`close` or :meth:`abort` in estimate mode."""
        fh = self._fh
        if fh is None:
            if self.estimate_of is not None:
                return
            raise ValueError(f"{self.name}: the CARMEN writer is closed")
        if pose is None and odometry is None:
            raise ValueError(f"{self.name}: record {self.written}: no pose to write")
        at = pose if pose is not None else odometry
        assert at is not None
        xyt = _pose_text(at)
        odo = _pose_text(odometry) if odometry is not None else xyt
        trailer = f"{scan.stamp!r} {self.hostname} {scan.stamp!r}"
        if self.estimate_of is None:
            params = "".join(self._check_log_scan(scan))
            ranges = _ranges_filled(scan, self._fill)
            text = f"{params}FLASER {scan.n_beams} {ranges} {xyt} {odo} {trailer}\n"
        else:
            truepos = "" if truth is None else f"TRUEPOS {_pose_text(truth)} {odo} {trailer}\n"
            held = self._estimate_lines(fh, scan, at, odometry, odo, trailer, truepos)
            if self._held is not None:
                self._held.append(held)
                self.written += 1
                return
            text = _held_text(held, at)
        if truth is not None and self.estimate_of is None:
            text += f"TRUEPOS {_pose_text(truth)} {odo} {trailer}\n"
        try:
            fh.write(text)
        except OSError as exc:
            raise self._write_error(exc) from exc
        self.written += 1

    # -- finishing -------------------------------------------------------------------------
    def _write_error(self, exc: OSError) -> OutputWriteError:
        return OutputWriteError(exc.errno, exc.strerror or str(exc), self.name)

    def _close_files(self) -> None:
        fh, raw = self._fh, self._raw
        self._fh = self._raw = None
        try:
            if fh is not None:
                fh.close()
        finally:
            if raw is not None:
                raw.close()

    def close(self, poses: NDArray[np.float64] | None = None, why: str = "") -> bool:
        """Finish the log and rename it over ``path``; return whether it was. In estimate mode
        a log without a scan is not kept (False; no file) and the scans left out are noted.
        ``poses`` (``poses_at_close``: one row (x, y, θ) per scan written): the scans'
        estimates, written now (the optimised poses after loop closure), with ``why`` in the
        header; the odometry, the truth and the ranges as :meth:`write` had them."""
        if self._fh is None:
            return False
        try:
            if self._held is not None:
                self._write_held(poses, why)
            elif poses is not None:
                raise ValueError(
                    f"{self.name}: poses are taken at close by a writer made with poses_at_close"
                )
            with _naming(self.name, self.tmp):
                self._close_files()
            if self.estimate_of is not None:
                if 0 < self.robotlaser1 < self.written:
                    self.notes.append(
                        f"{self.path.name}: {self.robotlaser1} of {self.written} scans are "
                        "ROBOTLASER1 lines (beam angles or laser mount that FLASER, as set by "
                        "the first scan, cannot describe)"
                    )
                if self.written == 0:
                    if not self.streamed:
                        os.unlink(self.tmp)
                    return False
            if not self.streamed:
                os.replace(self.tmp, self._target)
        except BaseException:
            self.abort()
            raise
        return True

    def _write_held(self, poses: NDArray[np.float64] | None, why: str) -> None:
        """Write the held header and scans, at ``poses`` (else at :meth:`write`'s), once."""
        at = None if poses is None else np.asarray(poses, dtype=float)
        if at is not None and (at.shape != (self.written, 3) or not np.isfinite(at).all()):
            raise ValueError(
                f"{self.name}: expected {self.written} finite poses (x, y, θ), got an array "
                f"of shape {at.shape}"
            )
        held, self._held = self._held or [], []
        fh = self._fh
        assert fh is not None
        header = [
            line
            + (f"# {why}\n" if why and at is not None and line.startswith("# written by") else "")
            for line in self._header
        ]
        with _naming(self.name, self.tmp):
            try:
                fh.write("".join(header))
                for k, h in enumerate(held):
                    fh.write(_held_text(h, h.pose if at is None else Pose2D.from_array(at[k])))
            except OSError as exc:
                raise self._write_error(exc) from exc

    def abort(self) -> None:
        """Give up: close and remove the temporary file (``path`` is left as it was)."""
        try:
            with contextlib.suppress(OSError):  # a full disk fails the flush: nothing to keep
                self._close_files()
        finally:
            if not self.streamed:
                with contextlib.suppress(OSError):
                    os.unlink(self.tmp)

    def __enter__(self) -> CarmenWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


# -- write_carmen ----------------------------------------------------------------------------
def _unpack_record(rec: object, index: int) -> tuple[LaserScan, Pose2D, Pose2D | None]:
    scan: Any
    odom: Any
    truth: Any
    if isinstance(rec, LogRecord):
        scan, odom, truth = rec
    else:
        try:
            items = tuple(cast("Iterable[Any]", rec))
        except TypeError:
            raise TypeError(
                f"record {index}: expected a CarmenRecord(scan, odometry, truth), got "
                f"{type(rec).__name__}"
            ) from None
        if len(items) not in (2, 3):
            raise ValueError(
                f"record {index}: expected (scan, odometry[, truth]), got {len(items)} items"
            )
        scan, odom = items[0], items[1]
        truth = items[2] if len(items) == 3 else None
    if not isinstance(scan, LaserScan):
        raise TypeError(f"record {index}: scan must be a LaserScan, got {type(scan).__name__}")
    if not isinstance(odom, Pose2D):
        odom = Pose2D.from_array(odom)
    if truth is not None and not isinstance(truth, Pose2D):
        truth = Pose2D.from_array(truth)
    return scan, odom, truth


def write_carmen(
    path: PathLike,
    records: Iterable[LogRecord],
    *,
    hostname: str = "fuzzypos",
    header_comment: str | None = None,
    field_of_view_deg: float = 180.0,
    convention: str = "auto",
) -> int:
    """Write ``records`` as a CARMEN log the way CARMEN's simulator does; return their count.

    Per record a ``FLASER n r_1 … r_n x y θ odom_x odom_y odom_θ ipc_timestamp hostname
    logger_timestamp`` line (``x y θ`` repeat the odometry; both timestamps are the scan's
    stamp), then, when ``truth`` is given, a ``TRUEPOS`` line with the same trailer. The file
    opens with ``#`` comments (what wrote it, the beam convention, ``header_comment``), then
    ``PARAM robot_frontlaser_offset x`` when the laser sits ``x`` ahead of the robot centre and
    ``PARAM robot_front_laser_max r`` when the scans' ``range_max`` is finite.

    Ranges are written to 0.1 mm, poses and stamps at full precision (``repr``); invalid
    readings become ``range_max`` (``0`` when it is infinite), so they read back invalid.
    ``range_min`` is not stored. FLASER carries no angles: every scan's geometry must fit
    :func:`carmen_beam_geometry` for its beam count with ``field_of_view_deg`` and
    ``convention`` (a reader must use the same), all scans must share one ``sensor_pose``
    (a pure forward offset) and one ``range_max``; otherwise :class:`ValueError` (and no file
    is left behind: the log is written to a temporary file first). A name ending in ``.gz``
    gets a gzip file. (:class:`CarmenWriter` does the writing.)
    """
    writer = CarmenWriter(
        path,
        hostname=hostname,
        field_of_view_deg=field_of_view_deg,
        convention=convention,
        header_comment=header_comment,
    )
    with writer:
        for index, rec in enumerate(records):
            scan, odom, truth = _unpack_record(rec, index)
            writer.write(scan, odom, truth)
    return writer.written
