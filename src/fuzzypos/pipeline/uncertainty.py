"""The uncertainty stage: the covariance of every increment and of every scan's pose relative
to its keyframe, and the gate that rejects a match too unlikely under both its own and the
odometry's covariance.

Conventions. A pose error is a right perturbation: ε = ⊖(true) ⊕ estimate, (x, y in m, θ in
rad) in the frame of the pose itself; that is what ``Estimate.covariance`` (of the increment,
so in the previous scan's frame) and ``Estimate.keyframe_covariance`` (of the pose relative to
the keyframe) hold. Inside, the fit against the keyframe is solved in additive coordinates of
the keyframe's frame (δ = estimate − true, what Gauss-Newton updates); :func:`local` turns
those into the right-perturbation form.

The fit (:class:`~fuzzypos.matching.Refinement`) minimises the points' residuals with
weights ``A`` plus a prior term ``P`` (the odometry's motion, and the hold of a corridor's
unobservable direction). Its estimate is δT = M⁻¹ (g + P δp) with M = A + P, g the points'
gradient (covariance ``G`` under the noise their residuals show, times ``point_correlation``)
and δp the error of the prior: that of the previous scan's pose relative to the keyframe
carried on by the odometry's increment. The sandwich M⁻¹ (G + P Σ_p P) M⁻¹ is then the covariance
whatever weight the fit gave its prior: the odometry's information enters once, and where the
points do not constrain a direction (a corridor) the covariance along it is the prior's.
"""

from __future__ import annotations

import functools
import importlib
import math
from dataclasses import dataclass, replace
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .._kernels import f64
from ..config import CovarianceConfig, GateConfig
from ..geometry import compose3
from ..matching import Refinement

if TYPE_CHECKING:  # (the compiled kernels' module imports numba: on first use only)
    from .._kernels.pipeline import AssessInputs
    from .noise import OdometryNoise

__all__ = ["Assessment", "Uncertainty", "local"]

FloatArray = NDArray[np.float64]

#: the points' information is too ill-conditioned to give the motion alone beyond this
_MAX_CONDITION = 1e8


@functools.cache
def _kernels() -> ModuleType:
    """The compiled kernels (``_kernels.uncertainty``), imported with numba on first use and kept
    (``import fuzzypos`` does not import numba)."""
    return importlib.import_module("fuzzypos._kernels.uncertainty")


@functools.cache
def _pipeline_kernels() -> ModuleType:
    """The pipeline's own kernels (``_kernels.pipeline``: the assessment and the scan's own
    motion in one call), imported on first use and kept."""
    return importlib.import_module("fuzzypos._kernels.pipeline")


def _read_only(a: FloatArray) -> FloatArray:
    a.flags.writeable = False
    return a


def _compose(a: FloatArray, b: FloatArray) -> FloatArray:
    """:func:`~fuzzypos.geometry.compose` of one pose each, in floats (bit-identical)."""
    return np.array(compose3(a.tolist(), b.tolist()))


def local(cov: FloatArray, theta: float) -> FloatArray:
    """An additive covariance of a pose with heading ``theta`` as the covariance of its right
    perturbation (in the pose's own frame)."""
    c, s = math.cos(theta), math.sin(theta)
    g = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    out: FloatArray = g @ cov @ g.T
    sym: FloatArray = 0.5 * (out + out.T)
    return sym


@dataclass(frozen=True, eq=False)
class Assessment:
    """How good one scan's estimate is: ``covariance`` of its increment and
    ``keyframe_covariance`` of its pose relative to the keyframe it was matched against (both
    right perturbations, see the module), ``gate`` the Mahalanobis distance squared of the
    match's disagreement with the odometry (None where nothing was compared) and
    ``rejected`` whether the gate rejected the match. ``scan_only``: where
    :meth:`Uncertainty.assess` was asked for it (``with_scan_only``) and the fit stands, what
    :meth:`Uncertainty.scan_only` gives for it (None where not asked, rejected, or where the
    points alone do not fix the motion)."""

    covariance: FloatArray
    keyframe_covariance: FloatArray
    gate: float | None = None
    rejected: bool = False
    scan_only: tuple[FloatArray, FloatArray] | None = None

    @classmethod
    def _of(
        cls,
        covariance: FloatArray,
        keyframe_covariance: FloatArray,
        gate: float | None,
        rejected: bool,
        scan_only: tuple[FloatArray, FloatArray] | None,
    ) -> Assessment:
        """What the constructor builds, straight into the instance's dict (the frozen
        ``__init__``'s ``object.__setattr__`` per field costs more; once a scan)."""
        out = object.__new__(cls)
        out.__dict__.update(
            covariance=covariance, keyframe_covariance=keyframe_covariance, gate=gate,
            rejected=rejected, scan_only=scan_only,
        )  # fmt: skip
        return out


class Uncertainty:
    """Covariances (``[covariance]``) and the gate (``[gate]``); owns the covariance of the
    previous scan's pose relative to the keyframe, which the next fit's prior inherits."""

    def __init__(self, covariance: CovarianceConfig, gate: GateConfig) -> None:
        self.settings = covariance
        self.gate_settings = gate
        # χ²'s quantile with 3 degrees of freedom, as scipy.stats.chi2.ppf computes it, without
        # importing scipy.stats (0.5 s; scipy.special comes with the KD-tree's scipy.spatial)
        from scipy.special import gammaincinv

        self.threshold = float(2.0 * gammaincinv(1.5, gate.probability))
        #: beyond it a features-only match contradicts the odometry (``contradiction_probability``)
        self.contradiction_threshold = float(2.0 * gammaincinv(1.5, gate.contradiction_probability))
        f = covariance
        self.floor = np.diag([f.floor_translation**2, f.floor_translation**2, f.floor_rotation**2])
        self.floor.flags.writeable = False
        t, r = f.no_odometry_translation**2, f.no_odometry_rotation**2
        self._broad = _read_only(np.diag([t, t, r]))
        self._feature = _read_only(
            np.diag([f.feature_translation**2] * 2 + [f.feature_rotation**2])
        )
        # the compiled assessment's stand-ins for a fit's matrices and poses, without a fit
        self._no_fit = (np.zeros((3, 3)), np.zeros(3))
        self._point_correlation = float(f.point_correlation)
        self.reset()

    def reset(self) -> None:
        #: the previous scan's pose relative to the keyframe: its additive covariance
        self._previous = np.zeros((3, 3))

    def first(self) -> Assessment:
        """The first scan: the keyframe itself."""
        self._previous = np.zeros((3, 3))
        return Assessment(self.floor.copy(), self.floor.copy())

    def standing_still(self, t_prev: FloatArray) -> Assessment:
        """The robot stands still at ``t_prev`` from the keyframe: no motion, the pose
        relative to the keyframe unchanged."""
        kf = local(self._previous, float(t_prev[2])) + self.floor
        return Assessment(self.floor.copy(), kf)

    def gate_open(self, from_odometry: bool, noise: OdometryNoise) -> bool:
        """Whether a match is compared with the odometry (``[gate]``'s ``enabled``): where
        the prior is the odometry's (``from_odometry``) and its ``noise`` is known (learned
        from enough matches, or not learned at all), and, with
        ``only_where_odometry_is_better``, the odometry the more precise."""
        gate = self.gate_settings
        if not (gate.enabled and from_odometry and noise.warm):
            return False
        return noise.better_than_matching or not gate.only_where_odometry_is_better

    def prior_information(
        self, t_prev: FloatArray, prior: FloatArray, prior_covariance: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """The information of the features' motion from the keyframe (the inverse of the
        prior from the keyframe's additive covariance, the previous scan's pose relative to
        it carried on by ``prior``, plus :meth:`feature_covariance`) and of the odometry's
        (the inverse of that covariance): the refinement's priors from the learned noise. One
        compiled call (``_kernels.pipeline.prior_information``)."""
        out = _pipeline_kernels().prior_information(
            f64(t_prev), f64(prior), self._previous, f64(prior_covariance), self.floor,
            self._feature,
        )  # fmt: skip
        return out[0], out[1]

    def feature_covariance(self) -> FloatArray:
        """The features' own error, isotropic in translation (read-only)."""
        return self._feature

    def broad(self) -> FloatArray:
        """The covariance of a prior without (sane) odometry: the last increment (read-only)."""
        return self._broad

    def assess(
        self,
        t_prev: FloatArray,
        prior: FloatArray,
        prior_covariance: FloatArray,
        from_key: FloatArray | None,
        fit: Refinement | None,
        gate_open: bool,
        with_scan_only: bool = False,
        key_prior: FloatArray | None = None,
    ) -> Assessment:
        """The covariances of a scan whose previous scan lies at ``t_prev`` from the keyframe,
        whose motion since then was predicted as ``prior`` with ``prior_covariance`` (the
        odometry's, or a broad one), estimated from the keyframe as ``from_key`` by ``fit``
        (None: the features alone; ``from_key`` None: nothing, the prior stands). With
        ``gate_open`` the match is compared with the prior and rejected past the gate. With
        ``with_scan_only`` also :meth:`scan_only` of the fit where it stands (the compiled path
        computes both in one kernel call). ``key_prior``: ``compose(t_prev, prior)`` where the
        caller has it to the bit (else computed where needed)."""
        if from_key is None:
            return self._prior_stands(t_prev, prior, prior_covariance, self._previous)
        return self._assess_compiled(
            t_prev, prior, prior_covariance, from_key, fit, gate_open, with_scan_only, key_prior
        )

    def _assess_compiled(
        self,
        t_prev: FloatArray,
        prior: FloatArray,
        prior_covariance: FloatArray,
        from_key: FloatArray,
        fit: Refinement | None,
        gate_open: bool,
        with_scan_only: bool,
        key_prior: FloatArray | None,
    ) -> Assessment:
        """:meth:`assess` of a match through the compiled kernels, with :meth:`scan_only` in the
        same call where asked; where the gate rejects the match, the prior stands (the same
        call)."""
        kernels = _pipeline_kernels()
        zero, none = self._no_fit
        if fit is None:
            values = kernels.FitValues(zero, zero, zero, zero, none, none, none)
            wanted = False
        else:  # (the fit's own arrays, float64 already)
            if fit.hold_on_start:
                key_prior = fit.start
            elif key_prior is None:
                key_prior = _compose(t_prev, prior)
            values = kernels.FitValues(
                fit.information, fit.prior_information, fit.hold_information,
                fit.gradient_covariance, fit.prior, key_prior, f64(fit.increment),
            )  # fmt: skip
            # (scan_only's own test, the kernel's too: a held fit gives no motion of the
            # scan's own)
            wanted = with_scan_only
        inputs = self.assess_inputs(t_prev, prior, prior_covariance, gate_open, wanted, none, False)
        gate, ok, out = kernels.assess_and_scan_only(inputs, f64(from_key), fit is not None, values)
        rejected = gate_open and gate > self.threshold
        self._previous = out[2]  # (views of the kernel's one array)
        scan = (out[4, 0], out[3]) if ok else None
        gate_value = float(gate) if gate_open else None
        return Assessment._of(out[0], out[1], gate_value, rejected, scan)

    def assess_inputs(
        self,
        t_prev: FloatArray,
        prior: FloatArray,
        prior_covariance: FloatArray,
        gate_open: bool,
        wanted: bool,
        key_prior: FloatArray,
        key_prior_known: bool,
    ) -> AssessInputs:
        """What ``_kernels.pipeline.assess_and_scan_only`` reads for :meth:`assess` but the
        match's and the fit's own values, its record (``AssessInputs``): the previous scan's
        pose from the keyframe ``t_prev``, the ``prior`` and its covariance, the previous
        covariance, the features', the floor, the points' correlation, whether the gate is
        open, its threshold, whether the scan's own motion is ``wanted``, the condition's
        limit, and for the compiled step the prior from the keyframe and whether it is the
        assessment's."""
        inputs: AssessInputs = _pipeline_kernels().AssessInputs(
            f64(t_prev), f64(prior), f64(prior_covariance), self._previous, self._feature,
            self.floor, self._point_correlation, bool(gate_open), self.threshold, bool(wanted),
            _MAX_CONDITION, key_prior, bool(key_prior_known),
        )  # fmt: skip
        return inputs

    def assessed(
        self, gate: float, ok: bool, out: FloatArray, gate_open: bool
    ) -> Assessment | None:
        """The :class:`Assessment` of ``_kernels.pipeline.assess_and_scan_only``' values (its
        (5, 3, 3) array ``out``), as :meth:`assess` gives it, the previous covariance now
        its; None where the gate rejects the match (then :meth:`assess` gives it)."""
        if gate_open and gate > self.threshold:
            return None
        # (views of the kernel's one array)
        self._previous = out[2]
        scan = (out[4, 0], out[3]) if ok else None
        return Assessment._of(out[0], out[1], None if not gate_open else float(gate), False, scan)

    def scan_only(
        self, fit: Refinement, t_prev: FloatArray
    ) -> tuple[FloatArray, FloatArray] | None:
        """The increment the scan alone gives, and its covariance (right perturbation in the
        previous scan's frame): the fit without its prior's and hold's pull. At the fit's
        solution x, M x = A x_s + P p + H h (M = A + P + H, the points' information A, the
        prior's P toward p, the hold's H toward h), so x_s = A⁻¹ (M x − P p − H h), with
        covariance A⁻¹ G A⁻¹ carried on from the previous scan. What the odometry's noise is
        learned from: the fused increment would teach it its own weight back. None where the
        points alone do not fix the motion (a corridor held, or too little information)."""
        if np.count_nonzero(fit.hold_information):
            return None
        ok, inc, cov = _kernels().scan_only(
            f64(fit.information), f64(fit.prior_information),
            f64(fit.gradient_covariance), f64(fit.increment), f64(fit.prior),
            f64(t_prev), self._previous, self.floor,
            self._point_correlation, _MAX_CONDITION,
        )  # fmt: skip
        return (inc, cov) if ok else None

    def _prior_stands(
        self, t_prev: FloatArray, prior: FloatArray, prior_covariance: FloatArray, held: FloatArray
    ) -> Assessment:
        """The prior stands: its own covariance for the increment; relative to the keyframe
        the previous scan's (``held``) carried on by it (``_kernels.uncertainty.prior_stands``)."""
        out = _kernels().prior_stands(
            f64(t_prev), f64(prior), f64(prior_covariance), held, self.floor
        )
        self._previous = out[2]
        return Assessment._of(out[0], out[1], None, False, None)

    def held(self) -> FloatArray:
        """The previous scan's covariance relative to the keyframe as it stands, before the
        next assessment replaces it (what :meth:`overruled` starts from)."""
        return self._previous

    def overruled(
        self, held: FloatArray, t_prev: FloatArray, prior: FloatArray, prior_covariance: FloatArray
    ) -> Assessment:
        """The assessment of a scan whose match, assessed already, was overruled: the prior
        stands, from the previous scan's covariance ``held`` before that assessment."""
        return self._prior_stands(t_prev, prior, prior_covariance, held)

    def previous_covariance(self) -> FloatArray:
        """The additive covariance, in the keyframe's frame, of the previous scan's pose
        relative to the keyframe (a copy)."""
        out: FloatArray = self._previous.copy()
        return out

    def widened(self, judged: Assessment, extra: FloatArray, theta: float) -> Assessment:
        """``judged`` of a fit against points placed by an estimate whose additive covariance
        in the keyframe's frame is ``extra`` (the previous scan's): the pose relative to the
        keyframe carries that error too; the increment, from the previous scan, does not."""
        self._previous = self._previous + extra
        return replace(judged, keyframe_covariance=judged.keyframe_covariance + local(extra, theta))

    def renewed(self) -> None:
        """The scan just assessed became the keyframe: the next scan's prior starts from it."""
        self._previous = np.zeros((3, 3))
