"""Feature extraction (§3.1–3.6): :func:`extract_features` and its stages (:mod:`.extract`),
the segmentation stages it runs (:mod:`.segmentation`), the compiled chain's glue
(:mod:`.chain`, :mod:`.points`) and the containers they share (:mod:`.types`)."""

from __future__ import annotations

from .extract import (
    Features,
    angular_points,
    break_points,
    clusters,
    detection_angles,
    distance_scale,
    extract_features,
    filter_points,
    fit_lines,
    point_uncertainty,
    rule_bases,
    virtual_angular_points,
)
from .types import (
    ANGULAR_POINT,
    BREAK_POINT,
    KIND_NAMES,
    VIRTUAL_ANGULAR_POINT,
    FeatureError,
    FeaturePoints,
    Lines,
)

__all__ = [
    "BREAK_POINT",
    "ANGULAR_POINT",
    "VIRTUAL_ANGULAR_POINT",
    "KIND_NAMES",
    "FeatureError",
    "FeaturePoints",
    "Lines",
    "Features",
    "rule_bases",
    "detection_angles",
    "point_uncertainty",
    "distance_scale",
    "filter_points",
    "break_points",
    "clusters",
    "angular_points",
    "fit_lines",
    "virtual_angular_points",
    "extract_features",
]
