"""Beyond the paper: line-to-line matching (lines of scan k paired with lines of scan k+1, the
increment from the pairs' normals and distances)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._kernels import compiled, f64
from ..features import Lines
from ._robust import MAD_TO_SIGMA, OUTLIER_SIGMAS, FloatArray, IntArray, index_pairs, robust_keep

__all__ = ["LinePairs", "pair_lines", "increment_from_lines"]

_HALF_PI = 0.5 * math.pi


@dataclass(frozen=True, eq=False)
class LinePairs:
    """Paired lines: ``prev[i]`` of scan k ↔ ``curr[i]`` of scan k+1 (indices into ``Lines``)."""

    prev_index: IntArray
    curr_index: IntArray

    def __len__(self) -> int:
        return int(self.prev_index.shape[0])


def pair_lines(
    prev: Lines,
    curr: Lines,
    pose: FloatArray,
    angle_gate: float,
    distance_gate: float,
    overlap_margin: float,
) -> LinePairs:
    """Pair lines of scan k with lines of scan k+1 moved into frame k by ``pose``.

    Two lines pair when their directions differ by less than ``angle_gate``, their normal
    distances by less than ``distance_gate``, and their segments overlap along the line (the
    distance between their centres along it is at most their mean length plus
    ``overlap_margin``); each line keeps its best match, and only mutual best matches count.
    """
    if len(prev) == 0 or len(curr) == 0:
        z = np.zeros(0, dtype=np.int64)
        return LinePairs(z, z)
    if compiled():
        from .._kernels import lines as kernel

        f = f64
        rows, cols = kernel.pair_lines(
            f(prev.normal_angle), f(prev.distance), f(prev.normal), f(prev.centre),
            f(prev.length), f(curr.normal_angle), f(curr.distance), f(curr.centre),
            f(curr.length), f(pose),
            np.array([angle_gate, distance_gate, overlap_margin], dtype=np.float64),
        )  # fmt: skip
        return LinePairs(rows, cols)
    return _pair_lines_numpy(prev, curr, pose, angle_gate, distance_gate, overlap_margin)


def _pair_lines_numpy(
    prev: Lines,
    curr: Lines,
    pose: FloatArray,
    angle_gate: float,
    distance_gate: float,
    overlap_margin: float,
) -> LinePairs:
    """:func:`pair_lines` in numpy (the compiled kernel's reference)."""
    ang, dd, along, reach = _line_geometry(prev, curr, pose, overlap_margin)
    cost = ang * (1.0 / angle_gate) + dd * (1.0 / distance_gate)
    cost[(ang >= angle_gate) | (dd >= distance_gate) | (np.abs(along) > reach)] = np.inf
    j = cost.argmin(axis=1)
    i = cost.argmin(axis=0)
    rows = np.arange(len(prev))
    good = (cost.min(axis=1) < np.inf) & (i[j] == rows)
    return LinePairs(rows[good], j[good])


def _line_geometry(
    prev: Lines, curr: Lines, pose: FloatArray, overlap_margin: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Every previous line (rows) against every current one moved by ``pose`` (columns): the
    angle between their normals (either way), between their distances, the offset of the
    current centre along the previous line, and how far it may be for their segments to
    overlap."""
    ac = curr.normal_angle + pose[2]  # the current normals' angles in frame k
    raw = prev.normal_angle[:, None] - ac  # (P, C)
    ang = np.abs((raw + _HALF_PI) % math.pi - _HALF_PI)  # normals may point either way
    sign = np.copysign(1.0, np.cos(raw))
    d = curr.distance + np.cos(ac) * pose[0] + np.sin(ac) * pose[1]
    dd = np.abs(prev.distance[:, None] - sign * d)
    # centre of each current segment in frame k, and its offset along each previous line
    c, s = math.cos(pose[2]), math.sin(pose[2])
    cx = pose[0] + c * curr.centre[:, 0] - s * curr.centre[:, 1]
    cy = pose[1] + s * curr.centre[:, 0] + c * curr.centre[:, 1]
    pn = prev.normal
    along = pn[:, 1:2] * (cx - prev.centre[:, 0:1]) - pn[:, 0:1] * (cy - prev.centre[:, 1:2])
    reach = 0.5 * (prev.length[:, None] + curr.length) + overlap_margin
    return ang, dd, along, reach


def increment_from_lines(
    prev: Lines,
    curr: Lines,
    pairs: LinePairs,
    start: FloatArray,
    prior: FloatArray,
    prior_sigma: float,
    trim_floor_angle: float,
    inlier_distance: float,
    consensus_angle: float,
) -> FloatArray | None:
    """Beyond the paper: the increment from paired lines (line-to-line matching).

    Rotation: the inverse-variance weighted mean of the paired normals' angle differences,
    after dropping those beyond 3 robust sigmas (at least ``trim_floor_angle``) of their
    median. Translation: each pair says ``n·t = d_k − d′`` (normal form, ``n`` the scan-k
    line's normal); the pairs consistent (within ``inlier_distance``) with the best
    translation two of them at least ``consensus_angle`` apart fix
    (:func:`_translation_consensus`) enter a weighted least-squares fit (inverse variances)
    together with the prior's translation as one more measurement of standard deviation
    ``prior_sigma``, which decides what the lines leave unobservable (the parallel walls of a
    corridor). Returns None with fewer than two pairs.
    """
    if len(pairs) < 2:
        return None
    pa, ca, pd, cd = (
        prev.angle_variance,
        curr.angle_variance,
        prev.distance_variance,
        curr.distance_variance,
    )
    if pa is None or ca is None or pd is None or cd is None:
        raise ValueError("line matching needs the lines' variances (lines from extract_features)")
    P = pairs.prev_index
    C = pairs.curr_index
    if compiled():
        from .._kernels import lines as kernel

        params = np.array(
            [
                prior_sigma, trim_floor_angle, inlier_distance, math.sin(consensus_angle),
                OUTLIER_SIGMAS * MAD_TO_SIGMA,
            ]
        )  # fmt: skip
        f = f64
        out: FloatArray = kernel.increment_from_lines(
            f(prev.normal_angle[P]), f(prev.distance[P]), f(curr.normal_angle[C]),
            f(curr.distance[C]), f(pa[P] + ca[C]), f(pd[P] + cd[C]), f(start), f(prior), params,
        )  # fmt: skip
        return out
    raw = prev.normal_angle[P] - curr.normal_angle[C] - start[2]
    delta = (raw + _HALF_PI) % math.pi - _HALF_PI  # rotation left after ``start``
    sign = np.copysign(1.0, np.cos(raw - delta))  # opposite normals: flip d′
    w_a = 1.0 / (pa[P] + ca[C])
    keep = robust_keep(delta, trim_floor_angle)
    theta = float(start[2] + np.dot(w_a[keep], delta[keep]) / w_a[keep].sum())
    # n: the mean of the previous normal and the current one rotated by θ (both lines agree)
    half = 0.5 * (prev.normal_angle[P] + curr.normal_angle[C] + theta + (raw - delta))
    nx = np.cos(half)
    ny = np.sin(half)
    rhs = prev.distance[P] - sign * curr.distance[C]
    used = keep & _translation_consensus(
        nx, ny, rhs, keep, inlier_distance, math.sin(consensus_angle)
    )
    w = np.where(used, 1.0 / (pd[P] + cd[C]), 0.0)
    lam = 1.0 / (prior_sigma * prior_sigma)
    wx, wy = w * nx, w * ny
    a11 = float(np.dot(wx, nx)) + lam
    a12 = float(np.dot(wx, ny))
    a22 = float(np.dot(wy, ny)) + lam
    b1 = float(np.dot(wx, rhs)) + lam * float(prior[0])
    b2 = float(np.dot(wy, rhs)) + lam * float(prior[1])
    det = a11 * a22 - a12 * a12
    tx = (a22 * b1 - a12 * b2) / det
    ty = (a11 * b2 - a12 * b1) / det
    return np.array([tx, ty, math.atan2(math.sin(theta), math.cos(theta))])


def _translation_consensus(
    nx: FloatArray,
    ny: FloatArray,
    rhs: FloatArray,
    candidates: NDArray[np.bool_],
    tau: float,
    min_sine: float,
) -> NDArray[np.bool_]:
    """Line pairs consistent with the best translation that two non-parallel pairs fix.

    Every two candidate pairs whose normals' angle has a sine above ``min_sine`` give ``t``
    exactly (``n·t = rhs`` twice);
    the one with the smallest truncated squared residual over all pairs (MSAC, τ) wins and its
    pairs within τ are the inliers. With no such two (parallel walls) every candidate is kept.
    """
    idx = candidates.nonzero()[0]
    if idx.size < 3:
        return candidates
    a, b = index_pairs(idx.size)
    i, j = idx[a], idx[b]
    det = nx[i] * ny[j] - ny[i] * nx[j]
    ok = np.abs(det) > min_sine
    if not ok.any():
        return candidates
    i, j, det = i[ok], j[ok], det[ok]
    tx = (rhs[i] * ny[j] - ny[i] * rhs[j]) / det
    ty = (nx[i] * rhs[j] - rhs[i] * nx[j]) / det
    r = np.abs(tx[:, None] * nx[idx] + ty[:, None] * ny[idx] - rhs[idx])
    best = int(np.minimum(r * r, tau * tau).sum(axis=1).argmin())
    out = np.zeros_like(candidates)
    out[idx] = r[best] < tau
    return out
