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
validation that meets its conditions and whose weights meet them again on ``confirm_episodes``
confirmation episodes of their own seeds (seed + ``CONFIRMATION_SEED``; :mod:`.selection`); a
confirmation that misses a condition lets the run train on. A solved run ships the confirmed weights
(its last; with ``keep_best`` too) and reports the frames and wall seconds it took, the validation and
the confirmation (``summary["solved"]``); a checkpoint remembers it, so resuming a solved run with the
same conditions only finishes it.

One run per folder: :func:`prepare` takes an exclusive lock on ``<out>/.lock`` (``fcntl.flock``) before
it touches anything there and the run holds it to its end (:meth:`TrainingRun.finish`); the system
drops it when the process dies, and a later run of the same process takes it over. A second run into
the folder meanwhile is refused with a one-line ValueError; only the lock holder removes the
temporaries a killed writer left.

Non-finite episodes: a run whose ended training episodes all ended "non_finite" (a state, reward or
action that was not finite: a broken env option, airframe or policy) fails with a one-line ValueError,
checked after every batch, before any checkpoint, validation or export: it exports nothing. One episode
that ended otherwise (a crash, a stall, a truncation) shows the env flies, and clears the check.

Time: the summary's ``time_split`` divides this process's training loop into collecting (the Collector:
env steps, resets, the policy's forward passes), validating and learning (the rest), wall seconds.
"""

from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import json
import os
import time
from collections.abc import Iterator
from pathlib import Path

import torch
from tensordict import TensorDictBase
from torchrl.collectors import Collector

from ..atomic_files import default_file_mode, remove_temporaries, write_atomic
from ..envs import task_spec
from ..policies import FileFormatError, export_torchscript
from ..policies.format import atomic_save, policy_document
from ..transforms import flight_env
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
from .selection import CONFIRMATION_SEED, VALIDATION_SEED, BestPolicy, conditions_met, parse_stop_when

#: Files a run writes under ``out`` (each atomically, :func:`falcon_rl.atomic_files.write_atomic`).
OUTPUT_FILES = ("checkpoint.pt", "policy.pt", "policy.ts", "summary.json")
#: The file under ``out`` whose lock a run holds (it holds this process's id; it stays after the run).
LOCK_FILE = ".lock"

#: Run folder (resolved) -> descriptor of its lock file, for the folders this process's runs hold.
_HELD: dict[Path, int] = {}


def lock_run_folder(out: str | os.PathLike[str]) -> None:
    """Take the exclusive lock of the run folder ``out`` (created when missing) for this process, or
    raise a one-line ValueError naming it when another run holds it. A lock this process took before
    (a run that raised) is released first."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    key = folder.resolve()
    release_run_folder(key)
    descriptor = os.open(key / LOCK_FILE, os.O_RDWR | os.O_CREAT, default_file_mode())
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.read(descriptor, 32).decode(errors="replace").strip()
        os.close(descriptor)
        raise ValueError(f"{folder}: another training run{f' (process {holder})' if holder.isdigit() else ''}"
                         f" holds this output folder ({LOCK_FILE}); wait for it to end or choose another "
                         "output folder") from None
    except OSError as error:  # a file system without locks: name the file in the one-line message
        os.close(descriptor)
        raise OSError(error.errno, error.strerror, str(key / LOCK_FILE)) from None
    except BaseException:
        os.close(descriptor)
        raise
    _HELD[key] = descriptor
    with contextlib.suppress(OSError):  # the process id is for the message above only
        os.ftruncate(descriptor, 0)
        os.pwrite(descriptor, f"{os.getpid()}\n".encode(), 0)


def release_run_folder(out: str | os.PathLike[str] | None) -> None:
    """Release this process's lock of the run folder ``out`` (nothing when it holds none)."""
    descriptor = None if out is None else _HELD.pop(Path(out).resolve(), None)
    if descriptor is not None:
        os.close(descriptor)  # closing the last descriptor drops the flock


def prepare(algorithm: str, cfg: TrainConfig) -> dict | None:
    """Everything before a recipe builds anything: check ``cfg``, set the torch threads, seed every
    generator with ``cfg.seed``, lock ``cfg.out`` for this run (:func:`lock_run_folder`: a ValueError
    when another run holds it), remove temporary files a killed run left there, and read the checkpoint
    to resume, checked against this run (None for a new run). Without a checkpoint, ``resume=True`` is
    an error and ``resume="auto"`` starts a new run."""
    check_config(cfg)
    set_threads(cfg)
    seed_everything(cfg.seed)
    if cfg.out is None:
        if cfg.resume is True:
            raise ValueError("resume needs an output folder (out) holding checkpoint.pt")
        return None
    out = Path(cfg.out)
    lock_run_folder(out)  # before anything under out is touched: the temporaries may be another run's
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
        #: ``stop_when``'s conditions, and the validation that met them, confirmed: {"frames",
        #: "wall_seconds", "summary" (the validation's), "confirmation" (None without one)} (None until then).
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
        """The checkpoint's solved entry when this run's conditions still hold for its validation and,
        unless ``confirm_episodes`` is 0, for its confirmation."""
        if saved is None:
            return None
        if not (isinstance(saved, dict) and type(saved.get("frames")) is int
                and isinstance(saved.get("wall_seconds"), float) and isinstance(saved.get("summary"), dict)
                and isinstance(saved.get("confirmation"), dict | None)):
            raise FileFormatError(path, "damaged solved entry in the checkpoint")
        confirmation = saved.get("confirmation")
        confirmed = self.cfg.confirm_episodes == 0 or (
            confirmation is not None and conditions_met(confirmation, self.stop_conditions))
        return dict(saved) if confirmed and conditions_met(saved["summary"], self.stop_conditions) else None

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
        episode_scalars = self.stats.update(batch)
        self.check_episodes_finite()
        base = flight_env(self.env, "control_dt")
        terms = base.reward_term_means() if hasattr(base, "reward_term_means") else {}
        row = {**episode_scalars, **scalars, **{f"reward/{name}": value for name, value in terms.items()},
               "time/env_steps_per_s": rate,
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

    def check_episodes_finite(self) -> None:
        """One-line ValueError when every training episode that ended so far in this process ended
        "non_finite" (see the module docstring): the env or the policy is broken, nothing is exported."""
        stats = self.stats
        if stats.episodes_ended and stats.non_finite_ended == stats.episodes_ended:
            self.progress.close()
            raise ValueError(f"training failed: all {stats.episodes_ended} episodes that ended by "
                             f"{self.counters.frames:,} frames ended non-finite (termination reason "
                             "'non_finite': a state, reward or action that is not finite; check env_options, "
                             "the airframe and the policy); no policy exported")

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
            self._confirm_stop(dict(result.summary))

    def _confirm_stop(self, validation: dict[str, float]) -> None:
        """The validation ``validation`` met ``stop_when``: fly ``cfg.confirm_episodes`` confirmation
        episodes, and mark the run solved when they meet the conditions too (or when there are none)."""
        c, cfg = self.counters, self.cfg
        conditions = ", ".join(map(str, self.stop_conditions))
        confirmation = None
        if cfg.confirm_episodes:
            start = time.perf_counter()
            result = evaluate(self.actor, cfg, self.algorithm, cfg.confirm_episodes,
                              seed_offset=CONFIRMATION_SEED)
            self.timing["validate_s"] += time.perf_counter() - start
            confirmation = {} if result is None else dict(result.summary)
        wall = time.perf_counter() - self._t0
        prefix = f"[{c.frames:,} frames, {wall:.0f} s] stop_when ({conditions}) met on the validation"
        if confirmation is not None and not conditions_met(confirmation, self.stop_conditions):
            self.progress.write(f"{prefix}, not on {cfg.confirm_episodes} confirmation episodes ("
                                + ", ".join(f"{k} {v:.3g}" for k, v in confirmation.items())
                                + "): training goes on")
            return
        self.solved = {"frames": c.frames, "wall_seconds": wall, "summary": validation,
                       "confirmation": confirmation}
        self.progress.write(prefix + (f" and on {cfg.confirm_episodes} confirmation episodes"
                                      if confirmation is not None else "") + ": training ends here")

    # ------------------------------------------------------------------ end
    def meta(self) -> dict:
        return {"algorithm": self.algorithm, "task": self.cfg.task, "airframe": self.cfg.airframe,
                "frames": self.counters.frames, "seed": self.cfg.seed, "backend": self.cfg.backend,
                "episode_seconds": self.cfg.episode_seconds}

    def finish(self) -> dict:
        """Final checkpoint, policy file (the best snapshot with ``keep_best``, else the last weights),
        TorchScript export and evaluation; returns a summary."""
        time_split = self.time_split()  # the loop's, before the final validation and the test
        validated = self.best is not None and self.best.doc is not None  # a run too short ships its last
        if validated and self.solved is None and self.counters.last_eval_frames != self.counters.frames:
            self.validate()  # the last weights compete with the snapshots (and may solve the run)
        selected = validated and self.solved is None  # a solved run ships its confirmed, last weights
        shipped = self.best.doc if selected else policy_document(self.actor, self.meta())
        self.progress.close()
        wall = time.perf_counter() - self._t0
        rate = self.stats.rate(self.counters.frames)
        summary = {"algorithm": self.algorithm, "task": self.cfg.task, "airframe": self.cfg.airframe,
                   "frames": self.counters.frames, "iterations": self.counters.iterations,
                   "updates": self.counters.updates, "episodes": self.counters.episodes,
                   "wall_seconds": wall, "env_steps_per_s": rate, "time_split": time_split,
                   "train_return": self.stats.mean_return, "train_survival": self.stats.survival}
        if selected:
            summary.update(selected_frames=self.best.frames, validation=self.best.summary)
        elif self.solved is not None and self.best is not None:  # keep_best: the confirmed weights
            summary.update(selected_frames=self.solved["frames"], validation=self.solved["summary"])
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
        release_run_folder(self.out)
        return summary


__all__ = ["LOCK_FILE", "OUTPUT_FILES", "TrainingRun", "lock_run_folder", "prepare", "release_run_folder"]
