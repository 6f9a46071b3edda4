"""Evaluation hook: score the current actor on the protocol its task's ``TaskSpec`` names (e.g.
altitude: survival, acquisition, RMSE, settling time, overshoot; attitude: bank / climb-rate /
airspeed RMSE per maneuver); a task without a protocol is not scored (None).

An evaluation leaves torch's global generator as it found it, so that evaluating during training does
not change what the training draws.
"""

from __future__ import annotations

import math

import torch
from tensordict.nn import TensorDictModule

from ..envs import task_spec
from ..evaluation.protocols import ProtocolResult
from ..policies.format import DeployedPolicy, policy_document, policy_from_document
from .common import PolicyNet, TrainConfig

#: Seed offset of the evaluation episodes (never the training seed).
EVAL_SEED = 10_000


def deployed(net: PolicyNet) -> DeployedPolicy:
    """A frozen copy of ``net`` as deployed (deterministic tanh(loc), normaliser baked in)."""
    return policy_from_document(policy_document(net, {}))


def evaluate(net: PolicyNet | dict, cfg: TrainConfig, label: str, episodes: int, seed_offset: int = EVAL_SEED,
             **options) -> ProtocolResult | None:
    """Run the task's protocol on a frozen copy of ``net`` (a network or a policy document) with
    ``episodes`` (per case, e.g. per maneuver), seed ``cfg.seed + seed_offset`` (the test's by default;
    periodic evaluations use the validation seed), ``cfg.eval_seconds`` and ``options`` (protocol
    options); None for a task without one."""
    spec = task_spec(cfg.task)
    if spec.protocol is None:
        return None
    policy = policy_from_document(net) if isinstance(net, dict) else deployed(net)

    def factory(env):
        return TensorDictModule(policy.to(env.device), in_keys=["observation"], out_keys=["action"])

    protocol = spec.protocol_function()
    device = torch.device(cfg.device)
    cuda = [device.index or 0] if device.type == "cuda" else []
    with torch.random.fork_rng(devices=cuda):
        return protocol(cfg.airframe, label, factory, episodes=episodes, seed=cfg.seed + seed_offset,
                        backend=cfg.backend, device=cfg.device, episode_seconds=cfg.eval_seconds, **options)


def eval_scalars(result: ProtocolResult | None) -> dict[str, float]:
    """``eval/<metric>`` scalars of a protocol result (NaN-free)."""
    if result is None:
        return {}
    return {f"eval/{k}": v for k, v in result.summary.items() if not math.isnan(v)}


__all__ = ["EVAL_SEED", "deployed", "eval_scalars", "evaluate"]
