"""fuzzypos.plot: figures hold the expected artists, PNGs are written, pyplot is untouched."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib import colormaps
from matplotlib.collections import LineCollection, PathCollection
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from matplotlib.text import Text

from fuzzypos import Config, sim
from fuzzypos.features import Features, extract_features
from fuzzypos.geometry import Pose2D
from fuzzypos.plot import figures as plot
from fuzzypos.scan import LaserScan
from fuzzypos.sim import ScannerModel, furnished_room, simulate_scan

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
WORLD = furnished_room()


SCAN = simulate_scan(
    WORLD, Pose2D(0.2, 0.1, 0.3), ScannerModel(range_noise_std=0.01), rng=np.random.default_rng(1)
)


@pytest.fixture(scope="module")
def features() -> Features:
    f = extract_features(SCAN)
    # the scan exercises every figure
    assert f.kept.any() and (~f.kept).any()
    assert len(f.lines) >= 4 and len(f.virtual_points) >= 4 and len(f.angular_points) >= 1
    assert f.is_field_of_view_edge.sum() == 2
    return f


@pytest.fixture(scope="module")
def empty_features() -> Features:
    return extract_features(
        LaserScan(np.full(180, np.inf), angle_min=-np.pi / 2, angle_increment=np.pi / 180)
    )


def artist(fig: Figure, gid: str, ax_index: int = 0):
    ax = fig.axes[ax_index]
    found = [a for a in ax.get_children() if a.get_gid() == gid]
    assert len(found) == 1, f"{gid}: {len(found)} artists"
    return found[0]


def n_offsets(fig: Figure, gid: str) -> int:
    a = artist(fig, gid)
    assert isinstance(a, PathCollection)
    return int(a.get_offsets().shape[0])


def assert_png(path: Path) -> None:
    data = path.read_bytes()
    assert len(data) > 1000 and data.startswith(PNG_MAGIC)


def assert_metric_axes(fig: Figure) -> None:
    ax = fig.axes[0]
    assert ax.get_aspect() == 1.0
    assert ax.get_xlabel() == "x [m]" and ax.get_ylabel() == "y [m]"


# ---------------------------------------------------------------------------------------------
# Figs. 13–18
# ---------------------------------------------------------------------------------------------
def test_filtering(features: Features, tmp_path: Path) -> None:
    path = tmp_path / "sub" / "f13.png"
    fig = plot.plot_filtering(features, path=path)
    assert isinstance(fig, Figure)
    assert_png(path)
    assert_metric_axes(fig)
    assert n_offsets(fig, "kept_points") == int(features.kept.sum())
    assert n_offsets(fig, "removed_points") == int((~features.kept).sum())
    kept = artist(fig, "kept_points")
    np.testing.assert_allclose(kept.get_array(), features.uncertainty[features.kept])
    np.testing.assert_allclose(kept.get_offsets(), features.points[features.kept])
    assert kept.norm.vmin == 0.0 and kept.norm.vmax == 1.0
    assert artist(fig, "robot") is not None and artist(fig, "robot_heading") is not None
    # a colorbar axes labelled with the uncertainty's meaning
    assert len(fig.axes) == 2 and fig.axes[1].get_ylabel() == "uncertainty (0 = certain)"
    assert fig.axes[0].get_title() == "Fig. 13 — data filtering"


def test_break_points(features: Features) -> None:
    fig = plot.plot_break_points(features, title="custom")
    assert fig.axes[0].get_title() == "custom"
    fov = features.is_field_of_view_edge
    assert n_offsets(fig, "kept_points") == features.kept_index.size
    assert n_offsets(fig, "break_points") == int((features.is_break_point & ~fov).sum()) > 0
    assert n_offsets(fig, "fov_edges") == 2
    np.testing.assert_allclose(artist(fig, "fov_edges").get_offsets(), features.kept_points[fov])


def test_angular_points(features: Features) -> None:
    fig = plot.plot_angular_points(features)
    n = int(features.is_angular_point.sum())
    assert n_offsets(fig, "angular_sampled") == n
    assert n_offsets(fig, "angular_points") == len(features.angular_points) == n
    np.testing.assert_allclose(
        artist(fig, "angular_points").get_offsets(), features.angular_points.xy
    )


def test_clusters(features: Features) -> None:
    fig = plot.plot_clusters(features)
    ok = features.cluster >= 0
    assert n_offsets(fig, "cluster_points") == int(ok.sum())
    assert n_offsets(fig, "dropped_points") == int((~ok).sum())
    colours = artist(fig, "cluster_points").get_facecolors()
    # one colour per cluster (fewer than 10 here: tab10, all distinct)
    assert features.n_clusters <= 10
    assert len({tuple(c) for c in np.round(colours, 6)}) == features.n_clusters
    assert f"{features.n_clusters} clusters" in fig.axes[0].get_title()


def test_lines(features: Features) -> None:
    fig = plot.plot_lines(features)
    lc = artist(fig, "lines")
    assert isinstance(lc, LineCollection)
    segs = lc.get_segments()
    assert len(segs) == len(features.lines)
    np.testing.assert_allclose(np.array([s[0] for s in segs]), features.lines.start)
    np.testing.assert_allclose(np.array([s[-1] for s in segs]), features.lines.end)
    np.testing.assert_allclose(lc.get_array(), features.lines.uncertainty)
    assert n_offsets(fig, "line_centres") == len(features.lines)
    assert fig.axes[1].get_ylabel() == "line uncertainty (0 = certain)"


def test_virtual_points(features: Features) -> None:
    fig = plot.plot_virtual_points(features)
    vp = features.virtual_points
    assert n_offsets(fig, "virtual_points") == len(vp)
    sc = artist(fig, "virtual_points")
    np.testing.assert_allclose(sc.get_offsets(), vp.xy)
    np.testing.assert_allclose(sc.get_array(), vp.uncertainty)
    sizes = sc.get_sizes()
    order = np.argsort(vp.uncertainty)
    assert np.all(np.diff(sizes[order]) <= 1e-9)  # more certain = bigger
    assert len(artist(fig, "lines").get_segments()) == len(features.lines)
    assert len(artist(fig, "virtual_extensions").get_segments()) == 2 * len(vp)
    assert n_offsets(fig, "angular_points") == len(features.angular_points)


def test_feature_figures(features: Features, tmp_path: Path) -> None:
    out = tmp_path / "figs"
    written = plot.plot_feature_figures(features, out, scan_index=25)
    names = {
        13: "fig13_filtering.png",
        14: "fig14_break_points.png",
        15: "fig15_angular_points.png",
        16: "fig16_clusters.png",
        17: "fig17_lines.png",
        18: "fig18_virtual_angular_points.png",
    }
    assert set(written) == set(names)
    for num, name in names.items():
        assert written[num] == out / name
        assert_png(written[num])
    assert sorted(p.name for p in out.iterdir()) == sorted(names.values())


@pytest.mark.parametrize(
    "fn",
    [
        plot.plot_filtering,
        plot.plot_break_points,
        plot.plot_angular_points,
        plot.plot_clusters,
        plot.plot_lines,
        plot.plot_virtual_points,
    ],
)
def test_feature_plots_of_an_empty_scan(fn, empty_features: Features, tmp_path: Path) -> None:
    assert empty_features.n_valid == 0
    fig = fn(empty_features)
    assert isinstance(fig, Figure)


def test_feature_titles_carry_the_scan_index(
    features: Features, tmp_path: Path, monkeypatch
) -> None:
    titles: dict[str, str] = {}
    real_finish = plot._finish

    def spy(fig, ax, title, path, equal=True):
        titles[Path(path).name] = title
        return real_finish(fig, ax, title, None, equal)

    monkeypatch.setattr(plot, "_finish", spy)  # no PNG written: keeps the test fast
    written = plot.plot_feature_figures(features, tmp_path, scan_index=25, prefix="scan25_fig")
    assert written[17] == tmp_path / "scan25_fig17_lines.png"
    titles = {k.replace("scan25_", ""): v for k, v in titles.items()}
    assert titles["fig13_filtering.png"] == "Fig. 13 — data filtering, scan 25"
    fig18 = titles["fig18_virtual_angular_points.png"]
    assert fig18 == "Fig. 18 — virtual angular points, scan 25"
    assert titles["fig16_clusters.png"].startswith("Fig. 16 — ") and titles[
        "fig16_clusters.png"
    ].endswith(", scan 25")


# ---------------------------------------------------------------------------------------------
# Figs. 19–20 and the map
# ---------------------------------------------------------------------------------------------
def circle(n: int = 50, r: float = 2.0) -> np.ndarray:
    t = np.linspace(0.0, 2.0 * np.pi, n)
    return np.column_stack([r * np.cos(t), r * np.sin(t), t + np.pi / 2])


def test_paths(tmp_path: Path) -> None:
    true = circle()
    odo = circle(r=2.3)
    est = {"paper": circle(r=2.1)[:, :2], "default": circle(r=2.02)}
    path = tmp_path / "f19.png"
    fig = plot.plot_paths(true[:, :2], odo, est, path=path, world=WORLD)
    assert_png(path)
    assert_metric_axes(fig)
    ax = fig.axes[0]
    np.testing.assert_allclose(artist(fig, "path:true").get_xydata(), true[:, :2])
    np.testing.assert_allclose(artist(fig, "path:odometry").get_xydata(), odo[:, :2])
    for label, xy in est.items():
        np.testing.assert_allclose(artist(fig, f"path:{label}").get_xydata(), np.asarray(xy)[:, :2])
    np.testing.assert_allclose(artist(fig, "start").get_xydata(), true[:1, :2])
    assert len(artist(fig, "world").get_segments()) == WORLD.segments.shape[0]
    labels = ax.get_legend_handles_labels()[1]
    assert {"true path", "odometry", "paper", "default", "start"} <= set(labels)


def test_paths_without_ground_truth() -> None:
    fig = plot.plot_paths(None, circle(), {"default": circle(r=2.1)})
    np.testing.assert_allclose(artist(fig, "start").get_xydata(), circle()[:1, :2])
    with pytest.raises(ValueError):
        plot.plot_paths(np.zeros(5), None, {})


def test_error_crossings() -> None:
    d = np.linspace(0.0, 10.0, 101)
    odo = 0.01 * d**2  # crosses 0.05 * d at d = 5 (and at 0, where both are 0)
    est = 0.1 + 0.02 * d  # crosses 0.01 d² at d = 1 + sqrt(11) ≈ 4.317
    x = plot.error_crossings(d, est, odo)
    assert x.shape == (1,)
    assert x[0] == pytest.approx(1.0 + np.sqrt(11.0), abs=1e-3)
    # linear curves cross exactly where interpolation says
    assert plot.error_crossings([0, 1, 2, 3], [0, 1, 2, 3], [1.5, 1.5, 1.5, 1.5])[
        0
    ] == pytest.approx(1.5)
    # crossing back and forth; a touch is not a crossing; a run of equal samples crosses where
    # they first meet
    assert plot.error_crossings(d, np.sin(d), np.zeros_like(d)) == pytest.approx(
        [np.pi, 2 * np.pi, 3 * np.pi], abs=1e-3
    )
    assert plot.error_crossings([0, 1, 2], [1, 0, 1], [0, 0, 0]).size == 0
    assert plot.error_crossings([0, 1, 2, 3], [1, 0, 0, -1], [0, 0, 0, 0]) == pytest.approx([1.0])
    assert plot.error_crossings([0, 1, 2], [1, 2, 3], [0, 0, 0]).size == 0
    assert plot.error_crossings([0, 1, 2, 3], [1, np.nan, 1, -1], [0, 0, 0, 0]) == pytest.approx(
        [2.5]
    )
    with pytest.raises(ValueError):
        plot.error_crossings([0, 1], [0, 1, 2], [0, 1, 2])


def test_errors_vs_distance(tmp_path: Path) -> None:
    d = np.linspace(0.0, 10.0, 101)
    errors = {
        "odometry": 0.01 * d**2,
        "paper": 0.25 + 0.0 * d,
        "default": 0.1 + 0.02 * d,
        "never": 2.0 + 0 * d,
    }
    path = tmp_path / "f20.png"
    fig = plot.plot_errors_vs_distance(d, errors, path=path)
    assert_png(path)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "distance travelled [m]" and ax.get_ylabel() == "position error [m]"
    for label, e in errors.items():
        np.testing.assert_allclose(
            artist(fig, f"error:{label}").get_xydata(), np.column_stack([d, e])
        )
    paper = artist(fig, "crossing:paper").get_offsets()
    assert paper.shape == (1, 2) and paper[0, 0] == pytest.approx(5.0, abs=1e-2)
    assert paper[0, 1] == pytest.approx(0.25, abs=1e-3)
    default = artist(fig, "crossing:default").get_offsets()
    assert default.shape == (1, 2) and default[0, 0] == pytest.approx(1.0 + np.sqrt(11.0), abs=1e-2)
    assert artist(fig, "crossing_line:paper").get_xdata()[0] == pytest.approx(5.0, abs=1e-2)
    # "never" stays above odometry (0.01·100 = 1 < 2): no crossing marked
    assert artist(fig, "crossing:never").get_offsets().shape[0] == 0
    assert not [a for a in ax.get_children() if a.get_gid() == "crossing_line:never"]
    assert not [a for a in ax.get_children() if a.get_gid() == "crossing:odometry"]
    with pytest.raises(ValueError):
        plot.plot_errors_vs_distance(d, {"odometry": d[:-1]})


def test_map(tmp_path: Path) -> None:
    poses = circle(12)
    scanner = ScannerModel()
    scans = [simulate_scan(WORLD, Pose2D(*p), scanner).points_robot() for p in poses]
    scans[3] = np.zeros((0, 2))
    scans[4] = None
    path = tmp_path / "map.png"
    fig = plot.plot_map(poses, scans, odometry=poses + 0.05, path=path)
    assert_png(path)
    assert_metric_axes(fig)
    pts = artist(fig, "map_points").get_offsets()
    total = sum(0 if s is None else int(np.isfinite(s).all(axis=1).sum()) for s in scans)
    assert np.isnan(scans[0]).any()  # invalid beams (no return) come as NaN rows and are skipped
    assert pts.shape == (total, 2)
    # with the true poses, the map points lie on the world's walls
    assert np.max(WORLD.distance(np.asarray(pts))) < 1e-6
    np.testing.assert_allclose(artist(fig, "path:estimate").get_xydata(), poses[:, :2])
    np.testing.assert_allclose(artist(fig, "path:odometry").get_xydata(), poses[:, :2] + 0.05)
    # subsampling keeps it light
    small = plot.plot_map(poses, scans, None, max_points=500)
    assert artist(small, "map_points").get_offsets().shape[0] == 500
    assert not [a for a in small.axes[0].get_children() if a.get_gid() == "path:odometry"]
    with pytest.raises(ValueError):
        plot.plot_map(poses, scans[:-1])


# ---------------------------------------------------------------------------------------------
# no global matplotlib state
# ---------------------------------------------------------------------------------------------
def run_python(code: str) -> None:
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def test_import_and_plotting_leave_matplotlib_alone() -> None:
    # importing and plotting neither import pyplot nor resolve or set the backend (the raw
    # rcParams entry: matplotlib.get_backend() itself may import pyplot to resolve it)
    run_python(
        "import sys, matplotlib, numpy as np\n"
        "raw = lambda: dict.__getitem__(matplotlib.rcParams, 'backend')\n"
        "before = raw()\n"
        "import fuzzypos.plot as p\n"
        "assert raw() is before, (before, raw())\n"
        "assert 'matplotlib.pyplot' not in sys.modules\n"
        "p.plot_errors_vs_distance(np.arange(3.0), {'odometry': np.arange(3.0)})\n"
        "assert raw() is before and 'matplotlib.pyplot' not in sys.modules\n"
    )
    # with pyplot in use, get_backend() is the same before and after, and no figure is opened
    run_python(
        "import matplotlib, matplotlib.pyplot as plt, numpy as np\n"
        "b = matplotlib.get_backend()\n"
        "import fuzzypos.plot as p\n"
        "p.plot_paths(np.zeros((2, 2)), None, {})\n"
        "assert matplotlib.get_backend() == b and plt.get_fignums() == []\n"
    )


def test_plots_do_not_register_pyplot_figures(features: Features) -> None:
    import matplotlib
    import matplotlib.pyplot as plt

    backend = matplotlib.get_backend()
    open_before = plt.get_fignums()
    plot.plot_filtering(features)
    plot.plot_paths(circle(), None, {})
    assert plt.get_fignums() == open_before
    assert matplotlib.get_backend() == backend


# ---------------------------------------------------------------------------------------------
# readability (issue 11, items 18 and 19)
# ---------------------------------------------------------------------------------------------
def _relative_luminance(colour) -> float:
    rgb = np.asarray(to_rgb(colour))
    lin = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return float(lin @ np.array([0.2126, 0.7152, 0.0722]))


def _contrast(a, b) -> float:
    la, lb = sorted((_relative_luminance(a), _relative_luminance(b)), reverse=True)
    return (la + 0.05) / (lb + 0.05)


def test_cluster_labels_are_readable_on_their_tags(features: Features) -> None:
    """Each cluster's id sits on a tag of the cluster's colour, in black or white, whichever
    contrasts more (WCAG's 4.5:1 for text at least 3:1 here: tab20's mid tones)."""
    fig = plot.plot_clusters(features)
    labels = [t for t in fig.axes[0].texts if str(t.get_gid()).startswith("cluster_label:")]
    assert len(labels) == len(np.unique(features.cluster[features.cluster >= 0]))
    cmap = plot._qualitative_cmap(features.n_clusters)
    for t in labels:
        k = int(t.get_gid().split(":")[1])
        tag = t.get_bbox_patch()
        assert tag is not None
        assert np.allclose(tag.get_facecolor()[:3], to_rgb(cmap(k % cmap.N)))
        assert _contrast(t.get_color(), tag.get_facecolor()) >= 3.0, (k, t.get_color())


def test_light_cluster_colours_get_black_ink() -> None:
    tab20 = colormaps["tab20"]
    assert plot._ink_on(tab20(1)) == "black" and plot._ink_on(tab20(0)) == "white"
    for k in range(20):
        ink = plot._ink_on(tab20(k))
        other = "white" if ink == "black" else "black"
        assert _contrast(ink, tab20(k)) >= _contrast(other, tab20(k))


def _ends(fig: Figure, prefix: str = "") -> dict[str, np.ndarray]:
    ax = fig.axes[1] if prefix else fig.axes[0]
    return {
        a.get_gid().split(":")[-1]: a.get_xydata()[0]
        for a in ax.get_lines()
        if str(a.get_gid()).startswith(f"{prefix}end:")
    }


def test_paths_mark_every_end_and_zoom_on_the_ends() -> None:
    true = circle()
    odo = circle(r=2.3)
    est = {"paper": circle(r=2.1)[:, :2], "default": circle(r=2.02)}
    fig = plot.plot_paths(true[:, :2], odo, est, world=sim.gym())
    last = {"true": true[-1, :2], "odometry": odo[-1, :2]} | {k: v[-1, :2] for k, v in est.items()}
    for prefix in ("", "zoom:"):
        ends = _ends(fig, prefix)
        assert set(ends) == set(last)
        for key, xy in last.items():
            np.testing.assert_allclose(ends[key], xy)
    ax, zoom = fig.axes[0], fig.axes[1]
    assert zoom.get_gid() == "zoom" and zoom.get_aspect() == 1.0
    # a zoom: every end inside, a view a fraction of the main one's
    (x0, x1), (y0, y1) = zoom.get_xlim(), zoom.get_ylim()
    for xy in last.values():
        assert x0 < xy[0] < x1 and y0 < xy[1] < y1
    assert (x1 - x0) < 0.5 * np.ptp(ax.get_xlim())
    box = artist(fig, "zoom_region")
    np.testing.assert_allclose(box.get_xy(), (x0, y0))
    # each end's distance from the true end, drawn and named
    texts = [t.get_text() for t in zoom.get_legend().get_texts()]
    for key in ("odometry", "paper", "default"):
        gap = float(np.hypot(*(last[key] - last["true"])))
        line = [a for a in zoom.get_lines() if a.get_gid() == f"zoom:gap:{key}"]
        assert len(line) == 1
        np.testing.assert_allclose(line[0].get_xydata(), [last["true"], last[key]])
        assert f"{key} ends {gap:.2f} m off" in texts
    assert "end" in ax.get_legend_handles_labels()[1]


def test_paths_view_is_the_paths_not_the_whole_world() -> None:
    gym = sim.gym()
    fig = plot.plot_paths(circle(), circle(r=2.3), {}, world=gym)
    fig.canvas.draw()
    ax = fig.axes[0]
    assert len(artist(fig, "world").get_segments()) == gym.segments.shape[0]
    assert np.ptp(ax.get_xlim()) < 0.5 * np.ptp(gym.segments[:, [0, 2]])


def test_a_single_path_has_no_zoom() -> None:
    fig = plot.plot_paths(circle(), None, {})
    assert len(fig.axes) == 1 and set(_ends(fig)) == {"true"}


def _overlapping_texts(fig: Figure) -> list[tuple[str, str]]:
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    texts = [
        t
        for t in fig.findobj(Text)
        if t.get_visible() and t.get_text().strip() and t.get_figure() is fig
    ]
    boxes = [t.get_window_extent(renderer) for t in texts]
    return [
        (texts[i].get_text(), texts[j].get_text())
        for i in range(len(texts))
        for j in range(i + 1, len(texts))
        if boxes[i].overlaps(boxes[j])
    ]


def _demo_like_errors() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Curves shaped like the demo's: all near zero at first, where both estimates cross
    odometry back and forth within the first metre, then the paper's swinging about it."""
    rng = np.random.default_rng(4)
    d = np.linspace(0.0, 50.0, 1500)
    odo = 0.0008 * d**2 + 0.02 * d
    paper = odo * (1.0 + 0.5 * np.sin(d / 3.0)) + 0.02 * rng.standard_normal(d.size) * (d < 1)
    default = 0.005 + 0.004 * np.abs(rng.standard_normal(d.size))
    return d, {"odometry": odo, "paper": paper, "default": default}


def test_errors_vs_distance_marks_one_crossing_per_estimate() -> None:
    d, errors = _demo_like_errors()
    # the premise: the paper's curve crosses odometry many times, near zero and later
    assert plot.error_crossings(d, errors["paper"], errors["odometry"]).size >= 6
    fig = plot.plot_errors_vs_distance(d, errors)
    texts = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    for label in ("paper", "default"):
        x = plot.error_crossings(d, errors[label], errors["odometry"])[-1]
        offsets = artist(fig, f"crossing:{label}").get_offsets()
        assert offsets.shape == (1, 2) and offsets[0, 0] == pytest.approx(x)
        assert np.all(errors[label][d > x + 1e-9] < errors["odometry"][d > x + 1e-9])
        assert f"{label} below odometry from {x:.1f} m on" in texts


def test_errors_vs_distance_texts_do_not_overlap() -> None:
    d, errors = _demo_like_errors()
    fig = plot.plot_errors_vs_distance(d, errors, title="Fig. 20 — position error")
    assert len(fig.findobj(Text)) > 10
    assert not _overlapping_texts(fig)


def test_fig18_draws_the_virtual_points_removed_as_too_uncertain(features: Features) -> None:
    """Those drawn hollow are virtual angular points §3.6 found and graded above the
    threshold: extracted again with no threshold, each is one, more uncertain than it."""
    cfg = Config()
    removed = plot.too_uncertain_virtual_points(features, cfg)
    fig = plot.plot_virtual_points(features, config=cfg)
    np.testing.assert_allclose(artist(fig, "virtual_removed").get_offsets(), removed)
    assert removed.shape[0] >= 3 and len(features.virtual_points) >= 3
    keep_all = cfg.with_overrides({"virtual_points": {"max_uncertainty": 1.0}})
    every = extract_features(SCAN, keep_all).virtual_points
    gap = np.hypot(*(removed[:, None, :] - every.xy[None, :, :]).transpose(2, 0, 1))
    match = gap.argmin(axis=1)
    assert np.all(gap.min(axis=1) < 1e-9)
    assert np.all(every.uncertainty[match] > cfg.virtual_points.max_uncertainty)
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert f"too uncertain, removed ({removed.shape[0]})" in labels
    assert f"virtual angular points ({len(features.virtual_points)})" in labels
