"""Scans per second of ``extract_features`` and ``Positioner.update`` on one thread.

``extract_features`` is timed with every stage run, the point features included (the library
computes those on first use; the positioner needs them only where line matching gives no
motion, so ``update`` can be faster than the full extraction).

Simulated office (``fuzzypos.sim.office``), a robot driving down the corridor, 180-beam and
360-beam 180° scans with 1 cm range noise. Run with ``make bench`` or
``python benchmarks/bench_pipeline.py [--scans N] [--repeat R]``. Each figure is the best of R
passes over the scans (default 15): the fastest pass is what the code costs, slower ones are
the rest of the machine (on a shared 2-core virtual machine single passes vary by ±30 %).
``Positioner.update`` is timed with the compiled kernels (``fuzzypos._kernels``) and with
their pure-numpy references (the tests' oracles, ``tests/oracles``, put in the kernels' place).

First, in fresh processes: the time ``import fuzzypos`` takes, and the first call of every
compiled kernel (``fuzzypos.pipeline.warm.warm_up``) with an empty numba cache (compiling
them all, as a fresh install or CI does once) and again with that cache (loading them).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread, set before numpy loads

import argparse  # noqa: E402
import contextlib  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from fuzzypos import Config, Positioner, extract_features  # noqa: E402
from fuzzypos.geometry import Pose2D  # noqa: E402
from fuzzypos.pipeline.warm import warm_up  # noqa: E402
from fuzzypos.sim import ScannerModel, arc_path, drifting_odometry, office, simulate_scans  # noqa: E402


def _seconds(code: str, env: dict[str, str]) -> float:
    """The float ``code`` prints, run in a fresh Python process with ``env``."""
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    return float(out.stdout.strip().splitlines()[-1])


def first_calls() -> tuple[float, float, float]:
    """In fresh processes: ``import fuzzypos``, and every kernel's first call with an empty
    numba cache (compiling) and with the cache that left (loading)."""
    importing = (
        "import time; t = time.perf_counter(); import fuzzypos; print(time.perf_counter() - t)"
    )
    warming = "from fuzzypos.pipeline.warm import warm_up; print(warm_up())"
    with tempfile.TemporaryDirectory(prefix="fuzzypos-numba-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        seconds = (_seconds(importing, env), _seconds(warming, env), _seconds(warming, env))
    return seconds


def _update_seconds(scans, odom, cfg: Config, repeat: int, compiled: bool) -> float:
    """The fastest of ``repeat`` passes of ``Positioner.update`` over the scans (with the
    numpy references in the kernels' place where not ``compiled``)."""
    best = np.inf
    with contextlib.nullcontext() if compiled else _references():
        for _ in range(repeat):
            pos = Positioner(cfg)
            t0 = time.perf_counter()
            for s, o in zip(scans, odom):
                pos.update(s, o)
            best = min(best, time.perf_counter() - t0)
    return float(best)


def _references() -> contextlib.AbstractContextManager[None]:
    """The tests' numpy references (``tests/oracles``) in place of the compiled kernels."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from oracles import references

    return references()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scans", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args()
    importing, compiling, loading = first_calls()
    warm_up()
    world = office()
    truth = arc_path(Pose2D(-8.0, 0.0, 0.0), args.scans, step=0.05, turn_deg=0.0)
    odom = drifting_odometry(
        truth, scale=1.02, rotation_bias_deg=0.05, rng=np.random.default_rng(1)
    )
    rows = []
    for beams in (180, 360):
        scanner = ScannerModel(n_beams=beams, range_max=8.0, range_noise_std=0.01)
        scans = simulate_scans(world, truth, scanner, rng=np.random.default_rng(0))
        for preset in ("default", "paper"):
            cfg = Config.preset(preset)
            t_feat = []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                for s in scans:
                    # every stage, the point features too (they are computed on first use)
                    _ = extract_features(s, cfg).points_of_interest
                t_feat.append(time.perf_counter() - t0)
            t_upd = _update_seconds(scans, odom, cfg, args.repeat, compiled=True)
            t_ref = _update_seconds(scans, odom, cfg, args.repeat, compiled=False)
            n = len(scans)
            rows.append(
                (beams, preset, n / min(t_feat), 1e3 * min(t_feat) / n, n / t_upd,
                 1e3 * t_upd / n, 1e3 * t_ref / n)
            )  # fmt: skip
    print(
        "fuzzypos pipeline speed, one thread, "
        f"{platform.python_implementation()} {platform.python_version()}, numpy {np.__version__}"
    )
    print(f"import fuzzypos: {importing:.2f} s (compiles nothing)")
    print(
        f"first call of every compiled kernel: {compiling:.1f} s with an empty numba cache "
        f"(compiling), {loading:.2f} s from the cache"
    )
    print(f"{args.scans} scans of the simulated office, best of {args.repeat}")
    print()
    print(
        "| beams | config | extract_features scans/s | ms/scan "
        "| Positioner.update scans/s | ms/scan | numpy references ms/scan |"
    )
    print("|---:|---|---:|---:|---:|---:|---:|")
    for beams, preset, fs, fms, us, ums, rms in rows:
        print(f"| {beams} | {preset} | {fs:,.0f} | {fms:.2f} | {us:,.0f} | {ums:.2f} | {rms:.2f} |")


if __name__ == "__main__":
    main()
