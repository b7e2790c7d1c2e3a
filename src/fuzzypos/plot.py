"""Figures of the paper's §5 (Figs. 13–20) and a run overview, drawn with matplotlib.

Every function builds its own :class:`matplotlib.figure.Figure` with an Agg canvas attached,
returns it, and writes a PNG when given ``path``. Nothing here touches ``pyplot`` or selects a
backend, so importing this module or drawing with it never opens a window, never registers a
figure with pyplot and never changes ``matplotlib.get_backend()``.

Feature figures (13–18) are drawn in the robot frame of one scan (the robot at the origin,
heading along +x); path figures (19, the map) in the world frame. All points are drawn with one
artist per kind (no Python loop over points); lines and segments go into a LineCollection.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from numpy.typing import ArrayLike, NDArray

from .features import Features
from .geometry import transform_points

FloatArray = NDArray[np.float64]

__all__ = [
    "DPI",
    "FEATURE_FIGURES",
    "UNCERTAINTY_CMAP",
    "UNCERTAINTY_LABEL",
    "error_crossings",
    "plot_angular_points",
    "plot_break_points",
    "plot_clusters",
    "plot_errors_vs_distance",
    "plot_feature_figures",
    "plot_filtering",
    "plot_lines",
    "plot_map",
    "plot_paths",
    "plot_virtual_points",
]

DPI = 120
FIGSIZE = (7.0, 6.0)
UNCERTAINTY_CMAP = "viridis"  # dark = certain (0), yellow = uncertain (1)
UNCERTAINTY_LABEL = "uncertainty (0 = certain)"
_POINT_COLOUR = "0.55"
_UNC_NORM = (0.0, 1.0)

# the paper's figure number -> (file stem, title)
FEATURE_FIGURES: dict[int, tuple[str, str]] = {
    13: ("filtering", "Fig. 13 — data filtering"),
    14: ("break_points", "Fig. 14 — break points"),
    15: ("angular_points", "Fig. 15 — angular points"),
    16: ("clusters", "Fig. 16 — clusters"),
    17: ("lines", "Fig. 17 — line features"),
    18: ("virtual_angular_points", "Fig. 18 — virtual angular points"),
}


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
def _new_figure(figsize: tuple[float, float] = FIGSIZE) -> tuple[Figure, Axes]:
    """A figure with an Agg canvas (no pyplot, no GUI backend) and one axes."""
    fig = Figure(figsize=figsize, dpi=DPI)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    return fig, ax


def _finish(
    fig: Figure, ax: Axes, title: str, path: str | Path | None, equal: bool = True
) -> Figure:
    if equal:
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    ax.set_title(title)
    ax.grid(True, linewidth=0.4, alpha=0.5)
    handles, _labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(loc="best", fontsize="small", framealpha=0.8)
    fig.tight_layout()
    if path is not None:
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(p, dpi=DPI, format="png")
    return fig


def _xy(a: ArrayLike | None, what: str) -> FloatArray | None:
    """An (n, 2) array from (n, >=2) input (poses are accepted: their x, y are used)."""
    if a is None:
        return None
    arr = np.asarray(a, dtype=float)
    if arr.ndim != 2 or arr.shape[1] < 2:
        raise ValueError(f"{what} must be an (n, 2) or (n, 3) array, got shape {arr.shape}")
    return arr[:, :2]


def _draw_robot(ax: Axes, points: FloatArray) -> None:
    """The robot at the origin of its frame, an arrow along +x for its heading."""
    span = float(np.ptp(points, axis=0).max()) if points.shape[0] else 4.0
    length = max(0.06 * span, 0.25)
    ax.arrow(
        0.0,
        0.0,
        length,
        0.0,
        width=0.12 * length,
        head_width=0.4 * length,
        head_length=0.35 * length,
        length_includes_head=True,
        color="crimson",
        zorder=5,
        gid="robot_heading",
    )
    ax.plot([0.0], [0.0], "o", color="crimson", markersize=6, zorder=6, gid="robot", label="robot")


def _uncertainty_colorbar(
    fig: Figure, ax: Axes, mappable: Any, label: str = UNCERTAINTY_LABEL
) -> None:
    cb = fig.colorbar(mappable, ax=ax, shrink=0.85, pad=0.02)
    cb.set_label(label)


def _points_background(ax: Axes, pts: FloatArray, label: str = "kept points") -> None:
    ax.scatter(
        pts[:, 0],
        pts[:, 1],
        s=5,
        c=_POINT_COLOUR,
        linewidths=0,
        label=label,
        gid="kept_points",
        zorder=2,
    )


def _segments(start: FloatArray, end: FloatArray) -> FloatArray:
    """(k, 2, 2) segments for a LineCollection."""
    return np.stack([start, end], axis=1) if start.shape[0] else np.zeros((0, 2, 2))


def _as_segments(segments: FloatArray) -> Sequence[ArrayLike]:
    """A ``(k, 2, 2)`` array as LineCollection's segments: it takes the array as it is, but
    matplotlib's type hints only admit a sequence."""
    return cast("Sequence[ArrayLike]", segments)


def _title(default: str, title: str | None) -> str:
    return default if title is None else title


# ---------------------------------------------------------------------------------------------
# Figs. 13–18: one scan's features, robot frame
# ---------------------------------------------------------------------------------------------
def plot_filtering(
    features: Features, path: str | Path | None = None, title: str | None = None
) -> Figure:
    """Fig. 13: kept points coloured by their fuzzy uncertainty (eq. 4); the points removed by
    filtering (β ≤ ξ_TH, §3.1) as grey crosses; the robot at the origin with its heading."""
    fig, ax = _new_figure()
    kept = features.kept
    kp = features.points[kept]
    rp = features.points[~kept]
    sc = ax.scatter(
        kp[:, 0],
        kp[:, 1],
        s=9,
        c=features.uncertainty[kept],
        cmap=UNCERTAINTY_CMAP,
        vmin=_UNC_NORM[0],
        vmax=_UNC_NORM[1],
        linewidths=0,
        zorder=3,
        label=f"kept ({kp.shape[0]})",
        gid="kept_points",
    )
    ax.scatter(
        rp[:, 0],
        rp[:, 1],
        s=22,
        marker="x",
        c="0.5",
        linewidths=0.9,
        zorder=2,
        label=f"removed, β ≤ ξ_TH ({rp.shape[0]})",
        gid="removed_points",
    )
    _draw_robot(ax, features.points)
    _uncertainty_colorbar(fig, ax, sc)
    return _finish(fig, ax, _title(FEATURE_FIGURES[13][1], title), path)


def plot_break_points(
    features: Features, path: str | Path | None = None, title: str | None = None
) -> Figure:
    """Fig. 14: kept points with the break points of eq. 13 (red) and the field-of-view edges
    (the ends of a scan that is not a full circle, orange squares) distinguished."""
    fig, ax = _new_figure()
    kp = features.kept_points
    _points_background(ax, kp)
    fov = features.is_field_of_view_edge
    brk = features.is_break_point & ~fov
    b = kp[brk]
    e = kp[fov]
    ax.scatter(
        b[:, 0],
        b[:, 1],
        s=40,
        marker="o",
        facecolors="none",
        edgecolors="red",
        linewidths=1.3,
        zorder=4,
        label=f"break points ({b.shape[0]})",
        gid="break_points",
    )
    ax.scatter(
        e[:, 0],
        e[:, 1],
        s=55,
        marker="s",
        facecolors="none",
        edgecolors="darkorange",
        linewidths=1.3,
        zorder=4,
        label=f"field-of-view edges ({e.shape[0]})",
        gid="fov_edges",
    )
    _draw_robot(ax, features.points)
    return _finish(fig, ax, _title(FEATURE_FIGURES[14][1], title), path)


def plot_angular_points(
    features: Features, path: str | Path | None = None, title: str | None = None
) -> Figure:
    """Fig. 15: kept points with the angular points of eq. 14: the sampled corner points (open
    circles) and their positions as used (refined to their lines' intersection where that was
    done, stars coloured by uncertainty), joined by a short segment where they differ."""
    fig, ax = _new_figure()
    kp = features.kept_points
    _points_background(ax, kp)
    sampled = kp[features.is_angular_point]
    ang = features.angular_points
    ax.scatter(
        sampled[:, 0],
        sampled[:, 1],
        s=45,
        marker="o",
        facecolors="none",
        edgecolors="black",
        linewidths=1.0,
        zorder=4,
        label=f"sampled corner points ({sampled.shape[0]})",
        gid="angular_sampled",
    )
    if ang.xy.shape == sampled.shape:
        moved = np.hypot(*(ang.xy - sampled).T) > 1e-9 if sampled.shape[0] else np.zeros(0, bool)
        ax.add_collection(
            LineCollection(
                _as_segments(_segments(sampled[moved], ang.xy[moved])),
                colors="black",
                linewidths=0.8,
                zorder=4,
                gid="angular_refinement",
            )
        )
    sc = ax.scatter(
        ang.xy[:, 0],
        ang.xy[:, 1],
        s=110,
        marker="*",
        c=ang.uncertainty,
        cmap=UNCERTAINTY_CMAP,
        vmin=_UNC_NORM[0],
        vmax=_UNC_NORM[1],
        edgecolors="black",
        linewidths=0.5,
        zorder=5,
        label=f"angular points ({len(ang)})",
        gid="angular_points",
    )
    _draw_robot(ax, features.points)
    _uncertainty_colorbar(fig, ax, sc)
    return _finish(fig, ax, _title(FEATURE_FIGURES[15][1], title), path)


def plot_clusters(
    features: Features, path: str | Path | None = None, title: str | None = None
) -> Figure:
    """Fig. 16: kept points coloured by cluster (§3.3); points of dropped clusters (too small
    to fit a line) grey; the number of clusters in the title and each cluster's id at its
    centroid."""
    fig, ax = _new_figure()
    kp = features.kept_points
    cl = features.cluster
    n_clusters = features.n_clusters
    ok = cl >= 0
    cmap = _qualitative_cmap(n_clusters)
    pts = kp[ok]
    ids = cl[ok]
    ax.scatter(
        pts[:, 0],
        pts[:, 1],
        s=10,
        c=cmap(ids % cmap.N) if ids.size else np.zeros((0, 4)),
        linewidths=0,
        zorder=3,
        label=f"{n_clusters} clusters",
        gid="cluster_points",
    )
    d = kp[~ok]
    ax.scatter(
        d[:, 0],
        d[:, 1],
        s=12,
        marker="x",
        c="0.6",
        linewidths=0.8,
        zorder=2,
        label=f"dropped ({d.shape[0]} points)",
        gid="dropped_points",
    )
    if ids.size:
        count = np.bincount(ids, minlength=n_clusters)
        cx = np.bincount(ids, weights=pts[:, 0], minlength=n_clusters) / np.maximum(count, 1)
        cy = np.bincount(ids, weights=pts[:, 1], minlength=n_clusters) / np.maximum(count, 1)
        for k in np.flatnonzero(count):  # one label per cluster
            ax.annotate(
                str(k),
                (cx[k], cy[k]),
                fontsize=7,
                color=cmap(k % cmap.N),
                ha="center",
                va="center",
                xytext=(0, 8),
                textcoords="offset points",
                zorder=6,
            )
    _draw_robot(ax, features.points)
    default = f"{FEATURE_FIGURES[16][1]}: {n_clusters} clusters"
    return _finish(fig, ax, _title(default, title), path)


def _qualitative_cmap(n: int) -> Any:
    return colormaps["tab10" if n <= 10 else "tab20"]


def _line_collection(
    features: Features, linewidth: float = 2.2, gid: str = "lines"
) -> LineCollection:
    lines = features.lines
    lc = LineCollection(
        _as_segments(_segments(lines.start, lines.end)),
        cmap=UNCERTAINTY_CMAP,
        norm=Normalize(*_UNC_NORM),
        linewidths=linewidth,
        zorder=3,
        gid=gid,
        label=f"lines ({len(lines)})",
    )
    lc.set_array(np.asarray(lines.uncertainty, dtype=float))
    return lc


def plot_lines(
    features: Features, path: str | Path | None = None, title: str | None = None
) -> Figure:
    """Fig. 17: kept points with the fitted line segments (start → end, §3.5) coloured by the
    line's fuzzy uncertainty (eq. 9), their centres marked."""
    fig, ax = _new_figure()
    _points_background(ax, features.kept_points)
    lc = _line_collection(features)
    ax.add_collection(lc)
    c = features.lines.centre
    ax.scatter(
        c[:, 0], c[:, 1], s=14, marker="+", c="black", linewidths=0.8, zorder=4, gid="line_centres"
    )
    _draw_robot(ax, features.points)
    _uncertainty_colorbar(fig, ax, lc, "line uncertainty (0 = certain)")
    return _finish(fig, ax, _title(FEATURE_FIGURES[17][1], title), path)


def plot_virtual_points(
    features: Features, path: str | Path | None = None, title: str | None = None
) -> Figure:
    """Fig. 18: the line segments, the virtual angular points (§3.6) sized and coloured by
    uncertainty (bigger = more certain), each joined by dotted extensions to the nearer end of
    its two lines, and the real angular points."""
    fig, ax = _new_figure()
    _points_background(ax, features.kept_points)
    lines = features.lines
    ax.add_collection(_line_collection(features, linewidth=1.8))
    vp = features.virtual_points
    vl = features.virtual_lines
    if len(vp) and len(lines):
        # dotted extension from each virtual point to the nearer endpoint of each of its lines
        pts = np.repeat(vp.xy, 2, axis=0)
        li = vl.reshape(-1)
        s, e = lines.start[li], lines.end[li]
        ds = np.hypot(*(s - pts).T)
        de = np.hypot(*(e - pts).T)
        near = np.where((ds <= de)[:, None], s, e)
        ext = _segments(pts, near)
    else:
        ext = np.zeros((0, 2, 2))
    ax.add_collection(
        LineCollection(
            _as_segments(ext),
            colors="0.35",
            linestyles=":",
            linewidths=0.9,
            zorder=2,
            gid="virtual_extensions",
        )
    )
    size = 20.0 + 100.0 * (1.0 - np.clip(vp.uncertainty, 0.0, 1.0))
    sc = ax.scatter(
        vp.xy[:, 0],
        vp.xy[:, 1],
        s=size,
        marker="D",
        c=vp.uncertainty,
        cmap=UNCERTAINTY_CMAP,
        vmin=_UNC_NORM[0],
        vmax=_UNC_NORM[1],
        edgecolors="black",
        linewidths=0.6,
        zorder=5,
        label=f"virtual angular points ({len(vp)})",
        gid="virtual_points",
    )
    ang = features.angular_points
    ax.scatter(
        ang.xy[:, 0],
        ang.xy[:, 1],
        s=110,
        marker="*",
        facecolors="none",
        edgecolors="crimson",
        linewidths=1.0,
        zorder=6,
        label=f"angular points ({len(ang)})",
        gid="angular_points",
    )
    _draw_robot(ax, features.points)
    _uncertainty_colorbar(fig, ax, sc)
    return _finish(fig, ax, _title(FEATURE_FIGURES[18][1], title), path)


_FEATURE_PLOTTERS = {
    13: plot_filtering,
    14: plot_break_points,
    15: plot_angular_points,
    16: plot_clusters,
    17: plot_lines,
    18: plot_virtual_points,
}


def plot_feature_figures(
    features: Features, out_dir: str | Path, scan_index: int, prefix: str = "fig"
) -> dict[int, Path]:
    """Write Figs. 13–18 for one scan as ``{prefix}13_filtering.png`` …
    ``{prefix}18_virtual_angular_points.png`` in ``out_dir`` (created if missing), titled
    "Fig. 13 — …, scan {scan_index}". Returns ``{13: path, …, 18: path}``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: dict[int, Path] = {}
    for num, (stem, base_title) in FEATURE_FIGURES.items():
        path = out / f"{prefix}{num}_{stem}.png"
        title = f"{base_title}, scan {scan_index}"
        if num == 16:
            title = f"{base_title}: {features.n_clusters} clusters, scan {scan_index}"
        _FEATURE_PLOTTERS[num](features, path=path, title=title)
        written[num] = path
    return written


# ---------------------------------------------------------------------------------------------
# Figs. 19–20: paths and errors
# ---------------------------------------------------------------------------------------------
def _draw_world(ax: Axes, world: Any) -> None:
    if world is None:
        return
    segs = np.asarray(world.segments, dtype=float).reshape(-1, 4)
    ax.add_collection(
        LineCollection(
            _as_segments(segs.reshape(-1, 2, 2)),
            colors="0.6",
            linewidths=0.7,
            zorder=1,
            gid="world",
        )
    )


def plot_paths(
    true_xy: ArrayLike | None,
    odometry_xy: ArrayLike | None,
    estimates: Mapping[str, ArrayLike],
    path: str | Path | None = None,
    title: str | None = None,
    world: Any = None,
) -> Figure:
    """Fig. 19: the true path, the odometry path and one or more estimated paths (one line
    each, labelled by its key), in the world frame with equal aspect, the start marked.

    Paths are (n, 2) or (n, 3) arrays (poses: x, y are used); ``true_xy`` or ``odometry_xy``
    may be None (a real log has no ground truth). ``world``, an object with ``.segments``
    (m, 4), is drawn as thin grey lines.
    """
    fig, ax = _new_figure()
    _draw_world(ax, world)
    start: FloatArray | None = None
    true = _xy(true_xy, "true_xy")
    if true is not None:
        ax.plot(
            true[:, 0],
            true[:, 1],
            "-",
            color="black",
            linewidth=1.8,
            label="true path",
            gid="path:true",
            zorder=3,
        )
        start = true[0] if true.shape[0] else None
    odo = _xy(odometry_xy, "odometry_xy")
    if odo is not None:
        ax.plot(
            odo[:, 0],
            odo[:, 1],
            "--",
            color="tab:red",
            linewidth=1.4,
            label="odometry",
            gid="path:odometry",
            zorder=3,
        )
        if start is None and odo.shape[0]:
            start = odo[0]
    colours = ["tab:blue", "tab:green", "tab:purple", "tab:orange", "tab:cyan", "tab:olive"]
    for k, (label, xy) in enumerate(estimates.items()):
        e = _xy(xy, f"estimates[{label!r}]")
        assert e is not None
        ax.plot(
            e[:, 0],
            e[:, 1],
            "-",
            color=colours[k % len(colours)],
            linewidth=1.4,
            label=str(label),
            gid=f"path:{label}",
            zorder=4,
        )
        if start is None and e.shape[0]:
            start = e[0]
    if start is not None:
        ax.plot(
            [start[0]],
            [start[1]],
            "o",
            color="black",
            markerfacecolor="white",
            markersize=9,
            markeredgewidth=1.5,
            label="start",
            gid="start",
            zorder=6,
        )
    return _finish(fig, ax, _title("Fig. 19 — paths", title), path)


def error_crossings(distance: ArrayLike, error: ArrayLike, reference: ArrayLike) -> FloatArray:
    """The distances at which the curve ``error`` crosses ``reference`` (both sampled at
    ``distance``), linearly interpolated. Samples where either is not finite are ignored; a
    curve that touches the reference without crossing it gives no crossing; where the two are
    equal over a stretch, the crossing is where they first meet."""
    d = np.asarray(distance, dtype=float)
    diff = np.asarray(error, dtype=float) - np.asarray(reference, dtype=float)
    if d.shape != diff.shape or d.ndim != 1:
        raise ValueError(
            "distance, error and reference must be equal-length 1-D arrays, "
            f"got {d.shape} and {diff.shape}"
        )
    ok = np.isfinite(d) & np.isfinite(diff)
    d, diff = d[ok], diff[ok]
    sign = np.sign(diff)
    nz = np.flatnonzero(sign)  # samples off the reference
    if nz.size < 2:
        return np.zeros(0)
    j, k = nz[:-1], nz[1:]
    flips = sign[j] != sign[k]
    j, k = j[flips], k[flips]
    adjacent = k == j + 1
    dj, dk = diff[j], diff[k]
    frac = dj / (dj - dk)  # dj and dk have opposite signs: no division by zero
    interp = d[j] + frac * (d[k] - d[j])
    first_zero = d[np.minimum(j + 1, d.size - 1)]
    crossings: FloatArray = np.where(adjacent, interp, first_zero)
    return crossings


def plot_errors_vs_distance(
    distance: ArrayLike,
    errors: Mapping[str, ArrayLike],
    path: str | Path | None = None,
    title: str | None = None,
    reference: str = "odometry",
) -> Figure:
    """Fig. 20: position error against distance travelled, one curve per label (e.g.
    "odometry", "paper", "default"), with every crossing of an estimate's curve with the
    ``reference`` curve (odometry's) marked and the first one annotated."""
    d = np.asarray(distance, dtype=float)
    if d.ndim != 1:
        raise ValueError(f"distance must be 1-D, got shape {d.shape}")
    curves = {}
    for label, e in errors.items():
        arr = np.asarray(e, dtype=float)
        if arr.shape != d.shape:
            raise ValueError(f"errors[{label!r}] has shape {arr.shape}, distance {d.shape}")
        curves[str(label)] = arr
    fig, ax = _new_figure((7.5, 4.8))
    colours = {"odometry": "tab:red", "paper": "tab:blue", "default": "tab:green"}
    spare = iter(
        ["tab:purple", "tab:orange", "tab:cyan", "tab:olive", "tab:brown", "tab:pink"] * 10
    )
    colour_of = {label: colours.get(label) or next(spare) for label in curves}
    for label, e in curves.items():
        style = "--" if label == reference else "-"
        ax.plot(
            d, e, style, color=colour_of[label], linewidth=1.5, label=label, gid=f"error:{label}"
        )
    ref = curves.get(reference)
    if ref is not None:
        for label, e in curves.items():
            if label == reference:
                continue
            x = error_crossings(d, e, ref)
            y = np.interp(x, d, e) if x.size else np.zeros(0)
            ax.scatter(
                x,
                y,
                s=60,
                marker="o",
                facecolors="none",
                edgecolors=colour_of[label],
                linewidths=1.6,
                zorder=5,
                gid=f"crossing:{label}",
                label=f"{label} crosses {reference}" if x.size else None,
            )
            if x.size:
                ax.axvline(
                    x[0],
                    color=colour_of[label],
                    linestyle=":",
                    linewidth=0.9,
                    gid=f"crossing_line:{label}",
                )
                ax.annotate(
                    f"{x[0]:.1f} m",
                    (x[0], y[0]),
                    xytext=(6, -14),
                    textcoords="offset points",
                    fontsize=8,
                    color=colour_of[label],
                )
    ax.set_xlabel("distance travelled [m]")
    ax.set_ylabel("position error [m]")
    ax.set_xlim(left=0.0 if d.size == 0 or np.nanmin(d) >= 0 else None)
    ax.set_ylim(bottom=0.0)
    return _finish(
        fig,
        ax,
        _title("Fig. 20 — position error against distance travelled", title),
        path,
        equal=False,
    )


# ---------------------------------------------------------------------------------------------
# run overview
# ---------------------------------------------------------------------------------------------
def plot_map(
    poses: ArrayLike,
    scans_points: Sequence[ArrayLike | None],
    odometry: ArrayLike | None = None,
    path: str | Path | None = None,
    title: str | None = None,
    max_points: int = 30_000,
    world: Any = None,
) -> Figure:
    """A run's overview: the scans' points (each scan's, in its robot frame, moved by that
    scan's estimated pose) drawn as a map, the estimated path and the odometry path.

    ``poses`` and ``odometry`` are (n, 3); ``scans_points`` has one (k_i, 2) array per pose
    (None or empty for a scan without points; NaN rows, e.g. invalid beams, are skipped). At
    most ``max_points`` map points are drawn, evenly subsampled.
    """
    P = np.asarray(poses, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3:
        raise ValueError(f"poses must be an (n, 3) array, got shape {P.shape}")
    if len(scans_points) != P.shape[0]:
        raise ValueError(f"got {P.shape[0]} poses but {len(scans_points)} scans")
    parts = [
        np.zeros((0, 2)) if s is None else np.asarray(s, dtype=float).reshape(-1, 2)
        for s in scans_points
    ]
    counts = np.array([p.shape[0] for p in parts], dtype=np.int64)
    total = int(counts.sum())
    if total:
        owner = np.repeat(np.arange(P.shape[0]), counts)
        pts = np.concatenate(parts)
        finite = np.isfinite(pts).all(axis=1)  # invalid beams come as NaN rows
        if not finite.all():
            pts, owner = pts[finite], owner[finite]
            total = pts.shape[0]
        if total > max_points > 0:
            pick = np.unique(np.linspace(0, total - 1, max_points).astype(np.int64))
            pts, owner = pts[pick], owner[pick]
        world_pts = transform_points(P[owner], pts)
    else:
        world_pts = np.zeros((0, 2))
    fig, ax = _new_figure((8.0, 7.0))
    _draw_world(ax, world)
    ax.scatter(
        world_pts[:, 0],
        world_pts[:, 1],
        s=1.0,
        c="0.25",
        alpha=0.5,
        linewidths=0,
        zorder=2,
        label=f"map ({world_pts.shape[0]} points)",
        gid="map_points",
        rasterized=True,
    )
    odo = _xy(odometry, "odometry")
    if odo is not None:
        ax.plot(
            odo[:, 0],
            odo[:, 1],
            "--",
            color="tab:red",
            linewidth=1.3,
            label="odometry",
            gid="path:odometry",
            zorder=3,
        )
    ax.plot(
        P[:, 0],
        P[:, 1],
        "-",
        color="tab:blue",
        linewidth=1.5,
        label="estimate",
        gid="path:estimate",
        zorder=4,
    )
    if P.shape[0]:
        ax.plot(
            [P[0, 0]],
            [P[0, 1]],
            "o",
            color="black",
            markerfacecolor="white",
            markersize=8,
            markeredgewidth=1.5,
            label="start",
            gid="start",
            zorder=6,
        )
    return _finish(fig, ax, _title("Estimated path and map", title), path)
