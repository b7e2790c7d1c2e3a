"""Loop closure on a pose graph over the front end's keyframes (issue 13; gtsam, an optional
extra: ``pip install 'fuzzypos[graph]'``).

- :mod:`.pose_graph`: :class:`PoseGraph` (vertices the keyframes, edges from the front end's
  keyframe fits and from closures; gtsam Levenberg-Marquardt, robust closures), g2o out and in.
- :mod:`._gtsam`: gtsam imported on first use, :class:`GraphDependencyError` where it is absent.
"""

from __future__ import annotations

from ._gtsam import GraphDependencyError
from .closure import Closure, LoopCloser
from .pose_graph import ROBUST_KINDS, Edge, Keyframe, PoseGraph, PoseGraphError, read_g2o

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
]
