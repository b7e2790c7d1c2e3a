"""The configuration section of localisation in a known map (``[localization]``, issue 37).
Part of :mod:`fuzzypos.config`, which assembles every section into ``Config``."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .schema import _field, section

RAD = "rad"  # an angle: radians in code, degrees under "<name>_deg" in TOML
M = "m"


@dataclass(frozen=True)
@section("localization")
class LocalizationConfig:
    """Localisation in a known occupancy map (``fuzzypos.localization``): a branch-and-bound
    search of the whole map for the places that explain a scan, several hypotheses followed
    with the odometry and weighed scan by scan until one wins by a clear margin, then
    tracking by a point-to-line fit against the map's walls (docs/localization.md)."""

    hit_sigma: float = _field(
        0.10,
        "a scan point's likelihood falls as exp(-d²/2σ²) with its distance d to the nearest "
        "occupied cell, σ = 10 cm: two map cells of 5 cm plus the scanner's and the map's "
        "noise; the evidence between places and the fit are measured with it",
        unit=M,
        gt=0.0,
    )
    outlier_probability: float = _field(
        0.2,
        "a point far from every wall still has this likelihood (people, furniture moved, "
        "glass): without it one unmapped object would rule a place out",
        gt=0.0,
        lt=1.0,
    )
    field_distance: float = _field(
        1.0,
        "the distance to the walls is kept up to 1 m (further is as bad as 1 m): it bounds the "
        "fit's pull and the field's size in memory",
        unit=M,
        gt=0.0,
    )
    wall_radius: float = _field(
        0.15,
        "each occupied cell's wall line is fitted through the occupied cells within 15 cm "
        "(three cells of 5 cm each side): enough to find its direction, short enough to "
        "follow a corner",
        unit=M,
        gt=0.0,
    )
    max_points: int = _field(
        360,
        "a scan is thinned to at most 360 points (one per map cell first): the fit's cost "
        "grows with them, and more points along one wall add correlated, not new, evidence",
        ge=10,
    )
    search_resolution: float = _field(
        0.15,
        "the global search's grid is 15 cm (three cells of a 5 cm map; the map's cells where "
        "coarser): its candidates are refined by the fit afterwards, and its cost grows with "
        "the inverse cube (cells times angles): 10 cm costs 4-5 times as much",
        unit=M,
        gt=0.0,
    )
    search_range: float = _field(
        12.0,
        "the global search uses the points within 12 m: its angular step is the search "
        "resolution over this range (0.7°), and far points cost angles without telling rooms "
        "apart better",
        unit=M,
        gt=0.0,
    )
    search_points: int = _field(
        150,
        "at most 150 points per scan in the global search: its cost is linear in them",
        ge=10,
    )
    search_min_score: float = _field(
        0.35,
        "a place is a candidate only where the scan's mean likelihood there (on the search's "
        "grid) is at least 0.35: a true place scores 0.6–0.9, a wrong one seldom 0.3",
        gt=0.0,
        lt=1.0,
    )
    search_ratio: float = _field(
        0.75,
        "and at least 75 % of the best place's score: a twin of the best place (an identical "
        "room) scores within a few percent of it on the search's grid and must be kept as a "
        "rival, places far below it lose the vote anyway",
        gt=0.0,
        le=1.0,
    )
    max_hypotheses: int = _field(
        16,
        "at most 16 places are followed at once: each costs a fit per scan",
        ge=1,
    )
    separation: float = _field(
        1.0,
        "two hypotheses closer than 1 m (and separation_angle) are the same place: one is "
        "merged into the other; farther ones are rivals",
        unit=M,
        gt=0.0,
    )
    separation_angle: float = _field(
        math.radians(20.0),
        "and than 20° in heading (a corridor seen both ways is two places)",
        unit=RAD,
        gt=0.0,
    )
    research_interval: int = _field(
        10,
        "while not localised the whole map is searched again every 10 scans, for places the "
        "first scans did not show",
        ge=1,
    )
    evidence_window: int = _field(
        30,
        "hypotheses are compared over the last 30 scans: long enough for the robot to see "
        "what tells places apart, short enough that old scans do not outvote a new place",
        ge=2,
    )
    min_scans: int = _field(
        8,
        "no decision before 8 scans: a single scan's evidence is overrated by unmapped clutter",
        ge=1,
    )
    effective_points: float = _field(
        8.0,
        "a scan's points are counted as 8 independent measurements: points along one wall err "
        "together (the map's and the scan's own errors are shared), so a scan is worth far "
        "less than its point count",
        gt=0.0,
    )
    evidence_margin: float = _field(
        10.0,
        "the best place must beat every distinct rival by 10 nats of log-likelihood over the "
        "window (odds of 22,000 to one) before the localizer says where it is",
        gt=0.0,
    )
    min_fit: float = _field(
        0.45,
        "a place (and a tracked pose) must explain the scan: the points' mean likelihood at "
        "least 0.45 (a true match scores 0.6–0.9 with clutter, a wrong one below 0.4)",
        gt=0.0,
        lt=1.0,
    )
    contradicted_share: float = _field(
        0.1,
        "at the right pose about one point in ten is contradicted by the map: its beam passes "
        "through an occupied cell farther than 2 hit_sigma before its end, or it ends in free "
        "space farther than that from every wall (people, furniture moved, glass, the map's "
        "own blur); the share expected until measured on the tracked scans (then the larger)",
        gt=0.0,
        lt=1.0,
    )
    crossing_z: float = _field(
        2.0,
        "a place is accepted only where the mean contradicted share of its last min_scans "
        "scans stays below contradicted_share plus 2 standard errors (binomial, "
        "effective_points per scan): in another building, or at a wrong place whose walls "
        "fit nearby, a fifth to a half of the points are contradicted",
        gt=0.0,
    )
    crossing_share: float = _field(
        0.05,
        "of which about one beam in 20 crosses a wall (1-2 % on the shared logs' own maps); "
        "the share expected until measured on the tracked scans (then the larger)",
        gt=0.0,
        lt=1.0,
    )
    crossing_lost_z: float = _field(
        3.0,
        "a tracked pose is lost when the mean crossing share of its last lost_scans scans "
        "exceeds crossing_share plus 3 standard errors: only beams through walls count "
        "there (clutter comes and goes), and the bound to give a place up is stricter than "
        "to accept one",
        gt=0.0,
    )
    lost_scans: int = _field(
        6,
        "after 6 scans in a row whose fit is below min_fit, tracking is lost and the whole "
        "map searched again (a carried robot, a failed match)",
        ge=1,
    )
    fit_drop: float = _field(
        0.15,
        "a fit 0.15 below its running level for lost_scans scans in a row is suspect: the "
        "whole map is searched for a place that explains those scans better by "
        "evidence_margin (a robot carried to a place alike enough to fit, e.g. another part "
        "of the same corridor); found, the localizer is LOST and votes again",
        gt=0.0,
        lt=1.0,
    )
    fit_level_rate: float = _field(
        0.05,
        "the fit's running level follows each scan's fit by 5 % (about the last 20 scans)",
        gt=0.0,
        le=1.0,
    )
    fit_iterations: int = _field(
        12,
        "at most 12 Gauss-Newton iterations per fit: it converges in 3-6 from the odometry",
        ge=1,
    )
    fit_gate: float = _field(
        0.5,
        "a point pairs with a wall at most 50 cm away at the fit's start, shrinking to "
        "3 hit_sigma as it converges: further pairs pull toward a wrong wall",
        unit=M,
        gt=0.0,
    )
    odometry_translation: float = _field(
        0.05,
        "the odometry's step is trusted to 5 cm + 10 % of its length (σ) as the fit's prior",
        unit=M,
        ge=0.0,
    )
    odometry_rotation: float = _field(
        math.radians(3.0),
        "and its turn to 3° + 10 % of it",
        unit=RAD,
        ge=0.0,
    )
    odometry_fraction: float = _field(
        0.1,
        "the 10 % of the step's length and turn added to the odometry's σ above",
        ge=0.0,
    )
    covariance_points: float = _field(
        2.0,
        "the fit's covariance (residual variance times the inverse Hessian) counts the scan's "
        "points as 2 independent ones: along a wall the map's cells and the scan's points err "
        "together, so a scan holds about as much as its two main walls; against a mapping "
        "run's poses, more points make it overconfident",
        gt=0.0,
    )
    covariance_floor_cells: float = _field(
        0.7,
        "the covariance is at least (0.7 map cells)² in translation (3.5 cm in 5 cm cells): "
        "a wall's cell locates it to within a cell, and the map's passes disagree by about "
        "that much",
        gt=0.0,
    )
    covariance_floor_rotation: float = _field(
        math.radians(0.5),
        "and at least (0.5°)² in rotation, for the same reason (a cell at 6 m)",
        unit=RAD,
        ge=0.0,
    )
    covariance_fit_power: float = _field(
        4.0,
        "the covariance grows as fit^-4 (fit: the points' mean likelihood, 0..1): where the "
        "map explains less of the scan (clutter, a map drawn from passes that disagree) "
        "the pose against it is less sure than the residuals say; at a fit of 0.9 ×1.5, at "
        "0.6 ×7.7; without it one tracked scan in ten of a large hall's log lay beyond "
        "χ²(3)'s 99.9 % quantile",
        ge=0.0,
    )
    initial_sigma_translation: float = _field(
        0.5,
        "an initial pose given without σ is searched within 3σ = 1.5 m",
        unit=M,
        gt=0.0,
    )
    initial_sigma_rotation: float = _field(
        math.radians(15.0),
        "and 3σ = 45° in heading",
        unit=RAD,
        gt=0.0,
    )
    initial_free_distance: float = _field(
        0.5,
        "an initial pose must lie within 0.5 m of the map's free space: a pose inside a wall "
        "or off the map is a mistake the user should hear about",
        unit=M,
        ge=0.0,
    )
