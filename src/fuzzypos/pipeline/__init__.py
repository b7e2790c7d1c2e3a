"""The positioner and its stages: the odometry prior, the local map of keyframes, feature
matching, the refinement and the relocalisation search."""

from .estimate import Estimate, Reason
from .feature_match import FeatureMatch, FeatureMatcher
from .local_map import LocalMap
from .noise import OdometryNoise
from .positioner import Positioner
from .prior import OdometryPrior, Prior
from .refine import Refiner, ScanPoints, Starts
from .search import Relocaliser
from .uncertainty import Assessment, Uncertainty

__all__ = [
    "Assessment",
    "OdometryNoise",
    "Uncertainty",
    "Estimate",
    "FeatureMatch",
    "FeatureMatcher",
    "LocalMap",
    "OdometryPrior",
    "Positioner",
    "Prior",
    "Reason",
    "Refiner",
    "Relocaliser",
    "ScanPoints",
    "Starts",
]
