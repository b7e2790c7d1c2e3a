"""How far each loop closure of a run lies from a reference: the closures a
``fuzzypos run LOG --loop-closure`` wrote to its results folder, against the log's reference
keyframes (``LOG.keyframes.tum``, a SLAM output whose stamps are scans' stamps).

A closure's keyframes are rarely reference scans, so the reference is carried to each of them
by the front end's motion (``trajectory_frontend.tum``) from the nearest reference scan; over
a few scans it is exact to millimetres. Prints, for the closures kept (weight ≥ 0.5) and those
GNC left out, how many, and their position and heading errors (largest, and how many beyond
0.15 m or 2°), then the largest few.

    python benchmarks/bench_closures.py RESULTS_DIR ../shared/data/intel/intel.keyframes.tum
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from fuzzypos.geometry import compose, relative
from fuzzypos.io import read_tum


def closure_errors(
    folder: Path, reference: Path
) -> list[tuple[float, float, float, str, list[int]]]:
    """Per closure of ``folder``'s summary: position error m, heading error °, weight, source,
    keyframes."""
    stamps, front = read_tum(folder / "trajectory_frontend.tum")
    ref_stamps, ref_poses = read_tum(reference)
    scan_of = {float(t): k for k, t in enumerate(stamps)}
    ref_at = {scan_of[float(t)]: p for t, p in zip(ref_stamps, ref_poses) if float(t) in scan_of}
    if not ref_at:
        raise SystemExit(f"no reference stamp of {reference} is a scan of {folder}")
    ref_scans = np.array(sorted(ref_at))

    def truth(k: int) -> np.ndarray:
        r = int(ref_scans[np.argmin(np.abs(ref_scans - k))])
        return compose(ref_at[r], relative(front[r], front[k]))

    summary = json.loads((folder / "summary.json").read_text(encoding="utf-8"))["loop_closure"]
    out = []
    for c in summary["closures"]:
        ki, kj = (int(np.argmin(np.abs(stamps - t))) for t in c["stamps"])
        e = relative(relative(truth(ki), truth(kj)), np.array(c["measured"]))
        out.append((math.hypot(e[0], e[1]), abs(math.degrees(e[2])), c["weight"], c["source"],
                    c["keyframes"]))  # fmt: skip
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", type=Path, help="a --loop-closure run's results folder")
    parser.add_argument("reference", type=Path, help="the log's reference keyframes (TUM)")
    args = parser.parse_args()
    rows = closure_errors(args.results, args.reference)
    head = "| closures | count | largest position error m | beyond 0.15 m |"
    print(head + " largest heading error ° | beyond 2° |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, keep in (("kept", True), ("left out", False)):
        some = [r for r in rows if (r[2] >= 0.5) == keep]
        if not some:
            print(f"| {name} | 0 | | | | |")
            continue
        pos, head = [r[0] for r in some], [r[1] for r in some]
        print(f"| {name} | {len(some)} | {max(pos):.3f} | {sum(p > 0.15 for p in pos)} | "
              f"{max(head):.2f} | {sum(h > 2.0 for h in head)} |")  # fmt: skip
    print()
    for r in sorted(rows, key=lambda r: -r[0])[:5]:
        print(f"{r[4]}: {r[0]:.3f} m, {r[1]:.2f}°, weight {r[2]:.2f}, {r[3]}")


if __name__ == "__main__":
    main()
