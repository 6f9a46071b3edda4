"""Training logs through TorchRL's loggers and a tqdm progress bar.

    logger = make_logger("csv", out, "ppo_altitude_volantex_ranger", config)   # or tensorboard, wandb
    log_scalars(logger, {"train/return": 812.0}, step=frames)

CSV (default) writes ``<out>/logs/<exp_name>/scalars/<name>.csv``; TensorBoard needs the
``tensorboard`` package, wandb the ``wandb`` extra (``pip install falcon-rl[wandb]``) and runs offline
unless ``WANDB_MODE`` says otherwise, so it works with no network.
"""

from __future__ import annotations

import importlib.util
import math
import os
from pathlib import Path

from tqdm import tqdm

LOGGERS = ("csv", "tensorboard", "wandb", "none")


def make_logger(kind: str, out: str | Path | None, exp_name: str, config: dict | None = None):
    """A TorchRL logger writing under ``out``/logs, or None for ``kind="none"`` / no ``out``."""
    if kind not in LOGGERS:
        raise ValueError(f"logger must be one of {LOGGERS}, got {kind!r}")
    if kind == "none" or out is None:
        return None
    missing = {"tensorboard": "tensorboard", "wandb": "wandb"}.get(kind)
    if missing and importlib.util.find_spec(missing) is None:
        raise ImportError(f"the {kind} logger needs the {missing} package (pip install {missing}); "
                          "or use --logger csv")
    log_dir = Path(out) / "logs"
    if kind == "csv":
        from torchrl.record.loggers.csv import CSVLogger

        logger = CSVLogger(exp_name=exp_name, log_dir=str(log_dir))
    elif kind == "tensorboard":
        from torchrl.record.loggers.tensorboard import TensorboardLogger

        logger = TensorboardLogger(exp_name=exp_name, log_dir=str(log_dir))
    else:
        from torchrl.record.loggers.wandb import WandbLogger

        offline = os.environ.get("WANDB_MODE", "offline") == "offline"
        logger = WandbLogger(exp_name=exp_name, offline=offline, save_dir=str(log_dir), project="falcon-rl")
    if config:
        logger.log_hparams({k: (str(v) if isinstance(v, (list, tuple, dict)) else v)
                            for k, v in config.items() if v is not None})
    return logger


def log_scalars(logger, scalars: dict[str, float], step: int) -> None:
    """Log every finite scalar of ``scalars`` at ``step`` (frames)."""
    if logger is None:
        return
    for name, value in scalars.items():
        if value is not None and math.isfinite(float(value)):
            logger.log_scalar(name, float(value), step=step)


class Progress:
    """tqdm bar over frames with the current return, survival and env-steps/s."""

    def __init__(self, total: int, initial: int, desc: str, enabled: bool = True):
        self.bar = tqdm(total=total, initial=initial, desc=desc, unit="step", unit_scale=True,
                        disable=not enabled, mininterval=1.0, dynamic_ncols=True)

    def update(self, frames: int, mean_return: float, survival: float, steps_per_second: float) -> None:
        self.bar.update(frames)
        self.bar.set_postfix_str(f"return {mean_return:.4g} | survival {survival:.2f} | "
                                 f"{steps_per_second:,.0f} env-steps/s", refresh=False)

    def write(self, text: str) -> None:
        self.bar.write(text)

    def close(self) -> None:
        self.bar.close()


__all__ = ["LOGGERS", "Progress", "log_scalars", "make_logger"]
