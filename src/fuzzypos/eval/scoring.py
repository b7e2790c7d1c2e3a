"""Scoring trajectory files: the file interface over :mod:`fuzzypos.eval.metrics` (which scores
arrays). :func:`evaluate_trajectory` reads a TUM estimate, a relations file and/or a TUM
reference and scores the estimate (what ``fuzzypos evaluate`` prints)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

from ..io import read_relations, read_tum
from ..io.provenance import json_safe
from .metrics import (
    AbsoluteTrajectoryError,
    EvaluationError,
    RelationsErrors,
    RelativePoseError,
    absolute_trajectory_error,
    relations_errors,
    relative_pose_error,
)

__all__ = ["Evaluation", "evaluate_trajectory"]


@dataclass(eq=False)
class Evaluation:
    """:func:`evaluate_trajectory`'s scores; each None when not asked for."""

    estimate: str
    poses: int
    relations: RelationsErrors | None = None
    ate: AbsoluteTrajectoryError | None = None
    rpe_frame: RelativePoseError | None = None
    rpe_metre: RelativePoseError | None = None
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        ate = None if self.ate is None else {"rmse_m": self.ate.rmse_m, **self.ate.as_dict()}
        out: dict[str, Any] = json_safe(
            {
                "estimate": self.estimate,
                "poses": self.poses,
                "relations": None if self.relations is None else self.relations.as_dict(),
                "ate": ate,
                "rpe_1_frame": None if self.rpe_frame is None else self.rpe_frame.as_dict(),
                "rpe_1_m": None if self.rpe_metre is None else self.rpe_metre.as_dict(),
                "notes": self.notes,
            }
        )
        return out


def evaluate_trajectory(
    estimate: str | os.PathLike[str],
    *,
    relations: str | os.PathLike[str] | None = None,
    reference: str | os.PathLike[str] | None = None,
) -> Evaluation:
    """Score the TUM trajectory ``estimate`` against a relations file
    (:func:`~fuzzypos.eval.metrics.relations_errors`: all and local relations) and/or a
    reference TUM trajectory (ATE after SE(2) alignment,
    :func:`~fuzzypos.eval.metrics.absolute_trajectory_error`; RPE over 1 frame and over 1 m of
    the reference's path, :func:`~fuzzypos.eval.metrics.relative_pose_error`). At least one of
    the two is needed (``ValueError``). An RPE that has no pair (a reference shorter than 1 m)
    is left None with a note."""
    if relations is None and reference is None:
        raise ValueError("nothing to evaluate against: give relations and/or a reference")
    st, P = read_tum(estimate)
    if st.size == 0:
        raise ValueError(f"{os.fspath(estimate)}: no poses")
    ev = Evaluation(estimate=os.fspath(estimate), poses=int(st.size))
    if relations is not None:
        ev.relations = relations_errors(st, P, read_relations(relations))
    if reference is not None:
        rs, R = read_tum(reference)
        if rs.size == 0:
            raise ValueError(f"{os.fspath(reference)}: no poses")
        ev.ate = absolute_trajectory_error(rs, R, st, P)
        for attr, delta, unit in (("rpe_frame", 1, "frames"), ("rpe_metre", 1.0, "m")):
            try:
                setattr(ev, attr, relative_pose_error(rs, R, st, P, delta=delta, delta_unit=unit))
            except EvaluationError as exc:
                ev.notes.append(f"RPE over 1 {unit}: {exc}")
    return ev
