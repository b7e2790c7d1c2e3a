"""Helpers the test modules share (import them with ``from helpers import …``; pytest's default
``prepend`` import mode puts ``tests/`` on ``sys.path``): where the shared logs are
(:data:`DATA`), a small simulated CARMEN log (:func:`write_sim_log`), a relations file
(:func:`write_relations`), the compiled kernels against their numpy references
(:func:`numpy_kernels`, :func:`both`, :func:`compiled_and_staged`), ROS1/ROS2 bags written
with rosbags' writers (:func:`make_bag` with :func:`standard`'s scans and odometry),
pipes a thread fills (:func:`fifo_with`, :func:`pipe_with`), and a benchmark script as a
module (:func:`load_benchmark`)."""

from __future__ import annotations

import contextlib
import importlib.util
import math
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from fuzzypos import sim
from fuzzypos.geometry import compose, relative, wrap_angle
from fuzzypos.io import CarmenRecord, write_carmen
from fuzzypos.jobs import DemoSettings

# -- the shared logs ---------------------------------------------------------------------------
#: where the shared logs are: ``$FUZZYPOS_DATA``, else ``../shared/data`` beside the repository
#: (where CI and the workplace keep them); tests that need them skip where absent
_BESIDE = Path(__file__).resolve().parents[1].parent / "shared" / "data"
DATA = Path(os.environ.get("FUZZYPOS_DATA") or _BESIDE)

# -- the benchmarks ----------------------------------------------------------------------------
BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def load_benchmark(name: str) -> ModuleType:
    """``benchmarks/NAME.py`` as a module (not in ``sys.modules``), with the environment and
    ``sys.path`` its import may change (one thread for numpy; its own folder, for another
    benchmark it imports) put back afterwards."""
    saved_env, saved_path = dict(os.environ), list(sys.path)
    spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    finally:
        os.environ.clear()
        os.environ.update(saved_env)
        sys.path[:] = saved_path
    return module


# -- a simulated CARMEN log and relations ------------------------------------------------------
def write_sim_log(path: Path, *, laps: float = 0.15, seed: int = 1) -> sim.SimulatedRun:
    """A small simulated CARMEN log (FLASER with odometry, TRUEPOS with the truth)."""
    world = sim.world_by_name("office")
    commanded = sim.CommandedPath.circle(1.0, laps=laps, speed=0.3)
    run = sim.simulate_run(world, commanded, DemoSettings().scanner, sim.SlipModel(), seed)
    records = (
        CarmenRecord(scan, run.odometry_pose(k), run.true_pose(k))
        for k, scan in enumerate(run.scans)
    )
    write_carmen(path, records)
    return run


def write_relations(
    path: Path, stamps: np.ndarray, poses: np.ndarray, pairs: Sequence[tuple[int, int]]
) -> None:
    """A relations file: the motion of ``poses`` between each pair of scan indices."""
    lines = []
    for i, j in pairs:
        x, y, th = (float(v) for v in relative(poses[i], poses[j]))
        lines.append(f"{float(stamps[i])!r} {float(stamps[j])!r} {x!r} {y!r} 0 0 0 {th!r}")
    path.write_text("\n".join(lines) + "\n")


# -- bags --------------------------------------------------------------------------------------
SCAN = "sensor_msgs/msg/LaserScan"
ODOM = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"

N_BEAMS = 9
ANGLE_MIN = -1.2
ANGLE_INC = 0.3
RANGE_MAX = 10.0


# -- the analytic trajectory --------------------------------------------------------------
def truth(t: float) -> tuple[float, float, float]:
    """Linear in time (so linear interpolation is exact); θ crosses ±π at t ≈ 4.6 s."""
    return (0.5 * t - 1.0, 2.0 - 0.2 * t, float(wrap_angle(0.9 * t - 1.0)))


ODOM_T = [0.1 * k for k in range(1, 81)]  # 10 Hz, 0.1 … 8.0 s
SCAN_T = [0.05 + 0.37 * k for k in range(22)]  # ~2.7 Hz, 0.05 … 7.82 s: the first before odom


def scan_ranges(k: int) -> np.ndarray:
    r = (1.0 + 0.25 * np.arange(N_BEAMS) + 0.01 * k).astype(np.float32)
    r[1] = RANGE_MAX  # "no return"
    r[2] = np.inf
    r[3] = np.nan
    r[4] = 0.0
    return r


# -- writing bags -------------------------------------------------------------------------
class BagBuilder:
    """Messages for one ROS version: ``ros1`` (Noetic, serialize_ros1) or ``ros2`` (Humble, CDR)."""

    def __init__(self, ros: int) -> None:
        self.ros = ros
        self.store = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
        if TF not in self.store.types:  # Noetic's store lacks tf2_msgs
            self.store.register(
                get_types_from_msg("geometry_msgs/TransformStamped[] transforms", TF)
            )
        self.T = self.store.types

    def header(self, t: float, frame: str) -> Any:
        sec = math.floor(t)
        stamp = self.T["builtin_interfaces/msg/Time"](sec=sec, nanosec=round((t - sec) * 1e9))
        if self.ros == 1:
            return self.T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
        return self.T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def quat(self, yaw: float, roll: float = 0.0) -> Any:
        cr, sr = math.cos(roll / 2), math.sin(roll / 2)
        cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
        return self.T["geometry_msgs/msg/Quaternion"](x=sr * cy, y=sr * sy, z=cr * sy, w=cr * cy)

    def scan(self, t: float, ranges: np.ndarray, *, frame: str = "laser", **kw: float) -> Any:
        n = len(ranges)
        fields: dict[str, Any] = {
            "angle_min": ANGLE_MIN,
            "angle_max": ANGLE_MIN + (n - 1) * ANGLE_INC,
            "angle_increment": ANGLE_INC,
            "time_increment": 0.0,
            "scan_time": 0.1,
            "range_min": 0.0,
            "range_max": RANGE_MAX,
        }
        fields.update(kw)
        return self.T[SCAN](
            header=self.header(t, frame),
            ranges=np.asarray(ranges, dtype=np.float32),
            intensities=np.zeros(0, dtype=np.float32),
            **fields,
        )

    def odom(
        self, t: float, pose: Sequence[float], child: str = "base_link", frame: str = "odom"
    ) -> Any:
        T = self.T
        x, y, th = pose
        cov = np.zeros(36, dtype=np.float64)
        p = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=self.quat(th)
        )
        zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        return T[ODOM](
            header=self.header(t, frame),
            child_frame_id=child,
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=p, covariance=cov),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=cov
            ),
        )

    def tf(self, transforms: Sequence[tuple[str, str, float, float, float, float]]) -> Any:
        """``(parent, child, x, y, yaw, roll)`` each."""
        T = self.T
        out = []
        for parent, child, x, y, yaw, roll in transforms:
            out.append(
                T["geometry_msgs/msg/TransformStamped"](
                    header=self.header(0.01, parent),
                    child_frame_id=child,
                    transform=T["geometry_msgs/msg/Transform"](
                        translation=T["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.3),
                        rotation=self.quat(yaw, roll),
                    ),
                )
            )
        return T[TF](transforms=out)

    def serialize(self, msg: Any) -> bytes:
        typ = msg.__msgtype__
        if self.ros == 1:
            return bytes(self.store.serialize_ros1(msg, typ))
        return bytes(self.store.serialize_cdr(msg, typ))

    def write(self, path: Path, storage: str, messages: list[tuple[str, float, Any]]) -> Path:
        """Write ``(topic, record time, message)`` in the order given."""
        if self.ros == 1:
            writer: Any = Writer1(path)
        else:
            plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
            writer = Writer2(path, version=9, storage_plugin=plugin)
        conns: dict[str, Any] = {}
        with writer:
            for topic, t, msg in messages:
                if topic not in conns:
                    conns[topic] = writer.add_connection(
                        topic, msg.__msgtype__, typestore=self.store
                    )
                writer.write(conns[topic], round(t * 1e9), self.serialize(msg))
        return path


def make_bag(
    tmp_path: Path, kind: str, build: Callable[[BagBuilder], list[tuple[str, float, Any]]]
) -> Path:
    ros = 1 if kind == "ros1" else 2
    b = BagBuilder(ros)
    path = tmp_path / ("run.bag" if ros == 1 else "run_bag")
    return b.write(path, kind.partition("-")[2], build(b))


MOUNT = [  # base_link -> mount -> laser: x, y, yaw (roll 0)
    ("base_link", "laser_mount", 0.2, 0.05, 0.3, 0.0),
    ("laser_mount", "laser", 0.1, -0.02, 0.2, 0.0),
]
MOUNT_POSE = compose([0.2, 0.05, 0.3], [0.1, -0.02, 0.2])


def standard(
    b: BagBuilder,
    *,
    scan_topics: Sequence[str] = ("/scan",),
    odometry: bool = True,
    tf: Sequence[tuple[str, str, float, float, float, float]] | None = MOUNT,
) -> list[tuple[str, float, Any]]:
    """Scans and odometry interleaved by record time (record time = stamp + 5 ms)."""
    msgs: list[tuple[str, float, Any]] = []
    if tf is not None:
        msgs.append(("/tf_static", 0.0, b.tf(tf)))
    for k, t in enumerate(SCAN_T):
        for topic in scan_topics:
            msgs.append((topic, t + 0.005, b.scan(t, scan_ranges(k))))
    if odometry:
        msgs += [("/odom", t + 0.005, b.odom(t, truth(t))) for t in ODOM_T]
    msgs.sort(key=lambda m: m[1])
    return msgs


def odd_frames(b: BagBuilder) -> list:
    """A robot whose frames are not REP-105's names: odometry ``wheels`` → ``chassis``
    (and a few messages with another child), ``world`` → ``wheels`` on /tf, the laser
    mounted on the chassis."""
    msgs: list = [("/tf_static", 0.0, b.tf([("chassis", "laser_mount", *MOUNT[0][2:]),
                                             MOUNT[1]]))]  # fmt: skip
    for k, t in enumerate(SCAN_T):
        msgs.append(("/scan", t + 0.005, b.scan(t, scan_ranges(k))))
    for k, t in enumerate(ODOM_T):
        child = "chassis_old" if k % 10 == 5 else "chassis"
        msgs.append(("/wheel_odom", t + 0.005, b.odom(t, truth(t), child=child, frame="wheels")))
        if k % 4 == 0:
            msgs.append(("/tf", t + 0.006, b.tf([("/world", "wheels", 1.0, 2.0, 0.5, 0.0)])))
    msgs.sort(key=lambda m: m[1])
    return msgs


#: ScannerModel settings of a noise-free scanner (no noise, dropouts or spurious returns)
EXACT_SCANNER = {
    "range_noise_std": 0.0,
    "range_noise_per_metre": 0.0,
    "incidence_noise": 0.0,
    "dropout_probability": 0.0,
    "spurious_probability": 0.0,
}


# -- pipes -------------------------------------------------------------------------------------
@contextlib.contextmanager
def fifo_with(tmp_path: Path, data: bytes, name: str = "log.fifo") -> Iterator[Path]:
    """A named pipe (``os.mkfifo``) that a thread fills with ``data`` once, as a shell's
    ``<(zcat log.gz)`` would: a reader that opens it again later reads nothing (it does not
    hang)."""
    path = tmp_path / name
    os.mkfifo(path)
    stop = threading.Event()

    def feed() -> None:
        with open(path, "wb") as w:  # blocks until a reader opens the pipe
            w.write(data)
        while not stop.is_set():  # any later open: an empty stream
            with open(path, "wb"):
                pass
            time.sleep(0.01)

    writer = threading.Thread(target=feed, daemon=True)
    writer.start()
    try:
        yield path
    finally:
        stop.set()
        while writer.is_alive():  # let a writer blocked in open() through
            os.close(os.open(path, os.O_RDONLY | os.O_NONBLOCK))
            writer.join(0.05)


@contextlib.contextmanager
def pipe_with(data: bytes) -> Iterator[Path]:
    """An anonymous pipe filled with ``data`` by a thread, as the path ``/dev/fd/N`` (what
    ``<(…)`` and ``/dev/stdin`` are): every open of it reads the same pipe, once."""
    r, w = os.pipe()

    def feed() -> None:
        with os.fdopen(w, "wb") as f:
            f.write(data)

    writer = threading.Thread(target=feed, daemon=True)
    writer.start()
    try:
        yield Path(f"/dev/fd/{r}")
    finally:
        writer.join(5)
        os.close(r)


# -- the compiled kernels and their references -------------------------------------------
@contextlib.contextmanager
def numpy_kernels() -> Iterator[None]:
    """The numpy references (``tests/oracles``) in place of the compiled kernels' callers,
    for the duration."""
    from oracles import references

    with references():
        yield


def both(call: Callable[[], Any]) -> tuple[Any, Any]:
    """``call()`` with the compiled kernels, then with the numpy references."""
    compiled = call()
    with numpy_kernels():
        reference = call()
    return compiled, reference


def compiled_and_staged(scan: Any, cfg: Any) -> tuple[Any, Any]:
    """A scan's features from the one compiled call and from the staged chain (the compiled
    call switched off for it)."""
    import pytest

    from fuzzypos.features import extract as features_module

    compiled = features_module._extract_compiled(scan, features_module.rule_bases(cfg.fuzzy), cfg)
    assert compiled is not None
    with pytest.MonkeyPatch.context() as m:
        m.setattr(features_module, "_extract_compiled", lambda *args: None)
        staged = features_module.extract_features(scan, cfg)
    return compiled, staged


# -- the command line ---------------------------------------------------------------------------
def invoke(args: list[str], code: int) -> list[str]:
    """``fuzzypos ARGS`` through typer's runner: the non-blank lines of the output, after
    checking the exit code ``code`` and that no traceback was printed."""
    from typer.testing import CliRunner

    from fuzzypos.cli import app

    res = CliRunner().invoke(app, args)
    assert res.exit_code == code, (args, res.output, res.exception)
    assert "Traceback" not in res.output
    return [ln for ln in res.output.splitlines() if ln.strip()]


def one_line_error(args: list[str], *expect: str) -> str:
    """``fuzzypos ARGS`` fails with exit 2 and one line ``fuzzypos: error: …`` holding every
    text in ``expect``."""
    lines = invoke(args, 2)
    assert len(lines) == 1 and lines[0].startswith("fuzzypos: error: "), lines
    for text in expect:
        assert text in lines[0], (text, lines[0])
    return lines[0]


# -- a simulated world's map, as map_server saves one ------------------------------------------
def world_cells(world: sim.World, resolution: float, margin: float = 0.5) -> tuple[Any, Any]:
    """The occupancy of ``world`` on a grid of ``resolution`` (m): ``(occupied, origin)``,
    ``occupied`` a bool array with rows from the bottom (a cell is occupied where a wall
    passes within half a diagonal of its centre), ``origin`` the lower-left corner (x, y)."""
    x0, y0, x1, y1 = world.bounds
    lo = np.array([x0 - margin, y0 - margin])
    cols = math.ceil((x1 + margin - lo[0]) / resolution)
    rows = math.ceil((y1 + margin - lo[1]) / resolution)
    u = lo[0] + (np.arange(cols) + 0.5) * resolution
    v = lo[1] + (np.arange(rows) + 0.5) * resolution
    centres = np.stack(np.meshgrid(u, v), axis=-1)
    occupied = world.distance(centres) <= resolution * math.sqrt(0.5)
    return occupied, (float(lo[0]), float(lo[1]))


def write_world_map(
    folder: Path,
    world: sim.World,
    resolution: float = 0.05,
    *,
    negate: bool = False,
    name: str = "map",
    yaw: float = 0.0,
) -> tuple[Path, Any, tuple[float, float]]:
    """``name.pgm`` and ``name.yaml`` of ``world`` (:func:`world_cells`) as map_server saves
    them (occupied 0, free 254; white and black swapped with ``negate``), the origin's yaw
    ``yaw`` in the yaml (the grid's position is that of ``yaw`` 0): ``(yaml, occupied,
    origin)``."""
    occupied, origin = world_cells(world, resolution)
    img = np.where(occupied, 0, 254).astype(np.uint8)[::-1]
    if negate:
        img = 255 - img
    h, w = img.shape
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{name}.pgm").write_bytes(f"P5\n{w} {h}\n255\n".encode() + img.tobytes())
    yaml_path = folder / f"{name}.yaml"
    yaml_path.write_text(
        f"image: {name}.pgm\nresolution: {resolution!r}\n"
        f"origin: [{origin[0]!r}, {origin[1]!r}, {yaw!r}]\nnegate: {int(negate)}\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n",
        encoding="utf-8",
    )
    return yaml_path, occupied, origin
