"""fuzzypos: fuzzy-based positioning of a mobile robot from 2D laser scans and odometry."""

from ._version import __version__
from .config import Config, ConfigError
from .errors import FuzzyposError
from .features import Features, extract_features
from .geometry import Pose2D
from .pipeline import Estimate, Positioner, Reason
from .scan import LaserScan, ScanError

__all__ = [
    "Config",
    "ConfigError",
    "Estimate",
    "Features",
    "FuzzyposError",
    "LaserScan",
    "Pose2D",
    "Positioner",
    "Reason",
    "ScanError",
    "extract_features",
    "__version__",
]
