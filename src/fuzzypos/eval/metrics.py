"""Scoring trajectories against ground truth.

Pure, vectorised functions over ``(n, 3)`` pose arrays ``[x, y, θ]`` (θ in radians); a
sequence of :class:`~fuzzypos.geometry.Pose2D` (e.g. ``[est.pose for est in estimates]``) is
taken wherever such an array is. Anything else raises :class:`EvaluationError`.

- :func:`position_errors`, :func:`trajectory_errors`: pose by pose, the same scans in both.
- :func:`relations_errors`: the relations metric of the Freiburg SLAM benchmark (Kümmerle et
  al., "On measuring the accuracy of SLAM algorithms", 2009), exactly as the shared data's
  README (the shared data's ``README.md``, "How to score a trajectory") defines it.
- :func:`absolute_trajectory_error` (ATE) and :func:`relative_pose_error` (RPE), defined to
  agree with ``evo_ape``/``evo_rpe`` (evo 1.38) on planar trajectories; the exceptions are
  listed in each docstring.

Every error summary is a frozen dataclass with ``as_dict()`` (flat, scalars only). Units are
in the names: ``_m`` metres, ``_deg`` degrees, ``_s`` seconds.

Matching by timestamp. A pose at time ``t`` is the pose whose stamp is nearest ``t``, whatever
the order of the stamps (intel's go backwards in file order): the stamps are sorted once and
searched with :func:`numpy.searchsorted`. When two stamps are equally near, the earlier wins;
among equal (duplicate) stamps, the first in the given order wins. A match further than
``max_stamp_gap`` seconds is refused.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import FuzzyposError
from ..geometry import Pose2D, compose, relative, rotation_matrix, wrap_angle
from ..io.relations import Relations

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
#: poses as an ``(n, 3)`` array ``[x, y, θ]`` or a sequence of :class:`Pose2D`
Poses = ArrayLike | Sequence[Pose2D]

__all__ = [
    "DEFAULT_ASSOCIATION_GAP",
    "DEFAULT_RELATIONS_GAP",
    "AbsoluteTrajectoryError",
    "ErrorStatistics",
    "EvaluationError",
    "RelationsErrors",
    "RelationsScore",
    "RelativePoseError",
    "TrajectoryErrors",
    "absolute_trajectory_error",
    "align_se2",
    "associate",
    "distance_along",
    "nearest_stamps",
    "position_errors",
    "relations_errors",
    "relative_pose_error",
    "trajectory_errors",
]

#: Default ``max_stamp_gap`` (s) of :func:`relations_errors`. On the shared logs every relation
#: stamp equals a scan stamp exactly (gap 0); a trajectory written with at least 4 decimals
#: stays within 5e-5 s. It is far below the spacing of the scans (aces: at least 0.07 s apart;
#: intel: 1 pair of its 13,631 scans closer than 1e-4 s, but 1,479 closer than 1 ms and 4,038
#: closer than 10 ms), so a trajectory that lacks a scan leaves that relation unmatched instead
#: of silently scoring a neighbouring scan's pose.
DEFAULT_RELATIONS_GAP = 1e-4

#: Default ``max_stamp_gap`` (s) of :func:`associate`, ATE and RPE: evo's ``--t_max_diff``.
DEFAULT_ASSOCIATION_GAP = 0.01


class EvaluationError(FuzzyposError, ValueError):
    """Trajectories that cannot be compared (shapes, lengths, non-finite values)."""


def _poses(name: str, a: Poses) -> FloatArray:
    """``a`` as an ``(n, 3)`` float array: an array-like of poses or a sequence of Pose2D."""
    if isinstance(a, Pose2D):
        raise EvaluationError(f"{name} must be a sequence of poses, got a single Pose2D")
    if isinstance(a, (list, tuple)) and any(isinstance(p, Pose2D) for p in a):
        a = [p.as_array() if isinstance(p, Pose2D) else p for p in a]
    try:
        arr = np.asarray(a, dtype=float)
    except (TypeError, ValueError) as exc:
        raise EvaluationError(
            f"{name} must be an (n, 3) array of poses (x, y, θ) or a sequence of Pose2D, got "
            f"{type(a).__name__} ({' '.join(str(exc).split())})"
        ) from None
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise EvaluationError(f"{name} must be an (n, 3) array of poses, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise EvaluationError(f"{name} holds non-finite values")
    return arr


def distance_along(poses: Poses) -> FloatArray:
    """Cumulative distance travelled along a path, (n,), starting at 0."""
    p = _poses("poses", poses)
    steps = np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1]))
    return np.concatenate([[0.0], np.cumsum(steps)])


def position_errors(truth: Poses, estimate: Poses) -> tuple[FloatArray, FloatArray]:
    """Per pose: the position error (m) and the absolute heading error (rad)."""
    t = _poses("truth", truth)
    e = _poses("estimate", estimate)
    if t.shape != e.shape:
        raise EvaluationError(f"truth has {t.shape[0]} poses, estimate {e.shape[0]}")
    d = np.hypot(t[:, 0] - e[:, 0], t[:, 1] - e[:, 1])
    h = np.abs(wrap_angle(t[:, 2] - e[:, 2]))
    return d, h


@dataclass(frozen=True)
class TrajectoryErrors:
    """Summary of an estimated trajectory against the truth (metres and degrees)."""

    final_position_error_m: float
    mean_position_error_m: float
    max_position_error_m: float
    mean_heading_error_deg: float
    scans_degraded: int = 0

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def trajectory_errors(truth: Poses, estimate: Poses, scans_degraded: int = 0) -> TrajectoryErrors:
    """Final, mean and maximum position error and mean heading error of ``estimate``."""
    d, h = position_errors(truth, estimate)
    if d.size == 0:
        raise EvaluationError("no poses to compare")
    return TrajectoryErrors(
        final_position_error_m=float(d[-1]),
        mean_position_error_m=float(d.mean()),
        max_position_error_m=float(d.max()),
        mean_heading_error_deg=float(np.degrees(h.mean())),
        scans_degraded=int(scans_degraded),
    )


# -- statistics ----------------------------------------------------------------------------
@dataclass(frozen=True)
class ErrorStatistics:
    """Summary of a set of non-negative errors, in the unit its owner's field name gives.

    ``std`` is the population standard deviation (``ddof=0``, as evo and the benchmark's
    README); ``rmse = sqrt(mean(e²))``. With ``count == 0`` every statistic is NaN.
    """

    count: int
    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float

    @classmethod
    def of(cls, errors: ArrayLike) -> ErrorStatistics:
        e = np.asarray(errors, dtype=float).reshape(-1)
        if e.size == 0:
            nan = float("nan")
            return cls(0, nan, nan, nan, nan, nan, nan)
        return cls(
            count=int(e.size),
            rmse=float(np.sqrt(np.mean(e * e))),
            mean=float(e.mean()),
            median=float(np.median(e)),
            std=float(e.std()),
            min=float(e.min()),
            max=float(e.max()),
        )

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def _flat(prefix: str, unit: str, st: ErrorStatistics) -> dict[str, float]:
    d = st.as_dict()
    d.pop("count")
    return {f"{prefix}_{k}_{unit}": float(v) for k, v in d.items()}


# -- matching by timestamp -----------------------------------------------------------------
def _stamps(name: str, a: ArrayLike, n: int | None = None) -> FloatArray:
    try:
        arr = np.asarray(a, dtype=float)
    except (TypeError, ValueError) as exc:
        raise EvaluationError(
            f"{name} must be an (n,) array of timestamps, got {type(a).__name__} "
            f"({' '.join(str(exc).split())})"
        ) from None
    if arr.ndim != 1:
        raise EvaluationError(f"{name} must be an (n,) array of timestamps, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise EvaluationError(f"{name} holds non-finite values")
    if n is not None and arr.shape[0] != n:
        raise EvaluationError(f"got {arr.shape[0]} {name} for {n} poses")
    return arr


def _gap(max_stamp_gap: float) -> float:
    g = float(max_stamp_gap)
    if not g >= 0.0:  # also refuses NaN
        raise EvaluationError(f"max_stamp_gap must be >= 0 s, got {max_stamp_gap!r}")
    return g


def nearest_stamps(stamps: ArrayLike, t: ArrayLike) -> tuple[IntArray, FloatArray]:
    """For each time in ``t``, the index into ``stamps`` of the nearest stamp and ``|gap|`` (s).

    ``stamps`` need not be sorted. Equally near stamps: the earlier wins; duplicate stamps:
    the first in ``stamps``' order wins. Vectorised: one stable sort, then
    :func:`numpy.searchsorted`.
    """
    s_all = _stamps("stamps", stamps)
    q = np.asarray(t, dtype=float)
    if s_all.size == 0:
        raise EvaluationError("no stamps to match against")
    order = np.argsort(s_all, kind="stable")
    s = s_all[order]
    i = np.searchsorted(s, q, side="left")  # s[i-1] < q <= s[i]
    hi = np.minimum(i, s.size - 1)
    lo = np.maximum(i - 1, 0)
    j = np.where(np.abs(q - s[lo]) <= np.abs(s[hi] - q), lo, hi)
    j = np.searchsorted(s, s[j], side="left")  # the first of equal stamps (stable order)
    return order[j], np.abs(s[j] - q)


def associate(
    ref_stamps: ArrayLike,
    est_stamps: ArrayLike,
    *,
    max_stamp_gap: float = DEFAULT_ASSOCIATION_GAP,
) -> tuple[IntArray, IntArray]:
    """Pair a reference and an estimate by timestamp, as ``evo.core.sync.associate_trajectories``
    (nearest-time method) does: ``(ref_index, est_index)``, equal lengths.

    The trajectory with fewer poses drives (the estimate when both have as many): each of its
    poses, in its own order, is paired with the nearest-stamp pose of the other
    (:func:`nearest_stamps`) when that is at most ``max_stamp_gap`` s away, else dropped. A
    pose of the longer one may serve several pairs. The pairs keep the driving trajectory's
    order, which is what RPE's "consecutive" means. (evo, for sorted stamps, takes the *last*
    of duplicate stamps; here the first.)
    """
    rs = _stamps("ref_stamps", ref_stamps)
    es = _stamps("est_stamps", est_stamps)
    gap = _gap(max_stamp_gap)
    if rs.size == 0 or es.size == 0:
        raise EvaluationError("no poses to associate")
    if es.size <= rs.size:
        drive = np.arange(es.size)
        other, d = nearest_stamps(rs, es)
        ok = d <= gap
        ri, ei = other[ok], drive[ok]
    else:
        drive = np.arange(rs.size)
        other, d = nearest_stamps(es, rs)
        ok = d <= gap
        ri, ei = drive[ok], other[ok]
    if ri.size == 0:
        raise EvaluationError(
            f"no reference and estimated stamps within {gap:g} s of each other "
            f"(nearest {d.min():.6g} s apart)"
        )
    return ri.astype(np.intp), ei.astype(np.intp)


# -- the relations metric ------------------------------------------------------------------
@dataclass(frozen=True)
class RelationsScore:
    """The relations metric over one group of relations ("all" or "local"): ``matched``
    relations scored, their translational errors (m) and rotational errors (degrees)."""

    matched: int
    translation_m: ErrorStatistics
    rotation_deg: ErrorStatistics

    def format(self) -> str:
        """As the data README prints scores, with medians: ``mean ± std m / mean ± std°``."""
        t, r = self.translation_m, self.rotation_deg
        return (
            f"{t.mean:.3f} ± {t.std:.3f} m / {r.mean:.2f} ± {r.std:.2f}° "
            f"(median {t.median:.3f} m / {r.median:.2f}°, {self.matched} relations)"
        )

    def as_dict(self, prefix: str = "") -> dict[str, float | int]:
        p = f"{prefix}_" if prefix else ""
        return {
            f"{p}matched": self.matched,
            **_flat(f"{p}trans", "m", self.translation_m),
            **_flat(f"{p}rot", "deg", self.rotation_deg),
        }


@dataclass(frozen=True, eq=False)
class RelationsErrors:
    """A trajectory scored against the benchmark's relations (:func:`relations_errors`).

    ``all`` and ``local`` summarise the matched relations, all of them and those with
    ``t2 − t1 <= local_max_dt_s``. ``unmatched`` (``unmatched_local``) relations had no scan
    stamp within ``max_stamp_gap_s`` at ``t1`` or ``t2`` and count in no statistic.

    Per relation, in the relations' order (length ``relations``): ``translation_errors_m``,
    ``rotation_errors_deg`` (NaN where unmatched), ``is_matched``, ``is_local``, ``index1``
    and ``index2`` (the poses used at ``t1`` and ``t2``, even where unmatched) and
    ``stamp_gap_s`` (the larger of the two stamp gaps).
    """

    all: RelationsScore
    local: RelationsScore
    relations: int
    unmatched: int
    unmatched_local: int
    local_max_dt_s: float
    max_stamp_gap_s: float
    translation_errors_m: FloatArray
    rotation_errors_deg: FloatArray
    is_matched: NDArray[np.bool_]
    is_local: NDArray[np.bool_]
    index1: IntArray
    index2: IntArray
    stamp_gap_s: FloatArray

    def format(self) -> str:
        """Two lines, "all" and "local", as :meth:`RelationsScore.format`."""
        miss = f", {self.unmatched} unmatched" if self.unmatched else ""
        return (
            f"all   {self.all.format()}{miss}\n"
            f"local {self.local.format()} (t2 - t1 <= {self.local_max_dt_s:g} s)"
        )

    def as_dict(self) -> dict[str, float | int]:
        """Scalars only: ``all_matched``, ``all_trans_mean_m``, …, ``local_rot_std_deg``, …"""
        return {
            "relations": self.relations,
            "unmatched": self.unmatched,
            "unmatched_local": self.unmatched_local,
            "local_max_dt_s": self.local_max_dt_s,
            "max_stamp_gap_s": self.max_stamp_gap_s,
            **self.all.as_dict("all"),
            **self.local.as_dict("local"),
        }


def relations_errors(
    stamps: ArrayLike,
    poses: Poses,
    relations: Relations,
    *,
    local_max_dt: float = 10.0,
    max_stamp_gap: float = DEFAULT_RELATIONS_GAP,
) -> RelationsErrors:
    """Score a trajectory against the benchmark's relations, as the data README defines it.

    ``stamps`` ``(n,)`` and ``poses`` ``(n, 3)``: the estimated pose of each scan and the
    scan's timestamp (full precision), in any order. ``relations``: from
    :func:`fuzzypos.io.relations.read_relations`. For each relation ``(t1, t2, ref)``:

    1. ``p1``, ``p2`` = the estimated poses of the scans whose timestamps are nearest ``t1``
       and ``t2`` (:func:`nearest_stamps`: nearest in time regardless of order; equally near:
       the earlier; duplicate stamps: the first given). If either is more than
       ``max_stamp_gap`` s away (default :data:`DEFAULT_RELATIONS_GAP`, 1e-4 s) the relation
       is unmatched: counted, not scored;
    2. estimated motion ``est = ⊖p1 ⊕ p2``; error ``e = ⊖ref ⊕ est``;
    3. translational error ``|(e.x, e.y)|`` (m), rotational error ``|e.θ|`` (θ wrapped to
       ``[-π, π)``; reported in degrees).

    Statistics over all matched relations and over the local ones (``t2 − t1 <=
    local_max_dt``, 10 s; signed, so intel's 6 relations with ``t2 < t1`` are local): mean,
    population standard deviation (``ddof=0``), median, RMSE, min, max. On the shared logs,
    raw odometry (each FLASER's odometry fields at ``scan.stamp``) scores what the README
    prints (intel all 7.37 ± 14.35 m / 39.2 ± 53.8°, local 0.024 ± 0.023 m / 1.50 ± 1.24°;
    aces all 0.55 ± 2.67 m / 2.33 ± 6.50°, local 0.037 ± 0.040 m / 0.87 ± 1.15°), all 2,984
    and 1,279 relations matched with stamp gap 0, except that intel's local translation mean
    is 0.02346 m, which the README rounds to 0.024. Raises :class:`EvaluationError` for
    malformed input, no relations, or no relation matched.
    """
    p = _poses("poses", poses)
    st = _stamps("stamps", stamps, p.shape[0])
    if not isinstance(relations, Relations):
        raise EvaluationError(
            f"relations must be a fuzzypos.io.relations.Relations, got {type(relations).__name__}"
        )
    gap = _gap(max_stamp_gap)
    max_dt = float(local_max_dt)
    if np.isnan(max_dt):
        raise EvaluationError("local_max_dt must be a number of seconds, got NaN")
    if p.shape[0] == 0:
        raise EvaluationError("no poses to score")
    if len(relations) == 0:
        raise EvaluationError("no relations to score against")

    i1, g1 = nearest_stamps(st, relations.t1)
    i2, g2 = nearest_stamps(st, relations.t2)
    gaps = np.maximum(g1, g2)
    matched = gaps <= gap
    if not matched.any():
        raise EvaluationError(
            f"no relation matched: the nearest scan stamps are at least {gaps.min():.6g} s from "
            f"the relations' t1/t2 (max_stamp_gap {gap:g} s); are stamps and relations from "
            "the same log?"
        )
    est = relative(p[i1], p[i2])
    err = relative(relations.motion, est)
    trans = np.hypot(err[:, 0], err[:, 1])
    rot = np.degrees(np.abs(err[:, 2]))
    trans[~matched] = np.nan
    rot[~matched] = np.nan
    local = relations.is_local(max_dt)

    def score(mask: NDArray[np.bool_]) -> RelationsScore:
        m = mask & matched
        return RelationsScore(
            int(m.sum()), ErrorStatistics.of(trans[m]), ErrorStatistics.of(rot[m])
        )

    for a in (trans, rot, matched, local, i1, i2, gaps):
        a.setflags(write=False)
    return RelationsErrors(
        all=score(np.ones_like(matched)),
        local=score(local),
        relations=len(relations),
        unmatched=int((~matched).sum()),
        unmatched_local=int((~matched & local).sum()),
        local_max_dt_s=max_dt,
        max_stamp_gap_s=gap,
        translation_errors_m=trans,
        rotation_errors_deg=rot,
        is_matched=matched,
        is_local=local,
        index1=i1,
        index2=i2,
        stamp_gap_s=gaps,
    )


# -- ATE -----------------------------------------------------------------------------------
def align_se2(source: ArrayLike, target: ArrayLike) -> FloatArray:
    """The rigid motion ``T = (x, y, θ)`` minimising ``Σ |R(θ) s_i + (x, y) − t_i|²`` over
    point pairs ``source``, ``target`` ``(n, 2)`` (or ``(n, 3)`` poses, whose θ is ignored).

    Umeyama/Kabsch without scale in closed form: with centred points ``s'``, ``t'``,
    ``θ = atan2(Σ s' × t', Σ s' · t')`` and ``(x, y) = mean(t) − R(θ) mean(s)``. Always a
    rotation (never a reflection). Degenerate sets (one distinct point) get ``θ = 0``, which
    is then as good as any other.
    """
    s = np.asarray(source, dtype=float)
    t = np.asarray(target, dtype=float)
    if s.ndim != 2 or s.shape[1] not in (2, 3) or t.shape[:1] != s.shape[:1] or t.ndim != 2:
        raise EvaluationError(f"cannot align points of shapes {s.shape} and {t.shape}")
    if s.shape[0] == 0:
        raise EvaluationError("no points to align")
    s, t = s[:, :2], t[:, :2]
    ms, mt = s.mean(axis=0), t.mean(axis=0)
    sc, tc = s - ms, t - mt
    cross = float(np.sum(sc[:, 0] * tc[:, 1] - sc[:, 1] * tc[:, 0]))
    dot = float(np.sum(sc[:, 0] * tc[:, 0] + sc[:, 1] * tc[:, 1]))
    theta = float(np.arctan2(cross, dot)) if (cross or dot) else 0.0
    xy = mt - rotation_matrix(theta) @ ms
    return np.array([xy[0], xy[1], float(wrap_angle(theta))])


@dataclass(frozen=True, eq=False)
class AbsoluteTrajectoryError:
    """ATE (:func:`absolute_trajectory_error`): position errors (m) and heading errors
    (degrees) of the estimate after alignment, over ``matched`` associated pose pairs.

    ``alignment`` ``(x, y, θ)`` is the motion applied to the estimate
    (``aligned = alignment ⊕ est``; identity without alignment). Per pair:
    ``translation_errors_m``, ``rotation_errors_deg``, ``ref_index``, ``est_index``."""

    translation_m: ErrorStatistics
    rotation_deg: ErrorStatistics
    matched: int
    aligned: bool
    alignment: FloatArray
    translation_errors_m: FloatArray
    rotation_errors_deg: FloatArray
    ref_index: IntArray
    est_index: IntArray

    @property
    def rmse_m(self) -> float:
        """The ATE: RMSE of the aligned positions (m)."""
        return self.translation_m.rmse

    def as_dict(self) -> dict[str, float | int | bool]:
        return {
            "matched": self.matched,
            "aligned": self.aligned,
            "alignment_x_m": float(self.alignment[0]),
            "alignment_y_m": float(self.alignment[1]),
            "alignment_theta_deg": float(np.degrees(self.alignment[2])),
            **_flat("trans", "m", self.translation_m),
            **_flat("rot", "deg", self.rotation_deg),
        }


def absolute_trajectory_error(
    ref_stamps: ArrayLike,
    ref_poses: Poses,
    est_stamps: ArrayLike,
    est_poses: Poses,
    *,
    align: bool = True,
    max_stamp_gap: float = DEFAULT_ASSOCIATION_GAP,
) -> AbsoluteTrajectoryError:
    """ATE: the RMSE of the estimated positions after a rigid SE(2) alignment to the reference.

    1. Associate poses by nearest timestamp within ``max_stamp_gap`` s (:func:`associate`,
       evo's ``--t_max_diff``, default 0.01 s).
    2. With ``align`` (default), move the estimate by the rigid motion (no scale) that best
       fits its associated positions to the reference's in least squares (:func:`align_se2`).
    3. Per pair, translational error ``|p_est − p_ref|`` (m) and rotational error
       ``|wrap(θ_ref − θ_est)|`` (degrees).

    This is ``evo_ape tum ref.tum est.tum --align`` (``-r trans_part``, the default; ``-r
    angle_deg`` for the rotation), and :class:`evo.core.metrics.APE` after
    ``associate_trajectories`` and ``traj_est.align(traj_ref)``, for planar trajectories with
    two exceptions: evo aligns in 3D, so where a mirror image fits the estimate better than
    any rotation, it turns the plane over (a reflection within it) while this stays in
    SE(2); and evo refuses collinear positions (rank-deficient covariance) which are fine in
    2D.
    """
    rp = _poses("ref_poses", ref_poses)
    ep = _poses("est_poses", est_poses)
    rs = _stamps("ref_stamps", ref_stamps, rp.shape[0])
    es = _stamps("est_stamps", est_stamps, ep.shape[0])
    ri, ei = associate(rs, es, max_stamp_gap=max_stamp_gap)
    ref, est = rp[ri], ep[ei]
    T = align_se2(est, ref) if align else np.zeros(3)
    aligned = compose(T, est)
    trans = np.hypot(aligned[:, 0] - ref[:, 0], aligned[:, 1] - ref[:, 1])
    rot = np.degrees(np.abs(wrap_angle(ref[:, 2] - aligned[:, 2])))
    for a in (trans, rot, ri, ei, T):
        a.setflags(write=False)
    return AbsoluteTrajectoryError(
        translation_m=ErrorStatistics.of(trans),
        rotation_deg=ErrorStatistics.of(rot),
        matched=int(ri.size),
        aligned=bool(align),
        alignment=T,
        translation_errors_m=trans,
        rotation_errors_deg=rot,
        ref_index=ri,
        est_index=ei,
    )


# -- RPE -----------------------------------------------------------------------------------
_FRAMES = ("frames", "f")
_METRES = ("m", "meters", "metres")


def _pairs_by_path(positions: FloatArray, delta: float) -> tuple[IntArray, IntArray]:
    """evo's ``filter_pairs_by_path`` (consecutive pairs): from the first pose, the next one
    is the first whose path distance from the current reaches ``delta``; and so on."""
    d = distance_along(np.column_stack([positions, np.zeros(positions.shape[0])]))
    starts: list[int] = []
    ends: list[int] = []
    i = 0
    n = d.size
    while True:  # one iteration per pair (path length / delta), not per pose
        j = int(np.searchsorted(d, d[i] + delta, side="left"))
        while j < n and d[j] - d[i] < delta:  # rounding of d[i] + delta
            j += 1
        while j - 1 > i and d[j - 1] - d[i] >= delta:
            j -= 1
        if j >= n:
            break
        starts.append(i)
        ends.append(j)
        i = j
    return np.array(starts, dtype=np.intp), np.array(ends, dtype=np.intp)


@dataclass(frozen=True, eq=False)
class RelativePoseError:
    """RPE (:func:`relative_pose_error`) for one ``delta`` (``delta_unit`` ``"frames"`` or
    ``"m"``): translational (m) and rotational (degrees) errors of the relative motions over
    ``pairs`` pose pairs. Per pair: ``translation_errors_m``, ``rotation_errors_deg``, and the
    pair's poses as indices into the inputs, ``ref_index`` and ``est_index`` ``(pairs, 2)``."""

    delta: float
    delta_unit: str
    pairs: int
    translation_m: ErrorStatistics
    rotation_deg: ErrorStatistics
    translation_errors_m: FloatArray
    rotation_errors_deg: FloatArray
    ref_index: IntArray
    est_index: IntArray

    def as_dict(self) -> dict[str, float | int | str]:
        return {
            "delta": self.delta,
            "delta_unit": self.delta_unit,
            "pairs": self.pairs,
            **_flat("trans", "m", self.translation_m),
            **_flat("rot", "deg", self.rotation_deg),
        }


def relative_pose_error(
    ref_stamps: ArrayLike,
    ref_poses: Poses,
    est_stamps: ArrayLike,
    est_poses: Poses,
    *,
    delta: float = 1,
    delta_unit: str = "frames",
    pairs_from: str = "reference",
    max_stamp_gap: float = DEFAULT_ASSOCIATION_GAP,
) -> RelativePoseError:
    """RPE: errors of the estimated relative motions over ``delta`` frames or metres.

    1. Associate poses by nearest timestamp (:func:`associate`), giving sequences ``Q_k``
       (reference) and ``P_k`` (estimate) in the driving trajectory's order.
    2. Consecutive, non-overlapping pairs ``(i, j)``: ``delta_unit="frames"`` (or ``"f"``):
       ``(0, δ), (δ, 2δ), …``; ``"m"``: from ``i = 0``, ``j`` is the first pose whose path
       distance from ``i`` (summed position steps) reaches ``delta``, then ``i = j``, … The
       path is the reference's (``pairs_from="reference"``) or the estimate's
       (``"estimate"``).
    3. ``E = ⊖(⊖Q_i ⊕ Q_j) ⊕ (⊖P_i ⊕ P_j)``; translational error ``|E.xy|`` (m), rotational
       ``|E.θ|`` (degrees). Summaries as :class:`ErrorStatistics` (the RMSE is the usual RPE).

    No alignment is needed: the errors do not change when the estimate is moved rigidly.
    This is ``evo_rpe tum ref.tum est.tum --delta 1 --delta_unit f`` (``-r trans_part`` /
    ``-r angle_deg``) and, for metres, ``--delta 1 --delta_unit m --pairs_from_reference``
    (evo's default measures the path along the estimate: ``pairs_from="estimate"``).
    Exact ties of the path distance with ``delta`` may differ from evo by rounding.
    """
    rp = _poses("ref_poses", ref_poses)
    ep = _poses("est_poses", est_poses)
    rs = _stamps("ref_stamps", ref_stamps, rp.shape[0])
    es = _stamps("est_stamps", est_stamps, ep.shape[0])
    dl = float(delta)
    if not (np.isfinite(dl) and dl > 0):
        raise EvaluationError(f"delta must be a positive number, got {delta!r}")
    if pairs_from not in ("reference", "estimate"):
        raise EvaluationError(f"pairs_from must be 'reference' or 'estimate', got {pairs_from!r}")
    ri, ei = associate(rs, es, max_stamp_gap=max_stamp_gap)
    ref, est = rp[ri], ep[ei]
    if delta_unit in _FRAMES:
        if not dl.is_integer():
            raise EvaluationError(f"delta in frames must be a whole number, got {delta!r}")
        ids = np.arange(0, ref.shape[0], int(dl), dtype=np.intp)
        a, b = ids[:-1], ids[1:]
        unit = "frames"
    elif delta_unit in _METRES:
        a, b = _pairs_by_path((ref if pairs_from == "reference" else est)[:, :2], dl)
        unit = "m"
    else:
        raise EvaluationError(f"delta_unit must be 'frames' or 'm', got {delta_unit!r}")
    if a.size == 0:
        raise EvaluationError(
            f"delta = {dl:g} {unit} gives no pose pairs among {ref.shape[0]} associated poses"
        )
    e = relative(relative(ref[a], ref[b]), relative(est[a], est[b]))
    trans = np.hypot(e[:, 0], e[:, 1])
    rot = np.degrees(np.abs(e[:, 2]))
    r_idx = np.column_stack([ri[a], ri[b]])
    e_idx = np.column_stack([ei[a], ei[b]])
    for arr in (trans, rot, r_idx, e_idx):
        arr.setflags(write=False)
    return RelativePoseError(
        delta=dl,
        delta_unit=unit,
        pairs=int(a.size),
        translation_m=ErrorStatistics.of(trans),
        rotation_deg=ErrorStatistics.of(rot),
        translation_errors_m=trans,
        rotation_errors_deg=rot,
        ref_index=r_idx,
        est_index=e_idx,
    )
