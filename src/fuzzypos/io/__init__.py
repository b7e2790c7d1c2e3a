"""Reading and writing robot logs and trajectories.

- :mod:`fuzzypos.io.carmen`: CARMEN logs (``.clf``, plain or gzip), read as a stream and written;
- :mod:`fuzzypos.io.carmen_write`: :class:`CarmenWriter`, the one CARMEN writer (behind
  :func:`write_carmen` and the run job's ``trajectory.clf``);
- :mod:`fuzzypos.io.rosbag`: ROS1 and ROS2 bags (``sensor_msgs/LaserScan`` with
  ``nav_msgs/Odometry``) through the ``rosbags`` package;
- :mod:`fuzzypos.io.rosbag_write`: :class:`OdometryBagWriter`, an estimate as
  ``nav_msgs/Odometry`` and ``/tf`` into a ROS1 or ROS2 bag;
- :mod:`fuzzypos.io.relations`: the Freiburg benchmark's relations files;
- :mod:`fuzzypos.io.tum`: TUM trajectories (``t x y z qx qy qz qw``, what ``evo`` reads);
- :mod:`fuzzypos.io.logs`: :func:`open_log`, a CARMEN log or a bag opened as one stream of
  records, with the checks of its stamps, odometry (:mod:`fuzzypos.io.odometry_check`) and
  no-return readings (:mod:`fuzzypos.io.no_returns`);
- :mod:`fuzzypos.io.provenance`: what a results folder records of its inputs (hashes, git).

Every format error is a :class:`LogFormatError` (a :class:`ValueError`) naming the file, the
line and what is wrong. Outputs are written where their paths point
(:func:`output_target`): an :class:`OutputPathError` refuses a path before anything is
written, an :class:`OutputWriteError` names the file a write failed on.
"""

from __future__ import annotations

from ._common import (
    GZIP_MAGIC,
    LogFormatError,
    LogRecord,
    OutputPathError,
    OutputWriteError,
    check_output_file,
    open_text,
    output_target,
    write_text_file,
)
from .carmen import (
    CONVENTIONS,
    CarmenFormatError,
    CarmenReader,
    CarmenRecord,
    CarmenWriter,
    carmen_beam_geometry,
    read_carmen,
    write_carmen,
)
from .logs import LogInfo, OpenLog, UnknownLogError, describe_log, log_kind, open_log
from .relations import PLANAR_TOLERANCE, Relations, RelationsFormatError, read_relations
from .rosbag import (
    BagFormatError,
    BagReader,
    BagTopicError,
    interpolate_poses,
    is_ros1_bag,
    is_ros2_bag,
    read_bag,
)
from .rosbag_write import BAG_STORAGES, BagWriteError, OdometryBagWriter, covariance6
from .tum import TumFormatError, read_tum, write_tum

__all__ = [
    "LogInfo",
    "OpenLog",
    "UnknownLogError",
    "describe_log",
    "log_kind",
    "open_log",
    "PLANAR_TOLERANCE",
    "Relations",
    "RelationsFormatError",
    "read_relations",
    "BagFormatError",
    "BagReader",
    "BagTopicError",
    "interpolate_poses",
    "is_ros1_bag",
    "is_ros2_bag",
    "read_bag",
    "BAG_STORAGES",
    "BagWriteError",
    "OdometryBagWriter",
    "covariance6",
    "CONVENTIONS",
    "GZIP_MAGIC",
    "CarmenFormatError",
    "CarmenReader",
    "CarmenRecord",
    "CarmenWriter",
    "LogFormatError",
    "LogRecord",
    "OutputPathError",
    "OutputWriteError",
    "TumFormatError",
    "carmen_beam_geometry",
    "check_output_file",
    "open_text",
    "output_target",
    "read_carmen",
    "read_tum",
    "write_carmen",
    "write_text_file",
    "write_tum",
]
