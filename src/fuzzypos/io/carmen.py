"""Reading and writing robot logs: CARMEN (``.clf``, plain or gzip) and TUM trajectories.

CARMEN logs
-----------
One message per line, ``NAME fields… ipc_timestamp hostname logger_timestamp``
(the shared data's ``README.md`` describes the lines). The reader understands

- ``FLASER n r_1 … r_n x y θ odom_x odom_y odom_θ ipc_timestamp hostname logger_timestamp``:
  one scan of any beam count ``n >= 2`` (180, 181, 360, 361, 541 …). The odometry comes from
  the ``odom_*`` fields, never from ``x y θ`` (which may be a corrected pose in other logs);
  the scan's stamp is ``ipc_timestamp``. Beam angles and maximum range: see below.
- ``ROBOTLASER1 laser_type start_angle fov angular_res max_range accuracy remission_mode n
  r_1 … r_n n_rem rem_1 … rem_m laser_x laser_y laser_θ robot_x robot_y robot_θ tv rv
  forward_safety side_safety turn_axis ipc_timestamp hostname logger_timestamp``: one scan
  (``n >= 1``) that carries its own geometry: beam ``i`` is at ``start_angle + i*angular_res``
  (radians; ``fov`` is checked to be a number but not used), and a reading at or above its
  ``max_range`` is invalid. The record is the robot's, not the laser's: its odometry is
  ``robot_x robot_y robot_θ`` and the scan's ``sensor_pose`` (the laser's mounting pose on the
  robot) is ``⊖robot_pose ⊕ laser_pose``, computed per line from the line's own fields.
  Remissions are checked and dropped; the line must have exactly ``n + n_rem + 24`` fields.
  The reader options ``field_of_view_deg``, ``convention`` and ``PARAM`` lines do not apply to
  it; ``max_range`` and ``laser_offset`` do when given (see below).
- ``ODOM x y θ tv rv accel ipc_timestamp hostname logger_timestamp``: the raw odometry at its
  own rate. Always checked (count in :attr:`CarmenReader.odom_messages`); used only with
  ``odometry="interpolated"`` (see "Odometry").
- ``TRUEPOS true_x true_y true_θ odom_x odom_y odom_θ ipc_timestamp hostname
  logger_timestamp``: the simulator's true pose, attached to the scan record before it
  (the first TRUEPOS after a scan wins; one before any scan is ignored).
- ``PARAM robot_frontlaser_offset x``: the laser's forward offset on the robot (the FLASER
  scans' ``sensor_pose`` is ``(x, 0, 0)``, unless the reader's ``laser_offset`` is given);
  ``PARAM robot_front_laser_max r``: the laser's maximum range (see "Maximum range" below).
  Both apply to the FLASER lines after them; every other PARAM is skipped.
- ``#`` comments, blank lines and every other message type (``SYNC``, ``NEFF``, ``RLASER``,
  ``RAWLASER1`` …) are skipped. New message types plug in as one method each
  (see :attr:`CarmenReader._HANDLERS`).

Laser mounting pose (``sensor_pose``). In order of precedence: the reader's ``laser_offset``
argument (a :class:`~fuzzypos.geometry.Pose2D`) for every scan, FLASER and ROBOTLASER1 alike
(an explicit argument always wins, e.g. to correct a log whose pose fields are wrong); else,
for ROBOTLASER1, ``⊖robot_pose ⊕ laser_pose`` from the line; for FLASER, ``(x, 0, 0)`` from the
latest ``PARAM robot_frontlaser_offset x``, else the origin.

FLASER beam geometry. FLASER carries no angles: the reader's ``field_of_view_deg`` (default
180°) and ``convention`` give them, and they must match what wrote the log. Beams start at
``-fov/2`` (the right edge) and go counter-clockwise:

- ``"resolution"``: increment ``fov/n``, so 180 beams over 180° lie at -90° … +89°;
- ``"span"``: increment ``fov/(n-1)``, so the beams cover exactly -fov/2 … +fov/2;
- ``"auto"`` (default): ``"resolution"`` for an even beam count (180, 360: 1° and 0.5° over
  180°), ``"span"`` for an odd one (181, 361, 541). See :func:`carmen_beam_geometry`.

Maximum range. A reading at or above the scan's ``range_max`` is invalid
(:class:`~fuzzypos.scan.LaserScan`). The scans' ``range_max`` is, in order of precedence:

1. the ``max_range`` argument when given (``math.inf``: every positive reading is valid), for
   FLASER and ROBOTLASER1;
2. for ROBOTLASER1, the line's own ``max_range`` field (the steps below are FLASER's);
3. else the value of the latest ``PARAM robot_front_laser_max`` line (what :func:`write_carmen`
   writes for scans with a finite ``range_max``);
4. else it is learned from the data as the file streams. FLASER carries no maximum; a scanner
   reports "no return" as its maximum value (81.83 m in the intel log, 50.0 m in aces). The
   "no return" value ``v`` is the largest reading seen so far that was the maximum of its
   scan *and occurred at least twice in that scan* (a scanner's saturated value repeats; a
   genuine far wall rarely gives the same maximum twice). A scan whose largest finite reading
   is ``<= v`` gets ``range_max = v``; before any ``v`` is seen, or for a scan reaching above
   ``v`` without repeating its maximum, ``range_max = +inf``. On the shared logs this marks
   exactly the 68,313 readings of 81.83 m (intel) and 11,139 of 50.0 m (aces) invalid and
   nothing else. The current ``v`` is :attr:`CarmenReader.no_return_value`.

Odometry. ``odometry="scan"`` (default): each record's odometry is its scan line's own
odometry fields (FLASER ``odom_*``, ROBOTLASER1 ``robot_*``). ``odometry="interpolated"``: it
is the ``ODOM`` stream interpolated in SE(2) at the scan's ``ipc_timestamp`` ``t``: linearly
in ``x, y`` and along the shorter arc in ``θ`` between ``b``, the ODOM line with the latest
stamp ``<= t``, and ``a``, the one with the earliest stamp ``>= t``; where only one of them
exists (a scan before the first or after the last ODOM) it is that one's pose (the nearest),
and where ``a`` and ``b`` have the same stamp, ``b``'s. To keep streaming, ``a`` and ``b`` are
looked for among a bounded window of ODOM lines in *file order*: the 16 before the scan and
those after it up to the first one stamped ``>= t`` (at most 100). The scan is held (with the
scans after it, so records still come in file order) until that ODOM line arrives, the 100
are read, 1000 scans wait, or the log ends. So when both streams' stamps increase this is
exact interpolation in time even where a scan line is written a little before or after its
ODOM neighbours (aces: 161 scans); when stamps go backwards (intel: 602 times in the ODOM
stream, 631 in the scans, by up to 0.9 s, two hosts' clocks) the window still holds the ODOM
lines written around the scan, and the pose is interpolated *in time* between those of them
that bracket ``t`` (or the nearest in time, when none do on one side); ODOM lines further
away in the file are never used. Beware: on intel the scans' stamps are not acquisition times
(they arrive in bursts), and the README of the shared data advises the scans' own fields.
A scan with no ODOM line in its window at all raises :class:`CarmenFormatError` (a log
without ODOM lines cannot be read with ``odometry="interpolated"``).

Errors. A malformed FLASER, ROBOTLASER1, ODOM, TRUEPOS or interpreted PARAM line raises
:class:`CarmenFormatError` naming the file, the 1-based line and what is wrong (wrong field
counts, a count that is not an integer, ``n_rem`` disagreeing with the fields left, a field that
is not a number or not finite, a non-positive maximum range, a zero angular resolution …; but a
FLASER line whose ``odom_*`` fields are numbers that are not finite keeps its scan, without
odometry, counted in :attr:`CarmenReader.bad_odometry`); with ``skip_bad_lines=True`` the line
is skipped and counted in :attr:`CarmenReader.bad_lines`. A last line without its newline that
does not parse (a log cut off mid-write), or a gzip stream that ends early, stops the reading
with a :func:`warnings.warn` naming the file. A scan whose readings are all invalid is data, not
an error. Records come in file order, even where the timestamps go backwards.

The reader streams: one line in memory at a time, plus the record waiting for its TRUEPOS
(and, with ``odometry="interpolated"``, the bounded window above). Gzip is recognised by its
magic bytes, not by the file name. Ranges are parsed by numpy, not beam by beam. A pipe or
FIFO (``<(zcat log.clf.gz)``, ``/dev/stdin``) is copied once into a temporary file (a
:class:`~fuzzypos.io._common.Spool`, removed with the reader), so that every pass reads all
of it; messages still name it as given.

Writing is :mod:`fuzzypos.io.carmen_write` (:class:`CarmenWriter`, :func:`write_carmen`; both
re-exported here); the FLASER beam geometry both sides share is in :mod:`fuzzypos.io._flaser`.
"""

from __future__ import annotations

import gzip
import math
import warnings
import zlib
from collections import deque
from collections.abc import Callable, Iterator
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ..errors import Argument, ArgumentError, FuzzyposError, Words
from ..geometry import Pose2D
from ..scan import ABSURD_RANGE_M, LaserScan, ScanError
from ._common import (
    FloatArray,
    LogFormatError,
    LogRecord,
    PathLike,
    _lines,
    display_name,
    open_text,
    spool_if_stream,
)
from ._flaser import CONVENTIONS, carmen_beam_geometry, check_convention, check_fov
from .carmen_write import CarmenWriter, write_carmen

__all__ = [
    "CONVENTIONS",
    "ODOMETRY_SOURCES",
    "CarmenFormatError",
    "CarmenWriter",
    "CarmenReader",
    "CarmenRecord",
    "carmen_beam_geometry",
    "read_carmen",
    "write_carmen",
]

#: where a scan's odometry comes from: its own fields, or the ODOM stream at its stamp
ODOMETRY_SOURCES = ("scan", "interpolated")
_ODOMETRY = Argument("odometry")

#: odometry="interpolated": how many ODOM lines before a scan (in file order) it may use ...
_ODOM_HISTORY = 16
#: ... and how many after it at most (it uses those up to the first at or after its stamp)
_ODOM_LOOKAHEAD = 100
#: ... and how many scans may wait for their ODOM lines before the oldest is given the
#: odometry of those seen so far (bounds the memory on a log with few or no ODOM lines)
_MAX_HELD_SCANS = 1000

#: ROBOTLASER1 fields after the remissions: laser pose, robot pose, tv rv forward_safety
#: side_safety turn_axis, ipc_timestamp hostname logger_timestamp
_ROBOTLASER1_TAIL = 14

#: how many skipped-line errors a reader keeps (the count itself is unbounded)
_MAX_KEPT_ERRORS = 100

#: the PARAM names the reader interprets (their values must parse)
_INTERPRETED_PARAMS = ("robot_frontlaser_offset", "robot_front_laser_max")


class CarmenFormatError(LogFormatError):
    """A malformed CARMEN log line, e.g. ``log.clf:17: FLASER: expected 180 ranges, got 179``."""


class _Bad(FuzzyposError):
    """Internal: a line handler's complaint; the reader adds the file and line."""


# -- CARMEN: reading -----------------------------------------------------------------------
#: a CARMEN record is a :class:`~fuzzypos.io.LogRecord` (its odometry is None only for a FLASER
#: line whose odometry fields are not finite)
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


def _count(s: str, what: str, minimum: int) -> int:
    try:
        n = int(s)
    except ValueError:
        raise _Bad(f"{what} is not an integer: {s!r}") from None
    if n < minimum:
        raise _Bad(f"{what} must be >= {minimum}, got {n}")
    return n


#: a list of at least this many numbers (a scan's ranges) is parsed by the compiled kernel
_PARSED_FROM = 16
_PARSER: list[Callable[[NDArray[np.uint8], int], tuple[bool, FloatArray]]] = []


def _load_parser() -> Callable[[NDArray[np.uint8], int], tuple[bool, FloatArray]]:
    """``fuzzypos._kernels.text.parse_decimals``, imported (with numba) on first use and kept
    (``import fuzzypos`` does not import numba)."""
    from .._kernels.text import parse_decimals

    _PARSER.append(parse_decimals)
    return parse_decimals


def _numbers(tok: list[str], what: str) -> FloatArray:
    """``tok`` as a float array (numpy parses; the loop only runs to name a bad field). A
    scan's ranges go through the compiled parser first (``fuzzypos._kernels.text``: the same
    doubles, several times faster), which leaves what it is not sure of to numpy."""
    if len(tok) >= _PARSED_FROM:
        parse = _PARSER[0] if _PARSER else _load_parser()
        text = " ".join(tok).encode("ascii", "replace")
        ok, values = parse(np.frombuffer(text, dtype=np.uint8), len(tok))
        if ok:
            return values
    try:
        return np.array(tok, dtype=np.float64)
    except ValueError:
        for k, s in enumerate(tok):
            _float(s, f"{what} {k + 1} of {len(tok)}")
        raise  # pragma: no cover - numpy and float() disagree


def _check_offset(laser_offset: object) -> Pose2D | None:
    """``laser_offset`` as a Pose2D: TypeError for a wrong type, ValueError for a bad value."""
    if laser_offset is None or isinstance(laser_offset, Pose2D):
        return laser_offset
    if isinstance(laser_offset, (str, bytes)):
        raise TypeError(f"laser_offset must be a Pose2D or None, got {laser_offset!r}")
    try:
        return Pose2D.from_array(laser_offset)  # type: ignore[arg-type]
    except TypeError:
        raise TypeError(
            f"laser_offset must be a Pose2D (or x, y, theta) or None, got {laser_offset!r}"
        ) from None
    except ValueError as exc:
        raise ValueError(f"laser_offset: {exc} (got {laser_offset!r})") from None


class _Held:
    """Internal: a record on its way out, with where it came from (its 1-based line and how
    many ODOM lines came before it) and whether its odometry is final."""

    __slots__ = ("lineno", "odom_seq", "record", "resolved")

    def __init__(self, record: CarmenRecord, lineno: int, odom_seq: int, resolved: bool) -> None:
        self.record = record
        self.lineno = lineno
        self.odom_seq = odom_seq
        self.resolved = resolved


class CarmenReader:
    """Stream the scan records (FLASER, ROBOTLASER1) of a CARMEN log (plain or gzip).

    ``CarmenReader(path, …).records()`` (or iterating the reader) yields
    :class:`CarmenRecord` in file order; the options are :func:`read_carmen`'s (see the module
    docstring) and are kept as attributes (``field_of_view_deg``, ``max_range``,
    ``convention``, ``skip_bad_lines``, ``odometry``, ``laser_offset``). After (or during) the
    iteration:

    - ``bad_lines``: malformed lines skipped (``skip_bad_lines=True``);
    - ``errors``: the :class:`CarmenFormatError` of the first 100 of them;
    - ``truncated``: whether the log ended mid-line or mid-stream (a warning was issued);
    - ``lines``: lines read; ``no_return_value``: the learned "no return" reading (or None);
    - ``params``: the PARAM lines seen, name -> value (as text);
    - ``odom_messages``: the well-formed ODOM lines read;
    - ``bad_odometry``: FLASER lines whose odometry fields are not finite (NaN, inf), the
      first at ``first_bad_odometry_line``: their scans are kept with ``odometry=None`` (a
      bad value of that scan, not a malformed line: the reading goes on, with or without
      ``skip_bad_lines``); ``notes`` says so.

    Each call of :meth:`records` reads the file again from the start and resets these.
    :meth:`scan_stamps` is a quick pass over the scan lines' stamps only.
    """

    #: message type -> handler method name; a handler gets the line's tokens and either
    #: raises :class:`_Bad` or updates the reader's state (a scan goes through
    #: :meth:`_add_scan`)
    _HANDLERS: ClassVar[dict[str, str]] = {
        "FLASER": "_on_flaser",
        "ROBOTLASER1": "_on_robotlaser1",
        "ODOM": "_on_odom",
        "TRUEPOS": "_on_truepos",
        "PARAM": "_on_param",
    }
    #: message types that make a record: a malformed one that is skipped ends the record
    #: before it, so that a TRUEPOS meant for the skipped scan attaches to nothing
    _SCAN_MESSAGES: ClassVar[frozenset[str]] = frozenset({"FLASER", "ROBOTLASER1"})

    def __init__(
        self,
        path: PathLike,
        *,
        field_of_view_deg: float = 180.0,
        max_range: float | None = None,
        convention: str = "auto",
        skip_bad_lines: bool = False,
        odometry: str = "scan",
        laser_offset: Pose2D | None = None,
    ) -> None:
        self.path = spool_if_stream(path)  # a pipe is copied once: records() reads it again
        self.name = display_name(path)
        self.field_of_view_deg = check_fov(field_of_view_deg)
        check_convention(convention)
        self.convention = convention
        if max_range is not None:
            mr = float(max_range)
            if math.isnan(mr) or mr <= 0.0:
                raise ArgumentError(
                    Words(Argument("max_range"), f" must be > 0 (or None), got {max_range!r}")
                )
            max_range = mr
        self.max_range = max_range
        self.skip_bad_lines = bool(skip_bad_lines)
        if odometry not in ODOMETRY_SOURCES:
            raise ArgumentError(
                Words(_ODOMETRY, f" must be one of {ODOMETRY_SOURCES}, got {odometry!r}")
            )
        self.odometry = odometry
        self.laser_offset = _check_offset(laser_offset)
        with open(self.path, "rb"):  # fail here, not at the first record, if it cannot be read
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
        self.odom_messages = 0
        self.bad_odometry = 0
        self.first_bad_odometry_line = 0
        self._param_max: float | None = None
        self._sensor_pose = Pose2D(0.0, 0.0, 0.0)
        self._lineno = 0
        self._pending: _Held | None = None  # the latest scan, waiting for its TRUEPOS
        self._ready: deque[_Held] = deque()  # scans in file order, waiting to be yielded
        # odometry="interpolated": the scans whose odometry is not final yet (file order) and
        # the ODOM lines they may still need, as (index among ODOM lines, stamp, pose)
        self._unresolved: deque[_Held] = deque()
        self._odoms: deque[tuple[int, float, Pose2D]] = deque()

    def __iter__(self) -> Iterator[CarmenRecord]:
        return self.records()

    @property
    def notes(self) -> list[str]:
        """What the latest :meth:`records` pass found odd, as sentences (FLASER lines whose
        odometry fields are not finite)."""
        if not self.bad_odometry or self.odometry != "scan":
            return []
        note = (
            f"{self.bad_odometry:,} FLASER lines have odometry fields that are not finite (the "
            f"first: line {self.first_bad_odometry_line}): those scans are positioned from the "
            "scans alone, without an odometry prior"
        )
        return [note]

    # -- the loop ---------------------------------------------------------------------------
    def records(self) -> Iterator[CarmenRecord]:
        """Yield the log's records in file order (a record waits for its TRUEPOS, so it comes
        out when the next scan or the end of the file arrives; with
        ``odometry="interpolated"`` it may also wait for the ODOM lines after it)."""
        self._reset()
        for lineno, line in self._numbered_lines():
            tokens = line.split()
            if not tokens or tokens[0].startswith("#"):
                continue
            name = self._HANDLERS.get(tokens[0])
            if name is None:
                continue
            self._lineno = lineno
            try:
                getattr(self, name)(tokens)
            except _Bad as bad:
                err = CarmenFormatError(self.path, lineno, str(bad))
                if tokens[0] in self._SCAN_MESSAGES:
                    self._flush_pending()
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
            if len(self._ready) > _MAX_HELD_SCANS:
                self._force_oldest()
            while self._ready and self._ready[0].resolved:
                yield self._ready.popleft().record
        self._flush_pending()
        while self._unresolved:  # the end of the log: no later ODOM will come
            self._force_oldest()
        while self._ready:
            yield self._ready.popleft().record

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

    def scan_stamps(self) -> FloatArray:
        """The ``ipc_timestamp`` of every ``FLASER`` / ``ROBOTLASER1`` line in file order (the
        third field from the end), read without parsing the scans: a quick look at a log's
        stamps (one pass over the file; read-only). Lines whose field is not a finite number
        are left out; a damaged gzip stream ends the pass (:meth:`records` reports it)."""
        stamps = np.fromiter(self._scan_stamps(), dtype=np.float64)
        stamps.setflags(write=False)
        return stamps

    def _scan_stamps(self) -> Iterator[float]:
        with open_text(self.path) as fh:
            try:
                for _, line in _lines(fh, self.path, CarmenFormatError):
                    if not line.startswith(("FLASER ", "ROBOTLASER1 ")):
                        continue
                    tail = line.rsplit(None, 3)
                    try:
                        t = float(tail[1]) if len(tail) == 4 else math.nan
                    except ValueError:
                        continue
                    if math.isfinite(t):
                        yield t
            except CarmenFormatError:  # a damaged stream ends the pass; records() reports it
                return

    def _flush_pending(self) -> None:
        if self._pending is not None:
            self._ready.append(self._pending)
            self._pending = None

    def _add_scan(self, scan: LaserScan, odometry: Pose2D | None) -> None:
        """A parsed scan line: it becomes the pending record (the previous one is done)."""
        self._flush_pending()
        held = _Held(
            CarmenRecord(scan, odometry, None),
            self._lineno,
            self.odom_messages,
            resolved=self.odometry == "scan",
        )
        if not held.resolved:
            self._unresolved.append(held)
        self._pending = held

    # -- message handlers -------------------------------------------------------------------
    def _on_flaser(self, tok: list[str]) -> None:
        if len(tok) < 2:
            raise _Bad("FLASER: missing the beam count")
        n = _count(tok[1], "FLASER: beam count", 2)
        if len(tok) != n + 11:
            raise _Bad(
                f"FLASER: expected {n} ranges, got {len(tok) - 11} (line has {len(tok)} "
                f"fields; FLASER needs n + 11: n ranges, x y θ, odom_x odom_y odom_θ, "
                f"ipc_timestamp hostname logger_timestamp)"
            )
        ranges = _numbers(tok[2 : 2 + n], "FLASER: range")
        p = 2 + n
        for k, what in enumerate(("x", "y", "θ")):
            _float(tok[p + k], f"FLASER: {what}")
        ox = _float(tok[p + 3], "FLASER: odom_x")
        oy = _float(tok[p + 4], "FLASER: odom_y")
        ot = _float(tok[p + 5], "FLASER: odom_θ")
        odometry: Pose2D | None = None
        if math.isfinite(ox) and math.isfinite(oy) and math.isfinite(ot):
            odometry = Pose2D(ox, oy, ot)
        else:  # a bad value of this scan, not of the log: the scan is kept without odometry
            self.bad_odometry += 1
            if self.first_bad_odometry_line == 0:
                self.first_bad_odometry_line = self._lineno
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
            sensor_pose=self._sensor_pose if self.laser_offset is None else self.laser_offset,
        )
        self._add_scan(scan, odometry)

    def _range_max(self, ranges: FloatArray) -> float:
        """The scan's ``range_max`` (module docstring, "Maximum range")."""
        if self.max_range is not None:
            return self.max_range
        if self._param_max is not None:
            return self._param_max
        with np.errstate(invalid="ignore"):  # absurd readings are no scanner's "no return"
            finite = ranges[np.abs(ranges) < ABSURD_RANGE_M]
        if finite.size == 0:
            m = -math.inf
        else:
            m = float(finite.max())
            v = self.no_return_value
            if m > 0.0 and (v is None or m > v) and np.count_nonzero(finite == m) >= 2:
                self.no_return_value = m
        v = self.no_return_value
        return v if v is not None and m <= v else math.inf

    def _on_robotlaser1(self, tok: list[str]) -> None:
        # ROBOTLASER1 laser_type start_angle fov angular_res max_range accuracy remission_mode
        # n r_1..r_n n_rem rem_1..rem_m laser_x laser_y laser_θ robot_x robot_y robot_θ
        # tv rv forward_safety side_safety turn_axis ipc_timestamp hostname logger_timestamp
        if len(tok) < 10:
            raise _Bad(
                f"ROBOTLASER1: line has {len(tok)} fields, too few for the header "
                f"(laser_type start_angle fov angular_res max_range accuracy remission_mode n) "
                f"and the remission count"
            )
        _float(tok[1], "ROBOTLASER1: laser_type")
        start = _finite(tok[2], "ROBOTLASER1: start_angle")
        _finite(tok[3], "ROBOTLASER1: fov")
        res = _finite(tok[4], "ROBOTLASER1: angular_res")
        if res == 0.0:
            raise _Bad("ROBOTLASER1: angular_res must be non-zero")
        max_range = _float(tok[5], "ROBOTLASER1: max_range")
        if math.isnan(max_range) or max_range <= 0.0:
            raise _Bad(f"ROBOTLASER1: max_range must be > 0, got {tok[5]!r}")
        _float(tok[6], "ROBOTLASER1: accuracy")
        _float(tok[7], "ROBOTLASER1: remission_mode")
        n = _count(tok[8], "ROBOTLASER1: beam count n", 1)
        q = 9 + n  # where n_rem should be
        if len(tok) < q + 1 + _ROBOTLASER1_TAIL:
            raise _Bad(
                f"ROBOTLASER1: expected at least {q + 1 + _ROBOTLASER1_TAIL} fields for "
                f"{n} ranges (n + 24 with no remissions), got {len(tok)}"
            )
        try:
            m = int(tok[q])
        except ValueError:
            raise _Bad(
                f"ROBOTLASER1: n_rem (field {q + 1}, after {n} ranges) is not an integer: "
                f"{tok[q]!r} (is the range count n = {n} right?)"
            ) from None
        room = len(tok) - q - 1 - _ROBOTLASER1_TAIL
        if m != room:
            raise _Bad(
                f"ROBOTLASER1: n_rem is {m} but the line has {room} fields between it and the "
                f"{_ROBOTLASER1_TAIL} trailing ones (laser pose, robot pose, tv rv "
                f"forward_safety side_safety turn_axis, ipc_timestamp hostname "
                f"logger_timestamp); {len(tok)} fields for n = {n}"
            )
        ranges = _numbers(tok[9:q], "ROBOTLASER1: range")
        _numbers(tok[q + 1 : q + 1 + m], "ROBOTLASER1: remission")
        p = q + 1 + m
        laser = Pose2D(
            _finite(tok[p], "ROBOTLASER1: laser_x"),
            _finite(tok[p + 1], "ROBOTLASER1: laser_y"),
            _finite(tok[p + 2], "ROBOTLASER1: laser_θ"),
        )
        robot = Pose2D(
            _finite(tok[p + 3], "ROBOTLASER1: robot_x"),
            _finite(tok[p + 4], "ROBOTLASER1: robot_y"),
            _finite(tok[p + 5], "ROBOTLASER1: robot_θ"),
        )
        for k, what in enumerate(("tv", "rv", "forward_safety", "side_safety", "turn_axis")):
            _float(tok[p + 6 + k], f"ROBOTLASER1: {what}")
        stamp = _finite(tok[p + 11], "ROBOTLASER1: ipc_timestamp")
        _finite(tok[p + 13], "ROBOTLASER1: logger_timestamp")
        if self.laser_offset is not None:
            sensor_pose = self.laser_offset
        else:  # the laser's mounting pose on the robot: ⊖robot ⊕ laser
            sensor_pose = robot.inverse().compose(laser)
        try:
            scan = LaserScan(
                ranges,
                start,
                res,
                range_min=0.0,
                range_max=max_range if self.max_range is None else self.max_range,
                stamp=stamp,
                sensor_pose=sensor_pose,
            )
        except ScanError as exc:  # e.g. n beams of angular_res span more than one turn
            raise _Bad(f"ROBOTLASER1: {exc}") from None
        self._add_scan(scan, robot)

    def _on_odom(self, tok: list[str]) -> None:
        if len(tok) != 10:
            raise _Bad(
                f"ODOM: expected 10 fields (ODOM x y θ tv rv accel ipc_timestamp hostname "
                f"logger_timestamp), got {len(tok)}"
            )
        x = _finite(tok[1], "ODOM: x")
        y = _finite(tok[2], "ODOM: y")
        th = _finite(tok[3], "ODOM: θ")
        for k, what in ((4, "tv"), (5, "rv"), (6, "accel")):
            _finite(tok[k], f"ODOM: {what}")
        stamp = _finite(tok[7], "ODOM: ipc_timestamp")
        _finite(tok[9], "ODOM: logger_timestamp")
        seq = self.odom_messages
        self.odom_messages += 1
        if self.odometry == "scan":
            return
        odoms = self._odoms
        odoms.append((seq, stamp, Pose2D(x, y, th)))
        if self._unresolved:
            still: deque[_Held] = deque()
            for held in self._unresolved:
                if stamp >= held.record.scan.stamp or seq + 1 - held.odom_seq >= _ODOM_LOOKAHEAD:
                    self._resolve(held)
                else:
                    still.append(held)
            self._unresolved = still
        oldest = self._unresolved[0].odom_seq if self._unresolved else self.odom_messages
        while odoms and odoms[0][0] < oldest - _ODOM_HISTORY:
            odoms.popleft()

    def _force_oldest(self) -> None:
        """Give the oldest unresolved scan its odometry from the ODOM lines seen so far (the end
        of the log, or too many scans waiting)."""
        if self._unresolved:
            self._resolve(self._unresolved.popleft())

    def _resolve(self, held: _Held) -> None:
        """Interpolate the ODOM stream at the scan's stamp (module docstring, "Odometry")."""
        t = held.record.scan.stamp
        lo = held.odom_seq - _ODOM_HISTORY
        before: tuple[float, Pose2D] | None = None  # the latest stamp <= t
        after: tuple[float, Pose2D] | None = None  # the earliest stamp >= t
        for seq, ts, pose in self._odoms:
            if seq < lo:
                continue
            if ts <= t and (before is None or ts >= before[0]):
                before = (ts, pose)
            if ts >= t and (after is None or ts < after[0]):
                after = (ts, pose)
        if before is None and after is None:
            raise CarmenFormatError(
                self.path,
                held.lineno,
                Words(
                    Argument.given("odometry"),
                    "'interpolated', but no ODOM line comes within "
                    f"{_ODOM_HISTORY} ODOM lines before this scan or {_MAX_HELD_SCANS} scans "
                    "after it (does the log have ODOM lines?)",
                ),
            )
        if before is None or after is None or after[0] == before[0]:
            pose = before[1] if before is not None else after[1]  # type: ignore[index]
        else:
            s = (t - before[0]) / (after[0] - before[0])
            b, a = before[1], after[1]
            dth = math.remainder(a.theta - b.theta, math.tau)  # the shorter way round
            pose = Pose2D(b.x + s * (a.x - b.x), b.y + s * (a.y - b.y), b.theta + s * dth)
        held.record = held.record._replace(odometry=pose)
        held.resolved = True

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
        held = self._pending
        if held is not None and held.record.truth is None:
            held.record = held.record._replace(truth=Pose2D(tx, ty, tt))

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
    odometry: str = "scan",
    laser_offset: Pose2D | None = None,
) -> Iterator[CarmenRecord]:
    """Stream the :class:`CarmenRecord` of a CARMEN log (plain or gzip) in file order.

    ``field_of_view_deg`` and ``convention`` give the FLASER beam angles
    (:func:`carmen_beam_geometry`; they must match what wrote the log; ROBOTLASER1 lines carry
    their own); ``max_range``: a reading at or above it is invalid (None: ROBOTLASER1's own
    field, for FLASER ``PARAM robot_front_laser_max``, else learned from the data; module
    docstring); ``skip_bad_lines``: skip malformed lines instead of raising
    :class:`CarmenFormatError` (use :class:`CarmenReader` to get their count); ``odometry``:
    ``"scan"`` (each scan's own odometry fields) or ``"interpolated"`` (the ODOM stream at the
    scan's stamp); ``laser_offset``: the laser's mounting pose on the robot, overriding
    ``PARAM robot_frontlaser_offset`` and ROBOTLASER1's pose fields.
    """
    return CarmenReader(
        path,
        field_of_view_deg=field_of_view_deg,
        max_range=max_range,
        convention=convention,
        skip_bad_lines=skip_bad_lines,
        odometry=odometry,
        laser_offset=laser_offset,
    ).records()
