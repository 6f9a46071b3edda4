"""Keeping the best policy of a run (``keep_best``): every periodic evaluation scores the current
weights on *validation* episodes (the task's protocol with seed ``seed + VALIDATION_SEED``, never the
final evaluation's ``seed + EVAL_SEED``), and the run ships the best of those snapshots and of its
last weights, the way a practitioner picks a checkpoint on held-out episodes before the test. Where
the protocol's episodes do not depend on the seed (the attitude maneuvers, flown from trim in calm
air) the validation flies the test's episodes, and the choice is made on the protocol itself.

Score (lower is better, compared as a tuple): ``(-survival, -acquisition, ..., metric)`` (the
:data:`GATES`), each the mean over the protocol's cases (e.g. maneuvers), where ``metric`` is the
task's ``TaskSpec.select_on`` (altitude: RMSE, attitude: bank RMSE); a missing gate counts as 1, a
NaN gate as 0 and a NaN metric as +inf.

    best = BestPolicy("rmse_m")
    best.offer(policy_document(net, meta), result.summary, frames)   # True when it is the new best
    best.doc, best.frames, best.score
"""

from __future__ import annotations

import math

from ..policies.format import FileFormatError, check_policy_document

#: Seed offset of the validation episodes of periodic evaluations (EVAL_SEED is the test's).
VALIDATION_SEED = 20_000

#: Summary metrics (fractions) that must be as high as possible before the task's metric counts, in
#: order: survival, then whichever success fraction the task's protocol reports.
GATES = ("survival", "acquisition", "completion", "level_off")


def _mean_of(summary: dict[str, float], key: str) -> float | None:
    """Mean of ``summary[key]`` and every ``summary["<case>/<key>"]``; None when there is none."""
    values = [v for k, v in summary.items() if k == key or k.endswith("/" + key)]
    return sum(values) / len(values) if values else None


def selection_score(summary: dict[str, float], metric: str) -> tuple[float, ...]:
    """``(-gate for each of GATES, metric)`` of a protocol summary (lower is better); a missing gate
    counts as 1 and a NaN one as 0, a missing or NaN metric as +inf (e.g. an RMSE after an acquisition
    that never came)."""
    gates = [_mean_of(summary, g) for g in GATES]
    value = _mean_of(summary, metric)
    return (*(-1.0 if g is None else 0.0 if math.isnan(g) else -g for g in gates),
            math.inf if value is None or math.isnan(value) else value)


class BestPolicy:
    """The best-scoring policy document offered so far, with its score and training frames."""

    def __init__(self, metric: str):
        self.metric = metric
        self.doc: dict | None = None
        self.score: tuple[float, ...] | None = None
        self.frames = -1
        self.summary: dict[str, float] = {}

    def offer(self, doc: dict, summary: dict[str, float], frames: int) -> bool:
        """Keep ``doc`` (a policy document) when its validation ``summary`` beats the best so far
        (ties keep the earlier snapshot); returns whether it did."""
        score = selection_score(summary, self.metric)
        if self.score is not None and not score < self.score:
            return False
        self.doc, self.score, self.frames, self.summary = doc, score, frames, dict(summary)
        return True

    def state(self) -> dict:
        """Plain contents for a checkpoint (weights-only loadable)."""
        return {"doc": self.doc, "score": list(self.score or ()), "frames": self.frames,
                "summary": dict(self.summary)}

    def load(self, state: object, path) -> None:
        """Restore :meth:`state` from a checkpoint at ``path`` (FileFormatError when it is damaged)."""
        ok = isinstance(state, dict) and isinstance(state.get("score"), list) and type(
            state.get("frames")) is int and isinstance(state.get("summary"), dict)
        if not ok:
            raise FileFormatError(path, "damaged best-policy entry in the checkpoint")
        if state["doc"] is None:
            return
        check_policy_document(state["doc"], path)
        self.doc, self.frames, self.summary = state["doc"], state["frames"], dict(state["summary"])
        self.score = tuple(float(v) for v in state["score"])


__all__ = ["GATES", "VALIDATION_SEED", "BestPolicy", "selection_score"]
