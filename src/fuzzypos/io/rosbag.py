"""Reading ROS1 bags and ROS2 bag directories: laser scans with the wheel odometry at them.

:class:`BagReader` yields :class:`~fuzzypos.io.LogRecord` built from a bag's
``sensor_msgs/LaserScan`` and ``nav_msgs/Odometry`` messages, read with the ``rosbags``
package (no ROS installation needed).

What it reads
-------------
- The bag kind is sniffed from the content, not the name: a file starting with
  ``#ROSBAG V2.0`` is a ROS1 bag (:func:`is_ros1_bag`), a directory holding ``metadata.yaml``
  a ROS2 bag (:func:`is_ros2_bag`; sqlite3 or mcap storage). Anything else raises
  :class:`BagFormatError`, and so does a bag ``rosbags`` cannot open or a message it cannot
  read or decode, whatever ``rosbags`` raised on its damaged bytes (chained as
  ``__cause__``), or a message whose fields the bag's own (damaged) definition shaped
  otherwise. A path that does not exist raises :class:`FileNotFoundError`. A ROS1 bag given
  as a pipe (``<(cat run.bag)``) is copied once into a temporary file (rosbags seeks).
  ``rosbags`` skips some damage silently (a corrupt mcap chunk ends early): when fewer scans
  or odometry messages come out than the bag's index lists, the reader warns
  (:class:`RuntimeWarning`) and counts them.
- Message types come from the definitions stored in the bag (every ROS1 bag, recent ROS2
  bags), with the Noetic (ROS1) or Humble (ROS2) definitions where the bag stores none.
- Topics. The scan topic is the bag's only ``sensor_msgs/msg/LaserScan`` topic and the
  odometry topic its only ``nav_msgs/msg/Odometry`` topic. With several candidates of a kind,
  ``scan_topic=`` / ``odom_topic=`` must name one (else :class:`BagTopicError`, listing them).
  A bag without odometry (or whose odometry topic holds no message) is read with
  ``odometry=None`` in every record: :attr:`BagReader.has_odometry` is False and
  :attr:`BagReader.notes` says that the positioner runs without an odometry prior.
- Scans. One record per scan message, in the bag's order of the scan topic (the order it was
  recorded in, even where header stamps go backwards). The scan's ``stamp`` is its header
  stamp in float seconds (the bag's record time where the header stamp is zero, counted in
  :attr:`BagReader.zero_stamps`); ``angle_min``, ``angle_increment``, ``range_min`` and
  ``range_max`` come from the message, the ranges are copied to float64. As everywhere in
  fuzzypos a reading that is NaN, ±inf, 0, below ``range_min`` or at/above ``range_max`` is
  invalid: a driver reporting "no return" as ``range_max`` (the aces bag: 50.0) needs nothing
  more. Beam ``i`` is at ``angle_min + i*angle_increment``, so ``angle_max`` is not used, but
  it is checked: a message whose ``angle_max`` disagrees with ``angle_min +
  (n-1)*angle_increment`` by more than half an increment is counted in
  :attr:`BagReader.angle_max_mismatches`, and one whose ``angle_max`` lies on the other side
  of ``angle_min`` than the increment goes (``angle_max < angle_min`` with a positive
  increment, or ``>`` with a negative one) raises :class:`BagFormatError`: its beams would
  sweep away from where the message says the scan ends. A scan that turns clockwise (an
  upside-down mount) has ``angle_max < angle_min`` *and* a negative increment, which is
  consistent (sensor_msgs/LaserScan) and read as it is.
- Odometry. Two passes: the constructor reads the odometry topic (and ``/tf_static``) into
  arrays, which are small (4 doubles a message), sorted by header stamp, the first
  scan (for its frame) and every scan's header stamp (:meth:`BagReader.scan_stamps`, read
  from the serialized header without decoding the scan); :meth:`BagReader.records`
  then streams the scans, one message in memory at a time. Each scan gets the odometry pose
  (``pose.pose``: x, y and the yaw of the quaternion) interpolated at its header stamp
  (:func:`interpolate_poses`): linear in x and y, along the shorter arc in θ, between the two
  odometry messages around it; within two of the odometry's usual (median) periods before
  the first or after the last odometry stamp it gets the nearest (first or last) pose,
  counted in :attr:`BagReader.extrapolated`; further outside the odometry's span it gets
  none (``odometry=None``: the positioner runs without an odometry prior there, not with a
  pose frozen at the span's end), counted in :attr:`BagReader.outside_odometry` and said in
  :attr:`BagReader.notes`, as are the messages whose ``angle_max`` disagrees (below). An odometry
  message with a zero header stamp is placed at its record time like a scan.
- Laser mounting (each scan's ``sensor_pose``): ``laser_offset=`` when given; else the
  transform from the robot's base frame to the scan's ``header.frame_id`` found in the
  ``/tf_static`` messages (``tf2_msgs/msg/TFMessage``), chaining static transforms in either
  direction as needed and keeping x, y and the yaw of each (a mount tilted by more than 1°,
  e.g. upside down, is noted in :attr:`BagReader.notes`: only its yaw is used); else the
  identity, with a note. The base frame is ``base_frame=`` when given, else the odometry's
  ``child_frame_id``, else ``base_link``. Frame names are compared without a leading ``/``.

Errors name the bag and the topic; :attr:`BagFormatError.line` is the 1-based index of the
offending message within its topic (0 when the problem is not one message).
"""

from __future__ import annotations

import math
import struct
import warnings
from collections import deque
from collections.abc import Iterator, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from rosbags.interfaces import Connection, MessageDefinitionFormat
from rosbags.rosbag1 import Reader as Reader1
from rosbags.rosbag1 import ReaderError as ReaderError1
from rosbags.rosbag2 import Reader as Reader2
from rosbags.rosbag2 import ReaderError as ReaderError2
from rosbags.serde import SerdeError
from rosbags.typesys import (
    Stores,
    TypesysError,
    get_types_from_idl,
    get_types_from_msg,
    get_typestore,
)

from ..errors import Argument, Words
from ..geometry import Pose2D, _wrap_scalar, compose, inverse, wrap_angle
from ..scan import LaserScan, ScanError
from ._common import FloatArray, LogFormatError, LogRecord, PathLike, display_name, spool_if_stream

__all__ = [
    "LASERSCAN_TYPE",
    "ODOMETRY_TYPE",
    "ROS1_MAGIC",
    "TFMESSAGE_TYPE",
    "BagFormatError",
    "BagReader",
    "BagTopicError",
    "interpolate_poses",
    "is_ros1_bag",
    "is_ros2_bag",
    "open_bag",
    "read_bag",
]

#: the first bytes of a ROS1 bag (format 2.0, the only one ``rosbags`` reads)
ROS1_MAGIC = b"#ROSBAG V2.0"
LASERSCAN_TYPE = "sensor_msgs/msg/LaserScan"
ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
TFMESSAGE_TYPE = "tf2_msgs/msg/TFMessage"
#: the topic static transforms are read from
TF_STATIC_TOPIC = "/tf_static"
#: the base frame when neither ``base_frame`` nor the odometry's ``child_frame_id`` gives one
DEFAULT_BASE_FRAME = "base_link"
#: a mount tilted more than this (radians) from level gets a note (only its yaw is used)
_TILT_NOTE = math.radians(1.0)

#: what ``rosbags`` (and the storages and decoders under it) raise on a bag it cannot read:
#: its own errors, and on damaged bytes almost anything (a failed assertion, sqlite's
#: CorruptError, a size field too large to allocate …). Only the calls into ``rosbags`` are
#: guarded by this; the chained ``__cause__`` keeps the original.
_READ_ERRORS: tuple[type[BaseException], ...] = (
    ReaderError1,
    ReaderError2,
    SerdeError,
    TypesysError,
    Exception,
)
#: what reading a field of a decoded message may raise when the bag's own message definition
#: shapes it otherwise (a damaged definition renames or retypes a field)
_FIELD_ERRORS: tuple[type[BaseException], ...] = (
    AttributeError,
    TypeError,
    ValueError,
    OverflowError,
    IndexError,
)


class BagFormatError(LogFormatError):
    """A bag that cannot be read as asked: ``"<bag>:<message>: <topic>: <what>"`` (the
    message index, 1-based within its topic, is left out when the problem is not one
    message), e.g. ``run.bag:17: /scan: range_max must be > range_min …``."""


class BagTopicError(BagFormatError):
    """No topic, or more than one candidate topic, of a kind the reader needs; the message
    lists the candidates and the argument (``scan_topic=`` / ``odom_topic=``) that picks one."""


# -- sniffing ------------------------------------------------------------------------------
def is_ros1_bag(path: PathLike) -> bool:
    """Whether ``path`` is a file starting with ``#ROSBAG V2.0`` (whatever its name)."""
    p = Path(path)
    if not p.is_file():
        return False
    try:
        with open(p, "rb") as f:
            return f.read(len(ROS1_MAGIC)) == ROS1_MAGIC
    except OSError:
        return False


def is_ros2_bag(path: PathLike) -> bool:
    """Whether ``path`` is a directory holding a ``metadata.yaml`` (a ROS2 bag)."""
    p = Path(path)
    return p.is_dir() and (p / "metadata.yaml").is_file()


# -- SE(2) interpolation ---------------------------------------------------------------------
def interpolate_poses(stamps: ArrayLike, poses: ArrayLike, query: ArrayLike) -> FloatArray:
    """Poses ``(..., 3)`` at the times ``query`` (shape ``(...)``), from poses ``(n, 3)``
    sampled at the non-decreasing ``stamps`` ``(n,)``.

    Between two samples ``a`` (at ``t_a``) and ``b`` (at ``t_b > t_a``) with
    ``f = (t - t_a) / (t_b - t_a)``: ``x, y = (1-f)·a + f·b`` and
    ``θ = θ_a + f·wrap(θ_b - θ_a)`` (the shorter arc), wrapped to ``[-π, π)``. A query at or
    before the first stamp gets the first pose, at or after the last one the last pose; at a
    repeated stamp, the last sample with that stamp. Being affine in x, y and a rotation
    offset in θ, it commutes with moving the whole trajectory by a rigid motion.
    """
    t = np.asarray(stamps, dtype=np.float64)
    p = np.asarray(poses, dtype=np.float64)
    q = np.asarray(query, dtype=np.float64)
    if t.ndim != 1 or t.shape[0] == 0:
        raise ValueError(f"stamps must be a non-empty 1-D array, got shape {t.shape}")
    if p.shape != (t.shape[0], 3):
        raise ValueError(f"poses must have shape ({t.shape[0]}, 3), got {p.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
        raise ValueError("stamps, poses and query must be finite")
    if t.shape[0] > 1 and np.any(np.diff(t) < 0.0):
        raise ValueError("stamps must be non-decreasing")
    return _interpolate(t, p, q)


def _interpolate(t: FloatArray, p: FloatArray, q: FloatArray) -> FloatArray:
    """:func:`interpolate_poses` without the checks."""
    n = t.shape[0]
    i = np.searchsorted(t, q, side="right")
    lo = np.clip(i - 1, 0, n - 1)
    hi = np.clip(i, 0, n - 1)
    dt = t[hi] - t[lo]
    f = np.clip((q - t[lo]) / np.where(dt > 0.0, dt, 1.0), 0.0, 1.0)
    f = np.where(dt > 0.0, f, 0.0)
    a, b = p[lo], p[hi]
    out = np.empty((*q.shape, 3), dtype=np.float64)
    out[..., 0] = a[..., 0] + f * (b[..., 0] - a[..., 0])
    out[..., 1] = a[..., 1] + f * (b[..., 1] - a[..., 1])
    out[..., 2] = wrap_angle(a[..., 2] + f * wrap_angle(b[..., 2] - a[..., 2]))
    return out


def _interpolate_one(t: FloatArray, p: FloatArray, q: float) -> Pose2D:
    """:func:`interpolate_poses` at one time, as a :class:`Pose2D` (the per-scan path)."""
    n = t.shape[0]
    i = int(np.searchsorted(t, q, side="right"))
    if i == 0:
        return Pose2D._trusted(float(p[0, 0]), float(p[0, 1]), float(p[0, 2]))
    if i == n:
        return Pose2D._trusted(float(p[-1, 0]), float(p[-1, 1]), float(p[-1, 2]))
    ta, tb = float(t[i - 1]), float(t[i])  # ta <= q < tb
    xa, ya, tha = (float(v) for v in p[i - 1])
    xb, yb, thb = (float(v) for v in p[i])
    f = min(1.0, max(0.0, (q - ta) / (tb - ta)))
    th = _wrap_scalar(tha + f * _wrap_scalar(thb - tha))
    return Pose2D._trusted(xa + f * (xb - xa), ya + f * (yb - ya), th)


def _yaw(q: Any) -> float:
    """The yaw (rotation about z) of a ``geometry_msgs/Quaternion``."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _tilt(q: Any) -> float:
    """The angle between a quaternion's z axis and the vertical (0 for a level mount)."""
    n2 = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z
    zz = 1.0 - 2.0 * (q.x * q.x + q.y * q.y) / n2 if n2 > 0.0 else 1.0
    return math.acos(max(-1.0, min(1.0, zz)))


def _stamp(header: Any) -> float:
    return float(header.stamp.sec) + 1e-9 * float(header.stamp.nanosec)


def _frame(name: str) -> str:
    return name.lstrip("/")


def _header_stamp(raw: bytes, is2: bool) -> float:
    """The header stamp (float seconds, as :func:`_stamp` gives it) of a serialized message
    that starts with a ``std_msgs/Header``, without decoding it: ROS1 ``uint32 seq``, then
    ``uint32 sec, nsec``; CDR (ROS2): after the 4-byte encapsulation (whose second byte is 1
    for little endian), ``int32 sec, uint32 nanosec``. NaN where ``raw`` is too short."""
    try:
        if is2:
            fmt = "<iI" if raw[1:2] == b"\x01" else ">iI"
            sec, nsec = struct.unpack_from(fmt, raw, 4)
        else:
            sec, nsec = struct.unpack_from("<II", raw, 4)
    except struct.error:
        return math.nan
    return float(sec) + 1e-9 * float(nsec)


# -- the open bag ------------------------------------------------------------------------------
@dataclass
class _Bag:
    """An open bag: its reader and whether it is ROS2."""

    reader: Reader1 | Reader2
    is2: bool

    def topics(self) -> dict[str, tuple[str | None, list[Connection]]]:
        """topic -> (message type or None when the topic's connections disagree, connections)."""
        out: dict[str, tuple[str | None, list[Connection]]] = {}
        for c in self.reader.connections:
            typ, conns = out.get(c.topic, (c.msgtype, []))
            out[c.topic] = (typ if typ == c.msgtype else None, [*conns, c])
        return out


def raw_messages(
    bag: _Bag, connections: Sequence[Connection], name: PathLike
) -> Iterator[tuple[Connection, int, bytes]]:
    """``(connection, record time ns, serialized message)`` for the messages of
    ``connections`` in bag order (none for no connections); a read error becomes
    :class:`BagFormatError` naming the bag (``name``) and the topics."""
    if not connections:  # an empty filter would read every message
        return
    gen = bag.reader.messages(connections=connections)
    while True:
        try:
            conn, t_ns, raw = next(gen)
        except StopIteration:
            return
        except _READ_ERRORS as exc:
            topics = ", ".join(sorted({c.topic for c in connections}))
            raise BagFormatError(name, 0, f"{topics}: cannot read the bag: {exc!r}") from exc
        yield conn, t_ns, raw


def open_bag(path: PathLike, stack: ExitStack, name: str | None = None) -> _Bag:
    """Open the bag at ``path`` (closed with ``stack``), sniffing its kind from the content:
    :class:`FileNotFoundError` where nothing is there (``name``: how to call it), else
    :class:`BagFormatError` for what is no bag or a bag ``rosbags`` cannot open."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{name or p}: no such file or directory")
    if is_ros1_bag(p):
        is2 = False
    elif is_ros2_bag(p):
        is2 = True
    else:
        what = "a directory without metadata.yaml" if p.is_dir() else "a file"
        raise BagFormatError(
            path,
            0,
            f"not a bag: {what} that is neither a ROS1 bag (starting with "
            f"{ROS1_MAGIC.decode()!r}) nor a ROS2 bag directory (holding metadata.yaml)",
        )
    try:
        reader: Reader1 | Reader2 = Reader2(p) if is2 else Reader1(p)
        reader.open()
    except _READ_ERRORS as exc:
        hint = (
            " (a truncated or unindexed ROS1 bag: `rosbag reindex` may repair it)"
            if not is2 and "index" in str(exc).lower()
            else ""
        )
        raise BagFormatError(
            path, 0, f"cannot open the {'ROS2' if is2 else 'ROS1'} bag: {exc}{hint}"
        ) from exc
    stack.callback(reader.close)
    return _Bag(reader, is2)


def _typestore(connections: Sequence[Connection], is2: bool) -> Any:
    """A typestore for the messages of ``connections``: the definitions the bag stores for
    them (as AnyReader reads them), else the Noetic/Humble ones."""
    typs: dict[str, Any] = {}
    if any(c.msgdef.format == MessageDefinitionFormat.NONE for c in connections):
        typs.update(get_typestore(Stores.ROS2_HUMBLE if is2 else Stores.ROS1_NOETIC).fielddefs)
    for c in connections:
        fmt = c.msgdef.format
        if fmt == MessageDefinitionFormat.MSG:
            typs.update(get_types_from_msg(c.msgdef.data, c.msgtype))
        elif fmt == MessageDefinitionFormat.IDL:
            sep = "=" * 80 + "\n"
            if c.msgdef.data.startswith(f"{sep}IDL: "):
                for part in c.msgdef.data.split(sep)[1:]:
                    typs.update(get_types_from_idl(part.split("\n", 1)[1]))
            else:
                typs.update(get_types_from_idl(c.msgdef.data))
    store = get_typestore(Stores.EMPTY)
    store.register(typs)
    return store


# -- the reader ----------------------------------------------------------------------------------
class BagReader:
    """Stream the laser scans of a ROS1 bag or ROS2 bag directory as :class:`LogRecord`.

    ``BagReader(path, scan_topic=None, odom_topic=None, laser_offset=None,
    base_frame=None).records()`` (or iterating the reader) yields one record per scan message
    (module docstring). The constructor opens the bag, picks the topics and reads the
    odometry and ``/tf_static``; it raises :class:`BagTopicError` when a topic is ambiguous
    or missing, :class:`BagFormatError` when the bag cannot be read.

    Known after construction:

    - ``ros_version`` (1 or 2), ``topics`` (topic -> message type), ``scan_topic``,
      ``scan_count`` (messages on it, from the bag's index), :meth:`scan_stamps`;
    - ``odom_topic`` (None without odometry), ``has_odometry``, ``odometry_stamps`` ``(m,)``
      and ``odometry_poses`` ``(m, 3)`` (sorted by stamp; read-only);
    - ``base_frame``, ``odom_frame`` and ``odom_child_frame`` (the odometry's
      ``header.frame_id`` and ``child_frame_id``, None without them),
      ``scan_frame`` (of the first scan), ``sensor_pose`` (the mounting pose
      of ``scan_frame``) and ``sensor_pose_source`` (``"laser_offset"``, ``"tf_static"`` or
      ``"identity"``);
    - ``notes``: what the reader assumed or found odd, as sentences.

    Counted by :meth:`records` (reset by each call, which reads the bag again): ``messages``
    (scans read), ``missing`` (scans the bag's index lists but that could not be read: a
    damaged bag, with a warning), ``extrapolated`` (scans just outside the odometry's time
    span, within two of its usual periods, given its nearest pose), ``outside_odometry``
    (scans further outside it, given no odometry), ``zero_stamps`` (scans with a zero header
    stamp), ``angle_max_mismatches``; the last two of these, where not zero, are also said
    in ``notes`` at the end of the pass.
    """

    def __init__(
        self,
        path: PathLike,
        *,
        scan_topic: str | None = None,
        odom_topic: str | None = None,
        laser_offset: Pose2D | None = None,
        base_frame: str | None = None,
    ) -> None:
        self.path = spool_if_stream(path)  # a ROS1 bag through a pipe: rosbags needs to seek
        self.name = display_name(path)
        if laser_offset is not None and not isinstance(laser_offset, Pose2D):
            raise TypeError(f"laser_offset must be a Pose2D, got {type(laser_offset).__name__}")
        self.laser_offset = laser_offset
        self.notes: list[str] = []
        self._frame_poses: dict[str, Pose2D] = {}
        self._static: dict[str, tuple[str, Pose2D, float]] = {}  # child -> (parent, pose, tilt)
        self._reset_counters()

        with ExitStack() as stack:
            bag = self._open(stack)
            self.ros_version = 2 if bag.is2 else 1
            topics = bag.topics()
            self.topics: dict[str, str | None] = {t: v[0] for t, v in topics.items()}
            scan = self._pick(topics, LASERSCAN_TYPE, scan_topic, "scan_topic")
            assert scan is not None
            self.scan_topic: str = scan
            scan_conns = topics[scan][1]
            self.scan_count = sum(c.msgcount for c in scan_conns)
            self.odom_topic = self._pick(
                topics, ODOMETRY_TYPE, odom_topic, "odom_topic", required=False
            )
            odom_conns = topics[self.odom_topic][1] if self.odom_topic is not None else []
            tf_conns = [
                c for c in topics.get(TF_STATIC_TOPIC, (None, []))[1] if c.msgtype == TFMESSAGE_TYPE
            ]
            try:
                self._store = _typestore([*scan_conns, *odom_conns, *tf_conns], bag.is2)
            except _READ_ERRORS as exc:
                raise self._error(f"bad message definitions in the bag: {exc!r}") from exc
            child_frame = self._first_pass(bag, odom_conns, tf_conns, scan_conns)

        self.has_odometry = self.odometry_stamps.shape[0] > 0
        if not self.has_odometry:
            why = (
                f"no {ODOMETRY_TYPE} topic"
                if self.odom_topic is None
                else f"no message on the odometry topic {self.odom_topic}"
            )
            self.notes.append(
                f"{why}: every record has odometry=None and the positioner runs without an "
                "odometry prior"
            )
        self.odom_child_frame = None if child_frame is None else _frame(child_frame)
        self.base_frame = _frame(base_frame or child_frame or DEFAULT_BASE_FRAME)
        self.sensor_pose_source = "identity" if laser_offset is None else "laser_offset"
        if self.scan_frame is not None:
            self.sensor_pose = self._mounting(self.scan_frame)
        else:
            self.sensor_pose = laser_offset if laser_offset is not None else Pose2D()

    def _reset_counters(self) -> None:
        self.messages = 0
        self.missing = 0
        self.extrapolated = 0
        self.outside_odometry = 0
        self.zero_stamps = 0
        self.angle_max_mismatches = 0

    def __iter__(self) -> Iterator[LogRecord]:
        return self.records()

    # -- opening -----------------------------------------------------------------------------
    def _error(self, reason: str, index: int = 0, topic: str | None = None) -> BagFormatError:
        return BagFormatError(self.path, index, f"{topic}: {reason}" if topic else reason)

    def _open(self, stack: ExitStack) -> _Bag:
        """Open the bag (closed with ``stack``), sniffing its kind from the content."""
        return open_bag(self.path, stack, self.name)

    def _pick(
        self,
        topics: dict[str, tuple[str | None, list[Connection]]],
        msgtype: str,
        given: str | None,
        arg: str,
        *,
        required: bool = True,
    ) -> str | None:
        """The topic of ``msgtype`` to read: ``given`` (checked) or the only candidate."""
        candidates = sorted(t for t, (typ, _) in topics.items() if typ == msgtype)
        listing = ", ".join(candidates) if candidates else "none"
        if given is not None:
            if given not in topics:
                raise BagTopicError(
                    self.path,
                    0,
                    Words(
                        Argument.given(arg),
                        f"{given!r}: no such topic ({msgtype} topics: {listing})",
                    ),
                )
            if topics[given][0] != msgtype:
                raise BagTopicError(
                    self.path,
                    0,
                    Words(
                        Argument.given(arg),
                        f"{given!r} is a {topics[given][0]} topic, not {msgtype} "
                        f"(candidates: {listing})",
                    ),
                )
            return given
        if len(candidates) == 1:
            return candidates[0]
        if not candidates:
            if required:
                raise BagTopicError(self.path, 0, f"no {msgtype} topic in the bag")
            return None
        raise BagTopicError(
            self.path,
            0,
            Words(
                f"{len(candidates)} {msgtype} topics ({listing}): pass ",
                Argument(arg, "="),
                " to pick one",
            ),
        )

    def _raw_messages(
        self, bag: _Bag, connections: Sequence[Connection]
    ) -> Iterator[tuple[Connection, int, bytes, int]]:
        """``(connection, record time ns, serialized message, 1-based index in its topic)`` for
        the messages of ``connections`` in bag order; read errors become
        :class:`BagFormatError`."""
        counts: dict[str, int] = {}
        for conn, t_ns, raw in raw_messages(bag, connections, self.path):
            k = counts[conn.topic] = counts.get(conn.topic, 0) + 1
            yield conn, t_ns, raw, k

    def _decode(self, bag: _Bag, conn: Connection, raw: bytes, k: int) -> Any:
        """One message decoded; decoding errors become :class:`BagFormatError`."""
        try:
            if bag.is2:
                return self._store.deserialize_cdr(raw, conn.msgtype)
            return self._store.deserialize_ros1(raw, conn.msgtype)
        except _READ_ERRORS as exc:
            raise self._error(
                f"cannot decode the {conn.msgtype} message: {exc!r}", k, conn.topic
            ) from exc

    def _messages(
        self, bag: _Bag, connections: Sequence[Connection]
    ) -> Iterator[tuple[Connection, int, Any, int]]:
        """:meth:`_raw_messages`, decoded."""
        for conn, t_ns, raw, k in self._raw_messages(bag, connections):
            yield conn, t_ns, self._decode(bag, conn, raw, k), k

    @contextmanager
    def _fields(self, conn: Connection, k: int) -> Iterator[None]:
        """Reading a decoded message's fields: a message the bag's own (damaged) definition
        shaped otherwise raises :class:`BagFormatError`."""
        try:
            yield
        except LogFormatError:
            raise
        except _FIELD_ERRORS as exc:
            raise self._error(
                f"malformed {conn.msgtype} message (is the bag's message definition damaged?): "
                f"{exc!r}",
                k,
                conn.topic,
            ) from exc

    # -- first pass: odometry, static transforms, the scans' stamps ----------------------------
    def _first_pass(
        self,
        bag: _Bag,
        odom_conns: list[Connection],
        tf_conns: list[Connection],
        scan_conns: list[Connection],
    ) -> str | None:
        """Read the odometry into arrays, ``/tf_static`` into ``_static``, the scans' header
        stamps (without decoding the scans) and the first scan's frame; return the odometry's
        ``child_frame_id`` (of its first message; None without one)."""
        stamps: list[float] = []
        poses: list[tuple[float, float, float]] = []
        scan_stamps: list[float] = []
        child_frame: str | None = None
        zero = 0
        self.scan_frame: str | None = None
        self.odom_frame: str | None = None  # the odometry's header.frame_id (its first message)
        scan_topics = {c.topic for c in scan_conns}
        for conn, t_ns, raw, k in self._raw_messages(bag, [*odom_conns, *tf_conns, *scan_conns]):
            if conn.topic in scan_topics:
                t = _header_stamp(raw, bag.is2)
                if math.isfinite(t):
                    scan_stamps.append(t if t != 0.0 else t_ns * 1e-9)
                if k == 1:
                    with self._fields(conn, k):
                        self.scan_frame = _frame(self._decode(bag, conn, raw, k).header.frame_id)
                continue
            msg = self._decode(bag, conn, raw, k)
            with self._fields(conn, k):
                if conn.msgtype == TFMESSAGE_TYPE:
                    for tr in msg.transforms:
                        self._add_static(tr, conn.topic, k)
                    continue
                t = _stamp(msg.header)
                if t == 0.0:
                    t = t_ns * 1e-9
                    zero += 1
                pos, q = msg.pose.pose.position, msg.pose.pose.orientation
                pose = (float(pos.x), float(pos.y), _yaw(q))
                if not all(math.isfinite(v) for v in (t, *pose)):
                    raise self._error(f"odometry not finite: stamp {t}, pose {pose}", k, conn.topic)
                if child_frame is None and msg.child_frame_id:
                    child_frame = str(msg.child_frame_id)
                if self.odom_frame is None and msg.header.frame_id:
                    self.odom_frame = _frame(str(msg.header.frame_id))
            stamps.append(t)
            poses.append(pose)
        self._scan_stamps = np.asarray(scan_stamps, dtype=np.float64)
        self._scan_stamps.setflags(write=False)
        self._keep_odometry(stamps, poses, zero, sum(c.msgcount for c in odom_conns))
        return child_frame

    def _keep_odometry(
        self, stamps: list[float], poses: list[tuple[float, float, float]], zero: int, listed: int
    ) -> None:
        """The odometry read, sorted by stamp, with notes on what was odd about it."""
        if len(stamps) != listed:
            note = (
                f"{self.name}: {self.odom_topic}: read {len(stamps)} odometry messages where "
                f"the bag's index lists {listed}: the bag may be damaged"
            )
            self.notes.append(note)
            warnings.warn(note, RuntimeWarning, stacklevel=4)
        t_arr = np.asarray(stamps, dtype=np.float64)
        p_arr = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        backwards = int(np.count_nonzero(np.diff(t_arr) < 0.0)) if t_arr.size > 1 else 0
        if backwards:
            self.notes.append(
                f"odometry header stamps go backwards {backwards} times in bag order: "
                "sorted by stamp for the interpolation"
            )
        if zero:
            self.notes.append(
                f"{zero} odometry messages have a zero header stamp: placed at their record time"
            )
        order = np.argsort(t_arr, kind="stable")
        self.odometry_stamps: FloatArray = t_arr[order]
        self.odometry_poses: FloatArray = p_arr[order]
        self.odometry_stamps.setflags(write=False)
        self.odometry_poses.setflags(write=False)

    def _add_static(self, tr: Any, topic: str, k: int) -> None:
        parent, child = _frame(tr.header.frame_id), _frame(tr.child_frame_id)
        t, q = tr.transform.translation, tr.transform.rotation
        vals = (float(t.x), float(t.y), _yaw(q))
        if not all(math.isfinite(v) for v in vals):
            raise self._error(f"static transform {parent} -> {child} not finite: {vals}", k, topic)
        self._static[child] = (parent, Pose2D(*vals), _tilt(q))

    def scan_stamps(self) -> FloatArray:
        """Every scan's stamp in bag order, as :meth:`records` gives them (the header stamp, or
        the record time where it is zero), read by the constructor from the messages' headers
        without decoding the scans: a quick look at the stamps. Read-only."""
        return self._scan_stamps

    # -- laser mounting ------------------------------------------------------------------------
    def _mounting(self, frame: str) -> Pose2D:
        """The scans' ``sensor_pose`` for scans in ``frame`` (cached; module docstring)."""
        pose = self._frame_poses.get(frame)
        if pose is not None:
            return pose
        if self.laser_offset is not None:
            pose = self.laser_offset
        elif frame == self.base_frame:
            pose = Pose2D()
        else:
            found = self._static_chain(self.base_frame, frame)
            if found is None:
                where = (
                    f"no static transform chain {self.base_frame} -> {frame} in {TF_STATIC_TOPIC}"
                    if self._static
                    else f"no {TF_STATIC_TOPIC} in the bag"
                )
                self.notes.append(
                    f"{where}: the laser {frame!r} is taken to sit at the robot's origin"
                )
                pose = Pose2D()
            else:
                pose, tilt = found
                self.sensor_pose_source = "tf_static"
                if tilt > _TILT_NOTE:
                    self.notes.append(
                        f"the chain {self.base_frame} -> {frame} is tilted by "
                        f"{math.degrees(tilt):.1f}° from level: only x, y and yaw are used"
                    )
        self._frame_poses[frame] = pose
        return pose

    def _static_chain(self, start: str, goal: str) -> tuple[Pose2D, float] | None:
        """``(pose of goal in start, summed tilt)`` through the static transforms, walked in
        either direction (breadth first); None when they do not connect the two frames."""
        edges: dict[str, list[tuple[str, FloatArray, float]]] = {}
        for child, (parent, pose, tilt) in self._static.items():
            arr = pose.as_array()
            edges.setdefault(parent, []).append((child, arr, tilt))
            edges.setdefault(child, []).append((parent, inverse(arr), tilt))
        seen = {start: (np.zeros(3), 0.0)}
        queue = deque([start])
        while queue:
            frame = queue.popleft()
            here, tilt = seen[frame]
            if frame == goal:
                return Pose2D.from_array(here), tilt
            for nxt, step, t in edges.get(frame, []):
                if nxt not in seen:
                    seen[nxt] = (compose(here, step), tilt + t)
                    queue.append(nxt)
        return None

    # -- second pass: the scans -----------------------------------------------------------------
    def records(self) -> Iterator[LogRecord]:
        """Yield one :class:`LogRecord` per scan message, in the bag's order of the scan topic
        (the bag is opened again and read as a stream)."""
        self._reset_counters()
        t_odom, p_odom = self.odometry_stamps, self.odometry_poses
        reach = self._odometry_reach()
        with ExitStack() as stack:
            bag = self._open(stack)
            scan_conns = [c for c in bag.reader.connections if c.topic == self.scan_topic]
            for conn, t_ns, msg, k in self._messages(bag, scan_conns):
                self.messages += 1
                with self._fields(conn, k):
                    scan = self._scan(msg, t_ns, k)
                odometry: Pose2D | None = None
                if self.has_odometry:
                    t = scan.stamp
                    if t_odom[0] - reach <= t <= t_odom[-1] + reach:
                        self.extrapolated += not t_odom[0] <= t <= t_odom[-1]
                        odometry = _interpolate_one(t_odom, p_odom, t)
                    else:  # no odometry covers it: none, rather than a pose frozen at the end
                        self.outside_odometry += 1
                yield LogRecord(scan, odometry, None)
        self._pass_notes()
        self.missing = self.scan_count - self.messages
        if self.missing:
            warnings.warn(
                f"{self.name}: {self.scan_topic}: read {self.messages} scans where the bag's "
                f"index lists {self.scan_count}: the bag may be damaged",
                RuntimeWarning,
                stacklevel=2,
            )

    def _odometry_reach(self) -> float:
        """How far (s) beyond the odometry's first and last stamps a scan still takes the
        nearest pose: two of the odometry's usual (median) periods, in which a robot moves
        little; further out the scan gets no odometry (:attr:`outside_odometry`)."""
        t = self.odometry_stamps
        if t.shape[0] < 2:
            return 0.0
        steps = np.diff(t)
        steps = steps[steps > 0.0]
        return 2.0 * float(np.median(steps)) if steps.size else 0.0

    def _pass_notes(self) -> None:
        """The notes on what this pass over the scans counted (once each)."""
        notes = []
        if self.outside_odometry:
            t = self.odometry_stamps
            notes.append(
                f"{self.outside_odometry:,} of {self.messages:,} scans lie outside the "
                f"odometry's time span (stamps {t[0]!r} to {t[-1]!r}, {self.odom_topic}): they "
                "get no odometry (is the odometry's clock the scans'?)"
            )
        if self.angle_max_mismatches:
            notes.append(
                f"{self.angle_max_mismatches:,} of {self.messages:,} scan messages have an "
                "angle_max that disagrees with angle_min + (n-1)·angle_increment by more than "
                "half an increment: their beams are placed by angle_min and angle_increment"
            )
        for note in notes:
            if note not in self.notes:
                self.notes.append(note)

    def _scan(self, msg: Any, t_ns: int, k: int) -> LaserScan:
        stamp = _stamp(msg.header)
        if stamp == 0.0:
            stamp = t_ns * 1e-9
            self.zero_stamps += 1
        ranges = np.asarray(msg.ranges, dtype=np.float64)
        n = ranges.shape[0]
        a0, inc, a1 = float(msg.angle_min), float(msg.angle_increment), float(msg.angle_max)
        if n > 1 and abs(a0 + (n - 1) * inc - a1) > 0.5 * abs(inc):
            self.angle_max_mismatches += 1
            if abs(a1 - a0) > 0.5 * abs(inc) and (a1 > a0) != (inc > 0.0):
                raise self._error(
                    f"angle_max {a1:g} lies {'below' if a1 < a0 else 'above'} angle_min {a0:g} "
                    f"but angle_increment {inc:g} is {'positive' if inc > 0 else 'negative'}: "
                    f"the {n} beams would run from {math.degrees(a0):.1f}° to "
                    f"{math.degrees(a0 + (n - 1) * inc):.1f}°, away from angle_max (a scan "
                    "that turns clockwise has angle_max < angle_min and a negative increment)",
                    k,
                    self.scan_topic,
                )
        try:
            return LaserScan(
                ranges,
                a0,
                inc,
                range_min=float(msg.range_min),
                range_max=float(msg.range_max),
                stamp=stamp,
                sensor_pose=self._mounting(_frame(msg.header.frame_id)),
            )
        except ScanError as exc:
            raise self._error(str(exc), k, self.scan_topic) from exc


def read_bag(
    path: PathLike,
    *,
    scan_topic: str | None = None,
    odom_topic: str | None = None,
    laser_offset: Pose2D | None = None,
    base_frame: str | None = None,
) -> Iterator[LogRecord]:
    """Stream the :class:`LogRecord` of a ROS1 bag or ROS2 bag directory (see
    :class:`BagReader`, whose constructor runs here: topic and format errors raise at once)."""
    return BagReader(
        path,
        scan_topic=scan_topic,
        odom_topic=odom_topic,
        laser_offset=laser_offset,
        base_frame=base_frame,
    ).records()
