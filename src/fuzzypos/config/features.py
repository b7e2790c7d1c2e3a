"""The configuration sections of feature extraction (§2–3): the fuzzy systems, filtering,
segmentation, angular points, lines and virtual angular points. Part of :mod:`fuzzypos.config`,
which assembles every section into ``Config``."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .schema import Triangle, _field, _partition, section

RAD = "rad"  # an angle: radians in code, degrees under "<name>_deg" in TOML
M = "m"


_UNIT_SETS = _partition((0.0, 0.5, 1.0))  # S, M, B on [0, 1]


@dataclass(frozen=True)
@section("fuzzy")
class FuzzyConfig:
    """Membership functions (triangles ``(left foot, peak, right foot)``) and rule bases.

    Rule tables are written as strings of consequent labels ``S``/``M``/``B`` (centres 0, 0.5,
    1), one string per row: ``point_rules`` rows are ρ's sets GS..GB, columns β's sets S..B
    (Table 1); ``line_rules`` rows δ S..B, columns σ S..B (Table 2); ``virtual_pair_rules`` rows
    f_L2 S..B, columns f_L1 S..B (Table 3, upper); ``virtual_distance_rules`` rows d_v GS..GB,
    columns the upper table's result S..B (Table 3, lower).
    """

    inference: str = _field(
        "product",
        "eq. 4: product inference with centre-average defuzzification; 'mamdani' = min/max + "
        "centroid",
        choices=("product", "mamdani"),
    )
    mamdani_resolution: int = _field(
        1001,
        "samples of the output universe for the Mamdani centroid (fewer than 11 cannot place a "
        "centroid between the three output sets)",
        ge=11,
    )
    detection_angle_sets: tuple[Triangle, ...] = _field(
        _partition((0.0, math.pi / 4, math.pi / 2)),
        "β's S, M, B on [0°, 90°] (SPEC default; Fig. 5 is missing from the text); stored in "
        "radians",
        unit=RAD,
        ge=0.0,
    )
    distance_sets: tuple[Triangle, ...] = _field(
        _partition((0.0, 2.0, 4.0, 6.0, 8.0)),
        "ρ's GS..GB peaked at 0, ¼, ½, ¾, 1 × ρ_max = 8 m (SPEC default; Fig. 6 missing)",
        unit=M,
        ge=0.0,
    )
    uncertainty_sets: tuple[Triangle, ...] = _field(
        _UNIT_SETS,
        "u, δ, f_L1, f_L2 S, M, B on [0, 1] (SPEC default; Figs. 7–8 missing)",
        ge=0.0,
    )
    line_distance_sets: tuple[Triangle, ...] = _field(
        _partition((0.0, 0.025, 0.05)),
        "σ's S, M, B peaked at 0, ½, 1 × σ_max = 5 cm (SPEC default; Fig. 9 missing)",
        unit=M,
        ge=0.0,
    )
    virtual_distance_sets: tuple[Triangle, ...] = _field(
        _partition((0.0, 1.0, 2.0, 3.0, 4.0)),
        "d_v's GS..GB peaked at 0, ¼, ½, ¾, 1 × d_max = 4 m (SPEC default; Fig. 10 missing)",
        unit=M,
        ge=0.0,
    )
    distance_scale: str = _field(
        "scan",
        "the ρ and d_v sets and virtual_points.max_distance are drawn for indoor ranges (8 m, "
        "4 m, 8 m): 'scan' stretches them by max(1, the scan's distance_scale_quantile of "
        "valid ranges / distance_scale_reference), so a scan with no structure near the robot "
        "(a hall, outdoors: 10-50 m) is graded by its relative distance instead of all 'GB' "
        "and its virtual points are kept, while a scan with near structure (a room, a "
        "corridor) keeps SPEC's sets, whose grading favours that near structure; 'fixed' "
        "keeps them for every scan",
        choices=("scan", "fixed"),
    )
    distance_scale_quantile: float = _field(
        0.05,
        "the scan's nearest structure, robust to a stray reading or two: the scale is driven "
        "by whether anything is near, not by how far the far end reaches (a corridor's or a "
        "doorway's long readings leave it alone)",
        gt=0.0,
        le=1.0,
    )
    distance_scale_reference: float = _field(
        4.5,
        "the range that nearest structure is stretched to, between the M and B peaks: "
        "indoors the nearest walls and furniture lie closer (the scale stays 1), while a far "
        "scan's nearest structure is graded fairly certain and the rest by its distance",
        unit=M,
        gt=0.0,
    )
    line_distance_scale: str = _field(
        "structure",
        "the scale the lines (their δ, eq. 6), d_v and virtual_points.max_distance are graded "
        "on: 'structure' takes the distance_scale_quantile of the lines' own points weighted "
        "by their ranges (each beam's share of the surface it samples, so the lines' length "
        "by distance), never below the points' scale: a line is graded by the surface it lies "
        "on, and a few beams on small clutter near the robot (a box, a chair, whose short "
        "sides take many beams for little length) no longer grade far walls' lines and their "
        "intersections all uncertain; 'points' keeps the points' scale for them",
        choices=("structure", "points"),
    )
    output_centres: tuple[float, float, float] = _field(
        (0.0, 0.5, 1.0),
        "consequent centres of S, M, B (SPEC); the outputs are uncertainties in [0, 1]",
        ge=0.0,
        le=1.0,
    )
    point_rules: tuple[str, ...] = _field(
        ("MSS", "MSS", "BMM", "BBM", "BBB"), "Table 1 (rows ρ GS..GB, columns β S..B)"
    )
    line_rules: tuple[str, ...] = _field(
        ("SSM", "SMB", "MBB"), "Table 2 (rows δ S..B, columns σ S..B)"
    )
    virtual_pair_rules: tuple[str, ...] = _field(
        ("SSM", "SMB", "MBB"), "Table 3 upper (rows f_L2 S..B, columns f_L1 S..B)"
    )
    virtual_distance_rules: tuple[str, ...] = _field(
        ("SSM", "SSM", "SMB", "MBB", "BBB"),
        "Table 3 lower (rows d_v GS..GB, columns f_L1·f_L2 S..B)",
    )


@dataclass(frozen=True)
@section("filtering")
class FilterConfig:
    detection_angle_threshold: float = _field(
        math.radians(22.5),
        "ξ_TH = 22.5°, the paper's value (§3.1): points seen at a sharper angle are removed",
        unit=RAD,
        ge=0.0,
        lt=math.pi / 2,
    )


@dataclass(frozen=True)
@section("segmentation")
class SegmentationConfig:
    gap_distance: float = _field(
        0.20,
        "T2 (eq. 13), fixed part: 0.20 m between consecutive points is a gap (a doorway, an "
        "occlusion) at the 8 m scale of the fuzzy sets",
        unit=M,
        gt=0.0,
    )
    gap_distance_per_metre: float = _field(
        5.0,
        "T2 grows with range: 5 beam spacings at the point's range (ρ·Δφ·5) so that a wall "
        "sampled sparsely far away is not cut into pieces",
        ge=0.0,
    )
    gap_difference: float = _field(
        0.10,
        "T1 (eq. 13): a gap must exceed the spacing on its other side by 0.10 m, so a "
        "uniformly sparse surface is not all break points",
        unit=M,
        ge=0.0,
    )
    min_cluster_points: int = _field(
        4, "clusters too small to fit a line (fewer than 4 points, §5) are dropped", ge=1
    )


@dataclass(frozen=True)
@section("angular_points")
class AngularPointConfig:
    interior_angle_threshold: float = _field(
        math.radians(135.0),
        "θ_TH (eq. 14, as the interior angle): 135° separates corners (≈90°) from walls (180°) "
        "with room for noise",
        unit=RAD,
        gt=0.0,
        lt=math.pi,
    )
    neighbour_step: int = _field(
        3,
        "k (SPEC step 5): neighbours 3 beams away keep range noise from making every point a "
        "corner",
        ge=1,
    )
    neighbour_distance: float = _field(
        0.10,
        "the k-step neighbours must also be at least 0.10 m away (more beams are taken near the "
        "robot)",
        unit=M,
        ge=0.0,
    )
    refine: bool = _field(
        True,
        "move an angular point to the intersection of its two lines (SPEC step 5): exact where "
        "the sampled corner is up to a beam spacing off",
    )
    pair_unrefined: bool = _field(
        False,
        "with refine on, whether angular points whose two lines could not be intersected still "
        "take part in pairing: off, since a sampled corner is up to a beam spacing (several "
        "centimetres) off and the pose from two pairs inherits that",
    )


@dataclass(frozen=True)
@section("lines")
class LineConfig:
    min_points: int = _field(
        4, "§5: only lines with at least four points are kept (two points always fit)", ge=2
    )
    corner_exclusion: int = _field(
        1,
        "points within this many beams of an angular point belong to neither line (SPEC step 6)",
        ge=0,
    )
    min_length: float = _field(
        0.15, "lines shorter than 0.15 m give direction too poorly to intersect", unit=M, ge=0.0
    )


@dataclass(frozen=True)
@section("virtual_points")
class VirtualPointConfig:
    min_intersection_angle: float = _field(
        math.radians(30.0),
        "two lines must differ in direction by at least 30° to intersect well: the intersection's "
        "error grows as 1/sin of the angle between them",
        unit=RAD,
        gt=0.0,
        le=math.pi / 2,
    )
    max_uncertainty: float = _field(
        0.6,
        "§3.6: virtual angular points more uncertain than this are removed",
        ge=0.0,
        le=1.0,
    )
    max_distance: float = _field(
        8.0,
        "an intersection farther than this from its lines' centres is not a usable point",
        unit=M,
        gt=0.0,
    )
    merge_distance: float = _field(
        0.10,
        "feature points closer than 0.10 m are one feature (a wall split by an occlusion gives "
        "its corner twice); the most certain is kept",
        unit=M,
        ge=0.0,
    )
