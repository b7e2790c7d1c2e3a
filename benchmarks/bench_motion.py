"""Accuracy of single motions: the increment between two simulated scans, per configuration.

60 random motions (|t| <= 0.5 m, |θ| <= 20°) in ``sim.furnished_room(0)``, both poses seeing at
least two corners, a 180-beam 180° scanner (8 m), odometry off by up to ±7 cm per axis and ±5°
(the trials of ``tests/pipeline/test_positioner.py``). Prints the errors of odometry, the ``paper``
preset and the default, noise-free and with 1 cm range noise, as a table.

    python benchmarks/bench_motion.py
"""

from __future__ import annotations

import math

import numpy as np

from fuzzypos import Config, Pose2D, Positioner, sim
from fuzzypos.geometry import relative

WORLD = sim.furnished_room(0)
N_TRIALS = 60
TRIAL_SEED = 20240601  # the seeds of tests/pipeline/test_positioner.py
NOISE_SEED = 7


def errors(cfg: Config | None, noise: float) -> tuple[np.ndarray, np.ndarray, int]:
    """(translation errors m, rotation errors °, scans degraded); ``cfg=None``: odometry."""
    scanner = sim.ScannerModel(n_beams=180, range_max=8.0, range_noise_std=noise)
    trials = sim.random_motions(WORLD, scanner, N_TRIALS, TRIAL_SEED)
    t, r, degraded = [], [], 0
    for i, tr in enumerate(trials):
        if cfg is None:
            est = tr.odometry
        else:
            rng = np.random.default_rng((NOISE_SEED, i))
            s0 = sim.simulate_scan(WORLD, tr.start, scanner, rng, stamp=0.0)
            s1 = sim.simulate_scan(WORLD, tr.end, scanner, rng, stamp=1.0)
            pos = Positioner(cfg)
            pos.update(s0, Pose2D())
            e = pos.update(s1, Pose2D.from_array(tr.odometry))
            degraded += e.degraded
            est = e.increment.as_array()
        err = relative(tr.increment, est)
        t.append(math.hypot(err[0], err[1]))
        r.append(abs(math.degrees(err[2])))
    return np.array(t), np.array(r), degraded


def main() -> None:
    print(f"{N_TRIALS} motions in {WORLD.name}; translation mm / rotation °")
    print()
    print("| noise | estimate | mean | median | 90th pct | max | degraded |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for noise in (0.0, 0.01):
        for name, cfg in (
            ("odometry", None),
            ("paper", Config.preset("paper")),
            ("default", Config()),
        ):
            t, r, deg = errors(cfg, noise)
            cells = [
                f"{1e3 * f(t):.2f} / {f(r):.3f}"
                for f in (np.mean, np.median, lambda a: np.percentile(a, 90), np.max)
            ]
            label = "none" if noise == 0 else f"{noise * 100:.0f} cm"
            print(f"| {label} | {name} | " + " | ".join(cells) + f" | {deg} |")


if __name__ == "__main__":
    main()
