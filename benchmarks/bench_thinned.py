"""Large steps between scans: the default front end on the shared logs thinned to a scan every
0.5 m or 10° (and every 1 m or 20°) of odometry, against the same on the full logs, scored on
the same relations (issue 34, item 5).

    OMP_NUM_THREADS=1 python benchmarks/bench_thinned.py [--data ../shared/data]
        [--logs intel,aces,fr079,fr-clinic] [--thinnings 0.5,1] [--keep DIR] [--out PATH]

The logs are thinned by ``thinning.py`` (its docstring says which scans are kept and how
the thinned log is written and checked before it is run).

Both logs go through ``Positioner()`` (the default front end) as ``bench_peers.py`` runs it,
one thread, and are scored with ``fuzzypos.eval.metrics.relations_errors`` on the log's
relations: all relations and local ones (t2 − t1 <= 10 s), mean translational (m) and
rotational (degrees) errors, and each thinned figure over the full log's (the issue's target:
at most 1.15). The table is printed and written as markdown to ``--out`` (default
``docs/benchmarks/thinned.md``) with the date, commit, machine and command, and as JSON
beside it. With ``--peers``, ``bench_peers.py``'s small_gicp variants run on the same full and
thinned logs too, and fuzzypos's local rotational error is compared with the better
variant's (the issue's target: at most 1.2 times it); ``bench_peers.py --logs
intel-thin-0.5,…`` runs every peer on the same thinned logs (``thinning.thinned_log``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS"):
    os.environ[_var] = "1"  # one thread, set before numpy loads

import argparse  # noqa: E402
import datetime  # noqa: E402
import shlex  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from fuzzypos.io import (  # noqa: E402
    read_relations,
)
from fuzzypos.io.provenance import write_json  # noqa: E402

sys.path.insert(0, os.fspath(Path(__file__).resolve().parent))
import bench_peers  # noqa: E402
from bench_honesty import commit, machine  # noqa: E402
from thinning import (  # noqa: E402
    LOGS,
    THINNINGS,
    thin_log,
)

#: the issue's target: a thinned figure at most this many times the full log's
TARGET_RATIO = 1.15
#: the issue's target on the thinned logs: fuzzypos's local rotation at most this many times
#: the better small_gicp variant's
PEER_TARGET_RATIO = 1.2
#: the figures compared (relations_errors().as_dict() keys) and their headings
FIGURES = {
    "all_trans_mean_m": "all trans m",
    "all_rot_mean_deg": "all rot °",
    "local_trans_mean_m": "local trans m",
    "local_rot_mean_deg": "local rot °",
}


def run_default(log_path: Path, relations: Any, method: Any = None) -> dict[str, Any]:
    """The default front end (or ``method``, a ``bench_peers.Method``) along the log
    (``bench_peers.run_method``), scored; ``degraded``: its degraded estimates (fallbacks)."""
    method = bench_peers.FuzzyposDefault() if method is None else method
    run = bench_peers.run_method(method, log_path, None)
    row = bench_peers.score(run["stamps"], run["poses"], relations)
    row.update(
        scans=run["scans"],
        matcher_ms_per_scan=1000.0 * run["matcher_seconds"] / max(run["scans"], 1),
        degraded=method.fallbacks,
    )
    return row


def small_gicp_methods() -> list[Any]:
    """``bench_peers.py``'s small_gicp variants (empty where small_gicp is not installed)."""
    if bench_peers.small_gicp is None:
        return []
    return [
        bench_peers.SmallGicp("GICP"),
        bench_peers.SmallGicp("PLANE_ICP"),
        bench_peers.SmallGicp("GICP", scan_to_scan=True),
    ]


def peer_row(label: str, fuzzypos_row: dict[str, Any], log_path: Path, relations: Any) -> dict:
    """small_gicp's variants on a log; the better local rotation and fuzzypos's over it."""
    out: dict[str, Any] = {"label": label, "fuzzypos_local_rot_mean_deg": None, "variants": {}}
    out["fuzzypos_local_rot_mean_deg"] = fuzzypos_row.get("local_rot_mean_deg")
    for method in small_gicp_methods():
        r = run_default(log_path, relations, method)
        out["variants"][method.name] = {k: r.get(k) for k in (*FIGURES, "degraded")}
    rots = {
        name: v["local_rot_mean_deg"]
        for name, v in out["variants"].items()
        if v.get("local_rot_mean_deg") is not None
    }
    if rots and out["fuzzypos_local_rot_mean_deg"] is not None:
        best = min(rots, key=lambda name: rots[name])
        out.update(
            best=best,
            best_local_rot_mean_deg=rots[best],
            ratio=out["fuzzypos_local_rot_mean_deg"] / rots[best],
        )
    return out


def peer_table(rows: list[dict[str, Any]]) -> str:
    names = list(dict.fromkeys(n for r in rows for n in r["variants"]))
    lines = [
        "| log | fuzzypos local rot ° | "
        + " | ".join(f"{n} local rot °" for n in names)
        + " | fuzzypos ÷ the better |",
        "|---|---:|" + "---:|" * (len(names) + 1),
    ]
    for r in rows:
        cells = []
        for n in names:
            v = r["variants"].get(n, {}).get("local_rot_mean_deg")
            cells.append("–" if v is None else f"{v:.3f}")
        ratio = "–"
        if "ratio" in r:
            ratio = f"{r['ratio']:.2f}" + (" ✗" if r["ratio"] > PEER_TARGET_RATIO else "")
        f = r["fuzzypos_local_rot_mean_deg"]
        lines.append(
            f"| {r['label']} | {'–' if f is None else f'{f:.3f}'} | {' | '.join(cells)} | {ratio} |"
        )
    return "\n".join(lines)


def ratios(row: dict[str, Any], full: dict[str, Any]) -> dict[str, float]:
    return {k: row[k] / full[k] for k in FIGURES if k in row and k in full and full[k] > 0}


def table(rows: list[dict[str, Any]]) -> str:
    heads = " | ".join(FIGURES.values())
    ratio_heads = " | ".join(f"{h} ÷ full" for h in FIGURES.values())
    lines = [
        f"| log | scans | degraded | {heads} | {ratio_heads} |",
        "|---|---:|---:|" + "---:|" * (2 * len(FIGURES)),
    ]
    for r in rows:
        if "not_scored" in r:
            lines.append(f"| {r['label']} | {r['scans']} | | not scored: {r['not_scored']} |")
            continue
        figs = " | ".join(f"{r[k]:.4f}" if k.endswith("_m") else f"{r[k]:.3f}" for k in FIGURES)
        rat = r.get("ratios")
        if rat is None:
            rats = " | ".join("" for _ in FIGURES)
        else:
            rats = " | ".join(
                "–" if k not in rat else f"{rat[k]:.2f}" + (" ✗" if rat[k] > TARGET_RATIO else "")
                for k in FIGURES
            )
        scans = f"{r['scans']}"
        if "relation_end_scans" in r:
            scans += f" ({r['relation_end_scans']} relation ends)"
        lines.append(f"| {r['label']} | {scans} | {r.get('degraded', '–')} | {figs} | {rats} |")
    return "\n".join(lines)


def markdown(
    rows: list[dict[str, Any]], meta: dict[str, str], peers: list[dict[str, Any]] | None = None
) -> str:
    text = (
        "# The default front end on thinned logs (issue 34, item 5)\n\n"
        f"- date: {meta['date']}\n"
        f"- commit: {meta['commit']}\n"
        f"- machine: {meta['machine']}\n"
        f"- command: `{meta['command']}`\n"
        f"- data: {meta['data']}\n\n"
        "Each shared log thinned to every relation's end scans plus a scan each time the "
        "odometry moved 0.5 m or 10° (`thin 0.5`), or 1 m or 20° (`thin 1`), since the last "
        "scan kept; `Positioner()` (the default) on the full and the thinned logs, scored on "
        "the same relations: mean errors over all relations and the local ones (t2 − t1 ≤ "
        f"10 s), and the thinned over the full figure (✗: above the target {TARGET_RATIO}). "
        "`benchmarks/bench_thinned.py`'s docstring has the details.\n\n" + table(rows) + "\n"
    )
    if peers:
        text += (
            "\n## Local rotation against small_gicp on the same logs\n\n"
            "`bench_peers.py`'s small_gicp variants (points extruded into three layers, the "
            "odometry increment as the guess) on the same thinned and full logs; fuzzypos's "
            "local rotational error over the better variant's (✗: above the issue's target "
            f"{PEER_TARGET_RATIO}).\n\n" + peer_table(peers) + "\n"
        )
    return text


def main(argv: list[str] | None = None) -> None:
    here = Path(__file__).resolve().parent
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--data",
        default=os.environ.get("FUZZYPOS_DATA", os.fspath(here.parent.parent / "shared" / "data")),
        help="the shared data folder (default: $FUZZYPOS_DATA, else ../shared/data)",
    )
    ap.add_argument("--logs", default=",".join(LOGS), help=f"of {', '.join(LOGS)}")
    ap.add_argument("--thinnings", default=",".join(THINNINGS), help=f"of {', '.join(THINNINGS)}")
    ap.add_argument("--keep", type=Path, default=None, help="write the thinned logs here")
    ap.add_argument(
        "--out",
        type=Path,
        default=here.parent / "docs" / "benchmarks" / "thinned.md",
        help="the markdown to write (a JSON beside it); default docs/benchmarks/thinned.md",
    )
    ap.add_argument("--no-write", action="store_true", help="print only")
    ap.add_argument(
        "--peers",
        action="store_true",
        help="also run bench_peers.py's small_gicp variants on the same full and thinned logs "
        "and compare the local rotation (pip install -e '.[bench]')",
    )
    args = ap.parse_args(argv)
    if args.peers and not small_gicp_methods():
        sys.exit(f"--peers: small_gicp is not installed ({bench_peers.INSTALL_HINT})")
    names = [s.strip() for s in args.logs.split(",") if s.strip()]
    keys = [s.strip() for s in args.thinnings.split(",") if s.strip()]
    if [n for n in names if n not in LOGS] or [k for k in keys if k not in THINNINGS]:
        ap.error(f"--logs of {', '.join(LOGS)}; --thinnings of {', '.join(THINNINGS)}")
    data = Path(args.data)
    scratch = None
    if args.keep is None:
        scratch = tempfile.TemporaryDirectory(prefix="bench-thinned-")
        folder = Path(scratch.name)
    else:
        folder = args.keep
        folder.mkdir(parents=True, exist_ok=True)

    print(f"fuzzypos: kernels ready in {bench_peers.warm_up():.1f} s", file=sys.stderr)
    rows: list[dict[str, Any]] = []
    peers: list[dict[str, Any]] = []
    for name in names:
        log_path, rel_path = (data / part for part in LOGS[name])
        if not log_path.exists() or not rel_path.exists():
            sys.exit(f"{log_path}: missing (or its relations); see --data")
        relations = read_relations(rel_path)
        t0 = time.perf_counter()
        full = {"label": f"{name} full", "log": name, "thinning": None}
        full.update(run_default(log_path, relations))
        rows.append(full)
        if args.peers:
            peers.append(peer_row(full["label"], full, log_path, relations))
        print(f"{name}: full in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
        for key in keys:
            t0 = time.perf_counter()
            out = folder / f"{name}-thin-{key}.clf"
            info = thin_log(log_path, rel_path, out, *THINNINGS[key])
            row: dict[str, Any] = {"label": f"{name} thin {key}", "log": name, "thinning": key}
            row.update(info)
            row.update(run_default(out, relations))
            row["ratios"] = ratios(row, full)
            rows.append(row)
            if args.peers:
                peers.append(peer_row(row["label"], row, out, relations))
            print(
                f"{name}: thin {key}: {info['scans_kept']} of {info['scans_full']} scans in "
                f"{time.perf_counter() - t0:.0f} s",
                file=sys.stderr,
            )
    if scratch is not None:
        scratch.cleanup()
    print(table(rows))
    if peers:
        print()
        print(peer_table(peers))
    if args.no_write:
        return
    meta = {
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "commit": commit(),
        "machine": machine(),
        "command": shlex.join(
            ["python", "benchmarks/bench_thinned.py", *(sys.argv[1:] if argv is None else argv)]
        ),
        "data": os.path.relpath(data, here.parent),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(markdown(rows, meta, peers), encoding="utf-8")
    write_json(
        args.out.with_suffix(".json"),
        {
            **meta,
            "thinnings": {k: {"distance_m": d, "angle_deg": a} for k, (d, a) in THINNINGS.items()},
            "target_ratio": TARGET_RATIO,
            "rows": rows,
            "peers": peers,
        },
    )
    print(f"\nwritten: {args.out} and {args.out.with_suffix('.json').name}", file=sys.stderr)


if __name__ == "__main__":
    main()
