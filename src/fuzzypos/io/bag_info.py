"""What a bag holds, for ``fuzzypos info``, and the frames an estimate written back is named in.

:func:`describe_bag` reads a ROS1 bag or ROS2 bag directory once, quickly:

- every topic with its message type and message count (from the bag's index);
- for each ``sensor_msgs/LaserScan`` and ``nav_msgs/Odometry`` topic
  (:class:`StreamInfo`): the ``header.frame_id`` values (and for odometry the
  ``child_frame_id`` values) with their counts, the first and last header stamp, the span and
  the rate. Stamps and frames are read from the serialized header (a ``std_msgs/Header``
  opens both messages: the same offsets in ROS1 and CDR) and the odometry's
  ``child_frame_id`` from just after it, without decoding the messages;
- the transforms on ``/tf`` and ``/tf_static`` (``tf2_msgs/TFMessage``, decoded): each
  ``parent → child`` pair with how many transforms carried it (:class:`TfPair`);
- the topics fuzzypos reads by default (the only topic of each kind, or the one given) and the
  frames :func:`output_frames` names an estimate written back into a bag in.

:func:`output_frames` resolves the REP-105 frames of ``fuzzypos run --bag-out``: the robot's
base frame, the odometry frame and the map frame, each as given, else from the input bag (the
odometry's ``child_frame_id`` and ``header.frame_id``; the parent of the base frame, and of
the odometry frame, on ``/tf``), else ``base_link``, ``odom`` and ``map``
(:class:`OutputFrames`, which says where each came from).
"""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Iterable, Mapping
from contextlib import ExitStack
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ..errors import FuzzyposError
from ._common import PathLike, display_name
from .rosbag import (
    _READ_ERRORS,
    LASERSCAN_TYPE,
    ODOMETRY_TYPE,
    TF_STATIC_TOPIC,
    TFMESSAGE_TYPE,
    BagFormatError,
    _Bag,
    _frame,
    _typestore,
    open_bag,
    raw_messages,
)

__all__ = [
    "DEFAULT_FRAMES",
    "TF_TOPICS",
    "BagFrameError",
    "BagInfo",
    "OutputFrames",
    "StreamInfo",
    "TfPair",
    "TopicInfo",
    "describe_bag",
    "output_frames",
    "read_tf_pairs",
]

#: the topics whose transforms :func:`describe_bag` lists
TF_TOPICS = ("/tf", TF_STATIC_TOPIC)
#: REP-105's names where neither the caller nor the bag gives one
DEFAULT_FRAMES = {"base": "base_link", "odom": "odom", "map": "map"}


class BagFrameError(FuzzyposError, ValueError):
    """A frame name that cannot name an estimate's frames (empty, with spaces, or the same as
    another of the three)."""


@dataclass
class TopicInfo:
    """One topic: its message type (None where its connections disagree) and count."""

    topic: str
    msgtype: str | None
    messages: int


@dataclass
class StreamInfo:
    """A scan or odometry topic read from its headers: ``frame_ids`` (and for odometry
    ``child_frame_ids``) → messages; the header stamps' ``first_stamp``, ``last_stamp`` (in
    bag order), ``span_s`` (largest minus smallest), ``rate_hz`` ((messages − 1) / span) and
    ``median_rate_hz`` (one over the median of the positive steps between sorted stamps);
    ``zero_stamps``: headers stamped 0, placed at their record time."""

    topic: str
    msgtype: str
    messages: int = 0
    frame_ids: dict[str, int] = field(default_factory=dict)
    child_frame_ids: dict[str, int] | None = None
    first_stamp: float | None = None
    last_stamp: float | None = None
    span_s: float | None = None
    rate_hz: float | None = None
    median_rate_hz: float | None = None
    zero_stamps: int = 0


@dataclass
class TfPair:
    """``parent → child`` on a transform topic, and how many transforms carried it."""

    topic: str
    parent: str
    child: str
    count: int


@dataclass
class OutputFrames:
    """The frames an estimate is written in: ``base`` (the robot), ``odom`` (the front end's
    continuous frame), ``map`` (loop closure's); ``sources``: where each name came from."""

    base: str = DEFAULT_FRAMES["base"]
    odom: str = DEFAULT_FRAMES["odom"]
    map: str = DEFAULT_FRAMES["map"]
    sources: dict[str, str] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class BagInfo:
    """What :func:`describe_bag` found (module docstring). ``scan_topic`` / ``odom_topic``:
    the topics fuzzypos reads (None where there is none, or several and none given; then
    ``scan_candidates`` / ``odom_candidates`` list them); ``frames``: the frames ``run
    --bag-out`` writes in by default."""

    path: str
    ros_version: int
    topics: list[TopicInfo] = field(default_factory=list)
    streams: list[StreamInfo] = field(default_factory=list)
    tf: list[TfPair] = field(default_factory=list)
    scan_topic: str | None = None
    scan_candidates: list[str] = field(default_factory=list)
    odom_topic: str | None = None
    odom_candidates: list[str] = field(default_factory=list)
    frames: OutputFrames = field(default_factory=OutputFrames)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


# -- reading the headers ---------------------------------------------------------------------
def _string(raw: bytes, at: int, is2: bool, little: bool) -> tuple[str, int]:
    """The string serialized at ``at`` and the offset after it (CDR: its NUL dropped)."""
    if is2:  # CDR aligns a uint32 to 4 bytes from the payload's start (after 4 bytes)
        at = 4 + -(-(at - 4) // 4) * 4
    (n,) = struct.unpack_from("<I" if little else ">I", raw, at)
    end = at + 4 + n
    if end > len(raw):
        raise struct.error("string past the end of the message")
    text = raw[at + 4 : end - 1 if is2 and n else end]
    return text.decode("utf-8"), end


def _header(raw: bytes, is2: bool, odometry: bool) -> tuple[float, str, str | None]:
    """``(stamp, frame_id, child_frame_id or None)`` of a serialized message opening with a
    ``std_msgs/Header`` (ROS1: seq, sec, nsec, frame_id; CDR: 4 bytes of encapsulation, sec,
    nanosec, frame_id); an odometry's ``child_frame_id`` follows the header."""
    little = not is2 or raw[1:2] == b"\x01"
    sec, nsec = struct.unpack_from(("<" if little else ">") + ("iI" if is2 else "II"), raw, 4)
    frame, end = _string(raw, 12, is2, little)
    child = _string(raw, end, is2, little)[0] if odometry else None
    return float(sec) + 1e-9 * float(nsec), frame, child


def _stream(bag: _Bag, name: str, topic: str, msgtype: str, conns: list[Any]) -> StreamInfo:
    """A scan or odometry topic from its messages' headers."""
    odometry = msgtype == ODOMETRY_TYPE
    info = StreamInfo(topic, msgtype, child_frame_ids={} if odometry else None)
    frames: Counter[str] = Counter()
    children: Counter[str] = Counter()
    stamps: list[float] = []
    for k, (_, t_ns, raw) in enumerate(raw_messages(bag, conns, name), start=1):
        try:
            t, frame, child = _header(raw, bag.is2, odometry)
        except (struct.error, UnicodeDecodeError, IndexError) as exc:
            raise BagFormatError(name, k, f"{topic}: unreadable header: {exc}") from exc
        if t == 0.0:
            t, info.zero_stamps = t_ns * 1e-9, info.zero_stamps + 1
        stamps.append(t)
        frames[_frame(frame)] += 1
        if child is not None:
            children[_frame(child)] += 1
    info.messages = len(stamps)
    info.frame_ids = dict(frames.most_common())
    if odometry:
        info.child_frame_ids = dict(children.most_common())
    if stamps:
        t_arr = np.sort(np.asarray(stamps, dtype=np.float64))
        info.first_stamp, info.last_stamp = stamps[0], stamps[-1]
        info.span_s = float(t_arr[-1] - t_arr[0])
        if info.span_s > 0.0:
            info.rate_hz = (len(stamps) - 1) / info.span_s
            steps = np.diff(t_arr)
            info.median_rate_hz = 1.0 / float(np.median(steps[steps > 0.0]))
    return info


def _tf_pairs(bag: _Bag, name: str) -> list[TfPair]:
    """The ``parent → child`` pairs on :data:`TF_TOPICS`, most frequent first per topic."""
    conns = [c for c in bag.reader.connections if c.topic in TF_TOPICS]
    conns = [c for c in conns if c.msgtype == TFMESSAGE_TYPE]
    if not conns:
        return []
    try:
        store = _typestore(conns, bag.is2)
    except _READ_ERRORS as exc:
        raise BagFormatError(name, 0, f"bad message definitions in the bag: {exc!r}") from exc
    counts: Counter[tuple[str, str, str]] = Counter()
    seen: Counter[str] = Counter()
    for conn, _, raw in raw_messages(bag, conns, name):
        seen[conn.topic] += 1
        try:
            if bag.is2:
                msg = store.deserialize_cdr(raw, conn.msgtype)
            else:
                msg = store.deserialize_ros1(raw, conn.msgtype)
            for tr in msg.transforms:
                counts[(conn.topic, _frame(tr.header.frame_id), _frame(tr.child_frame_id))] += 1
        except _READ_ERRORS as exc:
            what = f"{conn.topic}: cannot decode the {conn.msgtype} message: {exc!r}"
            raise BagFormatError(name, seen[conn.topic], what) from exc
    order = {t: k for k, t in enumerate(TF_TOPICS)}
    pairs = [TfPair(t, p, c, n) for (t, p, c), n in counts.items()]
    return sorted(pairs, key=lambda q: (order[q.topic], -q.count, q.parent, q.child))


def read_tf_pairs(path: PathLike) -> list[TfPair]:
    """The transforms' ``parent → child`` pairs on ``/tf`` and ``/tf_static`` of a bag."""
    with ExitStack() as stack:
        return _tf_pairs(open_bag(path, stack, display_name(path)), display_name(path))


def _pick(topics: list[TopicInfo], msgtype: str, given: str | None) -> tuple[str | None, list]:
    """The topic read by default (``given`` where it is one of ``msgtype``), and the
    candidates."""
    candidates = sorted(t.topic for t in topics if t.msgtype == msgtype)
    if given is not None:
        return (given if given in candidates else None), candidates
    return (candidates[0] if len(candidates) == 1 else None), candidates


def describe_bag(
    path: PathLike, *, scan_topic: str | None = None, odom_topic: str | None = None
) -> BagInfo:
    """Read a bag's topics, its scan and odometry headers and its transforms (module
    docstring). ``scan_topic`` / ``odom_topic``: the topics the reader is told to read.
    Raises :class:`FileNotFoundError`, or :class:`~fuzzypos.io.BagFormatError` for what is no
    bag or a bag that cannot be read."""
    name = display_name(path)
    with ExitStack() as stack:
        bag = open_bag(path, stack, name)
        info = BagInfo(path=name, ros_version=2 if bag.is2 else 1)
        for topic, (msgtype, conns) in sorted(bag.topics().items()):
            info.topics.append(TopicInfo(topic, msgtype, sum(c.msgcount for c in conns)))
            if msgtype in (LASERSCAN_TYPE, ODOMETRY_TYPE):
                info.streams.append(_stream(bag, name, topic, msgtype, conns))
        info.tf = _tf_pairs(bag, name)
    info.scan_topic, info.scan_candidates = _pick(info.topics, LASERSCAN_TYPE, scan_topic)
    info.odom_topic, info.odom_candidates = _pick(info.topics, ODOMETRY_TYPE, odom_topic)
    odom = next((s for s in info.streams if s.topic == info.odom_topic), None)
    info.frames = output_frames(
        odom_frame=next(iter(odom.frame_ids), None) if odom is not None else None,
        odom_child=next(iter(odom.child_frame_ids or {}), None) if odom is not None else None,
        tf=info.tf,
    )
    return info


# -- the frames of an estimate written back --------------------------------------------------
def _check_name(name: str, what: str) -> str:
    out = _frame(str(name).strip())
    if not out or any(ch.isspace() for ch in out):
        raise BagFrameError(f"the {what} frame must be a name without spaces, got {name!r}")
    return out


def _parent(tf: Iterable[TfPair], child: str) -> str | None:
    """The parent of ``child`` on ``/tf`` (not ``/tf_static``: a moving frame), the most
    frequent where there are several."""
    for pair in tf:  # most frequent first
        if pair.topic == "/tf" and pair.child == child:
            return pair.parent
    return None


def output_frames(
    given: Mapping[str, str | None] | None = None,
    *,
    odom_frame: str | None = None,
    odom_child: str | None = None,
    tf: Iterable[TfPair] = (),
) -> OutputFrames:
    """The frames to write an estimate in (module docstring). ``given``: ``"base"``,
    ``"odom"``, ``"map"`` → a name (None: not given). From the input: ``odom_frame`` and
    ``odom_child`` (the odometry's ``header.frame_id`` and ``child_frame_id``) and ``tf``
    (:func:`read_tf_pairs`). Raises :class:`BagFrameError` for a bad name or two frames alike."""
    given = dict(given or {})
    tf = list(tf)
    out = OutputFrames()
    for key in ("base", "odom", "map"):
        name, source = given.get(key), "given"
        if name is None and key == "base" and odom_child:
            name, source = odom_child, "the odometry's child_frame_id"
        elif name is None and key == "odom":
            if odom_frame:
                name, source = odom_frame, "the odometry's header.frame_id"
            elif (parent := _parent(tf, out.base)) is not None:
                name, source = parent, f"/tf: the parent of {out.base}"
        elif name is None and key == "map" and (parent := _parent(tf, out.odom)) is not None:
            name, source = parent, f"/tf: the parent of {out.odom}"
        if name is None:
            name, source = DEFAULT_FRAMES[key], "REP-105's default"
        setattr(out, key, _check_name(name, key))
        out.sources[key] = source
    names = (out.base, out.odom, out.map)
    if len(set(names)) < 3:
        raise BagFrameError(
            f"the base, odometry and map frames must differ, got {', '.join(names)} "
            f"({', '.join(f'{k}: {v}' for k, v in out.sources.items())})"
        )
    return out
