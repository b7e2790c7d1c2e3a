"""The machinery behind :mod:`fuzzypos.config`: field declarations, checks, TOML conversion.

Each setting is declared with :func:`_field`, which records in the dataclass field's metadata
why it has its value, its unit and its bounds (a :class:`FieldSpec`). Everything else reads
that declaration: validation (finite numbers within the bounds, allowed choices), the degree
conversion at the TOML edge (unit ``"rad"``: radians in code, ``<name>_deg`` in TOML) and
``fuzzypos config --reasons``. Keys of older config files are translated by
:func:`translate_legacy`.
"""

from __future__ import annotations

import math
import numbers
import sys
import warnings
from collections.abc import Callable, Iterator, Mapping
from dataclasses import MISSING, Field, dataclass, field, fields
from pathlib import Path
from typing import Any, TypeVar

from ..errors import FuzzyposError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on 3.10 only
    import tomli as tomllib

Triangle = tuple[float, float, float]


def _partition(peaks: tuple[float, ...]) -> tuple[Triangle, ...]:
    """Triangles peaked at ``peaks`` whose feet are the neighbouring peaks: a partition of unity."""
    out = []
    for i, p in enumerate(peaks):
        left = peaks[i - 1] if i > 0 else p
        right = peaks[i + 1] if i + 1 < len(peaks) else p
        out.append((float(left), float(p), float(right)))
    return tuple(out)


ANGLE_UNIT = "rad"  # radians in code, degrees under "<name>_deg" in TOML


class ConfigError(FuzzyposError, ValueError):
    """A configuration value or file is wrong; the message names the key."""

    __module__ = "fuzzypos.config"  # where it is imported from (and pickled as)


@dataclass(frozen=True)
class FieldSpec:
    """What a setting declares about itself: why, in what unit, within which bounds.

    ``unit`` is ``"m"``, ``"s"``, ``"1/m"``, ``"m/s"``, ``"rad/s"``, ``"rad"`` (an angle:
    radians in code, degrees in TOML) or ``""`` (counts, fractions, ratios, switches).
    ``ge``/``gt``/``le``/``lt`` are inclusive/exclusive bounds in code units; they apply to
    every number of a list or membership function. ``choices`` lists a string's values.
    """

    reason: str
    unit: str = ""
    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    choices: tuple[str, ...] | None = None

    @property
    def is_angle(self) -> bool:
        return self.unit == ANGLE_UNIT

    @property
    def has_bounds(self) -> bool:
        return any(b is not None for b in (self.ge, self.gt, self.le, self.lt))

    def _show(self, v: float) -> str:
        return f"{math.degrees(v):g}°" if self.is_angle else f"{v:g}"

    def bounds_text(self) -> str:
        """``"in [0, 1]"``, ``"> 0"``, ``"in (0°, 90°]"``, ``"one of 'a', 'b'"`` or ``""``."""
        if self.choices is not None:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        lo, low = ("[", self.ge) if self.ge is not None else ("(", self.gt)
        hi, high = ("]", self.le) if self.le is not None else (")", self.lt)
        if low is not None and high is not None:
            return f"in {lo}{self._show(low)}, {self._show(high)}{hi}"
        if low is not None:
            return f"{'>=' if lo == '[' else '>'} {self._show(low)}"
        if high is not None:
            return f"{'<=' if hi == ']' else '<'} {self._show(high)}"
        return ""

    def describe(self) -> str:
        """Unit and bounds for humans: ``"m, > 0"``, ``"° in TOML (rad in code), > 0°"``."""
        unit = "° in TOML (rad in code)" if self.is_angle else self.unit
        return ", ".join(p for p in (unit, self.bounds_text()) if p)

    def within(self, v: float) -> bool:
        return not (
            (self.ge is not None and v < self.ge)
            or (self.gt is not None and v <= self.gt)
            or (self.le is not None and v > self.le)
            or (self.lt is not None and v >= self.lt)
        )


def _field(
    default: Any,
    reason: str,
    *,
    unit: str = "",
    ge: float | None = None,
    gt: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    choices: tuple[str, ...] | None = None,
) -> Any:
    """A dataclass field that declares its reason, unit, bounds and choices (a FieldSpec)."""
    spec = FieldSpec(reason, unit, ge, gt, le, lt, choices)
    return field(default=default, metadata={"reason": reason, "unit": unit, "spec": spec})


def spec_of(f: Field[Any]) -> FieldSpec:
    spec = f.metadata.get("spec")
    if not isinstance(spec, FieldSpec):  # pragma: no cover - every field is declared
        raise TypeError(f"field {f.name} was not declared with _field()")
    return spec


def is_numeric(default: Any) -> bool:
    """Whether a field with this default holds numbers (floats, ints, lists, triangles)."""
    if isinstance(default, tuple):
        return bool(default) and all(is_numeric(x) for x in default)
    return isinstance(default, (int, float)) and not isinstance(default, bool)


# -- validation from the declarations --------------------------------------------------------------
def _numbers(value: Any, key: str) -> Iterator[tuple[str, Any]]:
    """``(key[i][j], number)`` for every number of a (nested) tuple, the value itself otherwise."""
    if isinstance(value, (tuple, list)):
        for i, x in enumerate(value):
            yield from _numbers(x, f"{key}[{i}]")
    else:
        yield key, value


def check_field(key: str, value: Any, default: Any, spec: FieldSpec) -> None:
    """Raise ConfigError unless ``value`` fits the declaration of field ``key``."""
    if spec.choices is not None:
        if value not in spec.choices:
            raise ConfigError(f"{key} must be {spec.bounds_text()}, got {value!r}")
        return
    if not is_numeric(default):
        return
    integer = isinstance(default, int)
    for where, v in _numbers(value, key):
        if isinstance(v, bool) or not isinstance(v, numbers.Integral if integer else numbers.Real):
            raise ConfigError(
                f"{where} must be {'an integer' if integer else 'a number'}, got {v!r}"
            )
        try:
            fv = float(v)
        except OverflowError:  # an integer too large for a float
            raise ConfigError(f"{where} is too large: {_short(v)}") from None
        if not math.isfinite(fv):
            raise ConfigError(f"{where} must be a finite number, got {v!r}")
        if not spec.within(fv):
            got = f"{math.degrees(v):g}°" if spec.is_angle else repr(v)
            raise ConfigError(f"{where} must be {spec.bounds_text()}, got {got}")


def check_section(name: str, section: Any) -> None:
    for f in fields(section):
        check_field(f"{name}.{f.name}", getattr(section, f.name), f.default, spec_of(f))


_S = TypeVar("_S", bound=type)

#: ``[section]`` name -> section class, in the order they are declared (that of the TOML file)
SECTIONS: dict[str, type] = {}


def section(name: str) -> Callable[[_S], _S]:
    """Register a section class (apply under ``@dataclass``); it checks its fields when made."""

    def register(cls: _S) -> _S:
        def __post_init__(self: Any) -> None:
            check_section(name, self)

        cls.__post_init__ = __post_init__  # type: ignore[attr-defined]
        SECTIONS[name] = cls
        return cls

    return register


def check_sets(name: str, sets: tuple[Triangle, ...], n: int) -> None:
    """Membership functions: ``n`` triangles, left <= peak <= right, ordered by their peaks."""
    if len(sets) != n:
        raise ConfigError(f"fuzzy.{name} needs {n} membership functions, got {len(sets)}")
    for t in sets:
        if len(t) != 3:
            raise ConfigError(f"fuzzy.{name}: {t!r} is not a (left, peak, right) triangle")
        if not t[0] <= t[1] <= t[2] or t[0] == t[2]:
            raise ConfigError(f"fuzzy.{name}: {t!r} needs left <= peak <= right and left < right")
    peaks = [t[1] for t in sets]
    if peaks != sorted(peaks):
        raise ConfigError(f"fuzzy.{name}: membership functions must be ordered by their peaks")


def check_rules(name: str, rules: tuple[str, ...], rows: int, cols: int) -> None:
    if len(rules) != rows or any(len(r) != cols or set(r) - set("SMB") for r in rules):
        raise ConfigError(
            f"fuzzy.{name} needs {rows} rows of {cols} labels from S/M/B, got {list(rules)!r}"
        )


# -- TOML values ---------------------------------------------------------------------------------
def to_deg(v: Any) -> Any:
    """Degrees for TOML: the shortest rounding (12 decimals or more) that loads back exactly."""
    if isinstance(v, tuple):
        return [to_deg(x) for x in v]
    deg = math.degrees(v)
    for digits in range(12, 18):
        if math.radians(round(deg, digits)) == v:
            return round(deg, digits)
    down = up = deg  # no short decimal loads back: a double next to it, if one does
    for _ in range(4):
        down, up = math.nextafter(down, -math.inf), math.nextafter(up, math.inf)
        for d in (down, up):
            if math.radians(d) == v:
                return d
    return deg  # v is no degree value's radians: the nearest degrees


def _short(v: Any) -> str:
    """``repr(v)``, with a huge integer shown by its digit count."""
    text = repr(v)
    if len(text) <= 40:
        return text
    return f"an integer of {len(text)} digits (a number must be at most {sys.float_info.max:.4g})"


def plain(v: Any) -> Any:
    if isinstance(v, tuple):
        return [plain(x) for x in v]
    return v


def coerce(raw: Any, current: Any, is_angle: bool, where: str) -> Any:
    """Convert a TOML value to the type of ``current`` (the default), degrees to radians."""
    if isinstance(current, bool):
        if not isinstance(raw, bool):
            raise ConfigError(f"{where} must be true or false, got {raw!r}")
        return raw
    if isinstance(current, int):
        if isinstance(raw, bool) or not isinstance(raw, int):
            raise ConfigError(f"{where} must be an integer, got {raw!r}")
        return raw
    if isinstance(current, float):
        if isinstance(raw, bool) or not isinstance(raw, (int, float)):
            raise ConfigError(f"{where} must be a number, got {raw!r}")
        try:
            return math.radians(raw) if is_angle else float(raw)
        except OverflowError:
            raise ConfigError(f"{where} is too large: {_short(raw)}") from None
    if isinstance(current, str):
        if not isinstance(raw, str):
            raise ConfigError(f"{where} must be a string, got {raw!r}")
        return raw
    if isinstance(current, tuple):
        return _coerce_list(raw, current, is_angle, where)
    raise ConfigError(f"{where}: unsupported value {raw!r}")  # pragma: no cover


#: how a list's items look, by their count of numbers (for the error message)
_ITEM_SHAPES = {3: "membership function is [left, peak, right]", 2: "band is [low, high]"}


def _coerce_list(raw: Any, current: tuple[Any, ...], is_angle: bool, where: str) -> Any:
    if not isinstance(raw, list):
        raise ConfigError(f"{where} must be a list, got {raw!r}")
    if current and isinstance(current[0], tuple):  # list of triangles, or of [low, high] pairs
        width = len(current[0])
        out = []
        for item in raw:
            if not isinstance(item, list) or len(item) != width:
                shape = _ITEM_SHAPES.get(width, f"item has {width} numbers")
                raise ConfigError(f"{where}: each {shape}")
            out.append(tuple(coerce(x, 0.0, is_angle, where) for x in item))
        return tuple(out)
    if current and isinstance(current[0], str):
        return tuple(coerce(x, "", False, where) for x in raw)
    return tuple(coerce(x, 0.0, is_angle, where) for x in raw)


def read_toml(path: str | Path) -> dict[str, Any]:
    """The parsed TOML file; errors name the file."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read config: {exc.strerror or exc}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise ConfigError(
            f"{p}:{line}: not UTF-8 text (TOML files are UTF-8): byte "
            f"0x{data[exc.start]:02x} at offset {exc.start}"
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: invalid TOML: {' '.join(str(exc).split())}") from None
    except RecursionError:  # tomllib parses nested arrays and tables recursively
        raise ConfigError(f"{p}: invalid TOML: arrays or tables nested too deeply") from None


def section_to_dict(sec: Any) -> dict[str, Any]:
    """One section as TOML values: angles in degrees under ``<name>_deg`` keys."""
    out: dict[str, Any] = {}
    for f in fields(sec):
        v = getattr(sec, f.name)
        if spec_of(f).is_angle:
            out[f.name + "_deg"] = to_deg(v)
        else:
            out[f.name] = plain(v)
    return out


def convert_section(
    sec: Any, sec_name: str, values: Mapping[str, Any], source: str
) -> dict[str, Any]:
    """TOML values of one section in code units; unknown keys and wrong types name the key."""
    specs = {f.name: spec_of(f) for f in fields(sec)}
    # the declared default gives a value's shape (the current value may be an empty list)
    shapes = {
        f.name: getattr(sec, f.name) if f.default is MISSING else f.default for f in fields(sec)
    }
    conv: dict[str, Any] = {}
    for key, raw in values.items():
        name = key[:-4] if key.endswith("_deg") else key
        spec = specs.get(name)
        if spec is None or spec.is_angle != key.endswith("_deg"):
            hint = f" (use {name}_deg)" if spec is not None and spec.is_angle else ""
            raise ConfigError(f"{source}: unknown config key {sec_name}.{key}{hint}")
        conv[name] = coerce(raw, shapes[name], spec.is_angle, f"{source}: {sec_name}.{key}")
    return conv


# -- keys of older config files -------------------------------------------------------------------
# (section, name) -> (section, name): settings that moved; a "_deg" suffix moves with the name
MOVED: dict[tuple[str, str], tuple[str, str]] = {
    ("odometry", "jump_search_distance"): ("search", "jump_distance"),
    ("odometry", "search_angle"): ("search", "angle"),
    ("odometry", "search_angle_step"): ("search", "angle_step"),
    ("odometry", "search_translation_step"): ("search", "translation_step"),
    ("odometry", "search_distance_penalty"): ("search", "distance_penalty"),
    ("odometry", "search_min_inlier_fraction"): ("search", "min_inlier_fraction"),
    ("odometry", "search_gate"): ("search", "gate"),
    ("odometry", "failure_search_angle"): ("search", "failure_angle"),
    ("odometry", "failure_search_distance"): ("search", "failure_distance"),
    ("odometry", "search_after_gap"): ("search", "after_gap"),
}

_ANY = object()
# (section, key) -> (the value that did nothing, or _ANY; why the setting went)
REMOVED: dict[tuple[str, str], tuple[Any, str]] = {
    ("matching", "repair_iterations"): (
        0,
        "re-pairing the feature points with the refined motion; line matching refines it",
    ),
    ("matching", "repair_distance"): (_ANY, "the pairing distance of the removed re-pairing"),
    ("refinement", "skip_with_line_pairs"): (
        0,
        "leaving a motion from line pairs unrefined; every motion is refined",
    ),
}


def _is_noop(raw: Any, noop: Any) -> bool:
    return noop is _ANY or (type(raw) is type(noop) and raw == noop)


def _move(sec: str, key: str) -> tuple[str, str] | None:
    name, deg = (key[:-4], "_deg") if key.endswith("_deg") else (key, "")
    target = MOVED.get((sec, name))
    return (target[0], target[1] + deg) if target else None


def translate_legacy(data: Mapping[str, Any], source: str) -> dict[str, Any]:
    """``data`` with moved keys in their new place (a FutureWarning each) and removed keys gone.

    A removed key still holding the value with which it did nothing is dropped with a warning;
    any other value is a ConfigError, since what it asked for no longer exists.
    """
    out: dict[str, Any] = {k: dict(v) if isinstance(v, Mapping) else v for k, v in data.items()}
    for sec, values in data.items():
        if not isinstance(values, Mapping):
            continue
        for key, raw in values.items():
            target = _move(sec, key)
            if target is not None:
                new_sec, new_key = target
                dest = out.setdefault(new_sec, {})
                if not isinstance(dest, dict):
                    raise ConfigError(f"{source}: [{new_sec}] must be a table")
                if new_key in dest:
                    raise ConfigError(
                        f"{source}: {sec}.{key} has moved to {new_sec}.{new_key}, "
                        f"which is given too: keep only {new_sec}.{new_key}"
                    )
                warnings.warn(
                    f"{source}: {sec}.{key} has moved to {new_sec}.{new_key}; "
                    "it is read there, please rename it",
                    FutureWarning,
                    stacklevel=3,
                )
                dest[new_key] = raw
                del out[sec][key]
            elif (sec, key) in REMOVED:
                noop, what = REMOVED[(sec, key)]
                if not _is_noop(raw, noop):
                    raise ConfigError(
                        f"{source}: {sec}.{key} = {raw!r}: the setting was removed ({what}); "
                        "delete the key"
                    )
                warnings.warn(
                    f"{source}: {sec}.{key} was removed ({what}); the key is ignored, "
                    "please delete it",
                    FutureWarning,
                    stacklevel=3,
                )
                del out[sec][key]
    return out
