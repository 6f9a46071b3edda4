"""Keeping the best policy of a run: the selection score (gates before the metric, cases averaged,
NaN worst), the kept snapshot and its checkpoint entry, the shipped file being the best validation
snapshot, a killed and resumed run keeping the same best, and one-line errors for a misconfigured run."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from falcon_rl.cli import main
from falcon_rl.policies.format import FileFormatError, read_document
from falcon_rl.recipes import ppo
from falcon_rl.recipes.checkpoint import load_checkpoint
from falcon_rl.recipes.checks import check_config
from falcon_rl.recipes.selection import BestPolicy, selection_score

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).parent))
from test_training_reproducible import KILLED, train_argv  # noqa: E402

#: Validation on one 1 s episode per maneuver of the attitude protocol (bank RMSE differs from
#: snapshot to snapshot) every 64 frames of a 256-frame PPO run.
KEEP_BEST = ("--task", "attitude", "--eval-every", "64", "--set", "eval_episodes=1", "--set",
             "eval_seconds=1.0", "--set", "keep_best=True")


def test_gates_come_before_the_metric_and_cases_are_averaged():
    crashed = {"survival": 0.9, "acquisition": 1.0, "rmse_m": 0.01}
    slow = {"survival": 1.0, "acquisition": 0.5, "rmse_m": 0.02}
    good = {"survival": 1.0, "acquisition": 1.0, "rmse_m": 0.3}
    better = {"survival": 1.0, "acquisition": 1.0, "rmse_m": 0.05}
    ranked = sorted([crashed, slow, good, better], key=lambda s: selection_score(s, "rmse_m"))
    assert ranked == [better, good, slow, crashed]
    cases = {"circle/bank_rmse_deg": 1.0, "helix/bank_rmse_deg": 3.0, "circle/survival": 1.0,
             "helix/survival": 0.5}
    assert selection_score(cases, "bank_rmse_deg") == (-0.75, -1.0, -1.0, -1.0, 2.0)
    never_acquired = {"survival": 1.0, "acquisition": 0.0, "rmse_m": math.nan}
    assert selection_score(never_acquired, "rmse_m") == (-1.0, 0.0, -1.0, -1.0, math.inf)
    assert selection_score(never_acquired, "rmse_m") < selection_score(crashed | {"survival": 0.5}, "rmse_m")
    assert selection_score({"survival": math.nan, "rmse_m": 0.1}, "rmse_m")[0] == 0.0


def test_best_policy_keeps_the_earlier_of_equal_snapshots_and_checks_what_it_loads(tmp_path: Path):
    best = BestPolicy("rmse_m")
    assert best.offer({"name": "first"}, {"survival": 1.0, "rmse_m": 0.2}, 100)
    assert not best.offer({"name": "tie"}, {"survival": 1.0, "rmse_m": 0.2}, 200)
    assert not best.offer({"name": "worse"}, {"survival": 1.0, "rmse_m": 0.3}, 300)
    assert best.offer({"name": "better"}, {"survival": 1.0, "rmse_m": 0.1}, 400)
    assert (best.doc, best.frames) == ({"name": "better"}, 400)
    with pytest.raises(FileFormatError, match="not a falcon-rl policy file"):
        BestPolicy("rmse_m").load(best.state(), tmp_path / "checkpoint.pt")  # not a sealed policy
    with pytest.raises(FileFormatError, match="damaged best-policy entry"):
        BestPolicy("rmse_m").load({"doc": None, "score": "low"}, tmp_path / "checkpoint.pt")
    assert ppo.make_config("altitude").keep_best and not ppo.make_config("attitude").keep_best


def test_keep_best_needs_periodic_validation():
    with pytest.raises(ValueError, match="keep_best needs eval_every > 0"):
        check_config(ppo.make_config("altitude", keep_best=True, eval_every=0))
    with pytest.raises(ValueError, match="keep_best needs eval_every > 0"):
        check_config(ppo.make_config("altitude", keep_best=True, eval_every=64, eval_episodes=0))
    assert main(["train", "ppo", "--set", "keep_best=True", "--eval-every", "0", "--no-progress"]) == 2


def _mlp(doc: dict) -> dict[str, torch.Tensor]:
    return doc["mlp"]


def test_the_shipped_policy_is_the_best_validation_snapshot(tmp_path: Path, monkeypatch):
    offered: list[tuple[tuple[float, ...], int]] = []
    offer = BestPolicy.offer

    def record(self, doc, summary, frames):
        offered.append((selection_score(summary, self.metric), frames))
        return offer(self, doc, summary, frames)

    monkeypatch.setattr(BestPolicy, "offer", record)
    out = tmp_path / "run"
    assert main(train_argv("ppo", out, 256, *KEEP_BEST)) == 0
    summary = json.loads((out / "summary.json").read_text())
    best = load_checkpoint(out / "checkpoint.pt")["extra"]["best"]
    shipped = read_document(out / "policy.pt", "policy")
    assert [frames for _, frames in offered] == [64, 128, 192, 256]  # the last weights compete too
    assert len({score for score, _ in offered}) > 1
    assert best["frames"] == min(offered)[1] == summary["selected_frames"] == shipped["meta"]["frames"]
    assert summary["validation"] == best["summary"]
    for key, value in _mlp(best["doc"]).items():
        assert torch.equal(value, _mlp(shipped)[key])
    final = load_checkpoint(out / "checkpoint.pt")["modules"]["actor"]
    same_as_last = all(torch.equal(final[f"mlp.{k}"], v) for k, v in _mlp(shipped).items())
    assert same_as_last == (best["frames"] == 256)


def test_a_resumed_run_keeps_the_uninterrupted_runs_best(tmp_path: Path):
    resumed, uninterrupted = tmp_path / "resumed", tmp_path / "uninterrupted"
    extra = ("--set", "checkpoint_every=128", *KEEP_BEST)
    killed = subprocess.run([sys.executable, "-c", KILLED, *train_argv("ppo", resumed, 384, *extra)],
                            cwd=REPO, capture_output=True, timeout=600)
    assert killed.returncode == 17, killed.stderr.decode()[-2000:]
    assert load_checkpoint(resumed / "checkpoint.pt")["extra"]["best"]["frames"] in (64, 128)
    assert main(train_argv("ppo", resumed, 384, *extra, "--resume")) == 0
    assert main(train_argv("ppo", uninterrupted, 384, *extra)) == 0
    a, b = (load_checkpoint(p / "checkpoint.pt")["extra"]["best"] for p in (resumed, uninterrupted))
    assert (a["frames"], a["score"], a["summary"]) == (b["frames"], b["score"], b["summary"])
    assert a["doc"]["sha256"] == b["doc"]["sha256"]
