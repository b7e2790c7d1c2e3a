"""Running the positioner over a log and keeping the results; scoring trajectories; the
benchmark over the shared logs.

- :func:`run_log` streams a log (:func:`fuzzypos.logs.open_log`) through a
  :class:`~fuzzypos.positioner.Positioner` and writes a results folder:

  ================  ==========================================================================
  ``trajectory.tum``  the estimated pose of every scan, ``t x y z qx qy qz qw``, one line per
                      scan in file order, ``t`` the scan's stamp as the log gives it at full
                      precision (``repr``, never rounded: intel has scans < 2 ms apart)
  ``trajectory.clf``  the log again as CARMEN ``FLASER`` lines (:func:`write_estimate_clf`):
                      the ``x y θ`` fields carry the estimate, ``odom_x odom_y odom_θ`` the
                      log's odometry; ``TRUEPOS`` lines where the log had truth
  ``config.toml``     the configuration used (:meth:`~fuzzypos.config.Config.to_toml`; it
                      loads back with :meth:`~fuzzypos.config.Config.from_toml`)
  ``path.png``        the estimated path and the odometry over a map of every
                      ``map_every``-th scan's points placed by the estimate
  ``summary.json``    what ran on what, how fast, and how well (:func:`run_log`)
  ================  ==========================================================================

  Memory stays small on long logs: only the stamps and poses (estimate, odometry, truth)
  and the points of every ``map_every``-th scan are kept, never the scans.
- :func:`evaluate_trajectory` scores a TUM trajectory against relations and/or a reference.
- :func:`find_benchmark_logs` / :func:`run_benchmark`: every log with a relations file next
  to it, run with the raw odometry, the ``paper`` preset and the ``default`` configuration.
"""

from __future__ import annotations

import errno
import hashlib
import json
import math
import os
import subprocess
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np

from . import __version__
from .config import Config
from .evaluation import (
    AbsoluteTrajectoryError,
    EvaluationError,
    RelationsErrors,
    RelativePoseError,
    absolute_trajectory_error,
    relations_errors,
    relative_pose_error,
    trajectory_errors,
)
from .geometry import Pose2D
from .io import LogRecord, Relations, carmen_beam_geometry, read_relations, read_tum, write_tum
from .logs import OpenLog, open_log, select_records
from .positioner import Positioner
from .scan import LaserScan

__all__ = [
    "BENCHMARK_CONFIGS",
    "BenchmarkResult",
    "Evaluation",
    "RunSummary",
    "default_results_dir",
    "evaluate_trajectory",
    "file_sha256",
    "find_benchmark_logs",
    "git_hash",
    "log_name",
    "run_benchmark",
    "run_log",
    "write_estimate_clf",
]

#: ``progress(done, total)`` (``total`` None when unknown)
Progress = Callable[[int, "int | None"], None]

#: the runs of the benchmark, per log
BENCHMARK_CONFIGS = ("odometry", "paper", "default")

#: the log files a relations file ``NAME.relations`` is looked for with, in this order
BENCHMARK_LOG_NAMES = ("{}.clf.gz", "{}.clf", "{}.bag")

#: suffixes :func:`log_name` strips
_LOG_SUFFIXES = (".gz", ".clf", ".log", ".bag", ".carmen")


# -- small helpers --------------------------------------------------------------------------
def log_name(path: str | os.PathLike[str]) -> str:
    """A log's name without its usual suffixes: ``intel.clf.gz`` → ``intel``."""
    name = Path(path).name or Path(os.path.abspath(path)).name
    for _ in range(2):
        for suffix in _LOG_SUFFIXES:
            if name.lower().endswith(suffix) and len(name) > len(suffix):
                name = name[: -len(suffix)]
                break
    return name


def default_results_dir(path: str | os.PathLike[str]) -> Path:
    """``results/<log name>/`` (relative to the working directory)."""
    return Path("results") / log_name(path)


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file's bytes; for a directory (a ROS2 bag) of every file under it in
    sorted order of their relative paths (POSIX), each contributing its relative path, a NUL
    byte, its 8-byte big-endian size and its bytes."""
    p = Path(path)
    h = hashlib.sha256()

    def feed(f: Path) -> None:
        with open(f, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)

    if p.is_dir():
        files = sorted(
            (f for f in p.rglob("*") if f.is_file()), key=lambda f: f.relative_to(p).as_posix()
        )
        for f in files:
            h.update(f.relative_to(p).as_posix().encode("utf-8") + b"\x00")
            h.update(f.stat().st_size.to_bytes(8, "big"))
            feed(f)
    else:
        feed(p)
    return h.hexdigest()


def git_hash() -> str | None:
    """The commit of the source tree fuzzypos runs from (``git rev-parse HEAD`` in the
    package's directory), when that directory is part of a git work tree whose
    ``src/fuzzypos`` it is; None otherwise (installed package, no git, any failure)."""
    here = Path(__file__).resolve().parent
    try:
        def git(*args: str) -> str:
            return subprocess.run(
                ["git", "-C", str(here), *args],
                capture_output=True, text=True, timeout=5, check=True,
            ).stdout.strip()

        top = Path(git("rev-parse", "--show-toplevel")).resolve()
        if (top / "src" / "fuzzypos").resolve() != here:
            return None
        commit = git("rev-parse", "HEAD")
        return commit or None
    except Exception:  # noqa: BLE001 - never fail a run for its provenance
        return None


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def _clean(o: Any) -> Any:
    """NaN/inf → None (JSON has none), recursively."""
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    return o


def _write_json(path: Path, data: Any) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(
        json.dumps(_clean(data), indent=2, default=_json_default, allow_nan=False) + "\n",
        encoding="utf-8",
    )
    os.replace(tmp, path)


# -- the estimate as a CARMEN log -------------------------------------------------------------
_GEOMETRY_TOL = 1e-7
_RANGE_DECIMALS = 4


def _flaser_geometry(scan: LaserScan) -> tuple[float, str] | None:
    """``(field_of_view_deg, convention)`` under which FLASER's beam angles are this scan's,
    preferring ``"auto"``; None when no FLASER convention gives them."""
    n, inc, a0 = scan.n_beams, scan.angle_increment, scan.angle_min
    if n < 2 or inc <= 0.0:
        return None
    for convention, span in (("resolution", n * inc), ("span", (n - 1) * inc)):
        fov = math.degrees(span)
        if not 0.0 < fov <= 360.0:
            continue
        if abs(a0 + span / 2.0) > _GEOMETRY_TOL:
            continue
        fov = round(fov, 9)
        auto = "resolution" if n % 2 == 0 else "span"
        return (fov, "auto" if convention == auto else convention)
    return None


def _fits(scan: LaserScan, fov: float, convention: str) -> bool:
    if scan.n_beams < 2:
        return False
    a0, inc = carmen_beam_geometry(scan.n_beams, fov, convention)
    return (
        abs(scan.angle_min - a0) <= _GEOMETRY_TOL
        and abs(scan.angle_increment - inc) * scan.n_beams <= _GEOMETRY_TOL
    )


def _ranges_text(scan: LaserScan) -> str:
    """The raw ranges (as the log gave them) to 0.1 mm; a valid reading that rounding would
    move onto ``range_max`` or 0 at full precision; NaN and ±inf as 0 (invalid)."""
    out: list[str] = []
    rmax = scan.range_max
    for v, ok in zip(scan.ranges.tolist(), scan.valid.tolist()):
        if not math.isfinite(v):
            out.append("0")
            continue
        r = round(v, _RANGE_DECIMALS)
        if ok and (r >= rmax or r <= 0.0):
            out.append(repr(v))
        else:
            out.append(f"{r:.{_RANGE_DECIMALS}f}".rstrip("0").removesuffix("."))
    return " ".join(out)


class _ClfWriter:
    """Streams ``FLASER`` lines with the estimate as ``x y θ`` (see :func:`write_estimate_clf`);
    written to a temporary file renamed over ``path`` by :meth:`close`."""

    def __init__(self, path: Path, source: str, hostname: str = "fuzzypos") -> None:
        self.path = path
        self.tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        self.source = source
        self.hostname = hostname
        self.fh: IO[str] | None = open(self.tmp, "w", encoding="utf-8", newline="\n")  # noqa: SIM115
        self.geometry: tuple[float, str] | None = None
        self.sensor_pose: Pose2D | None = None
        self.skipped = 0
        self.written = 0
        self.notes: list[str] = []

    def header(self, first: LaserScan) -> None:
        assert self.fh is not None
        self.geometry = _flaser_geometry(first)
        fh = self.fh
        fh.write("# CARMEN Logfile\n")
        fh.write(f"# written by fuzzypos {__version__} (fuzzypos run) from {self.source}\n")
        fh.write("# FLASER x y theta: the fuzzypos estimate; odom_x odom_y odom_theta: the log's "
                 "odometry (the estimate where the log has none)\n")
        fh.write("# message formats defined: PARAM FLASER TRUEPOS\n")
        fh.write("# FLASER num_readings [range_readings] x y theta odom_x odom_y odom_theta\n")
        fh.write("# TRUEPOS true_x true_y true_theta odom_x odom_y odom_theta\n")
        if self.geometry is not None:
            fov, conv = self.geometry
            fh.write(
                f"# FLASER beams: field of view {fov:g} deg from -{fov / 2:g} deg, convention "
                f"{conv!r}; read with the same (fuzzypos: --fov {fov:g} --convention {conv})\n"
            )
        sp = first.sensor_pose
        self.sensor_pose = sp
        stamp = repr(first.stamp)
        if sp.y == 0.0 and sp.theta == 0.0:
            if sp.x != 0.0:
                fh.write(f"PARAM robot_frontlaser_offset {sp.x!r} {stamp} {self.hostname} {stamp}\n")
        else:
            fh.write(
                f"# the laser sits at x={sp.x!r} y={sp.y!r} theta={sp.theta!r} rad on the robot, "
                "which FLASER cannot store: read with --laser-offset "
                f"{sp.x:g},{sp.y:g},{math.degrees(sp.theta):g}\n"
            )
            self.notes.append(
                "trajectory.clf: the laser's mounting pose has a sideways or angular part "
                "that FLASER cannot store; it is in a comment"
            )

    def write(self, scan: LaserScan, estimate: Pose2D, odom: Pose2D | None, truth: Pose2D | None) -> None:
        if self.fh is None:
            return
        if self.written == 0 and self.skipped == 0:
            self.header(scan)
        if self.geometry is None or not _fits(scan, *self.geometry):
            self.skipped += 1
            return
        if scan.sensor_pose != self.sensor_pose and "sensor_pose" not in " ".join(self.notes):
            self.notes.append(
                "trajectory.clf: the scans' sensor_pose changes along the log; FLASER keeps "
                "the first one's"
            )
        est = f"{estimate.x!r} {estimate.y!r} {estimate.theta!r}"
        o = odom if odom is not None else estimate
        odo = f"{o.x!r} {o.y!r} {o.theta!r}"
        trailer = f"{scan.stamp!r} {self.hostname} {scan.stamp!r}"
        self.fh.write(f"FLASER {scan.n_beams} {_ranges_text(scan)} {est} {odo} {trailer}\n")
        if truth is not None:
            self.fh.write(f"TRUEPOS {truth.x!r} {truth.y!r} {truth.theta!r} {odo} {trailer}\n")
        self.written += 1

    def close(self) -> bool:
        """Finish the file; False (and no file) when no scan could be written as FLASER."""
        if self.fh is None:
            return False
        self.fh.close()
        self.fh = None
        if self.skipped:
            self.notes.append(
                f"trajectory.clf: {self.skipped} scans have beam angles FLASER cannot "
                "describe (no symmetric field of view) and were left out"
            )
        if self.written == 0:
            os.unlink(self.tmp)
            return False
        os.replace(self.tmp, self.path)
        return True

    def abort(self) -> None:
        if self.fh is not None:
            self.fh.close()
            self.fh = None
        try:
            os.unlink(self.tmp)
        except OSError:
            pass


def write_estimate_clf(
    path: str | os.PathLike[str],
    records: Iterable[tuple[LaserScan, Pose2D, Pose2D | None, Pose2D | None]],
    *,
    source: str = "",
) -> int:
    """Write ``(scan, estimate, odometry, truth)`` tuples as a CARMEN log; return the lines
    written.

    One ``FLASER n r_1 … r_n x y θ odom_x odom_y odom_θ ipc_timestamp hostname
    logger_timestamp`` line per scan, in the order given: ``x y θ`` = the estimate,
    ``odom_*`` = the odometry (the estimate where it is None), both timestamps the scan's
    stamp (``repr``); then ``TRUEPOS`` when ``truth`` is given. Ranges are the scan's raw
    readings to 0.1 mm (NaN/inf as 0, which reads back invalid). Unlike
    :func:`fuzzypos.io.write_carmen` (which writes the odometry into both pose fields and
    needs one ``range_max`` for the whole log) this streams any log the readers give: the
    beam geometry is taken from the first scan (field of view and convention in a header
    comment; scans that do not fit it are left out and counted in a note) and the maximum
    range is left for the reader to learn. Written to a temporary file first, so a failure
    leaves no partial file.
    """
    target = Path(path)
    w = _ClfWriter(target, source)
    try:
        for scan, est, odom, truth in records:
            w.write(scan, est, odom, truth)
    except BaseException:
        w.abort()
        raise
    w.close()
    return w.written


# -- one run ----------------------------------------------------------------------------------
@dataclass(eq=False)
class RunSummary:
    """What :func:`run_log` did.

    ``stamps`` ``(n,)``, ``poses`` ``(n, 3)`` (the estimate), ``odometry`` ``(n, 3)`` or None
    (NaN rows for scans without odometry), ``truth`` likewise; ``files``: name → path of
    what was written; ``summary``: the content of ``summary.json``.
    """

    results_dir: Path
    scans: int
    scans_degraded: int
    odometry_jumps_rejected: int
    seconds: float
    positioner_seconds: float
    stamps: np.ndarray
    poses: np.ndarray
    odometry: np.ndarray | None
    truth: np.ndarray | None
    files: dict[str, Path]
    summary: dict[str, Any]
    notes: list[str] = field(default_factory=list)

    @property
    def scans_per_second(self) -> float:
        return self.scans / self.seconds if self.seconds > 0 else float("nan")


def _pose_rows(poses: list[tuple[float, float, float] | None]) -> np.ndarray | None:
    if not any(p is not None for p in poses):
        return None
    nan = (math.nan, math.nan, math.nan)
    return np.array([p if p is not None else nan for p in poses], dtype=np.float64).reshape(-1, 3)


def run_log(
    log: OpenLog | str | os.PathLike[str],
    config: Config | None = None,
    *,
    results_dir: str | os.PathLike[str],
    out_tum: str | os.PathLike[str] | None = None,
    progress: Progress | None = None,
    start: float | None = None,
    end: float | None = None,
    max_scans: int | None = None,
    preset: str | None = None,
    config_file: str | os.PathLike[str] | None = None,
    relations: Relations | None = None,
    map_every: int = 10,
    plot: bool = True,
    hash_input: bool = True,
) -> RunSummary:
    """Position the robot along ``log`` (an :class:`~fuzzypos.logs.OpenLog`, or a path opened
    with :func:`~fuzzypos.logs.open_log`'s defaults) and write the results folder
    ``results_dir`` (created; files in it are replaced): ``trajectory.tum``,
    ``trajectory.clf``, ``config.toml``, ``path.png`` (unless ``plot=False``) and
    ``summary.json`` (module docstring). ``out_tum``: also write the trajectory there.

    ``start``, ``end``, ``max_scans`` choose a stretch (:func:`~fuzzypos.logs.select_records`).
    ``preset`` and ``config_file`` only label the configuration in ``summary.json``.
    ``relations``: also score the trajectory against them (``summary["relations"]``).
    ``progress(done, total)`` is called every 25 scans and at the end (``total``: the scans
    the stretch can have at most, when known).

    ``summary.json`` holds: ``fuzzypos_version``, ``git_hash`` (:func:`git_hash`), ``input``
    (``path``, ``sha256`` (:func:`file_sha256`; None with ``hash_input=False``), ``kind``,
    reader ``options``), ``selection``, ``scans``, ``scans_degraded``,
    ``odometry_jumps_rejected``, ``seconds`` (the whole loop: reading, positioning,
    writing), ``scans_per_second`` (``scans / seconds``), ``positioner_seconds`` and
    ``positioner_ms_per_scan`` (inside :meth:`Positioner.update` only), ``config`` (``preset``,
    ``file``), ``bad_lines_skipped``, ``first_stamp``/``last_stamp``, ``has_odometry``,
    ``truth_errors`` (:func:`~fuzzypos.evaluation.trajectory_errors` of the estimate and of the
    odometry against the log's ``TRUEPOS``, where every scan has one; else None),
    ``relations`` (or None), ``notes`` and ``files``.

    Raises ``ValueError`` (bad arguments, a log without scans in the stretch, a malformed
    log) or ``OSError``; the results folder then holds no partial trajectory files.
    """
    if not isinstance(log, OpenLog):
        log = open_log(log)
    cfg = config if config is not None else Config()
    if isinstance(map_every, bool) or not isinstance(map_every, int) or map_every < 1:
        raise ValueError(f"map_every must be a whole number >= 1, got {map_every!r}")
    records = select_records(log.records(), start=start, end=end, max_scans=max_scans)
    out = Path(results_dir)
    out.mkdir(parents=True, exist_ok=True)
    total: int | None = log.scan_count_hint() if progress is not None else None
    if max_scans is not None:
        total = max_scans if total is None else min(total, max_scans)

    positioner = Positioner(cfg)
    stamps: list[float] = []
    poses: list[tuple[float, float, float]] = []
    odoms: list[tuple[float, float, float] | None] = []
    truths: list[tuple[float, float, float] | None] = []
    map_points: list[np.ndarray | None] = []
    degraded = 0
    pos_seconds = 0.0
    clf = _ClfWriter(out / "trajectory.clf", log.name)
    t_start = time.perf_counter()
    try:
        rec: LogRecord
        for k, rec in enumerate(records):
            scan, odom = rec.scan, rec.odometry
            t0 = time.perf_counter()
            est = positioner.update(scan, odom)
            pos_seconds += time.perf_counter() - t0
            pose = est.pose
            stamps.append(scan.stamp)
            poses.append((pose.x, pose.y, pose.theta))
            odoms.append(None if odom is None else (odom.x, odom.y, odom.theta))
            truths.append(None if rec.truth is None else (rec.truth.x, rec.truth.y, rec.truth.theta))
            degraded += bool(est.degraded)
            if plot:
                map_points.append(scan.points_robot() if k % map_every == 0 else None)
            clf.write(scan, pose, odom, rec.truth)
            if progress is not None and (k + 1) % 25 == 0:
                progress(k + 1, total)
    except BaseException:
        clf.abort()
        raise
    seconds = time.perf_counter() - t_start
    n = len(stamps)
    if n == 0:
        clf.abort()
        what = "no scans" if (start is None and end is None) else "no scans in the chosen stretch"
        hint = " (is it a CARMEN log with FLASER or ROBOTLASER1 lines?)" if log.kind == "carmen" else ""
        raise ValueError(f"{log.name}: {what}{hint}")
    if progress is not None:
        progress(n, n)

    notes = list(dict.fromkeys([*log.notes, *getattr(log.reader, "notes", [])]))
    files: dict[str, Path] = {}
    st = np.array(stamps, dtype=np.float64)
    P = np.array(poses, dtype=np.float64).reshape(-1, 3)
    O = _pose_rows(odoms)
    T = _pose_rows(truths)

    files["trajectory.tum"] = out / "trajectory.tum"
    write_tum(
        files["trajectory.tum"], st, P,
        header_comment=f"fuzzypos {__version__} estimate of {log.name} (t = the scan's stamp)",
    )
    if out_tum is not None:
        write_tum(out_tum, st, P, header_comment=f"fuzzypos {__version__} estimate of {log.name}")
        files["out_tum"] = Path(out_tum)
    if clf.close():
        files["trajectory.clf"] = out / "trajectory.clf"
    notes.extend(clf.notes)
    files["config.toml"] = out / "config.toml"
    files["config.toml"].write_text(cfg.to_toml(), encoding="utf-8")
    if plot:
        from . import plot as plotting  # matplotlib only when figures are made

        files["path.png"] = out / "path.png"
        odo_xy = None if O is None else O[np.isfinite(O).all(axis=1)]
        plotting.plot_map(
            P, map_points, odometry=odo_xy, path=files["path.png"],
            title=f"{log_name(log.name)}: estimated path, odometry and map "
            f"(scans 1 in {map_every})",
        )

    truth_errors: dict[str, Any] | None = None
    if T is not None and np.isfinite(T).all():
        truth_errors = {"estimate": trajectory_errors(T, P, degraded).as_dict()}
        if O is not None and np.isfinite(O).all():
            truth_errors["odometry"] = trajectory_errors(T, O, 0).as_dict()
    rel: dict[str, Any] | None = None
    if relations is not None:
        try:
            rel = relations_errors(st, P, relations).as_dict()
        except EvaluationError as exc:
            notes.append(f"relations: {exc}")

    files["summary.json"] = out / "summary.json"
    summary: dict[str, Any] = {
        "fuzzypos_version": __version__,
        "git_hash": git_hash(),
        "input": {
            "path": os.path.abspath(log.name),
            "sha256": file_sha256(log.path) if hash_input else None,
            "kind": log.kind,
            "options": log.options,
        },
        "selection": {"start_s": start, "end_s": end, "max_scans": max_scans},
        "scans": n,
        "scans_degraded": degraded,
        "odometry_jumps_rejected": int(positioner.odometry_jumps),
        "seconds": seconds,
        "scans_per_second": n / seconds if seconds > 0 else None,
        "positioner_seconds": pos_seconds,
        "positioner_ms_per_scan": 1000.0 * pos_seconds / n,
        "config": {"preset": preset, "file": None if config_file is None else str(config_file)},
        "bad_lines_skipped": log.bad_lines,
        "truncated": log.truncated,
        "first_stamp": stamps[0],
        "last_stamp": stamps[-1],
        "has_odometry": O is not None,
        "has_truth": T is not None,
        "truth_errors": truth_errors,
        "relations": rel,
        "notes": notes,
        "files": {k: str(v) for k, v in files.items()},
    }
    _write_json(files["summary.json"], summary)
    return RunSummary(
        results_dir=out,
        scans=n,
        scans_degraded=degraded,
        odometry_jumps_rejected=int(positioner.odometry_jumps),
        seconds=seconds,
        positioner_seconds=pos_seconds,
        stamps=st,
        poses=P,
        odometry=O,
        truth=T,
        files=files,
        summary=summary,
        notes=notes,
    )


# -- scoring a trajectory file ----------------------------------------------------------------
@dataclass(eq=False)
class Evaluation:
    """:func:`evaluate_trajectory`'s scores; each None when not asked for."""

    estimate: str
    poses: int
    relations: RelationsErrors | None = None
    ate: AbsoluteTrajectoryError | None = None
    rpe_frame: RelativePoseError | None = None
    rpe_metre: RelativePoseError | None = None
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return _clean({
            "estimate": self.estimate,
            "poses": self.poses,
            "relations": None if self.relations is None else self.relations.as_dict(),
            "ate": None if self.ate is None else {"rmse_m": self.ate.rmse_m, **self.ate.as_dict()},
            "rpe_1_frame": None if self.rpe_frame is None else self.rpe_frame.as_dict(),
            "rpe_1_m": None if self.rpe_metre is None else self.rpe_metre.as_dict(),
            "notes": self.notes,
        })


def evaluate_trajectory(
    estimate: str | os.PathLike[str],
    *,
    relations: str | os.PathLike[str] | None = None,
    reference: str | os.PathLike[str] | None = None,
) -> Evaluation:
    """Score the TUM trajectory ``estimate`` against a relations file
    (:func:`~fuzzypos.evaluation.relations_errors`: all and local relations) and/or a
    reference TUM trajectory (ATE after SE(2) alignment,
    :func:`~fuzzypos.evaluation.absolute_trajectory_error`; RPE over 1 frame and over 1 m of
    the reference's path, :func:`~fuzzypos.evaluation.relative_pose_error`). At least one of
    the two is needed (``ValueError``). An RPE that has no pair (a reference shorter than 1 m)
    is left None with a note."""
    if relations is None and reference is None:
        raise ValueError("nothing to evaluate against: give relations and/or a reference")
    st, P = read_tum(estimate)
    if st.size == 0:
        raise ValueError(f"{os.fspath(estimate)}: no poses")
    ev = Evaluation(estimate=os.fspath(estimate), poses=int(st.size))
    if relations is not None:
        ev.relations = relations_errors(st, P, read_relations(relations))
    if reference is not None:
        rs, R = read_tum(reference)
        if rs.size == 0:
            raise ValueError(f"{os.fspath(reference)}: no poses")
        ev.ate = absolute_trajectory_error(rs, R, st, P)
        for attr, delta, unit in (("rpe_frame", 1, "frames"), ("rpe_metre", 1.0, "m")):
            try:
                setattr(ev, attr, relative_pose_error(rs, R, st, P, delta=delta, delta_unit=unit))
            except EvaluationError as exc:
                ev.notes.append(f"RPE over 1 {unit}: {exc}")
    return ev


# -- the benchmark ----------------------------------------------------------------------------
def find_benchmark_logs(data_dir: str | os.PathLike[str]) -> list[tuple[Path, Path]]:
    """``(log, relations)`` pairs under ``data_dir`` (searched recursively, sorted): for every
    ``NAME.relations``, each of ``NAME.clf.gz``, ``NAME.clf`` and ``NAME.bag`` next to it
    that exists (the file *names* only find the candidates; :func:`~fuzzypos.logs.open_log`
    then tells their kind by content). ``FileNotFoundError`` when ``data_dir`` is no
    directory."""
    root = Path(data_dir)
    if not root.is_dir():
        raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), os.fspath(data_dir))
    pairs: list[tuple[Path, Path]] = []
    for rel in sorted(root.rglob("*.relations")):
        if not rel.is_file():
            continue
        name = rel.name[: -len(".relations")]
        for pattern in BENCHMARK_LOG_NAMES:
            cand = rel.with_name(pattern.format(name))
            if cand.exists():
                pairs.append((cand, rel))
    return pairs


@dataclass(eq=False)
class BenchmarkResult:
    """:func:`run_benchmark`'s rows (one per log and configuration, as in ``benchmark.json``)
    and where it wrote them."""

    rows: list[dict[str, Any]]
    out_dir: Path
    json_path: Path
    data: dict[str, Any]


def _score_row(
    log_label: str, config: str, stamps: np.ndarray, poses: np.ndarray, relations: Relations
) -> dict[str, Any]:
    row: dict[str, Any] = {"log": log_label, "config": config}
    try:
        row.update(relations_errors(stamps, poses, relations).as_dict())
    except EvaluationError as exc:  # e.g. no relation within a short stretch
        row["not_scored"] = str(exc)
    return row


def run_benchmark(
    data_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    max_scans: int | None = None,
    progress: Callable[[str, int, int | None], None] | None = None,
    plot: bool = True,
) -> BenchmarkResult:
    """Run every log :func:`find_benchmark_logs` finds with the raw odometry, the ``paper``
    preset and the ``default`` configuration (:data:`BENCHMARK_CONFIGS`), sequentially, and
    score each against the log's relations.

    Per log ``L`` (its file name), ``out_dir/L/paper/`` and ``out_dir/L/default/`` are
    :func:`run_log` results folders (with ``summary["relations"]``) and
    ``out_dir/L/odometry/trajectory.tum`` holds the raw odometry poses of the same scans
    (taken from the first run: the log is not read a third time). ``max_scans`` runs only
    the first scans of each log (relations outside them are unmatched, not scored).
    ``out_dir/benchmark.json`` holds ``fuzzypos_version``, ``git_hash``, ``data_dir``,
    ``max_scans`` and ``rows``: per log and configuration the relations metric
    (:meth:`~fuzzypos.evaluation.RelationsErrors.as_dict` keys: ``all_trans_mean_m``,
    ``local_rot_median_deg`` …), ``scans``, ``scans_per_second``, ``scans_degraded``,
    ``odometry_jumps_rejected``, ``results`` (the folder); ``not_scored`` (why) instead of
    the metric where no relation could be scored (e.g. none within a short stretch); and
    only ``error`` where the run failed (the other runs still go ahead).
    ``progress(label, done, total)``.
    ``ValueError`` when ``data_dir`` holds no log with relations.
    """
    pairs = find_benchmark_logs(data_dir)
    if not pairs:
        raise ValueError(
            f"{os.fspath(data_dir)}: no log with a relations file next to it "
            "(NAME.relations with NAME.clf.gz, NAME.clf or NAME.bag)"
        )
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    for log_path, rel_path in pairs:
        label = log_path.name
        try:
            relations = read_relations(rel_path)
        except (ValueError, OSError) as exc:
            rows.extend({"log": label, "config": c, "error": str(exc)} for c in BENCHMARK_CONFIGS)
            continue
        odometry: tuple[np.ndarray, np.ndarray] | None = None
        odometry_error: str | None = None
        run_rows: list[dict[str, Any]] = []
        for config in ("paper", "default"):
            folder = out / label / config
            cb = None
            if progress is not None:
                def cb(done: int, total: int | None, _name: str = f"{label} {config}") -> None:
                    progress(_name, done, total)
            try:
                log = open_log(log_path)
                res = run_log(
                    log, Config.preset(config), results_dir=folder, progress=cb,
                    max_scans=max_scans, preset=config, relations=relations, plot=plot,
                )
            except (ValueError, OSError) as exc:
                run_rows.append({"log": label, "config": config, "error": str(exc)})
                continue
            row = _score_row(label, config, res.stamps, res.poses, relations)
            row.update(
                scans=res.scans,
                scans_per_second=res.scans_per_second,
                positioner_ms_per_scan=1000.0 * res.positioner_seconds / res.scans,
                scans_degraded=res.scans_degraded,
                odometry_jumps_rejected=res.odometry_jumps_rejected,
                results=str(folder),
            )
            run_rows.append(row)
            if odometry is None and odometry_error is None:
                if res.odometry is None or not np.isfinite(res.odometry).all():
                    odometry_error = "the log has no odometry for every scan"
                else:
                    odometry = (res.stamps, res.odometry)
        if odometry is not None:
            folder = out / label / "odometry"
            folder.mkdir(parents=True, exist_ok=True)
            write_tum(folder / "trajectory.tum", odometry[0], odometry[1],
                      header_comment=f"raw odometry of {log_path}")
            orow = _score_row(label, "odometry", odometry[0], odometry[1], relations)
            orow.update(scans=int(odometry[0].size), scans_per_second=None, scans_degraded=0,
                        odometry_jumps_rejected=0, results=str(folder))
        else:
            orow = {"log": label, "config": "odometry",
                    "error": odometry_error or "no run gave the odometry"}
        rows.append(orow)
        rows.extend(run_rows)
    data = {
        "fuzzypos_version": __version__,
        "git_hash": git_hash(),
        "data_dir": os.path.abspath(os.fspath(data_dir)),
        "max_scans": max_scans,
        "rows": rows,
    }
    json_path = out / "benchmark.json"
    _write_json(json_path, data)
    return BenchmarkResult(rows=rows, out_dir=out, json_path=json_path, data=_clean(data))
