"""SE(2) geometry: poses ``(x, y, theta)``, composition, inversion, point transforms.

Array functions do the work; :class:`Pose2D` is a thin frozen wrapper over them. Every array
function takes poses as ``(..., 3)`` arrays ``[x, y, theta]`` and points as ``(..., 2)`` arrays
and broadcasts over the leading axes. Angles are radians and wrapped to ``[-pi, pi)``.

Conventions (SPEC): ``a ⊕ b`` composes, ``⊖a`` inverts; the odometry increment between poses
``o_k`` and ``o_{k+1}`` is ``⊖o_k ⊕ o_{k+1}``, the pose of k+1 in the frame of k.

Covariances (:func:`compose_jacobians`, :func:`propagate`, :func:`covariance_to_parent`): the
error of an estimate ``ĝ`` of a pose or increment ``g`` is the right perturbation
``ε = ⊖g ⊕ ĝ`` (so ``ĝ = g ⊕ ε``): ``(x, y)`` in metres and ``θ`` in radians, in the frame of
the pose itself (the robot's frame); its covariance is the 3×3 ``E[ε εᵀ]``, rows and columns
``x, y, θ``. All three are first order (ε small).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TypeGuard

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

__all__ = [
    "Pose2D",
    "wrap_angle",
    "compose",
    "inverse",
    "relative",
    "compose3",
    "relative3",
    "transform_points",
    "rotation_matrix",
    "circular_mean",
    "stack_columns",
    "compose_jacobians",
    "propagate",
    "covariance_to_parent",
    "Cov3Upper",
    "propagate3",
    "covariance_to_parent3",
    "adjoint",
    "compose_steps",
    "inverse_covariance",
    "covariances_to_parent",
]


def wrap_angle(angle: ArrayLike) -> FloatArray:
    """Wrap angles to ``[-pi, pi)``; exact for inputs already in range."""
    a = np.asarray(angle, dtype=float)
    out = np.mod(a + np.pi, 2.0 * np.pi) - np.pi
    # mod can round up to exactly 2*pi (e.g. for a just below -pi), giving +pi: fold it to -pi
    out = np.where(out >= np.pi, -np.pi, out)
    # keep values already inside the interval bit-exact (mod can perturb the last digit)
    inside = (a >= -np.pi) & (a < np.pi)
    return np.where(inside, a, out)


def stack_columns(*cols: NDArray) -> NDArray:
    """Stack equal-length 1-D arrays as the columns of a 2-D array (np.column_stack without
    its per-call overhead, which counts on hot paths of a few hundred points)."""
    out = np.empty((cols[0].shape[0], len(cols)), dtype=np.result_type(*cols))
    for k, c in enumerate(cols):
        out[:, k] = c
    return out


def _wrap_scalar(a: float) -> float:
    """:func:`wrap_angle` for one float, to the bit: Python's float ``%`` is numpy's
    ``np.mod`` for finite floats (the fmod, its sign turned to the divisor's), without the
    arrays."""
    if -math.pi <= a < math.pi:
        return a
    if not math.isfinite(a):
        return float(wrap_angle(a))
    out = (a + math.pi) % _TWO_PI - math.pi
    return -math.pi if out >= math.pi else out


_TWO_PI = 2.0 * math.pi


#: the dtype of the pose arrays the fast paths of :func:`compose` and :func:`relative` take
_FLOAT64 = np.dtype(np.float64)


def _one_pose(p: ArrayLike) -> TypeGuard[FloatArray]:
    """Whether ``p`` is one pose as a float64 array (the pipeline's own: its floats need no
    conversion)."""
    return type(p) is np.ndarray and p.shape == (3,) and p.dtype is _FLOAT64


def _as_poses(p: ArrayLike) -> FloatArray:
    arr = np.asarray(p, dtype=float)
    if arr.shape[-1:] != (3,):
        raise ValueError(
            f"poses must have a last axis of length 3 (x, y, theta), got shape {arr.shape}"
        )
    return arr


def _as_points(p: ArrayLike) -> FloatArray:
    arr = np.asarray(p, dtype=float)
    if arr.shape[-1:] != (2,):
        raise ValueError(f"points must have a last axis of length 2 (x, y), got shape {arr.shape}")
    return arr


def rotation_matrix(theta: ArrayLike) -> FloatArray:
    """Rotation matrices ``(..., 2, 2)`` for angles ``(...)``."""
    t = np.asarray(theta, dtype=float)
    c, s = np.cos(t), np.sin(t)
    return np.stack([np.stack([c, -s], axis=-1), np.stack([s, c], axis=-1)], axis=-2)


def compose(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """``a ⊕ b``: the pose ``b`` (given in the frame of ``a``) in the frame ``a`` is given in."""
    if _one_pose(a) and _one_pose(b):  # one pose each, float64 already: no conversions
        return np.array(_compose_floats(*a.tolist(), *b.tolist()))
    a = _as_poses(a)
    b = _as_poses(b)
    if a.ndim == 1 and b.ndim == 1:  # one pose each: scalar arithmetic, far fewer calls
        return np.array(_compose_floats(*a.tolist(), *b.tolist()))
    ca, sa = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + ca * b[..., 0] - sa * b[..., 1]
    y = a[..., 1] + sa * b[..., 0] + ca * b[..., 1]
    th = wrap_angle(a[..., 2] + b[..., 2])
    return np.stack(np.broadcast_arrays(x, y, th), axis=-1)


def inverse(a: ArrayLike) -> FloatArray:
    """``⊖a``: the pose of the outer frame seen from ``a``."""
    a = _as_poses(a)
    if a.ndim == 1:
        return np.array(_inverse_floats(*a.tolist()))
    ca, sa = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -(ca * a[..., 0] + sa * a[..., 1])
    y = sa * a[..., 0] - ca * a[..., 1]
    return np.stack([x, y, wrap_angle(-a[..., 2])], axis=-1)


def relative(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """``⊖a ⊕ b``: the pose ``b`` in the frame of ``a`` (e.g. the odometry increment)."""
    if _one_pose(a) and _one_pose(b):  # one pose each, float64 already: no conversions
        ia = _inverse_floats(*a.tolist())
        return np.array(_compose_floats(*ia, *b.tolist()))
    a = _as_poses(a)
    b = _as_poses(b)
    if a.ndim == 1 and b.ndim == 1:  # as compose(inverse(a), b), without the arrays between
        return np.array(_compose_floats(*_inverse_floats(*a.tolist()), *b.tolist()))
    return compose(inverse(a), b)


#: one pose as three floats ``(x, y, theta)``: what the per-scan pipeline computes with where
#: an array per pose would cost more than the arithmetic
Pose3 = tuple[float, float, float]


def compose3(a: Pose3, b: Pose3) -> Pose3:
    """:func:`compose` of one pose each as float triples (bit-identical to it; no checks: the
    pipeline's own finite poses)."""
    return _compose_floats(a[0], a[1], a[2], b[0], b[1], b[2])


def relative3(a: Pose3, b: Pose3) -> Pose3:
    """:func:`relative` of one pose each as float triples (bit-identical to it; no checks)."""
    ix, iy, it = _inverse_floats(a[0], a[1], a[2])
    return _compose_floats(ix, iy, it, b[0], b[1], b[2])


def _compose_floats(
    ax: float, ay: float, at: float, bx: float, by: float, bt: float
) -> tuple[float, float, float]:
    """:func:`compose` of one pose each, in floats (the very arithmetic of the arrays')."""
    c, s = math.cos(at), math.sin(at)
    t = at + bt
    if not -math.pi <= t < math.pi:  # (_wrap_scalar, inlined: the range check is the common case)
        t = _wrap_scalar(t)
    return ax + c * bx - s * by, ay + s * bx + c * by, t


def _inverse_floats(ax: float, ay: float, at: float) -> tuple[float, float, float]:
    """:func:`inverse` of one pose, in floats."""
    c, s = math.cos(at), math.sin(at)
    t = -at
    if not -math.pi <= t < math.pi:  # (_wrap_scalar, inlined)
        t = _wrap_scalar(t)
    return -(c * ax + s * ay), s * ax - c * ay, t


def transform_points(pose: ArrayLike, points: ArrayLike) -> FloatArray:
    """Map points given in the frame ``pose`` into the frame ``pose`` is given in.

    ``pose`` is ``(3,)`` or ``(..., 3)`` and ``points`` ``(..., 2)``; the leading axes broadcast
    as in numpy (one pose per point for ``(N, 3)`` with ``(N, 2)``). To move a set of ``M``
    points by each of ``N`` poses, pass ``pose[:, None, :]`` with ``(M, 2)`` or ``(N, M, 2)``.
    """
    pose = _as_poses(pose)
    pts = _as_points(points)
    if pose.ndim == 1 and pts.ndim == 2:  # one pose, a list of points: the hot path
        c, s = math.cos(pose[2]), math.sin(pose[2])
        out = np.empty_like(pts)
        out[:, 0] = pose[0] + c * pts[:, 0] - s * pts[:, 1]
        out[:, 1] = pose[1] + s * pts[:, 0] + c * pts[:, 1]
        return out
    ca, sa = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    tx, ty = pose[..., 0], pose[..., 1]
    x = tx + ca * pts[..., 0] - sa * pts[..., 1]
    y = ty + sa * pts[..., 0] + ca * pts[..., 1]
    return np.stack([x, y], axis=-1)


def circular_mean(angles: ArrayLike, weights: ArrayLike | None = None) -> float:
    """Weighted circular mean of angles (SPEC's fix of eq. 24). Returns 0.0 for no weight."""
    a = np.asarray(angles, dtype=float)
    w = np.ones_like(a) if weights is None else np.asarray(weights, dtype=float)
    s = float(np.sum(w * np.sin(a)))
    c = float(np.sum(w * np.cos(a)))
    if s == 0.0 and c == 0.0:
        return 0.0
    return float(wrap_angle(np.arctan2(s, c)))  # arctan2 can return +pi; keep [-pi, pi)


def _as_cov3(c: ArrayLike, name: str) -> FloatArray:
    arr = np.asarray(c, dtype=float)
    if arr.shape != (3, 3):
        raise ValueError(f"{name} must be a 3x3 covariance (x, y, theta), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr


def compose_jacobians(a: ArrayLike, b: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """The Jacobians ``(∂(a ⊕ b)/∂a, ∂(a ⊕ b)/∂b)`` (3×3 each) of :func:`compose` in the
    coordinates ``(x, y, θ)``, for one pose each.

    With ``c, s = cos θ_a, sin θ_a``: ``∂/∂a = [[1, 0, -s·b_x - c·b_y], [0, 1, c·b_x - s·b_y],
    [0, 0, 1]]`` and ``∂/∂b = [[c, -s, 0], [s, c, 0], [0, 0, 1]]`` (θ of the result unwrapped).
    """
    a = _as_poses(a).reshape(-1)
    b = _as_poses(b).reshape(-1)
    if a.shape != (3,) or b.shape != (3,):
        raise ValueError("compose_jacobians takes one pose each")
    at, (bx, by, _) = float(a[2]), b.tolist()
    c, s = math.cos(at), math.sin(at)
    ja = np.array([[1.0, 0.0, -s * bx - c * by], [0.0, 1.0, c * bx - s * by], [0, 0, 1.0]])
    jb = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return ja, jb


def propagate(pose_cov: ArrayLike, increment: ArrayLike, increment_cov: ArrayLike) -> FloatArray:
    """The covariance of ``p̂ ⊕ û`` from that of a pose ``p̂`` and of an increment ``û`` (the
    pose of the next frame in the frame of ``p̂``), their errors independent.

    Errors are right perturbations (module docstring): ``p̂ = p ⊕ e``, ``û = u ⊕ ε``, so the
    error of the composition is ``⊖(p ⊕ u) ⊕ (p̂ ⊕ û) = ⊖u ⊕ e ⊕ u ⊕ ε ≈ A·e + ε`` with
    ``A = ∂(⊖u ⊕ e ⊕ u)/∂e`` at ``e = 0`` ``= [[Rᵀ, Rᵀ·(-u_y, u_x)ᵀ], [0, 0, 1]]`` (``R`` the
    rotation by ``u_θ``): the pose's error moved into the new frame. The result,
    ``A·pose_cov·Aᵀ + increment_cov``, is in the new pose's frame, as both inputs are in
    their own; it does not depend on where the pose is. ``A`` is evaluated at ``û``.
    """
    pc = _as_cov3(pose_cov, "pose_cov")
    ic = _as_cov3(increment_cov, "increment_cov")
    u = _as_poses(increment).reshape(-1)
    if u.shape != (3,):
        raise ValueError("propagate takes one increment")
    ja, _ = compose_jacobians(inverse(u), u)  # ⊖u ⊕ e ⊕ u = (⊖u ⊕ e) ⊕ u, about e = 0
    _, je = compose_jacobians(inverse(u), np.zeros(3))
    a = ja @ je
    out: FloatArray = a @ pc @ a.T + ic
    sym: FloatArray = 0.5 * (out + out.T)
    return sym


def covariance_to_parent(pose: ArrayLike, cov: ArrayLike) -> FloatArray:
    """A pose's error covariance ``cov`` (in the pose's own frame, module docstring) in the
    frame the pose is given in, as additive errors of its ``(x, y, θ)`` there:
    ``J·cov·Jᵀ`` with ``J = ∂(p ⊕ e)/∂e`` at ``e = 0`` = the rotation by ``θ`` on ``x, y``
    (what ROS's ``PoseWithCovariance`` holds: the covariance in the header's frame)."""
    c3 = _as_cov3(cov, "cov")
    _, j = compose_jacobians(pose, np.zeros(3))
    out: FloatArray = j @ c3 @ j.T
    sym: FloatArray = 0.5 * (out + out.T)
    return sym


#: a 3×3 covariance as the six floats of its upper triangle, ``(xx, xy, xθ, yy, yθ, θθ)``
Cov3Upper = tuple[float, float, float, float, float, float]


def propagate3(pose_cov: Cov3Upper, increment: Pose3, increment_cov: Cov3Upper) -> Cov3Upper:
    """:func:`propagate` in floats, the covariances as upper triangles (:data:`Cov3Upper`):
    ``A·pose_cov·Aᵀ + increment_cov`` with ``A = [[c, s, s·u_x − c·u_y], [−s, c, s·u_y +
    c·u_x], [0, 0, 1]]`` (``c, s = cos u_θ, sin u_θ``); equal to it to rounding, without
    the arrays (once a scan, for a whole run). No checks."""
    p00, p01, p02, p11, p12, p22 = pose_cov
    ux, uy, ut = increment
    c, s = math.cos(ut), math.sin(ut)
    a, b = s * ux - c * uy, s * uy + c * ux
    # Q = A·P, then Q·Aᵀ (upper triangle; Q's third row is P's)
    q00, q01, q02 = (
        c * p00 + s * p01 + a * p02,
        c * p01 + s * p11 + a * p12,
        c * p02 + s * p12 + a * p22,
    )
    q11, q12 = -s * p01 + c * p11 + b * p12, -s * p02 + c * p12 + b * p22
    q10 = -s * p00 + c * p01 + b * p02
    i00, i01, i02, i11, i12, i22 = increment_cov
    return (
        q00 * c + q01 * s + q02 * a + i00,
        -q00 * s + q01 * c + q02 * b + i01,
        q02 + i02,
        -q10 * s + q11 * c + q12 * b + i11,
        q12 + i12,
        p22 + i22,
    )


def covariance_to_parent3(theta: float, cov: Cov3Upper) -> Cov3Upper:
    """:func:`covariance_to_parent` in floats for a pose of heading ``theta``, the covariances
    as upper triangles (:data:`Cov3Upper`): ``J·cov·Jᵀ``, ``J`` the rotation by ``theta`` on
    ``x, y``. No checks."""
    p00, p01, p02, p11, p12, p22 = cov
    c, s = math.cos(theta), math.sin(theta)
    q00, q01 = c * p00 - s * p01, c * p01 - s * p11
    q10, q11 = s * p00 + c * p01, s * p01 + c * p11
    return (
        q00 * c - q01 * s,
        q00 * s + q01 * c,
        c * p02 - s * p12,
        q10 * s + q11 * c,
        s * p02 + c * p12,
        p22,
    )


# -- SE(2) covariance composition (right perturbations) --------------------------------------
def adjoint(pose: ArrayLike) -> FloatArray:
    """The adjoint of an SE(2) element ``(x, y, θ)`` for right perturbations ``(x, y, θ)``:
    ``T ⊕ ε ⊕ ⊖T ≈ Ad(T)·ε`` to first order, ``[[c, −s, y], [s, c, −x], [0, 0, 1]]``; for
    ``(n, 3)`` poses, ``(n, 3, 3)``."""
    p = np.asarray(pose, dtype=float)
    x, y, th = p[..., 0], p[..., 1], p[..., 2]
    c, s = np.cos(th), np.sin(th)
    zero, one = np.zeros_like(th), np.ones_like(th)
    rows = [[c, -s, y], [s, c, -x], [zero, zero, one]]
    out: FloatArray = np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)
    return out


def compose_steps(steps: ArrayLike, covariances: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """The composition ``T = s₁ ⊕ s₂ ⊕ … ⊕ sₙ`` of ``steps`` ``(n, 3)`` and the covariance
    of its right-perturbation error from the steps' ``covariances`` ``(n, 3, 3)`` (each in its
    own step's frame, independent): step by step, for ``T ⊕ s``,
    ``Σ ← Ad(⊖s)·Σ·Ad(⊖s)ᵀ + Σ_s`` (first order; :func:`propagate`'s). No steps: the
    identity and zeros."""
    s = np.asarray(steps, dtype=float).reshape(-1, 3)
    c = np.asarray(covariances, dtype=float).reshape(-1, 3, 3)
    if s.shape[0] != c.shape[0]:
        raise ValueError(f"{s.shape[0]} steps but {c.shape[0]} covariances")
    total = np.zeros(3)
    sigma = np.zeros((3, 3))
    for step, cov in zip(s, c, strict=True):
        a = adjoint(inverse(step))
        sigma = a @ sigma @ a.T + cov
        total = compose(total, step)
    return total, 0.5 * (sigma + sigma.T)


def inverse_covariance(motion: ArrayLike, sigma: ArrayLike) -> FloatArray:
    """The covariance of ``⊖T``'s right-perturbation error from ``T``'s (first order):
    ``⊖(T ⊕ ε) = ⊖T ⊕ (−Ad(T)·ε)``, so ``Ad(T)·Σ·Ad(T)ᵀ``."""
    a = adjoint(motion)
    out: FloatArray = a @ np.asarray(sigma, dtype=float) @ a.T
    sym: FloatArray = 0.5 * (out + out.T)
    return sym


def covariances_to_parent(poses: ArrayLike, covariances: ArrayLike) -> FloatArray:
    """:func:`covariance_to_parent` for ``(n, 3)`` poses and their ``(n, 3, 3)`` covariances
    (each in its own pose's frame): ``R·Σ·Rᵀ``, ``R = blockdiag(rot(θ), 1)``."""
    p = _as_poses(poses).reshape(-1, 3)
    c = np.asarray(covariances, dtype=float).reshape(-1, 3, 3)
    r = adjoint(np.column_stack((np.zeros((len(p), 2)), p[:, 2])))
    out: FloatArray = r @ c @ np.swapaxes(r, -1, -2)
    sym: FloatArray = 0.5 * (out + np.swapaxes(out, -1, -2))
    return sym


@dataclass(frozen=True)
class Pose2D:
    """A pose in SE(2): position ``(x, y)`` in metres and heading ``theta`` in radians."""

    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x", "y", "theta"):
            v = getattr(self, name)
            try:
                fv = float(v)
            except (TypeError, ValueError):
                raise ValueError(f"Pose2D.{name} must be a number, got {v!r}") from None
            if not math.isfinite(fv):
                raise ValueError(f"Pose2D.{name} must be finite, got {fv}")
            object.__setattr__(self, name, fv)
        if not -math.pi <= self.theta < math.pi:
            object.__setattr__(self, "theta", _wrap_scalar(self.theta))

    @classmethod
    def _trusted(cls, x: float, y: float, theta: float) -> Pose2D:
        """Build from finite floats with ``theta`` already wrapped (no checks: internal use)."""
        p = object.__new__(cls)
        # straight into the instance's dict (the frozen __setattr__ would refuse; going
        # around it with object.__setattr__ takes longer, three times a scan)
        fields = p.__dict__
        fields["x"], fields["y"], fields["theta"] = x, y, theta
        return p

    @classmethod
    def from_array(cls, arr: ArrayLike) -> Pose2D:
        a = np.asarray(arr, dtype=float).reshape(-1)
        if a.shape != (3,):
            raise ValueError(f"a pose array needs 3 values (x, y, theta), got {a.shape[0]}")
        return cls(float(a[0]), float(a[1]), float(a[2]))

    @classmethod
    def of(cls, pose: Pose2D | Sequence[float], name: str = "pose") -> Pose2D:
        """``pose`` as a Pose2D: itself, or a sequence ``(x, y, theta)`` of three finite
        numbers (a tuple, a list, a 1-D array). A ``TypeError`` for anything else, a
        ``ValueError`` for another length or a value that is no finite number, each naming
        ``name``."""
        if isinstance(pose, Pose2D):
            return pose
        is_1d = isinstance(pose, Sequence) or (isinstance(pose, np.ndarray) and pose.ndim == 1)
        if isinstance(pose, (str, bytes)) or not is_1d:
            raise TypeError(f"{name} must be a Pose2D or (x, y, theta), got {type(pose).__name__}")
        if len(pose) != 3:
            raise ValueError(f"{name} must be (x, y, theta), got {len(pose)} values")
        try:
            return cls(*pose)  # (its checks: each a finite number)
        except ValueError as exc:
            raise ValueError(f"{name}: {exc}") from None

    @classmethod
    def identity(cls) -> Pose2D:
        return cls(0.0, 0.0, 0.0)

    def as_array(self) -> FloatArray:
        return np.array([self.x, self.y, self.theta], dtype=float)

    def __iter__(self) -> Iterator[float]:
        return iter((self.x, self.y, self.theta))

    def compose(self, other: Pose2D) -> Pose2D:
        """``self ⊕ other``."""
        return Pose2D.from_array(compose(self.as_array(), other.as_array()))

    def __matmul__(self, other: Pose2D) -> Pose2D:
        return self.compose(other)

    def inverse(self) -> Pose2D:
        """``⊖self``."""
        return Pose2D.from_array(inverse(self.as_array()))

    def relative_to(self, other: Pose2D) -> Pose2D:
        """``⊖other ⊕ self``: this pose in the frame of ``other``."""
        return Pose2D.from_array(relative(other.as_array(), self.as_array()))

    def transform_points(self, points: ArrayLike) -> FloatArray:
        """Points given in this pose's frame, in the frame this pose is given in."""
        return transform_points(self.as_array(), points)

    @property
    def translation_norm(self) -> float:
        return float(np.hypot(self.x, self.y))
