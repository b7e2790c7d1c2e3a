"""Compiled hot paths (numba, ``@njit(cache=True)``): whole loops per scan where numpy code
would make many small calls. numba is a dependency and each kernel is its stage's one
implementation; the numpy code a kernel replaced is kept as the tests' oracle
(``tests/oracles``), and the property tests check the two against each other.

No kernel module is imported, and nothing compiled, when ``fuzzypos`` is imported (only this
package and ``packing``, plain Python without numba): a caller imports a kernel module on first
use (which imports numba), and numba compiles each kernel on its first call, caching the
machine code on disk (``__pycache__`` beside the module) for the next process. numba's own
``NUMBA_DISABLE_JIT=1`` runs the kernels as plain Python (slow; for debugging a kernel).
"""

from __future__ import annotations

import os

import numpy as np
from numpy.typing import NDArray

__all__ = ["compiled", "f64"]


def compiled() -> bool:
    """Whether numba compiles the kernels: always, unless numba's own ``NUMBA_DISABLE_JIT``
    runs them as Python (then a warm-up has nothing to compile)."""
    flag = os.environ.get("NUMBA_DISABLE_JIT", "0").strip()
    return flag in ("", "0")


def f64(a: NDArray | None) -> NDArray[np.float64]:
    """``a`` as a contiguous float64 array, the one type the kernels are compiled for (no copy
    where it is one already)."""
    return np.ascontiguousarray(a, dtype=np.float64)
