"""Localisation in a map built by a mapping run (``fuzzypos run LOG --loop-closure --results
R``): the whole log localised without an initial pose, and 8 starts spread over it.

For each ``NAME=R`` given: the map ``R/map.yaml``, the mapping run's poses
``R/trajectory.tum`` and the log ``$FUZZYPOS_DATA/NAME/NAME.clf.gz`` with its relations.

- whole log: the scans until localised (and their compute seconds); the relations (Freiburg
  benchmark) scored on the localised rows only, their mean translation error and the share
  of relations those rows cover; the median distance to the mapping run's poses from the
  51st localised row on; d² of that difference under the reported covariance (the share
  within χ²(3)'s 99.9 % quantile, 16.27, and its median; a calibrated one is about 2.4).
- tracking speed: scans per second of ``Localizer.update`` while tracking, one thread, beside
  ``Positioner.update`` over the same log's first scans (the front end), and their ratio.
- 8 starts: runs of 400 scans from 8 evenly spread starts, no initial pose: how many
  localise, after how many scans, and the share of rows from the 51st on within 0.3 m and 3°
  of the mapping run's poses.
- keyframe logs: the log thinned to a scan per 0.5 m / 10° (1 m / 20°) of odometry
  (``thinning.thin_indices``), localised likewise: the motion between consecutive keyframes
  against the mapping run's, and the median distance to its poses.
- the global search's cost: one search of a scan over the whole map padded to 50 m × 50 m.

``python benchmarks/bench_localize.py intel=R1 aces=R2 [--write docs/benchmarks/localize.md]``
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread, set before numpy loads

import argparse  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from fuzzypos import Positioner  # noqa: E402
from fuzzypos.eval import relations_errors  # noqa: E402
from fuzzypos.geometry import relative  # noqa: E402
from fuzzypos.io import open_log  # noqa: E402
from fuzzypos.io.occupancy_map import UNKNOWN, OccupancyMap, read_map_yaml  # noqa: E402
from fuzzypos.io.relations import read_relations  # noqa: E402
from fuzzypos.localization import Localizer  # noqa: E402
from fuzzypos.pipeline.warm import warm_up  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_honesty import commit, machine  # noqa: E402
from thinning import thin_indices  # noqa: E402

CHI2_3_999 = 16.266


@dataclass
class Run:
    """One localisation run: per scan, stamp, whether tracked, pose, covariance, seconds."""

    stamps: list[float] = field(default_factory=list)
    tracked: list[bool] = field(default_factory=list)
    matched: list[bool] = field(default_factory=list)
    poses: list[tuple[float, float, float]] = field(default_factory=list)
    covs: list[np.ndarray] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)


def reference(path: Path) -> dict[float, np.ndarray]:
    """The mapping run's poses by stamp (rounded to µs)."""
    tum = np.loadtxt(path)
    theta = 2.0 * np.arctan2(tum[:, 6], tum[:, 7])
    return {
        round(t, 6): np.array([x, y, th])
        for t, x, y, th in zip(tum[:, 0], tum[:, 1], tum[:, 2], theta)
    }


def localise(loc: Localizer, records: list) -> Run:
    run = Run()
    for rec in records:
        t = time.perf_counter()
        est = loc.update(rec.scan, rec.odometry)
        run.seconds.append(time.perf_counter() - t)
        run.stamps.append(rec.scan.stamp)
        run.tracked.append(est.localised)
        run.matched.append(est.reason == "matched")
        run.poses.append(tuple(est.pose) if est.pose is not None else (math.nan,) * 3)
        run.covs.append(est.covariance if est.covariance is not None else np.full((3, 3), np.nan))
    return run


def differences(run: Run, ref: dict[float, np.ndarray]) -> np.ndarray:
    """(n, 3) the run's pose less the mapping run's (angle wrapped); NaN where not tracked."""
    out = np.full((len(run.stamps), 3), np.nan)
    for k, (s, p) in enumerate(zip(run.stamps, run.poses)):
        r = ref.get(round(s, 6))
        if r is not None and run.tracked[k]:
            d = np.array(p) - r
            d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
            out[k] = d
    return out


def whole_log(name: str, loc: Localizer, records: list, ref: dict, data: Path) -> dict[str, str]:
    run = localise(loc, records)
    tracked = np.array(run.tracked)
    first = int(np.argmax(tracked)) if tracked.any() else len(tracked)
    rel = read_relations(data / name / f"{name}.relations")
    ok = np.flatnonzero(tracked)
    errs = relations_errors(np.array(run.stamps)[ok], np.array(run.poses)[ok], rel)
    diff = differences(run, ref)
    rows = ok[50:]
    dist = np.hypot(diff[rows, 0], diff[rows, 1])
    d2 = np.array(
        [
            d @ np.linalg.solve(run.covs[k], d)
            for k, d in zip(rows, diff[rows])
            if np.isfinite(d).all()
        ]
    )
    seconds = np.array(run.seconds)
    matched = np.array(run.matched)
    # tracking only: the scans fitted from the last pose (no search of any kind)
    fits = np.flatnonzero(matched & (seconds < 10 * np.median(seconds[matched])))
    fit_rate = len(fits) / float(np.sum(seconds[fits]))
    all_rate = (len(ok) - 1) / float(np.sum(seconds[ok[1:]]))
    return {
        "log": name,
        "scans": f"{len(records)}",
        "localised after": f"{first + 1} scans, {sum(run.seconds[: first + 1]):.1f} s",
        "tracked rows": f"{tracked.mean():.1%}",
        "relations (all) mean": (
            f"{errs.all.translation_m.mean:.3f} m, {errs.all.rotation_deg.mean:.2f}°"
        ),
        "relations covered": f"{errs.all.matched / errs.relations:.1%}",
        "median to mapping run (51st row on)": f"{np.nanmedian(dist):.3f} m",
        "d² ≤ 16.27 / median d²": f"{np.mean(d2 <= CHI2_3_999):.1%} / {np.median(d2):.2f}",
        "tracking speed": f"{fit_rate:.0f} scans/s",
        "tracked scans with their searches": f"{all_rate:.0f} scans/s",
    }


def starts(
    m: OccupancyMap, records: list, ref: dict, n: int = 8, length: int = 400
) -> dict[str, str]:
    """Runs of ``length`` scans from ``n`` starts spread evenly over the log (the first at
    its start, the last ending at its end), each without an initial pose."""
    good, times, secs = 0, [], []
    shares, firsts = [], []
    for i in range(n):
        s = (len(records) - length) * i // max(n - 1, 1)
        run = localise(Localizer(m), records[s : s + length])
        tracked = np.array(run.tracked)
        every = differences(run, ref)
        if tracked.any():  # the first localised pose against the mapping run's
            d = every[int(np.argmax(tracked))]
            firsts.append(f"{math.hypot(d[0], d[1]):.2f} m/{abs(math.degrees(d[2])):.1f}°")
        diff = every[50:]
        near = (np.hypot(diff[:, 0], diff[:, 1]) <= 0.3) & (np.degrees(np.abs(diff[:, 2])) <= 3.0)
        share = float(np.mean(near))
        shares.append(share)
        if tracked.any():
            f = int(np.argmax(tracked))
            times.append(f + 1)
            secs.append(sum(run.seconds[: f + 1]))
        if tracked.any() and share >= 0.9:
            good += 1
    return {
        "8 starts: localised and ≥ 90 % rows within 0.3 m, 3°": f"{good} of {n}",
        "8 starts: scans (s) to localise, median": (
            f"{np.median(times):.0f} ({np.median(secs):.1f} s)" if times else "-"
        ),
        "8 starts: rows within, each": " ".join(f"{s:.0%}" for s in shares),
        "8 starts: first localised pose from the mapping run's": " ".join(firsts),
    }


def thinned(m: OccupancyMap, records: list, ref: dict, distance: float, angle: float) -> str:
    """The log thinned to a scan per ``distance`` m or ``angle`` degrees of odometry
    (``thinning.thin_indices``, no other scan kept), localised without an initial pose:
    the motion between consecutive localised keyframes against the mapping run's (mean
    translation error), and the median distance to its poses from the 51st localised on."""
    stamps = [r.scan.stamp for r in records]
    odometry = [None if r.odometry is None else r.odometry.as_array() for r in records]
    keep = thin_indices(stamps, odometry, np.zeros(0), distance, angle)
    run = localise(Localizer(m), [records[k] for k in keep])
    ok = np.flatnonzero(run.tracked)
    est = np.array(run.poses)[ok]
    truth = np.array([ref[round(run.stamps[k], 6)] for k in ok])
    err = relative(relative(truth[:-1], truth[1:]), relative(est[:-1], est[1:]))
    step = np.hypot(*relative(truth[:-1], truth[1:])[:, :2].T)
    dist = np.hypot(*(est[50:, :2] - truth[50:, :2]).T)
    return (
        f"{np.mean(np.hypot(err[:, 0], err[:, 1])):.3f} m between keyframes "
        f"(median step {np.median(step):.2f} m), {np.median(dist):.3f} m median to the "
        f"mapping run ({len(keep)} scans, {len(ok) / len(keep):.0%} localised)"
    )


def front_end_speed(records: list, seconds: float = 90.0) -> float:
    """Scans per second of ``Positioner.update`` over the log from its start (at most about
    ``seconds``; every kernel compiled or loaded first: ``warm_up``)."""
    warm_up()
    pos = Positioner()
    t = time.perf_counter()
    n = 0
    for rec in records:
        pos.update(rec.scan, rec.odometry)
        n += 1
        if time.perf_counter() - t > seconds:
            break
    return n / (time.perf_counter() - t)


def search_cost(m: OccupancyMap, records: list, count: int = 5) -> str:
    """Global searches over the map padded (unknown) to at least 50 m × 50 m, of ``count``
    scans spread over the log: the median time and the places found."""
    cells = round(50.0 / m.resolution)
    rows, cols = m.shape
    big = np.full((max(rows, cells), max(cols, cells)), UNKNOWN, dtype=np.int8)
    big[:rows, :cols] = m.cells
    loc = Localizer(OccupancyMap(big, m.resolution, m.origin))
    times, places = [], []
    for k in np.linspace(100, len(records) - 1, count).astype(int):
        pts = loc.points_of(records[k].scan)
        t = time.perf_counter()
        places.append(len(loc.search.search(pts)))
        times.append(time.perf_counter() - t)
    w, h = loc.field.size
    return (
        f"{np.median(times) * 1000:.0f} ms median, {max(times) * 1000:.0f} ms max "
        f"({w:.0f} m × {h:.0f} m; places found {min(places)}–{max(places)})"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", help="NAME=RESULTS_FOLDER of a mapping run")
    ap.add_argument("--data", default=os.environ.get("FUZZYPOS_DATA", "data"))
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--write", type=Path, default=None, help="also write the table here")
    args = ap.parse_args(argv)
    data = Path(args.data)
    table: list[dict[str, str]] = []
    for item in args.runs:
        name, _, folder = item.partition("=")
        results = Path(folder)
        m = read_map_yaml(results / "map.yaml")
        ref = reference(results / "trajectory.tum")
        records = list(open_log(data / name / f"{name}.clf.gz").records())
        row = whole_log(name, Localizer(m), records, ref, data)
        front = front_end_speed(records)
        speed = float(row["tracking speed"].split()[0])
        row["front end (Positioner.update)"] = f"{front:.0f} scans/s (ratio {speed / front:.1f})"
        for d, a in ((0.5, 10.0), (1.0, 20.0)):
            row[f"keyframes {d} m / {a:.0f}°"] = thinned(m, records, ref, d, a)
        row.update(starts(m, records, ref, args.starts))
        row["global search, one scan"] = search_cost(m, records)
        table.append(row)
        print(row, flush=True)
    keys = list(table[0])
    lines = ["| " + " | ".join(["measure", *[r["log"] for r in table]]) + " |"]
    lines.append("|" + "---|" * (len(table) + 1))
    lines += ["| " + " | ".join([k, *[r[k] for r in table]]) + " |" for k in keys[1:]]
    text = "\n".join(lines)
    print(text)
    if args.write is not None:
        command = "python benchmarks/bench_localize.py " + " ".join(
            f"{r['log']}=RESULTS_{r['log'].upper()}" for r in table
        )
        stamp = time.strftime("%Y-%m-%d", time.gmtime())
        args.write.write_text(
            "# Localisation in a mapping run's map\n\n"
            f"{stamp}, commit {commit()}, {machine()}, one thread.\n\n"
            f"`{command}` (RESULTS_x: the folder of `fuzzypos run LOG --loop-closure --results`; "
            "the log's data under `$FUZZYPOS_DATA`). What each row measures: the script's "
            "docstring.\n\n" + text + "\n",
            encoding="utf-8",
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
