"""A scan's line matching, refinement and assessment in one compiled call
(``Positioner._match_refine_assess``' common path): the three kernels the positioner calls one
after the other for most scans, ``lines.match_lines``, ``refine.weigh_and_refine_both`` and
``pipeline.assess_and_scan_only``, with the choices its Python makes between them. Where a
stage leaves the common path (the lines give no motion, neither fit counts, the assessment
needs what only Python computes), it returns the stage it reached and the positioner goes on
from there with the staged calls. Its reference is that staged path itself:
``tests/test_step.py`` checks both to the bit. :func:`features_and_step` makes the scan's
features (``front.scan_features``, ``extract_features``' compiled chain) in the same call
(``Positioner._features_match_refine_assess``): the Python between the two, which reads the
chain's packed arrays for the match, left out."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ._jit import kernel
from .front import ChainSizes, scan_features
from .lines import match_lines
from .pipeline import assess_and_scan_only
from .refine import FROM_START, NEITHER, weigh_and_refine_both

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: the stage :func:`match_refine_assess` reached: the lines gave no motion; they did, and
#: neither fit counts; a fit counts, its assessment left to Python; all three done;
#: (:func:`features_and_step`) the scan's features alone, the scan having no line or fewer
#: than the refinement's least points (the staged calls' cases)
NO_LINES, NOT_REFINED, REFINED, ASSESSED, FEATURES_ONLY = 0, 1, 2, 3, 4
#: the rows of the returned (10, 3, 3) array: the lines' motion (its first row), the fit's
#: four (``refine.refine``'s), the assessment's five (``assess_and_scan_only``'s)
LINES, FIT, ASSESSMENT = 0, 1, 5


@kernel
def match_refine_assess(
    prev: FloatArray,
    prev_first: int,
    prev_n: int,
    curr: FloatArray,
    curr_first: int,
    curr_n: int,
    line_gates: FloatArray,
    line_params: FloatArray,
    passes: int,
    min_pairs: int,
    key_prior: FloatArray,
    geometry: FloatArray,
    shape: IntArray,
    cells: IntArray,
    table: FloatArray,
    points: FloatArray,
    ranges: FloatArray,
    uncertainty: FloatArray,
    weighing: FloatArray,
    gates: FloatArray,
    params: FloatArray,
    iterations: int,
    prior_diag: FloatArray,
    information: FloatArray,
    full: bool,
    prior_from_features: bool,
    checks: FloatArray,
    t_prev: FloatArray,
    prior: FloatArray,
    prior_covariance: FloatArray,
    previous: FloatArray,
    feature: FloatArray,
    floor: FloatArray,
    point_correlation: float,
    gate_open: bool,
    threshold: float,
    wanted: bool,
    max_condition: float,
    key_prior_known: bool,
) -> tuple[int, int, int, int, int, bool, float, bool, FloatArray]:
    """Line matching from the prior from the keyframe ``key_prior`` (its gates
    ``line_gates``: ``FeatureMatcher.match``' first try), the refinement from the lines'
    motion (``Refiner.refine``: held to that motion where ``prior_from_features`` and no
    learned information is given, else to ``key_prior``; ``information`` the learned one's
    3×3 where ``full``, else the diagonal ``prior_diag``'s, for both fits), and its
    assessment (``Uncertainty.assess`` of the refined match, with the scan's own motion
    where ``wanted``; ``key_prior_known``: the caller's ``key_prior`` is the assessment's,
    else the kernel stops before it unless the fit holds the start). Returns the stage
    reached (:data:`NO_LINES` … :data:`ASSESSED`), the line pairs,
    ``weigh_and_refine_both``' which, paired, close and on-start, the assessment's gate and
    whether the scan alone fixes the motion, and one (10, 3, 3) array (rows as
    :data:`LINES`, :data:`FIT`, :data:`ASSESSMENT`)."""
    out = np.zeros((10, 3, 3))
    found, est, n_pairs = match_lines(
        prev, prev_first, prev_n, curr, curr_first, curr_n, key_prior, key_prior, line_gates,
        line_params, passes, min_pairs,
    )  # fmt: skip
    if not found:
        return NO_LINES, n_pairs, NEITHER, 0, 0, False, 0.0, False, out
    out[LINES, 0] = est
    # (Positioner._refine's starts: the lines' motion the start, the prior and the hold)
    fit_prior = est if prior_from_features and not full else key_prior
    which, paired, close, on_start, result = weigh_and_refine_both(
        geometry, shape, cells, table, points, ranges, uncertainty, weighing, est, fit_prior,
        key_prior, gates, params, iterations, prior_diag, information, full, information, full,
        checks,
    )  # fmt: skip
    if which == NEITHER:
        return NOT_REFINED, n_pairs, which, 0, 0, False, 0.0, False, out
    out[FIT : FIT + 4] = result
    # (the fit's prior and start: Refinement's, as matching.surface.refine_both gives them)
    held, begin = (fit_prior, est) if which == FROM_START else (key_prior, key_prior)
    if on_start:
        target = begin
    elif key_prior_known:
        target = key_prior
    else:
        return REFINED, n_pairs, which, paired, close, on_start, 0.0, False, out
    increment = result[0, 0].copy()
    has_fit = which != NEITHER  # (True, typed a bool: a literal True would compile the
    # assessment once more, beside the staged calls' bool)
    gate, ok, judged = assess_and_scan_only(
        t_prev, prior, prior_covariance, previous, increment, feature, floor, has_fit, result[1],
        information, result[2], result[3], held, target, point_correlation, gate_open, threshold,
        wanted, increment, max_condition,
    )  # fmt: skip
    out[ASSESSMENT : ASSESSMENT + 5] = judged
    return ASSESSED, n_pairs, which, paired, close, on_start, gate, ok, out


@kernel
def features_and_step(
    ranges: FloatArray,
    directions: FloatArray,
    valid: BoolArray,
    angle_increment: float,
    sensor_x: float,
    sensor_y: float,
    sensor_theta: float,
    closed: bool,
    settings: FloatArray,
    lines_at: IntArray,
    min_points: int,
    prev: FloatArray,
    prev_first: int,
    prev_n: int,
    line_gates: FloatArray,
    line_params: FloatArray,
    passes: int,
    min_pairs: int,
    key_prior: FloatArray,
    geometry: FloatArray,
    shape: IntArray,
    cells: IntArray,
    table: FloatArray,
    weighing: FloatArray,
    gates: FloatArray,
    params: FloatArray,
    iterations: int,
    prior_diag: FloatArray,
    information: FloatArray,
    full: bool,
    prior_from_features: bool,
    checks: FloatArray,
    t_prev: FloatArray,
    prior: FloatArray,
    prior_covariance: FloatArray,
    previous: FloatArray,
    feature: FloatArray,
    floor: FloatArray,
    point_correlation: float,
    gate_open: bool,
    threshold: float,
    wanted: bool,
    max_condition: float,
    key_prior_known: bool,
) -> tuple[
    bool, float, float, ChainSizes, FloatArray, IntArray, BoolArray, int, int, int, int, int,
    bool, float, bool, FloatArray,
]:  # fmt: skip
    """A scan's features (``front.scan_features`` of its first nine arguments) and, where
    the chain is done and the scan has a line and at least ``min_points`` points, its
    :func:`match_refine_assess` against the keyframe (the scan's lines, points, ranges and
    uncertainty read from the chain's packed floats, as ``Positioner`` hands them over;
    ``lines_at``: where the lines begin in them per size, ``packing.LAYOUT``'s): one call
    instead of two, with nothing but the packed arrays between. Returns the chain's values
    and :func:`match_refine_assess`' (stage :data:`FEATURES_ONLY` where it was not run)."""
    done, scale, line_scale, sizes, fl, it, bl = scan_features(
        ranges, directions, valid, angle_increment, sensor_x, sensor_y, sensor_theta, closed,
        settings,
    )  # fmt: skip
    n, nl = sizes[0], sizes[2]
    if not done or nl == 0 or n == 0 or n < min_points:
        return (
            done, scale, line_scale, sizes, fl, it, bl, FEATURES_ONLY, 0, NEITHER, 0, 0, False,
            0.0, False, np.zeros((10, 3, 3)),
        )  # fmt: skip
    first = (  # (an int64 from the start: a literal 0 would compile the step once more)
        lines_at[0] * sizes[0] + lines_at[1] * sizes[1] + lines_at[2] * sizes[2]
        + lines_at[3] * sizes[3] + lines_at[4] * sizes[4]
    )  # fmt: skip
    points = fl[: 2 * n].reshape((n, 2))
    stage, n_pairs, which, paired, close, on_start, gate, ok, out = match_refine_assess(
        prev, prev_first, prev_n, fl, first, nl, line_gates, line_params, passes, min_pairs,
        key_prior, geometry, shape, cells, table, points, fl[2 * n : 3 * n], fl[4 * n : 5 * n],
        weighing, gates, params, iterations, prior_diag, information, full, prior_from_features,
        checks, t_prev, prior, prior_covariance, previous, feature, floor, point_correlation,
        gate_open, threshold, wanted, max_condition, key_prior_known,
    )  # fmt: skip
    return (
        done, scale, line_scale, sizes, fl, it, bl, stage, n_pairs, which, paired, close,
        on_start, gate, ok, out,
    )  # fmt: skip
