"""A scan's features, line matching, refinement and assessment in one compiled call
(:func:`features_and_step`; ``pipeline.step.Step.run``'s common path): the feature chain
(``front.scan_features``) and the three kernels the staged path calls one after the other for
most scans, ``lines.match_lines``, ``refine.weigh_and_refine_both`` and
``pipeline.assess_and_scan_only``, with the choices its Python makes between them. Where a
stage leaves the common path (the lines give no motion, neither fit counts, the assessment
needs what only Python computes), it returns the stage it reached and the step goes on
from there with the staged calls. Its reference is that staged path itself:
``tests/pipeline/test_step.py`` checks both to the bit.

Its inputs cross as a few typed records (:class:`ScanInputs`, :class:`KeyframeInputs`,
:class:`MatchSettings`, :class:`RefineSettings`, :class:`AssessInputs`), not as dozens of
positional arguments, and its values come back as one (:class:`Stepped`, named at the call,
:func:`run`)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ._jit import kernel
from .front import ChainSizes, scan_features
from .lines import match_lines
from .pipeline import AssessInputs, FitValues, assess_and_scan_only
from .refine import FROM_START, NEITHER, weigh_and_refine_both

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: the stage :func:`features_and_step` reached: the lines gave no motion; they did, and
#: neither fit counts; a fit counts, its assessment left to Python; all three done; the
#: scan's features alone, the scan having no line or fewer than the
#: refinement's least points (the staged calls' cases)
NO_LINES, NOT_REFINED, REFINED, ASSESSED, FEATURES_ONLY = 0, 1, 2, 3, 4
#: the rows of the returned (10, 3, 3) array: the lines' motion (its first row), the fit's
#: four (``refine.refine``'s), the assessment's five (``assess_and_scan_only``'s)
LINES, FIT, ASSESSMENT = 0, 1, 5


class ScanInputs(NamedTuple):
    """What the feature chain (``front.scan_features``) reads of a scan and the config
    (``fuzzypos.features.chain.chain_inputs``' values, in its order)."""

    ranges: FloatArray
    directions: FloatArray
    valid: BoolArray
    angle_increment: float
    sensor_x: float
    sensor_y: float
    sensor_theta: float
    closed: bool
    settings: FloatArray


class KeyframeInputs(NamedTuple):
    """The keyframe as the match and the refinement read it: its lines' floats, the first
    and their number (``lines.LINE_FLOATS`` each), and its surface's grid and table."""

    lines: FloatArray
    first: int
    n: int
    geometry: FloatArray
    shape: IntArray
    cells: IntArray
    table: FloatArray


class MatchSettings(NamedTuple):
    """The line match's settings (the prior's gates, the params, the passes and the least
    pairs), where the scan's lines begin in the chain's packed floats per size
    (``packing.LAYOUT``'s) and the refinement's least points."""

    line_gates: FloatArray
    line_params: FloatArray
    passes: int
    min_pairs: int
    lines_at: IntArray
    min_points: int


class RefineSettings(NamedTuple):
    """The refinement's settings: the weighing's, the pairing distances, the params, the
    iterations, the prior's diagonal, both fits' information (the learned one's 3×3 where
    ``full``), whether the fit is held to the features' motion, and the checks."""

    weighing: FloatArray
    gates: FloatArray
    params: FloatArray
    iterations: int
    prior_diag: FloatArray
    information: FloatArray
    full: bool
    prior_from_features: bool
    checks: FloatArray


class Stepped(NamedTuple):
    """:func:`features_and_step`' values, named (:func:`run`): the chain's (the scales, the sizes
    and the packed floats, integers and masks), the ``stage`` reached, the line pairs,
    ``weigh_and_refine_both``' which, paired, close and on-start, the assessment's ``gate``, whether
    the scan alone fixes the motion (``scan_alone``) and the (10, 3, 3) array its properties
    read."""

    scale: float
    line_scale: float
    sizes: ChainSizes
    floats: FloatArray
    integers: IntArray
    masks: BoolArray
    stage: int
    n_pairs: int
    which: int
    paired: int
    close: int
    on_start: bool
    gate: float
    scan_alone: bool
    values: FloatArray

    @property
    def chain(self) -> tuple[float, float, ChainSizes, FloatArray, IntArray, BoolArray]:
        """The chain's values (``fuzzypos.features.extract.features_of_chain`` reads them)."""
        return self.scale, self.line_scale, self.sizes, self.floats, self.integers, self.masks

    @property
    def lines_motion(self) -> FloatArray:
        """The lines' motion from the keyframe."""
        out: FloatArray = self.values[LINES, 0]
        return out

    @property
    def fit(self) -> FloatArray:
        """The fit's four (3, 3) (``refine.refine``'s values; its increment the first row)."""
        return self.values[FIT : FIT + 4]

    @property
    def assessment(self) -> FloatArray:
        """The assessment's five (3, 3) (``pipeline.assess_and_scan_only``'s array)."""
        return self.values[ASSESSMENT : ASSESSMENT + 5]


def run(
    scan: ScanInputs,
    keyframe: KeyframeInputs,
    match: MatchSettings,
    refine: RefineSettings,
    assess: AssessInputs,
) -> Stepped:
    """:func:`features_and_step`, its values named (the one place they are taken apart)."""
    return Stepped(*features_and_step(scan, keyframe, match, refine, assess))


@kernel
def match_refine_assess(
    keyframe: KeyframeInputs,
    curr: FloatArray,
    curr_first: int,
    curr_n: int,
    points: FloatArray,
    ranges: FloatArray,
    uncertainty: FloatArray,
    match: MatchSettings,
    refine: RefineSettings,
    assess: AssessInputs,
) -> tuple[int, int, int, int, int, bool, float, bool, FloatArray]:
    """Line matching from the prior from the keyframe ``assess.key_prior`` (its gates
    ``match.line_gates``: ``FeatureMatcher.match``' first try) of the scan's lines (``curr``
    from ``curr_first``, ``curr_n`` of them), the refinement of its ``points`` from the
    lines' motion (``Refiner.refine``: held to that motion where ``prior_from_features`` and
    no learned information is given, else to the key prior; the learned information's 3×3
    where ``full``, else the diagonal's, for both fits), and its assessment
    (``Uncertainty.assess`` of the refined match, with the scan's own motion where
    ``wanted``; where the key prior is not the assessment's, the kernel stops before it
    unless the fit holds the start). Returns the stage reached (:data:`NO_LINES` …
    :data:`ASSESSED`), the line pairs, ``weigh_and_refine_both``' which, paired, close and
    on-start, the assessment's gate and whether the scan alone fixes the motion, and one
    (10, 3, 3) array (rows as :data:`LINES`, :data:`FIT`, :data:`ASSESSMENT`)."""
    out = np.zeros((10, 3, 3))
    key_prior, r, a, k = assess.key_prior, refine, assess, keyframe
    found, est, n_pairs = match_lines(
        k.lines, k.first, k.n, curr, curr_first, curr_n, key_prior, key_prior, match.line_gates,
        match.line_params, match.passes, match.min_pairs,
    )  # fmt: skip
    if not found:
        return NO_LINES, n_pairs, NEITHER, 0, 0, False, 0.0, False, out
    out[LINES, 0] = est
    # (Refiner.starts: the lines' motion the start, the prior and the hold)
    fit_prior = est if r.prior_from_features and not r.full else key_prior
    which, paired, close, on_start, result = weigh_and_refine_both(
        k.geometry, k.shape, k.cells, k.table, points, ranges, uncertainty, r.weighing, est,
        fit_prior, key_prior, r.gates, r.params, r.iterations, r.prior_diag, r.information,
        r.full, r.information, r.full, r.checks,
    )  # fmt: skip
    if which == NEITHER:
        return NOT_REFINED, n_pairs, which, 0, 0, False, 0.0, False, out
    out[FIT : FIT + 4] = result
    # (the fit's prior and start: Refinement's, as matching.surface.refine_both gives them)
    held, begin = (fit_prior, est) if which == FROM_START else (key_prior, key_prior)
    if on_start:
        target = begin
    elif a.key_prior_known:
        target = key_prior
    else:
        return REFINED, n_pairs, which, paired, close, on_start, 0.0, False, out
    increment = result[0, 0].copy()
    has_fit = which != NEITHER  # (True, typed a bool: a literal True would compile the
    # assessment once more, beside the staged calls' bool)
    fit = FitValues(result[1], r.information, result[2], result[3], held, target, increment)
    gate, ok, judged = assess_and_scan_only(a, increment, has_fit, fit)
    out[ASSESSMENT : ASSESSMENT + 5] = judged
    return ASSESSED, n_pairs, which, paired, close, on_start, gate, ok, out


@kernel
def features_and_step(
    scan: ScanInputs,
    keyframe: KeyframeInputs,
    match: MatchSettings,
    refine: RefineSettings,
    assess: AssessInputs,
) -> tuple[
    float, float, ChainSizes, FloatArray, IntArray, BoolArray, int, int, int, int, int,
    bool, float, bool, FloatArray,
]:  # fmt: skip
    """A scan's features (``front.scan_features`` of ``scan``) and, where the scan has a line and at
    least ``match.min_points`` points, its :func:`match_refine_assess` against the keyframe (the
    scan's lines, points, ranges and uncertainty read from the chain's packed floats, where
    ``match.lines_at`` says). Returns the chain's values and :func:`match_refine_assess`' (stage
    :data:`FEATURES_ONLY` where it was not run)."""
    s, lines_at = scan, match.lines_at
    scale, line_scale, sizes, fl, it, bl = scan_features(
        s.ranges, s.directions, s.valid, s.angle_increment, s.sensor_x, s.sensor_y,
        s.sensor_theta, s.closed, s.settings,
    )  # fmt: skip
    n, nl = sizes[0], sizes[2]
    if nl == 0 or n == 0 or n < match.min_points:
        return (
            scale, line_scale, sizes, fl, it, bl, FEATURES_ONLY, 0, NEITHER, 0, 0, False,
            0.0, False, np.zeros((10, 3, 3)),
        )  # fmt: skip
    first = (  # (an int64 from the start: a literal 0 would compile the step once more)
        lines_at[0] * sizes[0] + lines_at[1] * sizes[1] + lines_at[2] * sizes[2]
        + lines_at[3] * sizes[3] + lines_at[4] * sizes[4]
    )  # fmt: skip
    points = fl[: 2 * n].reshape((n, 2))
    stage, n_pairs, which, paired, close, on_start, gate, ok, out = match_refine_assess(
        keyframe, fl, first, nl, points, fl[2 * n : 3 * n], fl[4 * n : 5 * n], match, refine,
        assess,
    )  # fmt: skip
    return (
        scale, line_scale, sizes, fl, it, bl, stage, n_pairs, which, paired, close,
        on_start, gate, ok, out,
    )  # fmt: skip
