"""The uncertainty stage's 3×3 arithmetic as compiled loops: the sandwich of a fit and the
gate (``Uncertainty.assess``), and the motion the scan alone gives (``Uncertainty.scan_only``).
The references are ``assess_numpy`` (also the path where the gate rejects a match or
nothing was matched, ``prior_stands``) and ``scan_only_numpy`` of
``tests/oracles/pipeline.py``: a few dozen numpy calls on 3×3 matrices, each far slower than
its arithmetic.

Inside, a 3×3 is a tuple of its nine entries row by row (:data:`M3`) and a pose or a vector
a tuple of three (:data:`V3`): values, not arrays, which cost nothing to make, where each
compiled array is a heap allocation (about 50 ns, more than a 3×3 product's arithmetic). The
operations are numpy's, in its order (a product's sums from 0.0, k = 0, 1, 2). numpy's matrix
product makes each sum a chain of fused multiply-adds: where the prior stands
(:func:`prior_stands_of`) the products are those too (:func:`_mm_fused`), numpy's values to
the bit; elsewhere plain ones (:func:`_mm`), within rounding of numpy's. The kernels that
Python or other kernels call take and give arrays at the edge."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._jit import contracted, inlined, kernel

FloatArray = NDArray[np.float64]
#: a 3×3 as its nine entries, row by row
M3 = tuple[float, float, float, float, float, float, float, float, float]
#: a pose (x, y, θ) or a vector of three
V3 = tuple[float, float, float]

#: what keeps the fit's information invertible (``_TINY`` of the reference)
_TINY = 1e-12
_NAN3 = (math.nan, math.nan, math.nan)
_ZERO: M3 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
_EYE: M3 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


@inlined
def _m(a: FloatArray) -> M3:
    """A (3, 3) array's entries (inlined: compiled into each caller for its array's type, one
    read-only or not)."""
    return (a[0, 0], a[0, 1], a[0, 2], a[1, 0], a[1, 1], a[1, 2], a[2, 0], a[2, 1], a[2, 2])


@inlined
def _v(a: FloatArray) -> V3:
    """A 3-vector's entries (inlined, as :func:`_m`)."""
    return (a[0], a[1], a[2])


@kernel
def _put(out: FloatArray, m: M3) -> None:
    """``out`` (3, 3) := the entries ``m``."""
    out[0, 0], out[0, 1], out[0, 2] = m[0], m[1], m[2]
    out[1, 0], out[1, 1], out[1, 2] = m[3], m[4], m[5]
    out[2, 0], out[2, 1], out[2, 2] = m[6], m[7], m[8]


@kernel
def _array(m: M3) -> FloatArray:
    """The (3, 3) array of the entries ``m``."""
    out = np.empty((3, 3))
    _put(out, m)
    return out


@kernel
def _array3(v: V3) -> FloatArray:
    """The array of a 3-vector."""
    out = np.empty(3)
    out[0], out[1], out[2] = v[0], v[1], v[2]
    return out


@kernel
def _wrap(a: float) -> float:
    """``fuzzypos.geometry`` wrapping of one angle into [−π, π)."""
    if -math.pi <= a < math.pi:
        return a
    return (a + math.pi) % (2 * math.pi) - math.pi


@kernel
def _relative(a: V3, b: V3) -> V3:
    """``⊖a ⊕ b`` of one pose each (``geometry.relative``, the same arithmetic)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    ix, iy, it = -(c * a[0] + s * a[1]), s * a[0] - c * a[1], _wrap(-a[2])
    c, s = math.cos(it), math.sin(it)
    return (ix + c * b[0] - s * b[1], iy + s * b[0] + c * b[1], _wrap(it + b[2]))


@kernel
def _compose(a: V3, b: V3) -> V3:
    """``a ⊕ b`` of one pose each (``geometry.compose``)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], _wrap(a[2] + b[2]))


@kernel
def _jacobians(a: V3, b: V3) -> tuple[M3, M3]:
    """``geometry.compose_jacobians(a, b)``."""
    c, s = math.cos(a[2]), math.sin(a[2])
    ja = (1.0, 0.0, -s * b[0] - c * b[1], 0.0, 1.0, c * b[0] - s * b[1], 0.0, 0.0, 1.0)
    jb = (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
    return ja, jb


@kernel
def _solve(a: M3, b: V3) -> V3:
    """``np.linalg.solve`` of a 3×3 (Gaussian elimination with partial pivoting, as LAPACK's
    dgesv and ``refine``'s solve, the same operations; NaN where a pivot is exactly zero):
    numba's own LAPACK bindings take seconds to compile."""
    r0, r1, r2 = (a[0], a[1], a[2]), (a[3], a[4], a[5]), (a[6], a[7], a[8])
    v0, v1, v2 = b[0], b[1], b[2]
    # column 0: the row of the largest |entry| (the first of equal ones) to the top
    p = 0
    if abs(r1[0]) > abs(r0[0]):
        p = 1
    if abs(r2[0]) > abs((r0 if p == 0 else r1)[0]):
        p = 2
    if (r0 if p == 0 else (r1 if p == 1 else r2))[0] == 0.0:
        return _NAN3
    if p == 1:
        r0, r1, v0, v1 = r1, r0, v1, v0
    elif p == 2:
        r0, r2, v0, v2 = r2, r0, v2, v0
    f = r1[0] / r0[0]
    r1, v1 = (r1[0] - f * r0[0], r1[1] - f * r0[1], r1[2] - f * r0[2]), v1 - f * v0
    f = r2[0] / r0[0]
    r2, v2 = (r2[0] - f * r0[0], r2[1] - f * r0[1], r2[2] - f * r0[2]), v2 - f * v0
    # column 1
    if abs(r2[1]) > abs(r1[1]):
        if r2[1] == 0.0:
            return _NAN3
        r1, r2, v1, v2 = r2, r1, v2, v1
    elif r1[1] == 0.0:
        return _NAN3
    f = r2[1] / r1[1]
    r2, v2 = (r2[0], r2[1] - f * r1[1], r2[2] - f * r1[2]), v2 - f * v1
    if r2[2] == 0.0:
        return _NAN3
    x2 = v2 / r2[2]
    x1 = (v1 - r1[2] * x2) / r1[1]
    acc = v0 - r0[1] * x1
    x0 = (acc - r0[2] * x2) / r0[0]
    return (x0, x1, x2)


@kernel
def _inv(a: M3) -> M3:
    """``np.linalg.inv`` of a 3×3, a column at a time by :func:`_solve`."""
    c0 = _solve(a, (1.0, 0.0, 0.0))
    c1 = _solve(a, (0.0, 1.0, 0.0))
    c2 = _solve(a, (0.0, 0.0, 1.0))
    return (c0[0], c1[0], c2[0], c0[1], c1[1], c2[1], c0[2], c1[2], c2[2])


@kernel
def _condition(a: M3) -> float:
    """``np.linalg.cond`` (2-norm) of a symmetric positive semi-definite 3×3, the ratio of its
    largest eigenvalue to its smallest (closed form, trigonometric; inf where singular)."""
    p1 = a[1] ** 2 + a[2] ** 2 + a[5] ** 2
    q = (a[0] + a[4] + a[8]) / 3.0
    if p1 == 0.0:  # diagonal
        lo = min(a[0], a[4], a[8])
        hi = max(a[0], a[4], a[8])
    else:
        p2 = (a[0] - q) ** 2 + (a[4] - q) ** 2 + (a[8] - q) ** 2 + 2.0 * p1
        p = math.sqrt(p2 / 6.0)
        b = _scaled(_sub(a, _scaled(_EYE, q)), 1.0 / p)
        r = 0.5 * (
            b[0] * (b[4] * b[8] - b[5] * b[7])
            - b[1] * (b[3] * b[8] - b[5] * b[6])
            + b[2] * (b[3] * b[7] - b[4] * b[6])
        )
        phi = math.acos(min(max(r, -1.0), 1.0)) / 3.0
        hi = q + 2.0 * p * math.cos(phi)
        lo = q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
    hi, lo = abs(hi), abs(lo)
    if lo == 0.0:
        return math.inf
    return float(hi / lo)


@kernel
def _add(a: M3, b: M3) -> M3:
    """``a + b`` of two 3×3."""
    return (
        a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3], a[4] + b[4], a[5] + b[5],
        a[6] + b[6], a[7] + b[7], a[8] + b[8],
    )  # fmt: skip


@kernel
def _sub(a: M3, b: M3) -> M3:
    """``a − b`` of two 3×3."""
    return (
        a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3], a[4] - b[4], a[5] - b[5],
        a[6] - b[6], a[7] - b[7], a[8] - b[8],
    )  # fmt: skip


@kernel
def _scaled(a: M3, c: float) -> M3:
    """``c · a`` of a 3×3."""
    return (
        c * a[0], c * a[1], c * a[2], c * a[3], c * a[4], c * a[5], c * a[6], c * a[7],
        c * a[8],
    )  # fmt: skip


@kernel
def _t(a: M3) -> M3:
    """``a.T`` of a 3×3."""
    return (a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8])


@kernel
def _sym(a: M3) -> M3:
    """``0.5 · (a + a.T)`` of a 3×3."""
    return (
        0.5 * (a[0] + a[0]), 0.5 * (a[1] + a[3]), 0.5 * (a[2] + a[6]),
        0.5 * (a[3] + a[1]), 0.5 * (a[4] + a[4]), 0.5 * (a[5] + a[7]),
        0.5 * (a[6] + a[2]), 0.5 * (a[7] + a[5]), 0.5 * (a[8] + a[8]),
    )  # fmt: skip


@kernel
def _mm(a: M3, b: M3) -> M3:
    """``a @ b`` of two 3×3 (each entry's sum from 0.0, k = 0, 1, 2)."""
    return (
        0.0 + a[0] * b[0] + a[1] * b[3] + a[2] * b[6],
        0.0 + a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
        0.0 + a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
        0.0 + a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
        0.0 + a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
        0.0 + a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        0.0 + a[6] * b[0] + a[7] * b[3] + a[8] * b[6],
        0.0 + a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
        0.0 + a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )


@contracted
def _mm_fused(a: M3, b: M3) -> M3:
    """``a @ b`` of two 3×3 as numpy computes it: each entry's sum from 0.0, k = 0, 1, 2, each
    step a fused multiply-add (numpy's product, to the bit)."""
    return (
        0.0 + a[0] * b[0] + a[1] * b[3] + a[2] * b[6],
        0.0 + a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
        0.0 + a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
        0.0 + a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
        0.0 + a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
        0.0 + a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        0.0 + a[6] * b[0] + a[7] * b[3] + a[8] * b[6],
        0.0 + a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
        0.0 + a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )


@kernel
def _sandwich_fused(a: M3, b: M3) -> M3:
    """``a @ b @ a.T`` of two 3×3 by :func:`_mm_fused` (numpy's, to the bit)."""
    return _mm_fused(_mm_fused(a, b), _t(a))


@kernel
def _sandwich(a: M3, b: M3) -> M3:
    """``a @ b @ a.T`` of two 3×3."""
    return _mm(_mm(a, b), _t(a))


@kernel
def _local(cov: M3, theta: float) -> M3:
    """``uncertainty.local``: the additive covariance as the right perturbation's."""
    c, s = math.cos(theta), math.sin(theta)
    return _sym(_sandwich((c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0), cov))


@kernel
def _differs(target: V3, key: V3) -> bool:
    """Whether a prior's target is not the odometry's motion from the keyframe."""
    worst = 0.0
    for i in range(3):
        worst = max(worst, abs(target[i] - key[i]))
    return worst > 1e-12


@kernel
def _fit_parts(
    information: M3,
    prior_information: M3,
    hold_information: M3,
    fit_prior: V3,
    hold_target: V3,
    gradient_covariance: M3,
    point_correlation: float,
    key_prior: V3,
    prev: M3,
    odo: M3,
    feature: M3,
) -> tuple[M3, M3, M3]:
    """``Uncertainty._fit_parts``: the covariance relative to the keyframe, the increment's
    share that is not the odometry's error, and the pull toward the odometry's motion."""
    odometric = _add(prior_information, hold_information)
    m = _add(information, odometric)
    m_inv = _inv(_add(m, _scaled(_EYE, _TINY)))
    other = _ZERO
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
def assessed(
    t_prev: V3,
    prior: V3,
    prior_covariance: M3,
    previous: M3,
    from_key: V3,
    feature: M3,
    floor: M3,
    has_fit: bool,
    information: M3,
    prior_information: M3,
    hold_information: M3,
    gradient_covariance: M3,
    fit_prior: V3,
    hold_target: V3,
    point_correlation: float,
    gate_open: bool,
) -> tuple[M3, M3, M3, float]:
    """``Uncertainty.assess`` of a match ``from_key`` (by a fit where ``has_fit``, else the
    features alone; each 3×3 and pose as its entries): the increment's covariance, the
    covariance relative to the keyframe (both right perturbations, the floor added), the new
    previous scan's additive covariance and the gate's Mahalanobis distance squared (NaN
    where the gate is closed). The fit's information, prior and hold information, gradient
    covariance, prior and the hold's target (each read only where ``has_fit``)."""
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
        kf = feature
        scan_part = _add(feature, prev)
        pull = _ZERO
    inc_cov = _sandwich(jb_inv, _add(scan_part, _sandwich(pull, odo)))
    gate = math.nan
    if gate_open:
        k = _sub(_mm(_mm(jb_inv, pull), jb), _EYE)
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
def prior_stands_of(
    t_prev: V3, prior: V3, prior_covariance: M3, previous: M3, floor: M3
) -> tuple[M3, M3, M3]:
    """The prior stands (nothing matched, or the gate rejected the match, or the match was
    overruled): its own covariance for the increment (symmetric, the floor added); relative to
    the keyframe the previous scan's ``previous`` carried on by it, as the right
    perturbation's with the floor added and as the new previous additive covariance."""
    ja, jb = _jacobians(t_prev, prior)
    carried = _add(_sandwich_fused(ja, previous), _sandwich_fused(jb, prior_covariance))
    theta = t_prev[2] + prior[2]
    c, s = math.cos(theta), math.sin(theta)
    kf = _sym(_sandwich_fused((c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0), carried))
    return _add(_sym(prior_covariance), floor), _add(kf, floor), carried


@kernel
def prior_stands(
    t_prev: FloatArray,
    prior: FloatArray,
    prior_covariance: FloatArray,
    previous: FloatArray,
    floor: FloatArray,
) -> FloatArray:
    """:func:`prior_stands_of` of arrays, in one (3, 3, 3) array: the increment's covariance,
    the keyframe's and the new previous one."""
    inc_cov, kf, carried = prior_stands_of(
        _v(t_prev), _v(prior), _m(prior_covariance), _m(previous), _m(floor)
    )
    out = np.empty((3, 3, 3))
    _put(out[0], inc_cov)
    _put(out[1], kf)
    _put(out[2], carried)
    return out


@kernel
def scan_only_of(
    information: M3,
    prior_information: M3,
    gradient_covariance: M3,
    increment: V3,
    fit_prior: V3,
    t_prev: V3,
    previous: M3,
    floor: M3,
    point_correlation: float,
    max_condition: float,
) -> tuple[bool, V3, M3]:
    """:func:`scan_only` of the entries."""
    a = information
    for i in range(9):
        if not math.isfinite(a[i]):
            return False, (0.0, 0.0, 0.0), _ZERO
    if not _condition(a) <= max_condition:
        return False, (0.0, 0.0, 0.0), _ZERO
    m = _add(a, prior_information)
    d = fit_prior[2] - increment[2]
    p = (fit_prior[0], fit_prior[1], increment[2] + (d - np.rint(d / math.tau) * math.tau))
    rhs = (  # (each sum from 0.0, j = 0, 1, 2)
        0.0
        + (m[0] * increment[0] - prior_information[0] * p[0])
        + (m[1] * increment[1] - prior_information[1] * p[1])
        + (m[2] * increment[2] - prior_information[2] * p[2]),
        0.0
        + (m[3] * increment[0] - prior_information[3] * p[0])
        + (m[4] * increment[1] - prior_information[4] * p[1])
        + (m[5] * increment[2] - prior_information[5] * p[2]),
        0.0
        + (m[6] * increment[0] - prior_information[6] * p[0])
        + (m[7] * increment[1] - prior_information[7] * p[1])
        + (m[8] * increment[2] - prior_information[8] * p[2]),
    )
    x_s = _solve(a, rhs)
    a_inv = _inv(a)
    points = _scaled(gradient_covariance, point_correlation)
    inc = _relative(t_prev, x_s)
    ja, jb = _jacobians(t_prev, inc)
    cov = _mm(_mm(_t(jb), _add(_sandwich(a_inv, points), _sandwich(ja, previous))), jb)
    return True, inc, _add(_local(cov, inc[2]), floor)


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
    ok, inc, cov = scan_only_of(
        _m(information), _m(prior_information), _m(gradient_covariance), _v(increment),
        _v(fit_prior), _v(t_prev), _m(previous), _m(floor), point_correlation, max_condition,
    )  # fmt: skip
    return ok, _array3(inc), _array(cov)
