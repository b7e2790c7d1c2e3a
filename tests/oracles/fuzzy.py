"""The numpy reference of ``fuzzypos.fuzzy``'s kernel (``_kernels.fuzzy.bilinear``): the code
it replaced, the tests' oracle."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fuzzypos.fuzzy import FuzzyError, RuleBase

FloatArray = NDArray[np.float64]

try:  # np.interp's own compiled loop, without the wrapper's checks (real inputs; same result)
    from numpy._core.multiarray import interp as _interp
except ImportError:  # pragma: no cover - another numpy layout
    _interp = np.interp


def bilinear(base: RuleBase, x1: FloatArray, x2: FloatArray) -> FloatArray:
    """``_kernels.fuzzy.bilinear`` in numpy: Σ_j μ_j(x_2) · interp(x_1; peaks, ȳ_·j), each
    μ_j one np.interp too."""
    assert base._grids is not None
    g1, g2 = base._grids
    table = base._table
    units = np.eye(table.shape[1])
    out = np.zeros(x1.shape[0])
    for j in range(table.shape[1]):
        col = table[:, j].copy()
        out += _interp(x1, g1, col, None, None) * _interp(x2, g2, units[j], None, None)
    return np.minimum(np.maximum(out, base._centre_lo), base._centre_hi)


def interpolate(base: RuleBase, inputs: tuple[ArrayLike, ...]) -> FloatArray:
    """``RuleBase._interpolate`` with :func:`bilinear` in place of the kernel."""
    if len(inputs) != 2:
        raise FuzzyError(f"{base.name} takes 2 inputs, got {len(inputs)}")
    x1 = np.asarray(inputs[0], dtype=float).ravel()
    x2 = np.asarray(inputs[1], dtype=float).ravel()
    if x1.shape != x2.shape:
        raise FuzzyError(f"{base.name}: inputs have different lengths")
    if x1.shape[0] == 0:
        return np.zeros(0)
    return bilinear(base, x1, x2)


#: (module, attribute, its reference) for :func:`oracles.references`
STAND_INS = [("fuzzypos.fuzzy", "RuleBase._interpolate", interpolate)]
