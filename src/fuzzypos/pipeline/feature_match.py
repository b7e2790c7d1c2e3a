"""The feature matching stage: line-to-line matching from the prior first, then the paper's
feature points (§3.7, §4) refined by line matching."""

from __future__ import annotations

import functools
import importlib
import math
from dataclasses import dataclass
from types import ModuleType

import numpy as np
from numpy.typing import NDArray

from .._kernels import f64, packing
from ..config import FusionConfig, MatchingConfig
from ..features import FeatureError, FeaturePoints, Features, Lines
from ..matching import estimate_increment, pair_features
from ..matching._robust import MAD_TO_SIGMA, OUTLIER_SIGMAS
from .estimate import Reason

__all__ = ["FeatureMatch", "FeatureMatcher"]

FloatArray = NDArray[np.float64]


@functools.cache
def _kernels() -> ModuleType:
    """The compiled kernels (``_kernels.lines``), imported with numba on first use and kept
    (``import fuzzypos`` does not import numba)."""
    return importlib.import_module("fuzzypos._kernels.lines")


@dataclass(frozen=True, eq=False)
class FeatureMatch:
    """The motion from the keyframe's features to the scan's (None where nothing gave one),
    the pairs it rests on (line pairs where line matching gave it), and why: ``MATCHED``, or
    why no motion came of the point features."""

    increment: FloatArray | None
    n_pairs: int
    reason: Reason

    @classmethod
    def _of(cls, increment: FloatArray | None, n_pairs: int, reason: Reason) -> FeatureMatch:
        """What the constructor builds, straight into the instance's dict (the frozen
        ``__init__``'s ``object.__setattr__`` per field costs more; once a scan)."""
        out = object.__new__(cls)
        out.__dict__.update(increment=increment, n_pairs=n_pairs, reason=reason)
        return out


class FeatureMatcher:
    """Matches a scan's features against the keyframe's (``[matching]``, ``[fusion]``)."""

    def __init__(self, matching: MatchingConfig, fusion: FusionConfig) -> None:
        self.matching = matching
        self.fusion = fusion
        m = matching
        # the line-matching kernel's settings from the prior (True) or from a start (False)
        # and its params: the section's alone
        self._line_settings = {
            from_prior: np.array([
                *((m.line_angle_gate_prior, m.line_distance_gate_prior) if from_prior
                  else (m.line_angle_gate, m.line_distance_gate)),
                m.line_angle_gate, m.line_distance_gate, m.line_overlap_margin,
                m.line_repair_fraction,
            ])
            for from_prior in (True, False)
        }  # fmt: skip
        self._line_params = np.array([
            m.line_prior_sigma, m.line_trim_angle, m.line_inlier_distance,
            math.sin(m.line_consensus_angle), OUTLIER_SIGMAS * MAD_TO_SIGMA,
        ])  # fmt: skip
        # the kernel's arrays of the last two scans' lines (the keyframe's among them: every
        # scan matched against it reads them), the most recently read first
        self._recent: list[tuple[Lines, _LineArrays]] = []
        # the keyframe's lines that :meth:`lines_first_inputs` last read and their arrays (every
        # scan matched against the keyframe reads them)
        self._keyframe_lines: tuple[Lines, _LineArrays] | None = None

    def _arrays_of(self, lines: Lines) -> _LineArrays:
        """:func:`_line_arrays` of ``lines``, built once while they are among the last two
        (the compiled chain's lines: their packed floats, nothing to build)."""
        if "_packed" in lines.__dict__:
            return _line_arrays(lines)
        recent = self._recent
        for k, (seen, arrays) in enumerate(recent):
            if seen is lines:
                if k:
                    recent.insert(0, recent.pop(k))
                return arrays
        arrays = _line_arrays(lines)
        recent.insert(0, (lines, arrays))
        del recent[2:]
        return arrays

    def match(self, prev: Features, curr: Features, prior: FloatArray) -> FeatureMatch:
        """The motion from ``prev`` to ``curr``: line matching from ``prior`` first (where
        configured), else the paper's point pairing (refined by line matching)."""
        m = self.matching
        lines_tried = m.match_lines and m.lines_first
        if lines_tried:
            increment, n_lines = self.match_lines(prev.lines, curr.lines, None, prior)
            if increment is not None:
                return FeatureMatch._of(increment, n_lines, Reason.MATCHED)
        return self.match_after_lines(prev, curr, prior)

    def match_after_lines(self, prev: Features, curr: Features, prior: FloatArray) -> FeatureMatch:
        """:meth:`match` where the lines matched from the prior gave no motion (or were not
        tried first): the point pairing, refined by line matching."""
        m = self.matching
        lines_tried = m.match_lines and m.lines_first
        points = self.match_points(prev.points_of_interest, curr.points_of_interest, prior)
        if m.match_lines and (points.increment is not None or not lines_tried):
            refined, n_lines = self.match_lines(prev.lines, curr.lines, points.increment, prior)
            if refined is not None:
                return FeatureMatch._of(refined, n_lines, Reason.MATCHED)
        return points

    def lines_first_inputs(self, prev: Features, curr: Features) -> _LinesFirst | None:
        """What ``_kernels.lines.match_lines`` reads for :meth:`match`' first try (the lines
        from the prior) but the prior itself: both scans' line arrays, the prior's gates,
        the params, the passes and the least pairs; None where that try is not the compiled
        one's (not configured, lines without variances, or none)."""
        keyframe = self.keyframe_inputs(prev)
        if keyframe is None:
            return None
        b = curr.lines
        if not _has_variances(b) or len(b) == 0:
            return None
        of_prev, settings, params, passes, min_pairs = keyframe
        return (*of_prev, *self._arrays_of(b), settings, params, passes, min_pairs)

    def keyframe_inputs(self, prev: Features) -> _KeyframeLines | None:
        """:meth:`lines_first_inputs` but the scan's own lines (the compiled chain's, which
        come with variances: its lines are compiled with the scan's features, ``_kernels.step``):
        the keyframe's line arrays, the prior's gates, the params, the passes and the least
        pairs; None where that try is not the compiled one's."""
        m = self.matching
        if not (m.match_lines and m.lines_first):
            return None
        a = prev.lines
        last = self._keyframe_lines
        if last is not None and last[0] is a:
            of_prev = last[1]
        elif _has_variances(a) and len(a) > 0:
            of_prev = self._arrays_of(a)
            self._keyframe_lines = (a, of_prev)
        else:
            return None
        return (
            of_prev, self._line_settings[True], self._line_params, int(m.line_passes),
            int(m.line_min_pairs),
        )  # fmt: skip

    def match_points(
        self, prev: FeaturePoints, curr: FeaturePoints, prior: FloatArray
    ) -> FeatureMatch:
        """The paper's way (§3.7, §4): pair the feature points with the prior, the pose from
        every two pairs, fusion."""
        m = self.matching
        if len(prev) < m.min_pairs or len(curr) < m.min_pairs:
            return FeatureMatch(None, 0, Reason.TOO_FEW_FEATURES)
        pairs = pair_features(prev, curr, prior, m.pairing_distance, m.same_kind_only, m.mutual)
        est, n_used = estimate_increment(pairs, self.fusion, m.min_pair_separation, m.min_pairs)
        if est is None:
            return FeatureMatch(None, len(pairs), Reason.TOO_FEW_PAIRS)
        return FeatureMatch(est, n_used, Reason.MATCHED)

    def match_lines(
        self, prev: Lines, curr: Lines, start: FloatArray | None, prior: FloatArray
    ) -> tuple[FloatArray | None, int]:
        """Line-to-line matching from the point features' motion ``start`` (or the prior,
        with the wider gates), and once more from its own result where that moved enough to
        change the pairs (at most ``line_passes`` passes), in one compiled loop
        (``_kernels.lines.match_lines``; its numpy reference is ``match_lines`` of
        ``tests/oracles/pipeline.py``). Returns the increment (None where the lines give
        none) and the number of line pairs."""
        m = self.matching
        if len(prev) == 0 or len(curr) == 0:
            return None, 0
        if not (_has_variances(prev) and _has_variances(curr)):
            raise FeatureError(
                "line matching needs the lines' variances (lines from extract_features)"
            )
        # (f64, not a copy: the kernel copies the start and writes to neither)
        found, est, n_pairs = _kernels().match_lines(
            *self._arrays_of(prev), *self._arrays_of(curr), f64(prior if start is None else start),
            f64(prior), self._line_settings[start is None], self._line_params,
            int(m.line_passes), int(m.line_min_pairs),
        )  # fmt: skip
        return (est if found else None), int(n_pairs)


def _has_variances(lines: Lines) -> bool:
    return lines.angle_variance is not None and lines.distance_variance is not None


#: :meth:`FeatureMatcher.lines_first_inputs`: the previous scan's and this one's
#: :data:`_LineArrays`, the gates, the params, the passes and the least pairs
_LinesFirst = tuple[FloatArray, int, int, FloatArray, int, int, FloatArray, FloatArray, int, int]

#: a scan's lines as the line-matching kernel reads them: a flat array of floats, the first
#: element and the number of lines (``fuzzypos._kernels.lines.LINE_FLOATS``)
_LineArrays = tuple[FloatArray, int, int]
#: :meth:`FeatureMatcher.keyframe_inputs`: the keyframe's :data:`_LineArrays`, the gates, the
#: params, the passes and the least pairs
_KeyframeLines = tuple[_LineArrays, FloatArray, FloatArray, int, int]


def _line_arrays(lines: Lines) -> _LineArrays:
    """What the line-matching kernel reads of a scan's lines: the compiled chain's packed
    floats themselves where it made the lines (nothing copied: the lines' arrays sit in them
    as the kernel reads them), else one flat array of them in that layout. The kernel
    computes the normals' angles (``Lines.normal_angle``'s values)."""
    packed = lines.__dict__.get("_packed")
    if packed is not None:  # the compiled chain's: its floats, the lines after the points
        return packed.buffers[0], packing.lines_first(packed.sizes), packed.sizes[2]
    k = _kernels()
    nl = len(lines)
    flat = np.zeros(k.LINE_FLOATS * nl)
    for first, values in (
        (k.LINE_NORMAL, lines.normal), (k.LINE_DISTANCE, lines.distance),
        (k.LINE_CENTRE, lines.centre), (k.LINE_ANGLE_VARIANCE, lines.angle_variance),
        (k.LINE_DISTANCE_VARIANCE, lines.distance_variance), (k.LINE_LENGTH, lines.length),
    ):  # fmt: skip
        part = np.asarray(values, dtype=np.float64).ravel()
        flat[first * nl : first * nl + part.size] = part
    return flat, 0, nl
