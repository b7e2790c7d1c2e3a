"""Loop closures: candidates gated by the graph's uncertainty, verified by matching a
keyframe's scan against a submap around the candidate, added to the pose graph and optimised
robustly (``[loop_closure]``).

A keyframe ``i`` is a candidate for the new keyframe ``j`` where it is not among the last
``recent_keyframes`` and its position relative to ``j``, under the covariance of the chain of
front-end edges between them plus ``overlap_radius``² (both see the same place from that far),
lies within the χ²(2) gate. The nearest ``max_candidates`` are verified: the scan of ``j`` is
searched (``search_start``) and refined (the front end's :class:`~fuzzypos.pipeline.Refiner`,
with the search's weak prior) against the surfaces of ``i`` and ``submap_keyframes`` either side
in ``i``'s frame, from the pose the graph predicts; the fit is accepted where enough of the part
of the scan that lies in the space the submap saw (:mod:`.overlap`) lies on the submap, the
translation is constrained both ways, and refinements from starts ``ambiguity_distance`` away
find no other answer nearly as good (a close fraction within ``ambiguity_margin`` of the fit's,
counted in shares of that part). Its covariance is the fit's M⁻¹ G M⁻¹ (the points' share of
the front end's sandwich), as a right perturbation.

Both checks are relative to what the scan can show. In a large hall seen by a scanner that
reaches tens of metres (fr-clinic) a true closure from a viewpoint metres away pairs only
30–50 % of its scan, the rest lying behind or beyond what the submap's keyframes saw, and its
far walls, sampled a beam spacing of tens of centimetres apart, put a quarter of the scan within
the Huber scale of a surface where an office scan puts half: fractions of the whole scan there
refused every revisit. (Most other candidates there had no pair at all: after a long stretch
without a closure the graph's prediction lies metres past the search; the place candidates
below find those revisits.)

Where none of those verifies, the other keyframes within the gate are ranked by their place
descriptors' likeness to ``j``'s (:mod:`.place`) and the ``place_candidates`` most alike are
verified from the descriptors' guess (the two keyframes at one point, turned by the
descriptors' best shift) with a search of ±``place_search_distance``: after a long stretch
without a closure the graph's guess is metres off, beyond the nearest candidates and the
search. Such a closure is checked as strictly, but the long chain cannot vouch for its heading
(its drift is why the gate missed it): its position must lie within the gate of the graph's
prediction under the chain's covariance and the fit's, other answers are sought as far as the
search went, and it is added only with another closure within ``recent_keyframes`` that agrees
with it over the short chains between them (pairwise consistency); GNC then weighs it with
the rest.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, replace
from statistics import NormalDist

import numpy as np
from numpy.typing import NDArray
from scipy.special import gammaincinv

from ..config import Config
from ..features import Features
from ..geometry import compose, relative, transform_points
from ..matching import Refinement, SurfacePoints, search_start, surface_points
from ..pipeline import Refiner
from ..pipeline.refine import ScanPoints
from ..pipeline.uncertainty import local
from .overlap import seen_fraction
from .place import PlaceDescriptor, PlaceIndex, place_descriptor
from .pose_graph import PoseGraph, PoseGraphError

__all__ = ["Closure", "LoopCloser"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


@dataclass(frozen=True, eq=False)
class Closure:
    """A verified loop closure: keyframe ``j``'s pose in keyframe ``i``'s frame, its covariance
    (right perturbation), the fraction of ``j``'s scan that paired with the submap, the
    Mahalanobis distance squared of the candidate gate (a place candidate's: of its measurement
    from the graph's prediction), (after optimisation) its weight, and what proposed it:
    ``"gate"`` (the candidate gate) or ``"place"`` (the place descriptor), and a place
    closure's: the keyframes ``(i, j)`` of the closure that agreed with it."""

    i: int
    j: int
    measured: FloatArray
    covariance: FloatArray
    inlier_fraction: float
    gate: float
    weight: float = 1.0
    source: str = "gate"
    agreed: tuple[int, int] | None = None


def angle_increment_of(features: Features) -> float:
    """The beam spacing (rad) of a scan, from its points' bearings and beam indices."""
    b = np.unwrap(np.arctan2(features.points[:, 1], features.points[:, 0]))
    di = np.diff(features.beam_index.astype(float))
    ok = di != 0
    if not np.any(ok):
        return math.radians(1.0)
    return float(np.median(np.abs(np.diff(b)[ok] / di[ok])))


class LoopCloser:
    """Finds, verifies and adds loop closures to a :class:`PoseGraph` whose keyframes kept
    their features (``config.loop_closure``; the refinement and search sections for the
    matching)."""

    def __init__(self, config: Config) -> None:
        self.config = config
        self.settings = config.loop_closure
        self.refiner = Refiner(config.refinement, config.search)
        self.closures: list[Closure] = []
        self.verified = 0  # candidates verified
        self._surfaces: dict[int, SurfacePoints] = {}
        self._chi2 = -2.0 * math.log(1.0 - self.settings.gate_probability)  # χ²(2) quantile
        p = self.settings.gate_probability  # χ²(1) quantile: the normal's, squared
        self._chi2_1 = NormalDist().inv_cdf(0.5 + 0.5 * p) ** 2
        # χ²(3) quantile: twice the regularised lower incomplete gamma's inverse at 3/2
        self._chi2_3 = 2.0 * float(gammaincinv(1.5, self.settings.reoptimize_probability))
        self._prefix_of: tuple[FloatArray, tuple[FloatArray, ...]] | None = None
        self._places: tuple[PoseGraph, PlaceIndex] | None = None
        #: candidates verified and refused, by the check that refused them
        self.rejections: Counter[str] = Counter()
        self._pending: list[Closure] = []  # place closures awaiting another that agrees

    def candidates(self, graph: PoseGraph, j: int) -> list[tuple[int, float]]:
        """``(i, d²)`` for every keyframe ``i`` within the gate of ``j``, nearest first, at
        most ``max_candidates``: d² the Mahalanobis distance squared of the two positions under
        the covariance of ``j`` relative to ``i`` along the chain of front-end edges between
        them (:meth:`chain_covariances`) plus ``overlap_radius``²."""
        return self.gated(graph, j)[: self.settings.max_candidates]

    def gated(self, graph: PoseGraph, j: int) -> list[tuple[int, float]]:
        """Every keyframe within the gate of ``j`` (:meth:`candidates`), nearest first."""
        last = j - self.settings.recent_keyframes
        if last < 0:
            return []
        ks = np.arange(last + 1)
        cov = self.chain_covariances(graph, j, ks)
        cov = cov + self.settings.overlap_radius**2 * np.eye(2)
        delta = graph.poses[j, :2] - graph.poses[ks, :2]
        d2 = np.einsum("ni,ni->n", delta, np.linalg.solve(cov, delta[:, :, None])[:, :, 0])
        inside = np.flatnonzero(d2 <= self._chi2)
        order = inside[np.argsort(d2[inside], kind="stable")]
        return [(int(k), float(d2[k])) for k in order]

    def chain_covariances(self, graph: PoseGraph, j: int, ks: IntArray) -> FloatArray:
        """The 2×2 world-frame covariances of keyframe ``j``'s position relative to each
        keyframe of ``ks`` (all before ``j``) from the front-end edges between them, linearised
        at the graph's poses. Edge m's right perturbation (δt, δθ) moves ``j`` by R_{m+1} δt +
        δθ J (p_j − p_{m+1}) (J the quarter turn), so the covariance is a sum over the edges
        whose terms split into prefix sums: one pass over the chain per optimisation, then a
        few array operations per keyframe."""
        c1, cu, cuq, cs, csq, csqq = self._prefix(graph)
        a = np.array([-graph.poses[j, 1], graph.poses[j, 0]])  # J p_j
        s1 = c1[j] - c1[ks]
        su = cu[j] - cu[ks]
        suq = cuq[j] - cuq[ks]
        ss = cs[j] - cs[ks]
        ssq = csq[j] - csq[ks]
        ssqq = csqq[j] - csqq[ks]
        t2 = su[:, :, None] * a[None, None, :] - suq  # Σ u (a − q)ᵀ
        t4 = (
            ss[:, None, None] * np.outer(a, a)[None]
            - a[None, :, None] * ssq[:, None, :]
            - ssq[:, :, None] * a[None, None, :]
            + ssqq
        )  # Σ σθθ (a − q)(a − q)ᵀ
        out: FloatArray = s1 + t2 + np.transpose(t2, (0, 2, 1)) + t4
        return out

    def _prefix(self, graph: PoseGraph) -> tuple[FloatArray, ...]:
        """The prefix sums over the chain's edges m < n (index n) of R Σtt Rᵀ, u = R σtθ,
        u qᵀ, σθθ, σθθ q and σθθ q qᵀ, with R, q = J p of keyframe m + 1 at the graph's poses
        (cached until the poses change)."""
        if self._prefix_of is not None and self._prefix_of[0] is graph.poses:
            return self._prefix_of[1]
        n = len(graph)
        chain = {e.i: e for e in graph.edges if not e.closure and e.j == e.i + 1}
        if len(chain) < n - 1:
            raise PoseGraphError("the pose graph's chain of front-end edges is broken")
        cov = np.array([chain[m].covariance for m in range(n - 1)]).reshape(-1, 3, 3)
        nxt = graph.poses[1:]
        c, s_ = np.cos(nxt[:, 2]), np.sin(nxt[:, 2])
        rot = np.stack((np.stack((c, -s_), -1), np.stack((s_, c), -1)), 1)  # (m, 2, 2)
        q = np.stack((-nxt[:, 1], nxt[:, 0]), 1)
        tt = rot @ cov[:, :2, :2] @ np.transpose(rot, (0, 2, 1))
        u = (rot @ cov[:, :2, 2:3])[:, :, 0]
        sig = cov[:, 2, 2]
        terms = (
            tt,
            u,
            u[:, :, None] * q[:, None, :],
            sig,
            sig[:, None] * q,
            sig[:, None, None] * q[:, :, None] * q[:, None, :],
        )
        sums = tuple(
            np.concatenate((np.zeros((1, *t.shape[1:])), np.cumsum(t, axis=0))) for t in terms
        )
        self._prefix_of = (graph.poses, sums)
        return sums

    def submap_keyframes(self, graph: PoseGraph, i: int, j: int) -> range:
        """Keyframe ``i`` and ``submap_keyframes`` either side (none among the last
        ``recent_keyframes`` before ``j``)."""
        h = self.settings.submap_keyframes
        top = min(i + h, j - self.settings.recent_keyframes, len(graph) - 1)
        return range(max(0, i - h), max(i, top) + 1)

    def submap(self, graph: PoseGraph, i: int, j: int) -> SurfacePoints:
        """The surfaces of :meth:`submap_keyframes` in ``i``'s frame at the graph's poses."""
        return self.surfaces_in_frame_of(graph, i, self.submap_keyframes(graph, i, j))

    def seen(self, graph: PoseGraph, i: int, j: int, fit: Refinement, points: ScanPoints) -> float:
        """The fraction of ``j``'s scan, at the fit's pose in ``i``'s frame, that lies in the
        space the submap's keyframes saw (:mod:`.overlap`): what could pair at all."""
        views = []
        for k in self.submap_keyframes(graph, i, j):
            f = graph.keyframes[k].features
            if f is not None:
                views.append((relative(graph.poses[i], graph.poses[k]), f.points))
        xy = transform_points(np.asarray(fit.increment, dtype=float), points.xy)
        s = self.settings
        return seen_fraction(xy, views, s.seen_margin, s.seen_beams)

    def surfaces_in_frame_of(
        self, graph: PoseGraph, i: int, keyframes: Iterable[int]
    ) -> SurfacePoints:
        """The surfaces of ``keyframes`` (those with features) in keyframe ``i``'s frame at
        the graph's poses, in one :class:`~fuzzypos.matching.SurfacePoints`."""
        xy, normal, weight = [], [], []
        for k in keyframes:
            surf = self._surface(graph, k)
            if surf is None:
                continue
            rel = relative(graph.poses[i], graph.poses[k])
            xy.append(transform_points(rel, surf.xy))
            c, s_ = math.cos(rel[2]), math.sin(rel[2])
            n = surf.normal
            normal.append(np.stack((c * n[:, 0] - s_ * n[:, 1], s_ * n[:, 0] + c * n[:, 1]), 1))
            weight.append(surf.weight)
        if not xy:
            empty = np.zeros((0, 2))
            return SurfacePoints(empty, empty, np.zeros(0))
        return SurfacePoints(np.concatenate(xy), np.concatenate(normal), np.concatenate(weight))

    def _surface(self, graph: PoseGraph, k: int) -> SurfacePoints | None:
        if k not in self._surfaces:
            f = graph.keyframes[k].features
            if f is None:
                return None
            r = self.config.refinement
            self._surfaces[k] = surface_points(f.points, f.ranges, f.uncertainty, r)
        return self._surfaces[k]

    def verify(
        self,
        graph: PoseGraph,
        i: int,
        j: int,
        gate: float = 0.0,
        predicted: FloatArray | None = None,
        start: FloatArray | None = None,
        source: str = "gate",
    ) -> Closure | None:
        """The closure between keyframes ``i`` and ``j`` where the match of ``j``'s scan
        against the submap around ``i`` is good and unambiguous (module docstring), else None
        (the check that refused it counted in :attr:`rejections`). The search starts from
        ``start`` (by default ``predicted``, ``j``'s pose in ``i``'s frame, by default the
        graph's), within ``search_distance`` (a ``"place"`` candidate's: ``place_search_distance``);
        the fit must agree with ``predicted`` in heading, a place candidate's in position too."""
        s = self.settings
        features = graph.keyframes[j].features
        if features is None:
            return None
        points = self.refiner.points(features, angle_increment_of(features))
        surface = self.submap(graph, i, j)
        if points is None or len(surface) < 3:
            return None
        self.verified += 1
        if predicted is None:
            predicted = relative(graph.poses[i], graph.poses[j])
        place = source == "place"
        hit = search_start(
            surface, points.xy, predicted if start is None else start, self.config.search,
            half_width=s.search_angle,
            translation_half_width=s.place_search_distance if place else s.search_distance,
        )  # fmt: skip
        fit = self._fit(surface, points, hit.start)
        reach = s.place_search_distance if place else s.ambiguity_distance
        refusal = self._refusal(
            graph, i, j, fit, None if place else predicted, surface, points, reach
        )
        if refusal is None and place and fit is not None:
            gate = self._position_distance(graph, i, j, fit, predicted)
            refusal = "position" if gate > self._chi2 else None
        if refusal is not None or fit is None:
            self.rejections[refusal or "no fit"] += 1
            return None
        return Closure(
            i, j, fit.increment, self._covariance(fit), fit.inlier_fraction, gate, source=source
        )

    def _refusal(
        self,
        graph: PoseGraph,
        i: int,
        j: int,
        fit: Refinement | None,
        predicted: FloatArray | None,
        surface: SurfacePoints,
        points: ScanPoints,
        reach: float,
    ) -> str | None:
        """Why the fit is no closure (``"no fit"``, ``"inliers"``, ``"heading"``,
        ``"corridor"``, ``"ambiguous"``: other answers sought as far as ``reach``), or None;
        the heading is checked against ``predicted`` where given."""
        if fit is None:
            return "no fit"
        seen = self.seen(graph, i, j, fit, points)
        if fit.inlier_fraction < self.settings.min_inlier_fraction * seen:
            return "inliers"
        if predicted is not None and not self._heading_agrees(
            graph, i, j, fit.increment, predicted
        ):
            return "heading"
        if not self._constrained(fit):
            return "corridor"
        if self._ambiguous(surface, points, fit, reach, seen):
            return "ambiguous"
        return None

    def _position_distance(
        self, graph: PoseGraph, i: int, j: int, fit: Refinement, predicted: FloatArray
    ) -> float:
        """The Mahalanobis distance squared of the fit's position of ``j`` from the predicted
        one, under the chain's covariance of ``j`` relative to ``i`` plus the fit's own (world
        frame): a place candidate's closure must be one the chain's drift allows."""
        lo, hi = min(i, j), max(i, j)
        cov = self.chain_covariances(graph, hi, np.array([lo]))[0]
        th = float(graph.poses[i, 2])
        c, s_ = math.cos(th), math.sin(th)
        rot = np.array([[c, -s_], [s_, c]])
        cj, sj = math.cos(th + float(fit.increment[2])), math.sin(th + float(fit.increment[2]))
        rot_j = np.array([[cj, -sj], [sj, cj]])
        cov = cov + rot_j @ self._covariance(fit)[:2, :2] @ rot_j.T
        d = rot @ (np.asarray(fit.increment[:2], dtype=float) - predicted[:2])
        return float(d @ np.linalg.solve(cov, d))

    def place_of(self, graph: PoseGraph, k: int) -> PlaceDescriptor:
        """Keyframe ``k``'s place descriptor: the points of its scan and of the
        ``place_keyframes`` before it, in its frame at the front end's poses."""
        s = self.settings
        pts = []
        for m in range(max(0, k - s.place_keyframes), k + 1):
            f = graph.keyframes[m].features
            if f is not None:
                rel = relative(graph.keyframes[k].pose, graph.keyframes[m].pose)
                pts.append(transform_points(rel, f.points))
        xy = np.concatenate(pts) if pts else np.zeros((0, 2))
        return place_descriptor(xy, s.place_rings, s.place_sectors, s.place_range)

    def place_candidates(
        self, graph: PoseGraph, j: int, among: list[int], tried: list[int]
    ) -> list[tuple[int, float, float]]:
        """``(i, distance, heading)`` for the keyframes of ``among`` whose places look most
        like ``j``'s: at most ``place_candidates``, none within ``submap_keyframes`` of another
        or of ``tried``; ``heading`` is ``j``'s in ``i``'s frame by the descriptors' best
        shift."""
        s = self.settings
        if not among or not s.place_recognition:
            return []
        if (
            self._places is None
            or self._places[0] is not graph
            or len(self._places[1]) > len(graph)
        ):
            self._places = (graph, PlaceIndex([self.place_of(graph, 0)]))
        index = self._places[1]
        for k in range(len(index), len(graph)):  # a keyframe's descriptor is made once
            index.append(self.place_of(graph, k))
        ks = np.array(among, dtype=np.intp)
        distance, heading = index.compare(index.descriptors[j], ks, s.place_min_overlap)
        out: list[tuple[int, float, float]] = []
        taken = list(tried)
        for n in np.argsort(distance, kind="stable"):
            k = int(ks[n])
            if distance[n] >= 1.0 or len(out) >= s.place_candidates:
                break
            if any(abs(k - t) <= s.submap_keyframes for t in taken):
                continue
            out.append((k, float(distance[n]), float(heading[n])))
            taken.append(k)
        return out

    def _fit(
        self, surface: SurfacePoints, points: ScanPoints, start: FloatArray
    ) -> Refinement | None:
        r = self.config.refinement
        return self.refiner.fit(
            surface, points, start, start, start, max_distance=r.max_distance, weak_prior=True
        )

    def _heading_agrees(
        self, graph: PoseGraph, i: int, j: int, measured: FloatArray, predicted: FloatArray
    ) -> bool:
        """Whether the fit's heading lies within the χ²(1) gate of the predicted one under the
        chain's heading variance between ``i`` and ``j`` plus ``heading_floor``²."""
        cs = self._prefix(graph)[3]
        lo, hi = min(i, j), max(i, j)
        variance = float(cs[hi] - cs[lo]) + self.settings.heading_floor**2
        d = math.remainder(float(measured[2]) - float(predicted[2]), math.tau)
        return d * d <= self._chi2_1 * variance

    def _constrained(self, fit: Refinement) -> bool:
        """Whether the points fix the translation both ways (not a corridor)."""
        w = np.linalg.eigvalsh(fit.information[:2, :2])
        return bool(w[-1] > 0.0 and w[0] >= self.settings.min_constraint_ratio * w[-1])

    def _ambiguous(
        self,
        surface: SurfacePoints,
        points: ScanPoints,
        fit: Refinement,
        reach: float,
        seen: float = 1.0,
    ) -> bool:
        """Whether a refinement from a start ``ambiguity_distance`` away on either axis (and
        twice, four times … that, up to ``reach``) ends elsewhere with nearly as good a close
        fraction: within ``ambiguity_margin`` of the part of the scan the submap saw
        (``seen``, :meth:`seen`), as the inlier fraction is asked of it."""
        s = self.settings
        x = np.asarray(fit.increment, dtype=float)
        steps = [s.ambiguity_distance]
        while steps[-1] * 2.0 <= reach:
            steps.append(steps[-1] * 2.0)
        for step, (dx, dy) in ((a, d) for a in steps for d in ((1, 0), (-1, 0), (0, 1), (0, -1))):
            start = x + np.array([dx, dy, 0.0]) * step
            other = self._fit(surface, points, start)
            if other is None:
                continue
            if math.dist(other.increment[:2], x[:2]) <= s.agree_distance:
                continue
            if other.close_fraction >= fit.close_fraction - s.ambiguity_margin * seen:
                return True
        return False

    def _covariance(self, fit: Refinement) -> FloatArray:
        """M⁻¹ G M⁻¹ of the fit (additive, keyframe i's frame) as a right perturbation."""
        m = fit.information + fit.prior_information + fit.hold_information
        m_inv = np.linalg.inv(m + 1e-12 * np.eye(3))
        g = self.config.covariance.point_correlation * fit.gradient_covariance
        cov = m_inv @ g @ m_inv
        s = self.settings  # the floors: what a closure is at best (the config's reasons)
        floor = np.diag([s.closure_floor_translation**2] * 2 + [s.closure_floor_rotation**2])
        out: FloatArray = local(0.5 * (cov + cov.T), float(fit.increment[2])) + floor
        return out

    def close(self, graph: PoseGraph, j: int) -> Closure | None:
        """The first verified closure of keyframe ``j``, added to the graph (not yet
        optimised), or None: the gate's candidates first, then the place candidates, searched
        from the descriptors' guess (the graph's may be metres off)."""
        gated = self.gated(graph, j)
        tried = []
        for i, d2 in gated[: self.settings.max_candidates]:
            tried.append(i)
            found = self.verify(graph, i, j, d2)
            if found is not None:
                return self._add(graph, found)
        among = [i for i, _ in gated[self.settings.max_candidates :]]
        for i, _, heading in self.place_candidates(graph, j, among, tried):
            start = np.array([0.0, 0.0, heading])
            found = self.verify(graph, i, j, start=start, source="place")
            if found is not None:
                return self._corroborated(graph, found)
        return None

    def _corroborated(self, graph: PoseGraph, found: Closure) -> Closure | None:
        """A place closure is added (with the pending one that agrees) where it agrees with a
        closure both of whose keyframes lie within ``recent_keyframes`` of its own
        (:meth:`agree`), else held back: the long chain cannot check its heading (its drift is
        why the gate missed it), two closures over short chains can (over a long one the check
        is as loose as the chain: a closure 6 m off agreed with a true one 100 keyframes
        away), and one false match rarely has a consistent twin."""
        w = self.settings.recent_keyframes
        near = [c for c in self.closures if found.j - c.j <= w]
        pending = [c for c in self._pending if found.j - c.j <= w]
        self._pending = [*pending, found]
        short = [c for c in [*pending, *near] if abs(found.i - c.i) <= w]
        match = next((c for c in short if self.agree(graph, c, found)), None)
        if match is None:
            self.rejections["uncorroborated"] += 1
            return None
        if match in pending:
            self._pending.remove(match)
            self._add(graph, replace(match, agreed=(found.i, found.j)))
        self._pending.remove(found)
        return self._add(graph, replace(found, agreed=(match.i, match.j)))

    def agree(self, graph: PoseGraph, a: Closure, b: Closure) -> bool:
        """Whether two closures agree: ``b``'s measurement against ``a``'s carried along the
        front end's short chains ``a.i → b.i`` and ``a.j → b.j``, within the χ²(2) gate in
        position and the χ²(1) gate in heading under both chains' and both closures'
        covariances."""
        kf = graph.keyframes
        expected = compose(
            compose(relative(kf[b.i].pose, kf[a.i].pose), a.measured),
            relative(kf[a.j].pose, kf[b.j].pose),
        )
        e = relative(expected, b.measured)  # in b.j's frame (as it is predicted)
        pos, head = np.zeros((2, 2)), 0.0
        cs = self._prefix(graph)[3]
        for lo, hi in sorted((a.i, b.i)), sorted((a.j, b.j)):
            if hi > lo:
                pos += self.chain_covariances(graph, hi, np.array([lo]))[0]
                head += float(cs[hi] - cs[lo])
        th = float(graph.poses[b.j, 2])
        c, s_ = math.cos(th), math.sin(th)
        rot = np.array([[c, -s_], [s_, c]])
        for x, at in ((a, a.j), (b, b.j)):
            ca, sa = math.cos(graph.poses[at, 2]), math.sin(graph.poses[at, 2])
            ra = np.array([[ca, -sa], [sa, ca]])
            pos += ra @ x.covariance[:2, :2] @ ra.T
            head += float(x.covariance[2, 2])
        d = rot @ e[:2]
        d2 = float(d @ np.linalg.solve(pos, d))
        return d2 <= self._chi2 and float(e[2]) ** 2 <= self._chi2_1 * head

    def disagrees(self, graph: PoseGraph, found: Closure) -> bool:
        """Whether ``found``'s measurement lies beyond the χ²(3) quantile of
        ``reoptimize_probability`` from the graph's prediction of it, under the closure's own
        covariance (both in keyframe ``j``'s frame): where the graph must be optimised again
        before the next keyframes are predicted from it."""
        prediction = relative(graph.poses[found.i], graph.poses[found.j])
        off = relative(prediction, found.measured)
        off[2] = math.remainder(float(off[2]), math.tau)
        return float(off @ np.linalg.solve(found.covariance, off)) > self._chi2_3

    def _add(self, graph: PoseGraph, found: Closure) -> Closure:
        graph.add_closure(found.i, found.j, found.measured, found.covariance)
        self.closures.append(found)
        return found

    def run(self, graph: PoseGraph) -> list[Closure]:
        """Every keyframe in turn: close its loop where it can, the graph optimised after a
        closure that disagrees with it (:meth:`disagrees`: the next keyframes' predictions start
        from the corrected poses) and at the end. The closures
        with their final weights."""
        s = self.settings
        for j in range(len(graph)):
            found = self.close(graph, j)
            if found is None:
                continue
            if self.disagrees(graph, found):
                graph.optimize(s.robust, gnc_mu_step=s.gnc_mu_step)
        if self.closures:
            graph.optimize(s.robust, gnc_mu_step=s.gnc_mu_step)
        mine = [e for e in graph.edges if e.closure]
        weights = dict(zip(((e.i, e.j) for e in mine), graph.closure_weights))
        self.closures = [replace(c, weight=weights.get((c.i, c.j), 1.0)) for c in self.closures]
        return self.closures
