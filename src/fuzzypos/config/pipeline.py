"""The configuration sections of the positioner's stages: matching, fusion, the refinement,
the odometry prior and the search. Part of :mod:`fuzzypos.config`, which assembles every
section into ``Config``."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .schema import _field, section

RAD = "rad"  # an angle: radians in code, degrees under "<name>_deg" in TOML
M = "m"


@dataclass(frozen=True)
@section("matching")
class MatchingConfig:
    pairing_distance: float = _field(
        0.5,
        "T (eq. 18): a mapped feature pairs with the one feature of the next scan within 0.5 m",
        unit=M,
        gt=0.0,
    )
    same_kind_only: bool = _field(
        True,
        "pair a feature only with one of its own kind (break/angular/virtual): fewer false pairs",
    )
    mutual: bool = _field(
        True, "also require the pair to be the only candidate seen from the other scan"
    )
    min_pair_separation: float = _field(
        0.3,
        "eq. 22's determinant is ±|p′₁ − p′₂|²: two pairs closer than 0.3 m are ill-conditioned",
        unit=M,
        ge=0.0,
    )
    min_pairs: int = _field(2, "two pairs fix a pose (eq. 19–22)", ge=2)
    use_break_points: bool = _field(
        False,
        "break points are not the same physical point from two poses (§1): the default leaves "
        "them out of the pose",
    )
    use_angular_points: bool = _field(True, "real angular points (§3.4)")
    use_virtual_points: bool = _field(True, "virtual angular points (§3.6)")
    match_lines: bool = _field(
        True,
        "beyond the paper: line-to-line matching after the point features. Lines fitted to "
        "dozens of points give the rotation and the translation far more precisely than a "
        "dozen feature points; what they leave unobservable (a corridor) the prior decides",
    )
    lines_first: bool = _field(
        True,
        "try line-to-line matching from the prior first and pair the point features only where "
        "the lines give no motion: where lines give a motion the point features add nothing to "
        "it, so pairing them there is wasted time",
    )
    keyframe_distance: float = _field(
        1.0,
        "the paper is silent on how often a scan is matched: each scan is matched against a "
        "keyframe, renewed once the robot has moved 1 m (or turned keyframe_angle) from it. "
        "Every match adds an error of its own; matching scans 1 m apart adds few of them while "
        "consecutive keyframes still overlap mostly. 0 matches every scan against the previous "
        "one (the paper's consecutive-scan method)",
        unit=M,
        ge=0.0,
    )
    keyframe_angle: float = _field(
        math.radians(30.0),
        "the keyframe is renewed once the robot has turned 30° from it, before the turn takes "
        "much of the keyframe's scene out of sight",
        unit=RAD,
        ge=0.0,
    )
    line_min_pairs: int = _field(
        2,
        "line matching needs at least 2 paired lines (the two walls of a corridor fix the "
        "heading and the sideways position; the prior keeps the rest)",
        ge=2,
    )
    line_angle_gate: float = _field(
        math.radians(3.0),
        "lines pair when their directions differ by less than 3° once the point features have "
        "given the motion (8° when starting from the prior, whose heading may be 5° off)",
        unit=RAD,
        gt=0.0,
    )
    line_angle_gate_prior: float = _field(
        math.radians(8.0),
        "the angle gate when the point features gave no motion and pairing starts from the prior",
        unit=RAD,
        gt=0.0,
    )
    line_distance_gate: float = _field(
        0.2,
        "lines pair when their normal distances differ by less than 0.2 m (0.5 m from the prior)",
        unit=M,
        gt=0.0,
    )
    line_distance_gate_prior: float = _field(
        0.5, "the distance gate when pairing lines starts from the prior", unit=M, gt=0.0
    )
    line_overlap_margin: float = _field(
        0.5,
        "paired lines must overlap along their direction, give or take 0.5 m",
        unit=M,
        ge=0.0,
    )
    line_prior_sigma: float = _field(
        0.05,
        "the prior translation counts in the line fit as a measurement with a 5 cm standard "
        "deviation: lines that fix a direction overrule it by orders of magnitude, but along a "
        "corridor (walls parallel, or nearly so) the prior decides",
        unit=M,
        gt=0.0,
    )
    line_trim_angle: float = _field(
        math.radians(0.2),
        "line pairs whose rotation is beyond 3 robust sigmas of the median are dropped, never "
        "with a tighter cut than 0.2° (good lines agree to about that; a tighter cut would drop "
        "them for their noise alone)",
        unit=RAD,
        ge=0.0,
    )
    line_inlier_distance: float = _field(
        0.05,
        "a line pair must agree within 5 cm with the best translation two non-parallel pairs "
        "fix: short noisy lines scatter by a few centimetres, a false pair (a neighbouring "
        "wall) lies farther off",
        unit=M,
        ge=0.0,
    )
    line_consensus_angle: float = _field(
        math.asin(0.342),
        "two line pairs fix a translation in the consensus only when their normals differ by at "
        "least 20°: nearly parallel lines fix it only across them, and the error along them "
        "grows as 1/sin of the angle",
        unit=RAD,
        gt=0.0,
        le=math.pi / 2,
    )
    line_repair_fraction: float = _field(
        0.1,
        "line matching pairs again with its own result unless that moved by less than this "
        "fraction of the gates (then the pairs would be the same)",
        gt=0.0,
        le=1.0,
    )
    line_passes: int = _field(
        2,
        "at most this many pairing passes of line matching: the second pass, with the first "
        "pass's motion, catches pairs the prior's error hid",
        ge=1,
    )


@dataclass(frozen=True)
@section("fusion")
class FusionConfig:
    method: str = _field(
        "least_squares",
        "'weighted_mean' = eq. 23–24 (certainty weights, circular mean); 'least_squares' = "
        "certainty-weighted least squares over all pairs",
        choices=("weighted_mean", "least_squares"),
    )
    robust: bool = _field(
        True,
        "consensus before fusion: the two-pair solution that most pairs agree with picks the "
        "inlier pairs, so one false pair cannot drag the mean",
    )
    inlier_distance: float = _field(
        0.10,
        "a pair agrees with a solution when its points land within 0.10 m of each other",
        unit=M,
        ge=0.0,
    )
    min_inliers: int = _field(
        3,
        "with robust fusion, an increment needs at least 3 consistent pairs: two pairs always "
        "agree with their own solution, so a false one cannot be told apart",
        ge=2,
    )
    trim_floor: float = _field(
        0.01,
        "after the least-squares fit, pairs beyond 3 robust sigmas of the residuals (but never "
        "a tighter cut than 1 cm) are dropped and the fit repeated",
        unit=M,
        ge=0.0,
    )
    max_solutions: int = _field(
        2000,
        "at most this many two-pair solutions (all pairs of pairs up to it; a fixed random "
        "subset beyond): the consensus costs the square of the pairs",
        ge=1,
    )


@dataclass(frozen=True)
@section("refinement")
class RefinementConfig:
    """Beyond the paper: the feature estimate refined by fuzzy-weighted point-to-line matching
    of every filtered point of the scan against the keyframe's points and their surface."""

    enabled: bool = _field(
        True,
        "beyond the paper: features give the motion to a few centimetres; every filtered point "
        "matched to the keyframe's surfaces gives it to millimetres, also where a real log has "
        "too few lines (clutter)",
    )
    max_distance: float = _field(
        0.3,
        "a point pairs with the nearest keyframe point within 0.3 m at the first iteration",
        unit=M,
        gt=0.0,
    )
    min_distance: float = _field(
        0.1, "the pairing distance shrinks each iteration down to 0.1 m", unit=M, gt=0.0
    )
    iterations: int = _field(15, "Gauss-Newton iterations at most", ge=1)
    residual_scale: float = _field(
        0.05,
        "Huber scale of the point-to-line residual: 5 cm, about the range noise plus the error "
        "of the normals; a smaller scale treats good points as outliers and leaves the fit to "
        "few points",
        unit=M,
        gt=0.0,
    )
    point_sigma: float = _field(
        0.05,
        "each point weighs certainty / (5 cm)²: with a smaller sigma the many points overrule "
        "the prior along a corridor, where their normals all agree and say nothing along it",
        unit=M,
        gt=0.0,
    )
    degenerate_ratio: float = _field(
        0.1,
        "where the points fix the translation in one direction less than 10 % as well as in the "
        "other (a corridor), the translation along it keeps the line matching's or the prior's "
        "value: the points' say there is mostly the noise of their normals, which pulls the "
        "estimate back toward the keyframe",
        ge=0.0,
        le=1.0,
    )
    local_map_keyframes: int = _field(
        2,
        "scans are refined against the surfaces of the last N keyframes (a local map): 2 fills "
        "what one keyframe does not see, while older keyframes bring their own drift into the "
        "fit",
        ge=1,
    )
    length_weight_max: float = _field(
        5.0,
        "each point's weight is multiplied by the stretch of surface it stands for (the "
        "distance to its nearer neighbour) over the scan's median, kept within [1/N, N]: the "
        "fit is one over the surfaces' length, and clutter next to the robot (sampled densely) "
        "stops outvoting the walls; 1 turns it off",
        ge=1.0,
    )
    length_cap: float = _field(
        3.0,
        "a point's stretch of surface is at most 3 beam spacings at its range (across a gap "
        "or a jump edge its neighbour lies on another surface)",
        gt=0.0,
    )
    hold_tolerance: float = _field(
        0.03,
        "along such a direction the features' motion stands where it lies within 3 cm of the "
        "odometry's (doorways and jambs see it), else the odometry's does: a feature motion "
        "farther off along a corridor comes from break points, which are not fixed points",
        unit=M,
        ge=0.0,
    )
    neighbour_distance: float = _field(
        0.3,
        "consecutive keyframe points lie on one surface when closer than 0.3 m (or "
        "neighbour_ratio × their range)",
        unit=M,
        gt=0.0,
    )
    neighbour_ratio: float = _field(
        0.05,
        "far walls are sampled sparsely: points closer than 5 % of their range are neighbours",
        gt=0.0,
    )
    neighbour_step: int = _field(
        2,
        "the normal is that of the chord from the 2nd neighbour before to the 2nd after",
        ge=1,
    )
    min_points: int = _field(20, "at least 20 points must pair for the refinement to count", ge=3)
    min_inlier_fraction: float = _field(
        0.4,
        "and at least 40 % of the scan's points must pair, else the refinement is not trusted",
        ge=0.0,
        le=1.0,
    )
    with_previous_scan: bool = _field(
        False,
        "where nothing fits against the local map (the scan has moved so far from the "
        "keyframes that too little of it pairs), refine once more against the local map and "
        "the previous scan, whose view overlaps most, instead of falling back on the features' "
        "motion from a few pairs (or the prior), which at the keyframe distance becomes the "
        "keyframe the next scans are matched against. Off: it moves the keyframes, and in a "
        "corridor of alike doors the loop closer then accepts two false closures that agree "
        "with each other (its verification prefers a door along the corridor that the submap "
        "covers over the true place, whose view it does not)",
    )
    also_from_odometry: bool = _field(
        True,
        "where the features' motion and the odometry's differ by more than both_distance or "
        "both_angle, refine from the odometry's too and keep that one where it fits better "
        "(both_min_gain): a refinement settles in the minimum nearest its start, and a false "
        "feature motion starts it in the wrong one",
    )
    both_distance: float = _field(
        0.05,
        "starts 5 cm apart can settle in different minima (the Huber scale): beyond that both "
        "are refined",
        unit=M,
        ge=0.0,
    )
    both_angle: float = _field(
        math.radians(1.0),
        "and starts 1° apart: at a few metres' range that moves points by a few centimetres",
        unit=RAD,
        ge=0.0,
    )
    prior_from_features: bool = _field(
        True,
        "where the features gave a motion, it is the refinement's prior (it already holds the "
        "odometry's say along a corridor); else the odometry's",
    )
    max_bend_angle: float = _field(
        math.radians(30.0),
        "a keyframe point's normal is the chord across it where the chords to either side bend "
        "by less than 30°, else the chord on the side that runs straight on (next to a corner); "
        "a corner or a round pillar gives none. Tighter rejects noisy real walls, looser bends "
        "normals round corners and biases the fit",
        unit=RAD,
        gt=0.0,
        le=math.pi / 2,
    )
    prior_sigma: float = _field(
        0.05,
        "the starting motion counts as a measurement with 5 cm standard deviation in "
        "translation: along a corridor (every normal the same) the odometry keeps its say",
        unit=M,
        gt=0.0,
    )
    prior_sigma_angle: float = _field(
        math.radians(2.0),
        "and 2° in rotation, about what odometry drifts between keyframes",
        unit=RAD,
        gt=0.0,
    )
    max_correction: float = _field(
        0.5,
        "a refinement that moves the estimate by more than 0.5 m from its start is rejected: "
        "beyond the pairing distance it has paired with other surfaces",
        unit=M,
        gt=0.0,
    )
    weight_floor: float = _field(
        0.05,
        "a point's certainty weight 1 − u is at least this (an uncertain point still says where "
        "a surface is)",
        gt=0.0,
        le=1.0,
    )
    both_min_gain: float = _field(
        0.02,
        "the refinement from the odometry's start replaces the one from the features' only "
        "where it puts this fraction more of the scan's points within half the Huber scale of "
        "its surfaces: of two near-equal fits the features' stands",
        ge=0.0,
        le=1.0,
    )
    pairing_spacing: float = _field(
        2.0,
        "a point pairs with the nearest keyframe point within the shrinking distance or "
        "within two beam spacings at its own range, whichever is larger: the keyframe samples "
        "a surface about as sparsely as the scan, so a point's neighbour on it lies up to a "
        "spacing away, plus the start's error; far walls are sampled sparsely (a degree is "
        "0.6 m at 36 m), where a fixed distance leaves most of a scan unpaired (0: the fixed "
        "distance alone)",
        ge=0.0,
    )
    trim_floor: float = _field(
        0.002,
        "once converged, pairs beyond 3 robust sigmas of the residuals are dropped, never with "
        "a tighter cut than this (2 mm, below any real range noise)",
        unit=M,
        ge=0.0,
    )
    gate_steps: int = _field(
        3,
        "the pairing distance shrinks geometrically from max_distance to min_distance over this "
        "many iterations: wide while the start may be off, tight once the fit is close",
        ge=1,
    )
    converged_translation: float = _field(
        1e-4,
        "Gauss-Newton has converged when the step's |dx| + |dy| is below this (0.1 mm, far "
        "below the range noise), or when the step and the one before it cancel to within it "
        "(a two-cycle: a point at the gate's edge paired and unpaired by turns)",
        unit=M,
        gt=0.0,
    )
    converged_rotation: float = _field(
        1e-5,
        "and its |dθ| below this (1e-5 rad moves a point 8 m away by 0.08 mm)",
        unit=RAD,
        gt=0.0,
    )


@dataclass(frozen=True)
@section("odometry")
class OdometryConfig:
    """How far the odometry prior is trusted (beyond the paper, which assumes sane odometry)."""

    max_speed: float = _field(
        1.5,
        "an odometry increment faster than 1.5 m/s (plus max_jump_distance) is no indoor "
        "robot's motion",
        unit="m/s",
        gt=0.0,
    )
    max_turn_rate: float = _field(
        2.0, "nor one turning faster than 2 rad/s (plus max_jump_angle)", unit="rad/s", gt=0.0
    )
    max_jump_distance: float = _field(
        0.25,
        "allowance whatever the time step: stamps of real logs are not acquisition times (scans "
        "come in bursts), and a sane increment between two stamps stays below 0.25 m",
        unit=M,
        ge=0.0,
    )
    max_jump_angle: float = _field(
        math.radians(20.0),
        "allowance in rotation whatever the time step: 20°, above the sane increments of real "
        "logs and well below the jumps of their odometry",
        unit=RAD,
        ge=0.0,
    )
    trust_stand_still: bool = _field(
        True,
        "an odometry increment of exactly zero means the robot stands still: the estimate keeps "
        "its pose (real logs stand still for long stretches; matching there only adds noise)",
    )


@dataclass(frozen=True)
@section("search")
class SearchConfig:
    """The wider search for a start where the odometry has lost its say (a jump, a gap)."""

    jump_distance: float = _field(
        1.0,
        "after a rejected increment the refinement pairs points within 1 m of the last "
        "increment's prediction: a robot moves less than that in a scan or two",
        unit=M,
        gt=0.0,
    )
    angle: float = _field(
        math.pi,
        "the wider search tries every rotation: after a jump or a gap the odometry's heading "
        "says nothing (the robot may have turned far during a gap the odometry missed)",
        unit=RAD,
        gt=0.0,
    )
    angle_step: float = _field(
        math.radians(2.0),
        "in steps of 2°: the refinement from the best candidate converges from a few degrees off",
        unit=RAD,
        gt=0.0,
    )
    translation_step: float = _field(
        0.2,
        "and translations within jump_distance in steps of 0.2 m, within the refinement's "
        "pairing distance of any true start",
        unit=M,
        gt=0.0,
    )
    distance_penalty: float = _field(
        0.1,
        "the search's score (the fraction of points near a surface) is lowered by 0.1 per metre "
        "of translation from the start: of near-equal scores the one nearest the start wins "
        "(repetitive structure, a corridor with a rib every 0.2 m, scores alike one rib along)",
        unit="1/m",
        ge=0.0,
    )
    min_inlier_fraction: float = _field(
        0.2,
        "a motion found by the wider search must pair 20 % of the scan's points: after a large "
        "turn part of the scene is new, so the refinement's usual fraction would reject true "
        "matches, while a false match in clutter pairs less",
        ge=0.0,
        le=1.0,
    )
    gate: float = _field(
        0.25,
        "a candidate scores the fraction of points within 0.25 m of a keyframe point: about "
        "the search's grid step, so the true start's cell scores",
        unit=M,
        gt=0.0,
    )
    failure_angle: float = _field(
        math.radians(30.0),
        "where matching from the prior fails otherwise, rotations within ±30° of it are "
        "searched: such failures come while turning, with the heading off by the turn's "
        "error; every rotation would find false matches in repetitive offices",
        unit=RAD,
        gt=0.0,
    )
    failure_distance: float = _field(
        0.4, "and translations within 0.4 m (twice the grid step)", unit=M, gt=0.0
    )
    after_gap: float = _field(
        1.0,
        "where matching fails after more than 1 s without a scan, the wider search runs too: a "
        "gap is where odometry misses turns; elsewhere a failure falls back to the odometry, "
        "which searching every rotation would only replace by false matches",
        unit="s",
        ge=0.0,
    )
    max_points: int = _field(
        60,
        "the search scores at most this many of the scan's points, evenly picked: enough to "
        "tell the true start from others, and the search's cost grows with them",
        ge=1,
    )
    weak_prior_scale: float = _field(
        100.0,
        "after a jump or a gap the refinement from the search's start weighs the prior with "
        "standard deviations this many times larger (the odometry has lost its say)",
        ge=1.0,
    )
    batch_size: int = _field(
        200_000,
        "at most this many transformed points go into one KD-tree query (bounded memory)",
        ge=1,
    )
