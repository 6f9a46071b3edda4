"""Flight tasks, one small module each (observation, reward, termination, reference).

``TASKS`` maps a task name to its (Task class, config dataclass).
"""

from __future__ import annotations

from .altitude import AltitudeConfig, AltitudeTask
from .attitude import AttitudeConfig, AttitudeTask
from .base import Task, TaskConfig
from .climb_descend import ClimbDescendConfig, ClimbDescendTask
from .path_following import PathFollowingConfig, PathFollowingTask
from .trajectory import TrajectoryConfig, TrajectoryTask

TASKS: dict[str, tuple[type[Task], type[TaskConfig]]] = {
    "altitude": (AltitudeTask, AltitudeConfig),
    "attitude": (AttitudeTask, AttitudeConfig),
    "climb_descend": (ClimbDescendTask, ClimbDescendConfig),
    "path_following": (PathFollowingTask, PathFollowingConfig),
    "trajectory": (TrajectoryTask, TrajectoryConfig),
}

__all__ = [
    "TASKS", "AltitudeConfig", "AltitudeTask", "AttitudeConfig", "AttitudeTask", "ClimbDescendConfig",
    "ClimbDescendTask", "PathFollowingConfig", "PathFollowingTask", "Task", "TaskConfig",
    "TrajectoryConfig", "TrajectoryTask",
]
