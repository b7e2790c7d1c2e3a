"""Loop closure on a pose graph over the front end's keyframes (issue 13; gtsam, an optional
extra: ``pip install 'fuzzypos[graph]'``).

- :mod:`.pose_graph`: :class:`PoseGraph` (vertices the keyframes, edges from the front end's
  keyframe fits and from closures; gtsam Levenberg-Marquardt, robust closures), g2o out and in.
- :mod:`.closure`: :class:`LoopCloser` (candidates, verification against a submap, closures).
- :mod:`.place`: the place descriptor (a rotation-invariant polar occupancy grid of a
  keyframe's surroundings) that ranks candidates where the graph's guess has drifted.
- :mod:`.occupancy`: the occupancy map (ROS map_server's ``map.pgm`` + ``map.yaml``, ``map.png``).
- :mod:`.online`: :class:`OnlineMapper`, loop closure online: the front end, the graph grown
  keyframe by keyframe and kept optimised by ISAM2, the latest optimised pose after each scan.
- :mod:`.realign`: after the last optimisation, every scan fitted once more to the surfaces of
  the keyframes around its own at their optimised poses (:func:`realign`, :class:`ScanStore`).
- :mod:`.outputs`: :func:`close_loops` after a run, and the files it adds to a results folder.
- :mod:`._gtsam`: gtsam imported on first use, :class:`GraphDependencyError` where it is absent.
"""

from __future__ import annotations

from ._gtsam import GraphDependencyError
from ._gtsam import gtsam as require_gtsam
from .closure import Closure, LoopCloser
from .online import OnlineMapper, OnlineUpdate
from .outputs import LOOP_CLOSURE_FILES, LoopClosureResult, close_loops
from .pose_graph import ROBUST_KINDS, Edge, Keyframe, PoseGraph, PoseGraphError, read_g2o
from .realign import Realigned, ScanStore, realign

__all__ = [
    "GraphDependencyError",
    "LoopCloser",
    "Closure",
    "PoseGraph",
    "PoseGraphError",
    "Edge",
    "Keyframe",
    "ROBUST_KINDS",
    "read_g2o",
    "require_gtsam",
    "close_loops",
    "LoopClosureResult",
    "LOOP_CLOSURE_FILES",
    "OnlineMapper",
    "OnlineUpdate",
    "Realigned",
    "ScanStore",
    "realign",
]
