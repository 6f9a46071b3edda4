"""Deployable policies: the policy file format (:mod:`.format`) and the shipped policies (package data:
``<algorithm>_<task>_<airframe>.pt`` policy files for training seed 0, ``..._seed<k>.pt`` for seed k;
see README.md).

    path = shipped_policy("altitude", "volantex_ranger")          # PPO, seed 0 by default
    path = shipped_policy("altitude", "airship_v7", "sac", seed=2)
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
#: Learning algorithms whose policies ship (the ``falcon-rl eval --controller`` names of shipped policies).
ALGORITHMS: tuple[str, ...] = ("ppo", "sac", "td3")


def available() -> list[str]:
    """Stems of the shipped policy files, e.g. ``ppo_altitude_volantex_ranger``."""
    return sorted(p.stem for p in HERE.glob("*.pt"))


def shipped_name(task: str, airframe: str, algorithm: str = "ppo", seed: int = 0) -> str:
    """File name of the shipped ``algorithm`` policy of (task, airframe) trained with ``seed``."""
    suffix = "" if seed == 0 else f"_seed{seed}"
    return f"{algorithm}_{task}_{Path(airframe).stem}{suffix}.pt"


def shipped_policy(task: str, airframe: str, algorithm: str = "ppo", seed: int = 0) -> Path:
    """Path of the shipped ``algorithm`` policy for (task, airframe) trained with ``seed``; ValueError
    (naming what ships) when there is none."""
    path = HERE / shipped_name(task, airframe, algorithm, seed)
    if not path.is_file():
        seed_text = "" if seed == 0 else f" of seed {seed}"
        raise ValueError(f"no shipped {algorithm} policy{seed_text} for task {task!r} on {airframe!r}; "
                         f"shipped: {available()}")
    return path


__all__ = ["ALGORITHMS", "FORMAT", "LEGACY_FORMATS", "DeployedPolicy", "FileFormatError", "PolicyNetwork",
           "available", "export_torchscript", "load_policy", "policy_document", "read_policy", "save_policy",
           "shipped_name", "shipped_policy"]
