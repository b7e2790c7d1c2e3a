"""Fuzzy inference over triangular membership functions, and the paper's three rule bases.

Two inference modes (SPEC, "Where the paper is wrong"):

* ``"product"`` — eq. 4 (and eq. 9, 11–12): the firing strength of a rule is the product of its
  antecedent memberships, and the output is the centre-average of the rule consequents
  weighted by those strengths. This is the default.
* ``"mamdani"`` — what §2.2's text describes: min for AND, each consequent set clipped at its
  rule's strength, max aggregation, centroid defuzzification over a sampled output universe.

Everything is vectorised over the inputs: one call grades every point of a scan.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .config import FuzzyConfig
from .errors import FuzzyposError

FloatArray = NDArray[np.float64]

__all__ = [
    "FuzzyError",
    "triangular_memberships",
    "RuleBase",
    "point_rule_base",
    "line_rule_base",
    "virtual_point_rule_base",
    "compose_virtual_rules",
    "RuleBases",
    "LABELS",
]

LABELS = "SMB"


class FuzzyError(FuzzyposError, ValueError):
    """Bad input to the fuzzy engine (wrong number of inputs, mismatched shapes)."""


def _slopes(sets: ArrayLike) -> FloatArray:
    """Rows (left, 1/rise, right, 1/fall, lo, hi) for fast evaluation of triangles.

    A shoulder (a foot equal to its peak) at the end of the variable's range gets a unit
    slope on its open side, which the clamping to the range makes exactly 1 there; an
    interior foot equal to its peak is a vertical edge.
    """
    s = np.asarray(sets, dtype=float)
    left, peak, right = s[:, 0], s[:, 1], s[:, 2]
    lo, hi = s[0, 0], s[-1, 2]
    rise_w = np.where(peak > left, peak - left, np.where(peak <= lo, 1.0, 1e-12))
    fall_w = np.where(right > peak, right - peak, np.where(peak >= hi, 1.0, 1e-12))
    left_eff = np.where(peak > left, left, peak - rise_w)
    right_eff = np.where(right > peak, right, peak + fall_w)
    return np.stack(
        [
            left_eff,
            1.0 / rise_w,
            right_eff,
            1.0 / fall_w,
            np.full_like(peak, lo),
            np.full_like(peak, hi),
        ]
    )


def _partition_peaks(sets: FloatArray) -> FloatArray | None:
    """The peaks of triangles that form a partition of unity (each foot at the neighbouring
    peak, shoulders at the ends), else None."""
    s = np.asarray(sets, dtype=float)
    peaks: FloatArray = s[:, 1]
    if len(peaks) < 2 or np.any(np.diff(peaks) <= 0):
        return None
    left = np.concatenate([[peaks[0]], peaks[:-1]])
    right = np.concatenate([peaks[1:], [peaks[-1]]])
    if np.array_equal(s[:, 0], left) and np.array_equal(s[:, 2], right):
        out: FloatArray = peaks.copy()
        return out
    return None


def _memberships(x: FloatArray, slopes: FloatArray | tuple[FloatArray, ...]) -> FloatArray:
    left, inv_rise, right, inv_fall, lo, hi = slopes
    # np.minimum/np.maximum rather than np.clip: the same result at a fraction of the overhead
    v = np.minimum(np.maximum(x, lo[0]), hi[0])[:, None]
    mu: FloatArray = np.maximum(
        np.minimum(np.minimum((v - left) * inv_rise, (right - v) * inv_fall), 1.0), 0.0
    )
    return mu


def triangular_memberships(x: ArrayLike, sets: ArrayLike) -> FloatArray:
    """Memberships ``(n, k)`` of values ``x`` (n,) in ``k`` triangles ``(left, peak, right)``.

    The triangle of eq. 4, ``(b − |x − a|)/b``, generalised to asymmetric feet and clipped to
    [0, 1] (SPEC); a set whose foot equals its peak is a shoulder. Inputs are clamped to the
    variable's range, ``[first set's left foot, last set's right foot]``.
    """
    return _memberships(np.asarray(x, dtype=float).reshape(-1), _slopes(sets))


@dataclass(frozen=True, eq=False)
class RuleBase:
    """A complete rule table over ``d`` inputs.

    ``input_sets[i]`` is a ``(k_i, 3)`` array of triangles; ``consequents`` an integer array of
    shape ``(k_1, …, k_d)`` whose entries index ``output_sets`` / ``output_centres``.
    """

    name: str
    input_sets: tuple[FloatArray, ...]
    consequents: NDArray[np.int64]
    output_sets: FloatArray
    output_centres: FloatArray
    mode: str = "product"
    resolution: int = 1001

    if TYPE_CHECKING:
        # Derived in __post_init__ (object.__setattr__ on the frozen instance). Declared for
        # the type checker only: at run time they are plain attributes, not dataclass fields.
        _slopes: tuple[tuple[FloatArray, ...], ...] = field(init=False, repr=False)
        _centres: FloatArray = field(init=False, repr=False)
        _centre_lo: float = field(init=False, repr=False)
        _centre_hi: float = field(init=False, repr=False)
        _grids: tuple[FloatArray, FloatArray] | None = field(init=False, repr=False)
        _table: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        shape = tuple(len(s) for s in self.input_sets)
        if self.consequents.shape != shape:
            raise FuzzyError(
                f"{self.name}: rule table shape {self.consequents.shape} does not match the "
                f"inputs' set counts {shape}"
            )
        if self.mode not in ("product", "mamdani"):
            raise FuzzyError(f"{self.name}: unknown inference mode {self.mode!r}")
        object.__setattr__(self, "_slopes", tuple(tuple(_slopes(s)) for s in self.input_sets))
        object.__setattr__(self, "_centres", self.output_centres[self.consequents.reshape(-1)])
        object.__setattr__(self, "_centre_lo", float(self.output_centres.min()))
        object.__setattr__(self, "_centre_hi", float(self.output_centres.max()))
        # With two inputs whose sets are partitions of unity (each triangle's feet at its
        # neighbours' peaks), eq. 4's centre average is exactly the bilinear interpolation of
        # the consequent centres on the grid of peaks, which np.interp does in few steps.
        grids = [_partition_peaks(s) for s in self.input_sets]
        fast = self.mode == "product" and len(grids) == 2 and all(g is not None for g in grids)
        object.__setattr__(self, "_grids", tuple(grids) if fast else None)
        table = self.output_centres[self.consequents]
        object.__setattr__(self, "_table", np.ascontiguousarray(table, dtype=np.float64))

    @property
    def n_rules(self) -> int:
        return int(self.consequents.size)

    def firing_strengths(self, *inputs: ArrayLike) -> FloatArray:
        """``(n, n_rules)`` firing strengths: product (eq. 4) or minimum (Mamdani)."""
        if len(inputs) != len(self.input_sets):
            raise FuzzyError(f"{self.name} takes {len(self.input_sets)} inputs, got {len(inputs)}")
        arrays = [np.asarray(x, dtype=float).ravel() for x in inputs]
        n = arrays[0].shape[0]
        if any(a.shape[0] != n for a in arrays):
            raise FuzzyError(
                f"{self.name}: inputs have different lengths {[a.shape[0] for a in arrays]}"
            )
        slopes = self._slopes
        w = _memberships(arrays[0], slopes[0])
        for a, sl in zip(arrays[1:], slopes[1:]):
            mu = _memberships(a, sl)
            if self.mode == "product":
                w = (w[:, :, None] * mu[:, None, :]).reshape(n, w.shape[1] * mu.shape[1])
            else:
                w = np.minimum(w[:, :, None], mu[:, None, :]).reshape(n, w.shape[1] * mu.shape[1])
        return w

    def __call__(self, *inputs: ArrayLike) -> FloatArray:
        """The crisp output for each input tuple, shape ``(n,)``."""
        if self._grids is not None:
            return self._interpolate(inputs)
        w = self.firing_strengths(*inputs)
        cons = self.consequents.reshape(-1)
        if self.mode == "product":
            # eq. 4: Σ ȳ_l w_l / Σ w_l (centre-average defuzzifier)
            num = w @ self._centres
            den = w.sum(axis=1)
            out = num / np.where(den > 0, den, np.inf)  # no rule fires: 0
            # a weighted average lies between the centres; rounding can overshoot by an ulp
            return np.minimum(np.maximum(out, self._centre_lo), self._centre_hi)
        return self._mamdani(w, cons)

    def _interpolate(self, inputs: tuple[ArrayLike, ...]) -> FloatArray:
        """Eq. 4 for two inputs whose sets are partitions of unity: then the centre average is
        exactly the bilinear interpolation of the consequent centres on the grid of peaks,
        Σ_j μ_j(x_2) · interp(x_1; peaks, ȳ_·j), each μ_j one np.interp too (which clamps to
        the range's ends as the memberships do). Equal to eq. 4 to rounding."""
        if len(inputs) != 2:
            raise FuzzyError(f"{self.name} takes 2 inputs, got {len(inputs)}")
        x1 = np.asarray(inputs[0], dtype=float).ravel()
        x2 = np.asarray(inputs[1], dtype=float).ravel()
        if x1.shape != x2.shape:
            raise FuzzyError(
                f"{self.name}: inputs have different lengths {[x1.shape[0], x2.shape[0]]}"
            )
        assert self._grids is not None  # only called on the fast path set up in __post_init__
        g1, g2 = self._grids
        if x1.shape[0] == 0:
            return np.zeros(0)
        from ._kernels.fuzzy import bilinear

        return bilinear(x1, x2, g1, g2, self._table, self._centre_lo, self._centre_hi)

    def _mamdani(self, w: FloatArray, cons: NDArray[np.int64]) -> FloatArray:
        n_out = len(self.output_sets)
        # strength of each output set: max over the rules that conclude it
        onehot = cons[None, :] == np.arange(n_out)[:, None]  # (n_out, n_rules)
        strength = np.max(np.where(onehot[None, :, :], w[:, None, :], 0.0), axis=2)  # (n, n_out)
        lo, hi = self.output_sets[0, 0], self.output_sets[-1, 2]
        y = np.linspace(lo, hi, self.resolution)
        mu_out = triangular_memberships(y, self.output_sets).T  # (n_out, R)
        agg = np.max(np.minimum(strength[:, :, None], mu_out[None, :, :]), axis=1)  # (n, R)
        return _centroid(y, agg)


def _centroid(x: FloatArray, mu: FloatArray) -> FloatArray:
    """Exact centroid of piecewise-linear membership curves ``mu`` (n, R) sampled at ``x``."""
    dx = np.diff(x)
    y1, y2 = mu[:, :-1], mu[:, 1:]
    area = 0.5 * dx * (y1 + y2)
    moment = area * x[:-1] + dx * dx * (y1 + 2.0 * y2) / 6.0
    a = area.sum(axis=1)
    m = moment.sum(axis=1)
    c: FloatArray = np.divide(m, a, out=np.zeros_like(m), where=a > 0)
    return c


def _table(rows: Sequence[str]) -> NDArray[np.int64]:
    return np.array([[LABELS.index(c) for c in row] for row in rows], dtype=np.int64)


def _sets(t: Sequence[Sequence[float]]) -> FloatArray:
    return np.asarray(t, dtype=float)


def point_rule_base(cfg: FuzzyConfig) -> RuleBase:
    """Table 1: uncertainty of a point from its distance ρ and detection angle β (15 rules)."""
    return RuleBase(
        name="points",
        input_sets=(_sets(cfg.distance_sets), _sets(cfg.detection_angle_sets)),
        consequents=_table(cfg.point_rules),
        output_sets=_sets(cfg.uncertainty_sets),
        output_centres=np.asarray(cfg.output_centres, dtype=float),
        mode=cfg.inference,
        resolution=cfg.mamdani_resolution,
    )


def line_rule_base(cfg: FuzzyConfig) -> RuleBase:
    """Table 2: uncertainty of a line from δ (eq. 6) and σ (eq. 8) (9 rules; eq. 9 says 15)."""
    return RuleBase(
        name="lines",
        input_sets=(_sets(cfg.uncertainty_sets), _sets(cfg.line_distance_sets)),
        consequents=_table(cfg.line_rules),
        output_sets=_sets(cfg.uncertainty_sets),
        output_centres=np.asarray(cfg.output_centres, dtype=float),
        mode=cfg.inference,
        resolution=cfg.mamdani_resolution,
    )


def compose_virtual_rules(
    pair_rules: Sequence[str], distance_rules: Sequence[str]
) -> NDArray[np.int64]:
    """Table 3's two tables as one flat 3 × 3 × 5 table (f_L1, f_L2, d_v) → S/M/B: 45 rules.

    The upper table maps (f_L1, f_L2) to an intermediate label; the lower maps (that label,
    d_v) to the output.
    """
    upper = _table(pair_rules)  # rows f_L2, columns f_L1
    lower = _table(distance_rules)  # rows d_v, columns intermediate label
    out = np.empty((3, 3, len(distance_rules)), dtype=np.int64)
    for i1 in range(3):  # f_L1
        for i2 in range(3):  # f_L2
            out[i1, i2, :] = lower[:, upper[i2, i1]]
    return out


def virtual_point_rule_base(cfg: FuzzyConfig) -> RuleBase:
    """Table 3: uncertainty of a virtual angular point from f_L1, f_L2, d_v (eq. 10–12)."""
    return RuleBase(
        name="virtual_points",
        input_sets=(
            _sets(cfg.uncertainty_sets),
            _sets(cfg.uncertainty_sets),
            _sets(cfg.virtual_distance_sets),
        ),
        consequents=compose_virtual_rules(cfg.virtual_pair_rules, cfg.virtual_distance_rules),
        output_sets=_sets(cfg.uncertainty_sets),
        output_centres=np.asarray(cfg.output_centres, dtype=float),
        mode=cfg.inference,
        resolution=cfg.mamdani_resolution,
    )


@dataclass(frozen=True, eq=False)
class RuleBases:
    """The three fuzzy systems of the paper, built once from a config."""

    points: RuleBase
    lines: RuleBase
    virtual_points: RuleBase

    @classmethod
    def from_config(cls, cfg: FuzzyConfig) -> RuleBases:
        return cls(point_rule_base(cfg), line_rule_base(cfg), virtual_point_rule_base(cfg))
