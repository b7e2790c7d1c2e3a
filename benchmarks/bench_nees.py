"""How honest the covariances are: the normalised estimation error squared (NEES) of simulated
increments with known truth.

60 random motions (|t| <= 0.5 m, |θ| <= 20°) in ``sim.furnished_room(0)`` seen by a 180-beam
180° scanner (8 m) with range noise; the odometry increment is the true one with an error drawn
from the default odometry noise model, so the prior's covariance is true. For each motion the
NEES εᵀ Σ⁻¹ ε of the estimated increment (ε = ⊖ true ⊕ estimate, Σ = ``Estimate.covariance``)
is a draw of χ²(3) where the covariance is honest (median 2.37, 90th percentile 6.25). Prints
its median and 90th percentile per range noise, with the median σ and error.

    python benchmarks/bench_nees.py
"""

from __future__ import annotations

import math

import numpy as np

from fuzzypos import Config, Pose2D, Positioner, sim
from fuzzypos.geometry import compose, relative
from fuzzypos.pipeline import OdometryNoise

WORLD = sim.furnished_room(0)
N_TRIALS = 60
TRIAL_SEED = 20240601
NOISE_SEED = 7


def nees(config: Config, noise: float) -> np.ndarray:
    """Per motion: NEES, σ_x (m), σ_θ (rad), |translation error| (m), |rotation error| (rad)."""
    scanner = sim.ScannerModel(n_beams=180, range_max=8.0, range_noise_std=noise)
    trials = sim.random_motions(WORLD, scanner, N_TRIALS, TRIAL_SEED, odometry_error=(0.0, 0.0))
    model = OdometryNoise(config.odometry_noise)
    rows = []
    for i, trial in enumerate(trials):
        rng = np.random.default_rng((NOISE_SEED, i))
        odometry = compose(
            trial.increment, rng.multivariate_normal(np.zeros(3), model.covariance(trial.increment))
        )
        s0 = sim.simulate_scan(WORLD, trial.start, scanner, rng, stamp=0.0)
        s1 = sim.simulate_scan(WORLD, trial.end, scanner, rng, stamp=1.0)
        pos = Positioner(config)
        pos.update(s0, Pose2D())
        est = pos.update(s1, Pose2D.from_array(odometry))
        assert est.covariance is not None
        err = relative(trial.increment, est.increment.as_array())
        cov = est.covariance
        rows.append(
            (
                float(err @ np.linalg.solve(cov, err)),
                math.sqrt(cov[0, 0]),
                math.sqrt(cov[2, 2]),
                math.hypot(err[0], err[1]),
                abs(err[2]),
            )
        )
    return np.array(rows)


def main() -> None:
    print(f"NEES of {N_TRIALS} simulated increments (χ²(3): median 2.37, 90th percentile 6.25)")
    print()
    print("| range noise | NEES median | NEES 90th pct | σ_x mm | σ_θ ° | error mm | error ° |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for noise in (0.005, 0.01, 0.02):
        a = nees(Config(), noise)
        med = np.median(a, axis=0)
        print(
            f"| {noise * 100:.1f} cm | {med[0]:.2f} | {np.percentile(a[:, 0], 90):.2f} "
            f"| {1e3 * med[1]:.2f} | {math.degrees(med[2]):.3f} | {1e3 * med[3]:.2f} "
            f"| {math.degrees(med[4]):.3f} |"
        )


if __name__ == "__main__":
    main()
