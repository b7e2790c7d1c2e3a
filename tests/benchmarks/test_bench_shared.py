"""``benchmarks/bench_shared.py``: the report's table from ``fuzzypos benchmark``'s rows, each
run against the odometry of its log; and a real (short) run on a simulated data folder."""

from __future__ import annotations

from types import ModuleType

import numpy as np
import pytest

from helpers import load_benchmark, write_relations, write_sim_log


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return load_benchmark("bench_shared")


def _row(log: str, config: str, all_m: float) -> dict:
    return {
        "log": log, "config": config, "all_trans_mean_m": all_m, "all_rot_mean_deg": 1.0,
        "local_trans_mean_m": 0.01, "local_rot_mean_deg": 0.2, "scans": 10,
        "scans_degraded": 0,
    }  # fmt: skip


def test_a_run_worse_than_the_odometry_is_marked(bench) -> None:
    rows = [_row("a.clf", "odometry", 0.5), _row("a.clf", "default", 1.0),
            _row("b.clf", "odometry", 2.0), _row("b.clf", "default", 0.5),
            {"log": "c.clf", "config": "default", "error": "no scans"}]  # fmt: skip
    text = bench.table(rows)
    line = {(ln.split("|")[1].strip(), ln.split("|")[2].strip()): ln for ln in text.splitlines()}
    assert line[("a.clf", "default")].rstrip(" |").endswith("2.00 ✗")
    assert line[("b.clf", "default")].rstrip(" |").endswith("0.25")
    assert line[("a.clf", "odometry")].rstrip().endswith("|  |")  # no ratio of its own
    assert "failed: no scans" in line[("c.clf", "default")]


def test_a_simulated_data_folder_is_benchmarked(bench, tmp_path) -> None:
    data = tmp_path / "data" / "sim"
    data.mkdir(parents=True)
    run = write_sim_log(data / "sim.clf", laps=0.3)
    stamps = np.array([s.stamp for s in run.scans])
    truth = np.array([run.true_pose(k).as_array() for k in range(len(run.scans))])
    pairs = [(k, k + 10) for k in range(0, len(stamps) - 10, 5)]
    write_relations(data / "sim.relations", stamps, truth, pairs)
    rows = bench.run_benchmark(tmp_path / "data", tmp_path / "out", None, False)
    assert {r["config"] for r in rows} == {"odometry", "paper", "default"}
    assert all("results" not in r for r in rows)
    text = bench.markdown(
        rows, dict.fromkeys(("date", "commit", "machine", "command", "data"), "x")
    )
    assert "| sim.clf | default |" in text
    default = next(r for r in rows if r["config"] == "default")
    assert default["all_trans_mean_m"] < 0.05  # a simulated world: the answer is known
