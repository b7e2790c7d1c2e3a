"""fuzzypos: fuzzy-based positioning of a mobile robot from 2D laser scans and odometry."""

from .config import Config, ConfigError
from .features import Features, extract_features
from .geometry import Pose2D
from .positioner import Estimate, Positioner
from .scan import LaserScan, ScanError

__version__ = "0.1.0"

__all__ = [
    "Config",
    "ConfigError",
    "Estimate",
    "Features",
    "LaserScan",
    "Pose2D",
    "Positioner",
    "ScanError",
    "extract_features",
    "__version__",
]
