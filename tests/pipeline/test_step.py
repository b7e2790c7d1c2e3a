"""The positioner's one compiled call for a scan's features, line matching, refinement and
assessment (``fuzzypos._kernels.step.features_and_step``, ``match_refine_assess`` inside it;
``pipeline.step.Step.run``) against its reference, the staged calls it
replaces (``Positioner(fused=False)``: the feature chain, the line
matcher, the refiner and the uncertainty stage called one after the other): the same
estimates to the bit, scan by scan, on simulated runs that reach every stage where the call
hands over to the staged path (the lines give no motion, neither fit counts, the assessment is
left to Python, the gate rejects the match) and the cases around it (learned information, an
odometry jump, no odometry, the fit held to the prior rather than to the features' motion),
and on other kinds of log (an interlaced SICK outdoors, a 360° scanner of 360 beams)."""

from __future__ import annotations

import collections
import math
from collections.abc import Iterator
from functools import cache
from typing import Any

import numpy as np
import pytest

from fuzzypos import sim
from fuzzypos.config import Config
from fuzzypos.geometry import Pose2D
from fuzzypos.jobs import DemoSettings
from fuzzypos.pipeline import Estimate, Positioner
from fuzzypos.pipeline import step as step_module
from fuzzypos.pipeline.warm import warm_up

#: the scenarios: a config's overrides, and the metres added to the odometry's x at some scans
#: (None: no odometry at all), on the office run unless :data:`KINDS` names another
SCENARIOS: dict[str, tuple[dict[str, Any], dict[int, float] | None]] = {
    "default": ({}, {}),
    # neither fit counts for some scans (the search, and the fit against the previous scan)
    "strict inliers": (
        {"refinement": {"min_inlier_fraction": 0.8, "with_previous_scan": True}},
        {},
    ),
    # the lines from the prior give no motion for some scans (the point pairing takes over)
    "five lines": ({"matching": {"line_min_pairs": 5}}, {}),
    # the odometry off by a few centimetres at some scans: the gate rejects the match
    "odometry off": ({}, dict.fromkeys(range(40, 63, 4), 0.06)),
    # the odometry jumps by metres: the prior is not trusted (the wide search)
    "odometry jump": ({}, {40: 3.0, 41: 3.0}),
    # the fit held to the prior from the keyframe, not to the features' motion
    "held to the prior": ({"refinement": {"prior_from_features": False}}, {}),
    # the gate open wherever the noise is learned
    "gate everywhere": (
        {"gate": {"only_where_odometry_is_better": False}},
        dict.fromkeys(range(40, 63, 4), 0.1),
    ),
    "no odometry": ({}, None),
    # other kinds of log: an interlaced SICK outdoors (181/180 beams, no-return codes, far
    # structure) and a 360° scanner of 360 beams
    "sick yard": ({}, {}),
    "360 beams": ({}, {}),
}
KINDS = {"sick yard": "sick yard", "360 beams": "360 beams"}


@cache
def _run(kind: str = "office") -> sim.SimulatedRun:
    """63 scans of the office, driving part of a circle (the demo's scanner); or 64 of the
    interlaced SICK's yard (``"sick yard"``); or 63 of the gym with a 360° scanner of 360
    beams (``"360 beams"``)."""
    if kind == "sick yard":
        return sim.sick_outdoor_run(0, duration=40.0)
    path = sim.CommandedPath.circle(1.0, laps=0.3, speed=0.3)
    if kind == "360 beams":
        scanner = sim.ScannerModel(
            n_beams=360, field_of_view_deg=360.0, angle_min_deg=-180.0, range_max=20.0,
            range_noise_std=0.01,
        )  # fmt: skip
        return sim.simulate_run(sim.world_by_name("gym"), path, scanner, sim.SlipModel(), 2)
    world = sim.world_by_name("office")
    return sim.simulate_run(world, path, DemoSettings().scanner, sim.SlipModel(), 1)


def _odometry(run: sim.SimulatedRun, shifts: dict[int, float] | None) -> Iterator[Pose2D | None]:
    for k in range(len(run.scans)):
        if shifts is None:
            yield None
            continue
        o = run.odometry_pose(k)
        yield Pose2D(o.x + shifts.get(k, 0.0), o.y, o.theta)


def _estimates(name: str, fused: bool) -> tuple[list[Estimate], Positioner]:
    overrides, shifts = SCENARIOS[name]
    positioner = Positioner(Config().with_overrides(overrides), fused=fused)
    run = _run(KINDS.get(name, "office"))
    estimates = [positioner.update(s, o) for s, o in zip(run.scans, _odometry(run, shifts))]
    return estimates, positioner


@cache
def _compiled() -> None:
    warm_up()


def _bits(value: Any) -> Any:
    """``value`` as something ``==`` compares to the bit (arrays and floats by their bytes)."""
    if isinstance(value, Pose2D):
        return np.array([value.x, value.y, value.theta]).tobytes()
    if isinstance(value, np.ndarray):
        return (value.shape, value.tobytes())
    if isinstance(value, float):
        return np.float64(value).tobytes()
    return value


def _fields(e: Estimate) -> dict[str, Any]:
    names = ("stamp", "pose", "increment", "prior", "n_pairs", "degraded", "reason")
    names += ("odometry_rejected", "refined", "covariance", "keyframe_covariance", "gate")
    return {n: _bits(getattr(e, n)) for n in names + ("keyframe",)}


class _Stages:
    """The stages the compiled call reached (its first value), and how often the gate it
    computed rejected the match, counted while patched in (every kernel compiled first: a
    kernel compiled while a callee of it is patched would find a Python function there)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        _compiled()
        self.reached: collections.Counter[int] = collections.Counter()
        self.full = 0
        step = step_module._step()
        chained = step.features_and_step

        def count(stage: int, gate: float, full: bool, gate_open: bool, threshold: float) -> None:
            self.reached[stage] += 1
            self.full += bool(full)
            if stage == step.ASSESSED and gate_open and gate > threshold:
                self.reached[-1] += 1  # (rejected)

        def counted(*args: Any) -> Any:  # (args: the scan's, the keyframe's, the settings)
            values = chained(*args)
            stepped = step.Stepped(*values)
            if stepped.stage != step.FEATURES_ONLY:
                refine, assess = args[3], args[4]
                count(stepped.stage, stepped.gate, refine.full, assess.gate_open, assess.threshold)
            return values

        monkeypatch.setattr(step, "features_and_step", counted)


@pytest.mark.parametrize("name", SCENARIOS)
def test_the_compiled_step_gives_the_staged_estimates_to_the_bit(
    name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Scan by scan, the positioner with the compiled call gives the estimates of the staged
    calls: the poses, increments, covariances, gates, pairs, reasons and flags, to the bit;
    and it leaves the same learned odometry noise behind."""
    staged, staged_positioner = _estimates(name, fused=False)
    stages = _Stages(monkeypatch)
    fused, fused_positioner = _estimates(name, fused=True)
    assert sum(stages.reached.values()) > 0  # (the compiled call was made)
    assert len(fused) == len(staged) == len(_run(KINDS.get(name, "office")).scans)
    for k, (a, b) in enumerate(zip(fused, staged)):
        assert _fields(a) == _fields(b), f"scan {k}"
    increment = np.array([0.1, 0.02, 0.05])
    noise_a, noise_b = fused_positioner.odometry_noise, staged_positioner.odometry_noise
    np.testing.assert_array_equal(noise_a.covariance(increment), noise_b.covariance(increment))
    assert (noise_a.scale, noise_a.rotation_factor) == (noise_b.scale, noise_b.rotation_factor)


def test_the_scenarios_reach_every_stage(monkeypatch: pytest.MonkeyPatch) -> None:
    """The scenarios above take the compiled call to each of its stages (and the gate to a
    rejection, the learned information to the fits), so the test above compares them all."""
    step = step_module._step()
    reached: dict[str, collections.Counter[int]] = {}
    full = 0
    for name in SCENARIOS:
        stages = _Stages(monkeypatch)
        _estimates(name, fused=True)
        reached[name] = stages.reached
        full += stages.full
        monkeypatch.undo()
    assert reached["five lines"][step.NO_LINES] > 0
    assert reached["strict inliers"][step.NOT_REFINED] > 0
    assert reached["default"][step.REFINED] > 0  # (after a keyframe renewal)
    assert reached["default"][step.ASSESSED] > 0
    assert reached["odometry off"][-1] > 0  # (the gate rejected)
    assert full > 0
    # no odometry: the prior is no odometry's, nothing learned, no gate
    assert reached["no odometry"][-1] == 0
    for kind in KINDS:  # (the other kinds of log take the common path too)
        assert reached[kind][step.ASSESSED] > 0, kind


def test_the_odometry_jump_leaves_the_compiled_call(monkeypatch: pytest.MonkeyPatch) -> None:
    """After an odometry jump the prior is not trusted and the search takes over: the compiled
    call is not made for those scans (the staged path's wide refinement instead)."""
    stages = _Stages(monkeypatch)
    estimates, _ = _estimates("odometry jump", fused=True)
    jumped = sum(e.odometry_rejected for e in estimates)
    assert jumped > 0
    assert sum(stages.reached.values()) == len(estimates) - 1 - jumped  # (not the first scan)
    assert all(math.isfinite(e.pose.x) for e in estimates)
