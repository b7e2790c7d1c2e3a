"""Small kernels of the per-scan pipeline's own glue (``fuzzypos.pipeline``), where numpy makes
several small calls per step. Each has its numpy reference beside its caller, and
``tests/_kernels/test_kernels_pipeline.py`` checks the two against each other."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ._jit import kernel
from .uncertainty import (
    _add,
    _inv,
    _jacobians,
    _m,
    _put,
    _sandwich,
    _v,
    assessed,
    prior_stands_of,
    scan_only_of,
)  # fmt: skip

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@kernel
def move_surfaces(
    xy: FloatArray, normal: FloatArray, moves: FloatArray, ends: IntArray
) -> tuple[FloatArray, FloatArray]:
    """Several surfaces' points ``xy`` and unit normals (``(n, 2)`` each, part ``k`` the rows
    from ``ends[k - 1]`` (0 for the first) to ``ends[k]``), part ``k`` moved by ``moves[k]``
    = ``(x, y, cos θ, sin θ)``: the points as ``geometry.transform_points`` moves them and
    the normals turned by θ, in the same order of operations (the same values).
    ``pipeline.local_map.LocalMap._map_of`` in one loop."""
    n = xy.shape[0]
    out_xy = np.empty((n, 2))
    out_normal = np.empty((n, 2))
    begin = 0
    for k in range(moves.shape[0]):
        tx, ty, c, s = moves[k, 0], moves[k, 1], moves[k, 2], moves[k, 3]
        for i in range(begin, ends[k]):
            x, y = xy[i, 0], xy[i, 1]
            out_xy[i, 0] = tx + c * x - s * y
            out_xy[i, 1] = ty + s * x + c * y
            nx, ny = normal[i, 0], normal[i, 1]
            out_normal[i, 0] = c * nx - s * ny
            out_normal[i, 1] = s * nx + c * ny
        begin = ends[k]
    return out_xy, out_normal


class AssessInputs(NamedTuple):
    """What the assessment reads but the match's and the fit's own values
    (``Uncertainty.assess_inputs``): the previous scan's pose from the keyframe, the prior
    and its covariance, the previous covariance, the features', the floor, the points'
    correlation, whether the gate is open, its threshold, whether the scan's own motion is
    wanted, the condition's limit; and for the compiled step
    (``step.match_refine_assess``) the prior from the keyframe and whether it is the
    assessment's (``pipeline.step._is_key_prior``)."""

    t_prev: FloatArray
    prior: FloatArray
    prior_covariance: FloatArray
    previous: FloatArray
    feature: FloatArray
    floor: FloatArray
    point_correlation: float
    gate_open: bool
    threshold: float
    wanted: bool
    max_condition: float
    key_prior: FloatArray
    key_prior_known: bool


class FitValues(NamedTuple):
    """What the assessment reads of a fit (``matching.Refinement``'s): the points'
    information, the prior's and the hold's, the points' gradient covariance, the motion the
    fit was held to by its prior (``prior``) and by its hold (``hold_target``), and its
    ``increment``."""

    information: FloatArray
    prior_information: FloatArray
    hold_information: FloatArray
    gradient_covariance: FloatArray
    prior: FloatArray
    hold_target: FloatArray
    increment: FloatArray


@kernel
def assess_and_scan_only(
    a: AssessInputs, from_key: FloatArray, has_fit: bool, fit: FitValues
) -> tuple[float, bool, FloatArray]:
    """``uncertainty.assessed`` of the match ``from_key`` (by the ``fit`` where ``has_fit``,
    else the features alone) and, where ``a.wanted``, the fit holds nothing (its
    ``hold_information`` zero) and the gate (at ``a.threshold``) lets the match stand,
    ``uncertainty.scan_only`` of the fit (its ``increment``) from the previous covariance the
    assessment leaves: the two kernels the positioner calls one after the
    other for a refined match, in one call. Returns the assessment's gate, whether the scan
    alone fixes the motion, and one (5, 3, 3) array (one array to box, not five): the
    assessment's three matrices (the increment's covariance, the keyframe's, the new
    previous one; where the gate rejects the match, the prior's, ``uncertainty.prior_stands_of``),
    the scan's own motion's covariance, and that motion in the last one's first row (zeros
    where not computed)."""
    t_prev, prior, prior_covariance, previous = a.t_prev, a.prior, a.prior_covariance, a.previous
    floor, point_correlation, gate_open = a.floor, a.point_correlation, a.gate_open
    threshold, wanted = a.threshold, a.wanted
    information, prior_information = fit.information, fit.prior_information
    hold_information, gradient_covariance = fit.hold_information, fit.gradient_covariance
    fit_prior, hold_target, increment = fit.prior, fit.hold_target, fit.increment
    info, prior_info, hold_info = _m(information), _m(prior_information), _m(hold_information)
    gradient, at, key, cov_floor = _m(gradient_covariance), _v(t_prev), _v(fit_prior), _m(floor)
    inc_cov, kf, new_previous, gate = assessed(
        at, _v(prior), _m(prior_covariance), _m(previous), _v(from_key), _m(a.feature), cov_floor,
        has_fit, info, prior_info, hold_info, gradient, key, _v(hold_target),
        point_correlation, gate_open,
    )  # fmt: skip
    out = np.zeros((5, 3, 3))
    if gate_open and gate > threshold:  # rejected: the prior stands
        inc_cov, kf, new_previous = prior_stands_of(
            at, _v(prior), _m(prior_covariance), _m(previous), cov_floor
        )
    _put(out[0], inc_cov)
    _put(out[1], kf)
    _put(out[2], new_previous)
    ok = False
    for i in range(9):  # (a held fit gives no motion of the scan's own)
        if hold_info[i] != 0.0:
            wanted = False
    if wanted and not (gate_open and gate > threshold):
        ok, inc, cov = scan_only_of(
            info, prior_info, gradient, _v(increment), key, at, new_previous, cov_floor,
            point_correlation, a.max_condition,
        )  # fmt: skip
        _put(out[3], cov)
        out[4, 0, 0], out[4, 0, 1], out[4, 0, 2] = inc[0], inc[1], inc[2]
    return gate, ok, out


@kernel
def prior_information(
    t_prev: FloatArray,
    prior: FloatArray,
    previous: FloatArray,
    prior_covariance: FloatArray,
    floor: FloatArray,
    feature: FloatArray,
) -> FloatArray:
    """The information of the features' and of the odometry's motion from the keyframe, the
    refinement's priors where the learned noise is trusted (``Positioner._context``):
    the odometry's covariance from the keyframe, ``ja P_prev jaᵀ + jb Σ_odo jbᵀ + floor``
    (``key_prior_covariance`` of ``tests/oracles/pipeline.py``, the Jacobians of
    ``t_prev ⊕ prior``), then the inverse of it plus the features' own ``feature`` and its
    own inverse, in one (2, 3, 3) array."""
    ja, jb = _jacobians(_v(t_prev), _v(prior))
    moved = _add(_sandwich(ja, _m(previous)), _sandwich(jb, _m(prior_covariance)))
    odometry = _add(moved, _m(floor))
    out = np.empty((2, 3, 3))
    _put(out[0], _inv(_add(odometry, _m(feature))))
    _put(out[1], _inv(odometry))
    return out
