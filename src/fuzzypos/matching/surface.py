"""Beyond the paper: fuzzy-weighted point-to-line refinement of the increment against a
keyframe's surfaces (every filtered point of the scan, not only the features)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np

from .._kernels import f64
from ..config import RefinementConfig, same_as_last_call
from ._robust import MAD_TO_SIGMA, OUTLIER_SIGMAS, FloatArray, IntArray

if TYPE_CHECKING:
    from .._kernels.grid import Grid

__all__ = [
    "SurfacePoints",
    "surface_lengths",
    "surface_points",
    "Refinement",
    "refine_point_to_line",
    "refine_both",
    "refine_both_settings",
    "refinement_of",
]


@dataclass(frozen=True, eq=False)
class SurfacePoints:
    """A keyframe's filtered points with the normal of the surface through each (unit,
    robot frame), their certainty ``weight`` (1 − the fuzzy uncertainty of eq. 4) and a grid
    over them for the kernels' look-ups (built on first use). Points with no neighbour on
    their surface are left out."""

    xy: FloatArray
    normal: FloatArray
    weight: FloatArray

    def __len__(self) -> int:
        return int(self.xy.shape[0])

    @cached_property
    def grid(self) -> Grid:
        """The points sorted into a grid of GRID_CELL cells, built once (first use)."""
        from .._kernels.grid import build_grid

        return build_grid(self.xy, GRID_CELL)

    @cached_property
    def table(self) -> FloatArray:
        """The points in ``grid``'s order, a row each: x, y, the normal's x and y, the weight
        (the compiled refinement's one look-up per pair; built once, on first use)."""
        from .._kernels.refine import surface_table

        grid = self.grid
        return surface_table(grid.xy, f64(self.normal), f64(self.weight), grid.order)


#: what ``_kernels.refine.scan_weights`` weighs a scan's points from: their ranges, their
#: uncertainty and its settings (``_kernels.refine.WEIGHING``)
Weighing = tuple[FloatArray, FloatArray, FloatArray]

#: the side (m) of the surface grid's cells: about the refinement's pairing distance
GRID_CELL = 0.15
_NO_SPACING = np.zeros(0)  # (writeable: numba types read-only arrays apart)


def surface_lengths(
    points: FloatArray, ranges: FloatArray, angle_increment: float, cap: float
) -> FloatArray:
    """The stretch of surface each scan point stands for: the distance to its nearer neighbour
    along the scan (``points`` in beam order), at most ``cap`` beam spacings at its range
    (``cap · range · |angle_increment|``: across a gap or a jump edge the neighbour is on
    another surface), and one beam spacing for a point alone. Points that sample a wall at
    grazing incidence or far away stand for more of it than a dense patch of clutter next to
    the robot."""
    points = np.asarray(points, dtype=float)
    ranges = np.asarray(ranges, dtype=float)
    spacing: FloatArray = ranges * abs(float(angle_increment))
    n = points.shape[0]
    if n < 2:
        alone: FloatArray = spacing.copy()
        return alone
    d = np.hypot(*np.diff(points, axis=0).T)  # between consecutive points
    length = np.empty(n)
    length[0], length[-1] = d[0], d[-1]
    length[1:-1] = np.minimum(d[:-1], d[1:])
    return np.minimum(length, cap * spacing)


def surface_points(
    points: FloatArray,
    ranges: FloatArray,
    uncertainty: FloatArray,
    settings: RefinementConfig,
) -> SurfacePoints:
    """The keyframe's surfaces (``settings``: ``neighbour_distance``, ``neighbour_step``,
    ``neighbour_ratio``, ``max_bend_angle``, ``weight_floor`` of the refinement section).

    Normals from the chord between each point's ``neighbour_step``-th neighbours on either
    side in scan order, within its run of points (consecutive points no further apart than
    ``neighbour_distance`` or ``neighbour_ratio`` × their range, whichever is larger, so that
    far walls, sampled sparsely, stay one surface; at a run's end the chord stops at its last
    point). Only points on a straight stretch keep a normal: the chords to either side must
    agree in direction within ``max_bend``. One compiled loop over the points."""
    neighbour_distance, neighbour_step = settings.neighbour_distance, settings.neighbour_step
    neighbour_ratio, max_bend = settings.neighbour_ratio, settings.max_bend_angle
    xy = np.asarray(points, dtype=float).reshape(-1, 2)
    n = xy.shape[0]
    if n < 3:
        empty = np.zeros((0, 2))
        return SurfacePoints(empty, empty, np.zeros(0))
    from .._kernels.refine import surface_normals

    tan_bend = math.tan(max_bend) if max_bend < math.pi / 2 else math.inf
    params = np.array([neighbour_distance, neighbour_ratio, tan_bend, settings.weight_floor])
    return SurfacePoints(
        *surface_normals(
            np.ascontiguousarray(xy), np.ascontiguousarray(ranges, dtype=np.float64),
            np.ascontiguousarray(uncertainty, dtype=np.float64), params, int(neighbour_step),
        )
    )  # fmt: skip


@dataclass(frozen=True)
class Refinement:
    """The refined increment, how many points paired at the last iteration, the fraction of
    the scan's points that did, and the fraction that lay within half the Huber scale of
    their surface (the finer score when two refinements are compared).

    For the covariance of the result, the last iteration's normal equations: ``information``
    (the points' Σ w J Jᵀ with their weights w), ``prior_information`` (the prior's term, which
    pulls toward ``prior``), ``hold_information`` (the term that holds a corridor's unobservable
    direction at the start's value, ``hold_on_start``, or at the odometry's), the ``start``
    and ``prior`` it was given, and ``gradient_covariance`` (Σ w² σ_r² J Jᵀ, the covariance of
    the points' gradient Σ w r J under the noise σ_r² their residuals show: the weights are the
    points' certainty
    and the stretch of surface each stands for, not their inverse variances, so the estimate's
    covariance is the sandwich M⁻¹ (gradient covariance + the prior's share) M⁻¹)."""

    increment: FloatArray
    n_paired: int
    inlier_fraction: float
    close_fraction: float = 0.0
    information: FloatArray = field(default_factory=lambda: np.zeros((3, 3)))
    prior_information: FloatArray = field(default_factory=lambda: np.zeros((3, 3)))
    hold_information: FloatArray = field(default_factory=lambda: np.zeros((3, 3)))
    hold_on_start: bool = False
    start: FloatArray = field(default_factory=lambda: np.zeros(3))
    prior: FloatArray = field(default_factory=lambda: np.zeros(3))
    gradient_covariance: FloatArray = field(default_factory=lambda: np.zeros((3, 3)))

    @classmethod
    def _trusted(
        cls,
        increment: FloatArray,
        n_paired: int,
        inlier_fraction: float,
        close_fraction: float,
        information: FloatArray,
        prior_information: FloatArray,
        hold_information: FloatArray,
        hold_on_start: bool,
        start: FloatArray,
        prior: FloatArray,
        gradient_covariance: FloatArray,
    ) -> Refinement:
        """The refinement of every field, as the constructor builds it, straight into the
        instance's dict (the frozen dataclass's ``__init__`` sets each of the eleven through
        ``object.__setattr__``; the compiled refinement's)."""
        r = object.__new__(cls)
        r.__dict__.update(
            increment=increment,
            n_paired=n_paired,
            inlier_fraction=inlier_fraction,
            close_fraction=close_fraction,
            information=information,
            prior_information=prior_information,
            hold_information=hold_information,
            hold_on_start=hold_on_start,
            start=start,
            prior=prior,
            gradient_covariance=gradient_covariance,
        )
        return r


def refine_point_to_line(
    reference: SurfacePoints,
    points: FloatArray,
    weights: FloatArray,
    start: FloatArray,
    prior: FloatArray,
    hold: FloatArray,
    settings: RefinementConfig,
    *,
    max_distance: float,
    prior_scale: float,
    prior_information: FloatArray | None = None,
    spacing: FloatArray | None = None,
) -> Refinement | None:
    """Refine the increment ``start`` (the pose of the scan in the reference's frame) so that
    the scan's ``points`` land on the reference's surfaces (``settings``: the refinement
    section; the prior's standard deviations are its ``prior_sigma``/``prior_sigma_angle``
    times ``prior_scale``): Gauss-Newton on Σ w ρ(n·(T·p − q))
    with ρ Huber at ``residual_scale``, w the product of both points' certainties over
    ``point_sigma``² (a certain point's standard deviation along its normal), and the
    ``prior`` as one more measurement with standard deviations ``prior_sigma`` (translation)
    and ``prior_sigma_angle``. Where the points constrain one direction of the translation
    less than ``degenerate_ratio`` times the other (a corridor), the translation along it stays
    at ``start``'s where that lies within ``hold_tolerance`` of ``hold``'s (the odometry), else
    at ``hold``'s: the odometry keeps its say along a corridor. Each point pairs with the
    nearest reference point within a distance that shrinks from ``max_distance`` to
    ``min_distance`` over ``gate_steps`` iterations. None when no point pairs."""
    if len(reference) < 3 or points.shape[0] == 0:
        return None
    return _refine_compiled(
        reference, points, weights, start, prior, hold, settings, max_distance, prior_scale,
        prior_information, spacing,
    )  # fmt: skip


def _refine_compiled(
    reference: SurfacePoints,
    points: FloatArray,
    weights: FloatArray,
    start: FloatArray,
    prior: FloatArray,
    hold: FloatArray,
    cfg: RefinementConfig,
    max_distance: float,
    prior_scale: float,
    prior_information: FloatArray | None,
    spacing: FloatArray | None,
) -> Refinement | None:
    """:func:`refine_point_to_line` as one compiled loop (``fuzzypos._kernels.refine``)."""
    kernel = _KERNEL[0] if _KERNEL else _load_kernel()
    start = np.array(start, dtype=np.float64)
    prior = np.array(prior, dtype=np.float64)
    gates, params, info_prior, diagonal = _kernel_settings(cfg, max_distance, prior_scale)
    full = prior_information is not None
    if not full:
        prior_info = diagonal
    elif prior_scale == 1.0:  # (x / 1.0 is x to the bit: a copy, a third of the division's time)
        prior_info = np.array(prior_information, dtype=np.float64)
    else:
        prior_info = f64(prior_information) / prior_scale**2
    geometry, shape, cells, _order, _xy = reference.grid
    table = reference.table
    contiguous = np.ascontiguousarray
    # (the hold's x and y: the kernel reads those two of the pose)
    status, paired, close, on_start, result = kernel.refine(
        geometry, shape, cells, table, contiguous(points, dtype=np.float64),
        contiguous(weights, dtype=np.float64), start, prior, contiguous(hold, dtype=np.float64),
        gates, _NO_SPACING if spacing is None else contiguous(spacing, dtype=np.float64),
        params, int(cfg.iterations), info_prior, prior_info, full,
    )  # fmt: skip
    if status:  # (not kernel.OK)
        return None
    n = points.shape[0]
    return Refinement._trusted(
        result[0, 0], paired, paired / n, close / n, result[1],
        prior_info if full else prior_info.copy(), result[2], on_start, start, prior, result[3],
    )  # fmt: skip


def refine_both(
    reference: SurfacePoints,
    points: FloatArray,
    weights: FloatArray | None,
    start: FloatArray,
    prior: FloatArray,
    hold: FloatArray,
    cfg: RefinementConfig,
    checks: FloatArray,
    *,
    max_distance: float,
    prior_information: FloatArray | None,
    hold_information: FloatArray | None,
    spacing: FloatArray | None,
    weighing: Weighing | None = None,
) -> Refinement | None:
    """The fit from ``start`` held to ``prior`` and, where ``start`` and ``hold`` differ enough,
    the fit from ``hold`` held to it, each kept only where it counts, the better of the two
    (``checks`` as ``_kernels.refine.CHECKS``), in one compiled call
    (``_kernels.refine.refine_both``: ``Refiner.refine``'s steps with the refinement's compiled
    kernel, ``prior_scale`` 1). None where neither counts. ``weighing``: the points' weights
    and spacings are the ones ``_kernels.refine.scan_weights`` gives for these inputs, weighed
    in the same call (``weights`` and ``spacing`` are then not read)."""
    if len(reference) < 3 or points.shape[0] == 0:
        return None
    kernel = _KERNEL[0] if _KERNEL else _load_kernel()
    start = np.array(start, dtype=np.float64)
    prior = np.array(prior, dtype=np.float64)
    hold = np.array(hold, dtype=np.float64)
    gates, params, info_prior, diagonal = _kernel_settings(cfg, max_distance, 1.0)
    full_start, full_hold = prior_information is not None, hold_information is not None
    start_info = np.array(prior_information, dtype=np.float64) if full_start else diagonal
    hold_info = np.array(hold_information, dtype=np.float64) if full_hold else diagonal
    geometry, shape, cells, _order, _xy = reference.grid
    if weighing is not None:
        ranges, uncertainty, settings = weighing
        which, paired, close, on_start, result = kernel.weigh_and_refine_both(
            geometry, shape, cells, reference.table, f64(points), f64(ranges), f64(uncertainty),
            settings, start, prior, hold, gates, params, int(cfg.iterations), info_prior,
            start_info, full_start, hold_info, full_hold, checks,
        )  # fmt: skip
    else:
        which, paired, close, on_start, result = kernel.refine_both(
            geometry, shape, cells, reference.table, f64(points), f64(weights), start, prior,
            hold, gates, _NO_SPACING if spacing is None else f64(spacing), params,
            int(cfg.iterations), info_prior, start_info, full_start, hold_info, full_hold,
            checks,
        )  # fmt: skip
    if which == kernel.NEITHER:
        return None
    return refinement_of(
        which == kernel.FROM_START, paired, close, on_start, result, points.shape[0],
        (start, prior, start_info, full_start), (hold, hold, hold_info, full_hold),
    )  # fmt: skip


def refinement_of(
    from_start: bool,
    paired: int,
    close: int,
    on_start: bool,
    result: FloatArray,
    n: int,
    start_fit: tuple[FloatArray, FloatArray, FloatArray, bool],
    hold_fit: tuple[FloatArray, FloatArray, FloatArray, bool],
) -> Refinement:
    """The :class:`Refinement` of ``_kernels.refine.refine_both``' values (``result`` its
    (4, 3, 3) array, ``n`` the scan's points): the fit from the start (``from_start``) or
    from the hold, each given as (its start, its prior, its prior's information, whether
    that is the full 3×3 rather than the diagonal's; a prior that is its start's very
    array gets one of its own)."""
    begin, held, info, full = start_fit if from_start else hold_fit
    if held is begin:
        held = held.copy()
    return Refinement._trusted(
        result[0, 0], paired, paired / n, close / n, result[1], info if full else info.copy(),
        result[2], on_start, begin, held, result[3],
    )  # fmt: skip


def refine_both_settings(
    reference: SurfacePoints, cfg: RefinementConfig, information: FloatArray | None
) -> tuple[FloatArray, IntArray, IntArray, FloatArray, FloatArray, FloatArray, int,
           FloatArray, FloatArray, bool]:  # fmt: skip
    """What ``_kernels.refine.refine_both`` reads of the surface and the section, as
    :func:`refine_both` hands it over from ``max_distance`` (no search's): the surface's
    grid (geometry, shape, cells) and table, the pairing distances, the params, the
    iterations, the prior's diagonal information, and both fits' information (the learned
    ``information``, else the diagonal's 3×3) and whether it is the full 3×3."""
    gates, params, info_prior, diagonal = _kernel_settings(cfg, cfg.max_distance, 1.0)
    geometry, shape, cells, _order, _xy = reference.grid
    full = information is not None
    info = np.array(information, dtype=np.float64) if full else diagonal
    return (
        geometry, shape, cells, reference.table, gates, params, int(cfg.iterations), info_prior,
        info, full,
    )  # fmt: skip


_KERNEL: list[ModuleType] = []  # fuzzypos._kernels.refine, once imported


def _load_kernel() -> ModuleType:
    """The refinement's kernels' module, imported on first use (it imports numba)."""
    from .._kernels import refine

    _KERNEL.append(refine)
    return refine


@same_as_last_call
@lru_cache(maxsize=64)
def _kernel_settings(
    cfg: RefinementConfig, max_distance: float, prior_scale: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The kernel's settings that depend on the section alone (cached: not to be written to;
    not flagged read-only, which numba would compile a second time for): the pairing
    distances per iteration, its ``params`` and the prior's diagonal information (as a vector
    and as the 3×3)."""
    from .._kernels import refine as kernel

    values = {
        **{name: getattr(cfg, name) for name in kernel.PARAMS if name != "trim_sigmas"},
        "trim_sigmas": OUTLIER_SIGMAS * MAD_TO_SIGMA,
    }
    info_prior, diagonal = _prior_terms(cfg, prior_scale, None)
    out = (
        np.geomspace(max_distance, cfg.min_distance, cfg.gate_steps),
        np.array([float(values[name]) for name in kernel.PARAMS]),
        info_prior,
        diagonal,
    )
    return out


def _prior_terms(
    cfg: RefinementConfig, prior_scale: float, prior_information: FloatArray | None
) -> tuple[FloatArray, FloatArray]:
    """The prior's information: the diagonal from the section's standard deviations, and the
    3×3 used (that diagonal, or ``prior_information``: the learned odometry's), both with the
    standard deviations times ``prior_scale``."""
    prior_sigma = cfg.prior_sigma * prior_scale
    prior_sigma_angle = cfg.prior_sigma_angle * prior_scale
    info_prior = np.array([1.0 / prior_sigma**2, 1.0 / prior_sigma**2, 1.0 / prior_sigma_angle**2])
    if prior_information is None:
        return info_prior, np.diag(info_prior)
    return info_prior, np.asarray(prior_information, dtype=float) / prior_scale**2
