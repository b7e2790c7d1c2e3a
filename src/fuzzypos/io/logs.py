"""Opening robot logs whatever they are, choosing a stretch of them, and describing them.

- :func:`open_log` tells a log's kind by its *content*, never by its name, and returns an
  :class:`OpenLog` whose :meth:`~OpenLog.records` streams :class:`~fuzzypos.io.LogRecord`:

  ================================================  ============  ==================================
  what the path is                                  ``kind``      read with
  ================================================  ============  ==================================
  a directory holding ``metadata.yaml``             ``"ros2"``    :class:`~fuzzypos.io.BagReader`
  a file starting with ``#ROSBAG V2.0``             ``"ros1"``    :class:`~fuzzypos.io.BagReader`
  a gzip file (by its magic bytes), or text         ``"carmen"``  :class:`~fuzzypos.io.CarmenReader`
  anything else (binary data, other directories)    —             :class:`UnknownLogError`
  ================================================  ============  ==================================

  "Text" means: the first 8 KiB (decompressed, for gzip) hold no NUL byte and decode as UTF-8
  (a multi-byte character cut at the end of the 8 KiB is allowed). An empty file is text (a
  CARMEN log without scans). A path that does not exist raises :class:`FileNotFoundError`.
  A pipe or FIFO (``<(zcat log.clf.gz)``, ``/dev/stdin``), which can be read only once, is
  first copied into a temporary file (:class:`~fuzzypos.io._common.Spool`: it is
  :attr:`OpenLog.path`, shown everywhere by the name given, and removed with the log), so
  that sniffing, counting, reading and hashing all see the whole of it.
- :func:`select_records` picks a stretch of a record stream by time and count, streaming.
- :class:`StampCheck` judges how a log's scan stamps run; :meth:`OpenLog.check_stamps`
  refuses a log whose stamps cannot give the time between its scans (:class:`StampError`)
  before anything is positioned.
- :func:`describe_log` reads a whole log once and summarises it (:class:`LogInfo`).
- :func:`find_no_return_values` reads a whole log once for the values its scanner uses as
  "no return" codes (:mod:`fuzzypos.io.no_returns`); :func:`describe_log` finds them too.
- :func:`parse_laser_offset` reads the command line's ``x,y,θdeg``.

Every error here is a :class:`ValueError` subclass naming what is wrong (or an
:class:`OSError` from the file system), so that the command line can print it on one line.
"""

from __future__ import annotations

import errno
import gzip
import math
import os
import warnings
import zlib
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, TypeVar, Union

import numpy as np

from ..config import ScannerConfig
from ..errors import Argument, ArgumentError, Words
from ..geometry import Pose2D
from ..scan import LaserScan, no_return_counts
from ._common import GZIP_MAGIC, LogFormatError, LogRecord, display_name, spool_if_stream
from .carmen import CarmenReader
from .no_returns import FoundNoReturn, RangeTally
from .odometry_check import OdometryCoverage
from .rosbag import ROS1_MAGIC, BagReader

__all__ = [
    "LOG_KINDS",
    "LogInfo",
    "NoReturnCount",
    "OpenLog",
    "SelectionError",
    "StampCheck",
    "StampError",
    "UnknownLogError",
    "describe_log",
    "empty_stretch",
    "find_no_return_values",
    "log_kind",
    "open_log",
    "parse_laser_offset",
    "select_records",
    "select_stamps",
    "survey_log",
]

PathLike = Union[str, "os.PathLike[str]"]

#: what :attr:`OpenLog.kind` may be
LOG_KINDS = ("carmen", "ros1", "ros2")

#: how many leading bytes :func:`log_kind` looks at to tell text from binary
_SNIFF_BYTES = 8192

#: the first bytes of files that are parts of a ROS2 bag (its storage), for a better message
_ROS2_STORAGE_MAGIC = {b"SQLite format 3\x00": "sqlite3", b"\x89MCAP0\r\n": "mcap"}


class UnknownLogError(LogFormatError):
    """A path that is no log fuzzypos reads (neither a CARMEN log nor a ROS1/ROS2 bag):
    ``"<path>: not a log: …"``."""

    def __init__(self, path: PathLike, reason: str) -> None:
        super().__init__(path, 0, reason)

    def __reduce__(self) -> tuple[type, tuple[str, str]]:  # type: ignore[override]
        return (type(self), (self.path, self.reason))


_MAX_SCANS = Argument("max_scans")
_RATE = Argument("scan_rate_hz")


class SelectionError(ArgumentError):
    """A bad ``start`` / ``end`` / ``max_scans`` (or ``--laser-offset``) argument."""


class StampError(LogFormatError):
    """A log whose scan stamps cannot give the time between its scans (most of them repeat or
    go back on the stamp before them): ``"<path>: …"``, from :meth:`OpenLog.check_stamps`."""


# -- telling the kind ----------------------------------------------------------------------
def _is_text(head: bytes, complete: bool) -> bool:
    """Whether ``head`` (the first bytes of a file; ``complete`` when that is all of it) looks
    like UTF-8 text."""
    if b"\x00" in head:
        return False
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        # a multi-byte character cut by the end of the sniffed block is still text
        return (
            not complete and exc.start >= len(head) - 3 and exc.reason == "unexpected end of data"
        )
    return True


def log_kind(path: PathLike) -> str:
    """``"ros2"``, ``"ros1"`` or ``"carmen"`` from the content of ``path`` (see the module
    docstring); :class:`UnknownLogError` for anything else, :class:`FileNotFoundError` when
    nothing is there, an ``OSError`` (``ELOOP``, "symlink loop") for a symbolic link that
    leads back to itself."""
    p = Path(path)
    name = display_name(path)
    try:
        os.stat(p)
    except OSError as exc:
        if exc.errno == errno.ELOOP:  # not "No such file or directory"
            what = "symlink loop (too many levels of symbolic links)"
            raise OSError(errno.ELOOP, what, name) from None
        raise type(exc)(exc.errno, exc.strerror, name) from None
    if p.is_dir():
        if (p / "metadata.yaml").is_file():
            return "ros2"
        raise UnknownLogError(
            path, "not a log: a directory without metadata.yaml (a ROS2 bag directory holds one)"
        )
    with open(p, "rb") as f:
        head = f.read(_SNIFF_BYTES)
        complete = len(head) < _SNIFF_BYTES or not f.read(1)
    if head.startswith(ROS1_MAGIC):
        return "ros1"
    if head.startswith(GZIP_MAGIC):
        try:
            with gzip.open(p, "rb") as gz:
                inner = gz.read(_SNIFF_BYTES)
                inner_complete = len(inner) < _SNIFF_BYTES
        except (OSError, EOFError, zlib.error) as exc:
            raise UnknownLogError(path, f"not a log: a broken gzip file ({exc})") from None
        if not _is_text(inner, inner_complete):
            raise UnknownLogError(
                path, "not a log: a gzip file whose content is binary, not a CARMEN text log"
            )
        return "carmen"
    for magic, storage in _ROS2_STORAGE_MAGIC.items():
        if head.startswith(magic):
            raise UnknownLogError(
                path,
                f"not a log: this looks like the {storage} storage file of a ROS2 bag; give the "
                "bag's directory (the one holding metadata.yaml)",
            )
    if not _is_text(head, complete):
        raise UnknownLogError(
            path,
            "not a log: binary content that is neither a ROS1 bag (starting with "
            f"{ROS1_MAGIC.decode()!r}), a gzip file nor a CARMEN text log",
        )
    return "carmen"


# -- the open log ---------------------------------------------------------------------------
@dataclass(eq=False)
class OpenLog:
    """A log opened by :func:`open_log`.

    ``path`` as given (for a pipe, its :class:`~fuzzypos.io._common.Spool`, which opens as
    the copy and reads as the name given); ``kind``: ``"carmen"``, ``"ros1"`` or ``"ros2"``;
    ``reader``: the
    :class:`~fuzzypos.io.CarmenReader` or :class:`~fuzzypos.io.BagReader` (its counters,
    e.g. ``bad_lines``, are those of the latest :meth:`records` pass); ``notes``: what the
    reader assumed or found odd, and the options that do not apply to this kind of log, as
    sentences; ``options``: the reader options used (plain values, for a summary).
    """

    path: PathLike
    kind: str
    reader: CarmenReader | BagReader
    notes: list[str] = field(default_factory=list)
    options: dict[str, Any] = field(default_factory=dict)
    #: the scans taken as evenly spaced at this rate (Hz) in file order, stamped ``k / rate``
    #: (``k`` from 0), instead of the log's own stamps (None: the log's)
    scan_rate_hz: float | None = None

    _stamps: Any = field(default=None, init=False, repr=False)

    @property
    def name(self) -> str:
        return display_name(self.path)

    def records(self) -> Iterator[LogRecord]:
        """Stream the log's records in file (bag) order; each call reads the log again. With
        :attr:`scan_rate_hz` the scans are stamped ``k / scan_rate_hz`` (the odometry is
        still the log's at its own stamps)."""
        if self.scan_rate_hz is None:
            return self.reader.records()
        return _evenly_stamped(self.reader.records(), self.scan_rate_hz)

    def __iter__(self) -> Iterator[LogRecord]:
        return self.records()

    @property
    def has_odometry(self) -> bool:
        """Whether the log has odometry: a CARMEN log always (its scan lines carry it), a bag
        with an odometry topic that holds messages."""
        return bool(getattr(self.reader, "has_odometry", True))

    @property
    def bad_lines(self) -> int:
        """Malformed lines skipped so far (CARMEN with ``skip_bad_lines``; 0 for a bag)."""
        return int(getattr(self.reader, "bad_lines", 0))

    @property
    def truncated(self) -> bool:
        """Whether a CARMEN log ended mid-line or mid-stream (False for a bag)."""
        return bool(getattr(self.reader, "truncated", False))

    def scan_count_hint(self) -> int | None:
        """The number of scans, when known without reading the scans: a bag's index; for a
        CARMEN log a quick count of its ``FLASER`` / ``ROBOTLASER1`` lines with a stamp
        (:meth:`scan_stamps`). None when it cannot be had."""
        if isinstance(self.reader, BagReader):
            return int(self.reader.scan_count)
        try:
            return int(self.scan_stamps().shape[0])
        except OSError:
            return None

    def scan_stamps(self) -> np.ndarray:
        """Every scan's stamp in file (bag) order, read without parsing the scans (read-only;
        the first call reads them, unless :func:`survey_log` took them:
        :meth:`CarmenReader.scan_stamps` / :meth:`BagReader.scan_stamps`)."""
        if self._stamps is None:
            stamps = self.reader.scan_stamps()
            if self.scan_rate_hz is not None:
                stamps = np.arange(stamps.shape[0], dtype=np.float64) / self.scan_rate_hz
                stamps.setflags(write=False)
            self._stamps = stamps
        return self._stamps  # type: ignore[no-any-return]

    def check_stamps(
        self,
        *,
        start: float | None = None,
        end: float | None = None,
        max_scans: int | None = None,
    ) -> StampCheck:
        """Judge the stamps of the scans a run of this stretch (:func:`select_records`'s
        ``start``, ``end``, ``max_scans``) would position, before positioning any.

        The positioner needs the time between scans (the odometry is judged against what a
        robot can move in it). Raises :class:`StampError`, naming the log and how many scans
        are affected, when the stamps are :attr:`StampCheck.unusable` (most scans repeat or
        go back on the stamp before them: a corrupt log, which would run for ages with every
        odometry increment rejected); a lesser problem (some repeated stamps, an absurd jump)
        is a :class:`RuntimeWarning` naming the log. A few bad stamps in a long log lose
        nothing: the positioner falls back per scan."""
        chosen = select_stamps(self.scan_stamps(), start=start, end=end, max_scans=max_scans)
        check = StampCheck.of(chosen)
        if check.unusable:
            raise StampError(
                self.path,
                0,
                Words(
                    f"{check.remark()}; fuzzypos needs the time between scans to judge the "
                    f"odometry (see `fuzzypos info {self.name}`); to take the scans as evenly "
                    "spaced in file order at the scanner's rate, pass ",
                    Argument.given("scan_rate_hz"),
                    "HZ",
                ),
            )
        remark = check.remark()
        if remark is not None:
            warnings.warn(f"{self.name}: {remark}", RuntimeWarning, stacklevel=2)
        return check


def _evenly_stamped(records: Iterator[LogRecord], rate_hz: float) -> Iterator[LogRecord]:
    for k, rec in enumerate(records):
        yield rec._replace(scan=replace(rec.scan, stamp=k / rate_hz))


def _scan_rate(scan_rate_hz: float | None) -> float | None:
    """``scan_rate_hz`` checked: None, or a finite rate > 0 (else :class:`SelectionError`)."""
    if scan_rate_hz is None:
        return None
    try:
        rate = float(scan_rate_hz)
    except (TypeError, ValueError):
        raise SelectionError(Words(_RATE, f" must be a number, got {scan_rate_hz!r}")) from None
    if not (math.isfinite(rate) and rate > 0.0):
        raise SelectionError(Words(_RATE, f" must be a finite rate > 0 (Hz), got {scan_rate_hz!r}"))
    return rate


def open_log(
    path: PathLike,
    *,
    scan_topic: str | None = None,
    odom_topic: str | None = None,
    laser_offset: Pose2D | None = None,
    skip_bad_lines: bool = False,
    odometry: str = "scan",
    field_of_view_deg: float = 180.0,
    max_range: float | None = None,
    convention: str = "auto",
    scan_rate_hz: float | None = None,
    base_frame: str | None = None,
) -> OpenLog:
    """Open a CARMEN log or a ROS1/ROS2 bag, telling which by content (module docstring).

    ``scan_rate_hz``: take the scans as evenly spaced at this rate in file order (stamps
    ``k / scan_rate_hz`` from 0) instead of their own stamps, for a log whose stamps are
    corrupt (:class:`StampError`); said in :attr:`OpenLog.notes` and ``options``.

    CARMEN logs take ``skip_bad_lines``, ``odometry`` (``"scan"``: each scan line's own
    odometry fields; ``"interpolated"``: the ODOM stream at the scan's stamp),
    ``field_of_view_deg``, ``max_range``, ``convention`` and ``laser_offset``
    (:class:`~fuzzypos.io.CarmenReader`). Bags take ``scan_topic``, ``odom_topic`` and
    ``laser_offset`` and ``base_frame`` (the robot's frame, whose pose is estimated:
    :class:`~fuzzypos.io.BagReader`; their odometry is always the odometry topic interpolated
    at the scan's stamp). An option given that does not apply to the kind
    found is ignored with a note in :attr:`OpenLog.notes`.

    Raises :class:`FileNotFoundError` for a missing path, :class:`UnknownLogError` for what
    is no log, and the reader's own errors (``ValueError`` subclasses) for bad options or a
    bag that cannot be opened.
    """
    if laser_offset is not None and not isinstance(laser_offset, Pose2D):
        raise TypeError(f"laser_offset must be a Pose2D or None, got {type(laser_offset).__name__}")
    rate = _scan_rate(scan_rate_hz)
    path = spool_if_stream(path)  # a pipe can be read once: copy it, read the copy
    kind = log_kind(path)
    notes: list[str] = []
    options: dict[str, Any] = {
        "laser_offset": None if laser_offset is None else list(laser_offset.as_array()),
    }
    reader: CarmenReader | BagReader
    if kind == "carmen":
        for given, what in ((scan_topic, "scan_topic"), (odom_topic, "odom_topic")):
            if given is not None:
                notes.append(f"{what} applies to bags only; ignored for this CARMEN log")
        reader = CarmenReader(
            path,
            field_of_view_deg=field_of_view_deg,
            max_range=max_range,
            convention=convention,
            skip_bad_lines=skip_bad_lines,
            odometry=odometry,
            laser_offset=laser_offset,
        )
        options.update(
            field_of_view_deg=reader.field_of_view_deg,
            max_range=reader.max_range,
            convention=reader.convention,
            skip_bad_lines=reader.skip_bad_lines,
            odometry=reader.odometry,
        )
    else:
        ignored = []
        if skip_bad_lines:
            ignored.append("skip_bad_lines")
        if odometry != "scan":
            ignored.append(f"odometry={odometry!r} (a bag's odometry is always interpolated)")
        if float(field_of_view_deg) != 180.0:
            ignored.append("field_of_view_deg (a bag's scans carry their angles)")
        if max_range is not None:
            ignored.append("max_range (a bag's scans carry their range_max)")
        if convention != "auto":
            ignored.append("convention")
        for what in ignored:
            notes.append(f"{what}: applies to CARMEN logs only; ignored for this bag")
        reader = BagReader(
            path,
            scan_topic=scan_topic,
            odom_topic=odom_topic,
            laser_offset=laser_offset,
            base_frame=base_frame,
        )
        notes.extend(reader.notes)
        options.update(
            scan_topic=reader.scan_topic,
            odom_topic=reader.odom_topic,
            sensor_pose_source=reader.sensor_pose_source,
        )
    if rate is not None:
        options["scan_rate_hz"] = rate
        notes.append(
            f"scan_rate_hz={rate:g}: the scans are taken as evenly spaced {1.0 / rate:g} s apart "
            f"in file order (stamps k/{rate:g} s from 0), not stamped as in the log"
        )
    return OpenLog(
        path=path, kind=kind, reader=reader, notes=notes, options=options, scan_rate_hz=rate
    )


# -- choosing a stretch -----------------------------------------------------------------------
def _seconds(name: str, value: float | None) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool):
        raise SelectionError(Words(Argument(name), f" must be a number of seconds, got {value!r}"))
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SelectionError(
            Words(Argument(name), f" must be a number of seconds, got {value!r}")
        ) from None
    if not math.isfinite(v) or v < 0.0:
        raise SelectionError(
            Words(Argument(name), f" must be a finite number of seconds >= 0, got {value!r}")
        )
    return v


def select_records(
    records: Iterable[LogRecord],
    *,
    start: float | None = None,
    end: float | None = None,
    max_scans: int | None = None,
) -> Iterator[LogRecord]:
    """A stretch of ``records`` (in their order), as a generator that reads no further than
    it needs.

    ``start`` and ``end`` are seconds relative to ``t0``, the stamp of the *first record of
    the stream* (not the smallest stamp); ``rel = stamp - t0``. Because stamps may go
    backwards in file order (intel: 631 times, by up to 0.9 s), the stretch is defined by
    positions in the stream, not by a time filter:

    - it begins at the first record (in stream order) with ``rel >= start`` (``start`` None
      or 0: the first record). Every record after that one is a candidate, even one whose
      ``rel`` is back below ``start``;
    - it ends just before the first record after its beginning with ``rel > end`` (``end``
      None: never); that record and everything after it are left out, even records whose
      ``rel`` comes back under ``end``;
    - ``max_scans`` (None: no cap) stops it after that many records.

    So the stretch is always one contiguous run of the log in file order. ``start`` and
    ``end`` must be finite and ``>= 0`` with ``end >= start``; ``max_scans`` an integer
    ``>= 1``; otherwise :class:`SelectionError` (raised here, not at the first ``next()``).
    """
    s, e = _selection(start, end, max_scans)
    return _select(iter(records), s, e, max_scans, _record_stamp)


def select_stamps(
    stamps: Iterable[float],
    *,
    start: float | None = None,
    end: float | None = None,
    max_scans: int | None = None,
) -> np.ndarray:
    """The stamps of the records :func:`select_records` would pick from records stamped
    ``stamps`` (same arguments, same rules, same errors), as an array."""
    s, e = _selection(start, end, max_scans)
    chosen = _select(iter(stamps), s, e, max_scans, float)
    return np.fromiter(chosen, dtype=np.float64)


def empty_stretch(log: OpenLog, start: float | None, end: float | None) -> SelectionError | None:
    """The error for a stretch (``start``, ``end``) that holds none of ``log``'s scans when the
    log has some: the log's first and last stamps and its duration, so that the user can
    choose again. None when the log has no scans at all (or its stamps cannot be read)."""
    try:
        stamps = log.scan_stamps()
    except (ValueError, OSError):
        return None
    if stamps.shape[0] == 0:
        return None
    first, last = float(stamps[0]), float(stamps[-1])
    asked: list[str | Argument] = []
    for name, v in (("start", start), ("end", end)):
        if v is not None:
            asked += [" and "] if asked else []
            asked += [Argument.given(name), f"{v:g} s"]
    return SelectionError(
        Words(
            f"{log.name}: the stretch (",
            *asked,
            ", counted from the first scan's stamp) holds no scans: the log's "
            f"{stamps.shape[0]:,} scans run from stamp {first!r} to {last!r} "
            f"({last - first:.3f} s)",
        )
    )


def _selection(
    start: float | None, end: float | None, max_scans: int | None
) -> tuple[float, float | None]:
    """``start`` (0 for None) and ``end`` checked, and ``max_scans``; SelectionError else."""
    s = _seconds("start", start)
    e = _seconds("end", end)
    if s is not None and e is not None and e < s:
        raise SelectionError(
            Words(
                Argument("end"),
                f" ({e:g} s) must not come before ",
                Argument("start"),
                f" ({s:g} s)",
            )
        )
    if max_scans is not None:
        if isinstance(max_scans, bool) or not isinstance(max_scans, int):
            raise SelectionError(Words(_MAX_SCANS, f" must be a whole number, got {max_scans!r}"))
        if max_scans < 1:
            raise SelectionError(Words(_MAX_SCANS, f" must be at least 1, got {max_scans}"))
    return s or 0.0, e


def _record_stamp(rec: LogRecord) -> float:
    return rec.scan.stamp


_T = TypeVar("_T")


def _select(
    it: Iterator[_T],
    start: float,
    end: float | None,
    max_scans: int | None,
    stamp_of: Callable[[_T], float],
) -> Iterator[_T]:
    t0: float | None = None
    begun = False
    count = 0
    for rec in it:
        stamp = stamp_of(rec)
        if t0 is None:
            t0 = stamp
        rel = stamp - t0
        if not begun:
            if rel < start:
                continue
            begun = True
        if end is not None and rel > end:
            return
        yield rec
        count += 1
        if max_scans is not None and count >= max_scans:
            return


# -- judging the stamps ----------------------------------------------------------------------
#: consecutive scans (in file order) further apart than this (s) are an absurd jump: no robot
#: log runs a day without a scan; stamps in other units than seconds, or corrupt ones, do
ABSURD_GAP_S = 86400.0


@dataclass
class StampCheck:
    """How the stamps of a log's scans run, in file order (:meth:`add` them one at a time, or
    :meth:`of` a sequence).

    ``scans``; ``repeated``: scans stamped the same as the scan before them; ``backwards``:
    scans stamped before it (intel: 631 of 13,631, two hosts' clocks; harmless);
    ``largest_gap_s``: the longest step forward between consecutive scans, ``largest_gap_at``
    the 0-based index of the scan after it.
    """

    scans: int = 0
    repeated: int = 0
    backwards: int = 0
    largest_gap_s: float = 0.0
    largest_gap_at: int = 0
    _prev: float | None = field(default=None, init=False, repr=False, compare=False)

    @classmethod
    def of(cls, stamps: Iterable[float]) -> StampCheck:
        check = cls()
        for t in stamps:
            check.add(float(t))
        return check

    def add(self, t: float) -> None:
        prev = self._prev
        if prev is not None:
            if t == prev:
                self.repeated += 1
            elif t < prev:
                self.backwards += 1
            elif t - prev > self.largest_gap_s:
                self.largest_gap_s = t - prev
                self.largest_gap_at = self.scans
        self._prev = t
        self.scans += 1

    @property
    def unusable(self) -> bool:
        """Whether most scans after the first (more than half, of at least 3 scans) repeat or
        go back on the stamp before them: the stamps cannot give the time between scans."""
        return self.scans >= 3 and 2 * (self.repeated + self.backwards) > self.scans - 1

    @property
    def absurd_gap(self) -> bool:
        """Whether two consecutive scans are more than :data:`ABSURD_GAP_S` apart."""
        return self.largest_gap_s > ABSURD_GAP_S

    @property
    def corrupt(self) -> bool:
        """:attr:`unusable` or :attr:`absurd_gap`: the log's duration means nothing."""
        return self.unusable or self.absurd_gap

    def remark(self) -> str | None:
        """What is wrong with the stamps, as a sentence (None when nothing is): most scans
        out of order, an absurd jump, or scans that repeat the stamp before them. Stamps
        that go backwards now and then are left unsaid (``backwards`` counts them)."""
        n, rep, back = self.scans, self.repeated, self.backwards
        if self.unusable:
            return (
                f"the scans' stamps are corrupt: {rep + back:,} of {n:,} scans repeat or go back "
                f"on the stamp of the scan before them ({rep:,} repeat it, {back:,} go back)"
            )
        if self.absurd_gap:
            k = self.largest_gap_at
            return (
                f"the scans' stamps jump forward by {self.largest_gap_s:.6g} s between scans "
                f"{k - 1:,} and {k:,} (counting from 0): stamps that are not seconds, or corrupt"
                + (f"; {rep:,} of {n:,} scans repeat the stamp before them" if rep else "")
            )
        if rep:
            return (
                f"{rep:,} of {n:,} scans repeat the stamp of the scan before them: their "
                "odometry is judged over 0 s"
            )
        return None


# -- the command line's laser offset ----------------------------------------------------------
def parse_laser_offset(text: str) -> Pose2D:
    """``"x,y,θ"`` (metres, metres, degrees) → the laser's mounting pose on the robot
    (θ in radians). :class:`SelectionError` for anything else."""
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) != 3:
        raise SelectionError(
            f"--laser-offset {text!r}: expected three numbers 'x,y,θ' (metres, metres, degrees)"
        )
    try:
        x, y, th = (float(p) for p in parts)
    except ValueError:
        raise SelectionError(
            f"--laser-offset {text!r}: expected three numbers 'x,y,θ' (metres, metres, degrees)"
        ) from None
    if not all(math.isfinite(v) for v in (x, y, th)):
        raise SelectionError(f"--laser-offset {text!r}: the numbers must be finite")
    return Pose2D(x, y, math.radians(th))


# -- describing a log -------------------------------------------------------------------------
@dataclass
class NoReturnCount:
    """One "no return" band of ``config.scanner`` (metres, inclusive) and its readings in a log.

    ``removed``: the readings it makes invalid (valid by ``range_max`` and inside the band);
    ``in_band``: every reading inside it, including those already invalid at ``range_max``.
    A reading inside several bands counts for the first (:func:`~fuzzypos.scan.no_return_counts`).
    """

    low_m: float
    high_m: float
    removed: int = 0
    in_band: int = 0


@dataclass
class LogInfo:
    """What :func:`describe_log` found in one pass over a log.

    ``beams``: the distinct beam counts; ``angle_min_deg`` / ``angle_max_deg``: the first and
    last beam's angle (degrees, over all scans); ``field_of_view_deg``: ``n·|increment|`` (the
    largest over the scans; each beam covers one increment); ``first_stamp`` /
    ``last_stamp``: of the first and last scan in file order, ``duration_s`` their
    difference (None when the stamps are corrupt, :attr:`StampCheck.corrupt`);
    ``min_stamp`` / ``max_stamp``; ``stamps_backwards``: how often a scan's stamp is below the
    previous one's; ``stamps_repeated``: how often it equals it; ``stamp_problem``: what is
    wrong with the stamps (:meth:`StampCheck.remark`, also warned), else None;
    ``scans_without_ranges``: scans of no beam (not in the beam angles);
    ``scans_with_odometry``: scans whose odometry covers them, ``scans_odometry_not_covered``
    the others (no odometry at them in a log that has some, or odometry standing still while
    the scans move: :class:`~fuzzypos.io.odometry_check.OdometryCoverage`, whose
    ``as_dict()`` is ``odometry_coverage``); ``scans_with_truth``;
    ``range_max``: the distinct finite ``range_max`` of the scans (at most 10 kept);
    ``no_returns``: per "no return" band, the readings it removes (:class:`NoReturnCount`);
    ``no_return_values_found``: the codes found in the readings (:func:`find_no_return_values`;
    empty when ``find_no_return_values`` is off).
    """

    path: str
    kind: str
    scans: int = 0
    beams: list[int] = field(default_factory=list)
    angle_min_deg: float | None = None
    angle_max_deg: float | None = None
    field_of_view_deg: float | None = None
    first_stamp: float | None = None
    last_stamp: float | None = None
    duration_s: float | None = None
    min_stamp: float | None = None
    max_stamp: float | None = None
    stamps_backwards: int = 0
    stamps_repeated: int = 0
    stamp_problem: str | None = None
    scans_without_ranges: int = 0
    scans_with_odometry: int = 0
    scans_odometry_not_covered: int = 0
    odometry_coverage: dict[str, Any] = field(default_factory=dict)
    scans_with_truth: int = 0
    range_max: list[float] = field(default_factory=list)
    no_returns: list[NoReturnCount] = field(default_factory=list)
    no_return_values_found: list[FoundNoReturn] = field(default_factory=list)
    bad_lines: int = 0
    truncated: bool = False
    notes: list[str] = field(default_factory=list)

    @property
    def has_odometry(self) -> bool:
        return self.scans_with_odometry > 0

    @property
    def has_truth(self) -> bool:
        return self.scans_with_truth > 0

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["has_odometry"] = self.has_odometry
        d["has_truth"] = self.has_truth
        return d


def describe_log(
    log: OpenLog,
    progress: Callable[[int], None] | None = None,
    no_return_bands: Sequence[tuple[float, float]] | None = None,
    scanner: ScannerConfig | None = None,
) -> LogInfo:
    """Read ``log`` once (streaming) and summarise it; ``progress(scans_so_far)`` is called
    every 100 scans. ``no_return_bands`` (default ``scanner``'s, itself by default
    ``ScannerConfig()``) are counted in :attr:`LogInfo.no_returns`; the codes ``scanner``'s
    ``find_*`` settings find are :attr:`LogInfo.no_return_values_found`. Corrupt or repeated
    stamps are reported in :attr:`LogInfo.stamp_problem` and warned (:class:`RuntimeWarning`,
    naming the log)."""
    scanner = ScannerConfig() if scanner is None else scanner
    if no_return_bands is not None:
        bands_given = tuple((float(lo), float(hi)) for lo, hi in no_return_bands)
        scanner = replace(scanner, no_return_bands=bands_given)
    bands = scanner.no_return_bands
    tally = RangeTally() if scanner.find_no_return_values else None
    info = LogInfo(path=log.name, kind=log.kind)
    info.no_returns = [NoReturnCount(float(lo), float(hi)) for lo, hi in bands]
    beams: set[int] = set()
    rmax: set[float] = set()
    stamps = StampCheck()
    coverage = OdometryCoverage(expected=log.has_odometry)
    amin = amax = fov = None
    for rec in log.records():
        scan = rec.scan
        info.scans += 1
        beams.add(scan.n_beams)
        a = scan.angles
        if a.shape[0]:
            lo, hi = float(min(a[0], a[-1])), float(max(a[0], a[-1]))
            amin = lo if amin is None else min(amin, lo)
            amax = hi if amax is None else max(amax, hi)
            fov = scan.field_of_view if fov is None else max(fov, scan.field_of_view)
        else:
            info.scans_without_ranges += 1
        t = scan.stamp
        if info.first_stamp is None:
            info.first_stamp = info.min_stamp = info.max_stamp = t
        else:
            info.min_stamp = min(info.min_stamp, t)  # type: ignore[type-var]
            info.max_stamp = max(info.max_stamp, t)  # type: ignore[type-var]
        stamps.add(t)
        info.last_stamp = t
        coverage.add(rec)
        info.scans_with_truth += rec.truth is not None
        if math.isfinite(scan.range_max) and len(rmax) < 10:
            rmax.add(scan.range_max)
        if bands:
            _count_no_returns(info.no_returns, scan, bands)
        if tally is not None:
            tally.add(scan, rec.odometry)
        if progress is not None and info.scans % 100 == 0:
            progress(info.scans)
    info.beams = sorted(beams)
    info.range_max = sorted(rmax)
    if tally is not None:
        info.no_return_values_found = tally.find(scanner)
    if amin is not None:
        info.angle_min_deg = math.degrees(amin)
        info.angle_max_deg = math.degrees(amax)  # type: ignore[arg-type]
        info.field_of_view_deg = math.degrees(fov)  # type: ignore[arg-type]
    _describe_stamps(info, stamps, log.name)
    info.bad_lines = log.bad_lines
    info.truncated = log.truncated
    # the readers' notes may grow while reading
    info.notes = list(dict.fromkeys([*log.notes, *log.reader.notes]))
    _describe_coverage(info, coverage.finish())
    if info.scans_without_ranges:
        info.notes.append(f"{info.scans_without_ranges:,} scans have no ranges at all")
    return info


def _describe_coverage(info: LogInfo, coverage: OdometryCoverage) -> None:
    info.scans_with_odometry = coverage.covered
    info.scans_odometry_not_covered = coverage.uncovered
    info.odometry_coverage = coverage.as_dict()
    note = coverage.note()
    if note is not None:
        info.notes.append(note)


def _describe_stamps(info: LogInfo, stamps: StampCheck, name: str) -> None:
    info.stamps_backwards = stamps.backwards
    info.stamps_repeated = stamps.repeated
    info.stamp_problem = stamps.remark()
    if info.first_stamp is not None and info.last_stamp is not None and not stamps.corrupt:
        info.duration_s = info.last_stamp - info.first_stamp
    if info.stamp_problem is not None:
        warnings.warn(f"{name}: {info.stamp_problem}", RuntimeWarning, stacklevel=3)


def _count_no_returns(
    counts: list[NoReturnCount], scan: LaserScan, bands: Sequence[tuple[float, float]]
) -> None:
    """Add one scan's readings inside each band to ``counts``."""
    removed = no_return_counts(scan.ranges, bands, among=scan.valid)
    in_band = no_return_counts(scan.ranges, bands)
    for c, r, b in zip(counts, removed, in_band):
        c.removed += r
        c.in_band += b


def survey_log(
    log: OpenLog, scanner: ScannerConfig
) -> tuple[list[FoundNoReturn], OdometryCoverage]:
    """One pass over the whole of ``log`` before a run: the "no return" codes
    (:func:`find_no_return_values`, none when ``scanner.find_no_return_values`` is off) and
    which scans the odometry covers (:class:`~fuzzypos.io.odometry_check.OdometryCoverage`). A
    log that cannot be read to its end is judged on the records before the error, silently
    (the run's own pass reports it). A CARMEN log read to its end also gives its scans'
    stamps (:meth:`OpenLog.scan_stamps`, which need not read it again)."""
    tally = RangeTally() if scanner.find_no_return_values else None
    coverage = OdometryCoverage(expected=log.has_odometry)
    stamps: list[float] | None = [] if log.kind == "carmen" else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            for rec in log.records():
                coverage.add(rec)
                if tally is not None:
                    tally.add(rec.scan, rec.odometry)
                if stamps is not None:
                    stamps.append(rec.scan.stamp)
        except (ValueError, OSError):
            stamps = None
    if stamps is not None and log._stamps is None:
        kept = np.array(stamps, dtype=np.float64)
        kept.setflags(write=False)
        log._stamps = kept
    return ([] if tally is None else tally.find(scanner)), coverage.finish()


def find_no_return_values(log: OpenLog, scanner: ScannerConfig) -> list[FoundNoReturn]:
    """Read the whole of ``log`` once and return the values its scanner uses as "no return"
    codes by ``scanner``'s ``find_*`` settings (:mod:`fuzzypos.io.no_returns`), highest first;
    none when ``scanner.find_no_return_values`` is off (then the log is not read). A log that
    cannot be read to its end is judged on the readings before the error, silently: reporting
    it (and the reader's warnings) is the next pass's job, which keeps the scans before it."""
    if not scanner.find_no_return_values:
        return []
    tally = RangeTally()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            for rec in log.records():
                tally.add(rec.scan, rec.odometry)
        except (ValueError, OSError):
            pass
    return tally.find(scanner)
