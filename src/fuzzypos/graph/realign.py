"""Every scan fitted once more to the map the loops closed (``[loop_closure]``'s ``realign``).

After the last optimisation a keyframe's pose is the graph's, but a scan between two
keyframes only follows them: the front end's pose relative to its keyframe, with the
keyframes' corrections blended (:meth:`~.pose_graph.PoseGraph.trajectory`). That keeps the
front end's own error from scan to scan, and where a loop closed, the trajectory is bent a
little at every keyframe to spread its correction. Here each scan's points are refined once
more, by the front end's refinement (:meth:`~fuzzypos.pipeline.Refiner.fit`, its prior the
scan's optimised pose), against the surfaces of its keyframe and ``realign_keyframes``
either side, placed at their optimised poses: the scan lands on the walls as the closed map
has them. A scan whose fit is not trusted (too few points on the map, or a correction beyond
``max_correction``) keeps its optimised pose.

:class:`ScanStore` keeps what the fit needs of each scan during the run (its points, their
weights and spacing, in float32: about 3 KB a scan of 180 beams)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..config import Config
from ..features import Features
from ..geometry import compose, relative
from ..matching import SurfacePoints
from ..pipeline import Refiner
from ..pipeline.refine import ScanPoints
from .closure import LoopCloser, angle_increment_of
from .pose_graph import PoseGraph

__all__ = ["Realigned", "ScanStore", "realign"]

FloatArray = NDArray[np.float64]

_Kept = tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]] | None


class ScanStore:
    """Each scan's points for :func:`realign`, in the order the graph got the scans (None:
    a scan without enough points to fit), weighed as ``config``'s refinement weighs them."""

    def __init__(self, config: Config) -> None:
        self.refiner = Refiner(config.refinement, config.search)
        self.scans: list[_Kept] = []
        #: per scan: the information of its pose relative to its keyframe (the front end's
        #: ``keyframe_covariance`` inverted; None: not known)
        self.information: list[FloatArray | None] = []

    def __len__(self) -> int:
        return len(self.scans)

    def add(
        self,
        features: Features | None,
        angle_increment: float | None = None,
        keyframe_covariance: FloatArray | None = None,
    ) -> None:
        """The next scan's features (None: nothing to fit), its beam spacing (rad; None:
        estimated from the features' points) and the covariance of its pose relative to its
        keyframe (the front end's ``Estimate.keyframe_covariance``; None: the refinement's
        fixed prior)."""
        self.information.append(_information(keyframe_covariance))
        if features is not None and angle_increment is None:
            angle_increment = angle_increment_of(features)
        points = None
        if features is not None and angle_increment is not None:
            points = self.refiner.points(features, angle_increment)
        if points is None:
            self.scans.append(None)
            return
        spacing = points.spacing if points.spacing is not None else np.zeros(0)
        f32 = np.float32
        self.scans.append((points.xy.astype(f32), points.weights.astype(f32), spacing.astype(f32)))

    def points(self, s: int) -> ScanPoints | None:
        """Scan ``s``'s points (float64 again, as the refinement takes them)."""
        kept = self.scans[s]
        if kept is None:
            return None
        xy, weights, spacing = (a.astype(np.float64) for a in kept)
        return ScanPoints(xy, weights, spacing if spacing.shape[0] else None)


def _information(cov: FloatArray | None) -> FloatArray | None:
    """The inverse of a 3×3 covariance, None where it is absent or not positive definite
    (Sylvester's test on the leading minors, in floats: a Cholesky per scan costs more)."""
    if cov is None:
        return None
    c = np.asarray(cov, dtype=float)
    if c.shape != (3, 3) or not np.isfinite(c).all():
        return None
    (a, b, d), (_, e, f), (_, _, g) = c.tolist()
    minor = a * e - b * b
    det = a * (e * g - f * f) - b * (b * g - f * d) + d * (b * f - e * d)
    if not (a > 0.0 and minor > 0.0 and det > 0.0):
        return None
    return np.asarray(np.linalg.inv(c), dtype=np.float64)


@dataclass(frozen=True, eq=False)
class Realigned:
    """The realigned poses of every scan and how many scans were refitted."""

    poses: FloatArray
    refitted: int


def realign(graph: PoseGraph, closer: LoopCloser, store: ScanStore, poses: FloatArray) -> Realigned:
    """Every scan of ``store`` fitted from its row of ``poses`` (the optimised trajectory,
    ``(scans, 3)``) to the surfaces of its keyframe and ``realign_keyframes`` either side
    at the graph's poses (module docstring)."""
    if len(store) != graph.scans or poses.shape != (graph.scans, 3):
        raise ValueError(
            f"realign needs one kept scan and one pose per scan of the graph ({graph.scans}), "
            f"got {len(store)} scans and poses of shape {poses.shape}"
        )
    h = closer.settings.realign_keyframes
    max_distance = closer.config.refinement.max_distance
    owners, at = graph.owners, graph.poses
    out = np.array(poses, dtype=float)
    surface: SurfacePoints | None = None
    surface_of, refitted = -1, 0
    for s in range(graph.scans):
        points = store.points(s)
        if points is None:
            continue
        k = int(owners[s])
        if k != surface_of:  # the scans come keyframe by keyframe: one submap each
            around = range(max(0, k - h), min(len(graph) - 1, k + h) + 1)
            surface, surface_of = closer.surfaces_in_frame_of(graph, k, around), k
        if surface is None or len(surface) < 3:
            continue
        start = np.array(relative(at[k], out[s]))
        fit = closer.refiner.fit(
            surface, points, start, start, start, max_distance=max_distance,
            prior_information=store.information[s],
        )  # fmt: skip
        if fit is None:
            continue
        out[s] = compose(at[k], fit.increment)
        refitted += 1
    return Realigned(out, refitted)
