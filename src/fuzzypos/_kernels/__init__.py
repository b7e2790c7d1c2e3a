"""Compiled hot paths (numba, ``@njit(cache=True)``): whole loops per scan where the numpy code
they stand in for makes many small calls. Each kernel has its pure-numpy reference (the code it
replaces, kept beside its caller) and ``tests/test_kernels.py`` checks the two against each
other.

No kernel module is imported, and nothing compiled, when ``fuzzypos`` is imported (only this
package and ``packing``, plain Python without numba): a caller imports a kernel module on first
use (which imports numba), and numba compiles each kernel on its first call, caching the
machine code on disk (``__pycache__`` beside the module) for the next process.
``FUZZYPOS_KERNELS=numpy`` in the environment makes the callers use the numpy references
instead (slower; for comparison and for platforms without numba).
"""

from __future__ import annotations

import importlib.util
import os

import numpy as np
from numpy.typing import NDArray

__all__ = ["compiled", "f64"]

_ENABLED: bool | None = None


def compiled() -> bool:
    """Whether the compiled kernels are used (decided once): unless ``FUZZYPOS_KERNELS`` is
    ``numpy``, and where numba can be imported (it is a dependency; without it the numpy
    references run)."""
    global _ENABLED
    if _ENABLED is None:
        wanted = os.environ.get("FUZZYPOS_KERNELS", "numba").strip().lower() != "numpy"
        _ENABLED = wanted and importlib.util.find_spec("numba") is not None
    return _ENABLED


def f64(a: NDArray | None) -> NDArray[np.float64]:
    """``a`` as a contiguous float64 array, the one type the kernels are compiled for (no copy
    where it is one already)."""
    return np.ascontiguousarray(a, dtype=np.float64)
