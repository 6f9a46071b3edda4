"""The bookkeeping around a recipe's loop: seeding, resume, collection in segments, counters, logs,
progress bar, periodic checkpoints and validations, and the final policy export.

    doc = prepare("ppo", cfg)                      # checks, threads, seeds; the checkpoint to resume
    env, nets, optimizers = ...                    # built after seeding: weights follow cfg.seed
    run = TrainingRun("ppo", cfg, env, actor_net, modules, optimizers)   # replay=buffer (SAC, TD3)
    run.start(doc)                                 # restores the checkpoint when resuming
    for batch in run.batches(policy, batch_frames):
        ...learn...
        run.after_batch(batch, {"loss/actor": ...})
    summary = run.finish()                         # checkpoint, policy.pt, policy.ts, final evaluation

Reproducibility: the same config gives bit-identical weights (same machine, versions and threads),
and a run killed and resumed from its last checkpoint ends with the weights of an uninterrupted one:
collection runs in segments that end where a checkpoint falls due, and every segment starts a fresh
Collector on envs reset and staggered from the counters, from the generator states the checkpoint
holds.

Evaluations: every ``eval_every`` frames the current weights fly the task's protocol on validation
episodes (seed + ``VALIDATION_SEED``); with ``keep_best`` the run ships the best of those snapshots
and its last weights (:mod:`.selection`; the checkpoint keeps the best so far and the last weights,
to go on training from). The final evaluation flies the shipped policy on the test episodes (seed +
``EVAL_SEED``), which no choice of the run has seen. With ``stop_when`` the run ends at the first
validation that meets its conditions (``summary["solved"]``: the frames and wall seconds it took); a
checkpoint remembers it, so resuming a solved run with the same conditions only finishes it.

Time: the summary's ``time_split`` divides this process's training loop into collecting (the Collector:
env steps, resets, the policy's forward passes), validating and learning (the rest), wall seconds.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from collections.abc import Iterator
from pathlib import Path

import torch
from tensordict import TensorDictBase
from torchrl.collectors import Collector

from ..atomic_files import remove_temporaries, write_atomic
from ..envs import task_spec
from ..policies import FileFormatError, export_torchscript
from ..policies.format import atomic_save, policy_document
from .checkpoint import check_resumable, load_checkpoint, load_replay, restore, save_checkpoint
from .checks import check_config
from .common import (
    Counters,
    EpisodeStats,
    PolicyNet,
    TrainConfig,
    seed_everything,
    set_threads,
    stagger_episodes,
    transition_shapes,
)
from .evaluate import eval_scalars, evaluate
from .logging import Progress, log_scalars, make_logger
from .selection import VALIDATION_SEED, BestPolicy, conditions_met, parse_stop_when

#: Files a run writes under ``out`` (each atomically, :func:`falcon_rl.atomic_files.write_atomic`).
OUTPUT_FILES = ("checkpoint.pt", "policy.pt", "policy.ts", "summary.json")


def prepare(algorithm: str, cfg: TrainConfig) -> dict | None:
    """Everything before a recipe builds anything: check ``cfg``, set the torch threads, seed every
    generator with ``cfg.seed``, remove temporary files a killed run left under ``cfg.out``, and read
    the checkpoint to resume, checked against this run (None for a new run). Without a checkpoint,
    ``resume=True`` is an error and ``resume="auto"`` starts a new run."""
    check_config(cfg)
    set_threads(cfg)
    seed_everything(cfg.seed)
    if cfg.out is None:
        if cfg.resume is True:
            raise ValueError("resume needs an output folder (out) holding checkpoint.pt")
        return None
    out = Path(cfg.out)
    for name in OUTPUT_FILES:
        remove_temporaries(out / name)
    path = out / "checkpoint.pt"
    if not cfg.resume:
        return None
    if not os.path.lexists(path):
        if cfg.resume == "auto":
            return None
        raise FileFormatError(path, "no checkpoint to resume (drop --resume to start a new run, or use "
                                    "--resume-if-present)")
    doc = load_checkpoint(path)  # on the CPU: generator states stay there; loading moves the rest
    check_resumable(doc, path, algorithm, cfg.to_dict())
    return doc


class TrainingRun:
    """Counters, collection, logs, checkpoints and evaluations of one training run (see the module
    docstring). ``replay``: the off-policy run's replay buffer, saved in every checkpoint and refilled
    on resume.
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
        #: The best validated snapshot so far (``keep_best``; the metric is checked by check_config).
        self.best = BestPolicy(task_spec(cfg.task).select_on or "") if cfg.keep_best else None
        #: ``stop_when``'s conditions, and the validation that met them: {"frames", "wall_seconds",
        #: "summary"} (None until then).
        self.stop_conditions = parse_stop_when(cfg.stop_when, task_spec(cfg.task).metric_keys)
        self.solved: dict | None = None
        #: Wall seconds of this process's training loop spent collecting (the Collector's iteration: env
        #: steps, resets and policy forward passes) and validating; the rest of the loop is learning.
        self.timing = {"collect_s": 0.0, "validate_s": 0.0}

    # ------------------------------------------------------------------ files
    @property
    def checkpoint_path(self) -> Path | None:
        return None if self.out is None else self.out / "checkpoint.pt"

    def start(self, doc: dict | None = None) -> Counters:
        """Restore everything from the checkpoint ``doc`` (from :func:`prepare`) when resuming; open
        the logs and the progress bar."""
        if doc is not None:
            path = self.checkpoint_path or "checkpoint"
            counters = restore(doc, path, self.modules, self.optimizers, self.actor.norm, self.env)
            self.counters = Counters(**counters)
            if self.replay is not None:
                if "replay" not in doc:
                    raise FileFormatError(path, "checkpoint holds no replay buffer")
                load_replay(self.replay, doc["replay"], path,
                            transition_shapes(self.env, getattr(self.cfg, "n_step", 1)))
            saved_best = doc.get("extra", {}).get("best")
            if self.best is not None and saved_best is not None:  # None: a run that kept no best
                self.best.load(saved_best, path)
            self.solved = self._saved_solved(doc.get("extra", {}).get("solved"), path)
        self.logger = make_logger(self.cfg.logger, self.out, self.name, self.cfg.to_dict())
        self.stats = EpisodeStats(frames_at_start=self.counters.frames)
        self.progress = Progress(self.cfg.frames, self.counters.frames, self.name, self.cfg.progress)
        self._t0 = time.perf_counter() - self.counters.wall_seconds
        self._loop_t0 = time.perf_counter()
        return self.counters

    def _saved_solved(self, saved: object, path) -> dict | None:
        """The checkpoint's solved entry when this run's conditions still hold for its summary."""
        if saved is None:
            return None
        if not (isinstance(saved, dict) and type(saved.get("frames")) is int
                and isinstance(saved.get("wall_seconds"), float) and isinstance(saved.get("summary"), dict)):
            raise FileFormatError(path, "damaged solved entry in the checkpoint")
        return dict(saved) if conditions_met(saved["summary"], self.stop_conditions) else None

    def remaining_frames(self) -> int:
        """Frames still to collect: none once ``stop_when`` is met."""
        return 0 if self.solved is not None else max(self.cfg.frames - self.counters.frames, 0)

    def segment_frames(self, batch_frames: int) -> int:
        """Frames of the next collection segment: whole batches up to the next checkpoint or the end."""
        c, cfg = self.counters, self.cfg
        if self.remaining_frames() == 0:
            return 0
        until_checkpoint = max(cfg.checkpoint_every - (c.frames - c.last_checkpoint_frames), 1)
        return -(-min(self.remaining_frames(), until_checkpoint) // batch_frames) * batch_frames

    def batches(self, policy, batch_frames: int, random_frames: int = 0) -> Iterator[TensorDictBase]:
        """Batches [num_envs, rollout_steps] of ``policy`` until ``cfg.frames``, segment by segment:
        each a fresh Collector on the envs (reset, then staggered with ``seed + iterations``), uniform
        random actions while fewer than ``random_frames`` frames were collected in the whole run."""
        while total := self.segment_frames(batch_frames):
            start = time.perf_counter()  # a segment's set-up (the envs' reset and stagger) is collection
            collector = Collector(self.env, policy, frames_per_batch=batch_frames, total_frames=total,
                                  init_random_frames=max(random_frames - self.counters.frames, 0),
                                  device=self.cfg.device, trust_policy=True,
                                  auto_register_policy_transforms=False)
            stagger_episodes(self.env, self.cfg.seed + self.counters.iterations)
            self.timing["collect_s"] += time.perf_counter() - start
            try:
                for batch in self._timed(collector):
                    yield batch
                    if self.solved is not None:  # stop_when met at the validation after this batch
                        break
            finally:
                collector.shutdown()

    def _timed(self, collector: Collector) -> Iterator[TensorDictBase]:
        """The collector's batches, the time spent producing each added to ``timing["collect_s"]``."""
        batches = iter(collector)
        while True:
            start = time.perf_counter()
            batch = next(batches, None)
            self.timing["collect_s"] += time.perf_counter() - start
            if batch is None:
                return
            yield batch

    def time_split(self) -> dict[str, float]:
        """This process's training loop so far: wall seconds collecting, validating and learning (the
        rest), and the fraction of the loop spent collecting."""
        loop = time.perf_counter() - self._loop_t0
        collect, validate = self.timing["collect_s"], self.timing["validate_s"]
        return {"loop_s": loop, "collect_s": collect, "validate_s": validate,
                "learn_s": max(loop - collect - validate, 0.0), "collect_fraction": collect / max(loop, 1e-9)}

    def save(self) -> Path | None:
        """Mark a checkpoint at the current frames and write it (when the run has an ``out``)."""
        self.counters.last_checkpoint_frames = self.counters.frames
        if self.checkpoint_path is None:
            return None
        self.counters.wall_seconds = time.perf_counter() - self._t0
        extra = {} if self.best is None else {"best": self.best.state()}
        if self.solved is not None:
            extra["solved"] = self.solved
        return save_checkpoint(self.checkpoint_path, algorithm=self.algorithm, config=self.cfg.to_dict(),
                               counters=dataclasses.asdict(self.counters), modules=self.modules,
                               optimizers=self.optimizers, norm=self.actor.norm.stats(), env=self.env,
                               replay=self.replay, extra=extra)

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
               "time/wall_s": time.perf_counter() - self._t0, "time/collect_s": self.timing["collect_s"],
               "time/validate_s": self.timing["validate_s"]}
        log_scalars(self.logger, row, c.frames)
        self.history.append({"frames": c.frames, **row})
        self.progress.update(frames, self.stats.mean_return, self.stats.survival, rate)
        if cfg.eval_every and c.frames - c.last_eval_frames >= cfg.eval_every and c.frames < cfg.frames:
            c.last_eval_frames = c.frames
            self.validate()
        if self.solved is None and c.frames - c.last_checkpoint_frames >= cfg.checkpoint_every \
                and c.frames < cfg.frames:
            self.save()

    def validate(self) -> None:
        """Score the current weights on the validation episodes; log it, and offer the snapshot to
        ``best`` when the run keeps its best policy."""
        c, cfg = self.counters, self.cfg
        start = time.perf_counter()
        result = evaluate(self.actor, cfg, self.algorithm, cfg.eval_episodes, seed_offset=VALIDATION_SEED)
        self.timing["validate_s"] += time.perf_counter() - start
        log_scalars(self.logger, eval_scalars(result), c.frames)
        if result is None:
            return
        kept = self.best is not None and self.best.offer(policy_document(self.actor, self.meta()),
                                                         result.summary, c.frames)
        wall = time.perf_counter() - self._t0
        self.progress.write(f"[{c.frames:,} frames, {wall:.0f} s] validation: " + ", ".join(
            f"{k} {v:.3g}" for k, v in result.summary.items()) + (" (best so far)" if kept else ""))
        if self.solved is None and conditions_met(result.summary, self.stop_conditions):
            self.solved = {"frames": c.frames, "wall_seconds": wall, "summary": dict(result.summary)}
            self.progress.write(f"[{c.frames:,} frames, {wall:.0f} s] stop_when met ("
                                + ", ".join(map(str, self.stop_conditions)) + "): training ends here")

    # ------------------------------------------------------------------ end
    def meta(self) -> dict:
        return {"algorithm": self.algorithm, "task": self.cfg.task, "airframe": self.cfg.airframe,
                "frames": self.counters.frames, "seed": self.cfg.seed, "backend": self.cfg.backend,
                "episode_seconds": self.cfg.episode_seconds}

    def finish(self) -> dict:
        """Final checkpoint, policy file (the best snapshot with ``keep_best``, else the last weights),
        TorchScript export and evaluation; returns a summary."""
        time_split = self.time_split()  # the loop's, before the final validation and the test
        if self.best is not None and self.best.doc is not None:  # a run too short to validate ships its last
            if self.counters.last_eval_frames != self.counters.frames:  # solved: validated already
                self.validate()  # the last weights compete with the snapshots
            shipped = self.best.doc
        else:
            shipped = policy_document(self.actor, self.meta())
        self.progress.close()
        wall = time.perf_counter() - self._t0
        rate = self.stats.rate(self.counters.frames)
        summary = {"algorithm": self.algorithm, "task": self.cfg.task, "airframe": self.cfg.airframe,
                   "frames": self.counters.frames, "iterations": self.counters.iterations,
                   "updates": self.counters.updates, "episodes": self.counters.episodes,
                   "wall_seconds": wall, "env_steps_per_s": rate, "time_split": time_split,
                   "train_return": self.stats.mean_return, "train_survival": self.stats.survival}
        if self.best is not None and self.best.doc is not None:
            summary.update(selected_frames=self.best.frames, validation=self.best.summary)
        if self.stop_conditions:
            summary["solved"] = self.solved
        checkpoint = self.save()  # the last weights, to continue training from
        if self.out is not None:
            summary["checkpoint"] = str(checkpoint)
            policy = atomic_save(shipped, self.out / "policy.pt")
            summary["policy"] = str(policy)
            summary["torchscript"] = str(export_torchscript(self.out / "policy.ts", policy))
        if self.cfg.final_eval_episodes > 0:
            self.final_eval = evaluate(shipped, self.cfg, self.algorithm, self.cfg.final_eval_episodes)
            scalars = eval_scalars(self.final_eval)
            log_scalars(self.logger, scalars, self.counters.frames)
            summary["eval"] = None if self.final_eval is None else dict(self.final_eval.summary)
            summary["eval_episodes"] = self.cfg.final_eval_episodes
        if self.out is not None:
            write_atomic(self.out / "summary.json", json.dumps(summary, indent=2, default=str))
        return summary


__all__ = ["OUTPUT_FILES", "TrainingRun", "prepare"]
