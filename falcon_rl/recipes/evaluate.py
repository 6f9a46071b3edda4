"""Evaluation hook: score the current actor on the harness's protocol for its task.

altitude -> ``altitude_protocol`` (survival, acquisition, RMSE, settling time, overshoot over
``episodes`` 30 s episodes); attitude -> ``attitude_protocol`` (bank / climb-rate / airspeed RMSE per
maneuver); other tasks are not scored (empty result).
"""

from __future__ import annotations

import math

from tensordict.nn import TensorDictModule

from ..envs.maneuvers import MANEUVERS
from ..evaluation.protocols import ProtocolResult, altitude_protocol, attitude_protocol
from .common import PolicyNet, TrainConfig
from .export import DeployedPolicy, policy_document

#: Seed offset of the evaluation episodes (never the training seed).
EVAL_SEED = 10_000


def deployed(net: PolicyNet) -> DeployedPolicy:
    """A frozen copy of ``net`` as deployed (deterministic tanh(loc), normaliser baked in)."""
    doc = policy_document(net, {})
    policy = DeployedPolicy(doc["arch"], doc["norm"])
    policy.mlp.load_state_dict(doc["mlp"])
    return policy.eval()


def evaluate(net: PolicyNet, cfg: TrainConfig, label: str, episodes: int,
             maneuvers: tuple[str, ...] = MANEUVERS) -> ProtocolResult | None:
    """Run the task's protocol on a frozen copy of ``net`` (None for tasks without one)."""
    policy = deployed(net)

    def factory(env):
        return TensorDictModule(policy.to(env.device), in_keys=["observation"], out_keys=["action"])

    common = {"seed": cfg.seed + EVAL_SEED, "backend": cfg.backend, "device": cfg.device}
    if cfg.task == "altitude":
        return altitude_protocol(cfg.airframe, label, factory, episodes=episodes,
                                 episode_seconds=cfg.eval_seconds, **common)
    if cfg.task == "attitude":
        return attitude_protocol(cfg.airframe, label, factory, maneuvers=maneuvers,
                                 episodes=max(1, episodes // len(maneuvers)), **common)
    return None


def eval_scalars(result: ProtocolResult | None) -> dict[str, float]:
    """``eval/<metric>`` scalars of a protocol result (NaN-free)."""
    if result is None:
        return {}
    return {f"eval/{k}": v for k, v in result.summary.items() if not math.isnan(v)}


__all__ = ["EVAL_SEED", "deployed", "eval_scalars", "evaluate"]
