"""An occupancy map as ROS map_server saves it: ``MAP.yaml`` beside its image (pgm or png).

:class:`OccupancyMap` holds the cells as ``nav_msgs/OccupancyGrid`` does: -1 unknown, 0 free up
to 100 occupied, row 0 the map's bottom row (``y`` up), with the cells' side and the pose of
cell (0, 0)'s lower-left corner in the map frame (``origin``: x, y and yaw, as the yaml's).
:func:`read_map_yaml` reads one as map_server does (ROS 2's ``nav2_map_server``,
``map_io.cpp``: ``loadMapYaml`` and ``loadMapFromFile``; ROS1's ``map_server`` agrees but
where noted):

- the yaml: ``image`` (a path relative to the yaml's folder unless absolute; required),
  ``resolution`` (m per cell, > 0; required), ``origin`` (``[x, y, yaw]``, exactly three
  numbers; required; the yaw is kept: ROS1's map_server and AMCL ignore it), ``negate``
  (0/1 or a boolean; default 0), ``occupied_thresh`` and ``free_thresh`` (0 <= free <
  occupied <= 1; defaults 0.65 and 0.196, what ROS1's map_saver writes: nav2 requires both
  and the negate key), ``mode`` (``trinary``, the default, ``scale`` or ``raw``, any case);
  other keys are ignored. Numbers may be written as YAML numbers or strings (``1e-2``, which
  YAML 1.1 reads as a string, is 0.01, as yaml-cpp reads it);
- the image: any image Pillow reads (pgm, png, bmp …; 8 or 16 bits, grey, palette, RGB, with
  or without alpha); each pixel's *shade* is the mean of its red, green and blue in 0..1
  (a grey pixel's grey), in trinary mode with the alpha averaged in as a fourth channel
  (1 opaque), as nav2 does; ``occ = shade`` with ``negate``, else ``1 - shade``;
- ``trinary``: occupied (100) where ``occupied_thresh < occ``, else free (0) where ``occ <
  free_thresh``, else unknown (-1);
- ``scale``: unknown where the pixel is not opaque, else as trinary but that between the
  thresholds a cell is ``rint(100 (occ - free) / (occupied - free))`` (ROS1: ``1 + 98 …``);
- ``raw``: the cell is ``round(255 shade)`` where that is 0..100, else unknown (``negate``
  is not applied, as in nav2; ROS1 applies it);
- the image's top row is the map's last (``cells[::-1]``).

Every problem is a :class:`MapError` (a ``ValueError``) naming the file, the line of the yaml
where there is one, the key and what is wrong; a yaml or image that cannot be opened is a
:class:`MapFileError` (an ``OSError``).
"""

from __future__ import annotations

import errno
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import FuzzyposError

__all__ = [
    "FREE",
    "MAP_MODES",
    "OCCUPIED",
    "UNKNOWN",
    "MapError",
    "MapFileError",
    "OccupancyMap",
    "read_map_yaml",
]

#: the cells' values (``nav_msgs/OccupancyGrid``)
UNKNOWN, FREE, OCCUPIED = -1, 0, 100
#: map_server's ``mode``\ s
MAP_MODES = ("trinary", "scale", "raw")
#: the thresholds where the yaml has none (ROS1 map_saver's)
DEFAULT_OCCUPIED_THRESH, DEFAULT_FREE_THRESH = 0.65, 0.196
#: a yaml larger than this is not a map's (bytes)
_MAX_YAML_BYTES = 1 << 20


class MapError(FuzzyposError, ValueError):
    """A map that cannot be read: ``"<file>:<line>: <what>"`` (``line`` 0, left out, where the
    problem is not on one line of the yaml). ``path``, ``line`` and ``reason`` as given."""

    def __init__(self, path: str | os.PathLike[str], line: int, reason: str) -> None:
        self.path, self.line, self.reason = os.fspath(path), int(line), reason
        where = f"{self.path}:{self.line}" if self.line > 0 else self.path
        super().__init__(f"{where}: {reason}")

    def __reduce__(self) -> tuple[type, tuple[str, int, str]]:
        return (type(self), (self.path, self.line, self.reason))


class MapFileError(FuzzyposError, OSError):
    """A map's yaml or image that cannot be opened: ``"<file>: <why>"``."""

    def __str__(self) -> str:
        return f"{self.filename}: {self.strerror}"


@dataclass(frozen=True, eq=False)
class OccupancyMap:
    """An occupancy map: ``cells`` (int8, rows from the bottom: -1 unknown, 0..100 the chance
    of an obstacle in percent), ``resolution`` (m per cell) and ``origin`` (x, y in m, yaw in
    rad: the pose of cell (0, 0)'s lower-left corner in the map frame); ``source`` the yaml
    it was read from, if any."""

    cells: NDArray[np.int8]
    resolution: float
    origin: tuple[float, float, float]
    source: Path | None = None

    @property
    def shape(self) -> tuple[int, int]:
        """Rows and columns."""
        return (int(self.cells.shape[0]), int(self.cells.shape[1]))

    def occupied(self, threshold: int = 50) -> NDArray[np.bool_]:
        """The cells whose value is at least ``threshold`` (percent)."""
        out: NDArray[np.bool_] = self.cells >= threshold
        return out

    def to_map(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Grid coordinates (column, row, in cells, fractional) of map-frame ``points``."""
        x0, y0, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        d = np.asarray(points, dtype=np.float64) - (x0, y0)
        local = np.column_stack((c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]))
        out: NDArray[np.float64] = local / self.resolution
        return out

    def cell_centres(self, rows: NDArray[np.int64], cols: NDArray[np.int64]) -> NDArray[np.float64]:
        """The map-frame positions of the centres of cells (``rows``, ``cols``)."""
        x0, y0, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        u = (np.asarray(cols, dtype=np.float64) + 0.5) * self.resolution
        v = (np.asarray(rows, dtype=np.float64) + 0.5) * self.resolution
        return np.column_stack((x0 + c * u - s * v, y0 + s * u + c * v))

    def contains(self, x: float, y: float) -> bool:
        """Whether the map-frame point ``(x, y)`` lies on the map (in one of its cells)."""
        col, row = self.to_map(np.array([[x, y]], dtype=np.float64))[0]
        rows, cols = self.shape
        return bool(0.0 <= col < cols and 0.0 <= row < rows)


# -- the yaml ------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Meta:
    """A map yaml's keys, checked (module docstring)."""

    image: Path
    resolution: float
    origin: tuple[float, float, float]
    negate: bool
    occupied_thresh: float
    free_thresh: float
    mode: str


class _Keys:
    """The yaml's top-level mapping with each key's line (1-based), for the errors."""

    def __init__(self, path: Path, data: Mapping[Any, Any], lines: dict[str, int]) -> None:
        self.path, self.data, self.lines = path, data, lines

    def fail(self, key: str, what: str) -> MapError:
        return MapError(self.path, self.lines.get(key, 0), f"{key!r} {what}")

    def number(self, key: str, default: float | None = None) -> float:
        if key not in self.data:
            if default is None:
                raise MapError(self.path, 0, f"no {key!r}: a map_server yaml needs one")
            return default
        value = self.data[key]
        try:
            if isinstance(value, bool):
                raise TypeError
            number = float(value)
        except (TypeError, ValueError, OverflowError):
            raise self.fail(key, f"must be a number, got {value!r}") from None
        if not math.isfinite(number):
            raise self.fail(key, f"must be finite, got {value!r}")
        return number


def _yaml_mapping(path: Path) -> tuple[Mapping[Any, Any], dict[str, int]]:
    """The yaml's top-level mapping and the line of each of its (string) keys."""
    import yaml  # type: ignore[import-untyped]

    text = _read_yaml_text(path)
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
        data = yaml.safe_load(text)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = 0 if mark is None else mark.line + 1
        why = " ".join(str(exc.problem or exc.context or "malformed").split())
        raise MapError(path, line, f"not valid YAML: {why}") from None
    except (yaml.YAMLError, RecursionError, ValueError, TypeError) as exc:
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise MapError(path, 0, f"not valid YAML: {why}") from None
    if not isinstance(data, dict) or not isinstance(node, yaml.MappingNode):
        got = "nothing" if data is None else type(data).__name__
        raise MapError(
            path, 0, f"a map yaml is a mapping of keys (image, resolution, …), got {got}"
        )
    lines: dict[str, int] = {}
    for key_node, _ in node.value:
        if isinstance(key_node, yaml.ScalarNode):
            lines.setdefault(str(key_node.value), key_node.start_mark.line + 1)
    return data, lines


def _read_yaml_text(path: Path) -> str:
    try:
        with open(path, "rb") as fh:
            raw = fh.read(_MAX_YAML_BYTES + 1)
    except OSError as exc:
        raise _file_error(path, exc) from None
    if len(raw) > _MAX_YAML_BYTES:
        raise MapError(path, 0, f"larger than {_MAX_YAML_BYTES} bytes: not a map yaml")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise MapError(path, line, "not UTF-8 text") from None


def _file_error(path: Path, exc: OSError) -> MapFileError:
    why = exc.strerror or type(exc).__name__
    return MapFileError(exc.errno or errno.EIO, why, os.fspath(path))


def _read_meta(path: Path) -> _Meta:
    data, lines = _yaml_mapping(path)
    keys = _Keys(path, data, lines)
    if "image" not in data:
        raise MapError(path, 0, "no 'image': a map_server yaml names its image file")
    image = data["image"]
    if not isinstance(image, str) or not image.strip():
        raise keys.fail("image", f"must be the image's file name, got {image!r}")
    resolution = keys.number("resolution")
    if resolution <= 0.0:
        raise keys.fail("resolution", f"must be > 0 m per cell, got {data['resolution']!r}")
    origin = _origin(keys)
    occupied = keys.number("occupied_thresh", DEFAULT_OCCUPIED_THRESH)
    free = keys.number("free_thresh", DEFAULT_FREE_THRESH)
    for key, value in (("occupied_thresh", occupied), ("free_thresh", free)):
        if not 0.0 <= value <= 1.0:
            raise keys.fail(key, f"must be in 0..1, got {value!r}")
    if not free < occupied:
        raise keys.fail("free_thresh", f"({free!r}) must be below occupied_thresh ({occupied!r})")
    target = Path(image)
    return _Meta(
        image=target if target.is_absolute() else path.parent / target,
        resolution=resolution,
        origin=origin,
        negate=_negate(keys),
        occupied_thresh=occupied,
        free_thresh=free,
        mode=_mode(keys),
    )


def _origin(keys: _Keys) -> tuple[float, float, float]:
    if "origin" not in keys.data:
        raise MapError(keys.path, 0, "no 'origin': a map_server yaml needs [x, y, yaw]")
    value = keys.data["origin"]
    if not isinstance(value, list) or len(value) != 3:
        raise keys.fail("origin", f"must be [x, y, yaw] (three numbers), got {value!r}")
    out = []
    for v in value:
        try:
            if isinstance(v, bool):
                raise TypeError
            out.append(float(v))
        except (TypeError, ValueError, OverflowError):
            raise keys.fail("origin", f"must be three numbers, got {value!r}") from None
    if not all(math.isfinite(v) for v in out):
        raise keys.fail("origin", f"must be three finite numbers, got {value!r}")
    return (out[0], out[1], out[2])


def _negate(keys: _Keys) -> bool:
    value = keys.data.get("negate", 0)
    if isinstance(value, bool):
        return value
    if isinstance(value, int):
        return value != 0
    if isinstance(value, str) and value.strip().lower() in ("0", "1", "true", "false"):
        return value.strip().lower() in ("1", "true")
    raise keys.fail("negate", f"must be 0 or 1 (or true/false), got {value!r}")


def _mode(keys: _Keys) -> str:
    value = keys.data.get("mode", "trinary")
    mode = value.strip().lower() if isinstance(value, str) else None
    if mode not in MAP_MODES:
        raise keys.fail("mode", f"must be one of {', '.join(MAP_MODES)}, got {value!r}")
    return mode


# -- the image -----------------------------------------------------------------------------
def _pixels(image: Path, mode: str) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None]:
    """The image's shade per pixel (0..1, top row first; in trinary mode the alpha averaged
    in) and, where it has an alpha channel, which pixels are opaque."""
    from PIL import Image

    try:
        with Image.open(image) as img:
            img.load()
            return _shades(img, mode)
    except FileNotFoundError as exc:
        raise _file_error(image, exc) from None
    except (IsADirectoryError, PermissionError) as exc:
        raise _file_error(image, exc) from None
    except MemoryError:
        raise MapError(image, 0, "too large an image to read") from None
    except Exception as exc:  # Pillow raises many kinds on a damaged or foreign file
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise MapError(image, 0, f"not an image Pillow can read: {why}") from None


def _shades(img: Any, mode: str) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None]:
    """:func:`_pixels` of an open Pillow image."""
    if img.mode in ("I", "I;16", "I;16B", "I;16L", "I;16N"):  # 16-bit grey
        grey = np.asarray(img, dtype=np.float64)
        return np.clip(grey / 65535.0, 0.0, 1.0), None
    has_alpha = "A" in img.getbands() or "transparency" in img.info
    if img.mode in ("1", "L") and not has_alpha:
        return np.asarray(img.convert("L"), dtype=np.float64) / 255.0, None
    if img.mode == "LA" or (img.mode in ("L", "1") and has_alpha):
        la = np.asarray(img.convert("LA"), dtype=np.float64)
        grey, alpha = la[..., 0], la[..., 1]
        rgb_sum, channels = 3.0 * grey, 3.0
    elif has_alpha:
        rgba = np.asarray(img.convert("RGBA"), dtype=np.float64)
        rgb_sum, alpha, channels = rgba[..., :3].sum(axis=2), rgba[..., 3], 3.0
    else:
        rgb = np.asarray(img.convert("RGB"), dtype=np.float64)
        return rgb.sum(axis=2) / (3.0 * 255.0), None
    if mode == "trinary":  # nav2 averages the alpha in as a fourth channel
        return (rgb_sum + alpha) / ((channels + 1.0) * 255.0), alpha >= 255.0
    return rgb_sum / (channels * 255.0), alpha >= 255.0


def _cells(
    meta: _Meta, shade: NDArray[np.float64], opaque: NDArray[np.bool_] | None
) -> NDArray[np.int8]:
    """The map's cells (top row first, as the image) from the pixels' shades."""
    cells = np.full(shade.shape, UNKNOWN, dtype=np.int8)
    if meta.mode == "raw":
        value = np.floor(shade * 255.0 + 0.5)  # C's round(): halves away from zero
        keep = (value >= FREE) & (value <= OCCUPIED)
        cells[keep] = value[keep].astype(np.int8)
        return cells
    occ = shade if meta.negate else 1.0 - shade
    occupied = meta.occupied_thresh < occ
    free = ~occupied & (occ < meta.free_thresh)
    cells[occupied] = OCCUPIED
    cells[free] = FREE
    if meta.mode == "scale":
        between = ~occupied & ~free
        span = meta.occupied_thresh - meta.free_thresh
        scaled = np.rint((occ[between] - meta.free_thresh) / span * 100.0)
        cells[between] = np.clip(scaled, FREE, OCCUPIED).astype(np.int8)
        if opaque is not None:
            cells[~opaque] = UNKNOWN
    return cells


def read_map_yaml(path: str | os.PathLike[str]) -> OccupancyMap:
    """The map of a map_server ``yaml`` and its image, read as map_server reads them (module
    docstring). Raises :class:`MapError` (bad yaml, key, threshold, mode, an image that is
    not one or has no pixel) and :class:`MapFileError` (a yaml or image that cannot be
    opened)."""
    path = Path(path)
    meta = _read_meta(path)
    shade, opaque = _pixels(meta.image, meta.mode)
    if shade.ndim != 2 or shade.shape[0] < 1 or shade.shape[1] < 1:
        raise MapError(meta.image, 0, f"a map needs at least one cell, the image is {shade.shape}")
    cells = _cells(meta, shade, opaque)
    return OccupancyMap(cells[::-1].copy(), meta.resolution, meta.origin, path)
