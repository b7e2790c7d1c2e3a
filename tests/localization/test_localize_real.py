"""``fuzzypos localize`` end to end with the real localizer (``fuzzypos.localization``) on a
simulated log in the office world, its map drawn from the world's walls: it localises
globally within a second of the log and tracks the truth to centimetres; from an initial
pose at once; in a map with nothing like the scans never (exit 1, no pose rows)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fuzzypos import sim
from fuzzypos.io import read_tum
from fuzzypos.jobs.localize import localize_log
from helpers import invoke, write_sim_log, write_world_map

pytest.importorskip("fuzzypos.localization")


@pytest.fixture(scope="module")
def office(tmp_path_factory):
    folder = tmp_path_factory.mktemp("real_localize")
    log = folder / "sim.clf"
    run = write_sim_log(log, laps=0.3, seed=0)
    yaml_path, _, _ = write_world_map(folder / "map", sim.world_by_name("office"), 0.05)
    return log, yaml_path, run


def test_it_localises_globally_and_tracks_the_truth(office, tmp_path) -> None:
    log, yaml_path, run = office
    s = localize_log(log, yaml_path, results_dir=tmp_path / "r")
    data = s.summary
    assert s.localised and data["localised_at"]["scan"] <= 20
    assert data["states"]["tracking"] >= len(run) - 20 and data["final_state"] == "tracking"
    t, poses = read_tum(tmp_path / "r" / "trajectory.tum")
    truth = {round(float(st), 6): p for st, p in zip(run.stamps, run.true_poses)}
    want = np.array([truth[round(float(st), 6)] for st in t])
    err = np.hypot(*(poses[:, :2] - want[:, :2]).T)
    assert err.max() < 0.05, err.max()
    assert data["truth_errors"]["max_position_error_m"] == pytest.approx(err.max())
    cov = np.loadtxt(tmp_path / "r" / "covariance.csv", delimiter=",", skiprows=1,
                     usecols=range(14), ndmin=2)  # fmt: skip
    assert cov.shape[0] == len(t) and np.all(cov[:, [7, 10, 12]] > 0)  # variances


def test_from_an_initial_pose_it_tracks_at_once(office, tmp_path) -> None:
    log, yaml_path, run = office
    x, y, th = run.true_poses[0]
    lines = invoke(["localize", str(log), "--map", str(yaml_path), "--results",
                    str(tmp_path / "r"), "--initial-pose", f"{x},{y},{np.degrees(th)}",
                    "--initial-sigma", "0.2,5"], 0)  # fmt: skip
    assert lines[0].startswith("localised at scan 1 ")
    data = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert data["states"]["tracking"] == len(run) and data["events"][0]["scan"] == 1


def test_a_map_with_nothing_like_the_scans_never_localises(office, tmp_path) -> None:
    log = office[0]
    img = np.full((200, 200), 254, dtype=np.uint8)
    img[100, 100] = 0  # one obstacle in an empty floor
    (tmp_path / "empty.pgm").write_bytes(b"P5\n200 200\n255\n" + img.tobytes())
    (tmp_path / "empty.yaml").write_text(
        "image: empty.pgm\nresolution: 0.05\norigin: [-5, -5, 0]\n"
    )
    out = tmp_path / "r"
    (line,) = invoke(["localize", str(log), "--map", str(tmp_path / "empty.yaml"),
                      "--results", str(out)], 1)  # fmt: skip
    assert "never localised" in line
    assert json.loads((out / "summary.json").read_text())["localised"] is False
    t, _ = read_tum(out / "trajectory.tum")
    assert t.size == 0


def test_a_map_another_tool_wrote_negated_trinary_and_coarser_is_localised_in(
    office, tmp_path
) -> None:
    """The issue's "map made by another tool": the world's map_server map written with
    ``negate: 1``, ``mode: trinary`` and 0.1 m cells (not the run's own 0.05 m, white-free
    map): read as map_server reads it, localised in globally, tracking the truth."""
    log, _, run = office
    yaml_path, _, _ = write_world_map(
        tmp_path / "other", sim.world_by_name("office"), 0.1, negate=True
    )
    yaml_path.write_text(yaml_path.read_text(encoding="utf-8") + "mode: trinary\n")
    s = localize_log(log, yaml_path, results_dir=tmp_path / "r")
    assert s.localised and s.summary["localised_at"]["scan"] <= 30
    t, poses = read_tum(tmp_path / "r" / "trajectory.tum")
    truth = {round(float(st), 6): p for st, p in zip(run.stamps, run.true_poses)}
    want = np.array([truth[round(float(st), 6)] for st in t])
    err = np.hypot(*(poses[:, :2] - want[:, :2]).T)
    # within a cell of the coarser map (its walls are drawn to the nearest 0.1 m cell)
    assert len(t) >= len(run) - 30 and np.median(err) < 0.1, (len(t), np.median(err))
