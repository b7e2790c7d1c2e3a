"""Beyond the paper: line-to-line matching (lines of scan k paired with lines of scan k+1, the
increment from the pairs' normals and distances)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._kernels import f64
from ..features import Lines
from ._robust import MAD_TO_SIGMA, OUTLIER_SIGMAS, FloatArray, IntArray

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
    from .._kernels import lines as kernel

    f = f64
    rows, cols = kernel.pair_lines(
        f(prev.normal_angle), f(prev.distance), f(prev.normal), f(prev.centre),
        f(prev.length), f(curr.normal_angle), f(curr.distance), f(curr.centre),
        f(curr.length), f(pose),
        np.array([angle_gate, distance_gate, overlap_margin], dtype=np.float64),
    )  # fmt: skip
    return LinePairs(rows, cols)


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
    translation two of them at least ``consensus_angle`` apart fix (MSAC over every two of
    them) enter a weighted least-squares fit (inverse variances)
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
