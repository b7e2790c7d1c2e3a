"""The configuration section of loop closure on a pose graph (``[loop_closure]``, issue 13).
Part of :mod:`fuzzypos.config`, which assembles every section into ``Config``."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .schema import _field, section

RAD = "rad"  # an angle: radians in code, degrees under "<name>_deg" in TOML
M = "m"


@dataclass(frozen=True)
@section("loop_closure")
class LoopClosureConfig:
    """Loop closure: a pose graph over the keyframes, candidates gated by the graph's
    uncertainty, each verified by matching the keyframe's scan against a submap around the
    candidate, and a robust optimisation against false closures (``fuzzypos.graph``)."""

    enabled: bool = _field(
        False,
        "off by default: it needs gtsam (the optional extra [graph]) and its verification "
        "searches cost several times the front end's time on a long log; tested on simulated "
        "loops (a known closure brings the end back, no false closure survives between two "
        "identical rooms) and measured on the shared logs (docs/history.md); `fuzzypos run "
        "--loop-closure` turns it on",
    )
    recent_keyframes: int = _field(
        10,
        "the last 10 keyframes are not loop candidates: the front end matched against them "
        "already (its local map holds two), and closing on them adds nothing but correlation",
        ge=1,
    )
    overlap_radius: float = _field(
        1.5,
        "two keyframes whose positions lie within 1.5 m of each other see mostly the same place: "
        "the candidate gate allows this on top of the graph's uncertainty",
        unit=M,
        gt=0.0,
    )
    gate_probability: float = _field(
        0.99,
        "a keyframe is a candidate where its position relative to the new one, under the "
        "chain's covariance plus overlap_radius², lies within the χ²(2) quantile of 99 %: "
        "where the drift could have put the robot back at it",
        gt=0.0,
        lt=1.0,
    )
    max_candidates: int = _field(
        3,
        "at most the 3 nearest candidates (by Mahalanobis distance) are verified per keyframe: "
        "each verification is a search and several refinements",
        ge=1,
    )
    closure_floor_translation: float = _field(
        0.03,
        "a verified closure's covariance is at least (3 cm)² in translation: its fit's own "
        "M⁻¹ G M⁻¹ says 1–5 mm where closures lie 2–7 cm from a SLAM reference (the submap's "
        "keyframes carry their own error); overconfident closures fight each other and the "
        "chain, and GNC then drops true ones",
        unit=M,
        gt=0.0,
        le=1.0,
    )
    closure_floor_rotation: float = _field(
        math.radians(2.0),
        "and at least (2°)² in rotation, for the same reason: fits claim 0.05–0.6°, and lie "
        "0.4° off on average but up to 1.7° where the submap is alike along its length (a "
        "corridor of alike doors); a closure that claims more turns the chain toward its own "
        "error, and the local headings with it",
        unit=RAD,
        gt=0.0,
        le=math.radians(10.0),
    )
    heading_floor: float = _field(
        math.radians(4.0),
        "a verified fit's heading must lie within the χ²(1) gate (gate_probability) of the "
        "graph's predicted heading under the chain's heading variance plus (4°)²: a false match "
        "in a symmetric place turns the scan by many degrees where a short chain knows the "
        "heading to a fraction of one; the floor allows for the front end's overconfidence "
        "over long chains (its heading drifts by more than its covariances add up to: a "
        "smaller floor refuses true closures a lap apart)",
        unit=RAD,
        gt=0.0,
    )
    submap_keyframes: int = _field(
        2,
        "the submap holds the candidate and 2 keyframes either side of it (in the candidate's "
        "frame): one keyframe's scan sees too little of a place from another viewpoint",
        ge=0,
    )
    search_distance: float = _field(
        3.0,
        "the verification searches translations within ±3 m of the predicted pose: where the "
        "graph has gone a while without a closure to the old map its prediction drifts past "
        "1 m and a narrower search never attaches it again (the ambiguity test guards the "
        "wider one); the search's grid (search.translation_step) costs grow with its square",
        unit=M,
        gt=0.0,
    )
    search_angle: float = _field(
        math.radians(20.0),
        "and rotations within ±20° of it: a front end that drifts degrees over a loop has lost "
        "its way, a closure would not mend it",
        unit=RAD,
        gt=0.0,
    )
    min_inlier_fraction: float = _field(
        0.6,
        "a closure is accepted only where 60 % of the part of the scan that lies in the space "
        "the submap's keyframes saw (seen_margin) pairs with the submap's surfaces: a false "
        "match in clutter pairs far less, a true one from a nearby viewpoint more (the front "
        "end asks refinement.min_inlier_fraction from the previous keyframes); of the whole "
        "scan, a large hall seen from metres away by a scanner reaching tens of metres pairs "
        "30–50 % where the match is true (the rest lies beyond what the submap saw), and every "
        "revisit of a large building was refused; the search's search.min_inlier_fraction of "
        "the whole scan still applies",
        ge=0.0,
        le=1.0,
    )
    seen_margin: float = _field(
        0.3,
        "a point of the scan lies in the space a submap keyframe saw where a beam of that "
        "keyframe near its bearing (seen_beams) returned at least as far as the point less "
        "0.3 m (refinement.max_distance, the first pairing distance): points on a wall the "
        "keyframe saw count, points behind it or where it looked into nothing do not",
        unit=M,
        ge=0.0,
    )
    seen_beams: float = _field(
        1.5,
        "a keyframe's beam counts for a point within 1.5 of its beam spacings of the point's "
        "bearing: the nearest beam on either side, not across a gap of missing returns",
        gt=0.0,
    )
    min_constraint_ratio: float = _field(
        0.05,
        "and where the fit constrains the weaker direction of the translation at least 5 % as "
        "much as the stronger: along a corridor a closure would fix a position it cannot see",
        gt=0.0,
        le=1.0,
    )
    ambiguity_distance: float = _field(
        0.5,
        "the fit is refined again from starts 0.5 m away on either axis: two places alike (a "
        "corridor's doors) give a second answer from there",
        unit=M,
        gt=0.0,
    )
    agree_distance: float = _field(
        0.1,
        "a refinement that ends further than 0.1 m from the fit is another answer (the "
        "refinement converges to within millimetres from the true start)",
        unit=M,
        gt=0.0,
    )
    ambiguity_margin: float = _field(
        0.1,
        "the fit is ambiguous, and rejected, where another answer puts its close fraction "
        "within 0.1 of the fit's, counted as a share of the part of the scan the submap saw "
        "(as min_inlier_fraction is): both explain the scan about as well; of the whole "
        "scan, a large hall whose far walls lie behind or beyond what the submap saw leaves "
        "every close fraction small, and a fixed difference refused nearly every true closure",
        ge=0.0,
        le=1.0,
    )
    reoptimize_probability: float = _field(
        0.95,
        "the graph is optimised again after a closure whose measurement lies beyond the χ²(3) "
        "quantile of 95 % from the graph's prediction, under the closure's own covariance: the "
        "next candidates' predictions start from the corrected poses, while a closure that "
        "agrees within its own uncertainty moves little and goes to ISAM2 alone; fixed "
        "thresholds tighter than the closures' covariance floors re-optimised after most "
        "closures along a loop, each batch turning the stiffer chain by a fraction of the "
        "closure's heading offset, so the next closure disagreed again",
        gt=0.0,
        lt=1.0,
    )
    robust: str = _field(
        "gnc",
        "closures enter the optimisation through graduated non-convexity (gtsam's GNC with "
        "truncated least squares, the front end's edges known inliers): a closure inconsistent "
        "with the chain gets weight 0 instead of bending it ('cauchy': a Cauchy kernel; "
        "'none': plain least squares, for comparison)",
        choices=("gnc", "cauchy", "none"),
    )
    gnc_mu_step: float = _field(
        2.0,
        "GNC's control parameter changes by a factor of 2 per iteration (gtsam's default 1.4): "
        "GNC was two thirds of loop closure's time, each of its iterations a solve of the "
        "whole graph, and with 2 it takes half the iterations to the same weights",
        gt=1.0,
    )
    place_recognition: bool = _field(
        True,
        "where no keyframe within the gate verifies, keyframes whose place descriptor is most "
        "alike are verified too (fuzzypos.graph.place): after a long stretch without a closure "
        "the drift can put a revisit metres from the graph's guess, beyond the gate's nearest "
        "candidates and the verification's search",
    )
    place_keyframes: int = _field(
        4,
        "a keyframe's place is its scan and those of the 4 keyframes before it, in its frame: a "
        "scanner that sees half a turn then describes most of the place around it, and over a "
        "few metres the front end's poses are exact to centimetres",
        ge=0,
    )
    place_rings: int = _field(
        20,
        "the descriptor's polar grid has 20 rings out to place_range (0.5 m each at 10 m): "
        "coarser than a viewpoint a metre away changes",
        ge=1,
    )
    place_sectors: int = _field(
        60,
        "and 60 sectors of bearing (6°): the best shift gives the heading to a sector, well "
        "within the verification's search_angle",
        ge=4,
    )
    place_range: float = _field(
        10.0,
        "points beyond 10 m are left out of the descriptor: indoors they are few and, seen past "
        "doorways, change most with the viewpoint",
        unit=M,
        gt=0.0,
    )
    place_min_overlap: float = _field(
        0.5,
        "two places are compared only where they share half the sectors the one that sees "
        "fewer sees (at the best shift): otherwise they look in different directions",
        gt=0.0,
        le=1.0,
    )
    place_candidates: int = _field(
        2,
        "the 2 most alike places (not within submap_keyframes of each other, nor of a gate "
        "candidate already verified) are verified: each costs a wide search",
        ge=1,
    )
    place_search_distance: float = _field(
        4.0,
        "a place candidate is searched within ±4 m of the descriptor's guess (the two keyframes "
        "at the same point, turned by the best shift): two keyframes whose places look alike "
        "stand within a few metres of each other",
        unit=M,
        gt=0.0,
    )
    map_resolution: float = _field(
        0.05,
        "the occupancy map's cells are 5 cm, ROS map_server's usual resolution for a 2D lidar "
        "(1 cm to 10 m: finer, a building's grid outgrows memory)",
        unit=M,
        ge=0.01,
        le=10.0,
    )
    map_scan_distance: float = _field(
        0.25,
        "the map is drawn from every scan whose front-end pose moved 0.25 m (or turned "
        "map_scan_angle) since the last one drawn, at its optimised pose: four views per "
        "keyframe (a keyframe every metre) fill in what one misses behind furniture, while "
        "drawing every scan, at 10 a second mostly a few centimetres apart, casts ten times "
        "as many beams for the same walls",
        unit=M,
        gt=0.0,
    )
    map_scan_angle: float = _field(
        math.radians(10.0),
        "or turned 10°: a scan turning on the spot sees new walls at its edges",
        unit=RAD,
        gt=0.0,
    )
    isam_extra_updates: int = _field(
        2,
        "online, after a closure that agrees with the graph enters ISAM2, 2 more updates: "
        "ISAM2 relinearises only variables that moved past its threshold and solves once per "
        "update, a closure moves a whole loop a little (one that disagrees is solved in "
        "batch with the robust kernel instead)",
        ge=0,
    )
    isam_factorization: str = _field(
        "qr",
        "online, ISAM2 factors each clique by QR of its square-root information, not by "
        "Cholesky of the information (gtsam's default): along a chain without a closure the "
        "newest keyframe's position grows uncertain by metres while its heading stays within "
        "degrees, and Cholesky, working on the information (the condition number squared), "
        "then declares the system indeterminate (gtsam issue #406) where QR solves it; on a "
        "chain of a thousand keyframes both cost the same ('cholesky': gtsam's default, for "
        "comparison; a failure is recovered from either way, summary isam_recoveries)",
        choices=("qr", "cholesky"),
    )
    realign: bool = _field(
        True,
        "after the last optimisation every scan is fitted once more (the front end's "
        "refinement, from its optimised pose) to the surfaces of its keyframe and "
        "realign_keyframes either side at their optimised poses: between two keyframes the "
        "optimised trajectory only carries the front end's increments and a blended "
        "correction, so it keeps the front end's error from scan to scan, heading included, "
        "and bends a little at every keyframe to spread a loop's correction; fitted to the map "
        "the loops closed, each scan lands on the walls as that map has them, for a fit per "
        "scan at the end and the scans' points kept until then (about 3 KB a scan of 180 "
        "beams)",
    )
    realign_keyframes: int = _field(
        2,
        "the scan's keyframe and 2 either side, as submap_keyframes around a candidate: some "
        "metres of wall on each side of the scan; more reach into the keyframes' own drift, "
        "fewer leave a scan between two keyframes half outside its map",
        ge=0,
    )
