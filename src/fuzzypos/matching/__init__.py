"""Matching one scan against another: the paper's feature points and their fusion
(:mod:`.points`), line-to-line matching (:mod:`.lines`), point-to-line refinement against a
keyframe's surfaces (:mod:`.surface`) and the wide search for a start (:mod:`.search`)."""

from .lines import LinePairs, increment_from_lines, pair_lines
from .points import (
    Pairs,
    TwoPairSolutions,
    consensus_inliers,
    estimate_increment,
    fuse_least_squares,
    fuse_weighted_mean,
    pair_features,
    poses_from_two_pairs,
    two_pair_solutions,
)
from .search import SearchHit, search_start
from .surface import (
    Refinement,
    SurfacePoints,
    refine_both,
    refine_both_settings,
    refine_point_to_line,
    refinement_of,
    surface_lengths,
    surface_points,
)

__all__ = [
    "Pairs",
    "pair_features",
    "poses_from_two_pairs",
    "TwoPairSolutions",
    "two_pair_solutions",
    "fuse_weighted_mean",
    "fuse_least_squares",
    "consensus_inliers",
    "estimate_increment",
    "LinePairs",
    "pair_lines",
    "increment_from_lines",
    "SurfacePoints",
    "surface_points",
    "Refinement",
    "refine_point_to_line",
    "refine_both",
    "refine_both_settings",
    "refinement_of",
    "SearchHit",
    "search_start",
    "surface_lengths",
]
