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
from matplotlib.colors import Normalize, to_rgb
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle
from numpy.typing import ArrayLike, NDArray

from ..config import Config
from ..features import Features, rule_bases
from ..features.extract import virtual_candidates
from ..geometry import transform_points

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
    "too_uncertain_virtual_points",
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
        for k in np.flatnonzero(count):  # one label per cluster, on a tag of its colour
            colour = cmap(k % cmap.N)
            ax.annotate(
                str(k),
                (cx[k], cy[k]),
                fontsize=7,
                color=_ink_on(colour),
                bbox={"boxstyle": "round,pad=0.2", "fc": colour, "ec": "0.2", "lw": 0.5},
                ha="center",
                va="center",
                xytext=(0, 9),
                textcoords="offset points",
                zorder=6,
                gid=f"cluster_label:{k}",
            )
    _draw_robot(ax, features.points)
    default = f"{FEATURE_FIGURES[16][1]}: {n_clusters} clusters"
    return _finish(fig, ax, _title(default, title), path)


def _ink_on(colour: Any) -> str:
    """Black or white, whichever reads better on ``colour`` (by its relative luminance)."""
    rgb = np.asarray(to_rgb(colour))
    lin = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return "black" if float(lin @ (0.2126, 0.7152, 0.0722)) > 0.179 else "white"


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


def too_uncertain_virtual_points(features: Features, config: Config | None = None) -> FloatArray:
    """The virtual angular points that §3.6 considered on this scan and removed as more
    uncertain than ``virtual_points.max_uncertainty`` (``config``: the one the features were
    extracted with), without those on a real angular point (merged into it): (k, 2)."""
    cfg = config if config is not None else Config()
    lines, scale = features.lines, features.line_distance_scale
    pts, i, j, dv = virtual_candidates(lines, cfg, None, scale)
    f = rule_bases(cfg.fuzzy).virtual_points(lines.uncertainty[i], lines.uncertainty[j], dv / scale)
    ang = features.angular_points.xy
    if ang.shape[0] and pts.shape[0]:
        gap = np.hypot(*(pts[:, None, :] - ang[None, :, :]).transpose(2, 0, 1)).min(axis=1)
        on_corner = gap <= cfg.virtual_points.merge_distance
    else:
        on_corner = np.zeros(pts.shape[0], bool)
    removed: FloatArray = pts[(f > cfg.virtual_points.max_uncertainty) & ~on_corner]
    return removed


def plot_virtual_points(
    features: Features,
    path: str | Path | None = None,
    title: str | None = None,
    config: Config | None = None,
) -> Figure:
    """Fig. 18: the line segments, the virtual angular points (§3.6) sized and coloured by
    uncertainty (bigger = more certain), each joined by dotted extensions to the nearer end of
    its two lines, those removed as too uncertain as hollow diamonds
    (:func:`too_uncertain_virtual_points`), and the real angular points."""
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
    removed = too_uncertain_virtual_points(features, config)
    ax.scatter(
        removed[:, 0],
        removed[:, 1],
        s=45,
        marker="D",
        facecolors="none",
        edgecolors="0.3",
        linewidths=1.0,
        zorder=4,
        label=f"too uncertain, removed ({removed.shape[0]})",
        gid="virtual_removed",
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
    features: Features,
    out_dir: str | Path,
    scan_index: int,
    prefix: str = "fig",
    config: Config | None = None,
) -> dict[int, Path]:
    """Write Figs. 13–18 for one scan as ``{prefix}13_filtering.png`` …
    ``{prefix}18_virtual_angular_points.png`` in ``out_dir`` (created if missing), titled
    "Fig. 13 — …, scan {scan_index}"; ``config``: the one the features were extracted with.
    Returns ``{13: path, …, 18: path}``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: dict[int, Path] = {}
    for num, (stem, base_title) in FEATURE_FIGURES.items():
        path = out / f"{prefix}{num}_{stem}.png"
        title = f"{base_title}, scan {scan_index}"
        if num == 16:
            title = f"{base_title}: {features.n_clusters} clusters, scan {scan_index}"
        if num == 18:
            plot_virtual_points(features, path=path, title=title, config=config)
        else:
            _FEATURE_PLOTTERS[num](features, path=path, title=title)
        written[num] = path
    return written


# ---------------------------------------------------------------------------------------------
# Figs. 19–20: paths and errors
# ---------------------------------------------------------------------------------------------
def _draw_world(ax: Axes, world: Any, autolim: bool = True) -> None:
    """The world's walls, thin grey; with ``autolim`` off they do not widen the view."""
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
        ),
        autolim=autolim,
    )


_ESTIMATE_COLOURS = ("tab:blue", "tab:green", "tab:purple", "tab:orange", "tab:cyan", "tab:olive")

#: a path of Fig. 19: (gid key, legend label, (n, 2) points, line style)
_Track = tuple[str, str, FloatArray, dict[str, Any]]


def _tracks(
    true_xy: ArrayLike | None, odometry_xy: ArrayLike | None, estimates: Mapping[str, ArrayLike]
) -> list[_Track]:
    """The paths of Fig. 19 that have points, the truth first: a wide black line under the
    others, so that an estimate on top of it still shows it on both sides."""
    out: list[_Track] = []
    true = _xy(true_xy, "true_xy")
    if true is not None:
        out.append(("true", "true path", true, {"color": "black", "lw": 2.8, "zorder": 3}))
    odo = _xy(odometry_xy, "odometry_xy")
    if odo is not None:
        out.append(("odometry", "odometry", odo, {"color": "tab:red", "ls": "--", "lw": 1.4}))
    for k, (label, xy) in enumerate(estimates.items()):
        e = _xy(xy, f"estimates[{label!r}]")
        assert e is not None
        colour = _ESTIMATE_COLOURS[k % len(_ESTIMATE_COLOURS)]
        out.append((str(label), str(label), e, {"color": colour, "lw": 1.2, "zorder": 5}))
    return [t for t in out if t[2].shape[0]]


def _draw_tracks(ax: Axes, tracks: Sequence[_Track], zoom: bool = False) -> None:
    """Each path with its end (a square in its colour). In the zoom (gids ``zoom:…``) each
    end is joined to the true end by a dotted line and labelled with its distance."""
    prefix = "zoom:" if zoom else ""
    true_end = tracks[0][2][-1] if tracks and tracks[0][0] == "true" else None
    for key, label, xy, style in tracks:
        ax.plot(
            xy[:, 0],
            xy[:, 1],
            gid=f"{prefix}path:{key}",
            **{"zorder": 4, **style},
            label=None if zoom else label,
        )
        end = xy[-1]
        end_label = None if zoom or key != tracks[0][0] else "end"
        if zoom:
            end_label = "true end" if key == "true" else f"{label}'s end"
        if zoom and true_end is not None and key != "true":
            gap = float(np.hypot(*(end - true_end)))
            ax.plot(
                *np.stack([true_end, end]).T,
                ":",
                color=style["color"],
                lw=1.3,
                zorder=6,
                gid=f"zoom:gap:{key}",
            )
            end_label = f"{label} ends {gap:.2f} m off"
        ax.plot(
            [end[0]],
            [end[1]],
            "s",
            color=style["color"],
            markeredgecolor="black",
            markersize=10 if key == "true" else 7,  # the truth's shows behind a close one
            zorder=7,
            gid=f"{prefix}end:{key}",
            label=end_label,
        )


def _draw_start(
    ax: Axes, start: FloatArray, gid: str = "start", label: str | None = "start"
) -> None:
    """The start: a white circle ringed in black."""
    style: dict[str, Any] = {"color": "black", "markerfacecolor": "white", "markersize": 9}
    ax.plot([start[0]], [start[1]], "o", mew=1.5, zorder=6, label=label, gid=gid, **style)


def _box(points: FloatArray, pad_fraction: float, min_pad: float) -> tuple[FloatArray, float]:
    """The centre and half side of a square around ``points``, padded."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    half = 0.5 * float((hi - lo).max())
    return 0.5 * (lo + hi), half + max(pad_fraction * 2 * half, min_pad)


def _zoom_on_ends(ax: Axes, zax: Axes, tracks: Sequence[_Track], world: Any) -> None:
    """The zoom on the paths' ends (and the start, where odometry that believes in a closed
    path ends): the ends apart, the distance of each from the true end; its square marked on
    the main axes."""
    ends = np.array([xy[-1] for _k, _l, xy, _s in tracks] + [tracks[0][2][0]])
    centre, half = _box(ends, 0.15, 0.25)
    _draw_world(zax, world, autolim=False)
    _draw_tracks(zax, tracks, zoom=True)
    _draw_start(zax, tracks[0][2][0], gid="zoom:start", label=None)
    zax.set_xlim(centre[0] - half, centre[0] + half)
    zax.set_ylim(centre[1] - half, centre[1] + half)
    zax.set_aspect("equal", adjustable="box")
    zax.set_gid("zoom")
    zax.set_title("the ends, zoomed")
    zax.set_xlabel("x [m]")
    zax.grid(True, linewidth=0.4, alpha=0.5)
    zax.legend(loc="best", fontsize="small", framealpha=0.85)
    corner = (centre[0] - half, centre[1] - half)
    ax.add_patch(
        Rectangle(
            corner, 2 * half, 2 * half, fill=False, ec="0.25", lw=0.9, zorder=8, gid="zoom_region"
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
    each, labelled by its key), in the world frame with equal aspect, the start and each
    path's end marked; with two paths or more, a second panel zooms on the ends.

    Paths are (n, 2) or (n, 3) arrays (poses: x, y are used); ``true_xy`` or ``odometry_xy``
    may be None (a real log has no ground truth). ``world``, an object with ``.segments``
    (m, 4), is drawn as thin grey lines; the view is the paths' with a margin around.
    """
    tracks = _tracks(true_xy, odometry_xy, estimates)
    if len(tracks) < 2:
        fig, ax = _new_figure()
    else:
        fig = Figure(figsize=(11.5, 6.0), dpi=DPI)
        FigureCanvasAgg(fig)
        grid = fig.add_gridspec(1, 2, width_ratios=(1.6, 1.0))
        ax = fig.add_subplot(grid[0])
        _zoom_on_ends(ax, fig.add_subplot(grid[1]), tracks, world)
    _draw_world(ax, world, autolim=not tracks)  # the view is the paths', not the world's
    _draw_tracks(ax, tracks)
    if tracks:
        _draw_start(ax, tracks[0][2][0])
        ax.margins(0.12)
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


def _mark_last_crossing(
    ax: Axes, d: FloatArray, e: FloatArray, ref: FloatArray, label: str, reference: str, colour: Any
) -> None:
    """The crossing of ``e`` with ``ref`` after which ``e`` stays below it (none where it ends
    above), as a circle on the curve, a dotted vertical line and a legend entry."""
    x = error_crossings(d, e, ref)
    last = np.flatnonzero(np.isfinite(e) & np.isfinite(ref))
    x = x[-1:] if x.size and last.size and e[last[-1]] < ref[last[-1]] else np.zeros(0)
    name = f"{label} below {reference} from {x[0]:.1f} m on" if x.size else None
    ax.scatter(
        x,
        np.interp(x, d, e) if x.size else np.zeros(0),
        s=60,
        marker="o",
        facecolors="none",
        edgecolors=colour,
        linewidths=1.6,
        zorder=5,
        gid=f"crossing:{label}",
        label=name,
    )
    if x.size:
        ax.axvline(x[0], color=colour, linestyle=":", linewidth=0.9, gid=f"crossing_line:{label}")


def plot_errors_vs_distance(
    distance: ArrayLike,
    errors: Mapping[str, ArrayLike],
    path: str | Path | None = None,
    title: str | None = None,
    reference: str = "odometry",
) -> Figure:
    """Fig. 20: position error against distance travelled, one curve per label (e.g.
    "odometry", "paper", "default"). Where an estimate ends below the ``reference`` curve
    (odometry's), its last crossing with it, after which it stays below, is marked and named
    in the legend ("default below odometry from 0.4 m on"); the noise of the first metres,
    where both are near zero and cross back and forth, is left unmarked."""
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
    for label, e in curves.items():
        if ref is not None and label != reference:
            _mark_last_crossing(ax, d, e, ref, label, reference, colour_of[label])
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
        _draw_start(ax, P[0])
    return _finish(fig, ax, _title("Estimated path and map", title), path)
