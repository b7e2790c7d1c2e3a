"""The local map stage: the keyframe each scan is matched against, the surfaces of the last
keyframes, and the previous scan."""

from __future__ import annotations

import functools
import importlib
import math
from types import ModuleType

import numpy as np
from numpy.typing import NDArray

from .._kernels import f64
from ..config import MatchingConfig, RefinementConfig
from ..features import Features
from ..geometry import Pose3, compose3, relative3
from ..matching import SurfacePoints, surface_points

__all__ = ["LocalMap"]

FloatArray = NDArray[np.float64]


@functools.cache
def _kernels() -> ModuleType:
    """The compiled kernels (``_kernels.pipeline``), imported with numba on first use and kept
    (``import fuzzypos`` does not import numba)."""
    return importlib.import_module("fuzzypos._kernels.pipeline")


class LocalMap:
    """The keyframe (its features and pose), renewed once the robot has moved
    ``keyframe_distance`` or turned ``keyframe_angle`` from it (``[matching]``); the surfaces
    of the last ``local_map_keyframes`` keyframes, each with the pose it was seen from, kept
    where the refinement runs (``[refinement]``); and the previous scan where it is not the
    keyframe."""

    def __init__(self, matching: MatchingConfig, refinement: RefinementConfig) -> None:
        self.matching = matching
        self.refinement = refinement
        self.reset()

    def reset(self) -> None:
        self._features: Features | None = None
        self._pose: FloatArray = np.zeros(3)
        self._surface: SurfacePoints | None = None
        self._recent: list[tuple[SurfacePoints, FloatArray]] = []
        self._previous: tuple[Features, FloatArray] | None = None
        # the last pose from_keyframe was asked about, the keyframe it was seen from and
        # that pose relative to it (the positioner asks twice per scan, about one pose)
        self._relative: tuple[FloatArray, FloatArray, Pose3] | None = None

    @property
    def features(self) -> Features:
        """The keyframe's features."""
        if self._features is None:
            raise RuntimeError("the local map has no keyframe yet")
        return self._features

    @property
    def keyframes(self) -> int:
        """How many keyframes' surfaces the local map holds."""
        return len(self._recent)

    def from_keyframe(self, pose: FloatArray, increment: FloatArray) -> FloatArray:
        """The motion ``increment`` from ``pose`` expressed from the keyframe: what was
        estimated up to ``pose``, then ``increment``."""
        # in floats (compose3/relative3: the arithmetic of compose/relative without an array
        # per step), one array for the result
        return np.array(compose3(self._relative_of(pose), increment.tolist()))

    def at(self, pose: FloatArray) -> FloatArray:
        """``from_keyframe(pose, zeros)``: ``pose`` seen from the keyframe. Where no coordinate
        of it is zero, composing the zero motion adds and subtracts zeros to nonzero numbers
        (and the angle needs no wrapping): the very floats, without the arithmetic."""
        rel = self._relative_of(pose)
        if rel[0] != 0.0 and rel[1] != 0.0 and rel[2] != 0.0:
            return np.array(rel)
        return np.array(compose3(rel, (0.0, 0.0, 0.0)))

    def _relative_of(self, pose: FloatArray) -> Pose3:
        """``pose`` relative to the keyframe's, kept for the next call with the same two."""
        seen = self._relative
        if seen is not None and seen[0] is pose and seen[1] is self._pose:
            return seen[2]
        rel = relative3(self._pose.tolist(), pose.tolist())
        self._relative = (pose, self._pose, rel)
        return rel

    def pose_of(self, from_keyframe: FloatArray) -> FloatArray:
        """The pose at ``from_keyframe`` seen from the keyframe."""
        return np.array(self.pose3_of(from_keyframe))

    def pose3_of(self, from_keyframe: FloatArray) -> Pose3:
        """:meth:`pose_of` as three floats."""
        return compose3(self._pose.tolist(), from_keyframe.tolist())

    def add(self, features: Features, pose: FloatArray, from_keyframe: FloatArray | None) -> bool:
        """The scan just estimated: it becomes the keyframe where matching it failed
        (``from_keyframe`` None: start afresh from it) or it lies far enough from the
        keyframe, else it is kept as the previous scan. Whether it became the keyframe."""
        m = self.matching
        if from_keyframe is None:
            renew = True
        else:
            x, y, theta = from_keyframe.tolist()
            renew = math.hypot(x, y) >= m.keyframe_distance or abs(theta) >= m.keyframe_angle
        if renew:
            self.set_keyframe(features, pose)
            return True
        self._previous = (features, pose)
        return False

    def set_keyframe(self, features: Features, pose: FloatArray) -> None:
        self._features = features
        self._pose = pose
        self._surface = None
        self._previous = None  # the latest scan is the keyframe itself
        r = self.refinement
        if not r.enabled:
            return
        self._recent.append((self._surface_of(features), np.asarray(pose, dtype=float)))
        del self._recent[: -r.local_map_keyframes]

    def surface(self) -> SurfacePoints:
        """The recent keyframes' surface points in the keyframe's frame (built once per
        keyframe, with one grid or KD-tree)."""
        if self._surface is None:
            parts = self._recent
            self._surface = parts[0][0] if len(parts) == 1 else self._map_of(parts)
        return self._surface

    @property
    def has_previous(self) -> bool:
        """Whether the previous scan (with points) is not the keyframe itself."""
        return self._previous is not None and self._previous[0].points.shape[0] > 0

    def search_surface(self) -> SurfacePoints:
        """The local map and the previous scan (where it is not the keyframe): after a jump
        or a gap the latest view of the place overlaps most with the new scan."""
        if self._previous is None or self._previous[0].points.shape[0] == 0:
            return self.surface()
        features, pose = self._previous
        return self._map_of([*self._recent, (self._surface_of(features), pose)])

    def _surface_of(self, features: Features) -> SurfacePoints:
        return surface_points(
            features.points, features.ranges, features.uncertainty, self.refinement
        )

    def _map_of(self, parts: list[tuple[SurfacePoints, FloatArray]]) -> SurfacePoints:
        """Surface points seen from the given poses, in the keyframe's frame (one grid or
        KD-tree over them all, built on first use)."""
        key = self._pose.tolist()
        moves, ends, n = [], [], 0
        for surf, pose in parts:
            x, y, theta = relative3(key, pose.tolist())
            moves.append((x, y, math.cos(theta), math.sin(theta)))
            n += surf.xy.shape[0]
            ends.append(n)
        weight = np.concatenate([surf.weight for surf, _ in parts])
        xy, normal = _kernels().move_surfaces(  # every part moved in one loop
            f64(np.concatenate([surf.xy for surf, _ in parts])),
            f64(np.concatenate([surf.normal for surf, _ in parts])),
            np.array(moves), np.array(ends, dtype=np.int64),
        )  # fmt: skip
        return SurfacePoints(xy, normal, weight)
