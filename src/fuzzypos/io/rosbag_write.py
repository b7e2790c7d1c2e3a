"""Writing an estimated trajectory as ``nav_msgs/msg/Odometry`` and ``/tf`` into a bag.

:class:`OdometryBagWriter` streams one pose at a time into a ROS1 bag (a file) or a ROS2 bag
(a directory, sqlite3 or mcap storage) through the ``rosbags`` package's writers: memory
stays flat however long the trajectory.

The frames follow REP-105 and are named by the caller: ``frame_id`` (the odometry frame,
default ``odom``), ``child_frame_id`` (the robot's base, default ``base_link``) and
``map_frame_id`` (default ``map``). Each :meth:`OdometryBagWriter.write` adds, with the record
time = the stamp:

- on ``/fuzzypos/odom`` (``topic=``) a ``nav_msgs/msg/Odometry``: ``header.frame_id`` the
  odometry frame, ``child_frame_id`` the base; ``pose.pose`` the pose (z = 0, the quaternion
  of the yaw), ``pose.covariance`` the 6×6 (:func:`covariance6`, ROS's order x, y, z, roll,
  pitch, yaw) of the pose's 3×3 covariance, which the caller gives in the header's frame as
  ROS expects; ``twist.twist`` the velocity (linear x, y in the base frame, angular z) and
  ``twist.covariance`` the 6×6 of its 3×3 (unknown when None: every variance
  :data:`UNUSED_VARIANCE`);
- on ``/tf`` a ``tf2_msgs/msg/TFMessage`` with one odometry frame → base transform, the same
  pose (continuous, as REP-105 wants the odometry frame).

Each :meth:`OdometryBagWriter.write_optimised` (loop closure's poses, known at the end of a
run and written after the stream above, stamped as their scans) adds:

- on ``/fuzzypos/pose`` (``pose_topic=``) a ``geometry_msgs/msg/PoseWithCovarianceStamped``
  in the map frame: the optimised pose, its 6×6 covariance (unknown when None), whose 3×3
  the caller gives in the map frame as ROS expects, like the odometry's: additive errors of
  ``(x, y, θ)`` along the map's axes, ``R·Σ·Rᵀ`` of the right perturbation ``Σ`` in the
  robot's own frame (gtsam's ``Pose2`` marginals' convention, x, y, θ), ``R =
  blockdiag(rot(θ), 1)``;
- on ``/tf`` one map → odometry frame transform, ``optimised ∘ front_end⁻¹``: composed with
  the odometry frame → base transform of the same stamp it gives the optimised pose.

Messages carry Noetic (ROS1) or Humble (ROS2) definitions, stored in the bag. The kind is
:func:`bag_storage_for`: ``"ros1"`` for a path ending ``.bag``, else ``"sqlite3"``, unless
``storage=`` says (``"ros1"``, ``"sqlite3"`` or ``"mcap"``).

An existing path is never overwritten (:class:`FileExistsError`); bad values raise
:class:`BagWriteError` naming the bag and the message. :meth:`OdometryBagWriter.abort`
removes what was written (a failed run leaves no partial bag).
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag1 import WriterError as WriterError1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.rosbag2 import WriterError as WriterError2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from ..geometry import Pose2D, compose, inverse
from ._common import FloatArray, LogFormatError, PathLike

__all__ = [
    "BAG_STORAGES",
    "ODOM_OUT_TOPIC",
    "POSE_OUT_TOPIC",
    "TF_TOPIC",
    "UNUSED_VARIANCE",
    "BagWriteError",
    "OdometryBagWriter",
    "bag_storage_for",
    "covariance6",
]

#: the kinds of bag :class:`OdometryBagWriter` writes
BAG_STORAGES = ("ros1", "sqlite3", "mcap")
ODOM_OUT_TOPIC = "/fuzzypos/odom"
#: where :meth:`OdometryBagWriter.write_optimised` puts the optimised poses
POSE_OUT_TOPIC = "/fuzzypos/pose"
TF_TOPIC = "/tf"
#: the variance of an axis the estimate says nothing about (z, roll, pitch; unknown twists)
UNUSED_VARIANCE = 1e6
#: where each of (x, y, θ) sits among ROS's (x, y, z, roll, pitch, yaw)
_ROS_AXES = (0, 1, 5)

_ODOM = "nav_msgs/msg/Odometry"
_TF = "tf2_msgs/msg/TFMessage"
_POSE = "geometry_msgs/msg/PoseWithCovarianceStamped"
_WRITER_ERRORS = (WriterError1, WriterError2)


class BagWriteError(LogFormatError):
    """A value that cannot go into the bag: ``"<bag>:<message>: <what>"`` (the message index
    1-based, left out when the problem is not one message)."""


def bag_storage_for(path: PathLike, storage: str | None = None) -> str:
    """The kind of bag to write at ``path``: ``storage`` when given (one of
    :data:`BAG_STORAGES`), else ``"ros1"`` for a name ending ``.bag``, else ``"sqlite3"``."""
    if storage is None:
        return "ros1" if os.fspath(path).lower().endswith(".bag") else "sqlite3"
    if storage not in BAG_STORAGES:
        raise ValueError(f"bag storage must be one of {', '.join(BAG_STORAGES)}, got {storage!r}")
    return storage


def covariance6(cov3: ArrayLike | None) -> FloatArray:
    """ROS's 6×6 covariance (x, y, z, roll, pitch, yaw), row-major as 36 floats, from a 3×3
    over (x, y, θ): its entries at the x, y and yaw rows and columns, z, roll and pitch
    :data:`UNUSED_VARIANCE` on the diagonal (every axis so where ``cov3`` is None)."""
    out = np.zeros((6, 6), dtype=np.float64)
    np.fill_diagonal(out, UNUSED_VARIANCE)
    if cov3 is not None:
        out[np.ix_(_ROS_AXES, _ROS_AXES)] = np.asarray(cov3, dtype=np.float64)
    return out.reshape(36)


def _typestore(ros1: bool) -> Any:
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if _TF not in store.types:  # Noetic's store lacks tf2_msgs
        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", _TF))
    return store


def _split_stamp(stamp: float) -> tuple[int, int]:
    """``(sec, nanosec)`` of a stamp in seconds, nanoseconds rounded."""
    sec = math.floor(stamp)
    nsec = round((stamp - sec) * 1e9)
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    return sec, nsec


class OdometryBagWriter:
    """Stream an estimated trajectory into a new bag at ``path`` (module docstring).

    ``storage``: ``"ros1"``, ``"sqlite3"`` or ``"mcap"``, or None to choose by the name
    (:func:`bag_storage_for`). ``written`` counts the poses written, ``optimised_written``
    the optimised ones. Use as a context manager, or call :meth:`close` (or :meth:`abort`)
    at the end.
    """

    def __init__(
        self,
        path: PathLike,
        storage: str | None = None,
        *,
        topic: str | None = ODOM_OUT_TOPIC,
        frame_id: str = "odom",
        child_frame_id: str = "base_link",
        map_frame_id: str = "map",
        pose_topic: str = POSE_OUT_TOPIC,
    ) -> None:
        self.path = Path(path)
        self.storage = bag_storage_for(path, storage)
        if self.path.exists() or self.path.is_symlink():
            raise FileExistsError(
                errno.EEXIST, "exists already; a bag is never overwritten", os.fspath(path)
            )
        self.frame_id, self.child_frame_id = frame_id, child_frame_id
        self.map_frame_id, self.topic, self.pose_topic = map_frame_id, topic, pose_topic
        self.written = self.optimised_written = 0
        #: map → odometry frame transforms written by :meth:`write_optimised`
        self.transforms_written = 0
        self._pose: Any = None  # the optimised poses' connection, added with the first
        self._ros1 = self.storage == "ros1"
        self._store = _typestore(self._ros1)
        self._T = self._store.types
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self._ros1:
            self._writer: Any = Writer1(self.path)
        else:
            plugin = StoragePlugin.MCAP if self.storage == "mcap" else StoragePlugin.SQLITE3
            self._writer = Writer2(self.path, version=9, storage_plugin=plugin)
        self._open = False
        try:
            self._writer.open()
            self._open = True
            self._odom = (
                None
                if topic is None
                else self._writer.add_connection(topic, _ODOM, typestore=self._store)
            )
            self._tf = self._writer.add_connection(TF_TOPIC, _TF, typestore=self._store)
        except _WRITER_ERRORS as exc:
            if self._open:
                self.abort()
            raise BagWriteError(path, 0, f"cannot write the bag: {exc}") from exc

    def __enter__(self) -> OdometryBagWriter:
        return self

    def __exit__(self, exc_type: object, exc: object, tb: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    # -- messages ----------------------------------------------------------------------------
    def _header(self, sec: int, nsec: int, frame: str, seq: int | None = None) -> Any:
        stamp = self._T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
        if self._ros1:
            seq = self.written if seq is None else seq
            return self._T["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=frame)
        return self._T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def _vector(self, x: float, y: float, z: float) -> Any:
        return self._T["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)

    def _quat(self, yaw: float) -> Any:
        q = self._T["geometry_msgs/msg/Quaternion"]
        return q(x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0))

    def _messages(
        self,
        when: tuple[int, int],
        pose: tuple[float, float, float],
        pose_cov: FloatArray,
        twist: tuple[float, float, float],
        twist_cov: FloatArray,
    ) -> tuple[Any, Any]:
        T = self._T
        x, y, th = pose
        p = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=self._quat(th)
        )
        tw = T["geometry_msgs/msg/Twist"](
            linear=self._vector(twist[0], twist[1], 0.0), angular=self._vector(0.0, 0.0, twist[2])
        )
        odom = T[_ODOM](
            header=self._header(*when, self.frame_id),
            child_frame_id=self.child_frame_id,
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=p, covariance=pose_cov),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=tw, covariance=twist_cov),
        )
        transform = T["geometry_msgs/msg/TransformStamped"](
            header=self._header(*when, self.frame_id),
            child_frame_id=self.child_frame_id,
            transform=T["geometry_msgs/msg/Transform"](
                translation=self._vector(x, y, 0.0), rotation=self._quat(th)
            ),
        )
        return odom, T[_TF](transforms=[transform])

    def _serialize(self, msg: Any) -> bytes:
        if self._ros1:
            return bytes(self._store.serialize_ros1(msg, msg.__msgtype__))
        return bytes(self._store.serialize_cdr(msg, msg.__msgtype__))

    # -- checks ------------------------------------------------------------------------------
    def _fail(self, what: str) -> BagWriteError:
        return BagWriteError(self.path, self.written + 1, what)

    def _triple(self, v: Pose2D | Sequence[float] | ArrayLike, name: str) -> tuple[float, ...]:
        a = np.asarray(tuple(v) if isinstance(v, Pose2D) else v, dtype=np.float64).reshape(-1)
        if a.shape != (3,) or not np.all(np.isfinite(a)):
            raise self._fail(f"{name} must be 3 finite numbers, got {v!r}")
        return tuple(float(t) for t in a)

    def _cov(self, c: ArrayLike | None, name: str, required: bool) -> FloatArray:
        if c is None:
            if required:
                raise self._fail(f"{name} is missing")
            return covariance6(None)
        a = np.asarray(c, dtype=np.float64)
        if a.shape != (3, 3) or not np.all(np.isfinite(a)):
            raise self._fail(f"{name} must be a finite 3x3 array, got shape {a.shape}")
        if not np.allclose(a, a.T, rtol=1e-9, atol=1e-15) or np.any(np.diag(a) < 0.0):
            raise self._fail(f"{name} must be symmetric with non-negative variances")
        return covariance6(a)

    # -- the interface ----------------------------------------------------------------------
    def write(
        self,
        stamp: float,
        pose: Pose2D | Sequence[float],
        pose_cov3: ArrayLike,
        twist: Sequence[float] = (0.0, 0.0, 0.0),
        twist_cov3: ArrayLike | None = None,
    ) -> None:
        """Add one pose at ``stamp`` (seconds, >= 0): ``pose`` ``(x, y, θ)`` in ``odom``, its
        3×3 covariance in ``odom`` (x, y, θ), the twist ``(v_x, v_y, ω)`` in ``base_link``
        and its 3×3 covariance (None: unknown)."""
        if not self._open:
            raise ValueError(f"{self.path}: the bag writer is closed")
        if self._odom is None:
            raise ValueError(f"{self.path}: the bag writer has no odometry topic (topic=None)")
        t = float(stamp)
        if not math.isfinite(t) or t < 0.0:
            raise self._fail(f"the stamp must be a finite number >= 0 s, got {stamp!r}")
        p = self._triple(pose, "the pose")
        v = self._triple(twist, "the twist")
        pc = self._cov(pose_cov3, "the pose covariance", True)
        vc = self._cov(twist_cov3, "the twist covariance", False)
        sec, nsec = _split_stamp(t)
        odom, tf = self._messages((sec, nsec), (p[0], p[1], p[2]), pc, (v[0], v[1], v[2]), vc)
        ns = sec * 1_000_000_000 + nsec
        try:
            self._writer.write(self._odom, ns, self._serialize(odom))
            self._writer.write(self._tf, ns, self._serialize(tf))
        except _WRITER_ERRORS as exc:
            raise self._fail(f"cannot write: {exc}") from exc
        self.written += 1

    def _optimised_messages(
        self,
        when: tuple[int, int],
        pose: tuple[float, ...],
        correction: FloatArray | None,
        cov: Any,
    ) -> tuple[Any, Any]:
        T, seq = self._T, self.optimised_written
        x, y, th = pose
        p = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=self._quat(th)
        )
        stamped = T[_POSE](
            header=self._header(*when, self.map_frame_id, seq),
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=p, covariance=cov),
        )
        if correction is None:
            return stamped, None
        cx, cy, cth = (float(v) for v in correction)
        transform = T["geometry_msgs/msg/TransformStamped"](
            header=self._header(*when, self.map_frame_id, seq),
            child_frame_id=self.frame_id,
            transform=T["geometry_msgs/msg/Transform"](
                translation=self._vector(cx, cy, 0.0), rotation=self._quat(cth)
            ),
        )
        return stamped, T[_TF](transforms=[transform])

    def write_optimised(
        self,
        stamp: float,
        pose: Pose2D | Sequence[float],
        frontend_pose: Pose2D | Sequence[float] | None,
        pose_cov3: ArrayLike | None = None,
    ) -> None:
        """Add one optimised pose at ``stamp``: ``pose`` ``(x, y, θ)`` in the map frame, the
        front end's pose ``frontend_pose`` of the same scan (in the odometry frame, as given
        to :meth:`write`) and the optimised pose's 3×3 covariance in the map frame (None:
        unknown). Writes the pose and the map → odometry frame transform
        ``pose ∘ frontend_pose⁻¹`` (module docstring; none where ``frontend_pose`` is None)."""
        if not self._open:
            raise ValueError(f"{self.path}: the bag writer is closed")
        t = float(stamp)
        if not math.isfinite(t) or t < 0.0:
            raise self._fail(f"the stamp must be a finite number >= 0 s, got {stamp!r}")
        p = self._triple(pose, "the optimised pose")
        cov = self._cov(pose_cov3, "the optimised pose's covariance", False)
        correction = None
        if frontend_pose is not None:
            f = self._triple(frontend_pose, "the front end's pose")
            correction = compose(np.asarray(p), inverse(np.asarray(f)))
        sec, nsec = _split_stamp(t)
        stamped, tf = self._optimised_messages((sec, nsec), p, correction, cov)
        ns = sec * 1_000_000_000 + nsec
        try:
            if self._pose is None:
                self._pose = self._writer.add_connection(
                    self.pose_topic, _POSE, typestore=self._store
                )
            self._writer.write(self._pose, ns, self._serialize(stamped))
            if tf is not None:
                self._writer.write(self._tf, ns, self._serialize(tf))
                self.transforms_written += 1
        except _WRITER_ERRORS as exc:
            raise self._fail(f"cannot write: {exc}") from exc
        self.optimised_written += 1

    def close(self) -> None:
        """Finish the bag (its index, its metadata); a second call does nothing."""
        if self._open:
            self._open = False
            try:
                self._writer.close()
            except _WRITER_ERRORS as exc:
                raise BagWriteError(self.path, 0, f"cannot finish the bag: {exc}") from exc

    def abort(self) -> None:
        """Close and remove the bag (it did not exist before this writer)."""
        with contextlib.suppress(BagWriteError, OSError):
            self.close()
        if self.path.is_dir():
            shutil.rmtree(self.path, ignore_errors=True)
        elif self.path.exists():
            self.path.unlink()
