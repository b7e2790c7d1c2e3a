"""fuzzypos.plot: figures hold the expected artists, PNGs are written, pyplot is untouched."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.collections import LineCollection, PathCollection
from matplotlib.figure import Figure

from fuzzypos import plot
from fuzzypos.features import Features, extract_features
from fuzzypos.geometry import Pose2D
from fuzzypos.scan import LaserScan
from fuzzypos.sim import ScannerModel, furnished_room, simulate_scan

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
WORLD = furnished_room()


@pytest.fixture(scope="module")
def features() -> Features:
    scanner = ScannerModel(range_noise_std=0.01)
    scan = simulate_scan(WORLD, Pose2D(0.2, 0.1, 0.3), scanner, rng=np.random.default_rng(1))
    f = extract_features(scan)
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
