"""The peers benchmark's simulated logs (``benchmarks/bench_peers.py --logs sim360``): written
as CARMEN logs that read back with the scanner's beams, and relations that are the truth's."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from fuzzypos import sim
from fuzzypos.eval import relations_errors
from fuzzypos.io import open_log, read_relations
from fuzzypos.jobs import DemoSettings
from helpers import load_benchmark


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    """The benchmark as a module (its import pins the thread counts: put back afterwards)."""
    return load_benchmark("bench_peers")


def test_the_simulated_log_reads_back_and_its_relations_are_the_truth(bench, tmp_path) -> None:
    log, relations_path = bench.simulated_log(tmp_path, "sim360")
    records = list(open_log(log).records())
    run = sim.simulate_run(
        sim.gym(), sim.CommandedPath.circle(4.0, 3.0, 0.3),
        DemoSettings().scanner, DemoSettings().slip, 0, with_scans=False,
    )  # fmt: skip
    assert len(records) == len(run.true_poses) > 2000
    assert all(len(r.scan.ranges) == 360 for r in records[:50])
    stamps = np.array([r.scan.stamp for r in records])
    relations = read_relations(relations_path)
    assert np.all(relations.t2 > relations.t1)  # (t2 < t1 would count as local)
    local = relations.t2 - relations.t1 <= 10.0
    assert 0 < local.sum() < len(local)  # local relations and long ones
    truth = relations_errors(stamps, run.true_poses, relations)
    assert truth.all.matched == len(local)
    assert truth.all.translation_m.mean < 1e-9 and truth.all.rotation_deg.mean < 1e-7
    odometry = np.array([r.odometry.as_array() for r in records])
    assert relations_errors(stamps, odometry, relations).all.translation_m.mean > 0.01


def test_the_timing_rounds_ratio_each_round_and_alternate_the_order(bench, monkeypatch) -> None:
    """``--rounds``: the main run's ratio first, then one per round of fuzzypos and the ratio
    peers run anew (no other method), fuzzypos last in the even rounds, first in the odd."""
    gicp, kiss = bench.RATIO_PEERS
    names = [bench.FuzzyposDefault.name, gicp, "small_gicp PLANE_ICP, 1 m / 30° keyframes", kiss]
    ms = {bench.FuzzyposDefault.name: [0.2, 0.3], gicp: [0.5, 0.6], kiss: [0.4, 1.2]}
    order: list[str] = []

    class Stub(bench.Method):
        def __init__(self, name: str) -> None:
            super().__init__()
            self.name = name

    def run(method, log_path, max_scans):
        k = sum(name == method.name for name in order)
        order.append(method.name)
        return {"matcher_seconds": ms[method.name][k] * 10 / 1000.0, "scans": 10}

    monkeypatch.setattr(bench, "make_methods", lambda: ([Stub(n) for n in names], []))
    monkeypatch.setattr(bench, "run_method", run)
    first = {bench.FuzzyposDefault.name: 0.25, gicp: 0.5, kiss: 1.0, names[2]: 0.1}
    out = bench.timing_rounds(Path("log.clf"), 3, None, first)
    assert out[gicp] == pytest.approx([0.5, 0.4, 0.5])
    assert out[kiss] == pytest.approx([0.25, 0.5, 0.25])
    assert set(out) == {gicp, kiss}
    assert order == [kiss, gicp, bench.FuzzyposDefault.name, bench.FuzzyposDefault.name, gicp, kiss]
