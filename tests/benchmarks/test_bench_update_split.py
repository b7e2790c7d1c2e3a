"""``benchmarks/bench_update_split.py --gicp``: small_gicp GICP timed on the same scans as
``Positioner.update`` and its kernels, and the times printed over GICP's (issue 12's proxy beside
what the kernels alone take)."""

from __future__ import annotations

from types import ModuleType

import pytest

from fuzzypos import sim
from fuzzypos.jobs import DemoSettings
from helpers import load_benchmark


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return load_benchmark("bench_update_split")


def test_the_times_over_gicp_are_each_part_over_its_time(bench, capsys) -> None:
    # 100 scans: update 1 s, the kernels 0.6 s, the Python 0.3 s, GICP 2 s
    bench.print_over_gicp(1.0, 0.6, 0.3, 2.0, 1e6 / 100)
    rows = {
        line.split(" | ")[0].strip("| "): line.split(" | ")[1:]
        for line in capsys.readouterr().out.splitlines()
        if line.startswith("| ") and "µs a scan" not in line
    }
    assert rows["Positioner.update"] == ["10000.0", "0.50 |"]
    assert rows["all the kernels"] == ["6000.0", "0.30 |"]
    assert rows["Python between the kernels"] == ["3000.0", "0.15 |"]
    assert rows["small_gicp GICP, 1 m / 30° keyframes: align"] == ["20000.0", "1.00 |"]


def test_split_times_gicp_on_the_same_scans_only_when_asked(bench) -> None:
    pytest.importorskip("small_gicp", reason="the bench extra: pip install -e '.[bench]'")
    settings = DemoSettings()
    run = sim.simulate_run(
        sim.gym(), sim.CommandedPath.circle(settings.radius, 0.1, settings.speed),
        settings.scanner, settings.slip, 0,
    )  # fmt: skip
    records = [(s, run.odometry_pose(k)) for k, s in enumerate(run.scans)]
    assert len(records) > 30
    without = bench.split(records, 1)
    assert without["gicp"] is None
    out = bench.split(records, 1, gicp=True)
    assert out["gicp"] > 0.0  # GICP aligned the scans after the first keyframe
    in_kernels = sum(seconds for seconds, _ in out["kernels"].values())
    assert 0.0 < in_kernels < out["with_timers"]
