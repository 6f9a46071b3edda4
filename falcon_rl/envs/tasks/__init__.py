"""Flight tasks, one small module each (observation, reward, termination, reference), each registering
its :class:`TaskSpec` (gym id, evaluation protocol and metrics, baselines, figure, training defaults).

``task_spec(name)`` is the record of a task; ``TASKS`` maps a task name to its (Task class, config
dataclass) and ``TASK_SPECS`` to its spec (both live, read-only views of the registry).
"""

from __future__ import annotations

from .altitude import AltitudeConfig, AltitudeTask
from .attitude import AttitudeConfig, AttitudeTask
from .base import TERMINATION_CODE, TERMINATION_REASONS, Task, TaskConfig
from .climb_descend import ClimbDescendConfig, ClimbDescendTask
from .path_following import PathFollowingConfig, PathFollowingTask
from .registry import (
    TASK_SPECS,
    TASKS,
    TRIM_HOLD,
    Metric,
    TaskSpec,
    register_task,
    resolve,
    task_names,
    task_spec,
    unregister_task,
)
from .trajectory import TrajectoryConfig, TrajectoryTask

__all__ = [
    "TASKS",
    "TASK_SPECS",
    "TERMINATION_CODE",
    "TERMINATION_REASONS",
    "TRIM_HOLD",
    "AltitudeConfig",
    "AltitudeTask",
    "AttitudeConfig",
    "AttitudeTask",
    "ClimbDescendConfig",
    "ClimbDescendTask",
    "Metric",
    "PathFollowingConfig",
    "PathFollowingTask",
    "Task",
    "TaskConfig",
    "TaskSpec",
    "TrajectoryConfig",
    "TrajectoryTask",
    "register_task",
    "resolve",
    "task_names",
    "task_spec",
    "unregister_task",
]
