"""The refinement stage: every filtered point of the scan fitted to the local map's surfaces
(fuzzy-weighted point-to-line Gauss-Newton), from the features' motion and, where it
disagrees with the odometry's, from the odometry's too."""

from __future__ import annotations

import functools
import importlib
import math
from dataclasses import dataclass
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .._kernels import f64
from ..config import RefinementConfig, SearchConfig
from ..features import Features
from ..matching import (
    Refinement,
    SurfacePoints,
    refine_both,
    refine_both_settings,
    refine_point_to_line,
    refinement_of,
)
from ..matching.surface import Weighing

if TYPE_CHECKING:  # (the compiled step's module imports numba: on first use only)
    from .._kernels.step import Stepped

__all__ = ["Refiner", "ScanPoints", "Starts"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
#: :meth:`Refiner.lines_start_inputs`: the surface's grid and table, the points, their
#: ranges and uncertainty, the weighing settings, the pairing distances, the params, the
#: iterations, the prior's diagonal, both fits' information, whether it is the full 3×3,
#: whether the fit is held to the features' motion, and the checks
_FromLines = tuple[
    FloatArray, IntArray, IntArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray,
    FloatArray, FloatArray, int, FloatArray, FloatArray, bool, bool, FloatArray,
]  # fmt: skip
#: :func:`~fuzzypos.matching.refine_both_settings`' values: the surface's grid and table, the
#: pairing distances, the params, the iterations, the prior's diagonal, both fits'
#: information and whether it is the full 3×3
_SurfaceSettings = tuple[
    FloatArray, IntArray, IntArray, FloatArray, FloatArray, FloatArray, int, FloatArray,
    FloatArray, bool,
]  # fmt: skip


@functools.cache
def _kernels() -> ModuleType:
    """The compiled kernels (``_kernels.refine``), imported with numba on first use and kept
    (``import fuzzypos`` does not import numba)."""
    return importlib.import_module("fuzzypos._kernels.refine")


@dataclass(frozen=True, eq=False)
class ScanPoints:
    """The scan's points to fit, the weight of each and the beam spacing at its range (m)."""

    xy: FloatArray
    weights: FloatArray
    spacing: FloatArray | None = None

    @classmethod
    def _of(cls, xy: FloatArray, weights: FloatArray, spacing: FloatArray | None) -> ScanPoints:
        """What the constructor builds, straight into the instance's dict (the frozen
        ``__init__``'s ``object.__setattr__`` per field costs more; once a scan)."""
        out = object.__new__(cls)
        out.__dict__.update(xy=xy, weights=weights, spacing=spacing)
        return out


class _WeighedOnUse(ScanPoints):
    """:class:`ScanPoints` whose weights and spacing are computed on first use (by the
    compiled ``scan_weights``, from the ``weighing`` inputs): the fused refinement weighs the
    points in its own call, and only the searches and fits after it read them."""

    # (the instance's dict holds xy and weighing, then the two arrays once computed)
    weighing: Weighing | None

    def __init__(
        self, xy: FloatArray, weights: FloatArray, spacing: FloatArray | None = None
    ) -> None:
        """Already weighed (``dataclasses.replace``'s way in: the fields as given)."""
        self.__dict__.update(xy=xy, weighing=None, _weights=weights, _spacing=spacing)

    @classmethod
    def _lazy(cls, xy: FloatArray, weighing: Weighing) -> _WeighedOnUse:
        out = object.__new__(cls)
        out.__dict__.update(xy=xy, weighing=weighing)
        return out

    def _weigh(self) -> None:
        assert self.weighing is not None
        ranges, uncertainty, settings = self.weighing
        inc, floor, most, cap = settings.tolist()
        weights, spacing = _kernels().scan_weights(
            f64(self.xy), f64(ranges), f64(uncertainty), inc, floor, most, cap
        )
        self.__dict__.update(_weights=weights, _spacing=spacing)

    @property
    def weights(self) -> FloatArray:
        if "_weights" not in self.__dict__:
            self._weigh()
        weights: FloatArray = self.__dict__["_weights"]
        return weights

    @property
    def spacing(self) -> FloatArray | None:
        if "_weights" not in self.__dict__:
            self._weigh()
        spacing: FloatArray | None = self.__dict__["_spacing"]
        return spacing


@dataclass(frozen=True, eq=False)
class Starts:
    """Where a scan's refinement starts, all from the keyframe: ``start`` (the features'
    motion, else the odometry's), ``prior`` (the motion the fit is held to) and ``hold`` (the
    odometry's motion, which keeps its say along a corridor); ``prior_information`` and
    ``odometry_information``: the information of ``prior`` and of ``hold`` where they come
    from the learned noise (None: the refinement section's fixed standard deviations)."""

    start: FloatArray
    prior: FloatArray
    hold: FloatArray
    prior_information: FloatArray | None = None
    odometry_information: FloatArray | None = None

    @classmethod
    def _of(
        cls,
        start: FloatArray,
        prior: FloatArray,
        hold: FloatArray,
        prior_information: FloatArray | None,
        odometry_information: FloatArray | None,
    ) -> Starts:
        """What the constructor builds, straight into the instance's dict (as
        :meth:`ScanPoints._of`; once a scan)."""
        out = object.__new__(cls)
        out.__dict__.update(
            start=start, prior=prior, hold=hold, prior_information=prior_information,
            odometry_information=odometry_information,
        )  # fmt: skip
        return out


class Refiner:
    """Point-to-line refinement against the local map (``[refinement]``; after a search it
    uses ``[search]``'s looser limits)."""

    def __init__(self, refinement: RefinementConfig, search: SearchConfig) -> None:
        self.refinement = refinement
        self.search = search
        r = refinement
        # the weight kernel's settings, as floats once (not per scan)
        self._weight_settings = (
            float(r.weight_floor),
            float(r.length_weight_max),
            float(r.length_cap),
        )
        # the weight kernel's settings with the last scan's angle increment, as one array
        # (``_kernels.refine.WEIGHING``)
        self._weighing: tuple[float, FloatArray] | None = None
        # the last surface and what the fused refinement reads of it and the section without
        # a learned information (``refine_both_settings``): the same for every scan against
        # one keyframe
        self._surface_settings: tuple[SurfacePoints, _SurfaceSettings] | None = None
        # the checks of the fused refinement (``_kernels.refine.CHECKS``), after an odometry
        # jump (True: no fit from the odometry's motion) or not
        self._checks = {
            wide: np.array([
                float(r.also_from_odometry and not wide), r.both_distance, r.both_angle,
                r.both_min_gain, r.min_points, r.min_inlier_fraction, r.max_correction,
            ])
            for wide in (True, False)
        }  # fmt: skip

    @property
    def enabled(self) -> bool:
        """Whether scans are refined at all (``enabled``)."""
        return self.refinement.enabled

    @property
    def min_points(self) -> int:
        """The least points a scan is refined with (``min_points``)."""
        return int(self.refinement.min_points)

    @property
    def prior_from_features(self) -> bool:
        """Whether the fit is held to the features' motion (``prior_from_features``)."""
        return bool(self.refinement.prior_from_features)

    @property
    def with_previous_scan(self) -> bool:
        """Whether, where nothing else fits, the scan is refined against the local map and
        the previous scan too (``with_previous_scan``)."""
        return self.refinement.with_previous_scan

    def starts(
        self,
        features_motion: FloatArray | None,
        key_prior: FloatArray,
        information: tuple[FloatArray, FloatArray] | None,
    ) -> Starts:
        """Where the refinement starts: the features' motion, else the prior from the
        keyframe ``key_prior``; held to the features' motion (``prior_from_features``) or to
        the prior, with the learned ``information`` where given (the features', the
        odometry's)."""
        start = key_prior if features_motion is None else features_motion
        from_features = features_motion is not None and self.refinement.prior_from_features
        if information is None:
            return Starts._of(start, start if from_features else key_prior, key_prior, None, None)
        # the learned odometry is the prior, the features the start
        return Starts._of(start, key_prior, key_prior, information[1], information[1])

    def points(self, features: Features, angle_increment: float) -> ScanPoints | None:
        """Every valid point of the scan (the paper's filter, §3.1, drops grazing points that
        still tell where a wall is), each weighed by its certainty and by the stretch of
        surface it stands for; None with fewer than ``min_points``."""
        r = self.refinement
        pts = features.points
        if pts.shape[0] < r.min_points:
            return None
        ranges = features.ranges
        # (weighed in the fused refinement's call, or on first use)
        weighing = self.weighing_settings(angle_increment)
        return _WeighedOnUse._lazy(pts, (ranges, features.uncertainty, weighing))

    def checks(self, wide: bool) -> FloatArray:
        """The fused refinement's checks (``_kernels.refine.CHECKS``), after an odometry jump
        (``wide``) or not."""
        return self._checks[wide]

    def weighing_settings(self, angle_increment: float) -> FloatArray:
        """The weight kernel's settings (``_kernels.refine.WEIGHING``) with the scans' angle
        increment, one array (made again only where the increment changes: one scanner, once
        a log)."""
        last = self._weighing
        if last is None or last[0] != angle_increment:
            settings = np.array([float(angle_increment), *self._weight_settings])
            last = self._weighing = (angle_increment, settings)
        return last[1]

    def refine(
        self, surface: SurfacePoints, points: ScanPoints, starts: Starts, wide: bool
    ) -> Refinement | None:
        """The fit from ``starts.start`` (pairing within the search's ``jump_distance`` after
        an odometry jump, ``wide``); where the features' motion and the odometry's disagree
        by more than ``both_distance`` or ``both_angle``, also the fit from the odometry's
        (held to it), kept where it puts ``both_min_gain`` more of the scan close to its
        surfaces (a refinement settles where it starts). None where neither fits."""
        r = self.refinement
        start, hold = starts.start, starts.hold
        max_distance = self.search.jump_distance if wide else r.max_distance
        # both fits and the choice in one compiled call
        if isinstance(points, _WeighedOnUse) and "_weights" not in points.__dict__:
            weights, spacing, weighing = None, None, points.weighing  # (weighed in it)
            assert weighing is not None
        else:
            weights, spacing, weighing = points.weights, points.spacing, None
        return refine_both(
            surface, points.xy, weights, start, starts.prior, hold, r,
            self._checks[wide], max_distance=max_distance,
            prior_information=starts.prior_information,
            hold_information=starts.odometry_information, spacing=spacing,
            weighing=weighing,
        )  # fmt: skip

    def lines_start_inputs(
        self, surface: SurfacePoints, points: ScanPoints, information: FloatArray | None
    ) -> _FromLines | None:
        """What ``_kernels.refine.weigh_and_refine_both`` reads for :meth:`refine` from the
        lines' motion (no odometry jump) but the starts: the surface's, the scan's points
        with their weighing inputs, the section's settings, both fits' information (the
        learned ``information``, else the diagonal's) and whether it is the full 3×3,
        whether the fit is held to the features' motion, and the checks; None where that
        call is not the one :meth:`refine` would make (points already weighed, or too few
        on either side)."""
        weighing = points.__dict__.get("weighing")
        if weighing is None or points.xy.shape[0] == 0:
            return None
        of_surface = self.surface_inputs(surface, information)
        if of_surface is None:
            return None
        geometry, shape, cells, table, gates, params, iterations, diag, info, full = of_surface
        ranges, uncertainty, settings = weighing
        return (
            geometry, shape, cells, table, f64(points.xy), f64(ranges), f64(uncertainty),
            settings, gates, params, iterations, diag, info, full,
            bool(self.refinement.prior_from_features), self._checks[False],
        )  # fmt: skip

    def surface_inputs(
        self, surface: SurfacePoints, information: FloatArray | None
    ) -> _SurfaceSettings | None:
        """:meth:`lines_start_inputs`' values of the surface and the section
        (``refine_both_settings``; the last surface's kept, the same for every scan against
        one keyframe, where no learned ``information`` is given); None with fewer than three
        surface points."""
        if len(surface) < 3:
            return None
        if information is not None:
            return refine_both_settings(surface, self.refinement, information)
        last = self._surface_settings
        if last is not None and last[0] is surface:
            return last[1]
        of_surface = refine_both_settings(surface, self.refinement, None)
        self._surface_settings = (surface, of_surface)
        return of_surface

    @staticmethod
    def from_lines(
        stepped: Stepped, points: ScanPoints, starts: Starts, inputs: _FromLines
    ) -> Refinement:
        """The :class:`Refinement` of the fit the compiled step made from ``starts`` (the
        lines' motion the start; ``stepped``: its values, the fit's which, paired, close,
        on-start and (4, 3, 3) values), with :meth:`lines_start_inputs`' information:
        :meth:`refine`'s, to the bit."""
        *_, info, full, _from_features, _checks = inputs
        return refinement_of(
            stepped.which == _kernels().FROM_START, stepped.paired, stepped.close,
            stepped.on_start, stepped.fit, points.xy.shape[0],
            (starts.start, starts.prior, info, full), (starts.hold, starts.hold, info, full),
        )  # fmt: skip

    def fit(
        self,
        surface: SurfacePoints,
        points: ScanPoints,
        start: FloatArray,
        prior: FloatArray,
        hold: FloatArray,
        *,
        max_distance: float,
        weak_prior: bool = False,
        prior_information: FloatArray | None = None,
    ) -> Refinement | None:
        """One refinement against ``surface``; None where it is not trusted: fewer than
        ``min_points`` paired, less than the inlier fraction of the scan paired, or it moved
        further than ``max_correction`` from ``start``. ``weak_prior``: after a wide search,
        the prior barely counts (``weak_prior_scale``) and the search's looser limits apply."""
        r, s = self.refinement, self.search
        res = refine_point_to_line(
            surface,
            points.xy,
            points.weights,
            start,
            prior,
            hold,
            r,
            max_distance=max_distance,
            prior_scale=s.weak_prior_scale if weak_prior else 1.0,
            prior_information=prior_information,
            spacing=points.spacing,
        )
        min_fraction = s.min_inlier_fraction if weak_prior else r.min_inlier_fraction
        if res is None or res.n_paired < r.min_points or res.inlier_fraction < min_fraction:
            return None
        limit = s.jump_distance if weak_prior else r.max_correction
        (x, y, _), (x0, y0, _) = res.increment.tolist(), start.tolist()
        if math.hypot(x - x0, y - y0) > limit:
            return None
        return res
