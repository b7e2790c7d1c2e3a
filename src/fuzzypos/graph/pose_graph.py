"""A pose graph over the front end's keyframes: one vertex per keyframe, an edge between
consecutive keyframes from the fit itself (``Estimate.keyframe_covariance``, a right
perturbation x, y, θ), loop closures as more edges; optimised by gtsam's Levenberg-Marquardt,
closures made robust by a graduated non-convexity (GNC) or a Cauchy kernel; the scans between
keyframes follow their keyframe. g2o files out and in (``VERTEX_SE2``, ``EDGE_SE2`` with the
upper triangle of the information matrix)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import FuzzyposError
from ..features import Features
from ..geometry import adjoint, compose, inverse, propagate, relative
from ..pipeline import Estimate
from ._gtsam import gtsam

__all__ = ["Edge", "Keyframe", "PoseGraph", "PoseGraphError", "ROBUST_KINDS", "read_g2o"]

FloatArray = NDArray[np.float64]

#: how closures are made robust: graduated non-convexity, a Cauchy kernel, or not at all
ROBUST_KINDS = ("gnc", "cauchy", "none")
#: the first keyframe's anchor (m, rad): the graph's gauge, not a measurement
_ANCHOR_SIGMAS = (1e-6, 1e-6, 1e-7)
#: added to every edge's covariance's diagonal (m², rad²) so a degenerate one stays invertible
_COVARIANCE_FLOOR = 1e-12


class PoseGraphError(FuzzyposError, ValueError):
    """A pose graph cannot be built or read as asked; the message says why."""

    __module__ = "fuzzypos.graph"


@dataclass(frozen=True, eq=False)
class Keyframe:
    """A vertex: the scan it is (index among the estimates), its stamp, the front end's pose
    and, where kept, the scan's features (what a closure is verified with)."""

    scan: int
    stamp: float
    pose: FloatArray
    features: Features | None = None


@dataclass(frozen=True, eq=False)
class Edge:
    """Keyframe ``j``'s pose in keyframe ``i``'s frame, ``measured``, with the covariance of its
    right perturbation (x, y in m, θ in rad); ``closure``: a loop closure, not the front end."""

    i: int
    j: int
    measured: FloatArray
    covariance: FloatArray
    closure: bool = False

    @cached_property
    def information(self) -> FloatArray:
        cov = 0.5 * (self.covariance + self.covariance.T) + _COVARIANCE_FLOOR * np.eye(3)
        info = np.asarray(np.linalg.inv(cov), dtype=np.float64)
        out: FloatArray = 0.5 * (info + info.T)
        return out


class PoseGraph:
    """Keyframes and the edges between them, built one estimate at a time (:meth:`add`) or
    from a whole run (:meth:`from_estimates`). Every scan remembers its keyframe and its pose
    relative to it, so after :meth:`optimize` it follows its keyframe (:meth:`trajectory`)."""

    def __init__(self) -> None:
        self.keyframes: list[Keyframe] = []
        self.edges: list[Edge] = []
        self._owner: list[int] = []  # per scan: its keyframe
        self._offset: list[FloatArray] = []  # per scan: its pose relative to its keyframe
        #: per scan: the covariance of its pose relative to its keyframe (right perturbation;
        #: zeros at a keyframe, NaN where the front end gave none), :meth:`_offset_covariance`
        self._offset_cov: list[FloatArray] = []
        self._robust: tuple[str, float] = ("none", 1.0)  # the last optimisation's kernel
        self._stamps: list[float] = []
        self._frontend: list[FloatArray] = []
        #: the keyframes' optimised poses (the front end's until optimised)
        self.poses: FloatArray = np.zeros((0, 3))
        #: per closure edge (in order): its weight in the last optimisation (1 kept, 0 rejected)
        self.closure_weights: list[float] = []

    @classmethod
    def from_estimates(cls, estimates: Iterable[Estimate]) -> PoseGraph:
        graph = cls()
        for est in estimates:
            graph.add(est)
        return graph

    def __len__(self) -> int:
        return len(self.keyframes)

    @property
    def scans(self) -> int:
        return len(self._owner)

    @property
    def stamps(self) -> FloatArray:
        return np.array(self._stamps, dtype=float)

    @property
    def owners(self) -> NDArray[np.intp]:
        """Per scan: the index of its keyframe."""
        return np.array(self._owner, dtype=np.intp)

    @property
    def closures(self) -> list[Edge]:
        return [e for e in self.edges if e.closure]

    def add(self, est: Estimate) -> bool:
        """The next scan's estimate; whether it became a keyframe (a vertex, with an edge from
        the keyframe before it). The first estimate is always one."""
        pose = est.pose.as_array()
        k = len(self._owner)
        if est.keyframe or not self.keyframes:
            if self.keyframes:
                self._edge_to(est, pose, k)
            self.keyframes.append(Keyframe(k, est.stamp, pose, est.features))
            self.poses = np.vstack([self.poses, pose[None, :]])
        owner = len(self.keyframes) - 1
        self._owner.append(owner)
        self._offset.append(relative(self.keyframes[owner].pose, pose))
        self._offset_cov.append(self._offset_covariance(est, owner))
        self._stamps.append(float(est.stamp))
        self._frontend.append(pose)
        return self.keyframes[owner].scan == k

    def _offset_covariance(self, est: Estimate, owner: int) -> FloatArray:
        """The covariance of the new scan's pose relative to keyframe ``owner``: zeros where
        it is that keyframe; else the front end's ``keyframe_covariance`` (its fit against
        that keyframe), else the previous scan's carried on by the step's covariance
        (:func:`~fuzzypos.geometry.propagate`); NaN where neither is known."""
        if self.keyframes[owner].scan == len(self._owner) - 1:
            return np.zeros((3, 3))
        if est.keyframe_covariance is not None:
            return np.asarray(est.keyframe_covariance, dtype=np.float64)
        if est.covariance is None or not np.all(np.isfinite(self._offset_cov[-1])):
            return np.full((3, 3), np.nan)
        step = est.increment.as_array()
        return propagate(self._offset_cov[-1], step, np.asarray(est.covariance, dtype=float))

    def _edge_to(self, est: Estimate, pose: FloatArray, k: int) -> None:
        cov = est.keyframe_covariance
        if cov is None:
            raise PoseGraphError(
                f"scan {k} (stamp {est.stamp:.6f}) is a keyframe without a keyframe covariance: "
                "a pose graph needs the front end's (Positioner gives it)"
            )
        cov = np.asarray(cov, dtype=float)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            raise PoseGraphError(f"scan {k}: keyframe covariance is not a finite 3×3 matrix")
        i = len(self.keyframes) - 1
        measured = relative(self.keyframes[i].pose, pose)
        self.edges.append(Edge(i, i + 1, measured, cov))

    def add_closure(self, i: int, j: int, measured: FloatArray, covariance: FloatArray) -> Edge:
        """A loop closure: keyframe ``j``'s pose in keyframe ``i``'s frame."""
        n = len(self.keyframes)
        if not (0 <= i < n and 0 <= j < n) or i == j:
            raise PoseGraphError(f"a closure needs two keyframes of 0..{n - 1}, got {i} and {j}")
        cov = np.asarray(covariance, dtype=float)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            raise PoseGraphError("a closure's covariance must be a finite 3×3 matrix")
        edge = Edge(i, j, np.asarray(measured, dtype=float), cov, closure=True)
        self.edges.append(edge)
        return edge

    def optimize(
        self, robust: str = "gnc", cauchy_scale: float = 1.0, gnc_mu_step: float = 1.4
    ) -> FloatArray:
        """The keyframes' poses that best explain every edge (Levenberg-Marquardt from the
        current poses, the first keyframe held); closures robust by ``robust`` (``ROBUST_KINDS``;
        ``cauchy_scale``: the Cauchy kernel's, in standard deviations). With ``"gnc"`` the
        closures GNC (started from the plain solution with every closure) weighs below one half
        are left out and the rest kept whole in a last plain solve from the current poses
        (GNC stops once its weights settle, before solving with them); ``gnc_mu_step``: the
        factor GNC's control parameter changes by per iteration (gtsam's default 1.4). Sets
        :attr:`poses` and :attr:`closure_weights`."""
        if robust not in ROBUST_KINDS:
            raise PoseGraphError(f"robust must be one of {ROBUST_KINDS}, got {robust!r}")
        if not self.keyframes:
            raise PoseGraphError("the pose graph has no keyframes")
        g = gtsam()
        self._robust = (robust, cauchy_scale)
        closures = [e for e in self.edges if e.closure]
        keep = [True] * len(closures)
        if robust == "gnc" and closures:
            graph, values, factors = self._factors(g, "none", cauchy_scale, keep)
            # from the plain solution: from the front end's poses, where the closures' residuals
            # are thousands of σ, GNC's first weights dropped true closures (a simulated loop)
            values = g.LevenbergMarquardtOptimizer(
                graph, values, g.LevenbergMarquardtParams()
            ).optimize()
            params = g.GncLMParams(g.LevenbergMarquardtParams())
            # GncParams::muStep: setLambdaStep in gtsam 4.3's wrapper, setMuStep in 4.2's
            set_mu_step = getattr(params, "setLambdaStep", None) or params.setMuStep
            set_mu_step(gnc_mu_step)
            params.setKnownInliers([k for k in range(graph.size()) if k not in set(factors)])
            optimizer = g.GncLMOptimizer(graph, values, params)
            optimizer.setInlierCostThresholdsAtProbability(0.99)
            optimizer.optimize()
            weights = np.asarray(optimizer.getWeights(), dtype=float)
            self.closure_weights = [float(weights[k]) for k in factors]
            keep = [w >= 0.5 for w in self.closure_weights]
        else:
            self.closure_weights = [1.0] * len(closures)
        graph, values, _ = self._factors(g, robust, cauchy_scale, keep)
        result = g.LevenbergMarquardtOptimizer(graph, values, g.LevenbergMarquardtParams())
        solved = result.optimize()
        out = np.array([_array(solved.atPose2(k)) for k in range(len(self.keyframes))])
        self.poses = out
        return out

    def marginals(self) -> FloatArray:
        """The keyframes' marginal covariances ``(keyframes, 3, 3)`` at the current poses
        (:attr:`poses`, the last optimisation's solution): gtsam's ``Marginals`` of the graph
        the last optimisation solved (the anchor, the front end's edges, the closures it kept:
        weight ≥ ½, those added since all; a Cauchy kernel as it had it). gtsam's convention,
        the project's: the right perturbation (x, y, θ) in the keyframe's own frame. The first
        keyframe's is the anchor's (µm, 0.1 µrad). A RuntimeError where gtsam finds the
        system indeterminate."""
        if not self.keyframes:
            raise PoseGraphError("the pose graph has no keyframes")
        g = gtsam()
        robust, cauchy_scale = self._robust
        n_closures = sum(e.closure for e in self.edges)
        keep = [w >= 0.5 for w in self.closure_weights][:n_closures]
        keep += [True] * (n_closures - len(keep))
        graph, values, _ = self._factors(
            g, "cauchy" if robust == "cauchy" else "none", cauchy_scale, keep
        )
        marginals = g.Marginals(graph, values)
        out = np.array([marginals.marginalCovariance(k) for k in range(len(self.keyframes))])
        return np.asarray(0.5 * (out + np.swapaxes(out, 1, 2)), dtype=np.float64)

    def scan_covariances(self, poses: FloatArray, marginals: FloatArray) -> FloatArray:
        """Every scan's covariance ``(scans, 3, 3)`` at its row of ``poses`` (the optimised
        trajectory), in its own frame (right perturbation): its keyframe's ``marginals`` row
        (:meth:`marginals`) carried to the scan, ``Ad(T⁻¹)·Σ_kf·Ad(T⁻¹)ᵀ + Σ_rel``, ``T`` the
        scan's pose relative to its keyframe's current pose and ``Σ_rel`` the front end's
        covariance of it (:meth:`_offset_covariance`; the keyframe's errors and the scan's
        relative to it taken as independent)."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        if len(poses) != self.scans or len(marginals) != len(self.keyframes):
            raise PoseGraphError(
                f"scan_covariances needs {self.scans} poses and {len(self.keyframes)} "
                f"marginals, got {len(poses)} and {len(marginals)}"
            )
        owner = self.owners
        a = adjoint(inverse(relative(self.poses[owner], poses)))
        out = a @ np.asarray(marginals)[owner] @ np.swapaxes(a, 1, 2)
        out += np.array(self._offset_cov).reshape(-1, 3, 3)
        return np.asarray(0.5 * (out + np.swapaxes(out, 1, 2)), dtype=np.float64)

    def _factors(
        self, g: Any, robust: str, cauchy_scale: float, keep: list[bool]
    ) -> tuple[Any, Any, list[int]]:
        """The factor graph (the anchor, every front-end edge, the closures ``keep`` says),
        the initial values (the current poses) and the closures' factor indices."""
        graph, values = g.NonlinearFactorGraph(), g.Values()
        for k, pose in enumerate(self.poses):
            values.insert(k, g.Pose2(*map(float, pose)))
        anchor = g.noiseModel.Diagonal.Sigmas(np.array(_ANCHOR_SIGMAS))
        graph.add(g.PriorFactorPose2(0, g.Pose2(*map(float, self.poses[0])), anchor))
        factors: list[int] = []
        closure = 0
        for e in self.edges:
            if e.closure:
                closure += 1
                if not keep[closure - 1]:
                    continue
            noise = g.noiseModel.Gaussian.Information(e.information)
            if e.closure and robust == "cauchy":
                noise = g.noiseModel.Robust.Create(
                    g.noiseModel.mEstimator.Cauchy.Create(cauchy_scale), noise
                )
            if e.closure:
                factors.append(graph.size())
            graph.add(g.BetweenFactorPose2(e.i, e.j, g.Pose2(*map(float, e.measured)), noise))
        return graph, values, factors

    def trajectory(self, blend: bool = False, poses: FloatArray | None = None) -> FloatArray:
        """Every scan's pose, ``(scans, 3)``: its keyframe's current pose (or its row of
        ``poses``) composed with the scan's pose relative to it (the front end's). ``blend``:
        the correction (the keyframe's pose over the front end's) blended linearly, by scan
        index, from the scan's keyframe's to the next keyframe's, so the trajectory does not
        jump where the keyframe changes."""
        if not self._owner:
            return np.zeros((0, 3))
        kf_poses = self.poses if poses is None else np.asarray(poses, dtype=float)
        if kf_poses.shape != (len(self.keyframes), 3):
            raise PoseGraphError(f"poses must be ({len(self.keyframes)}, 3), got {kf_poses.shape}")
        owner = np.array(self._owner)
        follow = compose(kf_poses[owner], np.array(self._offset))
        if not blend or len(self.keyframes) < 2:
            return follow
        front = np.array([kf.pose for kf in self.keyframes])
        correction = compose(kf_poses, inverse(front))  # world-frame: current = C ⊕ front
        scan_of = np.array([kf.scan for kf in self.keyframes])
        idx = np.arange(len(owner))
        nxt = np.minimum(owner + 1, len(self.keyframes) - 1)
        span = np.maximum(scan_of[nxt] - scan_of[owner], 1)
        f = np.where(nxt > owner, (idx - scan_of[owner]) / span, 0.0)[:, None]
        a, b = correction[owner], correction[nxt]
        dth = np.arctan2(np.sin(b[:, 2] - a[:, 2]), np.cos(b[:, 2] - a[:, 2]))
        blended = np.column_stack((a[:, :2] + f * (b[:, :2] - a[:, :2]), a[:, 2] + f[:, 0] * dth))
        out: FloatArray = compose(blended, self.frontend_trajectory())
        return out

    def frontend_trajectory(self) -> FloatArray:
        """Every scan's pose as the front end gave it."""
        return np.array(self._frontend, dtype=float).reshape(-1, 3)

    def write_g2o(self, path: str | Path) -> None:
        """The graph as a g2o file: ``VERTEX_SE2 id x y θ`` (the current poses) and ``EDGE_SE2
        i j dx dy dθ`` with the information matrix's upper triangle (I11 I12 I13 I22 I23
        I33), closures after the front end's edges as added."""
        lines = [
            f"VERTEX_SE2 {k} {p[0]:.9g} {p[1]:.9g} {p[2]:.9g}" for k, p in enumerate(self.poses)
        ]
        for e in self.edges:
            info = e.information
            upper = (info[0, 0], info[0, 1], info[0, 2], info[1, 1], info[1, 2], info[2, 2])
            m = e.measured
            lines.append(
                f"EDGE_SE2 {e.i} {e.j} {m[0]:.9g} {m[1]:.9g} {m[2]:.9g} "
                + " ".join(f"{v:.9g}" for v in upper)
            )
        Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


def _array(pose: Any) -> FloatArray:
    """A gtsam Pose2 as ``[x, y, θ]``."""
    return np.array([pose.x(), pose.y(), pose.theta()], dtype=np.float64)


def read_g2o(path: str | Path) -> tuple[FloatArray, list[Edge]]:
    """A g2o file's ``VERTEX_SE2`` poses (by id, ids 0..n-1) and ``EDGE_SE2`` edges (each with
    the covariance its information matrix gives; ``closure`` where ``j`` ≠ ``i`` + 1)."""
    path = Path(path)
    vertices: dict[int, FloatArray] = {}
    edges: list[Edge] = []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        words = line.split()
        if not words:
            continue
        try:
            if words[0] == "VERTEX_SE2" and len(words) == 5:
                vertices[int(words[1])] = np.array([float(w) for w in words[2:5]])
                continue
            if words[0] == "EDGE_SE2" and len(words) == 12:
                i, j = int(words[1]), int(words[2])
                v = [float(w) for w in words[3:]]
                u = v[3:]
                info = np.array([[u[0], u[1], u[2]], [u[1], u[3], u[4]], [u[2], u[4], u[5]]])
                edges.append(Edge(i, j, np.array(v[:3]), np.linalg.inv(info), closure=j != i + 1))
                continue
        except (ValueError, np.linalg.LinAlgError) as exc:
            raise PoseGraphError(f"{path}:{n}: {exc}") from exc
        raise PoseGraphError(f"{path}:{n}: not a VERTEX_SE2 or EDGE_SE2 line: {line[:60]!r}")
    if sorted(vertices) != list(range(len(vertices))):
        raise PoseGraphError(f"{path}: vertex ids are not 0..{len(vertices) - 1}")
    poses = np.array([vertices[k] for k in range(len(vertices))]).reshape(-1, 3)
    if not all(math.isfinite(float(x)) for x in poses.ravel()):
        raise PoseGraphError(f"{path}: a vertex is not finite")
    return poses, edges
