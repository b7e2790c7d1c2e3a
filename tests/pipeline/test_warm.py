"""``warm_up`` pays the compile cost before the first scan: after it, a drive through every
path of ``Positioner.update`` (an odometry jump and its wide search, a gap in time, a scan
without odometry, standing still) compiles (or loads from the cache) no kernel, and each
kernel has been compiled for one set of argument types only (from an empty cache, as a fresh
install compiles them)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time

import pytest

from fuzzypos._kernels import compiled

#: run in a fresh process: in the test session's own, earlier tests have compiled every kernel
_SCRIPT = textwrap.dedent(
    """
    import importlib, json, math, pkgutil
    import numpy as np
    import fuzzypos._kernels
    from fuzzypos import sim
    from fuzzypos.geometry import Pose2D, compose
    from fuzzypos.pipeline import Positioner
    from fuzzypos.pipeline.warm import kernels_cold, warm_up

    def signatures():
        out = {}
        for info in pkgutil.iter_modules(fuzzypos._kernels.__path__):
            module = importlib.import_module("fuzzypos._kernels." + info.name)
            for name, value in vars(module).items():
                if hasattr(value, "py_func") and hasattr(value, "signatures"):
                    key = info.name + "." + name
                    out[key] = sorted(str(s) for s in value.signatures)
        return out

    cold_before = kernels_cold()
    warm_up()
    cold_after = kernels_cold()
    before = signatures()
    truth = sim.arc_path(Pose2D(-1.0, -0.5, 0.2), 16, 0.05, 1.0)
    jump = np.array([0.38, 0.0, math.radians(-60.6)])
    odom = truth[:6] + [Pose2D.from_array(compose(p.as_array(), jump)) for p in truth[6:]]
    odom[12] = None  # a scan without odometry
    odom[14] = odom[13]  # the wheels did not turn
    stamps = [0.1 * k + (2.0 if k >= 10 else 0.0) for k in range(16)]  # a gap before scan 10
    world = sim.furnished_room(seed=2)
    scanner = sim.ScannerModel(
        n_beams=180, field_of_view_deg=180.0, angle_min_deg=-90.0, range_max=20.0,
        range_noise_std=0.005,
    )
    rng = np.random.default_rng(0)
    positioner = Positioner()
    reasons = []
    for k, (p, o) in enumerate(zip(truth, odom)):
        scan = sim.simulate_scan(world, p, scanner, rng, stamp=stamps[k])
        est = positioner.update(scan, o)
        reasons.append(str(est.reason))
    after = signatures()
    new = {k: sorted(set(after[k]) - set(before.get(k, []))) for k in after}
    print(json.dumps({
        "new": {k: v for k, v in new.items() if v},
        "twice": sorted(k for k, v in after.items() if len(v) > 1),
        "jumps": positioner.odometry_jumps,
        "reasons": reasons,
        "cold_before": cold_before,
        "cold_after": cold_after,
    }))
    """
)

#: whether a new process finds the cache cold
_COLD = "from fuzzypos.pipeline.warm import kernels_cold; print(kernels_cold())"


_WARM_TEST = "test_after_warm_up_no_path_of_update_compiles_a_kernel"


def start_in_background(config: pytest.Config) -> None:
    """Start the fresh-cache drive as the session starts (``conftest.py`` calls this once the
    test is collected): compiling every kernel from an empty cache takes a minute or more, on
    a core the rest of the session leaves free where the machine has two."""
    folder = tempfile.mkdtemp(prefix="fuzzypos-warm-")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "NUMBA_CACHE_DIR": folder}
    proc = subprocess.Popen(
        [sys.executable, "-c", _SCRIPT], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, env=env,
    )  # fmt: skip
    config.stash[_BACKGROUND] = (proc, folder)


def stop_in_background(config: pytest.Config) -> None:
    """Kill the drive if the session ends before its test asked for it, and drop its cache."""
    proc, folder = config.stash.get(_BACKGROUND, (None, None))
    if proc is not None:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        shutil.rmtree(folder, ignore_errors=True)


_BACKGROUND = pytest.StashKey[tuple]()


@pytest.mark.skipif(not compiled(), reason="the compiled kernels are off (FUZZYPOS_KERNELS)")
def test_after_warm_up_no_path_of_update_compiles_a_kernel(request) -> None:
    # an empty cache of its own: a kernel loaded from the cache holds the kernels it calls,
    # whose own types are then never looked at (the test session's cache would hide a kernel
    # that a compiled caller compiles for other types than Python's calls do)
    if _BACKGROUND not in request.config.stash:  # the hook in conftest.py did not start it
        start_in_background(request.config)
    proc, folder = request.config.stash[_BACKGROUND]
    stdout, stderr = proc.communicate(timeout=900)
    assert proc.returncode == 0, stderr[-2000:]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "NUMBA_CACHE_DIR": folder}
    out = json.loads(stdout.strip().splitlines()[-1])
    assert out["jumps"] == 1  # the drive took the wide search's path
    assert "standing still" in out["reasons"], out["reasons"]
    assert out["new"] == {}, f"compiled after warm_up: {out['new']}"
    # one compiled version of each kernel: the update hands every kernel the same types (a
    # read-only array where it is otherwise writable would compile it, and its callees, again)
    assert out["twice"] == [], f"compiled for two sets of types: {out['twice']}"
    # the cold cache was told (before warm_up), the warm one is not, in the next process too
    assert out["cold_before"] is True and out["cold_after"] is False
    again = subprocess.run(
        [sys.executable, "-c", _COLD], capture_output=True, text=True, env=env, timeout=600
    )
    assert again.returncode == 0, again.stderr[-2000:]
    assert again.stdout.strip().splitlines()[-1] == "False"


def test_every_kernels_cache_is_keyed_on_every_kernel_modules_source() -> None:
    """numba keys a kernel's disk cache on its own module's source, while the code it caches
    holds the kernels it calls from other modules: each kernel's cache index carries the
    stamp of every kernel module's source too (numba/numba#1833), on the numba installed."""
    import importlib
    import pkgutil

    import fuzzypos._kernels
    from fuzzypos._kernels._jit import sources_stamp

    stamp = sources_stamp()
    seen = 0
    for info in pkgutil.iter_modules(fuzzypos._kernels.__path__):
        module = importlib.import_module(f"fuzzypos._kernels.{info.name}")
        for name, value in vars(module).items():
            if hasattr(value, "py_func") and getattr(value.py_func, "__module__", "") == (
                module.__name__
            ):
                own = value._cache._cache_file._source_stamp
                assert isinstance(own, tuple) and own[1] == stamp, f"{info.name}.{name}"
                seen += 1
    assert seen > 50


def test_the_sources_stamp_changes_with_any_kernel_module(tmp_path) -> None:
    from fuzzypos._kernels._jit import sources_stamp

    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "b.py").write_text("y = 2\n")
    before = sources_stamp(tmp_path)
    (tmp_path / "b.py").write_text("y = 3\n")
    sources_stamp.cache_clear()
    assert sources_stamp(tmp_path) != before
    (tmp_path / "b.py").write_text("y = 2\n")
    sources_stamp.cache_clear()
    assert sources_stamp(tmp_path) == before


def test_a_runs_speed_figures_leave_out_the_kernels_compiling(tmp_path, monkeypatch) -> None:
    """``run_log`` compiles the kernels before its clock starts: a warm-up of 2 s is in
    ``compile_seconds``, not in the positioner's or the loop's seconds."""
    from fuzzypos.jobs import run_log
    from fuzzypos.pipeline import warm
    from helpers import write_sim_log

    warm.compile_kernels()  # the kernels really compiled (or loaded) in this process first
    path = tmp_path / "sim.clf"
    write_sim_log(path)

    def slow_warm_up(config=None, *, in_map=False) -> float:
        time.sleep(2.0)
        return 2.0

    monkeypatch.setattr(warm, "compiled", lambda: True)
    monkeypatch.setattr(warm, "_compiled_in", {})  # as in a new process
    monkeypatch.setattr(warm, "warm_up", slow_warm_up)
    res = run_log(path, results_dir=tmp_path / "res", plot=False, hash_input=False)
    s = json.loads((tmp_path / "res" / "summary.json").read_text())
    assert 2.0 <= s["compile_seconds"] < 3.0 and res.compile_seconds == s["compile_seconds"]
    assert s["positioner_seconds"] < 1.0 and s["seconds"] < 1.5, s
    assert s["positioner_ms_per_scan"] < 1000.0 / s["scans"], s
    # once per process: the next run compiles nothing
    again = run_log(path, results_dir=tmp_path / "again", plot=False, hash_input=False)
    assert again.summary["compile_seconds"] == 0.0


def test_the_map_kernels_are_warmed_for_localisation_only(monkeypatch) -> None:
    """``warm_up`` compiles localisation's kernels (:data:`warm.MAP_KERNELS`) only with
    ``in_map`` (``fuzzypos localize``): a first ``fuzzypos run`` does not wait for them."""
    import importlib

    from fuzzypos._kernels import compiled
    from fuzzypos.pipeline import warm

    if not compiled():
        pytest.skip("the compiled kernels are off (NUMBA_DISABLE_JIT)")
    called: list[str] = []
    for name in warm.MAP_KERNELS:
        module = importlib.import_module(f"fuzzypos._kernels.{name}")
        monkeypatch.setattr(module, "warm", lambda name=name: called.append(name))
    warm.warm_up()
    assert called == []
    warm.warm_up(in_map=True)
    assert sorted(called) == sorted(warm.MAP_KERNELS)
