"""The uncertainty stage's 3×3 arithmetic as compiled loops: the sandwich of a fit and the
gate (``Uncertainty.assess``), and the motion the scan alone gives (``Uncertainty.scan_only``).
The references are those methods with ``FUZZYPOS_KERNELS=numpy`` (``_assess_numpy``,
``_scan_only_numpy`` in ``fuzzypos.pipeline.uncertainty``): a few dozen numpy calls on 3×3
matrices, each far slower than its arithmetic."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import kernel
from .refine import solve3

FloatArray = NDArray[np.float64]

#: what keeps the fit's information invertible (``_TINY`` of the reference)
_TINY = 1e-12


@kernel
def _wrap(a: float) -> float:
    """``fuzzypos.geometry`` wrapping of one angle into [−π, π)."""
    if -math.pi <= a < math.pi:
        return a
    return (a + math.pi) % (2 * math.pi) - math.pi


@kernel
def _relative(a: FloatArray, b: FloatArray) -> FloatArray:
    """``⊖a ⊕ b`` of one pose each (``geometry.relative``, the same arithmetic)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    ix, iy, it = -(c * a[0] + s * a[1]), s * a[0] - c * a[1], _wrap(-a[2])
    c, s = math.cos(it), math.sin(it)
    out = np.empty(3)
    out[0] = ix + c * b[0] - s * b[1]
    out[1] = iy + s * b[0] + c * b[1]
    out[2] = _wrap(it + b[2])
    return out


@kernel
def _compose(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a ⊕ b`` of one pose each (``geometry.compose``)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    out = np.empty(3)
    out[0] = a[0] + c * b[0] - s * b[1]
    out[1] = a[1] + s * b[0] + c * b[1]
    out[2] = _wrap(a[2] + b[2])
    return out


@kernel
def _jacobians(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``geometry.compose_jacobians(a, b)``."""
    c, s = math.cos(a[2]), math.sin(a[2])
    ja = np.eye(3)
    ja[0, 2] = -s * b[0] - c * b[1]
    ja[1, 2] = c * b[0] - s * b[1]
    jb = np.eye(3)
    jb[0, 0], jb[0, 1], jb[1, 0], jb[1, 1] = c, -s, s, c
    return ja, jb


@kernel
def _solve(a: FloatArray, b: FloatArray) -> FloatArray:
    """``np.linalg.solve`` of a 3×3 (partial pivoting, as LAPACK's; NaN where singular):
    numba's own LAPACK bindings take seconds to compile."""
    x = np.empty(3)
    if not solve3(a, b, x):
        x[:] = np.nan
    return x


@kernel
def _inv(a: FloatArray) -> FloatArray:
    """``np.linalg.inv`` of a 3×3, a column at a time by :func:`_solve`."""
    out = np.empty((3, 3))
    e = np.zeros(3)
    for j in range(3):
        e[:] = 0.0
        e[j] = 1.0
        col = _solve(a, e)
        for i in range(3):
            out[i, j] = col[i]
    return out


@kernel
def _condition(a: FloatArray) -> float:
    """``np.linalg.cond`` (2-norm) of a symmetric positive semi-definite 3×3, the ratio of its
    largest eigenvalue to its smallest (closed form, trigonometric; inf where singular)."""
    p1 = a[0, 1] ** 2 + a[0, 2] ** 2 + a[1, 2] ** 2
    q = (a[0, 0] + a[1, 1] + a[2, 2]) / 3.0
    if p1 == 0.0:  # diagonal
        lo = min(a[0, 0], a[1, 1], a[2, 2])
        hi = max(a[0, 0], a[1, 1], a[2, 2])
    else:
        p2 = (a[0, 0] - q) ** 2 + (a[1, 1] - q) ** 2 + (a[2, 2] - q) ** 2 + 2.0 * p1
        p = math.sqrt(p2 / 6.0)
        b = _scaled(_sub(a, _scaled(np.eye(3), q)), 1.0 / p)
        r = 0.5 * (
            b[0, 0] * (b[1, 1] * b[2, 2] - b[1, 2] * b[2, 1])
            - b[0, 1] * (b[1, 0] * b[2, 2] - b[1, 2] * b[2, 0])
            + b[0, 2] * (b[1, 0] * b[2, 1] - b[1, 1] * b[2, 0])
        )
        phi = math.acos(min(max(r, -1.0), 1.0)) / 3.0
        hi = q + 2.0 * p * math.cos(phi)
        lo = q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
    hi, lo = abs(hi), abs(lo)
    if lo == 0.0:
        return math.inf
    return float(hi / lo)


@kernel
def _add(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a + b`` of two 3×3 (loops: numba's array expressions are slow to compile)."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, j] + b[i, j]
    return out


@kernel
def _sub(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a − b`` of two 3×3."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, j] - b[i, j]
    return out


@kernel
def _scaled(a: FloatArray, c: float) -> FloatArray:
    """``c · a`` of a 3×3."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = c * a[i, j]
    return out


@kernel
def _t(a: FloatArray) -> FloatArray:
    """``a.T`` of a 3×3, a copy."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = a[j, i]
    return out


@kernel
def _sym(a: FloatArray) -> FloatArray:
    """``0.5 · (a + a.T)`` of a 3×3."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = 0.5 * (a[i, j] + a[j, i])
    return out


@kernel
def _mm(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a @ b`` of two 3×3."""
    out = np.zeros((3, 3))
    for i in range(3):
        for k in range(3):
            aik = a[i, k]
            for j in range(3):
                out[i, j] += aik * b[k, j]
    return out


@kernel
def _sandwich(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a @ b @ a.T`` of two 3×3."""
    return _mm(_mm(a, b), _t(a))


@kernel
def _local(cov: FloatArray, theta: float) -> FloatArray:
    """``uncertainty.local``: the additive covariance as the right perturbation's."""
    c, s = math.cos(theta), math.sin(theta)
    g = np.zeros((3, 3))
    g[0, 0], g[0, 1], g[1, 0], g[1, 1], g[2, 2] = c, s, -s, c, 1.0
    return _sym(_sandwich(g, cov))


@kernel
def _differs(target: FloatArray, key: FloatArray) -> bool:
    """Whether a prior's target is not the odometry's motion from the keyframe."""
    worst = 0.0
    for i in range(3):
        worst = max(worst, abs(target[i] - key[i]))
    return worst > 1e-12


@kernel
def _fit_parts(
    information: FloatArray,
    prior_information: FloatArray,
    hold_information: FloatArray,
    fit_prior: FloatArray,
    hold_target: FloatArray,
    gradient_covariance: FloatArray,
    point_correlation: float,
    key_prior: FloatArray,
    prev: FloatArray,
    odo: FloatArray,
    feature: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``Uncertainty._fit_parts``: the covariance relative to the keyframe, the increment's
    share that is not the odometry's error, and the pull toward the odometry's motion."""
    odometric = _add(prior_information, hold_information)
    m = _add(information, odometric)
    m_inv = _inv(_add(m, _scaled(np.eye(3), _TINY)))
    other = np.zeros((3, 3))
    if _differs(fit_prior, key_prior):
        other = _add(other, prior_information)
    if _differs(hold_target, key_prior):
        other = _add(other, hold_information)
    own = _add(_scaled(gradient_covariance, point_correlation), _mm(_mm(other, feature), other))
    kf = _mm(_mm(m_inv, _add(own, _mm(_mm(odometric, _add(prev, odo)), odometric))), m_inv)
    rest = _sub(m, odometric)
    scan_part = _mm(_mm(m_inv, _add(own, _mm(_mm(rest, prev), rest))), m_inv)
    return kf, scan_part, _mm(m_inv, odometric)


@kernel
def assess_fit(
    t_prev: FloatArray,
    prior: FloatArray,
    prior_covariance: FloatArray,
    previous: FloatArray,
    from_key: FloatArray,
    feature: FloatArray,
    floor: FloatArray,
    has_fit: bool,
    information: FloatArray,
    prior_information: FloatArray,
    hold_information: FloatArray,
    gradient_covariance: FloatArray,
    fit_prior: FloatArray,
    hold_target: FloatArray,
    point_correlation: float,
    gate_open: bool,
) -> tuple[FloatArray, FloatArray, FloatArray, float]:
    """``Uncertainty.assess`` of a match ``from_key`` (by a fit where ``has_fit``, else the
    features alone): the increment's covariance, the covariance relative to the keyframe (both
    right perturbations, the floor added), the new previous scan's additive covariance and
    the gate's Mahalanobis distance squared (NaN where the gate is closed). The fit's
    information, prior and hold information, gradient covariance, prior and the hold's target
    (each read only where ``has_fit``)."""
    ja, jb = _jacobians(t_prev, prior)
    prev = _sandwich(ja, previous)
    odo = _sandwich(jb, prior_covariance)
    inc = _relative(t_prev, from_key)
    jb_inv = _t(jb)
    if has_fit:
        key_prior = _compose(t_prev, prior)
        kf, scan_part, pull = _fit_parts(
            information, prior_information, hold_information, fit_prior, hold_target,
            gradient_covariance, point_correlation, key_prior, prev, odo, feature,
        )  # fmt: skip
    else:
        kf = feature.copy()
        scan_part = _add(feature, prev)
        pull = np.zeros((3, 3))
    inc_cov = _sandwich(jb_inv, _add(scan_part, _sandwich(pull, odo)))
    gate = math.nan
    if gate_open:
        k = _sub(_mm(_mm(jb_inv, pull), jb), np.eye(3))
        cov_d = _add(_add(_sandwich(jb_inv, scan_part), _sandwich(k, prior_covariance)), floor)
        d = _relative(prior, inc)
        x = _solve(cov_d, d)
        gate = d[0] * x[0] + d[1] * x[1] + d[2] * x[2]
    new_previous = _sym(kf)
    return (
        _add(_local(inc_cov, inc[2]), floor),
        _add(_local(new_previous, from_key[2]), floor),
        new_previous,
        gate,
    )


@kernel
def scan_only(
    information: FloatArray,
    prior_information: FloatArray,
    gradient_covariance: FloatArray,
    increment: FloatArray,
    fit_prior: FloatArray,
    t_prev: FloatArray,
    previous: FloatArray,
    floor: FloatArray,
    point_correlation: float,
    max_condition: float,
) -> tuple[bool, FloatArray, FloatArray]:
    """``Uncertainty.scan_only`` of a fit without a hold: whether the points alone fix the
    motion (finite, condition number at most ``max_condition``), the increment they give and
    its covariance (right perturbation in the previous scan's frame, the floor added)."""
    a = information
    for i in range(3):
        for j in range(3):
            if not math.isfinite(a[i, j]):
                return False, np.zeros(3), np.zeros((3, 3))
    if not _condition(a) <= max_condition:
        return False, np.zeros(3), np.zeros((3, 3))
    m = _add(a, prior_information)
    p = fit_prior.copy()
    d = p[2] - increment[2]
    p[2] = increment[2] + (d - np.rint(d / math.tau) * math.tau)  # math.remainder(d, τ)
    rhs = np.empty(3)
    for i in range(3):
        acc = 0.0
        for j in range(3):
            acc += m[i, j] * increment[j] - prior_information[i, j] * p[j]
        rhs[i] = acc
    x_s = _solve(a, rhs)
    a_inv = _inv(a)
    points = _scaled(gradient_covariance, point_correlation)
    inc = _relative(t_prev, x_s)
    ja, jb = _jacobians(t_prev, inc)
    cov = _mm(_mm(_t(jb), _add(_sandwich(a_inv, points), _sandwich(ja, previous))), jb)
    return True, inc, _add(_local(cov, inc[2]), floor)
