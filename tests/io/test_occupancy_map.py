"""Reading ROS map_server maps (``fuzzypos.io.occupancy_map.read_map_yaml``, issue 37): every
mode (trinary, scale, raw) against a pixel-by-pixel oracle written from nav2's
``loadMapFromFile``, grey, palette, RGB, alpha and 16-bit images, pgm and png; a simulated
world's map (negated, at another resolution, with a yawed origin); the round trip with
``OccupancyGrid.write``; every bad input a typed error naming the file, the line and the key,
and hypothesis's damaged yaml and images nothing else."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from fuzzypos import sim
from fuzzypos.errors import FuzzyposError
from fuzzypos.graph.occupancy import OccupancyGrid
from fuzzypos.io.occupancy_map import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    MapError,
    MapFileError,
    OccupancyMap,
    read_map_yaml,
)
from helpers import write_world_map

yaml = pytest.importorskip("yaml")


def write_yaml(folder: Path, image: str = "map.pgm", **keys: object) -> Path:
    """A map yaml with map_server's keys (``keys`` override them; None leaves one out)."""
    data: dict[str, object] = {
        "image": image,
        "resolution": 0.05,
        "origin": [0.0, 0.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    data.update(keys)
    text = "".join(f"{k}: {v}\n" for k, v in data.items() if v is not None)
    path = folder / "map.yaml"
    path.write_text(text, encoding="utf-8")
    return path


# -- the oracle: nav2's loadMapFromFile, one pixel at a time ---------------------------------
def nav2_cell(rgba: tuple[int, ...], has_alpha: bool, mode: str, negate: bool) -> int:
    """A cell as nav2's map_io.cpp makes it of one 8-bit pixel (r, g, b, a), thresholds 0.65
    and 0.196: the shade is the mean of r, g, b (and, in trinary mode, of the alpha too)."""
    r, g, b, a = rgba
    channels = [r, g, b] + ([a] if has_alpha and mode == "trinary" else [])
    shade = sum(channels) / len(channels) / 255.0
    if mode == "raw":
        percent = int(shade * 255.0 + 0.5)
        return percent if 0 <= percent <= 100 else -1
    occ = shade if negate else 1.0 - shade
    if mode == "scale" and has_alpha and a != 255:
        return -1
    if occ > 0.65:
        return 100
    if occ < 0.196:
        return 0
    if mode == "trinary":
        return -1
    return round((occ - 0.196) / (0.65 - 0.196) * 100.0)  # Python rounds halves to even: rint


def oracle_cells(img: Image.Image, mode: str, negate: bool) -> np.ndarray:
    has_alpha = "A" in img.getbands() or "transparency" in img.info
    rgba = img.convert("RGBA")
    w, h = img.size
    rows = [
        [nav2_cell(rgba.getpixel((x, y)), has_alpha, mode, negate) for x in range(w)]
        for y in range(h)
    ]
    return np.array(rows[::-1], dtype=np.int8)  # the map's first row is the image's last


def random_image(kind: str, rng: np.random.Generator, shape=(7, 9)) -> Image.Image:
    """An image of Pillow mode ``kind`` with random pixels (alpha mostly opaque)."""
    h, w = shape
    if kind == "1":
        return Image.fromarray(rng.integers(0, 2, shape).astype(bool))
    if kind == "P":
        img = Image.fromarray(rng.integers(0, 256, (h, w, 3)).astype(np.uint8)).convert(
            "P", palette=Image.Palette.ADAPTIVE, colors=16
        )
        return img
    bands = {"L": 1, "LA": 2, "RGB": 3, "RGBA": 4}[kind]
    data = rng.integers(0, 256, (h, w, bands)).astype(np.uint8)
    if kind in ("LA", "RGBA"):
        data[..., -1] = np.where(rng.random((h, w)) < 0.7, 255, data[..., -1])
    return Image.fromarray(data[..., 0] if bands == 1 else data, kind)


@pytest.mark.parametrize("mode", ["trinary", "scale", "raw"])
@pytest.mark.parametrize("negate", [False, True])
@pytest.mark.parametrize("kind", ["1", "L", "LA", "P", "RGB", "RGBA"])
def test_every_mode_reads_each_pixel_as_nav2_does(tmp_path, mode, negate, kind) -> None:
    rng = np.random.default_rng(hash((mode, negate, kind)) % 2**32)
    img = random_image(kind, rng)
    img.save(tmp_path / "map.png")
    m = read_map_yaml(write_yaml(tmp_path, "map.png", mode=mode, negate=int(negate)))
    want = oracle_cells(Image.open(tmp_path / "map.png"), mode, negate)
    assert m.cells.dtype == np.int8 and m.shape == want.shape
    np.testing.assert_array_equal(m.cells, want)
    if mode == "scale" and kind in ("LA", "RGBA"):  # transparent: unknown in scale mode
        alpha = np.asarray(img)[..., -1][::-1]
        assert np.all(m.cells[alpha < 255] == UNKNOWN)


def test_scale_mode_spreads_the_greys_between_the_thresholds(tmp_path) -> None:
    """Every grey level in scale mode: free below free_thresh, 100 above occupied_thresh, and
    the percent between them rising with the darkness, 0..100."""
    levels = np.arange(256, dtype=np.uint8)[None, :]
    Image.fromarray(levels).save(tmp_path / "grey.png")
    m = read_map_yaml(write_yaml(tmp_path, "grey.png", mode="scale"))
    occ = 1.0 - np.arange(256) / 255.0
    row = m.cells[0].astype(int)
    assert np.all(row[occ > 0.65] == OCCUPIED) and np.all(row[occ < 0.196] == FREE)
    between = (occ >= 0.196) & (occ <= 0.65)
    want = np.rint((occ[between] - 0.196) / (0.65 - 0.196) * 100.0)
    np.testing.assert_array_equal(row[between], want)
    assert np.all(np.diff(row[::-1]) >= 0)  # darker, more occupied


def test_raw_mode_keeps_the_values_0_to_100_and_nothing_else(tmp_path) -> None:
    levels = np.arange(256, dtype=np.uint8).reshape(16, 16)
    Image.fromarray(levels).save(tmp_path / "raw.pgm")
    for negate in (0, 1):  # nav2 does not negate a raw map
        m = read_map_yaml(write_yaml(tmp_path, "raw.pgm", mode="raw", negate=negate))
        flat = m.cells[::-1].reshape(-1).astype(int)
        np.testing.assert_array_equal(flat[:101], np.arange(101))
        assert np.all(flat[101:] == UNKNOWN)


def test_a_16_bit_pgm_reads_as_its_8_bit_copy(tmp_path) -> None:
    rng = np.random.default_rng(3)
    grey8 = rng.choice(np.array([0, 100, 205, 254, 255], dtype=np.uint16), (5, 6))
    grey16 = grey8 * 257
    h, w = grey16.shape
    (tmp_path / "m16.pgm").write_bytes(
        f"P5\n{w} {h}\n65535\n".encode() + grey16.astype(">u2").tobytes()
    )
    Image.fromarray(grey8.astype(np.uint8)).save(tmp_path / "m8.pgm")
    a = read_map_yaml(write_yaml(tmp_path, "m16.pgm"))
    b = read_map_yaml(write_yaml(tmp_path, "m8.pgm"))
    np.testing.assert_array_equal(a.cells, b.cells)
    assert set(np.unique(a.cells)) == {FREE, UNKNOWN, OCCUPIED}


def test_keys_map_server_accepts_in_other_spellings(tmp_path) -> None:
    Image.fromarray(np.array([[0, 254]], dtype=np.uint8)).save(tmp_path / "map.pgm")
    (tmp_path / "map.yaml").write_text(
        "image: map.pgm\nresolution: '5e-2'\norigin: [1, '2.5', 0]\nnegate: false\n"
        "mode: Trinary\nunused_key: [1, 2]\n",
        encoding="utf-8",
    )
    m = read_map_yaml(tmp_path / "map.yaml")
    assert m.resolution == 0.05 and m.origin == (1.0, 2.5, 0.0)
    np.testing.assert_array_equal(m.cells, [[OCCUPIED, FREE]])


def test_an_absolute_image_path_and_one_in_a_sub_folder(tmp_path) -> None:
    (tmp_path / "maps" / "img").mkdir(parents=True)
    Image.fromarray(np.array([[0]], dtype=np.uint8)).save(tmp_path / "maps" / "img" / "a.png")
    rel = read_map_yaml(write_yaml(tmp_path / "maps", "img/a.png"))
    elsewhere = tmp_path / "other"
    elsewhere.mkdir()
    absolute = read_map_yaml(write_yaml(elsewhere, str(tmp_path / "maps" / "img" / "a.png")))
    assert rel.cells.tolist() == absolute.cells.tolist() == [[OCCUPIED]]
    assert rel.source == tmp_path / "maps" / "map.yaml"


# -- a simulated world's map ---------------------------------------------------------------
@pytest.mark.parametrize(
    ("world", "resolution", "negate"),
    [("office", 0.05, False), ("office", 0.05, True), ("furnished_room", 0.1, False)],
)
def test_a_simulated_worlds_map_puts_its_walls_where_the_world_has_them(
    tmp_path, world, resolution, negate
) -> None:
    w = sim.world_by_name(world)
    path, occupied, origin = write_world_map(tmp_path, w, resolution, negate=negate)
    m = read_map_yaml(path)
    assert m.resolution == resolution and m.origin == (*origin, 0.0)
    np.testing.assert_array_equal(m.cells == OCCUPIED, occupied)
    np.testing.assert_array_equal(m.cells == FREE, ~occupied)
    rows, cols = np.nonzero(m.cells == OCCUPIED)
    walls = w.distance(m.cell_centres(rows, cols))
    assert walls.max() <= resolution * math.sqrt(0.5) + 1e-12
    rows, cols = np.nonzero(m.cells == FREE)
    assert w.distance(m.cell_centres(rows, cols)).min() > resolution * math.sqrt(0.5)


def test_the_origins_yaw_turns_the_map_about_its_origin(tmp_path) -> None:
    w = sim.world_by_name("rectangular_room")
    yaw = math.radians(30.0)
    path, _, origin = write_world_map(tmp_path, w, 0.1, yaw=yaw)
    m = read_map_yaml(path)
    assert m.origin == pytest.approx((*origin, yaw))
    rows, cols = np.nonzero(m.cells == OCCUPIED)
    centres = m.cell_centres(rows, cols)
    c, s = math.cos(yaw), math.sin(yaw)
    d = centres - origin  # turned back by -yaw about the origin: on the world's walls
    back = np.column_stack((c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1])) + origin
    assert w.distance(back).max() <= 0.1 * math.sqrt(0.5) + 1e-9
    grid = m.to_map(centres)  # and to_map undoes cell_centres
    np.testing.assert_allclose(grid, np.column_stack((cols + 0.5, rows + 0.5)), atol=1e-9)
    x, y = centres[0]
    assert m.contains(x, y)
    far = origin[0] - 5.0, origin[1] - 5.0
    assert not m.contains(*far)


def test_the_run_jobs_map_reads_back_as_it_was_written(tmp_path) -> None:
    """``OccupancyGrid.write`` (``run --save-map``) and read_map_yaml agree: 254 free,
    0 occupied, 205 unknown, bottom row first."""
    rng = np.random.default_rng(7)
    log_odds = rng.choice([-5.0, -1.0, 0.0, 0.4, 1.0, 5.0], (13, 17))
    grid = OccupancyGrid(log_odds, 0.05, (-1.25, 3.5))
    files = grid.write(tmp_path)
    m = read_map_yaml(files["map.yaml"])
    p = 1.0 - 1.0 / (1.0 + np.exp(log_odds))
    want = np.where(p > 0.65, OCCUPIED, np.where(p < 0.196, FREE, UNKNOWN))
    np.testing.assert_array_equal(m.cells, want)
    assert m.resolution == 0.05 and m.origin == (-1.25, 3.5, 0.0)
    assert isinstance(m, OccupancyMap) and m.source == files["map.yaml"]


# -- errors --------------------------------------------------------------------------------
BASE = "image: map.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n"


@pytest.mark.parametrize(
    ("text", "expect"),
    [
        ("resolution: 0.05\norigin: [0, 0, 0]\n", ["map.yaml:", "no 'image'"]),
        ("image: map.pgm\norigin: [0, 0, 0]\n", ["no 'resolution'"]),
        ("image: map.pgm\nresolution: 0.05\n", ["no 'origin'"]),
        ("image: ''\nresolution: 0.05\norigin: [0, 0, 0]\n", ["map.yaml:1:", "'image'"]),
        ("image: map.pgm\nresolution: fine\norigin: [0, 0, 0]\n", ["map.yaml:2:", "'resolution'"]),
        ("image: map.pgm\nresolution: -0.05\norigin: [0, 0, 0]\n", ["map.yaml:2:", "> 0"]),
        ("image: map.pgm\nresolution: .nan\norigin: [0, 0, 0]\n", [":2:", "finite"]),
        ("image: map.pgm\nresolution: 0.05\norigin: [0, 0]\n", ["map.yaml:3:", "'origin'"]),
        ("image: map.pgm\nresolution: 0.05\norigin: [0, a, 0]\n", [":3:", "'origin'"]),
        (BASE + "occupied_thresh: 1.5\n", ["map.yaml:4:", "'occupied_thresh'", "0..1"]),
        (BASE + "occupied_thresh: 0.5\nfree_thresh: 0.6\n", [":5:", "'free_thresh'", "below"]),
        (BASE + "free_thresh: -0.1\n", [":4:", "'free_thresh'"]),
        (BASE + "mode: fancy\n", ["map.yaml:4:", "'mode'", "trinary, scale, raw"]),
        (BASE + "negate: maybe\n", ["map.yaml:4:", "'negate'"]),
        (
            "image: map.pgm\nresolution: [0.05\norigin: [0, 0, 0]\n",
            ["map.yaml:3:", "not valid YAML"],
        ),
        ("image: map.pgm\n  resolution: 0.05\n", ["map.yaml:2:", "not valid YAML"]),
        ("- image\n- map.pgm\n", ["map.yaml:", "mapping", "list"]),
        ("", ["map.yaml:", "mapping", "nothing"]),
    ],
)
def test_a_bad_yaml_is_a_map_error_naming_file_line_and_key(tmp_path, text, expect) -> None:
    Image.fromarray(np.zeros((2, 2), dtype=np.uint8)).save(tmp_path / "map.pgm")
    (tmp_path / "map.yaml").write_text(text, encoding="utf-8")
    with pytest.raises(MapError) as info:
        read_map_yaml(tmp_path / "map.yaml")
    message = str(info.value)
    assert isinstance(info.value, FuzzyposError) and isinstance(info.value, ValueError)
    assert message.startswith(str(tmp_path / "map.yaml"))
    for part in expect:
        assert part in message, message
    assert "\n" not in message


def test_a_yaml_that_is_not_utf8_names_its_line(tmp_path) -> None:
    (tmp_path / "map.yaml").write_bytes(b"image: map.pgm\nresolution: 0.05 \xff\n")
    with pytest.raises(MapError, match=r"map\.yaml:2: not UTF-8"):
        read_map_yaml(tmp_path / "map.yaml")


def test_missing_files_are_os_errors_naming_them(tmp_path) -> None:
    with pytest.raises(MapFileError) as info:
        read_map_yaml(tmp_path / "nowhere.yaml")
    assert isinstance(info.value, OSError) and isinstance(info.value, FuzzyposError)
    assert str(info.value) == f"{tmp_path / 'nowhere.yaml'}: No such file or directory"
    with pytest.raises(MapFileError, match=r"missing\.pgm: No such file"):
        read_map_yaml(write_yaml(tmp_path, "missing.pgm"))
    (tmp_path / "folder.pgm").mkdir()
    with pytest.raises(MapFileError, match=r"folder\.pgm: Is a directory"):
        read_map_yaml(write_yaml(tmp_path, "folder.pgm"))


@pytest.mark.parametrize(
    "content",
    [b"not an image at all\n", b"P5\n0 0\n255\n", b"P5\n4 4\n255\n\x00\x01", b""],
    ids=["text", "no-cells", "cut-short", "empty"],
)
def test_an_image_that_is_not_one_is_a_map_error_naming_it(tmp_path, content) -> None:
    (tmp_path / "map.pgm").write_bytes(content)
    with pytest.raises(MapError) as info:
        read_map_yaml(write_yaml(tmp_path))
    assert str(info.value).startswith(f"{tmp_path / 'map.pgm'}: ")


# -- fuzzing -------------------------------------------------------------------------------
def read_or_typed_error(path: Path) -> OccupancyMap | None:
    """The map, or None where the reader raised its own typed error (anything else fails)."""
    try:
        m = read_map_yaml(path)
    except (MapError, MapFileError) as exc:
        assert "\n" not in str(exc)
        return None
    assert m.cells.dtype == np.int8 and m.cells.ndim == 2 and min(m.shape) >= 1
    assert np.all((m.cells >= -1) & (m.cells <= 100))
    assert m.resolution > 0 and all(math.isfinite(v) for v in m.origin)
    return m


SCALARS = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-3, 3),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
)
VALUES = st.one_of(SCALARS, st.lists(SCALARS, max_size=4))
KEYS = st.sampled_from(
    ["image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode"]
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(keys=st.dictionaries(KEYS, VALUES, max_size=7), keep_image=st.booleans())
def test_fuzzed_yaml_keys_give_a_map_or_a_typed_error(keys, keep_image) -> None:
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        Image.fromarray(np.array([[0, 205, 254]], dtype=np.uint8)).save(folder / "map.pgm")
        if keep_image:
            keys = {**keys, "image": "map.pgm"}
        (folder / "map.yaml").write_text(yaml.safe_dump(keys), encoding="utf-8")
        read_or_typed_error(folder / "map.yaml")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(text=st.text(max_size=200))
def test_fuzzed_yaml_text_gives_a_map_or_a_typed_error(text) -> None:
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        Image.fromarray(np.array([[0, 254]], dtype=np.uint8)).save(folder / "map.pgm")
        (folder / "map.yaml").write_text(BASE + text, encoding="utf-8")
        read_or_typed_error(folder / "map.yaml")


def _seed_images() -> list[bytes]:
    out = []
    with tempfile.TemporaryDirectory() as d:
        for name, img in (
            ("a.pgm", Image.fromarray(np.array([[0, 205], [254, 100]], dtype=np.uint8))),
            ("b.png", random_image("RGBA", np.random.default_rng(1), (3, 4))),
            ("c.png", random_image("P", np.random.default_rng(2), (3, 4))),
        ):
            img.save(Path(d) / name)
            out.append((Path(d) / name).read_bytes())
    return out


SEEDS = _seed_images()


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.sampled_from(SEEDS),
    cut=st.integers(0, 400),
    flips=st.lists(st.tuples(st.integers(0, 400), st.integers(0, 255)), max_size=6),
    mode=st.sampled_from(["trinary", "scale", "raw"]),
)
def test_damaged_images_give_a_map_or_a_typed_error(seed, cut, flips, mode) -> None:
    data = bytearray(seed[: max(cut, 1)] if cut < len(seed) else seed)
    for at, byte in flips:
        if at < len(data):
            data[at] = byte
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        (folder / "map.img").write_bytes(bytes(data))
        read_or_typed_error(write_yaml(folder, "map.img", mode=mode))
