"""Trajectory errors against known paths."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzypos.evaluation import EvaluationError, distance_along, position_errors, trajectory_errors


def test_distance_along_a_square() -> None:
    sq = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 0]], float)
    np.testing.assert_allclose(distance_along(sq), [0, 1, 2, 3, 4])


def test_errors_of_a_shifted_and_turned_path() -> None:
    truth = np.column_stack([np.arange(5.0), np.zeros(5), np.zeros(5)])
    est = truth + [0.0, 0.3, math.radians(2)]
    est[-1, 1] = 0.5
    d, h = position_errors(truth, est)
    np.testing.assert_allclose(d, [0.3, 0.3, 0.3, 0.3, 0.5])
    np.testing.assert_allclose(h, math.radians(2))
    e = trajectory_errors(truth, est, scans_degraded=3)
    assert e.final_position_error_m == pytest.approx(0.5)
    assert e.mean_position_error_m == pytest.approx(0.34)
    assert e.max_position_error_m == pytest.approx(0.5)
    assert e.mean_heading_error_deg == pytest.approx(2.0)
    assert e.as_dict()["scans_degraded"] == 3


def test_heading_error_wraps() -> None:
    t = np.array([[0, 0, math.pi - 0.01]])
    e = np.array([[0, 0, -math.pi + 0.01]])
    _, h = position_errors(t, e)
    assert h[0] == pytest.approx(0.02)


@pytest.mark.parametrize(
    ("truth", "est", "what"),
    [
        (np.zeros((3, 3)), np.zeros((4, 3)), "3 poses"),
        (np.zeros((3, 2)), np.zeros((3, 2)), "(n, 3)"),
        (np.zeros((3, 3)), np.full((3, 3), np.nan), "non-finite"),
        (np.zeros((0, 3)), np.zeros((0, 3)), "no poses"),
    ],
)
def test_bad_input(truth, est, what) -> None:
    with pytest.raises(EvaluationError, match=what.replace("(", r"\(").replace(")", r"\)")):
        trajectory_errors(truth, est)
