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

Stopping when solved (``stop_when``): a run ends at the first validation whose summary meets every
condition, each metric averaged over the protocol's cases as the score averages it, *and* whose weights
meet them again on ``confirm_episodes`` confirmation episodes (100 by default, the final test's count)
drawn from their own seeds (``seed + CONFIRMATION_SEED``); when the confirmation misses a condition the
run trains on. A 16-episode validation alone is a small sample: a run stopped on one (RMSE <= 0.5 m)
tested RMSE 0.504 m on the 100 test episodes. The confirmation keeps the test episodes unseen, so a
policy within sampling noise of a bound may still test just across it, but no longer on the strength of
16 episodes.

    conditions = parse_stop_when("survival>=1,acquisition>=0.95,rmse_m<=0.5", ["survival", ...])
    conditions_met(result.summary, conditions)   # True on the validation, then on the confirmation: stop
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Iterable
from dataclasses import dataclass

from ..policies.format import FileFormatError, check_policy_document

#: Seed offset of the validation episodes of periodic evaluations (EVAL_SEED is the test's).
VALIDATION_SEED = 20_000
#: Seed offset of the episodes that confirm a validation meeting ``stop_when`` before the run stops.
CONFIRMATION_SEED = 30_000

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


#: Comparisons a stop condition may use.
STOP_OPERATORS = {">=": operator.ge, "<=": operator.le}
_CONDITION = re.compile(r"^\s*([A-Za-z_][\w]*)\s*(>=|<=)\s*(\S+)\s*$")


@dataclass(frozen=True)
class StopCondition:
    """``metric op bound``, e.g. ``rmse_m <= 0.5``; met by a summary whose case mean of ``metric``
    is a number that satisfies it (a missing or NaN value never meets it)."""

    metric: str
    op: str
    bound: float

    def met(self, summary: dict[str, float]) -> bool:
        value = _mean_of(summary, self.metric)
        return value is not None and not math.isnan(value) and STOP_OPERATORS[self.op](value, self.bound)

    def __str__(self) -> str:
        return f"{self.metric}{self.op}{self.bound:g}"


def parse_stop_when(text: str, metrics: Iterable[str]) -> tuple[StopCondition, ...]:
    """Conditions of ``"metric>=bound,metric<=bound,..."`` over the protocol's ``metrics`` (summary
    keys without their case prefix); ``""`` gives none. One-line ValueError naming the part that is
    not ``metric>=number`` or ``metric<=number``, an unknown metric or a non-finite bound."""
    known = list(metrics)
    conditions = []
    for part in filter(str.strip, text.split(",")):
        match = _CONDITION.match(part)
        if match is None:
            raise ValueError(f"stop_when: {part.strip()!r} is not METRIC>=NUMBER or METRIC<=NUMBER")
        metric, op, number = match.groups()
        if metric not in known:
            raise ValueError(f"stop_when: unknown metric {metric!r}; the protocol reports {known}")
        try:
            bound = float(number)
        except ValueError:
            bound = math.nan
        if not math.isfinite(bound):
            raise ValueError(f"stop_when: the bound of {metric} must be a finite number, got {number!r}")
        conditions.append(StopCondition(metric, op, bound))
    if text.strip() and not conditions:
        raise ValueError(f"stop_when: no condition in {text!r}")
    return tuple(conditions)


def conditions_met(summary: dict[str, float], conditions: Iterable[StopCondition]) -> bool:
    """Whether ``summary`` meets every one of ``conditions`` (False when there are none)."""
    conditions = tuple(conditions)
    return bool(conditions) and all(c.met(summary) for c in conditions)


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


__all__ = ["CONFIRMATION_SEED", "GATES", "STOP_OPERATORS", "VALIDATION_SEED", "BestPolicy", "StopCondition",
           "conditions_met", "parse_stop_when", "selection_score"]
