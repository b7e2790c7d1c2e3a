"""Scans per second of ``extract_features`` and ``Positioner.update`` on one thread.

``extract_features`` is timed with every stage run, the point features included (the library
computes those on first use; the positioner needs them only where line matching gives no
motion, so ``update`` can be faster than the full extraction).

Simulated office (``fuzzypos.sim.office``), a robot driving down the corridor, 180-beam and
360-beam 180° scans with 1 cm range noise. Run with ``make bench`` or
``python benchmarks/bench_pipeline.py [--scans N] [--repeat R]``. Each figure is the best of R
passes over the scans (default 15): the fastest pass is what the code costs, slower ones are
the rest of the machine (on a shared 2-core virtual machine single passes vary by ±30 %).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread, set before numpy loads

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from fuzzypos import Config, Positioner, extract_features  # noqa: E402
from fuzzypos.geometry import Pose2D  # noqa: E402
from fuzzypos.sim import ScannerModel, arc_path, drifting_odometry, office, simulate_scans  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scans", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args()
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
            t_upd = []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                for s in scans:
                    # every stage, the point features too (they are computed on first use)
                    _ = extract_features(s, cfg).points_of_interest
                t_feat.append(time.perf_counter() - t0)
                pos = Positioner(cfg)
                t0 = time.perf_counter()
                for s, o in zip(scans, odom):
                    pos.update(s, o)
                t_upd.append(time.perf_counter() - t0)
            n = len(scans)
            rows.append(
                (
                    beams,
                    preset,
                    n / min(t_feat),
                    1e3 * min(t_feat) / n,
                    n / min(t_upd),
                    1e3 * min(t_upd) / n,
                )
            )
    print(
        "fuzzypos pipeline speed, one thread, "
        f"{platform.python_implementation()} {platform.python_version()}, numpy {np.__version__}"
    )
    print(f"{args.scans} scans of the simulated office, best of {args.repeat}")
    print()
    print(
        "| beams | config | extract_features scans/s | ms/scan "
        "| Positioner.update scans/s | ms/scan |"
    )
    print("|---:|---|---:|---:|---:|---:|")
    for beams, preset, fs, fms, us, ums in rows:
        print(f"| {beams} | {preset} | {fs:,.0f} | {fms:.2f} | {us:,.0f} | {ums:.2f} |")


if __name__ == "__main__":
    main()
