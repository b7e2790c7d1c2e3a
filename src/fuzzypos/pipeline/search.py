"""The relocalisation stage: a wider search for a start where the prior cannot be trusted,
then the refinement from it."""

from __future__ import annotations

from ..config import SearchConfig
from ..matching import Refinement, search_start
from .local_map import LocalMap
from .refine import Refiner, ScanPoints, Starts

__all__ = ["Relocaliser"]


class Relocaliser:
    """After an odometry jump or a gap in time (``full``): every rotation and translations
    within ``jump_distance``, against the local map and the previous scan, the refinement from
    the best start with a weak prior. Where the match from the prior failed otherwise: a
    narrower search (``failure_angle``, ``failure_distance``) against the local map, the
    refinement from its best start still held to the odometry (a corridor's repeating doors
    would otherwise pull the scan along it). ``[search]``."""

    def __init__(self, settings: SearchConfig, refiner: Refiner) -> None:
        self.settings = settings
        self.refiner = refiner

    def is_full(self, after_jump: bool, dt: float) -> bool:
        """Whether the search is the full one: after an odometry jump, or after a gap in time
        longer than ``after_gap`` (``dt`` seconds since the previous scan)."""
        return after_jump or dt > self.settings.after_gap

    def relocalise(
        self,
        local_map: LocalMap,
        points: ScanPoints,
        starts: Starts,
        best: Refinement | None,
        full: bool,
    ) -> Refinement | None:
        """``best`` (the refinement so far, or None), or the fit from the search's start where
        that lands more of the scan's points near the map and fits them better."""
        s = self.settings
        surface = local_map.search_surface() if full else local_map.surface()
        hit = search_start(
            surface,
            points.xy,
            starts.start,
            s,
            half_width=s.angle if full else s.failure_angle,
            translation_half_width=s.jump_distance if full else s.failure_distance,
        )
        # both are fractions of the scan's points that lie near the map
        if best is not None and hit.score <= best.inlier_fraction:
            return best
        if full:  # after a jump or a gap the odometry has lost its say
            found = self.refiner.fit(
                surface,
                points,
                hit.start,
                hit.start,
                starts.hold,
                max_distance=s.jump_distance,
                weak_prior=True,
                prior_information=starts.odometry_information,
            )
        else:
            found = self.refiner.fit(
                surface,
                points,
                hit.start,
                starts.hold,
                starts.hold,
                max_distance=self.refiner.refinement.max_distance,
                prior_information=starts.odometry_information,
            )
        if found is not None and (best is None or found.inlier_fraction > best.inlier_fraction):
            return found
        return best
