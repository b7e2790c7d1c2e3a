"""Loop closure after a run (``fuzzypos run --loop-closure``): the closures found on the run's
pose graph, the optimised trajectory, and the files it adds to a results folder:
``trajectory_frontend.tum`` (the front end's poses; ``trajectory.tum`` then holds the
optimised ones), ``covariance_optimised.csv`` (the optimised poses' covariances,
:func:`optimised_covariances`), ``trajectory_online.tum`` (online: each scan's pose as it was
first output, :class:`~.online.OnlineMapper`), ``graph.g2o`` and the occupancy map
``map.pgm`` + ``map.yaml`` (ROS map_server) and ``map.png``."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..config import Config
from ..geometry import covariances_to_parent
from ..io import write_tum
from .closure import Closure, LoopCloser
from .occupancy import map_grid, occupancy_grid
from .pose_graph import PoseGraph
from .realign import ScanStore, realign

__all__ = [
    "LOOP_CLOSURE_FILES",
    "OPTIMISED_COVARIANCE_COLUMNS",
    "LoopClosureResult",
    "close_loops",
    "loop_closure_result",
    "optimised_covariances",
]

FloatArray = NDArray[np.float64]

#: the files loop closure adds to a results folder
LOOP_CLOSURE_FILES = (
    "trajectory_frontend.tum",
    "covariance_optimised.csv",
    "trajectory_online.tum",
    "graph.g2o",
    "map.pgm",
    "map.yaml",
    "map.png",
)

#: ``covariance_optimised.csv``'s columns: the stamp, then the upper triangle of the optimised
#: pose's covariance in the map frame (as ``covariance.csv``'s ``pose_*`` columns)
OPTIMISED_COVARIANCE_COLUMNS = (
    "stamp", "pose_xx", "pose_xy", "pose_xtheta", "pose_yy", "pose_ytheta", "pose_thetatheta"
)  # fmt: skip


@dataclass(frozen=True, eq=False)
class LoopClosureResult:
    """The optimised poses of every scan, the front end's, the graph and its closures;
    online, each scan's pose as first output (``online``) and the scans the map is drawn
    from (``map_scans``: scan index and its points in the robot frame; None: the
    keyframes'). ``covariances``: each optimised pose's covariance ``(scans, 3, 3)`` in
    the map frame (:func:`optimised_covariances`; None where gtsam could not give the
    marginals)."""

    poses: FloatArray
    frontend: FloatArray
    graph: PoseGraph
    closures: list[Closure]
    verified: int
    seconds: float
    summary: dict[str, Any] = field(default_factory=dict)
    online: FloatArray | None = None
    map_scans: list[tuple[int, FloatArray]] | None = None
    covariances: FloatArray | None = None

    def write(
        self, folder: Path, stamps: FloatArray, source: str, resolution: float
    ) -> dict[str, Path]:
        """Write ``trajectory_frontend.tum``, ``trajectory_online.tum`` (online),
        ``graph.g2o`` and the map into ``folder``."""
        files: dict[str, Path] = {"trajectory_frontend.tum": folder / "trajectory_frontend.tum"}
        write_tum(
            files["trajectory_frontend.tum"], stamps, self.frontend,
            header_comment=f"the front end's estimate of {source}, before loop closure",
        )  # fmt: skip
        if self.online is not None:
            files["trajectory_online.tum"] = folder / "trajectory_online.tum"
            write_tum(
                files["trajectory_online.tum"], stamps, self.online,
                header_comment=f"loop closure online on {source}: each scan's pose as first "
                "output",
            )  # fmt: skip
        if self.covariances is not None:
            files["covariance_optimised.csv"] = folder / "covariance_optimised.csv"
            _write_covariances(files["covariance_optimised.csv"], stamps, self.covariances)
        files["graph.g2o"] = folder / "graph.g2o"
        self.graph.write_g2o(files["graph.g2o"])
        if self.map_scans is not None:
            grid = map_grid(self.poses, self.map_scans, resolution)
        else:
            scans = [
                kf.features.points if kf.features is not None else np.zeros((0, 2))
                for kf in self.graph.keyframes
            ]
            grid = occupancy_grid(self.graph.poses, scans, resolution)
        files.update(grid.write(folder))
        return files


def _write_covariances(path: Path, stamps: FloatArray, covariances: FloatArray) -> None:
    """``covariance_optimised.csv``: a header line (:data:`OPTIMISED_COVARIANCE_COLUMNS`),
    then per scan its stamp and its covariance's upper triangle (``nan``: not known)."""
    c = np.asarray(covariances, dtype=float).reshape(-1, 3, 3)
    upper = c[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]
    rows = np.column_stack((np.asarray(stamps, dtype=float), upper)).tolist()
    lines = [",".join(OPTIMISED_COVARIANCE_COLUMNS)]
    lines += [",".join(map(repr, row)) for row in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def optimised_covariances(graph: PoseGraph, poses: FloatArray) -> FloatArray:
    """The covariance of each scan's optimised pose (``poses``, a row per scan), ``(scans,
    3, 3)``, in the map frame (the frame ``poses`` are in; ROS's ``PoseWithCovariance``'s):
    the keyframes' marginals from the final graph (:meth:`~.pose_graph.PoseGraph.marginals`,
    each in its keyframe's own frame), carried to each scan with the front end's covariance
    of its pose relative to its keyframe
    (:meth:`~.pose_graph.PoseGraph.scan_covariances`: a right perturbation in the scan's own
    frame) and rotated by the scan's heading into the map frame,
    ``R·Σ·Rᵀ``, ``R = blockdiag(rot(θ), 1)`` (:func:`~fuzzypos.geometry.covariances_to_parent`,
    as the front end's pose covariance is rotated into the odometry frame). A RuntimeError
    where gtsam finds the graph indeterminate."""
    body = graph.scan_covariances(poses, graph.marginals())
    return covariances_to_parent(poses, body)


def close_loops(
    graph: PoseGraph, config: Config, scans: ScanStore | None = None
) -> LoopClosureResult:
    """Find, verify and add the closures of ``graph`` (its keyframes with their features) and
    optimise it, offline (after the front end's whole run); every scan realigned to the
    closed map where ``scans`` holds them (and ``realign`` is on); the summary for
    ``summary.json``."""
    t0 = time.perf_counter()
    closer = LoopCloser(config)
    closer.run(graph)
    result = loop_closure_result(graph, closer, config, time.perf_counter() - t0, scans=scans)
    result.summary["mode"] = "offline"
    return result


def loop_closure_result(
    graph: PoseGraph,
    closer: LoopCloser,
    config: Config,
    seconds: float,
    *,
    online: FloatArray | None = None,
    map_scans: list[tuple[int, FloatArray]] | None = None,
    scans: ScanStore | None = None,
) -> LoopClosureResult:
    """The result of loop closure on ``graph`` by ``closer`` (its closures with their final
    weights), the optimised trajectory (blended between keyframes; each scan then realigned
    to the closed map where ``scans`` holds every scan's points and ``realign`` is on,
    :mod:`.realign`) and the summary."""
    frontend = graph.frontend_trajectory()
    closures = closer.closures
    poses = graph.trajectory(blend=True)
    refitted = None
    if config.loop_closure.realign and scans is not None:
        t0 = time.perf_counter()
        realigned = realign(graph, closer, scans, poses)
        poses, refitted = realigned.poses, realigned.refitted
        seconds += time.perf_counter() - t0
    t0 = time.perf_counter()
    covariances, failed = None, None
    try:
        covariances = optimised_covariances(graph, poses)
    except RuntimeError as exc:  # gtsam: an indeterminate system
        failed = " ".join(str(exc).split()) or type(exc).__name__
    marginals_seconds = time.perf_counter() - t0
    seconds += marginals_seconds
    moved = np.hypot(*(poses[:, :2] - frontend[:, :2]).T) if len(poses) else np.zeros(1)
    summary = {
        "keyframes": len(graph),
        "candidates_verified": closer.verified,
        "closures": [
            {
                "keyframes": [c.i, c.j],
                "stamps": [graph.keyframes[c.i].stamp, graph.keyframes[c.j].stamp],
                "measured": [float(v) for v in c.measured],
                "inlier_fraction": c.inlier_fraction,
                "gate": c.gate,
                "weight": c.weight,
                "source": c.source,
                "agreed_with": None if c.agreed is None else list(c.agreed),
            }
            for c in closures
        ],
        "closures_kept": sum(c.weight >= 0.5 for c in closures),
        "closures_from_places": sum(c.source == "place" for c in closures),
        "rejected": dict(sorted(closer.rejections.items())),
        "max_correction_m": float(moved.max()),
        "seconds": seconds,
        "robust": config.loop_closure.robust,
        "map_scans": len(graph) if map_scans is None else len(map_scans),
        "realigned_scans": refitted,
        "marginals_seconds": marginals_seconds,
        "marginals_error": failed,
    }
    return LoopClosureResult(
        poses, frontend, graph, closures, closer.verified, seconds, summary, online, map_scans,
        covariances,
    )  # fmt: skip
