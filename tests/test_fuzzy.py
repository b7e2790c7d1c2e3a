"""Tests of the fuzzy engine and the paper's three rule bases (SPEC steps 2, 6, 7; §2.2–2.4).

The tables below are written out literally from the paper (Tables 1–3) so that a typo in the
configuration or an index swap in the engine shows up here, not in a positioning error.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzypos.config import FuzzyConfig
from fuzzypos.fuzzy import (
    FuzzyError,
    RuleBase,
    RuleBases,
    compose_virtual_rules,
    line_rule_base,
    point_rule_base,
    triangular_memberships,
    virtual_point_rule_base,
)

# scikit-fuzzy 0.5.0 calls np.maximum with a positional ``out``, deprecated in numpy 2
pytestmark = pytest.mark.filterwarnings(
    "ignore:Passing more than 2 positional arguments:DeprecationWarning"
)

PROPS = settings(derandomize=True, deadline=None, max_examples=100)

CFG = FuzzyConfig()
CENTRE = {"S": 0.0, "M": 0.5, "B": 1.0}
IDX = {"S": 0, "M": 1, "B": 2}

# ---------------------------------------------------------------------------------------------
# The paper's tables, literally
# ---------------------------------------------------------------------------------------------
# Table 1: rows ρ GS, S, M, B, GB; columns β S, M, B.
TABLE1 = [
    ["M", "S", "S"],  # GS
    ["M", "S", "S"],  # S
    ["B", "M", "M"],  # M
    ["B", "B", "M"],  # B
    ["B", "B", "B"],  # GB
]
# Table 2: rows δ S, M, B; columns σ S, M, B.
TABLE2 = [
    ["S", "S", "M"],
    ["S", "M", "B"],
    ["M", "B", "B"],
]
# Table 3, upper: rows f_L2 S, M, B; columns f_L1 S, M, B.
TABLE3_UPPER = [
    ["S", "S", "M"],
    ["S", "M", "B"],
    ["M", "B", "B"],
]
# Table 3, lower: rows d_v GS, S, M, B, GB; columns the f_L1·f_L2 result S, M, B.
TABLE3_LOWER = [
    ["S", "S", "M"],
    ["S", "S", "M"],
    ["S", "M", "B"],
    ["M", "B", "B"],
    ["B", "B", "B"],
]


def table3_composed(fl1: int, fl2: int, dv: int) -> str:
    """Table 3 read by hand: upper table, then lower table."""
    mid = TABLE3_UPPER[fl2][fl1]
    return TABLE3_LOWER[dv][IDX[mid]]


# ---------------------------------------------------------------------------------------------
# The default fuzzy sets (SPEC, "Default fuzzy sets"), literally; symmetric
# (a = peak, b = half width)
# ---------------------------------------------------------------------------------------------
HALF_PI = math.pi / 2
SPEC_SETS = {
    # name: (config attribute, lo, hi, peaks)
    "beta": ("detection_angle_sets", 0.0, HALF_PI, [0.0, math.pi / 4, HALF_PI]),
    "rho": ("distance_sets", 0.0, 8.0, [0.0, 2.0, 4.0, 6.0, 8.0]),
    "unit": ("uncertainty_sets", 0.0, 1.0, [0.0, 0.5, 1.0]),
    "sigma": ("line_distance_sets", 0.0, 0.05, [0.0, 0.025, 0.05]),
    "d_v": ("virtual_distance_sets", 0.0, 4.0, [0.0, 1.0, 2.0, 3.0, 4.0]),
}
VARS = sorted(SPEC_SETS)


def sets_of(name: str) -> np.ndarray:
    return np.asarray(getattr(CFG, SPEC_SETS[name][0]), dtype=float)


def range_of(name: str) -> tuple[float, float]:
    return SPEC_SETS[name][1], SPEC_SETS[name][2]


def half_width(name: str) -> float:
    peaks = SPEC_SETS[name][3]
    return peaks[1] - peaks[0]


def eq4_triangle(x: float, a: float, b: float) -> float:
    """The paper's triangle (b − |x − a|)/b, clipped to [0, 1] (SPEC's correction)."""
    return min(1.0, max(0.0, (b - abs(x - a)) / b))


# ---------------------------------------------------------------------------------------------
# Membership functions
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", VARS)
def test_default_sets_are_the_spec_triangles(name: str) -> None:
    peaks = SPEC_SETS[name][3]
    expected = [
        (peaks[max(i - 1, 0)], p, peaks[min(i + 1, len(peaks) - 1)]) for i, p in enumerate(peaks)
    ]
    np.testing.assert_allclose(sets_of(name), expected, rtol=0, atol=1e-15)


def test_default_beta_sets_in_degrees() -> None:
    # SPEC: β S (0, 0, 45), M (0, 45, 90), B (45, 90, 90) degrees, stored in radians
    np.testing.assert_allclose(
        np.degrees(sets_of("beta")), [[0, 0, 45], [0, 45, 90], [45, 90, 90]], atol=1e-12
    )


@pytest.mark.parametrize("name", VARS)
def test_sets_sum_to_one_on_a_dense_grid(name: str) -> None:
    lo, hi = range_of(name)
    x = np.linspace(lo, hi, 20001)
    mu = triangular_memberships(x, sets_of(name))
    assert mu.shape == (x.size, len(SPEC_SETS[name][3]))
    assert np.all(mu >= 0.0) and np.all(mu <= 1.0)
    np.testing.assert_allclose(mu.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    # each set is 1 at its own peak and 0 at every other peak
    peaks = np.asarray(SPEC_SETS[name][3])
    np.testing.assert_allclose(
        triangular_memberships(peaks, sets_of(name)), np.eye(len(peaks)), atol=1e-12
    )


@pytest.mark.parametrize("name", VARS)
def test_memberships_match_the_eq4_triangle(name: str) -> None:
    lo, hi = range_of(name)
    peaks, b = SPEC_SETS[name][3], half_width(name)
    x = np.linspace(lo, hi, 997)
    mu = triangular_memberships(x, sets_of(name))
    ref = np.array([[eq4_triangle(v, a, b) for a in peaks] for v in x])
    np.testing.assert_allclose(mu, ref, rtol=0, atol=1e-12)


def _unit_interval() -> st.SearchStrategy[float]:
    return st.floats(0.0, 1.0, allow_nan=False)


@pytest.mark.parametrize("name", VARS)
@PROPS
@given(t=_unit_interval())
def test_sets_sum_to_one_anywhere_in_range(name: str, t: float) -> None:
    lo, hi = range_of(name)
    x = min(hi, lo + t * (hi - lo))
    mu = triangular_memberships(x, sets_of(name))[0]
    assert np.all((mu >= 0.0) & (mu <= 1.0))
    assert mu.sum() == pytest.approx(1.0, abs=1e-12)
    # at most two neighbouring sets are active
    active = np.flatnonzero(mu > 0)
    assert 1 <= active.size <= 2
    if active.size == 2:
        assert active[1] - active[0] == 1


@pytest.mark.parametrize("name", VARS)
@PROPS
@given(excess=st.floats(1e-9, 1e6, allow_nan=False), below=st.booleans())
def test_inputs_outside_the_range_are_clamped(name: str, excess: float, below: bool) -> None:
    lo, hi = range_of(name)
    x = lo - excess if below else hi + excess
    end = lo if below else hi
    mu = triangular_memberships(x, sets_of(name))
    np.testing.assert_array_equal(mu, triangular_memberships(end, sets_of(name)))
    # the end set is fully on, the others off
    expected = np.zeros(len(SPEC_SETS[name][3]))
    expected[0 if below else -1] = 1.0
    np.testing.assert_array_equal(mu[0], expected)


def test_memberships_are_vectorised() -> None:
    x = np.array([-1.0, 0.0, 1.0, 3.0, 5.5, 8.0, 12.0])
    mu = triangular_memberships(x, sets_of("rho"))
    for i, v in enumerate(x):
        np.testing.assert_array_equal(mu[i], triangular_memberships(v, sets_of("rho"))[0])


# ---------------------------------------------------------------------------------------------
# Rule tables
# ---------------------------------------------------------------------------------------------
def _labels(cons: np.ndarray) -> np.ndarray:
    return np.array(list("SMB"))[cons]


def test_point_rules_are_table_1() -> None:
    rb = point_rule_base(CFG)
    assert rb.n_rules == 15
    assert rb.consequents.shape == (5, 3)  # (ρ, β)
    assert _labels(rb.consequents).tolist() == TABLE1


def test_line_rules_are_table_2() -> None:
    rb = line_rule_base(CFG)
    assert rb.n_rules == 9
    assert rb.consequents.shape == (3, 3)  # (δ, σ)
    assert _labels(rb.consequents).tolist() == TABLE2


def test_virtual_rules_are_table_3_composed() -> None:
    rb = virtual_point_rule_base(CFG)
    assert rb.n_rules == 45
    assert rb.consequents.shape == (3, 3, 5)  # (f_L1, f_L2, d_v)
    got = _labels(rb.consequents)
    for fl1, fl2, dv in itertools.product(range(3), range(3), range(5)):
        assert got[fl1, fl2, dv] == table3_composed(fl1, fl2, dv), (fl1, fl2, dv)


# (f_L1, f_L2, d_v) -> output, read by hand from the two printed tables
HAND_TABLE3 = [
    (("S", "S", "GS"), "S"),  # upper S; lower GS,S -> S
    (("S", "S", "GB"), "B"),  # upper S; lower GB,S -> B
    (("S", "S", "B"), "M"),  # upper S; lower B,S -> M
    (("B", "S", "M"), "M"),  # upper (f_L2 S, f_L1 B) = M; lower M,M -> M
    (("S", "B", "M"), "M"),  # upper (f_L2 B, f_L1 S) = M; lower M,M -> M
    (("M", "B", "GS"), "M"),  # upper (f_L2 B, f_L1 M) = B; lower GS,B -> M
    (("M", "B", "M"), "B"),  # upper B; lower M,B -> B
    (("M", "M", "S"), "S"),  # upper M; lower S,M -> S
    (("M", "M", "M"), "M"),  # upper M; lower M,M -> M
    (("M", "M", "B"), "B"),  # upper M; lower B,M -> B
    (("B", "B", "GS"), "M"),  # upper B; lower GS,B -> M
    (("B", "B", "B"), "B"),  # upper B; lower B,B -> B
    (("M", "S", "B"), "M"),  # upper (f_L2 S, f_L1 M) = S; lower B,S -> M
]
DV_IDX = {"GS": 0, "S": 1, "M": 2, "B": 3, "GB": 4}


@pytest.mark.parametrize("inputs,expected", HAND_TABLE3)
def test_virtual_rules_spot_entries(inputs: tuple[str, str, str], expected: str) -> None:
    fl1, fl2, dv = inputs
    cons = virtual_point_rule_base(CFG).consequents
    assert "SMB"[cons[IDX[fl1], IDX[fl2], DV_IDX[dv]]] == expected


def test_compose_orientation_rows_are_f_l2() -> None:
    # an asymmetric upper table whose result depends on f_L2 only (rows), and a lower table
    # whose result depends on the intermediate label only (columns)
    upper = ("SSS", "MMM", "BBB")
    lower = ("SMB",) * 5
    out = compose_virtual_rules(upper, lower)
    for fl1, fl2, dv in itertools.product(range(3), range(3), range(5)):
        assert out[fl1, fl2, dv] == fl2
    # and one that depends on f_L1 only (columns)
    out = compose_virtual_rules(("SMB",) * 3, lower)
    for fl1, fl2, dv in itertools.product(range(3), range(3), range(5)):
        assert out[fl1, fl2, dv] == fl1
    # a lower table that depends on d_v only (rows)
    out = compose_virtual_rules(("SMB",) * 3, ("SSS", "SSS", "MMM", "BBB", "BBB"))
    for fl1, fl2, dv in itertools.product(range(3), range(3), range(5)):
        assert out[fl1, fl2, dv] == [0, 0, 1, 2, 2][dv]


# ---------------------------------------------------------------------------------------------
# Product inference (eq. 4, 9, 11–12): literal reference
# ---------------------------------------------------------------------------------------------
def eq4_reference(rho: float, beta: float) -> float:
    """eq. 4 written out: Σ ȳ·μρ·μβ / Σ μρ·μβ over the 15 rules of Table 1."""
    num = den = 0.0
    for i, a_rho in enumerate(SPEC_SETS["rho"][3]):
        for j, a_beta in enumerate(SPEC_SETS["beta"][3]):
            w = eq4_triangle(rho, a_rho, 2.0) * eq4_triangle(beta, a_beta, math.pi / 4)
            num += CENTRE[TABLE1[i][j]] * w
            den += w
    return num / den


def eq9_reference(delta: float, sigma: float) -> float:
    """eq. 9 with Table 2's 9 rules (SPEC: eq. 9 says 15)."""
    num = den = 0.0
    for i, a_d in enumerate(SPEC_SETS["unit"][3]):
        for j, a_s in enumerate(SPEC_SETS["sigma"][3]):
            w = eq4_triangle(delta, a_d, 0.5) * eq4_triangle(sigma, a_s, 0.025)
            num += CENTRE[TABLE2[i][j]] * w
            den += w
    return num / den


def eq11_reference(fl1: float, fl2: float, dv: float) -> float:
    """eq. 11–12 over the 45 rules of Table 3 (divided by b_dv, SPEC's correction)."""
    num = den = 0.0
    for i1, a1 in enumerate(SPEC_SETS["unit"][3]):
        for i2, a2 in enumerate(SPEC_SETS["unit"][3]):
            f_l1l2 = eq4_triangle(fl1, a1, 0.5) * eq4_triangle(fl2, a2, 0.5)  # eq. 12
            for k, a_dv in enumerate(SPEC_SETS["d_v"][3]):
                w = f_l1l2 * eq4_triangle(dv, a_dv, 1.0)
                num += CENTRE[table3_composed(i1, i2, k)] * w
                den += w
    return num / den


def test_default_mode_is_product() -> None:
    assert CFG.inference == "product"
    bases = RuleBases.from_config(CFG)
    assert {bases.points.mode, bases.lines.mode, bases.virtual_points.mode} == {"product"}


def test_product_mode_equals_eq4_literally() -> None:
    rng = np.random.default_rng(20240401)
    rho = rng.uniform(0.0, 8.0, 400)
    beta = rng.uniform(0.0, HALF_PI, 400)
    # plus the grid corners and peaks, where sets switch on and off
    gr, gb = np.meshgrid([0.0, 1.0, 2.0, 4.0, 6.0, 7.5, 8.0], [0.0, 0.3, math.pi / 4, HALF_PI])
    rho = np.concatenate([rho, gr.ravel()])
    beta = np.concatenate([beta, gb.ravel()])
    got = point_rule_base(CFG)(rho, beta)
    ref = np.array([eq4_reference(r, b) for r, b in zip(rho, beta)])
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)


def test_product_mode_equals_eq9_literally() -> None:
    rng = np.random.default_rng(7)
    delta = rng.uniform(0.0, 1.0, 300)
    sigma = rng.uniform(0.0, 0.05, 300)
    got = line_rule_base(CFG)(delta, sigma)
    ref = np.array([eq9_reference(d, s) for d, s in zip(delta, sigma)])
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)


def test_product_mode_equals_eq11_literally() -> None:
    rng = np.random.default_rng(11)
    fl1, fl2 = rng.uniform(0.0, 1.0, (2, 300))
    dv = rng.uniform(0.0, 4.0, 300)
    got = virtual_point_rule_base(CFG)(fl1, fl2, dv)
    ref = np.array([eq11_reference(a, b, c) for a, b, c in zip(fl1, fl2, dv)])
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)


@PROPS
@given(rho=st.floats(0.0, 8.0), beta=st.floats(0.0, HALF_PI))
def test_product_mode_equals_eq4_property(rho: float, beta: float) -> None:
    assert point_rule_base(CFG)(rho, beta)[0] == pytest.approx(eq4_reference(rho, beta), abs=1e-12)


def test_product_firing_strengths_sum_to_one() -> None:
    rng = np.random.default_rng(3)
    w = point_rule_base(CFG).firing_strengths(rng.uniform(-1, 9, 200), rng.uniform(-0.2, 1.8, 200))
    assert w.shape == (200, 15)
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-12)
    w = virtual_point_rule_base(CFG).firing_strengths(
        *rng.uniform(0, 1, (2, 50)), rng.uniform(0, 4, 50)
    )
    assert w.shape == (50, 45)
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-12)


@pytest.mark.parametrize(
    "rho,beta_deg,expected",
    [
        (0.0, 90.0, 0.0),  # GS, B -> S
        (8.0, 0.0, 1.0),  # GB, S -> B
        (4.0, 45.0, 0.5),  # M, M -> M
        (0.0, 0.0, 0.5),  # GS, S -> M
        (2.0, 45.0, 0.0),  # S, M -> S
        (6.0, 45.0, 1.0),  # B, M -> B
        (6.0, 90.0, 0.5),  # B, B -> M
        (8.0, 90.0, 1.0),  # GB, B -> B
        (4.0, 0.0, 1.0),  # M, S -> B
    ],
)
def test_point_uncertainty_at_rule_peaks(rho: float, beta_deg: float, expected: float) -> None:
    assert point_rule_base(CFG)(rho, math.radians(beta_deg))[0] == pytest.approx(
        expected, abs=1e-12
    )


def test_point_uncertainty_between_peaks() -> None:
    # halfway between GS,B (S = 0) and S,B... both S; halfway between S (ρ = 2) and M (ρ = 4)
    # at β = 90°: S -> M, so the centre average is 0.25
    assert point_rule_base(CFG)(3.0, HALF_PI)[0] == pytest.approx(0.25, abs=1e-12)
    # ρ = 7 (B/GB halfway), β = 67.5° (M/B halfway): corners B, M, B, B -> (1 + .5 + 1 + 1)/4
    assert point_rule_base(CFG)(7.0, math.radians(67.5))[0] == pytest.approx(0.875, abs=1e-12)


@pytest.mark.parametrize(
    "inputs,expected",
    [
        ((0.0, 0.0), 0.0),
        ((1.0, 0.05), 1.0),
        ((0.5, 0.025), 0.5),
        ((0.0, 0.05), 0.5),  # δ S, σ B -> M
        ((1.0, 0.0), 0.5),  # δ B, σ S -> M
        ((0.5, 0.05), 1.0),  # δ M, σ B -> B
    ],
)
def test_line_uncertainty_at_rule_peaks(inputs: tuple[float, float], expected: float) -> None:
    assert line_rule_base(CFG)(*inputs)[0] == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize(
    "inputs,expected",
    [
        ((0.0, 0.0, 0.0), 0.0),
        ((1.0, 1.0, 4.0), 1.0),
        ((1.0, 0.0, 2.0), 0.5),  # upper M; lower M,M -> M
        ((0.5, 1.0, 0.0), 0.5),  # upper B; lower GS,B -> M
        ((0.0, 0.0, 3.0), 0.5),  # upper S; lower B,S -> M
    ],
)
def test_virtual_uncertainty_at_rule_peaks(
    inputs: tuple[float, float, float], expected: float
) -> None:
    assert virtual_point_rule_base(CFG)(*inputs)[0] == pytest.approx(expected, abs=1e-12)


def test_rule_base_inputs_outside_range_are_clamped() -> None:
    rb = point_rule_base(CFG)
    np.testing.assert_array_equal(
        rb([-3.0, 30.0, 5.0], [1.0, 0.5, -1.0]), rb([0.0, 8.0, 5.0], [1.0, 0.5, 0.0])
    )
    np.testing.assert_array_equal(rb(5.0, 3.0), rb(5.0, HALF_PI))
    lb = line_rule_base(CFG)
    np.testing.assert_array_equal(lb([1.5, -0.5], [0.2, -1.0]), lb([1.0, 0.0], [0.05, 0.0]))


def test_rule_base_is_vectorised() -> None:
    rng = np.random.default_rng(5)
    rho, beta = rng.uniform(0, 8, 40), rng.uniform(0, HALF_PI, 40)
    rb = point_rule_base(CFG)
    batch = rb(rho, beta)
    assert batch.shape == (40,)
    for i in range(40):
        assert batch[i] == pytest.approx(rb(rho[i], beta[i])[0], abs=1e-15)


@pytest.mark.parametrize("mode", ["product", "mamdani"])
def test_outputs_stay_in_the_unit_interval(mode: str) -> None:
    # u ∈ [0, 1] (SPEC step 2): a weighted average of the centres must not overshoot them, not
    # even by rounding (1 − u is a fusion weight, eq. 24)
    cfg = FuzzyConfig(inference=mode)
    rng = np.random.default_rng(99)
    n, k = (20000, 41) if mode == "product" else (500, 9)
    for rb, scale in [
        (point_rule_base(cfg), [8.0, HALF_PI]),
        (line_rule_base(cfg), [1.0, 0.05]),
        (virtual_point_rule_base(cfg), [1.0, 1.0, 4.0]),
    ]:
        inputs = [rng.uniform(-0.1, 1.1, n) * s for s in scale]
        grid = np.meshgrid(*[np.linspace(0, s, k) for s in scale], indexing="ij")
        inputs = [np.concatenate([a, g.ravel()]) for a, g in zip(inputs, grid)]
        u = rb(*inputs)
        assert np.all(np.isfinite(u))
        assert u.min() >= 0.0 and u.max() <= 1.0, (rb.name, u.min(), u.max())


# ---------------------------------------------------------------------------------------------
# Monotonicity (non-strict: Table 1 is flat in places)
# ---------------------------------------------------------------------------------------------
TOL = 1e-12


@PROPS
@given(r1=st.floats(-1.0, 9.0), r2=st.floats(-1.0, 9.0), beta=st.floats(0.0, HALF_PI))
def test_point_uncertainty_never_falls_with_distance(r1: float, r2: float, beta: float) -> None:
    lo, hi = sorted((r1, r2))
    u = point_rule_base(CFG)([lo, hi], [beta, beta])
    assert u[0] <= u[1] + TOL


@PROPS
@given(b1=st.floats(0.0, HALF_PI), b2=st.floats(0.0, HALF_PI), rho=st.floats(0.0, 8.0))
def test_point_uncertainty_never_rises_with_detection_angle(
    b1: float, b2: float, rho: float
) -> None:
    lo, hi = sorted((b1, b2))
    u = point_rule_base(CFG)([rho, rho], [lo, hi])
    assert u[0] + TOL >= u[1]


def test_point_uncertainty_monotone_on_a_grid() -> None:
    rho = np.linspace(0.0, 8.0, 161)
    beta = np.linspace(0.0, HALF_PI, 91)
    R, B = np.meshgrid(rho, beta, indexing="ij")
    u = point_rule_base(CFG)(R.ravel(), B.ravel()).reshape(R.shape)
    assert np.all(np.diff(u, axis=0) >= -TOL)  # non-decreasing in ρ
    assert np.all(np.diff(u, axis=1) <= TOL)  # non-increasing in β
    assert np.all((u >= 0.0) & (u <= 1.0))
    # and it does change in both directions somewhere (not a constant)
    assert np.ptp(u) == pytest.approx(1.0)


@PROPS
@given(
    x=st.tuples(st.floats(0, 1), st.floats(0, 1), st.floats(0, 1)),
    which=st.integers(0, 2),
    step=st.floats(0, 1),
)
def test_virtual_uncertainty_never_falls_as_any_input_grows(
    x: tuple[float, float, float], which: int, step: float
) -> None:
    scale = np.array([1.0, 1.0, 4.0])
    a = np.array(x) * scale
    b = a.copy()
    b[which] = min(scale[which], a[which] + step * scale[which])
    u = virtual_point_rule_base(CFG)(*np.stack([a, b], axis=1))
    assert u[0] <= u[1] + TOL


@PROPS
@given(d=st.floats(0, 1), s=st.floats(0, 0.05), dd=st.floats(0, 1), ds=st.floats(0, 0.05))
def test_line_uncertainty_never_falls_as_inputs_grow(
    d: float, s: float, dd: float, ds: float
) -> None:
    u = line_rule_base(CFG)([d, min(1.0, d + dd)], [s, min(0.05, s + ds)])
    assert u[0] <= u[1] + TOL


# ---------------------------------------------------------------------------------------------
# Mamdani mode against scikit-fuzzy
# ---------------------------------------------------------------------------------------------
skfuzzy = pytest.importorskip("skfuzzy")
from skfuzzy import control as ctrl  # noqa: E402

MAMDANI = FuzzyConfig(inference="mamdani")
N_SAMPLES = 30


def _sk_variable(kind, name: str, var: str, n: int):
    lo, hi = range_of(var)
    universe = np.linspace(lo, hi, n)
    v = kind(universe, name)
    labels = ["GS", "S", "M", "B", "GB"] if len(SPEC_SETS[var][3]) == 5 else ["S", "M", "B"]
    for label, tri in zip(labels, sets_of(var)):
        v[label] = skfuzzy.trimf(universe, list(tri))
    return v


def _sk_output():
    return _sk_variable(ctrl.Consequent, "out", "unit", 1001)


def _sk_points():
    rho = _sk_variable(ctrl.Antecedent, "rho", "rho", 801)
    beta = _sk_variable(ctrl.Antecedent, "beta", "beta", 901)
    out = _sk_output()
    rules = [
        ctrl.Rule(rho[r] & beta[b], out[TABLE1[i][j]])
        for i, r in enumerate(["GS", "S", "M", "B", "GB"])
        for j, b in enumerate("SMB")
    ]
    assert len(rules) == 15
    return rules, ["rho", "beta"]


def _sk_lines():
    delta = _sk_variable(ctrl.Antecedent, "delta", "unit", 1001)
    sigma = _sk_variable(ctrl.Antecedent, "sigma", "sigma", 1001)
    out = _sk_output()
    rules = [
        ctrl.Rule(delta[d] & sigma[s], out[TABLE2[i][j]])
        for i, d in enumerate("SMB")
        for j, s in enumerate("SMB")
    ]
    assert len(rules) == 9
    return rules, ["delta", "sigma"]


def _sk_virtual():
    fl1 = _sk_variable(ctrl.Antecedent, "fl1", "unit", 1001)
    fl2 = _sk_variable(ctrl.Antecedent, "fl2", "unit", 1001)
    dv = _sk_variable(ctrl.Antecedent, "dv", "d_v", 801)
    out = _sk_output()
    rules = [
        ctrl.Rule(fl1[a] & fl2[b] & dv[c], out[table3_composed(i1, i2, k)])
        for i1, a in enumerate("SMB")
        for i2, b in enumerate("SMB")
        for k, c in enumerate(["GS", "S", "M", "B", "GB"])
    ]
    assert len(rules) == 45
    return rules, ["fl1", "fl2", "dv"]


CASES = {
    "points": (_sk_points, point_rule_base, ["rho", "beta"]),
    "lines": (_sk_lines, line_rule_base, ["unit", "sigma"]),
    "virtual_points": (_sk_virtual, virtual_point_rule_base, ["unit", "unit", "d_v"]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_mamdani_matches_scikit_fuzzy(case: str) -> None:
    build_sk, build_ours, variables = CASES[case]
    rules, names = build_sk()
    sim = ctrl.ControlSystemSimulation(ctrl.ControlSystem(rules), cache=False)
    ours = build_ours(MAMDANI)
    assert ours.mode == "mamdani"

    rng = np.random.default_rng(sum(map(ord, case)))
    samples = np.array([rng.uniform(*range_of(v), N_SAMPLES) for v in variables])  # (d, n)
    # include some exact peaks / range ends, where sets switch on and off
    peaks = np.array(
        [[SPEC_SETS[v][3][k % len(SPEC_SETS[v][3])] for v in variables] for k in (0, 1, 2, 4)]
    ).T
    samples = np.concatenate([samples, peaks], axis=1)

    got = ours(*samples)
    expected = []
    for col in samples.T:
        for name, value in zip(names, col):
            sim.input[name] = float(value)
        sim.compute()
        expected.append(sim.output["out"])
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-3)
    # and Mamdani is not the product mode (the comparison would be vacuous otherwise)
    assert np.max(np.abs(got - build_ours(CFG)(*samples))) > 1e-2


def test_mamdani_uses_min_max_and_centroid() -> None:
    # ρ = 3 m (S 0.5, M 0.5), β = 67.5° (M 0.5, B 0.5): under min, the rules S,M -> S, S,B -> S,
    # M,M -> M, M,B -> M all fire at 0.5; max-aggregation clips S and M at 0.5. The centroid of
    # that shape, computed here on a fine grid, is not the product mode's 0.25.
    rb = point_rule_base(MAMDANI)
    y = np.linspace(0.0, 1.0, 400001)
    s = np.clip((0.5 - y) / 0.5, 0, 1)
    m = np.clip(1 - np.abs(y - 0.5) / 0.5, 0, 1)
    agg = np.maximum(np.minimum(s, 0.5), np.minimum(m, 0.5))
    expected = float(np.sum(agg * y) / np.sum(agg))
    got = rb(3.0, math.radians(67.5))[0]
    assert got == pytest.approx(expected, abs=1e-5)
    assert abs(got - 0.25) > 0.05
    assert point_rule_base(CFG)(3.0, math.radians(67.5))[0] == pytest.approx(0.25, abs=1e-12)


def test_mamdani_at_a_single_rule_is_the_centroid_of_its_set() -> None:
    # ρ = 0, β = 90°: only GS,B -> S fires, at 1; the centroid of S (0, 0, 0.5) is 1/6
    assert point_rule_base(MAMDANI)(0.0, HALF_PI)[0] == pytest.approx(1 / 6, abs=1e-6)
    # ρ = 8, β = 0: only GB,S -> B: centroid of (0.5, 1, 1) is 5/6
    assert point_rule_base(MAMDANI)(8.0, 0.0)[0] == pytest.approx(5 / 6, abs=1e-6)
    # ρ = 4, β = 45°: only M,M -> M: centroid 0.5
    assert point_rule_base(MAMDANI)(4.0, math.pi / 4)[0] == pytest.approx(0.5, abs=1e-9)


# ---------------------------------------------------------------------------------------------
# Errors
# ---------------------------------------------------------------------------------------------
def test_fuzzy_error_is_a_value_error() -> None:
    assert issubclass(FuzzyError, ValueError)


@pytest.mark.parametrize(
    "build,args",
    [
        (point_rule_base, (1.0,)),
        (point_rule_base, (1.0, 0.5, 0.2)),
        (point_rule_base, ()),
        (line_rule_base, (0.5,)),
        (virtual_point_rule_base, (0.1, 0.2)),
        (virtual_point_rule_base, (0.1, 0.2, 1.0, 3.0)),
    ],
)
def test_wrong_number_of_inputs(build, args) -> None:
    with pytest.raises(FuzzyError, match="inputs"):
        build(CFG)(*args)


@pytest.mark.parametrize("mode", ["product", "mamdani"])
def test_inputs_of_different_lengths(mode: str) -> None:
    cfg = FuzzyConfig(inference=mode)
    with pytest.raises(FuzzyError, match="lengths"):
        point_rule_base(cfg)([1.0, 2.0], [0.5])
    with pytest.raises(FuzzyError, match="lengths"):
        virtual_point_rule_base(cfg)([0.1, 0.2], [0.3, 0.4], [1.0, 2.0, 3.0])
    with pytest.raises(FuzzyError, match="lengths"):
        point_rule_base(cfg).firing_strengths([1.0], [0.5, 0.6])


def test_rule_base_rejects_a_table_of_the_wrong_shape() -> None:
    rb = point_rule_base(CFG)
    with pytest.raises(FuzzyError, match="shape"):
        RuleBase(
            name="bad",
            input_sets=rb.input_sets,
            consequents=rb.consequents.T.copy(),
            output_sets=rb.output_sets,
            output_centres=rb.output_centres,
        )


def test_rule_base_rejects_an_unknown_mode() -> None:
    rb = point_rule_base(CFG)
    with pytest.raises(FuzzyError, match="mode"):
        RuleBase(
            name="bad",
            input_sets=rb.input_sets,
            consequents=rb.consequents,
            output_sets=rb.output_sets,
            output_centres=rb.output_centres,
            mode="sugeno",
        )


def test_empty_inputs_give_empty_outputs() -> None:
    for mode in ("product", "mamdani"):
        bases = RuleBases.from_config(FuzzyConfig(inference=mode))
        for rb in (bases.points, bases.lines, bases.virtual_points):
            out = rb(*([np.zeros(0)] * len(rb.input_sets)))
            assert out.shape == (0,)


def test_bilinear_shortcut_equals_the_rule_sum() -> None:
    """Two inputs with partitions of unity take the interpolation shortcut; it must give eq. 4."""
    bases = RuleBases.from_config(FuzzyConfig())
    rng = np.random.default_rng(11)
    for rb, hi in ((bases.points, (9.0, 1.7)), (bases.lines, (1.1, 0.06))):
        assert rb._grids is not None  # the shortcut is taken
        x1, x2 = rng.uniform(-0.5, hi[0], 500), rng.uniform(-0.1, hi[1], 500)
        w = rb.firing_strengths(x1, x2)
        np.testing.assert_allclose(
            rb(x1, x2), (w @ rb._centres) / w.sum(axis=1), rtol=0, atol=1e-12
        )
    # sets that are not a partition of unity go the general way
    odd = FuzzyConfig(
        distance_sets=(
            (0.0, 0.0, 3.0),
            (0.0, 2.0, 4.0),
            (2.0, 4.0, 6.0),
            (4.0, 6.0, 8.0),
            (6.0, 8.0, 8.0),
        )
    )
    assert RuleBases.from_config(odd).points._grids is None
