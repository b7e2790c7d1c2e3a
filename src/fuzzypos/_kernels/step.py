"""A scan's line matching, refinement and assessment in one compiled call
(``Positioner._match_refine_assess``' common path): the three kernels the positioner calls one
after the other for most scans, ``lines.match_lines``, ``refine.weigh_and_refine_both`` and
``pipeline.assess_and_scan_only``, with the choices its Python makes between them. Where a
stage leaves the common path (the lines give no motion, neither fit counts, the assessment
needs what only Python computes), it returns the stage it reached and the positioner goes on
from there with the staged calls. Its reference is that staged path itself:
``tests/test_step.py`` checks both to the bit."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ._jit import kernel
from .lines import match_lines
from .pipeline import assess_and_scan_only
from .refine import FROM_START, NEITHER, weigh_and_refine_both

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: the stage :func:`match_refine_assess` reached: the lines gave no motion; they did, and
#: neither fit counts; a fit counts, its assessment left to Python; all three done
NO_LINES, NOT_REFINED, REFINED, ASSESSED = 0, 1, 2, 3
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
