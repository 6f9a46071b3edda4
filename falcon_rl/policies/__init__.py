"""Deployable policies: the policy file format (:mod:`.format`) and the shipped policies (package data:
``<algorithm>_<task>_<airframe>.pt`` policy files, see README.md).

    path = shipped_policy("altitude", "volantex_ranger")          # PPO by default
    policy = falcon_rl.policies.load_policy(path, env)

A file that cannot be used (unreadable, truncated, corrupt, foreign, or of other sizes than ``env``)
raises :class:`FileFormatError`, a one-line ValueError naming the file and the reason.
"""

from __future__ import annotations

from pathlib import Path

from .format import (
    FORMAT,
    LEGACY_FORMATS,
    DeployedPolicy,
    FileFormatError,
    PolicyNetwork,
    export_torchscript,
    load_policy,
    policy_document,
    read_policy,
    save_policy,
)

HERE = Path(__file__).resolve().parent


def available() -> list[str]:
    """Stems of the shipped policy files, e.g. ``ppo_altitude_volantex_ranger``."""
    return sorted(p.stem for p in HERE.glob("*.pt"))


def shipped_policy(task: str, airframe: str, algorithm: str = "ppo") -> Path:
    """Path of the shipped ``algorithm`` policy for (task, airframe); ValueError when none ships."""
    path = HERE / f"{algorithm}_{task}_{Path(airframe).stem}.pt"
    if not path.is_file():
        raise ValueError(f"no shipped {algorithm} policy for task {task!r} on {airframe!r}; shipped: "
                         f"{available()}")
    return path


__all__ = ["FORMAT", "LEGACY_FORMATS", "DeployedPolicy", "FileFormatError", "PolicyNetwork", "available",
           "export_torchscript", "load_policy", "policy_document", "read_policy", "save_policy",
           "shipped_policy"]
