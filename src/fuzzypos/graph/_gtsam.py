"""gtsam, imported on first use: it is an optional extra (``pip install 'fuzzypos[graph]'``)."""

from __future__ import annotations

from types import ModuleType

from ..errors import FuzzyposError

__all__ = ["GraphDependencyError", "gtsam"]

INSTALL = "pip install 'fuzzypos[graph]' (or pip install 'gtsam>=4.2')"


class GraphDependencyError(FuzzyposError, OSError):
    """The pose graph needs gtsam, which is not installed; the message says how to install it."""

    __module__ = "fuzzypos.graph"


def gtsam() -> ModuleType:
    """The gtsam module, or :class:`GraphDependencyError` saying how to install it."""
    try:
        import gtsam as module
    except ImportError as exc:
        raise GraphDependencyError(
            f"loop closure needs gtsam, which is not installed ({exc}): {INSTALL}"
        ) from exc
    return module
