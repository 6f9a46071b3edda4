"""The policy file format: the acting network with its observation normaliser baked in.

A policy file (``policy.pt``) is a weights-only ``torch.save`` of

    {"format": "falcon-rl-policy/1", "arch": {obs_dim, act_dim, out_dim, cells, activation},
     "mlp": state_dict, "norm": {"mean", "var", "enabled", "clip", "min_std"},
     "meta": {"algorithm", "task", "airframe", "frames", "seed", ...}}

and acts as ``action = tanh(mlp(clip((obs - mean) / max(sqrt(var), min_std)))[..., :act_dim])`` [N, A] in
[-1, 1]: the deterministic action of PPO and SAC (TanhNormal's mean) and TD3's action.
:func:`export_torchscript` writes the same function as a TorchScript file that needs no falcon-rl.

Writing a file needs only a :class:`PolicyNetwork` (the training recipes' ``PolicyNet`` is one), so this
module knows nothing about training.
"""

from __future__ import annotations

import itertools
import os
from pathlib import Path
from typing import Any, Protocol

import torch
from tensordict.nn import TensorDictModule
from torch import nn

FORMAT = "falcon-rl-policy/1"

#: Activation names of the ``arch`` entry -> module classes.
ACTIVATIONS: dict[str, type[nn.Module]] = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "silu": nn.SiLU}


class RunningStats(Protocol):
    """An observation normaliser that reports its statistics."""

    def stats(self) -> dict[str, torch.Tensor]:
        """``mean``, ``var``, ``enabled``, ``clip``, ``min_std`` (and optionally ``count``) as tensors."""
        ...


class PolicyNetwork(Protocol):
    """What :func:`policy_document` needs from a trained network: ``mlp`` maps normalised observations to
    pre-tanh outputs whose first ``act_dim`` entries are the action; ``arch()`` describes it as the file's
    ``arch`` entry; ``norm.stats()`` gives the normaliser."""

    mlp: nn.Module
    norm: RunningStats

    def arch(self) -> dict:
        """``{"obs_dim", "act_dim", "out_dim", "cells", "activation"}`` of ``mlp``."""
        ...


def atomic_save(obj: Any, path: str | Path) -> Path:
    """``torch.save(obj)`` to ``path`` through a temporary file and ``os.replace``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "wb") as f:
            torch.save(obj, f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


class DeployedPolicy(nn.Module):
    """obs [N, D] -> action [N, A] in [-1, 1]; the normaliser lives in buffers."""

    def __init__(self, arch: dict, norm: dict[str, torch.Tensor]):
        super().__init__()
        self.act_dim = int(arch["act_dim"])
        sizes = [int(arch["obs_dim"]), *(int(c) for c in arch["cells"])]
        layers: list[nn.Module] = []
        for a, b in itertools.pairwise(sizes):
            layers += [nn.Linear(a, b), ACTIVATIONS[arch["activation"]]()]
        layers.append(nn.Linear(sizes[-1], int(arch["out_dim"])))
        self.mlp = nn.Sequential(*layers)
        enabled = bool(norm["enabled"])
        dim = sizes[0]
        self.register_buffer("mean", norm["mean"].float().clone() if enabled else torch.zeros(dim))
        std = norm["var"].float().sqrt().clamp_min(float(norm["min_std"])) if enabled else torch.ones(dim)
        self.register_buffer("std", std)
        self.clip = float(norm["clip"]) if enabled else float("inf")

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        x = ((obs.to(self.mean.dtype) - self.mean) / self.std).clamp(-self.clip, self.clip)
        return torch.tanh(self.mlp(x)[..., : self.act_dim])


def policy_document(net: PolicyNetwork, meta: dict) -> dict:
    """The policy file's contents for ``net`` (a trained :class:`PolicyNetwork`)."""
    return {"format": FORMAT, "arch": net.arch(),
            "mlp": {k: v.detach().cpu().clone() for k, v in net.mlp.state_dict().items()},
            "norm": {k: v.cpu() for k, v in net.norm.stats().items() if k != "count"}, "meta": dict(meta)}


def policy_from_document(doc: dict) -> DeployedPolicy:
    """The :class:`DeployedPolicy` (CPU, eval mode) of a policy file's contents."""
    policy = DeployedPolicy(doc["arch"], doc["norm"])
    policy.mlp.load_state_dict(doc["mlp"])
    return policy.eval()


def save_policy(path: str | Path, net: PolicyNetwork, meta: dict) -> Path:
    """Write the policy file for ``net`` atomically."""
    return atomic_save(policy_document(net, meta), path)


def read_policy(path: str | Path) -> tuple[DeployedPolicy, dict]:
    """(DeployedPolicy on CPU in eval mode, meta) from a policy file, loaded weights-only."""
    doc = torch.load(path, map_location="cpu", weights_only=True)
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"{path}: not a falcon-rl policy file")
    return policy_from_document(doc), doc["meta"]


def load_policy(path: str | Path, env=None) -> TensorDictModule:
    """The policy at ``path`` as a TensorDictModule reading "observation" and writing "action"
    (moved to ``env``'s device and dtype). Checks the observation and action sizes against ``env``."""
    policy, meta = read_policy(path)
    if env is not None:
        obs_dim, act_dim = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
        arch = (policy.mlp[0].in_features, policy.act_dim)
        if arch != (obs_dim, act_dim):
            raise ValueError(f"{path}: policy for obs/action sizes {arch}, env has {(obs_dim, act_dim)} "
                             f"(policy trained on task {meta.get('task')!r})")
        policy = policy.to(device=env.device, dtype=env.action_spec.dtype)
    module = TensorDictModule(policy, in_keys=["observation"], out_keys=["action"])
    module.meta = meta
    return module


def export_torchscript(path: str | Path, policy_path: str | Path) -> Path:
    """Trace the policy file at ``policy_path`` into a TorchScript file (obs [N, D] -> action [N, A])."""
    policy, meta = read_policy(policy_path)
    example = torch.zeros(1, policy.mlp[0].in_features)
    traced = torch.jit.trace(policy, example, check_inputs=[(torch.zeros(4, example.shape[-1]),)])
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    torch.jit.save(traced, str(tmp), _extra_files={"meta.txt": repr(meta)})
    tmp.replace(path)
    return path


__all__ = ["ACTIVATIONS", "FORMAT", "DeployedPolicy", "PolicyNetwork", "RunningStats", "atomic_save",
           "export_torchscript", "load_policy", "policy_document", "policy_from_document", "read_policy",
           "save_policy"]
