"""Flight tasks, one folder each: ``<name>/task.py`` (config, episode, observation, reward, termination,
reference), ``<name>/kernels.py`` (its fused Warp step) and ``<name>/spec.py``, which registers its
:class:`TaskSpec` (gym id, evaluation protocol and metrics, baselines, figure, training defaults).

``task_spec(name)`` is the record of a task, ``task_names()`` lists them and ``TASK_SPECS`` maps a name to
its spec (a live, read-only view of the registry).
"""

from __future__ import annotations

from .altitude import AltitudeConfig, AltitudeTask
from .attitude import AttitudeConfig, AttitudeTask
from .base import TERMINATION_CODE, TERMINATION_REASONS, Task, TaskConfig
from .climb_descend import ClimbDescendConfig, ClimbDescendTask
from .landing import LandingConfig, LandingTask
from .path_following import PathFollowingConfig, PathFollowingTask
from .registry import (
    TASK_SPECS,
    TRIM_HOLD,
    Metric,
    TaskSpec,
    register_task,
    resolve,
    task_names,
    task_spec,
    unregister_task,
)
from .sea_skimming import SeaSkimmingConfig, SeaSkimmingTask
from .trajectory import TrajectoryConfig, TrajectoryTask

__all__ = [
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
    "LandingConfig",
    "LandingTask",
    "Metric",
    "PathFollowingConfig",
    "PathFollowingTask",
    "SeaSkimmingConfig",
    "SeaSkimmingTask",
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
