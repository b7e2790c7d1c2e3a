"""Thinning a log to large steps between scans, for ``bench_thinned.py`` and ``bench_peers.py``.

Thinning (:func:`thin_indices`), in file order: every relation's two end scans are kept (the
scans whose stamps are the relation's, as the metric matches them), and the first scan; any
other scan is kept when its odometry pose has moved at least the distance (straight, from
pose to pose) or turned at least the angle since the last scan kept (for whatever reason). A
scan without odometry is kept only as a relation's end. The kept records (read with
``fuzzypos.io.logs.open_log(path).records()``) are written as a CARMEN log
(:func:`write_thinned`): FLASER lines (``fuzzypos.io.write_carmen``) where the scans fit
FLASER's beam geometry, with one maximum range above every valid reading and each scan's
invalid readings written as it (:func:`one_range_max`: the reader learns a FLASER log's "no
return" value from the scans it streams, which thinning changes); else (fr-clinic: 180 and
181 beams, interlaced start angles, a laser 0.22 m ahead) ``ROBOTLASER1`` lines with their
own angles and mount (``CarmenWriter``), the odometry as the robot pose (which a reader
takes as the odometry) and in an ``ODOM`` line before each. Each thinned log is read back
and checked scan by scan against the kept records (stamps, odometry, beams, ranges, mount)
before it is run.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fuzzypos.eval.metrics import DEFAULT_RELATIONS_GAP, nearest_stamps
from fuzzypos.geometry import relative
from fuzzypos.io import CarmenWriter, LogRecord, open_log, read_relations, write_carmen
from fuzzypos.io.carmen_write import flaser_geometry

#: the shared logs, by name: the log and its relations under the data folder
LOGS = {
    name: (f"{name}/{name}.clf.gz", f"{name}/{name}.relations")
    for name in ("intel", "aces", "fr079", "fr-clinic")
}
#: the thinnings, by name: a scan kept every this many metres or degrees of odometry
THINNINGS = {"0.5": (0.5, 10.0), "1": (1.0, 20.0)}


# -- thinning --------------------------------------------------------------------------------
def thin_indices(
    stamps: Sequence[float] | np.ndarray,
    odometry: Sequence[Any],
    relation_stamps: np.ndarray,
    distance: float,
    angle_deg: float,
    *,
    max_stamp_gap: float = DEFAULT_RELATIONS_GAP,
) -> list[int]:
    """The scans (indices in file order) a thinned log keeps (module docstring): the first,
    every relation end (the scan of the nearest stamp within ``max_stamp_gap`` of each of
    ``relation_stamps``; ends without one are ignored), and a scan whenever its odometry pose
    (``odometry[k]``: ``(x, y, θ)`` or None) is at least ``distance`` m or ``angle_deg``
    degrees from the last scan kept's."""
    t = np.asarray(stamps, dtype=float)
    n = t.shape[0]
    if n == 0:
        return []
    ends: set[int] = set()
    rs = np.asarray(relation_stamps, dtype=float).reshape(-1)
    if rs.size:
        idx, gap = nearest_stamps(t, rs)
        ends = {int(i) for i in idx[gap <= max_stamp_gap]}
    angle = math.radians(angle_deg)
    kept: list[int] = []
    last: np.ndarray | None = None
    for k in range(n):
        odo = None if odometry[k] is None else np.asarray(odometry[k], dtype=float)
        keep = k == 0 or k in ends
        if not keep and odo is not None and last is not None:
            dx, dy, dth = relative(last, odo).tolist()
            keep = math.hypot(dx, dy) >= distance or abs(dth) >= angle
        if keep:
            kept.append(k)
            if odo is not None:
                last = odo
    return kept


def one_range_max(records: Sequence[LogRecord]) -> list[LogRecord]:
    """The records with one ``range_max`` for every scan, far above every valid reading, and
    each scan's invalid readings NaN (written as that maximum): what FLASER can carry (one
    ``PARAM robot_front_laser_max``), read back with each scan's own valid readings. (The
    reader learns a FLASER log's "no return" value as it streams, so a thinned log read as
    the full one was would learn it from other scans; a scan's ``range_max`` decides only
    which readings are valid.)"""
    top = max(
        (float(np.max(r.scan.ranges[r.scan.valid])) for r in records if r.scan.valid.any()),
        default=0.0,
    )
    common = max(100.0, 2.0 * top)
    out = []
    for r in records:
        ranges = np.where(r.scan.valid, r.scan.ranges, np.nan)
        scan = dataclasses.replace(r.scan, ranges=ranges, range_max=common)
        out.append(LogRecord(scan, r.odometry, r.truth))
    return out


def write_thinned(path: Path, records: Sequence[LogRecord], source: str) -> str:
    """Write the records as a CARMEN log (module docstring): FLASER lines when every scan
    has the first's FLASER beam geometry and mount, else ``CarmenWriter``'s ROBOTLASER1 lines
    where the first scan's FLASER geometry does not describe a scan (every scan of
    fr-clinic, whose angles fit no FLASER convention); the kinds of line written."""
    if not records:
        raise ValueError(f"{path}: no scans to write")
    first = records[0].scan
    geometry = flaser_geometry(first)
    if geometry is not None and all(
        flaser_geometry(r.scan) == geometry and r.scan.sensor_pose == first.sensor_pose
        for r in records
    ):
        fov, convention = geometry
        write_carmen(
            path,
            one_range_max(records),
            field_of_view_deg=fov,
            convention=convention,
            header_comment=f"thinned from {source} (benchmarks/bench_thinned.py)",
        )
        return "FLASER"
    with CarmenWriter(path, estimate_of=f"{source}, thinned") as writer:
        for rec in records:
            if rec.odometry is None:
                raise ValueError(f"{path}: a ROBOTLASER1 scan needs a robot pose (odometry)")
            writer.write(rec.scan, rec.odometry, rec.truth, pose=rec.odometry)
    return "ROBOTLASER1" if writer.robotlaser1 == writer.written else "FLASER and ROBOTLASER1"


def check_read_back(path: Path, records: Sequence[LogRecord], tol: float = 1e-4) -> None:
    """Raise ``ValueError`` unless ``path`` reads back as ``records``: the same stamps,
    odometry, beam angles, valid readings and their ranges (to ``tol`` m), the mount to 1e-9
    (a ROBOTLASER1 line gives it as the laser's pose in the world, composed anew)."""
    back = list(open_log(path).records())
    if len(back) != len(records):
        raise ValueError(f"{path}: {len(back)} scans read back, {len(records)} written")
    for k, (a, b) in enumerate(zip(records, back)):
        sa, sb = a.scan, b.scan
        what = None
        if sa.stamp != sb.stamp:
            what = f"stamp {sb.stamp!r} for {sa.stamp!r}"
        elif a.odometry != b.odometry:
            what = f"odometry {b.odometry} for {a.odometry}"
        elif sa.n_beams != sb.n_beams:
            what = "beam count"
        elif not np.allclose(
            sa.sensor_pose.as_array(), sb.sensor_pose.as_array(), rtol=0.0, atol=1e-9
        ):
            what = f"mount {sb.sensor_pose} for {sa.sensor_pose}"
        elif not np.allclose(sa.angles, sb.angles, rtol=0.0, atol=1e-9):
            what = "beam angles"
        elif not np.array_equal(sa.valid, sb.valid):
            what = f"{int(np.sum(sa.valid != sb.valid))} readings' validity"
        elif not np.allclose(sa.ranges[sa.valid], sb.ranges[sb.valid], rtol=0.0, atol=tol):
            what = "ranges"
        if what is not None:
            raise ValueError(f"{path}: scan {k} reads back with another {what}")


def thin_log(
    log_path: Path, relations_path: Path, out: Path, distance: float, angle_deg: float
) -> dict[str, Any]:
    """Thin one log into ``out`` (written, read back and checked); its figures."""
    records = list(open_log(log_path).records())
    rel = read_relations(relations_path)
    stamps = [r.scan.stamp for r in records]
    odometry = [None if r.odometry is None else r.odometry.as_array() for r in records]
    ends = np.concatenate([rel.t1, rel.t2])
    keep = thin_indices(stamps, odometry, ends, distance, angle_deg)
    kept = [records[k] for k in keep]
    kind = write_thinned(out, kept, log_path.name)
    check_read_back(out, kept)
    idx, gap = nearest_stamps(np.asarray(stamps), ends)
    return {
        "scans_full": len(records),
        "scans_kept": len(kept),
        "relation_end_scans": len(set(idx[gap <= DEFAULT_RELATIONS_GAP].tolist())),
        "lines": kind,
    }


def thinned_log(folder: Path, data: Path, name: str) -> tuple[Path, Path]:
    """``bench_peers.py``'s thinned choices: ``LOG-thin-KEY`` (LOG of :data:`LOGS`, KEY of
    :data:`THINNINGS`) written into ``folder``; the log's and its relations' paths."""
    log, _, key = name.partition("-thin-")
    if log not in LOGS or key not in THINNINGS:
        raise KeyError(name)
    log_path, rel_path = (data / part for part in LOGS[log])
    out = folder / f"{name}.clf"
    info = thin_log(log_path, rel_path, out, *THINNINGS[key])
    print(
        f"{name}: {info['scans_kept']} of {info['scans_full']} scans ({info['lines']})",
        file=sys.stderr,
    )
    return out, rel_path


def thinned_names() -> list[str]:
    return [f"{log}-thin-{key}" for log in LOGS for key in THINNINGS]


# -- running and the report ------------------------------------------------------------------
