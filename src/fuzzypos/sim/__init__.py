"""2D laser simulator: line-segment worlds, vectorised ray casting, a scanner with the paper's
error model, and a synchronous-drive robot that slips.

- :mod:`.world`: :class:`World` (wall segments ``[x1, y1, x2, y2]`` in metres, usually built
  from polygons whose vertex lists are kept so the true corners are known), loading and saving
  world files (:meth:`World.from_file`, :meth:`World.to_file`; format in :mod:`.worldfile`).
- :mod:`.raycast`: :func:`cast_rays` casts many rays against every segment at once (beams x
  segments broadcasting, in chunks of beams to bound memory).
- :mod:`.scanner`: :class:`ScannerModel` (beams, range, mounting, range noise growing with the
  distance and the incidence, dropouts, spurious returns, scan rate; :meth:`ScannerModel.
  sick_lms200`), :func:`simulate_scan` turns a world and a robot pose into a
  :class:`~fuzzypos.scan.LaserScan`, :func:`visible_corners`.
- :mod:`.worlds`: built-in worlds :func:`gym`, :func:`office`, :func:`furnished_room`,
  :func:`rectangular_room`, :func:`doorway_wall`; :func:`world_by_name`.
- :mod:`.robot`: :class:`CommandedPath` (circle, square, figure eight, waypoints),
  :class:`SlipModel` (a commanded circle becomes an outward spiral), :func:`simulate_run`
  (:class:`SimulatedRun`: true poses, odometry and scans at the scanner's rate).
- :mod:`.motion`: :func:`arc_path`, :func:`drifting_odometry`, :func:`random_motions`.
- :mod:`.kinds`: runs of the kinds of real log the estimator is checked on:
  :func:`sick_outdoor_run` (an interlaced SICK at 1.6 Hz in a yard of far structure, 12%
  no-returns read as 81.83 m, odometry under-reading rotation by 1%) and its parts.

Conventions (SPEC): SI units, radians inside the code (degrees only in ``*_deg`` fields), frames
as in ROS REP-103 (x forward, y left, angles counter-clockwise). A beam with no return reads
exactly ``range_max``, which :class:`~fuzzypos.scan.LaserScan` treats as invalid.
"""

from __future__ import annotations

# names the single-module simulator exposed by importing them; kept importable from here
from ..geometry import Pose2D as Pose2D
from ..geometry import compose as compose
from ..geometry import relative as relative
from ..geometry import wrap_angle as wrap_angle
from ..scan import LaserScan as LaserScan
from .kinds import (
    outdoor_yard,
    sick_interlaced_scanner,
    sick_outdoor_path,
    sick_outdoor_run,
    sick_outdoor_slip,
)
from .motion import MotionTrial, arc_path, drifting_odometry, random_motions
from .raycast import cast_rays
from .robot import CommandedPath, SimulatedRun, SlipModel, simulate_run
from .scanner import ScannerModel, laser_pose, simulate_scan, simulate_scans, visible_corners
from .world import ENDPOINT_TOL, PARALLEL_SIN, T_MIN, VERTEX_TOL, SimError, World
from .world import FloatArray as FloatArray
from .world import _point_segment_distance as _point_segment_distance  # the tests use it
from .worlds import (
    GYM_FREE_RADIUS,
    GYM_HALF,
    WORLD_NAMES,
    box_polygon,
    circle_polygon,
    doorway_wall,
    furnished_room,
    gym,
    office,
    rectangular_room,
    world_by_name,
)

__all__ = [
    "SimError",
    "World",
    "ScannerModel",
    "cast_rays",
    "simulate_scan",
    "simulate_scans",
    "visible_corners",
    "laser_pose",
    "rectangular_room",
    "furnished_room",
    "office",
    "doorway_wall",
    "gym",
    "world_by_name",
    "WORLD_NAMES",
    "GYM_HALF",
    "GYM_FREE_RADIUS",
    "box_polygon",
    "circle_polygon",
    "arc_path",
    "drifting_odometry",
    "MotionTrial",
    "random_motions",
    "CommandedPath",
    "SlipModel",
    "SimulatedRun",
    "simulate_run",
    "outdoor_yard",
    "sick_interlaced_scanner",
    "sick_outdoor_slip",
    "sick_outdoor_path",
    "sick_outdoor_run",
    "T_MIN",
    "ENDPOINT_TOL",
    "PARALLEL_SIN",
    "VERTEX_TOL",
]
