"""The paper's experiment (§5), simulated: a B21r drives a circle in a gym on a slippery floor.

The odometry believes in the commanded circle while the robot, skidding outward, drives a
spiral; the positioner runs with the default configuration and with the ``paper`` preset, and
the figures of the paper are written: the stages of feature extraction on the 25th scan
(Figs. 13–18), the paths (Fig. 19) and the position error against the distance travelled
(Fig. 20), with ``summary.json``.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..config import Config
from ..eval.metrics import TrajectoryErrors, position_errors, trajectory_errors
from ..features import Features, extract_features
from ..pipeline import Positioner, warm
from ..sim import CommandedPath, ScannerModel, SimulatedRun, SlipModel, gym, simulate_run

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "FEATURE_SCAN_INDEX",
    "DemoResult",
    "DemoSettings",
    "errors_figure",
    "feature_scan",
    "paths_figure",
    "run_demo",
    "simulate_gym_circle",
]

FEATURE_SCAN_INDEX = 24  # the paper's 25th scan (Figs. 13–18), 0-based
PRESETS = ("paper", "default")

Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class DemoSettings:
    """The simulated experiment: a circle of ``radius`` m, ``laps`` times, at ``speed`` m/s
    round the middle of the gym, with the B21r slip defaults and a SICK LMS200-like scanner in
    its 30 m mode (the gym's walls are 11–15 m from the circle; σ = 1 cm + 1 mm per metre)."""

    radius: float = 4.0
    laps: float = 2.0
    speed: float = 0.3
    seed: int = 0
    slip: SlipModel = field(default_factory=SlipModel)
    scanner: ScannerModel = field(
        default_factory=lambda: ScannerModel.sick_lms200(
            range_max=30.0, range_noise_per_metre=0.001
        )
    )


@dataclass(frozen=True, eq=False)
class DemoResult:
    """What :func:`run_demo` computed: the run, each preset's estimated poses and the errors."""

    run: SimulatedRun
    estimates: dict[str, np.ndarray]
    degraded: dict[str, int]
    errors: dict[str, TrajectoryErrors]
    summary: dict[str, object]
    files: dict[str, Path]


def simulate_gym_circle(settings: DemoSettings = DemoSettings()) -> SimulatedRun:
    """The simulated run of the experiment (truth, odometry, scans)."""
    path = CommandedPath.circle(settings.radius, settings.laps, settings.speed)
    return simulate_run(gym(), path, settings.scanner, settings.slip, settings.seed)


def _estimate(
    run: SimulatedRun, config: Config, name: str, progress: Progress | None
) -> tuple[np.ndarray, int]:
    pos = Positioner(config)
    poses = np.empty((len(run), 3))
    degraded = 0
    for k, scan in enumerate(run.scans):
        est = pos.update(scan, run.odometry_pose(k))
        poses[k] = est.pose.as_array()
        degraded += est.degraded
        if progress is not None:
            progress(name, k + 1, len(run))
    return poses, degraded


def feature_scan(run: SimulatedRun) -> Features:
    """The features of the scan of Figs. 13–18 (the paper's 25th), with the default config."""
    return extract_features(run.scans[min(FEATURE_SCAN_INDEX, len(run) - 1)], Config())


def paths_figure(
    run: SimulatedRun, estimates: dict[str, np.ndarray], path: Path | None = None
) -> Figure:
    """Fig. 19: the true path, odometry and each preset's estimate in the gym."""
    from ..plot import figures as plot  # matplotlib only when figures are made

    return plot.plot_paths(
        run.true_poses,
        run.odometry_poses,
        estimates,
        path=path,
        world=run.world,
        title="Fig. 19 — true path, odometry and fuzzy-based positioning",
    )


def errors_figure(
    run: SimulatedRun, estimates: dict[str, np.ndarray], path: Path | None = None
) -> Figure:
    """Fig. 20: the position error of odometry and each preset against distance travelled."""
    from ..plot import figures as plot

    truth = run.true_poses
    curves = {"odometry": position_errors(truth, run.odometry_poses)[0]}
    curves.update({name: position_errors(truth, poses)[0] for name, poses in estimates.items()})
    return plot.plot_errors_vs_distance(
        run.distance_travelled,
        curves,
        path=path,
        title="Fig. 20 — position error against distance travelled",
    )


def run_demo(
    out_dir: str | Path,
    settings: DemoSettings = DemoSettings(),
    progress: Progress | None = None,
) -> DemoResult:
    """Simulate the gym circle, position the robot with both configurations, and write the
    paper's Figs. 13–20 and ``summary.json`` to ``out_dir``."""
    from ..plot import figures as plot  # matplotlib only when figures are made

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    run = simulate_gym_circle(settings)
    warm.compile_kernels()  # (where the caller has not: the figures' seconds are positioning's)
    estimates: dict[str, np.ndarray] = {}
    degraded: dict[str, int] = {}
    for name in PRESETS:
        estimates[name], degraded[name] = _estimate(run, Config.preset(name), name, progress)

    truth, odometry = run.true_poses, run.odometry_poses
    errors = {"odometry": trajectory_errors(truth, odometry, 0)}
    for name in PRESETS:
        errors[name] = trajectory_errors(truth, estimates[name], degraded[name])

    files: dict[str, Path] = {}
    index = min(FEATURE_SCAN_INDEX, len(run) - 1)
    figures = plot.plot_feature_figures(feature_scan(run), out, index, config=Config())
    for number, path in figures.items():
        files[f"fig{number}"] = path
    files["fig19"] = out / "fig19_paths.png"
    paths_figure(run, estimates, files["fig19"])
    files["fig20"] = out / "fig20_position_error.png"
    errors_figure(run, estimates, files["fig20"])
    summary: dict[str, object] = {
        "distance_travelled_m": float(run.distance_travelled[-1]),
        "scans": len(run),
        "odometry": errors["odometry"].as_dict(),
        "paper": errors["paper"].as_dict(),
        "default": errors["default"].as_dict(),
        "experiment": {
            "world": run.world.name,
            "path": run.path.name,
            "seed": settings.seed,
            "slip": {
                k: getattr(settings.slip, k)
                for k in (
                    "radial_gain",
                    "longitudinal",
                    "angular",
                    "translation_noise",
                    "rotation_noise",
                )
            },
            "scanner": {
                "beams": settings.scanner.n_beams,
                "range_max_m": settings.scanner.range_max,
                "rate_hz": settings.scanner.rate_hz,
            },
        },
    }
    files["summary"] = out / "summary.json"
    files["summary"].write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return DemoResult(run, estimates, degraded, errors, summary, files)
