"""``fuzzypos run LOG --save-map [--map-resolution M]`` (issue 35): the occupancy map from the
front end's poses without loop closure, as ROS map_server reads it, on the simulated world's
walls; without gtsam. Each test fails without the feature."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fuzzypos import sim
from helpers import invoke, one_line_error, write_sim_log

yaml = pytest.importorskip("yaml")

MAP_FILES = ("map.pgm", "map.yaml", "map.png")


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory):
    """A short simulated log (0.3 of a lap of a 1 m circle) in the office world."""
    path = tmp_path_factory.mktemp("savemap") / "sim.clf"
    return path, write_sim_log(path, laps=0.3, seed=0)


@pytest.fixture(scope="module")
def saved(sim_log, tmp_path_factory):
    """``run --save-map`` on it (default resolution): the results folder."""
    path, _ = sim_log
    out = tmp_path_factory.mktemp("saved") / "res"
    invoke(["run", str(path), "--save-map", "--results", str(out)], 0)
    return out


def read_map(folder: Path) -> tuple[dict, np.ndarray]:
    """map.yaml as map_server reads it, and its image (top row first)."""
    meta = yaml.safe_load((folder / "map.yaml").read_text())
    data = (folder / meta["image"]).read_bytes()
    magic, _comment, size, maxval = data.split(b"\n", 4)[:4]
    assert magic == b"P5" and maxval == b"255"
    w, h = (int(v) for v in size.split())
    return meta, np.frombuffer(data[-w * h :], dtype=np.uint8).reshape(h, w)


def distance_to_walls(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Each point's distance to the nearest wall segment."""
    a, b = segments[:, :2], segments[:, 2:]
    ab = b - a
    t = np.einsum("pmk,mk->pm", points[:, None, :] - a, ab) / np.einsum("mk,mk->m", ab, ab)
    nearest = a + np.clip(t, 0.0, 1.0)[..., None] * ab
    return np.min(np.hypot(*(points[:, None, :] - nearest).transpose(2, 0, 1)), axis=1)


def test_save_map_writes_a_map_server_map_whose_walls_are_the_worlds(saved) -> None:
    meta, img = read_map(saved)
    assert {"image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh"} <= set(
        meta
    )
    assert meta["image"] == "map.pgm" and meta["resolution"] == pytest.approx(0.05)
    assert meta["negate"] == 0 and len(meta["origin"]) == 3
    assert 0 < meta["free_thresh"] < meta["occupied_thresh"] < 1
    assert (saved / "map.png").read_bytes()[:4] == b"\x89PNG"
    summary = json.loads((saved / "summary.json").read_text())
    assert all(summary["files"][name] == str(saved / name) for name in MAP_FILES)
    assert "loop_closure" not in summary
    # the occupied cells' centres lie on the simulated office's walls (the front end's frame
    # is the world's: the log's first pose); free cells there are many too
    rows, cols = np.nonzero(img == 0)
    assert len(rows) > 100 and np.mean(img == 254) > 0.05
    res, (x0, y0, _) = meta["resolution"], meta["origin"]
    h = img.shape[0]
    centres = np.column_stack([x0 + (cols + 0.5) * res, y0 + (h - 1 - rows + 0.5) * res])
    d = distance_to_walls(centres, sim.world_by_name("office").segments)
    assert np.mean(d < 2 * res) > 0.9, np.percentile(d, [50, 90, 99])


def test_map_resolution_sets_the_cells_size(sim_log, saved, tmp_path) -> None:
    path, _ = sim_log
    out = tmp_path / "res"
    invoke(["run", str(path), "--save-map", "--map-resolution", "0.1", "--results", str(out)], 0)
    fine_meta, fine = read_map(saved)
    meta, coarse = read_map(out)
    assert meta["resolution"] == pytest.approx(0.1)
    for n_fine, n_coarse in zip(fine.shape, coarse.shape):
        assert abs(n_fine / 2 - n_coarse) <= 1, (fine.shape, coarse.shape)
    assert meta["origin"] == pytest.approx(fine_meta["origin"], abs=1e-6)


def test_without_save_map_nor_loop_closure_there_is_no_map(sim_log, tmp_path) -> None:
    path, _ = sim_log
    out = tmp_path / "res"
    invoke(["run", str(path), "--results", str(out), "--max-scans", "20"], 0)
    assert (out / "summary.json").is_file()
    assert not any((out / name).exists() for name in MAP_FILES)
    files = json.loads((out / "summary.json").read_text())["files"]
    assert not set(MAP_FILES) & set(files)


@pytest.mark.parametrize("value", ["0", "-0.05", "nan", "inf", "1000"])
def test_an_absurd_map_resolution_is_one_line_and_exit_2(sim_log, tmp_path, value) -> None:
    path, _ = sim_log
    out = tmp_path / "res"
    one_line_error(
        ["run", str(path), "--save-map", "--map-resolution", value, "--results", str(out)],
        "--map-resolution",
    )
    assert not out.exists()


def test_save_map_needs_no_gtsam(sim_log, tmp_path) -> None:
    """In a process where ``import gtsam`` fails (and is recorded), the map is written and
    gtsam never even tried."""
    path, _ = sim_log
    out = tmp_path / "res"
    code = (
        "import sys\n"
        "tried = []\n"
        "class NoGtsam:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.partition('.')[0] == 'gtsam':\n"
        "            tried.append(name)\n"
        "            raise ImportError('no gtsam here')\n"
        "sys.modules.pop('gtsam', None)\n"
        "sys.meta_path.insert(0, NoGtsam())\n"
        "from fuzzypos.cli import app\n"
        "try:\n"
        f"    app(['run', {str(path)!r}, '--save-map', '--max-scans', '30', "
        f"'--results', {str(out)!r}])\n"
        "finally:\n"
        "    assert not tried, f'gtsam was imported: {tried}'\n"
    )
    src = str(Path(__file__).resolve().parents[2] / "src")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600
    )
    assert done.returncode == 0, done.stderr
    assert all((out / name).is_file() for name in MAP_FILES)


def test_map_resolution_applies_with_loop_closure(sim_log, tmp_path) -> None:
    pytest.importorskip("gtsam")
    path, _ = sim_log
    out = tmp_path / "res"
    args = ["run", str(path), "--loop-closure", "--map-resolution", "0.1", "--max-scans", "40"]
    invoke([*args, "--results", str(out)], 0)
    meta, _ = read_map(out)
    assert meta["resolution"] == pytest.approx(0.1)
    summary = json.loads((out / "summary.json").read_text())
    assert "loop_closure" in summary and "map.pgm" in summary["files"]


def test_the_map_scans_are_chosen_as_loop_closures_are() -> None:
    """One rule for both maps (:class:`~fuzzypos.graph.occupancy.MapScans`, which the online
    mapper uses too): a scan is drawn where it moved ``map_scan_distance`` or turned
    ``map_scan_angle`` since the last one drawn, and only with points."""
    from fuzzypos.config import Config
    from fuzzypos.graph import online
    from fuzzypos.graph.occupancy import MapScans

    assert online.MapScans is MapScans
    lc = Config().loop_closure
    kept = MapScans(lc.map_scan_distance, lc.map_scan_angle)
    pts = np.ones((3, 2))
    moves = [(0.1 * k, 0.0, 0.0) for k in range(7)] + [(0.6, 0.0, lc.map_scan_angle)]
    chosen = [k for k, pose in enumerate(moves) if kept.add(k, np.array(pose), pts)]
    assert chosen == [0, 3, 6, 7]
    assert not kept.add(8, np.array([5.0, 0.0, 0.0]), np.zeros((0, 2)))
    assert [k for k, _ in kept.scans] == chosen
