"""One configuration for the whole pipeline: frozen dataclasses, TOML in and out.

Every threshold and every membership function lives here, each with the reason for its value
(``reasons()``). Angles are radians in the code; in TOML they sit in keys ending in ``_deg`` and
are converted once, at load. Unknown keys are an error that names the key.

``Config()`` is the default: the best configuration measurement supports (see the README).
``Config.preset("paper")`` keeps every rule and value the paper states (with SPEC's corrections)
and takes our defaults where the paper states none.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Mapping

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on 3.10 only
    import tomli as tomllib

import tomli_w

__all__ = [
    "ConfigError",
    "Config",
    "FuzzyConfig",
    "FilterConfig",
    "SegmentationConfig",
    "AngularPointConfig",
    "LineConfig",
    "VirtualPointConfig",
    "MatchingConfig",
    "FusionConfig",
    "RefinementConfig",
    "OdometryConfig",
    "PRESETS",
]

Triangle = tuple[float, float, float]


class ConfigError(ValueError):
    """A configuration value or file is wrong; the message names the key."""


def _reason(text: str, **kw: Any) -> Any:
    """A dataclass field whose metadata records why it has its default."""
    return field(metadata={"reason": text}, **kw)


def _partition(peaks: tuple[float, ...]) -> tuple[Triangle, ...]:
    """Triangles peaked at ``peaks`` whose feet are the neighbouring peaks: a partition of unity."""
    out = []
    for i, p in enumerate(peaks):
        left = peaks[i - 1] if i > 0 else p
        right = peaks[i + 1] if i + 1 < len(peaks) else p
        out.append((float(left), float(p), float(right)))
    return tuple(out)


_UNIT_SETS = _partition((0.0, 0.5, 1.0))  # S, M, B on [0, 1]


@dataclass(frozen=True)
class FuzzyConfig:
    """Membership functions (triangles ``(left foot, peak, right foot)``) and rule bases.

    Rule tables are written as strings of consequent labels ``S``/``M``/``B`` (centres 0, 0.5,
    1), one string per row: ``point_rules`` rows are ρ's sets GS..GB, columns β's sets S..B
    (Table 1); ``line_rules`` rows δ S..B, columns σ S..B (Table 2); ``virtual_pair_rules`` rows
    f_L2 S..B, columns f_L1 S..B (Table 3, upper); ``virtual_distance_rules`` rows d_v GS..GB,
    columns the upper table's result S..B (Table 3, lower).
    """

    inference: str = _reason(
        "eq. 4: product inference with centre-average defuzzification; 'mamdani' = min/max + centroid",
        default="product",
    )
    mamdani_resolution: int = _reason(
        "samples of the output universe for the Mamdani centroid", default=1001
    )
    detection_angle_sets: tuple[Triangle, ...] = _reason(
        "β's S, M, B on [0°, 90°] (SPEC default; Fig. 5 is missing from the text); stored in radians",
        default=_partition((0.0, math.pi / 4, math.pi / 2)),
    )
    distance_sets: tuple[Triangle, ...] = _reason(
        "ρ's GS..GB peaked at 0, ¼, ½, ¾, 1 × ρ_max = 8 m (SPEC default; Fig. 6 missing)",
        default=_partition((0.0, 2.0, 4.0, 6.0, 8.0)),
    )
    uncertainty_sets: tuple[Triangle, ...] = _reason(
        "u, δ, f_L1, f_L2 S, M, B on [0, 1] (SPEC default; Figs. 7–8 missing)", default=_UNIT_SETS
    )
    line_distance_sets: tuple[Triangle, ...] = _reason(
        "σ's S, M, B peaked at 0, ½, 1 × σ_max = 5 cm (SPEC default; Fig. 9 missing)",
        default=_partition((0.0, 0.025, 0.05)),
    )
    virtual_distance_sets: tuple[Triangle, ...] = _reason(
        "d_v's GS..GB peaked at 0, ¼, ½, ¾, 1 × d_max = 4 m (SPEC default; Fig. 10 missing)",
        default=_partition((0.0, 1.0, 2.0, 3.0, 4.0)),
    )
    output_centres: tuple[float, float, float] = _reason(
        "consequent centres of S, M, B (SPEC)", default=(0.0, 0.5, 1.0)
    )
    point_rules: tuple[str, ...] = _reason(
        "Table 1 (rows ρ GS..GB, columns β S..B)", default=("MSS", "MSS", "BMM", "BBM", "BBB")
    )
    line_rules: tuple[str, ...] = _reason(
        "Table 2 (rows δ S..B, columns σ S..B)", default=("SSM", "SMB", "MBB")
    )
    virtual_pair_rules: tuple[str, ...] = _reason(
        "Table 3 upper (rows f_L2 S..B, columns f_L1 S..B)", default=("SSM", "SMB", "MBB")
    )
    virtual_distance_rules: tuple[str, ...] = _reason(
        "Table 3 lower (rows d_v GS..GB, columns f_L1·f_L2 S..B)",
        default=("SSM", "SSM", "SMB", "MBB", "BBB"),
    )


@dataclass(frozen=True)
class FilterConfig:
    detection_angle_threshold: float = _reason(
        "ξ_TH = 22.5°, the paper's value (§3.1): points seen at a sharper angle are removed",
        default=math.radians(22.5),
    )


@dataclass(frozen=True)
class SegmentationConfig:
    gap_distance: float = _reason(
        "T2 (eq. 13), fixed part: 0.20 m between consecutive points is a gap (a doorway, an "
        "occlusion) at the 8 m scale of the fuzzy sets",
        default=0.20,
    )
    gap_distance_per_metre: float = _reason(
        "T2 grows with range: 5 beam spacings at the point's range (ρ·Δφ·5) so that a wall "
        "sampled sparsely far away is not cut into pieces",
        default=5.0,
    )
    gap_difference: float = _reason(
        "T1 (eq. 13): a gap must exceed the spacing on its other side by 0.10 m, so a "
        "uniformly sparse surface is not all break points",
        default=0.10,
    )
    min_cluster_points: int = _reason(
        "clusters too small to fit a line (fewer than 4 points, §5) are dropped", default=4
    )


@dataclass(frozen=True)
class AngularPointConfig:
    interior_angle_threshold: float = _reason(
        "θ_TH (eq. 14, as the interior angle): 135° separates corners (≈90°) from walls (180°) "
        "with room for noise",
        default=math.radians(135.0),
    )
    neighbour_step: int = _reason(
        "k (SPEC step 5): neighbours 3 beams away keep range noise from making every point a corner",
        default=3,
    )
    neighbour_distance: float = _reason(
        "the k-step neighbours must also be at least 0.10 m away (more beams are taken near the robot)",
        default=0.10,
    )
    refine: bool = _reason(
        "move an angular point to the intersection of its two lines (SPEC step 5): exact where "
        "the sampled corner is up to a beam spacing off",
        default=True,
    )
    pair_unrefined: bool = _reason(
        "with refine on, whether angular points whose two lines could not be intersected still "
        "take part in pairing: off, since a sampled corner is up to a beam spacing (several "
        "centimetres) off and the pose from two pairs inherits that",
        default=False,
    )


@dataclass(frozen=True)
class LineConfig:
    min_points: int = _reason("§5: only lines with at least four points are kept", default=4)
    corner_exclusion: int = _reason(
        "points within this many beams of an angular point belong to neither line (SPEC step 6)",
        default=1,
    )
    min_length: float = _reason(
        "lines shorter than 0.15 m give direction too poorly to intersect", default=0.15
    )


@dataclass(frozen=True)
class VirtualPointConfig:
    min_intersection_angle: float = _reason(
        "two lines must differ in direction by at least 30° to intersect well", default=math.radians(30.0)
    )
    max_uncertainty: float = _reason(
        "§3.6: virtual angular points more uncertain than this are removed", default=0.6
    )
    max_distance: float = _reason(
        "an intersection farther than this from its lines' centres is not a usable point",
        default=8.0,
    )
    merge_distance: float = _reason(
        "feature points closer than 0.10 m are one feature (a wall split by an occlusion gives "
        "its corner twice); the most certain is kept",
        default=0.10,
    )


@dataclass(frozen=True)
class MatchingConfig:
    pairing_distance: float = _reason(
        "T (eq. 18): a mapped feature pairs with the one feature of the next scan within 0.5 m",
        default=0.5,
    )
    same_kind_only: bool = _reason(
        "pair a feature only with one of its own kind (break/angular/virtual): fewer false pairs",
        default=True,
    )
    mutual: bool = _reason(
        "also require the pair to be the only candidate seen from the other scan", default=True
    )
    min_pair_separation: float = _reason(
        "eq. 22's determinant is ±|p′₁ − p′₂|²: two pairs closer than 0.3 m are ill-conditioned",
        default=0.3,
    )
    min_pairs: int = _reason("two pairs fix a pose (eq. 19–22)", default=2)
    use_break_points: bool = _reason(
        "break points are not the same physical point from two poses (§1): the default leaves "
        "them out of the pose",
        default=False,
    )
    use_angular_points: bool = _reason("real angular points (§3.4)", default=True)
    use_virtual_points: bool = _reason("virtual angular points (§3.6)", default=True)
    repair_iterations: int = _reason(
        "re-pair with the refined motion this many times, with the tighter distance below (0: "
        "line matching refines the motion instead; re-pairing changed no figure and cost a third "
        "of the matching time)",
        default=0,
    )
    repair_distance: float = _reason(
        "T for re-pairing once the motion is known to a few centimetres", default=0.15
    )
    match_lines: bool = _reason(
        "beyond the paper: line-to-line matching after the point features. Lines fitted to "
        "dozens of points give the rotation and the translation far more precisely than a "
        "dozen feature points; what they leave unobservable (a corridor) the prior decides",
        default=True,
    )
    lines_first: bool = _reason(
        "try line-to-line matching from the prior first and pair the point features only where "
        "the lines give no motion: the same figures in every test, 10 % faster",
        default=True,
    )
    keyframe_distance: float = _reason(
        "the paper is silent on how often a scan is matched: each scan is matched against a "
        "keyframe, renewed once the robot has moved 1 m (or turned keyframe_angle) from it, so "
        "the paper's consecutive-scan method runs on scans 1 m apart and the errors of many small "
        "increments do not add up (demo, default: mean error 0.27 m with 0.3 m, 0.14 m with 1 m; "
        "paper preset: 3.5 m matching every scan at 10 Hz, 0.65 m with 1 m); 0 matches every scan "
        "against the previous one",
        default=1.0,
    )
    keyframe_angle: float = _reason(
        "the keyframe is renewed once the robot has turned 30° from it", default=math.radians(30.0)
    )
    line_min_pairs: int = _reason(
        "line matching needs at least 2 paired lines (the two walls of a corridor fix the "
        "heading and the sideways position; the prior keeps the rest)",
        default=2,
    )
    line_angle_gate: float = _reason(
        "lines pair when their directions differ by less than 3° once the point features have "
        "given the motion (8° when starting from the prior, whose heading may be 5° off)",
        default=math.radians(3.0),
    )
    line_angle_gate_prior: float = _reason(
        "the angle gate when the point features gave no motion and pairing starts from the prior",
        default=math.radians(8.0),
    )
    line_distance_gate: float = _reason(
        "lines pair when their normal distances differ by less than 0.2 m (0.5 m from the prior)",
        default=0.2,
    )
    line_distance_gate_prior: float = _reason(
        "the distance gate when pairing lines starts from the prior", default=0.5
    )
    line_overlap_margin: float = _reason(
        "paired lines must overlap along their direction, give or take 0.5 m", default=0.5
    )
    line_prior_sigma: float = _reason(
        "the prior translation counts in the line fit as a measurement with a 5 cm standard "
        "deviation: lines that fix a direction overrule it by orders of magnitude, but along a "
        "corridor (walls parallel, or nearly so) the prior decides",
        default=0.05,
    )
    line_trim_angle: float = _reason(
        "line pairs whose rotation is beyond 3 robust sigmas of the median are dropped, never "
        "with a tighter cut than 0.2°",
        default=math.radians(0.2),
    )
    line_inlier_distance: float = _reason(
        "a line pair must agree within 5 cm with the best translation two non-parallel pairs "
        "fix (3 cm rejected good pairs of short noisy lines; an 8 cm false pair must go)",
        default=0.05,
    )


@dataclass(frozen=True)
class FusionConfig:
    method: str = _reason(
        "'weighted_mean' = eq. 23–24 (certainty weights, circular mean); 'least_squares' = "
        "certainty-weighted least squares over all pairs",
        default="least_squares",
    )
    robust: bool = _reason(
        "consensus before fusion: the two-pair solution that most pairs agree with picks the "
        "inlier pairs, so one false pair cannot drag the mean",
        default=True,
    )
    inlier_distance: float = _reason(
        "a pair agrees with a solution when its points land within 0.10 m of each other",
        default=0.10,
    )
    min_inliers: int = _reason(
        "with robust fusion, an increment needs at least 3 consistent pairs: two pairs always "
        "agree with their own solution, so a false one cannot be told apart",
        default=3,
    )
    trim_floor: float = _reason(
        "after the least-squares fit, pairs beyond 3 robust sigmas of the residuals (but never "
        "a tighter cut than 1 cm) are dropped and the fit repeated",
        default=0.01,
    )
    max_solutions: int = _reason(
        "at most this many two-pair solutions (all pairs of pairs up to it; a fixed random subset beyond)",
        default=2000,
    )


@dataclass(frozen=True)
class RefinementConfig:
    """Beyond the paper: the feature estimate refined by fuzzy-weighted point-to-line matching
    of every filtered point of the scan against the keyframe's points and their surface."""

    enabled: bool = _reason(
        "beyond the paper: features give the motion to a few centimetres; every filtered point "
        "matched to the keyframe's surfaces gives it to millimetres, also where a real log has "
        "too few lines (intel's clutter)",
        default=True,
    )
    max_distance: float = _reason(
        "a point pairs with the nearest keyframe point within 0.3 m at the first iteration",
        default=0.3,
    )
    min_distance: float = _reason(
        "the pairing distance shrinks each iteration down to 0.1 m", default=0.1
    )
    iterations: int = _reason("Gauss-Newton iterations at most", default=15)
    residual_scale: float = _reason(
        "Huber scale of the point-to-line residual: 5 cm (aces, first 2,900 scans: local rotation error 0.41° mean with 5 cm, 0.44° with 2 cm)", default=0.05
    )
    point_sigma: float = _reason(
        "each point weighs "
        "certainty / (5 cm)²: 1 cm made the points overrule the prior in corridors (aces: local "
        "rotation error 0.74° against 0.64°)",
        default=0.05,
    )
    degenerate_ratio: float = _reason(
        "where the points fix the translation in one direction less than 10 % as well as in the "
        "other (a corridor), the translation along it keeps the line matching's or the prior's "
        "value: the points' say there is mostly the noise of their normals, which pulls the "
        "estimate back toward the keyframe",
        default=0.1,
    )
    local_map_keyframes: int = _reason(
        "scans are refined against the surfaces of the last N keyframes (a local map); 2: "
        "aces all relations 0.214 m and local rotation 0.388° against 0.481 m and 0.406° with "
        "1, intel 0.745 m against 0.991 m (fuzzypos benchmark); with 3 the local figures "
        "stay and the long relations lose (aces 0.341 m, intel 0.947 m)",
        default=2,
    )
    length_weight_max: float = _reason(
        "each point's weight is multiplied by the stretch of surface it stands for (the "
        "distance to its nearer neighbour) over the scan's median, kept within [1/N, N]: the "
        "fit is one over the surfaces' length, and clutter next to the robot stops outvoting "
        "the walls; 5: intel all relations 0.745 m and local rotation 0.220° against 1.398 m "
        "and 0.255° with 1 (off), aces 0.214 m and 0.388° against 0.257 m and 0.426°",
        default=5.0,
    )
    length_cap: float = _reason(
        "a point's stretch of surface is at most 3 beam spacings at its range (across a gap "
        "or a jump edge its neighbour lies on another surface)",
        default=3.0,
    )
    hold_tolerance: float = _reason(
        "along such a direction the features' motion stands where it lies within 3 cm of the "
        "odometry's (doorways and jambs see it: simulated office corridor 0.17 m off at the end "
        "against 0.33 m with 0), else the odometry's does (intel, first 2,500 scans: local "
        "translation error 0.022 m mean against 0.038 m with 10 cm; break points in corridors)",
        default=0.03,
    )
    neighbour_distance: float = _reason(
        "consecutive keyframe points lie on one surface when closer than 0.3 m (or "
        "neighbour_ratio × their range)",
        default=0.3,
    )
    neighbour_ratio: float = _reason(
        "far walls are sampled sparsely: points closer than 5 % of their range are neighbours",
        default=0.05,
    )
    neighbour_step: int = _reason(
        "the normal is that of the chord from the 2nd neighbour before to the 2nd after",
        default=2,
    )
    min_points: int = _reason(
        "at least 20 points must pair for the refinement to count", default=20
    )
    min_inlier_fraction: float = _reason(
        "and at least 40 % of the scan's points must pair, else the refinement is not trusted",
        default=0.4,
    )
    skip_with_line_pairs: int = _reason(
        "where this many line pairs gave the motion it stands unrefined (0: always refine)",
        default=0,
    )
    also_from_odometry: bool = _reason(
        "where the features' motion and the odometry's differ by more than both_distance or "
        "both_angle, refine from the odometry's too and keep that one where it puts 2 % more of "
        "the scan within 2.5 cm of its surfaces (a refinement settles where it starts: aces' "
        "all-relations error 0.276 → 0.213 m, intel's 1.585 → 1.547 m)",
        default=True,
    )
    both_distance: float = _reason("5 cm", default=0.05)
    both_angle: float = _reason("1°", default=math.radians(1.0))
    prior_from_features: bool = _reason(
        "where the features gave a motion, it is the refinement's prior (it already holds the "
        "odometry's say along a corridor); else the odometry's",
        default=True,
    )
    max_bend_angle: float = _reason(
        "a keyframe point's normal is the chord across it where the chords to either side bend "
        "by less than 30°, else the chord on the side that runs straight on (next to a corner); "
        "a corner or a round pillar gives none. Tighter cost aces accuracy (real points are "
        "noisy), looser left millimetres of bias on simulated rooms",
        default=math.radians(30.0),
    )
    prior_sigma: float = _reason(
        "the starting motion counts as a measurement with 5 cm standard deviation in translation: "
        "along a corridor (every normal the same) the odometry keeps its say",
        default=0.05,
    )
    prior_sigma_angle: float = _reason(
        "and 2° in rotation", default=math.radians(2.0)
    )
    max_correction: float = _reason(
        "a refinement that moves the estimate by more than 0.5 m from its start is rejected",
        default=0.5,
    )


@dataclass(frozen=True)
class OdometryConfig:
    """How far the odometry prior is trusted (beyond the paper, which assumes sane odometry)."""

    max_speed: float = _reason(
        "an odometry increment faster than 1.5 m/s (plus max_jump_distance) is no robot's motion",
        default=1.5,
    )
    max_turn_rate: float = _reason(
        "nor one turning faster than 2 rad/s (plus max_jump_angle)", default=2.0
    )
    max_jump_distance: float = _reason(
        "allowance whatever the time step: stamps of real logs are not acquisition times (intel's "
        "bursts); 0.25 m is above any of intel's and aces' sane increments",
        default=0.25,
    )
    max_jump_angle: float = _reason(
        "allowance in rotation whatever the time step: 20°, above intel's largest sane increment "
        "(15.8°) and below aces' jump (60.6°)",
        default=math.radians(20.0),
    )
    jump_search_distance: float = _reason(
        "after a rejected increment the refinement pairs points within 1 m of the last "
        "increment's prediction",
        default=1.0,
    )
    search_angle: float = _reason(
        "the wider search tries every rotation (aces, scan 2,945: after a 3 s gap the scan is "
        "turned 82° from the previous one, the odometry says 22°, and catches up with a "
        "-60.6° jump a scan later)",
        default=math.pi,
    )
    search_angle_step: float = _reason("in steps of 2°", default=math.radians(2.0))
    search_translation_step: float = _reason(
        "and translations within jump_search_distance in steps of 0.2 m", default=0.2
    )
    search_distance_penalty: float = _reason(
        "the search's score (the fraction of points near a surface) is lowered by 0.1 per "
        "metre of translation from the start: of near-equal scores the one nearest the start "
        "wins (a simulated corridor with a rib every 0.2 m: without it the scan slides one rib "
        "along; no effect on the shared logs' figures)",
        default=0.1,
    )
    search_min_inlier_fraction: float = _reason(
        "a motion found by the wider search must pair 20 % of the scan's points (aces, scan "
        "2,945: after an 82° turn during a 3 s gap, 31 % of the scan pairs with the keyframes "
        "and the previous scan at the true turn; against the keyframes alone, 21–26 %)",
        default=0.2,
    )
    search_gate: float = _reason(
        "a candidate scores the fraction of points within 0.25 m of a keyframe point", default=0.25
    )
    failure_search_angle: float = _reason(
        "where matching from the prior fails otherwise, rotations within ±30° of it are searched "
        "(aces: 36 failures while turning, each found within 15° of the odometry; searching "
        "every rotation there found false matches in intel's offices)",
        default=math.radians(30.0),
    )
    failure_search_distance: float = _reason(
        "and translations within 0.4 m", default=0.4
    )
    search_after_gap: float = _reason(
        "where matching fails after more than 1 s without a scan, the wider search runs too (aces, "
        "scan 2,945: 3 s, an 82° turn the odometry missed); elsewhere a failure falls back to the "
        "odometry, which searching every rotation would only replace by false matches (intel)",
        default=1.0,
    )
    trust_stand_still: bool = _reason(
        "an odometry increment of exactly zero means the robot stands still: the estimate keeps "
        "its pose (real logs stand still for long stretches; matching there only adds noise)",
        default=True,
    )


_SECTIONS: dict[str, type] = {
    "fuzzy": FuzzyConfig,
    "filtering": FilterConfig,
    "segmentation": SegmentationConfig,
    "angular_points": AngularPointConfig,
    "lines": LineConfig,
    "virtual_points": VirtualPointConfig,
    "matching": MatchingConfig,
    "fusion": FusionConfig,
    "refinement": RefinementConfig,
    "odometry": OdometryConfig,
}

# fields holding angles (radians in code, degrees in TOML under "<name>_deg")
_ANGLE_FIELDS = {
    ("fuzzy", "detection_angle_sets"),
    ("filtering", "detection_angle_threshold"),
    ("angular_points", "interior_angle_threshold"),
    ("virtual_points", "min_intersection_angle"),
    ("matching", "keyframe_angle"),
    ("matching", "line_angle_gate"),
    ("matching", "line_angle_gate_prior"),
    ("matching", "line_trim_angle"),
    ("refinement", "prior_sigma_angle"),
    ("refinement", "max_bend_angle"),
    ("refinement", "both_angle"),
    ("odometry", "max_jump_angle"),
    ("odometry", "search_angle"),
    ("odometry", "search_angle_step"),
    ("odometry", "failure_search_angle"),
}


@dataclass(frozen=True)
class Config:
    """Every threshold and membership function of the pipeline."""

    fuzzy: FuzzyConfig = field(default_factory=FuzzyConfig)
    filtering: FilterConfig = field(default_factory=FilterConfig)
    segmentation: SegmentationConfig = field(default_factory=SegmentationConfig)
    angular_points: AngularPointConfig = field(default_factory=AngularPointConfig)
    lines: LineConfig = field(default_factory=LineConfig)
    virtual_points: VirtualPointConfig = field(default_factory=VirtualPointConfig)
    matching: MatchingConfig = field(default_factory=MatchingConfig)
    fusion: FusionConfig = field(default_factory=FusionConfig)
    refinement: RefinementConfig = field(default_factory=RefinementConfig)
    odometry: OdometryConfig = field(default_factory=OdometryConfig)

    def __post_init__(self) -> None:
        _validate(self)

    # -- presets -------------------------------------------------------------------------------
    @classmethod
    def preset(cls, name: str) -> "Config":
        """A named configuration: ``default`` or ``paper``."""
        try:
            overrides = PRESETS[name]
        except KeyError:
            raise ConfigError(f"unknown preset {name!r}; known: {', '.join(sorted(PRESETS))}") from None
        return cls().with_overrides(overrides)

    def with_overrides(self, overrides: Mapping[str, Mapping[str, Any]]) -> "Config":
        """A copy with ``{section: {field: value}}`` replaced (code units: radians)."""
        sections = {}
        for sec_name, values in overrides.items():
            if sec_name not in _SECTIONS:
                raise ConfigError(f"unknown config section {sec_name!r}")
            sec = getattr(self, sec_name)
            known = {f.name for f in fields(sec)}
            for k in values:
                if k not in known:
                    raise ConfigError(f"unknown config key {sec_name}.{k}")
            sections[sec_name] = replace(sec, **dict(values))
        return replace(self, **sections)

    # -- TOML ----------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, dict[str, Any]]:
        """Plain TOML-ready dictionary, angles in ``_deg`` keys."""
        out: dict[str, dict[str, Any]] = {}
        for sec_name in _SECTIONS:
            sec = getattr(self, sec_name)
            d: dict[str, Any] = {}
            for f in fields(sec):
                v = getattr(sec, f.name)
                if (sec_name, f.name) in _ANGLE_FIELDS:
                    d[f.name + "_deg"] = _to_deg(v)
                else:
                    d[f.name] = _plain(v)
            out[sec_name] = d
        return out

    @classmethod
    def from_dict(
        cls, data: Mapping[str, Any], base: "Config | None" = None, source: str = "config"
    ) -> "Config":
        """Build from a TOML-shaped mapping; keys missing keep ``base`` (default: ``Config()``)."""
        base = base if base is not None else cls()
        overrides: dict[str, dict[str, Any]] = {}
        for sec_name, values in data.items():
            if sec_name == "preset":
                continue
            if sec_name not in _SECTIONS:
                raise ConfigError(f"{source}: unknown config section [{sec_name}]")
            if not isinstance(values, Mapping):
                raise ConfigError(f"{source}: [{sec_name}] must be a table")
            sec = getattr(base, sec_name)
            ftypes = {f.name: f for f in fields(sec)}
            conv: dict[str, Any] = {}
            for key, raw in values.items():
                name = key[:-4] if key.endswith("_deg") else key
                is_angle = (sec_name, name) in _ANGLE_FIELDS
                if name not in ftypes or (is_angle != key.endswith("_deg")):
                    hint = f" (use {name}_deg)" if is_angle and not key.endswith("_deg") else ""
                    raise ConfigError(f"{source}: unknown config key {sec_name}.{key}{hint}")
                current = getattr(sec, name)
                conv[name] = _coerce(raw, current, is_angle, f"{source}: {sec_name}.{key}")
            overrides[sec_name] = conv
        return base.with_overrides(overrides)

    @classmethod
    def from_toml(cls, path: str | Path) -> "Config":
        """Load a TOML file; an optional top-level ``preset = "paper"`` picks the base."""
        p = Path(path)
        try:
            text = p.read_text(encoding="utf-8")
        except OSError as exc:
            raise ConfigError(f"{p}: cannot read config: {exc.strerror or exc}") from None
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"{p}: invalid TOML: {exc}") from None
        preset = data.get("preset", "default")
        if not isinstance(preset, str):
            raise ConfigError(f"{p}: preset must be a string")
        return cls.from_dict(data, base=cls.preset(preset), source=str(p))

    def to_toml(self) -> str:
        return tomli_w.dumps(self.to_dict())

    def dump(self, path: str | Path) -> None:
        Path(path).write_text(self.to_toml(), encoding="utf-8")

    @staticmethod
    def reasons() -> dict[str, str]:
        """``{"section.key": reason}`` for every setting."""
        out = {}
        for sec_name, cls_ in _SECTIONS.items():
            for f in fields(cls_):
                out[f"{sec_name}.{f.name}"] = f.metadata.get("reason", "")
        return out


# The paper's way: every rule and value it states, with SPEC's corrections; ours elsewhere.
PRESETS: dict[str, dict[str, dict[str, Any]]] = {
    "default": {},
    "paper": {
        "angular_points": {"refine": False, "pair_unrefined": True},
        "matching": {
            "same_kind_only": False,
            "mutual": False,
            "use_break_points": True,
            "use_angular_points": True,
            "use_virtual_points": True,
            "repair_iterations": 0,
            "match_lines": False,
        },
        "fusion": {"method": "weighted_mean", "robust": False},
        "refinement": {"enabled": False},
    },
}


# -- helpers -------------------------------------------------------------------------------------
def _to_deg(v: Any) -> Any:
    if isinstance(v, tuple):
        return [_to_deg(x) for x in v]
    return round(math.degrees(v), 12)


def _plain(v: Any) -> Any:
    if isinstance(v, tuple):
        return [_plain(x) for x in v]
    return v


def _coerce(raw: Any, current: Any, is_angle: bool, where: str) -> Any:
    """Convert a TOML value to the type of ``current`` (the default), degrees to radians."""
    if isinstance(current, bool):
        if not isinstance(raw, bool):
            raise ConfigError(f"{where} must be true or false, got {raw!r}")
        return raw
    if isinstance(current, int):
        if isinstance(raw, bool) or not isinstance(raw, int):
            raise ConfigError(f"{where} must be an integer, got {raw!r}")
        return raw
    if isinstance(current, float):
        if isinstance(raw, bool) or not isinstance(raw, (int, float)):
            raise ConfigError(f"{where} must be a number, got {raw!r}")
        return math.radians(raw) if is_angle else float(raw)
    if isinstance(current, str):
        if not isinstance(raw, str):
            raise ConfigError(f"{where} must be a string, got {raw!r}")
        return raw
    if isinstance(current, tuple):
        if not isinstance(raw, list):
            raise ConfigError(f"{where} must be a list, got {raw!r}")
        if current and isinstance(current[0], tuple):  # list of triangles
            out = []
            for item in raw:
                if not isinstance(item, list) or len(item) != 3:
                    raise ConfigError(f"{where}: each membership function is [left, peak, right]")
                out.append(tuple(_coerce(x, 0.0, is_angle, where) for x in item))
            return tuple(out)
        if current and isinstance(current[0], str):
            return tuple(_coerce(x, "", False, where) for x in raw)
        return tuple(_coerce(x, 0.0, is_angle, where) for x in raw)
    raise ConfigError(f"{where}: unsupported value {raw!r}")  # pragma: no cover


def _check_sets(name: str, sets: tuple[Triangle, ...], n: int | None = None) -> None:
    if n is not None and len(sets) != n:
        raise ConfigError(f"fuzzy.{name} needs {n} membership functions, got {len(sets)}")
    for t in sets:
        if len(t) != 3 or not all(math.isfinite(v) for v in t):
            raise ConfigError(f"fuzzy.{name}: {t!r} is not a finite (left, peak, right) triangle")
        if not t[0] <= t[1] <= t[2] or t[0] == t[2]:
            raise ConfigError(f"fuzzy.{name}: {t!r} needs left <= peak <= right and left < right")
    peaks = [t[1] for t in sets]
    if peaks != sorted(peaks):
        raise ConfigError(f"fuzzy.{name}: membership functions must be ordered by their peaks")


def _check_rules(name: str, rules: tuple[str, ...], rows: int, cols: int) -> None:
    if len(rules) != rows or any(len(r) != cols or set(r) - set("SMB") for r in rules):
        raise ConfigError(
            f"fuzzy.{name} needs {rows} rows of {cols} labels from S/M/B, got {list(rules)!r}"
        )


def _validate(cfg: Config) -> None:
    fz = cfg.fuzzy
    if fz.inference not in ("product", "mamdani"):
        raise ConfigError(f"fuzzy.inference must be 'product' or 'mamdani', got {fz.inference!r}")
    if fz.mamdani_resolution < 11:
        raise ConfigError("fuzzy.mamdani_resolution must be at least 11")
    _check_sets("detection_angle_sets", fz.detection_angle_sets, 3)
    _check_sets("distance_sets", fz.distance_sets, 5)
    _check_sets("uncertainty_sets", fz.uncertainty_sets, 3)
    _check_sets("line_distance_sets", fz.line_distance_sets, 3)
    _check_sets("virtual_distance_sets", fz.virtual_distance_sets, 5)
    if len(fz.output_centres) != 3:
        raise ConfigError("fuzzy.output_centres needs 3 values (S, M, B)")
    _check_rules("point_rules", fz.point_rules, 5, 3)
    _check_rules("line_rules", fz.line_rules, 3, 3)
    _check_rules("virtual_pair_rules", fz.virtual_pair_rules, 3, 3)
    _check_rules("virtual_distance_rules", fz.virtual_distance_rules, 5, 3)
    positive = {
        "segmentation.gap_distance": cfg.segmentation.gap_distance,
        "matching.pairing_distance": cfg.matching.pairing_distance,
        "matching.repair_distance": cfg.matching.repair_distance,
        "matching.line_angle_gate": cfg.matching.line_angle_gate,
        "matching.line_angle_gate_prior": cfg.matching.line_angle_gate_prior,
        "matching.line_distance_gate": cfg.matching.line_distance_gate,
        "matching.line_distance_gate_prior": cfg.matching.line_distance_gate_prior,
        "matching.line_prior_sigma": cfg.matching.line_prior_sigma,
        "virtual_points.max_distance": cfg.virtual_points.max_distance,
        "refinement.max_distance": cfg.refinement.max_distance,
        "refinement.min_distance": cfg.refinement.min_distance,
        "refinement.residual_scale": cfg.refinement.residual_scale,
        "refinement.point_sigma": cfg.refinement.point_sigma,
        "refinement.max_bend_angle": cfg.refinement.max_bend_angle,
        "refinement.neighbour_distance": cfg.refinement.neighbour_distance,
        "refinement.neighbour_ratio": cfg.refinement.neighbour_ratio,
        "refinement.prior_sigma": cfg.refinement.prior_sigma,
        "refinement.prior_sigma_angle": cfg.refinement.prior_sigma_angle,
        "refinement.max_correction": cfg.refinement.max_correction,
        "odometry.max_speed": cfg.odometry.max_speed,
        "odometry.max_turn_rate": cfg.odometry.max_turn_rate,
        "odometry.jump_search_distance": cfg.odometry.jump_search_distance,
        "odometry.search_angle": cfg.odometry.search_angle,
        "odometry.search_angle_step": cfg.odometry.search_angle_step,
        "odometry.search_translation_step": cfg.odometry.search_translation_step,
        "odometry.search_gate": cfg.odometry.search_gate,
        "odometry.failure_search_angle": cfg.odometry.failure_search_angle,
        "odometry.failure_search_distance": cfg.odometry.failure_search_distance,

    }
    for key, v in positive.items():
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ConfigError(f"{key} must be a positive number, got {v!r}")
    nonneg = {
        "segmentation.gap_distance_per_metre": cfg.segmentation.gap_distance_per_metre,
        "segmentation.gap_difference": cfg.segmentation.gap_difference,
        "matching.min_pair_separation": cfg.matching.min_pair_separation,
        "lines.min_length": cfg.lines.min_length,
        "angular_points.neighbour_distance": cfg.angular_points.neighbour_distance,
        "fusion.inlier_distance": cfg.fusion.inlier_distance,
        "matching.line_overlap_margin": cfg.matching.line_overlap_margin,
        "matching.line_trim_angle": cfg.matching.line_trim_angle,
        "matching.keyframe_distance": cfg.matching.keyframe_distance,
        "matching.keyframe_angle": cfg.matching.keyframe_angle,
        "matching.line_inlier_distance": cfg.matching.line_inlier_distance,
        "fusion.trim_floor": cfg.fusion.trim_floor,
        "odometry.max_jump_distance": cfg.odometry.max_jump_distance,
        "refinement.hold_tolerance": cfg.refinement.hold_tolerance,
        "odometry.max_jump_angle": cfg.odometry.max_jump_angle,
    }
    for key, v in nonneg.items():
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
            raise ConfigError(f"{key} must be a non-negative number, got {v!r}")
    if not 0 <= cfg.filtering.detection_angle_threshold < math.pi / 2:
        raise ConfigError("filtering.detection_angle_threshold must lie in [0°, 90°)")
    if not 0 < cfg.angular_points.interior_angle_threshold < math.pi:
        raise ConfigError("angular_points.interior_angle_threshold must lie in (0°, 180°)")
    if cfg.angular_points.neighbour_step < 1:
        raise ConfigError("angular_points.neighbour_step must be at least 1")
    if cfg.lines.min_points < 2:
        raise ConfigError("lines.min_points must be at least 2")
    if cfg.segmentation.min_cluster_points < 1:
        raise ConfigError("segmentation.min_cluster_points must be at least 1")
    if cfg.lines.corner_exclusion < 0:
        raise ConfigError("lines.corner_exclusion must be non-negative")
    if not 0 < cfg.virtual_points.min_intersection_angle <= math.pi / 2:
        raise ConfigError("virtual_points.min_intersection_angle must lie in (0°, 90°]")
    if cfg.matching.min_pairs < 2:
        raise ConfigError("matching.min_pairs must be at least 2")
    if cfg.matching.line_min_pairs < 2:
        raise ConfigError("matching.line_min_pairs must be at least 2")
    if cfg.matching.repair_iterations < 0:
        raise ConfigError("matching.repair_iterations must be non-negative")
    if cfg.fusion.method not in ("weighted_mean", "least_squares"):
        raise ConfigError(
            f"fusion.method must be 'weighted_mean' or 'least_squares', got {cfg.fusion.method!r}"
        )
    if cfg.refinement.iterations < 1:
        raise ConfigError("refinement.iterations must be at least 1")
    if not 0 < cfg.refinement.max_bend_angle <= math.pi / 2:
        raise ConfigError("refinement.max_bend_angle must lie in (0°, 90°]")
    if not (math.isfinite(cfg.refinement.length_weight_max) and cfg.refinement.length_weight_max >= 1.0):
        raise ConfigError("refinement.length_weight_max must be a number >= 1 (1 turns it off)")
    if not (math.isfinite(cfg.refinement.length_cap) and cfg.refinement.length_cap > 0.0):
        raise ConfigError("refinement.length_cap must be a positive number")
    if cfg.refinement.local_map_keyframes < 1:
        raise ConfigError("refinement.local_map_keyframes must be at least 1")
    if cfg.refinement.neighbour_step < 1:
        raise ConfigError("refinement.neighbour_step must be at least 1")
    if cfg.refinement.min_points < 3:
        raise ConfigError("refinement.min_points must be at least 3")
    if not (math.isfinite(cfg.odometry.search_distance_penalty) and cfg.odometry.search_distance_penalty >= 0):
        raise ConfigError("odometry.search_distance_penalty must be a number >= 0")
    if not 0 <= cfg.odometry.search_min_inlier_fraction <= 1:
        raise ConfigError("odometry.search_min_inlier_fraction must lie in [0, 1]")
    if not 0 <= cfg.refinement.min_inlier_fraction <= 1:
        raise ConfigError("refinement.min_inlier_fraction must lie in [0, 1]")
    if cfg.refinement.min_distance > cfg.refinement.max_distance:
        raise ConfigError("refinement.min_distance must not exceed refinement.max_distance")
    if cfg.fusion.min_inliers < 2:
        raise ConfigError("fusion.min_inliers must be at least 2")
    if cfg.fusion.max_solutions < 1:
        raise ConfigError("fusion.max_solutions must be at least 1")
    if not (cfg.matching.use_break_points or cfg.matching.use_angular_points
            or cfg.matching.use_virtual_points):
        raise ConfigError("matching: at least one kind of feature point must be used")

