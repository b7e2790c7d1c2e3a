"""The refinement's compiled helpers (``fuzzypos._kernels.refine``, ``_select``) against plain
numpy: what ``tests/_kernels/test_kernels.py`` leaves to them."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

BUDGET = settings(max_examples=300, deadline=None)


@BUDGET
@given(
    values=st.one_of(
        st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=1, max_size=300),
        st.lists(st.sampled_from([0.0, 0.5, 1.0, -2.0, 3.25]), min_size=1, max_size=300),
    ),
    k=st.integers(0, 299),
    extra=st.integers(0, 5),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_kth_smallest_in_a_scratch_is_numpys(values, k, extra, seed) -> None:
    """The k-th smallest value with a scratch array for the copy, as numpy's sort gives it,
    whatever the scratch held (and many values equal); the input is left as it was."""
    from fuzzypos._kernels._select import kth_smallest, kth_smallest_in

    v = np.array(values)
    k = min(k, v.size - 1)
    scratch = np.random.default_rng(seed).normal(size=v.size + extra)
    assert kth_smallest_in(v, k, scratch) == np.sort(v)[k] == kth_smallest(v, k)
    assert kth_smallest_in(v[: k + 1], k, scratch) == np.sort(v[: k + 1])[k]  # a view's
    np.testing.assert_array_equal(v, np.array(values))
