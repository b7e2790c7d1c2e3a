"""Reading and writing robot logs: CARMEN (``.clf``, plain or gzip) and TUM trajectories.

CARMEN logs
-----------
One message per line, ``NAME fields… ipc_timestamp hostname logger_timestamp``
(``/work/shared/data/README.md`` describes the lines). This first version understands

- ``FLASER n r_1 … r_n x y θ odom_x odom_y odom_θ ipc_timestamp hostname logger_timestamp``:
  one scan. The odometry comes from the ``odom_*`` fields, never from ``x y θ`` (which may be
  a corrected pose in other logs); the scan's stamp is ``ipc_timestamp``.
- ``TRUEPOS true_x true_y true_θ odom_x odom_y odom_θ ipc_timestamp hostname
  logger_timestamp``: the simulator's true pose, attached to the FLASER record before it
  (the first TRUEPOS after a FLASER wins; one before any FLASER is ignored).
- ``PARAM robot_frontlaser_offset x``: the laser's forward offset on the robot (the scans'
  ``sensor_pose`` is ``(x, 0, 0)``); ``PARAM robot_front_laser_max r``: the laser's maximum
  range (see "Maximum range" below). Both apply to the FLASER lines after them; every other
  PARAM is skipped.
- ``#`` comments, blank lines and every other message type (``ODOM``, ``SYNC``, ``NEFF``,
  ``RLASER``, ``ROBOTLASER1`` …) are skipped. New message types plug in as one method each
  (see :attr:`CarmenReader._HANDLERS`).

Beam geometry. FLASER carries no angles: the reader's ``field_of_view_deg`` (default 180°)
and ``convention`` give them, and they must match what wrote the log. Beams start at
``-fov/2`` (the right edge) and go counter-clockwise:

- ``"resolution"``: increment ``fov/n``, so 180 beams over 180° lie at -90° … +89°;
- ``"span"``: increment ``fov/(n-1)``, so the beams cover exactly -fov/2 … +fov/2;
- ``"auto"`` (default): ``"resolution"`` for an even beam count (180, 360: 1° and 0.5° over
  180°), ``"span"`` for an odd one (181, 361). See :func:`carmen_beam_geometry`.

Maximum range. FLASER carries no maximum either; a scanner reports "no return" as its
maximum value (81.83 m in the intel log, 50.0 m in aces), and a reading at or above the
scan's ``range_max`` is invalid (:class:`~fuzzypos.scan.LaserScan`). The scans' ``range_max``
is, in order of precedence:

1. the ``max_range`` argument when given (``math.inf``: every positive reading is valid);
2. else the value of the latest ``PARAM robot_front_laser_max`` line (what :func:`write_carmen`
   writes for scans with a finite ``range_max``);
3. else it is learned from the data as the file streams: the "no return" value ``v`` is the
   largest reading seen so far that was the maximum of its scan *and occurred at least twice in
   that scan* (a scanner's saturated value repeats; a genuine far wall rarely gives the same
   maximum twice). A scan whose largest finite reading is ``<= v`` gets ``range_max = v``;
   before any ``v`` is seen, or for a scan reaching above ``v`` without repeating its maximum,
   ``range_max = +inf``. On the shared logs this marks exactly the 68,313 readings of 81.83 m
   (intel) and 11,139 of 50.0 m (aces) invalid and nothing else. The current ``v`` is
   :attr:`CarmenReader.no_return_value`.

Errors. A malformed FLASER, TRUEPOS or interpreted PARAM line raises
:class:`CarmenFormatError` naming the file, the 1-based line and what is wrong; with
``skip_bad_lines=True`` the line is skipped and counted in :attr:`CarmenReader.bad_lines`. A
last line without its newline that does not parse (a log cut off mid-write), or a gzip stream
that ends early, stops the reading with a :func:`warnings.warn` naming the file. A scan whose
readings are all invalid is data, not an error. Records come in file order, even where the
timestamps go backwards.

The reader streams: one line in memory at a time (plus the record waiting for its TRUEPOS).
Gzip is recognised by its magic bytes, not by the file name.
"""

from __future__ import annotations

import gzip
import math
import os
import warnings
import zlib
from collections import deque
from collections.abc import Iterable, Iterator
from typing import IO, ClassVar

import numpy as np

from ..geometry import Pose2D
from ..scan import LaserScan
from ._common import FloatArray, LogFormatError, LogRecord, PathLike, _write_atomically, open_text

__all__ = [
    "CONVENTIONS",
    "CarmenFormatError",
    "CarmenReader",
    "CarmenRecord",
    "carmen_beam_geometry",
    "read_carmen",
    "write_carmen",
]

#: the beam-angle conventions FLASER readers and writers understand (see the module docstring)
CONVENTIONS = ("auto", "resolution", "span")

#: tolerance (radians) when checking that a scan's geometry fits the FLASER convention
_GEOMETRY_TOL = 1e-7

#: how many skipped-line errors a reader keeps (the count itself is unbounded)
_MAX_KEPT_ERRORS = 100

#: the PARAM names the reader interprets (their values must parse)
_INTERPRETED_PARAMS = ("robot_frontlaser_offset", "robot_front_laser_max")

#: decimals of the ranges written to a CARMEN log (0.1 mm; poses and stamps get repr)
_RANGE_DECIMALS = 4


class CarmenFormatError(LogFormatError):
    """A malformed CARMEN log line, e.g. ``log.clf:17: FLASER: expected 180 ranges, got 179``."""


class _Bad(Exception):
    """Internal: a line handler's complaint; the reader adds the file and line."""


# -- CARMEN: beam geometry -----------------------------------------------------------------
def carmen_beam_geometry(
    n: int, field_of_view_deg: float = 180.0, convention: str = "auto"
) -> tuple[float, float]:
    """``(angle_min, angle_increment)`` in radians of an ``n``-beam FLASER scan.

    Beams start at ``-fov/2`` and go counter-clockwise. ``"resolution"``: increment
    ``fov/n``; ``"span"``: ``fov/(n-1)`` (the last beam at ``+fov/2``); ``"auto"``: the
    first for even ``n`` (180, 360), the second for odd ``n`` (181, 361).
    """
    fov = _check_fov(field_of_view_deg)
    _check_convention(convention)
    if isinstance(n, bool) or int(n) != n or n < 2:
        raise ValueError(f"a FLASER scan needs an integer beam count >= 2, got {n!r}")
    n = int(n)
    if convention == "auto":
        convention = "resolution" if n % 2 == 0 else "span"
    fov_rad = math.radians(fov)
    inc = fov_rad / n if convention == "resolution" else fov_rad / (n - 1)
    return -fov_rad / 2.0, inc


def _check_fov(field_of_view_deg: float) -> float:
    try:
        fov = float(field_of_view_deg)
    except (TypeError, ValueError):
        raise ValueError(f"field_of_view_deg must be a number, got {field_of_view_deg!r}") from None
    if not 0.0 < fov <= 360.0:
        raise ValueError(f"field_of_view_deg must be in (0, 360], got {fov}")
    return fov


def _check_convention(convention: str) -> None:
    if convention not in CONVENTIONS:
        raise ValueError(f"convention must be one of {CONVENTIONS}, got {convention!r}")


# -- CARMEN: reading -----------------------------------------------------------------------
#: a CARMEN record is a :class:`~fuzzypos.io.LogRecord` (its odometry is never None)
CarmenRecord = LogRecord


def _float(s: str, what: str) -> float:
    try:
        return float(s)
    except ValueError:
        raise _Bad(f"{what} is not a number: {s!r}") from None


def _finite(s: str, what: str) -> float:
    v = _float(s, what)
    if not math.isfinite(v):
        raise _Bad(f"{what} must be finite, got {s!r}")
    return v


class CarmenReader:
    """Stream the FLASER records of a CARMEN log (plain or gzip).

    ``CarmenReader(path, …).records()`` (or iterating the reader) yields
    :class:`CarmenRecord` in file order; the options are :func:`read_carmen`'s (see the module
    docstring). After (or during) the iteration:

    - ``bad_lines``: malformed lines skipped (``skip_bad_lines=True``);
    - ``errors``: the :class:`CarmenFormatError` of the first 100 of them;
    - ``truncated``: whether the log ended mid-line or mid-stream (a warning was issued);
    - ``lines``: lines read; ``no_return_value``: the learned "no return" reading (or None);
    - ``params``: the PARAM lines seen, name -> value (as text).

    Each call of :meth:`records` reads the file again from the start and resets these.
    """

    #: message type -> handler method name; a handler gets the line's tokens and either
    #: raises :class:`_Bad` or updates ``_pending`` / ``_ready``
    _HANDLERS: ClassVar[dict[str, str]] = {
        "FLASER": "_on_flaser",
        "TRUEPOS": "_on_truepos",
        "PARAM": "_on_param",
    }
    #: message types that make a record: a malformed one that is skipped ends the record
    #: before it, so that a TRUEPOS meant for the skipped scan attaches to nothing
    _SCAN_MESSAGES: ClassVar[frozenset[str]] = frozenset({"FLASER"})

    def __init__(
        self,
        path: PathLike,
        *,
        field_of_view_deg: float = 180.0,
        max_range: float | None = None,
        convention: str = "auto",
        skip_bad_lines: bool = False,
    ) -> None:
        self.path = path
        self.name = os.fspath(path)
        self.field_of_view_deg = _check_fov(field_of_view_deg)
        _check_convention(convention)
        self.convention = convention
        if max_range is not None:
            mr = float(max_range)
            if math.isnan(mr) or mr <= 0.0:
                raise ValueError(f"max_range must be > 0 (or None), got {max_range!r}")
            max_range = mr
        self.max_range = max_range
        self.skip_bad_lines = bool(skip_bad_lines)
        with open(path, "rb"):  # fail here, not at the first record, if it cannot be read
            pass
        self._geometry: dict[int, tuple[float, float]] = {}
        self._reset()

    def _reset(self) -> None:
        self.bad_lines = 0
        self.errors: list[CarmenFormatError] = []
        self.truncated = False
        self.lines = 0
        self.no_return_value: float | None = None
        self.params: dict[str, str] = {}
        self._param_max: float | None = None
        self._sensor_pose = Pose2D(0.0, 0.0, 0.0)
        self._pending: CarmenRecord | None = None
        self._ready: deque[CarmenRecord] = deque()

    def __iter__(self) -> Iterator[CarmenRecord]:
        return self.records()

    # -- the loop ---------------------------------------------------------------------------
    def records(self) -> Iterator[CarmenRecord]:
        """Yield the log's records in file order (a record waits for its TRUEPOS, so it comes
        out when the next FLASER or the end of the file arrives)."""
        self._reset()
        for lineno, line in self._numbered_lines():
            tokens = line.split()
            if not tokens or tokens[0].startswith("#"):
                continue
            name = self._HANDLERS.get(tokens[0])
            if name is None:
                continue
            try:
                getattr(self, name)(tokens)
            except _Bad as bad:
                err = CarmenFormatError(self.path, lineno, str(bad))
                if tokens[0] in self._SCAN_MESSAGES and self._pending is not None:
                    self._ready.append(self._pending)
                    self._pending = None
                if not line.endswith("\n"):
                    self.truncated = True
                    warnings.warn(
                        f"{self.name}: skipped the truncated last line {lineno} ({bad})",
                        RuntimeWarning,
                        stacklevel=2,
                    )
                    continue
                if not self.skip_bad_lines:
                    raise err from None
                self.bad_lines += 1
                if len(self.errors) < _MAX_KEPT_ERRORS:
                    self.errors.append(err)
            while self._ready:
                yield self._ready.popleft()
        while self._ready:
            yield self._ready.popleft()
        if self._pending is not None:
            rec, self._pending = self._pending, None
            yield rec

    def _numbered_lines(self) -> Iterator[tuple[int, str]]:
        with open_text(self.path) as fh:
            it = iter(fh)
            while True:
                try:
                    line = next(it)
                except StopIteration:
                    return
                except EOFError as exc:  # gzip stream cut off
                    self.truncated = True
                    warnings.warn(
                        f"{self.name}: compressed stream ends early after line {self.lines} "
                        f"({exc}); the rest of the log is lost",
                        RuntimeWarning,
                        stacklevel=3,
                    )
                    return
                except (gzip.BadGzipFile, zlib.error) as exc:
                    raise CarmenFormatError(
                        self.path, self.lines + 1, f"corrupt gzip stream: {exc}"
                    ) from None
                self.lines += 1
                yield self.lines, line

    # -- message handlers -------------------------------------------------------------------
    def _on_flaser(self, tok: list[str]) -> None:
        if len(tok) < 2:
            raise _Bad("FLASER: missing the beam count")
        try:
            n = int(tok[1])
        except ValueError:
            raise _Bad(f"FLASER: beam count is not an integer: {tok[1]!r}") from None
        if n < 2:
            raise _Bad(f"FLASER: beam count must be >= 2, got {n}")
        if len(tok) != n + 11:
            raise _Bad(
                f"FLASER: expected {n} ranges, got {len(tok) - 11} (line has {len(tok)} "
                f"fields; FLASER needs n + 11: n ranges, x y θ, odom_x odom_y odom_θ, "
                f"ipc_timestamp hostname logger_timestamp)"
            )
        try:
            ranges = np.array(tok[2 : 2 + n], dtype=np.float64)
        except ValueError:
            for k, s in enumerate(tok[2 : 2 + n]):
                _float(s, f"FLASER: range {k + 1} of {n}")
            raise  # pragma: no cover - numpy and float() disagree
        p = 2 + n
        for k, what in enumerate(("x", "y", "θ")):
            _float(tok[p + k], f"FLASER: {what}")
        ox = _finite(tok[p + 3], "FLASER: odom_x")
        oy = _finite(tok[p + 4], "FLASER: odom_y")
        ot = _finite(tok[p + 5], "FLASER: odom_θ")
        stamp = _finite(tok[p + 6], "FLASER: ipc_timestamp")
        _finite(tok[p + 8], "FLASER: logger_timestamp")

        geometry = self._geometry.get(n)
        if geometry is None:
            geometry = carmen_beam_geometry(n, self.field_of_view_deg, self.convention)
            self._geometry[n] = geometry
        scan = LaserScan(
            ranges,
            geometry[0],
            geometry[1],
            range_min=0.0,
            range_max=self._range_max(ranges),
            stamp=stamp,
            sensor_pose=self._sensor_pose,
        )
        if self._pending is not None:
            self._ready.append(self._pending)
        self._pending = CarmenRecord(scan, Pose2D(ox, oy, ot), None)

    def _range_max(self, ranges: FloatArray) -> float:
        """The scan's ``range_max`` (module docstring, "Maximum range")."""
        if self.max_range is not None:
            return self.max_range
        if self._param_max is not None:
            return self._param_max
        finite = ranges[np.isfinite(ranges)]
        if finite.size == 0:
            m = -math.inf
        else:
            m = float(finite.max())
            v = self.no_return_value
            if m > 0.0 and (v is None or m > v) and np.count_nonzero(finite == m) >= 2:
                self.no_return_value = m
        v = self.no_return_value
        return v if v is not None and m <= v else math.inf

    def _on_truepos(self, tok: list[str]) -> None:
        if len(tok) != 10:
            raise _Bad(
                f"TRUEPOS: expected 10 fields (TRUEPOS true_x true_y true_θ odom_x odom_y "
                f"odom_θ ipc_timestamp hostname logger_timestamp), got {len(tok)}"
            )
        tx = _finite(tok[1], "TRUEPOS: true_x")
        ty = _finite(tok[2], "TRUEPOS: true_y")
        tt = _finite(tok[3], "TRUEPOS: true_θ")
        for k, what in zip(
            (4, 5, 6, 7, 9), ("odom_x", "odom_y", "odom_θ", "ipc_timestamp", "logger_timestamp")
        ):
            _finite(tok[k], f"TRUEPOS: {what}")
        if self._pending is not None and self._pending.truth is None:
            self._pending = self._pending._replace(truth=Pose2D(tx, ty, tt))

    def _on_param(self, tok: list[str]) -> None:
        if len(tok) < 3:
            if len(tok) == 2 and tok[1] in _INTERPRETED_PARAMS:
                raise _Bad(f"PARAM {tok[1]}: missing its value")
            return  # a PARAM we do not interpret: skipped like any other line
        name, value = tok[1], tok[2]
        self.params[name] = value
        if name == "robot_frontlaser_offset":
            self._sensor_pose = Pose2D(_finite(value, "PARAM robot_frontlaser_offset"), 0.0, 0.0)
        elif name == "robot_front_laser_max":
            v = _float(value, "PARAM robot_front_laser_max")
            if math.isnan(v) or v <= 0.0:
                raise _Bad(f"PARAM robot_front_laser_max must be > 0, got {value!r}")
            self._param_max = v


def read_carmen(
    path: PathLike,
    *,
    field_of_view_deg: float = 180.0,
    max_range: float | None = None,
    convention: str = "auto",
    skip_bad_lines: bool = False,
) -> Iterator[CarmenRecord]:
    """Stream the :class:`CarmenRecord` of a CARMEN log (plain or gzip) in file order.

    ``field_of_view_deg`` and ``convention`` give the FLASER beam angles
    (:func:`carmen_beam_geometry`; they must match what wrote the log); ``max_range``: a
    reading at or above it is invalid (None: ``PARAM robot_front_laser_max``, else learned
    from the data; module docstring); ``skip_bad_lines``: skip malformed lines instead of
    raising :class:`CarmenFormatError` (use :class:`CarmenReader` to get their count).
    """
    return CarmenReader(
        path,
        field_of_view_deg=field_of_view_deg,
        max_range=max_range,
        convention=convention,
        skip_bad_lines=skip_bad_lines,
    ).records()


# -- CARMEN: writing -----------------------------------------------------------------------
def _fmt_ranges(scan: LaserScan, fill: str) -> list[str]:
    """Ranges as text: valid readings to 0.1 mm (full precision where rounding would move
    them across 0 or ``range_max``), invalid ones as ``fill``."""
    r = scan.ranges
    valid = scan.valid
    rounded = np.round(r, _RANGE_DECIMALS)
    exact = valid & ((rounded >= scan.range_max) | (rounded <= 0.0))
    out: list[str] = []
    for v, ok, ex in zip(r.tolist(), valid.tolist(), exact.tolist()):
        if not ok:
            out.append(fill)
        elif ex:
            out.append(repr(v))
        else:
            out.append(f"{v:.{_RANGE_DECIMALS}f}".rstrip("0").removesuffix("."))
    return out


def _unpack_record(rec: object, index: int) -> tuple[LaserScan, Pose2D, Pose2D | None]:
    if isinstance(rec, CarmenRecord):
        scan, odom, truth = rec
    else:
        try:
            items = tuple(rec)  # type: ignore[call-overload]
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
    records: Iterable[CarmenRecord],
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
    gets a gzip file.
    """
    fov = _check_fov(field_of_view_deg)
    _check_convention(convention)
    if not isinstance(hostname, str) or not hostname or any(c.isspace() for c in hostname):
        raise ValueError(f"hostname must be a non-empty word without whitespace, got {hostname!r}")
    name = os.fspath(path)
    count = 0

    def check_geometry(scan: LaserScan, index: int) -> None:
        n = scan.n_beams
        if n < 2:
            raise ValueError(f"{name}: record {index}: a FLASER scan needs >= 2 beams, got {n}")
        a0, inc = carmen_beam_geometry(n, fov, convention)
        if (
            abs(scan.angle_min - a0) > _GEOMETRY_TOL
            or abs(scan.angle_increment - inc) * n > _GEOMETRY_TOL
        ):
            raise ValueError(
                f"{name}: record {index}: scan geometry (angle_min "
                f"{math.degrees(scan.angle_min):.6g}°, increment "
                f"{math.degrees(scan.angle_increment):.6g}°, {n} beams) does not fit "
                f"FLASER with field_of_view_deg={fov:g}, convention={convention!r} "
                f"(expects angle_min {math.degrees(a0):.6g}°, increment {math.degrees(inc):.6g}°)"
            )

    def write(fh: IO[str]) -> None:
        nonlocal count
        from .. import __version__  # late: the package imports this module's siblings first

        fh.write("# CARMEN Logfile\n")
        fh.write(f"# written by fuzzypos {__version__} (fuzzypos.io.write_carmen)\n")
        fh.write("# file format is one message per line\n")
        fh.write("# message_name [message contents] ipc_timestamp ipc_hostname logger_timestamp\n")
        fh.write("# message formats defined: PARAM FLASER TRUEPOS\n")
        fh.write("# PARAM param_name param_value\n")
        fh.write("# FLASER num_readings [range_readings] x y theta odom_x odom_y odom_theta\n")
        fh.write("# TRUEPOS true_x true_y true_theta odom_x odom_y odom_theta\n")
        fh.write(
            f"# FLASER beams: field of view {fov:g} deg from -{fov / 2:g} deg, convention "
            f"{convention!r} (fov/n for even n, fov/(n-1) for odd n when 'auto'); read with "
            f"the same\n"
        )
        if header_comment:
            for line in str(header_comment).splitlines():
                fh.write(f"# {line}\n" if line else "#\n")

        first: LaserScan | None = None
        for index, rec in enumerate(records):
            scan, odom, truth = _unpack_record(rec, index)
            check_geometry(scan, index)
            if first is None:
                first = scan
                sp = scan.sensor_pose
                if sp.y != 0.0 or sp.theta != 0.0:
                    raise ValueError(
                        f"{name}: record {index}: FLASER logs store only a forward laser offset "
                        f"(robot_frontlaser_offset), got sensor_pose {sp}"
                    )
                stamp0 = repr(scan.stamp)
                if sp.x != 0.0:
                    fh.write(
                        f"PARAM robot_frontlaser_offset {sp.x!r} {stamp0} {hostname} {stamp0}\n"
                    )
                if math.isfinite(scan.range_max):
                    fh.write(
                        f"PARAM robot_front_laser_max {scan.range_max!r} {stamp0} {hostname} "
                        f"{stamp0}\n"
                    )
                fill = repr(scan.range_max) if math.isfinite(scan.range_max) else "0"
            else:
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
            pose = f"{odom.x!r} {odom.y!r} {odom.theta!r}"
            trailer = f"{scan.stamp!r} {hostname} {scan.stamp!r}"
            fh.write(
                f"FLASER {scan.n_beams} {' '.join(_fmt_ranges(scan, fill))} {pose} {pose} "
                f"{trailer}\n"
            )
            if truth is not None:
                fh.write(f"TRUEPOS {truth.x!r} {truth.y!r} {truth.theta!r} {pose} {trailer}\n")
            count += 1

    _write_atomically(path, write)
    return count
