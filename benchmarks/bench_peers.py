"""The peers side by side: fuzzypos's default against small_gicp (GICP, PLANE_ICP) and
kiss-icp on the shared logs, all scored with the benchmark's relations metric, with the
time per scan of each measured in the same process.

    OMP_NUM_THREADS=1 python benchmarks/bench_peers.py [--data ../shared/data]
        [--logs intel,aces,sim180,sim360,intel-thin-0.5,…] [--max-scans N] [--json OUT.json]
        [--rounds N]

``sim180`` and ``sim360`` are simulated logs (``simulated_log``: the demo's gym, three laps,
180 or 360 beams), written as CARMEN logs with relations from the truth before the runs: the
shared logs have 180 beams, and issue 12 asks for the time on 360 too. ``LOG-thin-0.5`` and
``LOG-thin-1`` (LOG one of intel, aces, fr079, fr-clinic) are the shared log thinned as
``bench_thinned.py`` thins it (its relations' end scans and a scan every 0.5 m / 10°, or
1 m / 20°, of odometry: large steps between scans, issue 34), written before the runs and
scored on the log's relations.

The peers are optional (``pip install -e '.[bench]'``); a peer that is not installed is
skipped with a note. Every run reads the log afresh with
``fuzzypos.io.logs.open_log(path).records()``, in file order, one thread.

- **fuzzypos**: ``Positioner()`` (the default), ``update(scan, odometry)``.
- **small_gicp** (GICP, PLANE_ICP): each scan's valid points in the robot frame
  (``scan.points_robot()``, i.e. through ``sensor_pose``) extruded into three layers at
  z = −7.5, 0, +7.5 cm, so that every 2D neighbourhood is a vertical plane; normals and
  covariances from the 10 nearest neighbours; registered against a keyframe renewed once the
  estimate is 1 m or 30° from it. The initial guess is the odometry increment composed onto
  the last estimate, relative to the keyframe. Scan to scan (GICP): the keyframe is renewed
  at every scan. A match with fewer than 20 % of the scan's points as inliers keeps the
  initial guess (counted as a fallback).
- **kiss-icp**: its ``KissICP`` pipeline (``load_config(None)``: default voxel size =
  max_range / 100 = 1 m; or 0.1 m voxels) on the same extruded points, deskewing off (a 2D
  scan has no per-point stamps), one thread. ``register_frame(frame, timestamps)`` takes no
  initial guess in 1.3.0: it predicts ``last_pose @ last_delta`` (constant velocity), so the
  odometry increment is fed as its prediction by setting ``last_delta`` before each call;
  one run keeps its own constant-velocity model for comparison.

3D poses are projected to (x, y, yaw). Times (``time.perf_counter``): "matcher" is the
matcher call alone (``Positioner.update``, which for fuzzypos includes its feature
extraction; small_gicp's ``align``; ``KissICP.register_frame``), "loop" the whole loop per
scan (reading and parsing the log, the points, normals and covariances, the keyframes).
fuzzypos's compiled kernels are compiled (or loaded from numba's disk cache) before the runs,
by ``fuzzypos.pipeline.warm.warm_up``, whose time is printed apart. After the table, the
ratios of this run: fuzzypos's ``Positioner.update`` per scan over small_gicp GICP's
``align`` (1 m / 30° keyframes) and over kiss-icp's ``register_frame`` (odometry, default
voxels), on the same scans (below 1: fuzzypos is faster). With ``--rounds N``, those ratios
again from N timing rounds per log (the main run's, then fuzzypos and the two peers run anew
one after the other, N − 1 times, in alternating order) and their median: the machine's
speed drifts over a run, and a round's two times lie minutes apart, not the run's length.
"""

from __future__ import annotations

import os

# One thread everywhere, before numpy and the peers load their thread pools.
for _var in (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import datetime  # noqa: E402
import importlib.metadata  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from fuzzypos import LaserScan, Pose2D, Positioner, __version__  # noqa: E402
from fuzzypos.eval import EvaluationError, relations_errors  # noqa: E402
from fuzzypos.io import open_log, read_relations  # noqa: E402
from fuzzypos.io.provenance import git_hash, write_json  # noqa: E402
from fuzzypos.pipeline.warm import warm_up  # noqa: E402

sys.path.insert(0, os.fspath(Path(__file__).resolve().parent))
import thinning  # noqa: E402

try:
    import small_gicp
except ImportError:  # optional peer
    small_gicp = None
try:
    from kiss_icp.config import load_config as kiss_load_config
    from kiss_icp.kiss_icp import KissICP
except ImportError:  # optional peer
    KissICP = None

INSTALL_HINT = "pip install -e '.[bench]'"

#: the layers the 2D points are extruded into (m)
LAYERS_Z = (-0.075, 0.0, 0.075)
#: keyframe renewal: distance (m) and rotation (rad) from the keyframe
KEYFRAME_DISTANCE = 1.0
KEYFRAME_ANGLE = math.radians(30.0)
#: small_gicp settings
GICP_NEIGHBORS = 10
GICP_MAX_CORRESPONDENCE = 0.5
GICP_MAX_ITERATIONS = 30
#: a match with fewer inliers than this share of the scan's points keeps the initial guess
MIN_INLIER_SHARE = 0.2

LOGS = {"intel": "intel/intel.clf.gz", "aces": "aces/aces.clf.gz"}
#: simulated logs, by name: their beam count (180° field of view; see simulated_log)
SIMULATED = {"sim180": 180, "sim360": 360}
#: the simulated logs' relations: every RELATION_STEP-th scan to the one RELATION_LOCAL
#: scans on (local), and RELATION_LONG pairs drawn at random (a fixed seed) over the run, the
#: earlier scan first (the metric counts a relation with t2 < t1 as local)
RELATION_STEP, RELATION_LOCAL, RELATION_LONG = 5, 10, 300


# -- SE(2) / SE(3) helpers -------------------------------------------------------------------
def compose(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple:
    """``a ⊕ b``."""
    c, s = math.cos(a[2]), math.sin(a[2])
    th = a[2] + b[2]
    return (
        a[0] + c * b[0] - s * b[1],
        a[1] + s * b[0] + c * b[1],
        math.atan2(math.sin(th), math.cos(th)),
    )


def relative(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple:
    """``⊖a ⊕ b``: ``b`` in the frame of ``a``."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    th = b[2] - a[2]
    return (c * dx + s * dy, -s * dx + c * dy, math.atan2(math.sin(th), math.cos(th)))


def to_matrix(p: tuple[float, float, float]) -> np.ndarray:
    """The 4×4 homogeneous matrix of a planar pose."""
    c, s = math.cos(p[2]), math.sin(p[2])
    m = np.eye(4)
    m[0, 0], m[0, 1], m[1, 0], m[1, 1] = c, -s, s, c
    m[0, 3], m[1, 3] = p[0], p[1]
    return m


def from_matrix(m: np.ndarray) -> tuple[float, float, float]:
    """A 4×4 pose projected to (x, y, yaw)."""
    return (float(m[0, 3]), float(m[1, 3]), math.atan2(float(m[1, 0]), float(m[0, 0])))


def pose_tuple(p: Pose2D | None) -> tuple[float, float, float] | None:
    return None if p is None else (p.x, p.y, p.theta)


def extruded_points(scan: LaserScan) -> np.ndarray:
    """The scan's valid points in the robot frame, three layers of them, ``(3n, 3)``."""
    xy = scan.points_robot()[scan.valid]
    n = xy.shape[0]
    out = np.empty((n * len(LAYERS_Z), 3))
    for k, z in enumerate(LAYERS_Z):
        out[k * n : (k + 1) * n, :2] = xy
        out[k * n : (k + 1) * n, 2] = z
    return out


# -- the methods -------------------------------------------------------------------------
class Method:
    """One way of positioning the robot along a log, scan by scan."""

    name = ""

    def __init__(self) -> None:
        self.matcher_seconds = 0.0
        self.fallbacks = 0

    def settings(self) -> dict[str, Any]:
        return {}

    def start(self, odom: tuple[float, float, float] | None) -> None:
        raise NotImplementedError

    def step(self, scan: LaserScan, odom: Pose2D | None) -> tuple[float, float, float]:
        raise NotImplementedError


class FuzzyposDefault(Method):
    name = "fuzzypos default"

    def start(self, odom: tuple[float, float, float] | None) -> None:
        self.pos = Positioner()

    def step(self, scan: LaserScan, odom: Pose2D | None) -> tuple[float, float, float]:
        t0 = time.perf_counter()
        est = self.pos.update(scan, odom)
        self.matcher_seconds += time.perf_counter() - t0
        self.fallbacks += bool(est.degraded)
        p = est.pose
        return (p.x, p.y, p.theta)


class PointPeer(Method):
    """A peer fed the extruded points and the odometry increment."""

    def start(self, odom: tuple[float, float, float] | None) -> None:
        self.pose = odom if odom is not None else (0.0, 0.0, 0.0)
        self.last_odom = odom
        self.first = True

    def step(self, scan: LaserScan, odom: Pose2D | None) -> tuple[float, float, float]:
        o = pose_tuple(odom)
        inc = (0.0, 0.0, 0.0)
        if o is not None and self.last_odom is not None:
            inc = relative(self.last_odom, o)
        if o is not None:
            self.last_odom = o
        self.pose = self.register(extruded_points(scan), inc)
        self.first = False
        return self.pose

    def register(self, pts: np.ndarray, inc: tuple[float, float, float]) -> tuple:
        raise NotImplementedError


class SmallGicp(PointPeer):
    """small_gicp against a keyframe (renewed every 1 m / 30°, or every scan)."""

    def __init__(self, registration_type: str, scan_to_scan: bool = False) -> None:
        super().__init__()
        self.registration_type = registration_type
        self.scan_to_scan = scan_to_scan
        kf = "scan to scan" if scan_to_scan else "1 m / 30° keyframes"
        self.name = f"small_gicp {registration_type}, {kf}"

    def settings(self) -> dict[str, Any]:
        return {
            "registration_type": self.registration_type,
            "keyframe_distance_m": 0.0 if self.scan_to_scan else KEYFRAME_DISTANCE,
            "keyframe_angle_deg": 0.0 if self.scan_to_scan else math.degrees(KEYFRAME_ANGLE),
            "layers_z_m": LAYERS_Z,
            "num_neighbors": GICP_NEIGHBORS,
            "max_correspondence_distance_m": GICP_MAX_CORRESPONDENCE,
            "max_iterations": GICP_MAX_ITERATIONS,
            "min_inlier_share": MIN_INLIER_SHARE,
            "num_threads": 1,
            "initial_guess": "odometry increment composed onto the last estimate",
        }

    def start(self, odom: tuple[float, float, float] | None) -> None:
        super().start(odom)
        self.kf: tuple[Any, Any] | None = None
        self.kf_pose = self.pose

    def register(self, pts: np.ndarray, inc: tuple[float, float, float]) -> tuple:
        pred = compose(self.pose, inc)
        if pts.shape[0] < 3 * len(LAYERS_Z):
            self.fallbacks += not self.first
            return pred
        cloud = small_gicp.PointCloud(pts)
        tree = small_gicp.KdTree(cloud, num_threads=1)
        small_gicp.estimate_normals_covariances(
            cloud, tree, num_neighbors=GICP_NEIGHBORS, num_threads=1
        )
        if self.kf is None:
            self.kf, self.kf_pose = (cloud, tree), pred
            return pred
        init = relative(self.kf_pose, pred)
        t0 = time.perf_counter()
        res = small_gicp.align(
            self.kf[0],
            cloud,
            self.kf[1],
            init_T_target_source=to_matrix(init),
            registration_type=self.registration_type,
            max_correspondence_distance=GICP_MAX_CORRESPONDENCE,
            num_threads=1,
            max_iterations=GICP_MAX_ITERATIONS,
        )
        self.matcher_seconds += time.perf_counter() - t0
        if res.num_inliers >= MIN_INLIER_SHARE * pts.shape[0]:
            rel = from_matrix(res.T_target_source)
        else:
            rel = init
            self.fallbacks += 1
        pose = compose(self.kf_pose, rel)
        if (
            self.scan_to_scan
            or math.hypot(rel[0], rel[1]) >= KEYFRAME_DISTANCE
            or abs(rel[2]) >= KEYFRAME_ANGLE
        ):
            self.kf, self.kf_pose = (cloud, tree), pose
        return pose


class Kiss(PointPeer):
    """kiss-icp's ``KissICP`` pipeline, predicting with the odometry or its own model."""

    def __init__(self, voxel_size: float | None, odometry: bool = True) -> None:
        super().__init__()
        self.voxel_size = voxel_size
        self.odometry = odometry
        vox = "default voxels" if voxel_size is None else f"{voxel_size:g} m voxels"
        pred = "odometry" if odometry else "constant velocity"
        self.name = f"kiss-icp, {pred}, {vox}"

    def settings(self) -> dict[str, Any]:
        return {
            "voxel_size_m": self.config.mapping.voxel_size,
            "prediction": "odometry increment (last_delta)" if self.odometry else "own model",
            "layers_z_m": LAYERS_Z,
            "deskew": False,
            "max_num_threads": 1,
            "config": self.config.model_dump(),
        }

    def start(self, odom: tuple[float, float, float] | None) -> None:
        super().start(odom)
        cfg = kiss_load_config(None)
        if self.voxel_size is not None:
            cfg.mapping.voxel_size = self.voxel_size
        cfg.data.deskew = False
        cfg.registration.max_num_threads = 1
        self.config = cfg
        self.kiss = KissICP(cfg)
        self.origin = self.pose
        self.no_stamps = np.empty(0)

    def register(self, pts: np.ndarray, inc: tuple[float, float, float]) -> tuple:
        if self.odometry:
            self.kiss.last_delta = to_matrix(inc)
        if pts.shape[0] == 0:  # nothing to match: move by the prediction
            self.fallbacks += not self.first
            new = self.kiss.last_pose @ self.kiss.last_delta
            self.kiss.last_delta = np.linalg.inv(self.kiss.last_pose) @ new
            self.kiss.last_pose = new
        else:
            t0 = time.perf_counter()
            self.kiss.register_frame(pts, self.no_stamps)
            self.matcher_seconds += time.perf_counter() - t0
        return compose(self.origin, from_matrix(self.kiss.last_pose))


def make_methods() -> tuple[list[Method], list[str]]:
    """The methods to run, and notes on the peers that are missing."""
    methods: list[Method] = [FuzzyposDefault()]
    notes: list[str] = []
    if small_gicp is not None:
        methods += [
            SmallGicp("GICP"),
            SmallGicp("PLANE_ICP"),
            SmallGicp("GICP", scan_to_scan=True),
        ]
    else:
        notes.append(f"small_gicp is not installed (skipped): {INSTALL_HINT}")
    if KissICP is not None:
        methods += [Kiss(None), Kiss(0.1), Kiss(0.1, odometry=False)]
    else:
        notes.append(f"kiss-icp is not installed (skipped): {INSTALL_HINT}")
    return methods, notes


# -- simulated logs ----------------------------------------------------------------------
def simulated_log(folder: Path, name: str) -> tuple[Path, Path]:
    """A simulated log of the kind issue 12 names beside the shared ones (360 beams: the
    shared logs have 180), written as a CARMEN log with its relations from the truth, so
    that every method reads it as it reads a real one: three laps of the demo's 4 m circle
    in the gym at 0.3 m/s (10 Hz, 2,514 scans), the demo's scanner (a SICK LMS200 in its 30 m
    mode, σ = 1 cm + 1 mm per metre) with ``SIMULATED[name]`` beams over 180°, the demo's slip
    (seed 0). Returns the log's and the relations' paths."""
    from fuzzypos import sim
    from fuzzypos.geometry import relative as relative_pose
    from fuzzypos.io import write_carmen
    from fuzzypos.jobs import DemoSettings

    settings = DemoSettings()
    scanner = dataclasses.replace(settings.scanner, n_beams=SIMULATED[name])
    path = sim.CommandedPath.circle(settings.radius, 3.0, settings.speed)
    run = sim.simulate_run(sim.gym(), path, scanner, settings.slip, 0)
    log = folder / f"{name}.clf"
    write_carmen(log, [(s, run.odometry_pose(k)) for k, s in enumerate(run.scans)])
    truth, stamps = run.true_poses, [s.stamp for s in run.scans]
    n = len(stamps)
    pairs = [(k, k + RELATION_LOCAL) for k in range(0, n - RELATION_LOCAL, RELATION_STEP)]
    drawn = np.random.default_rng(0).integers(0, n, size=(RELATION_LONG, 2))
    pairs += [(int(min(a, b)), int(max(a, b))) for a, b in drawn if a != b]  # t1 < t2
    lines = []
    for a, b in pairs:
        x, y, yaw = (float(v) for v in relative_pose(truth[a], truth[b]))
        lines.append(f"{float(stamps[a])!r} {float(stamps[b])!r} {x!r} {y!r} 0 0 0 {yaw!r}\n")
    relations = folder / f"{name}.relations"
    relations.write_text("".join(lines))
    return log, relations


# -- thinned logs ------------------------------------------------------------------------
def thinned_names() -> list[str]:
    """The thinned logs' names (``thinning.thinned_names``)."""
    return list(thinning.thinned_names())


# -- running and scoring -----------------------------------------------------------------
def run_method(method: Method, log_path: Path, max_scans: int | None) -> dict[str, Any]:
    """Run one method along a log: stamps, poses, odometry, timings."""
    stamps: list[float] = []
    poses: list[tuple[float, float, float]] = []
    odoms: list[tuple[float, float, float] | None] = []
    started = False
    t_loop = time.perf_counter()
    for k, rec in enumerate(open_log(log_path).records()):
        if max_scans is not None and k >= max_scans:
            break
        odom = pose_tuple(rec.odometry)
        if not started:
            method.start(odom)
            started = True
        poses.append(method.step(rec.scan, rec.odometry))
        stamps.append(rec.scan.stamp)
        odoms.append(odom)
    loop_seconds = time.perf_counter() - t_loop
    return {
        "stamps": np.array(stamps),
        "poses": np.array(poses, dtype=float).reshape(-1, 3),
        "odometry": odoms,
        "scans": len(stamps),
        "loop_seconds": loop_seconds,
        "matcher_seconds": method.matcher_seconds,
    }


def score(stamps: np.ndarray, poses: np.ndarray, relations: Any) -> dict[str, Any]:
    try:
        return dict(relations_errors(stamps, poses, relations).as_dict())
    except EvaluationError as exc:
        return {"not_scored": str(exc)}


def peer_versions() -> dict[str, str | None]:
    out: dict[str, str | None] = {"fuzzypos": __version__}
    for dist in ("small_gicp", "kiss-icp", "numpy"):
        try:
            out[dist] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            out[dist] = None
    return out


def fmt(row: dict[str, Any], key: str, digits: int) -> str:
    v = row.get(key)
    return "–" if v is None or not math.isfinite(v) else f"{v:.{digits}f}"


def print_table(rows: list[dict[str, Any]]) -> None:
    print(
        "| log | method | all trans m | all rot ° | local trans m / median | local rot ° "
        "| matcher ms/scan | loop ms/scan | × fuzzypos (matcher / loop) | fallbacks |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        if "not_scored" in r:
            metric = f"not scored: {r['not_scored']} | | | "
        else:
            metric = (
                f"{fmt(r, 'all_trans_mean_m', 3)}±{fmt(r, 'all_trans_std_m', 3)} | "
                f"{fmt(r, 'all_rot_mean_deg', 2)}±{fmt(r, 'all_rot_std_deg', 2)} | "
                f"{fmt(r, 'local_trans_mean_m', 3)} / {fmt(r, 'local_trans_median_m', 3)} | "
                f"{fmt(r, 'local_rot_mean_deg', 3)}±{fmt(r, 'local_rot_std_deg', 3)}"
            )
        ratio = "–"
        if r.get("matcher_ratio") is not None:
            ratio = f"{r['matcher_ratio']:.2f} / {r['loop_ratio']:.2f}"
        fb = "–" if r.get("fallbacks") is None else str(r["fallbacks"])
        print(
            f"| {r['log']} | {r['method']} | {metric} | {fmt(r, 'matcher_ms_per_scan', 2)} | "
            f"{fmt(r, 'loop_ms_per_scan', 2)} | {ratio} | {fb} |"
        )


#: the peers the ratios are taken against (method names as in the table)
RATIO_PEERS = ("small_gicp GICP, 1 m / 30° keyframes", "kiss-icp, odometry, default voxels")


def print_ratios(rows: list[dict[str, Any]]) -> None:
    """fuzzypos's matcher time per scan over each of RATIO_PEERS', per log (this run)."""
    print()
    print("fuzzypos Positioner.update time per scan over the peer's (this run, the same scans):")
    print()
    print("| log | fuzzypos ms/scan | peer | peer ms/scan | fuzzypos ÷ peer |")
    print("|---|---:|---|---:|---:|")
    for log in dict.fromkeys(r["log"] for r in rows):
        of_log = {r["method"]: r for r in rows if r["log"] == log}
        base = of_log.get(FuzzyposDefault.name)
        if base is None:
            continue
        for peer in RATIO_PEERS:
            if peer in of_log:
                f, p = base["matcher_ms_per_scan"], of_log[peer]["matcher_ms_per_scan"]
                print(f"| {log} | {f:.3f} | {peer} | {p:.3f} | {f / p:.2f} |")


def timing_rounds(
    log_path: Path, rounds: int, max_scans: int | None, first: dict[str, float]
) -> dict[str, list[float]]:
    """fuzzypos's matcher time per scan over each of RATIO_PEERS', round by round: the
    first round's the main run's (``first``: ms a scan by method), then ``rounds`` − 1 more,
    each running fuzzypos and the peers anew one after the other (fuzzypos first in the
    odd rounds, last in the even ones), so that a ratio's two times are taken minutes apart,
    not the whole run's length, on a machine whose speed drifts."""
    ratios: dict[str, list[float]] = {}
    for peer in RATIO_PEERS:
        if peer in first:
            ratios[peer] = [first[FuzzyposDefault.name] / first[peer]]
    for r in range(1, rounds):
        wanted = {FuzzyposDefault.name, *ratios}
        methods = [m for m in make_methods()[0] if m.name in wanted]
        if r % 2:
            methods.reverse()
        ms = {}
        for method in methods:
            run = run_method(method, log_path, max_scans)
            ms[method.name] = 1000.0 * run["matcher_seconds"] / max(run["scans"], 1)
        for peer in ratios:
            ratios[peer].append(ms[FuzzyposDefault.name] / ms[peer])
        print(f"{log_path.name}: timing round {r + 1} of {rounds}", file=sys.stderr)
    return ratios


def print_rounds(rounds: dict[str, dict[str, list[float]]]) -> None:
    """The ratios of :func:`timing_rounds`, per log and peer, and their median."""
    print()
    print("fuzzypos ÷ peer, round by round (each round's two times minutes apart), the median:")
    print()
    print("| log | peer | rounds | median |")
    print("|---|---|---|---:|")
    for log, by_peer in rounds.items():
        for peer, values in by_peer.items():
            each = ", ".join(f"{v:.2f}" for v in values)
            print(f"| {log} | {peer} | {each} | {statistics.median(values):.2f} |")


def main() -> None:
    here = Path(__file__).resolve().parent
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--data",
        default=os.environ.get("FUZZYPOS_DATA", os.fspath(here.parent.parent / "shared" / "data")),
        help="the shared data folder (default: ../shared/data beside the checkout)",
    )
    ap.add_argument(
        "--logs",
        default="intel,aces",
        help="comma-separated: intel, aces (shared), sim180, sim360 (simulated, see "
        "simulated_log), LOG-thin-0.5, LOG-thin-1 (a shared log thinned, see bench_thinned.py)",
    )
    ap.add_argument("--max-scans", type=int, default=None, help="the first N scans of each log")
    ap.add_argument("--json", type=Path, default=None, help="write the rows to this JSON file")
    ap.add_argument(
        "--rounds",
        type=int,
        default=1,
        help="time fuzzypos against the ratio peers this many times per log (the main run "
        "and rounds − 1 more, alternating) and print each round's ratio and the median",
    )
    args = ap.parse_args()
    if args.rounds < 1:
        sys.exit(f"--rounds: at least 1, got {args.rounds}")

    _, notes = make_methods()
    for note in notes:
        print(note, file=sys.stderr)
    names = [s.strip() for s in args.logs.split(",") if s.strip()]
    thinned = thinned_names()
    unknown = [n for n in names if n not in LOGS and n not in SIMULATED and n not in thinned]
    if unknown:
        known = ", ".join([*LOGS, *SIMULATED, *thinned])
        sys.exit(f"--logs: unknown log(s) {', '.join(unknown)} (known: {known})")
    scratch = tempfile.TemporaryDirectory(prefix="bench_peers_")

    print(f"fuzzypos: every compiled kernel ready in {warm_up():.2f} s", file=sys.stderr)
    rows: list[dict[str, Any]] = []
    rounds: dict[str, dict[str, list[float]]] = {}
    for name in names:
        if name in SIMULATED:
            log_path, rel_path = simulated_log(Path(scratch.name), name)
        elif name in thinned:
            log_path, rel_path = thinning.thinned_log(Path(scratch.name), Path(args.data), name)
        else:
            log_path = Path(args.data) / LOGS[name]
            rel_path = log_path.parent / f"{name}.relations"
        if not log_path.exists() or not rel_path.exists():
            sys.exit(f"{log_path}: missing (or its relations); see --data")
        relations = read_relations(rel_path)
        methods, _ = make_methods()
        log_rows: list[dict[str, Any]] = []
        for method in methods:
            t0 = time.perf_counter()
            run = run_method(method, log_path, args.max_scans)
            n = max(run["scans"], 1)
            row: dict[str, Any] = {"log": log_path.name, "method": method.name}
            row.update(score(run["stamps"], run["poses"], relations))
            row.update(
                scans=run["scans"],
                matcher_ms_per_scan=1000.0 * run["matcher_seconds"] / n,
                loop_ms_per_scan=1000.0 * run["loop_seconds"] / n,
                fallbacks=method.fallbacks,
                settings=method.settings(),
            )
            if isinstance(method, FuzzyposDefault):
                # the odometry of the same scans, scored alike
                odo = run["odometry"]
                if all(o is not None for o in odo):
                    orow: dict[str, Any] = {"log": log_path.name, "method": "odometry"}
                    orow.update(score(run["stamps"], np.array(odo, dtype=float), relations))
                    orow.update(scans=run["scans"], fallbacks=None)
                    log_rows.append(orow)
            log_rows.append(row)
            print(
                f"{log_path.name}: {method.name}: {run['scans']} scans in "
                f"{time.perf_counter() - t0:.1f} s",
                file=sys.stderr,
            )
        base = next((r for r in log_rows if r["method"] == FuzzyposDefault.name), None)
        for r in log_rows:
            if base is not None and "matcher_ms_per_scan" in r:
                r["matcher_ratio"] = r["matcher_ms_per_scan"] / base["matcher_ms_per_scan"]
                r["loop_ratio"] = r["loop_ms_per_scan"] / base["loop_ms_per_scan"]
        rows.extend(log_rows)
        if args.rounds > 1:
            timed = [r for r in log_rows if "matcher_ms_per_scan" in r]
            first = {r["method"]: r["matcher_ms_per_scan"] for r in timed}
            rounds[log_path.name] = timing_rounds(log_path, args.rounds, args.max_scans, first)

    print_table(rows)
    print_ratios(rows)
    if rounds:
        print_rounds(rounds)
    scratch.cleanup()
    for note in notes:
        print(f"\n{note}")
    if args.json is not None:
        write_json(
            args.json,
            {
                "date": datetime.datetime.now().isoformat(timespec="seconds"),
                "versions": peer_versions(),
                "git_hash": git_hash(),
                "data_dir": os.path.abspath(args.data),
                "max_scans": args.max_scans,
                "threads": 1,
                "rows": rows,
                "timing_rounds": rounds,
            },
        )


if __name__ == "__main__":
    main()
