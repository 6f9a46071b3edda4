"""The bookkeeping around a recipe's loop: resume, counters, logs, progress bar, periodic
checkpoints and evaluations, and the final policy export.

    run = TrainingRun("ppo", cfg, env, actor_net, modules, optimizers)   # replay=buffer (SAC, TD3)
    run.start()                                    # seeds, or restores a checkpoint with --resume
    for batch in collector:                        # collector of run.remaining_frames()
        ...learn...
        run.after_batch(batch, {"loss/actor": ...})
    summary = run.finish()                         # checkpoint, policy.pt, policy.ts, final evaluation
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import torch

from ..policies import export_torchscript, save_policy
from .checkpoint import load_checkpoint, load_replay, restore, save_checkpoint
from .common import Counters, EpisodeStats, PolicyNet, TrainConfig, set_threads
from .evaluate import eval_scalars, evaluate
from .logging import Progress, log_scalars, make_logger


class TrainingRun:
    """Counters, logs, checkpoints and evaluations of one training run (see the module docstring).

    ``replay``: the off-policy run's replay buffer, saved in every checkpoint and refilled on resume.
    """

    def __init__(self, algorithm: str, cfg: TrainConfig, env, actor: PolicyNet,
                 modules: dict[str, torch.nn.Module], optimizers: dict[str, torch.optim.Optimizer],
                 replay=None):
        self.algorithm, self.cfg, self.env, self.actor = algorithm, cfg, env, actor
        self.modules, self.optimizers, self.replay = modules, optimizers, replay
        self.out = None if cfg.out is None else Path(cfg.out)
        self.counters = Counters()
        self.name = f"{algorithm}_{cfg.task}_{cfg.airframe}"
        self.history: list[dict[str, float]] = []
        self.final_eval = None

    # ------------------------------------------------------------------ files
    @property
    def checkpoint_path(self) -> Path | None:
        return None if self.out is None else self.out / "checkpoint.pt"

    def start(self) -> Counters:
        """Seed torch, or restore everything from ``out``/checkpoint.pt when resuming."""
        set_threads(self.cfg)
        torch.manual_seed(self.cfg.seed)
        path = self.checkpoint_path
        if self.cfg.resume and path is not None and path.exists():
            doc = load_checkpoint(path, self.cfg.device)
            counters = restore(doc, self.modules, self.optimizers, self.actor.norm, self.env)
            self.counters = Counters(**counters)
            if self.replay is not None and "replay" in doc:
                load_replay(self.replay, doc["replay"])
        self.logger = make_logger(self.cfg.logger, self.out, self.name, self.cfg.to_dict())
        self.stats = EpisodeStats(frames_at_start=self.counters.frames)
        self.progress = Progress(self.cfg.frames, self.counters.frames, self.name, self.cfg.progress)
        self._t0 = time.perf_counter() - self.counters.wall_seconds
        return self.counters

    def remaining_frames(self) -> int:
        return max(self.cfg.frames - self.counters.frames, 0)

    def save(self) -> Path | None:
        if self.checkpoint_path is None:
            return None
        self.counters.wall_seconds = time.perf_counter() - self._t0
        self.counters.last_checkpoint_frames = self.counters.frames
        return save_checkpoint(self.checkpoint_path, algorithm=self.algorithm, config=self.cfg.to_dict(),
                               counters=dataclasses.asdict(self.counters), modules=self.modules,
                               optimizers=self.optimizers, norm=self.actor.norm.stats(), env=self.env,
                               replay=self.replay)

    # ------------------------------------------------------------------ per batch
    def after_batch(self, batch, scalars: dict[str, float]) -> None:
        """Count the batch, log, advance the bar; checkpoint and evaluate when due."""
        c, cfg = self.counters, self.cfg
        frames = batch.numel()
        c.frames += frames
        c.iterations += 1
        c.episodes += int(batch["next", "done"].sum())
        rate = self.stats.rate(c.frames)
        row = {**self.stats.update(batch), **scalars, "time/env_steps_per_s": rate,
               "time/wall_s": time.perf_counter() - self._t0}
        log_scalars(self.logger, row, c.frames)
        self.history.append({"frames": c.frames, **row})
        self.progress.update(frames, self.stats.mean_return, self.stats.survival, rate)
        if cfg.eval_every and c.frames - c.last_eval_frames >= cfg.eval_every and c.frames < cfg.frames:
            c.last_eval_frames = c.frames
            result = evaluate(self.actor, cfg, self.algorithm, cfg.eval_episodes)
            log_scalars(self.logger, eval_scalars(result), c.frames)
            if result is not None:
                self.progress.write(f"[{c.frames:,} frames] eval: " + ", ".join(
                    f"{k} {v:.3g}" for k, v in result.summary.items()))
        if c.frames - c.last_checkpoint_frames >= cfg.checkpoint_every and c.frames < cfg.frames:
            self.save()

    # ------------------------------------------------------------------ end
    def meta(self) -> dict:
        return {"algorithm": self.algorithm, "task": self.cfg.task, "airframe": self.cfg.airframe,
                "frames": self.counters.frames, "seed": self.cfg.seed, "backend": self.cfg.backend,
                "episode_seconds": self.cfg.episode_seconds}

    def finish(self) -> dict:
        """Final checkpoint, policy file, TorchScript export and evaluation; returns a summary."""
        self.progress.close()
        wall = time.perf_counter() - self._t0
        rate = self.stats.rate(self.counters.frames)
        summary = {"algorithm": self.algorithm, "task": self.cfg.task, "airframe": self.cfg.airframe,
                   "frames": self.counters.frames, "iterations": self.counters.iterations,
                   "updates": self.counters.updates, "episodes": self.counters.episodes,
                   "wall_seconds": wall, "env_steps_per_s": rate,
                   "train_return": self.stats.mean_return, "train_survival": self.stats.survival}
        if self.out is not None:
            summary["checkpoint"] = str(self.save())
            policy = save_policy(self.out / "policy.pt", self.actor, self.meta())
            summary["policy"] = str(policy)
            summary["torchscript"] = str(export_torchscript(self.out / "policy.ts", policy))
        if self.cfg.final_eval_episodes > 0:
            self.final_eval = evaluate(self.actor, self.cfg, self.algorithm, self.cfg.final_eval_episodes)
            scalars = eval_scalars(self.final_eval)
            log_scalars(self.logger, scalars, self.counters.frames)
            summary["eval"] = None if self.final_eval is None else dict(self.final_eval.summary)
            summary["eval_episodes"] = self.cfg.final_eval_episodes
        if self.out is not None:
            (self.out / "summary.json").write_text(json.dumps(summary, indent=2, default=str))
        return summary


__all__ = ["TrainingRun"]
