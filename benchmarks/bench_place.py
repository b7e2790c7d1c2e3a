"""How well the place descriptor tells revisits from other places, on the shared logs: why
place candidates are sought only among the loop-closure gate's keyframes.

The default front end runs over each log; every keyframe's place descriptor is made as the
loop closer makes it (``LoopCloser.place_of``). Where each keyframe really is comes from the
reference keyframes (``LOG.keyframes.tum``, a SLAM output): the nearest reference scan's pose
carried to the keyframe by the front end's motion between the two (over a few scans it is
exact to millimetres). Each keyframe is compared with every keyframe before its last
``recent_keyframes``; the pairs within 1 m of each other (revisits) and those more than 5 m
apart are tallied. Prints the distances' percentiles of both, and for a few thresholds how
many revisits score below it and how many pairs 5 m apart per keyframe do (what a search
beyond the gate would verify).

    python benchmarks/bench_place.py [--data ../shared/data] [--logs intel,aces]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from fuzzypos import Config, Positioner
from fuzzypos.geometry import compose, relative
from fuzzypos.graph import LoopCloser, PoseGraph
from fuzzypos.graph.place import PlaceIndex
from fuzzypos.io import open_log, read_tum

NEAR, FAR = 1.0, 5.0  # m
THRESHOLDS = (0.05, 0.1, 0.15, 0.2, 0.3)


def distances(log: Path, reference: Path) -> tuple[np.ndarray, np.ndarray, int]:
    """The descriptor distances of the keyframe pairs within NEAR and beyond FAR, and the
    number of keyframes."""
    config = Config()
    positioner = Positioner(config)
    graph, stamps, poses = PoseGraph(), [], []
    for record in open_log(log).records():
        est = positioner.update(record.scan, record.odometry)
        graph.add(est if est.keyframe else replace(est, features=None))
        stamps.append(est.stamp)
        poses.append(est.pose.as_array())
    front, t = np.array(poses), np.array(stamps)
    ref_t, ref_poses = read_tum(reference)
    at = {float(s): k for k, s in enumerate(t)}
    ref_scans = np.array(sorted(at[float(s)] for s in ref_t if float(s) in at))
    ref_of = {at[float(s)]: p for s, p in zip(ref_t, ref_poses) if float(s) in at}
    where = []
    for kf in graph.keyframes:
        r = int(ref_scans[np.argmin(np.abs(ref_scans - kf.scan))])
        where.append(compose(ref_of[r], relative(front[r], front[kf.scan])))
    truth = np.array(where)
    closer = LoopCloser(config)
    descriptors = [closer.place_of(graph, k) for k in range(len(graph))]
    index = PlaceIndex(descriptors)
    recent = config.loop_closure.recent_keyframes
    near, far = [], []
    for j in range(recent + 1, len(graph)):
        ks = np.arange(j - recent)
        d, _ = index.compare(descriptors[j], ks, config.loop_closure.place_min_overlap)
        apart = np.hypot(*(truth[ks, :2] - truth[j, :2]).T)
        near.append(d[apart < NEAR])
        far.append(d[apart > FAR])
    return np.concatenate(near), np.concatenate(far), len(graph)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--logs", default="intel,aces")
    args = parser.parse_args()
    rows = []
    for name in args.logs.split(","):
        log = args.data / name / f"{name}.clf.gz"
        reference = args.data / name / f"{name}.keyframes.tum"
        if not (log.exists() and reference.exists()):
            print(f"skipped {name}: {log} or {reference} is not there", file=sys.stderr)
            continue
        near, far, n = distances(log, reference)
        rows.append((name, near, far, n))
    print(f"place descriptor distances: revisits (< {NEAR:g} m apart) and places > {FAR:g} m apart")
    print()
    head = "| log | keyframes | revisits | their 10 / 50 / 90th pct | pairs apart |"
    print(head + " their 0.1 / 1 / 10th pct |")
    print("|---|---:|---:|---|---:|---|")
    for name, near, far, n in rows:
        a = " / ".join(f"{v:.3f}" for v in np.percentile(near, [10, 50, 90]))
        b = " / ".join(f"{v:.3f}" for v in np.percentile(far, [0.1, 1, 10]))
        print(f"| {name} | {n} | {len(near)} | {a} | {len(far)} | {b} |")
    print()
    print("| log | threshold | revisits below | pairs apart below, per keyframe |")
    print("|---|---:|---:|---:|")
    for name, near, far, n in rows:
        for t in THRESHOLDS:
            print(f"| {name} | {t:g} | {np.mean(near < t):.1%} | {np.sum(far < t) / n:.2f} |")


if __name__ == "__main__":
    main()
