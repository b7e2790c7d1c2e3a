"""``benchmarks/bench_keyframe_stamps.py``: the corrupt stamps it writes are refused without
``--scan-rate`` and run with it, a pose per scan, scored as the same scans with their own
stamps."""

from __future__ import annotations

import gzip
from types import ModuleType

import numpy as np
import pytest

from helpers import load_benchmark, write_relations, write_sim_log


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return load_benchmark("bench_keyframe_stamps")


def test_the_stamps_repeat_or_go_back_for_most_scans(bench) -> None:
    true = 1000.0 + 1.1 * np.arange(300)  # keyframes about a second apart
    bad = bench.corrupt_stamps(true)
    steps = np.diff(bad)
    assert (steps <= 0.0).mean() > 0.6  # most scans: a log refused as corrupt
    assert (steps < 0.0).sum() >= 80 and (steps == 0.0).sum() >= 80  # both kinds
    assert np.all(np.abs(bad - true) <= 20.2 + 1e-9)  # near the true stamps


def test_a_simulated_keyframe_log_is_refused_then_runs_with_the_flag(bench, tmp_path) -> None:
    data = tmp_path / "data"
    (data / "intel").mkdir(parents=True)
    plain = tmp_path / "sim.clf"
    run = write_sim_log(plain, laps=1.0)
    (data / "intel" / "intel.clf.gz").write_bytes(gzip.compress(plain.read_bytes()))
    stamps = np.array([s.stamp for s in run.scans])
    truth = np.array([run.true_pose(k).as_array() for k in range(len(run.scans))])
    pairs = [(k, k + 15) for k in range(0, len(stamps) - 15, 10)]
    write_relations(data / "intel" / "intel.relations", stamps, truth, pairs)
    folder = tmp_path / "work"
    folder.mkdir()
    r = bench.measure(data, "intel", 30, folder)
    assert r["scans"] == 30 and r["rows"] == 30
    assert r["refused_exit"] == 2 and r["refusal_names_flag"]
    assert r["relations"] > 0
    own, flagged = r["own"], r["scan_rate"]
    # the same scans: the evenly spaced stamps cost little against the scans' own
    assert flagged["all_trans_mean_m"] < 2.0 * own["all_trans_mean_m"] + 0.02
    assert flagged["all_trans_mean_m"] < 0.1  # a simulated world: the answer is known
    text = bench.markdown(r, {"date": "d", "commit": "c", "machine": "m", "command": "x"})
    assert "`--scan-rate " in text and "| 30 | 2 |" in text
