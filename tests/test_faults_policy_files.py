"""Faults found by trying real clients on the policy and checkpoint files, one parametrised case per
variant: files that pass their checksum but hold non-finite weights or statistics, or counters and
config values of the wrong kind, are refused in one line naming the file and the entry; nothing with
non-finite weights is ever written (the earlier file stays); the TorchScript export checks the shape
of its input."""

from __future__ import annotations

import math
import re
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest
import torch

from falcon_rl.cli import main
from falcon_rl.policies.format import (
    LEGACY_FORMATS,
    FileFormatError,
    atomic_save,
    export_torchscript,
    policy_document,
    read_document,
    read_policy,
    save_policy,
    seal,
)
from falcon_rl.recipes.checkpoint import load_checkpoint, save_checkpoint
from falcon_rl.recipes.common import PolicyNet, RunningNorm

#: Flags of the tiny PPO run every case starts from.
PPO = ("--envs", "8", "--eval-episodes", "0", "--no-progress", "--logger", "none", "--set", "rollout_steps=8",
       "--set", "epochs=1", "--set", "minibatches=2")
NAN, INF = float("nan"), float("inf")


def cli(argv: list, capsys) -> tuple[int, list[str]]:
    """Exit code and stderr lines of ``falcon-rl argv`` run in-process."""
    code = main([str(a) for a in argv])
    return code, capsys.readouterr().err.strip().splitlines()


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    """A tiny PPO run's folder: checkpoint.pt, policy.pt, policy.ts."""
    out = tmp_path_factory.mktemp("trained") / "ppo"
    assert main(["train", "ppo", "--out", str(out), "--frames", "64", *PPO]) == 0
    return out


def _outputs(out: Path) -> list[str]:
    """What a run wrote in ``out`` besides its checkpoint (policy files, summary, temporaries)."""
    return sorted(p.name for p in out.iterdir() if p.suffix in (".pt", ".ts", ".json", ".tmp")
                  and p.name != "checkpoint.pt")


def resealed(source: Path, path: Path, edit: Callable[[dict], None], legacy: bool = False) -> Path:
    """A copy of the file ``source`` with ``edit`` applied, sealed with the checksum of its new contents
    (or, ``legacy``, a policy file of format /1, which has none)."""
    doc = {k: v for k, v in read_document(source, "file").items() if k != "sha256"}
    edit(doc)
    if legacy:
        doc["format"] = LEGACY_FORMATS[0]
    torch.save(doc if legacy else seal(doc), path)
    return path


def _set(entry: str, key: str, value: float, index: tuple = (0,)) -> Callable[[dict], None]:
    """An edit putting ``value`` at ``index`` of the tensor ``doc[entry][key]``."""
    def edit(doc: dict) -> None:
        doc[entry][key][index] = value
    return edit


# ---------------------------------------------------------------------------------------- row 1: loading
POLICY_VALUES = [  # (id, edit, legacy, expected reason)
    ("nan-weight", _set("mlp", "0.weight", NAN, (slice(0, 3), 0)), False,
     "actor weight 'mlp.0.weight' has 3 non-finite values"),
    ("inf-bias", _set("mlp", "4.bias", -INF), False, "actor weight 'mlp.4.bias' has 1 non-finite value"),
    ("nan-mean", _set("norm", "mean", NAN), False, "observation normaliser statistic 'norm.mean'"),
    ("inf-var", _set("norm", "var", INF), False, "'norm.var' has 1 non-finite value"),
    ("negative-var", _set("norm", "var", -1.0), False, "'norm.var' has 1 negative value"),
    ("zero-clip", lambda d: d["norm"].update(clip=torch.tensor(0.0)), False, "'norm.clip' must be > 0"),
    ("nan-min-std", lambda d: d["norm"].update(min_std=torch.tensor(NAN)), False, "'norm.min_std'"),
    ("legacy-nan-weight", _set("mlp", "2.weight", NAN), True, "actor weight 'mlp.2.weight'"),
]


@pytest.mark.parametrize(("edit", "legacy", "reason"), [c[1:] for c in POLICY_VALUES],
                         ids=[c[0] for c in POLICY_VALUES])
def test_policy_with_unsound_values_is_refused(edit, legacy, reason, trained: Path, tmp_path: Path):
    path = resealed(trained / "policy.pt", tmp_path / "bad.pt", edit, legacy)
    for reader in (read_policy, lambda p: export_torchscript(tmp_path / "bad.ts", p)):
        with pytest.raises(FileFormatError) as caught:
            reader(path)
        assert str(caught.value).startswith(f"{path}: ") and reason in str(caught.value)
        assert "\n" not in str(caught.value)
    assert not (tmp_path / "bad.ts").exists()


def test_eval_refuses_a_nan_policy_in_one_line(trained: Path, tmp_path: Path, capsys):
    path = resealed(trained / "policy.pt", tmp_path / "nan.pt", _set("mlp", "0.weight", NAN, (0, 0)))
    code, lines = cli(["eval", "--controller", path, "--task", "altitude", "--episodes", "1",
                       "--seconds", "1",
                       "--backend", "torch", "--out", tmp_path / "eval"], capsys)
    assert code == 2 and len(lines) == 1, lines
    assert str(path) in lines[0] and "actor weight 'mlp.0.weight' has 1 non-finite value" in lines[0]


def _best_nan(doc: dict) -> None:
    """Keep a best-policy snapshot whose weights hold a NaN in the checkpoint."""
    policy = {k: v for k, v in policy_document(_net(), {"task": "altitude"}).items() if k != "sha256"}
    policy["mlp"]["0.weight"][0, 0] = NAN
    doc["extra"]["best"] = {"doc": seal(policy), "score": [0.0], "frames": 64, "summary": {}}


def _counter(name: str, value: object) -> Callable[[dict], None]:
    """An edit setting the counter ``name`` to ``value``."""
    return lambda doc: doc["counters"].update({name: value})


CHECKPOINT_VALUES = [  # (id, edit, expected reason)
    ("nan-actor-weight", lambda d: d["modules"]["actor"]["mlp.0.weight"][0, :3].fill_(NAN),
     "network weight 'modules.actor.mlp.0.weight' has 3 non-finite values"),
    ("inf-critic-bias", lambda d: d["modules"]["critic"]["mlp.4.bias"].fill_(INF),
     "network weight 'modules.critic.mlp.4.bias'"),
    ("nan-log-std", lambda d: d["modules"]["actor"]["log_std"].fill_(NAN), "'modules.actor.log_std'"),
    ("nan-adam-moment", lambda d: d["optimizers"]["optimizer"]["state"][1]["exp_avg_sq"][0, 0].fill_(NAN),
     "optimiser state 'optimizers.optimizer.state.1.exp_avg_sq' has 1 non-finite value"),
    ("inf-norm-var", _set("norm", "var", INF, (1,)), "observation normaliser statistic 'norm.var'"),
    ("negative-norm-count", lambda d: d["norm"]["count"].fill_(-1.0), "'norm.count' has 1 negative value"),
    ("nan-best-snapshot", _best_nan, "entry 'extra.best.doc.mlp.0.weight'"),
]
COUNTER_VALUES = [  # (id, counter, value, expected reason): every counter's constraint
    ("iterations-fraction", "iterations", 1.5, "counters.iterations must be a non-negative integer"),
    ("frames-nan", "frames", NAN,
     "counters.frames must be a non-negative integer (at most 2**63 - 1), got nan"),
    ("frames-negative", "frames", -64, "counters.frames must be a non-negative integer"),
    ("frames-huge", "frames", 10**30, "counters.frames must be a non-negative integer"),
    ("frames-2**63", "frames", 2**63, "at most 2**63 - 1"),
    ("frames-enormous", "frames", 10**400, "got 1000000000000000000000000000000000000..."),
    ("episodes-bool", "episodes", True,
     "counters.episodes must be a non-negative integer (at most 2**63 - 1), got True"),
    ("updates-string", "updates", "2",
     "counters.updates must be a non-negative integer (at most 2**63 - 1), got '2'"),
    ("wall-seconds-inf", "wall_seconds", -INF, "counters.wall_seconds must be a finite non-negative number"),
    ("wall-seconds-nan", "wall_seconds", NAN, "counters.wall_seconds must be a finite non-negative number"),
    ("wall-seconds-negative", "wall_seconds", -1.0, "counters.wall_seconds must be a finite non-negative"),
    ("last-checkpoint-ahead", "last_checkpoint_frames", 128,
     "counters.last_checkpoint_frames must be at most counters.frames (64), got 128"),
    ("last-eval-ahead", "last_eval_frames", 10**6,
     "counters.last_eval_frames must be at most counters.frames"),
]
STRUCTURE_VALUES = [  # (id, edit, expected reason)
    ("counter-missing", lambda d: d["counters"].pop("episodes"), "counters lack ['episodes']"),
    ("counter-unknown", lambda d: d["counters"].update(steps=3), "counters hold unknown entries ['steps']"),
    ("config-tensor", lambda d: d["config"].update(seed=torch.zeros(3)),
     "config.seed must be a plain value (None, bool, number, string, list or dict), got a Tensor"),
    ("config-nested-tensor", lambda d: d["config"].update(env_options={"wind": [torch.ones(2)]}),
     "config.env_options.wind[0] must be a plain value"),
    ("config-key", lambda d: d["config"].update({3: "x"}), "config keys must be strings, got 3"),
    ("extra-list", lambda d: d.update(extra=[1]), "incomplete training checkpoint (extra)"),
    ("replay-list", lambda d: d.update(replay=[1]), "incomplete training checkpoint (replay)"),
]
CHECKPOINT_CASES = [
    *CHECKPOINT_VALUES,
    *((name, _counter(counter, value), reason) for name, counter, value, reason in COUNTER_VALUES),
    *STRUCTURE_VALUES,
]


@pytest.mark.parametrize(("edit", "reason"), [c[1:] for c in CHECKPOINT_CASES],
                         ids=[c[0] for c in CHECKPOINT_CASES])
def test_resume_refuses_an_unsound_checkpoint_in_one_line(edit, reason, trained: Path, tmp_path: Path,
                                                          capsys):
    """Row 1 (non-finite values) and row 2 (counters, config): exit 2, one line naming the file and the
    entry; nothing is trained or written, the checkpoint stays as it was."""
    out = tmp_path / "run"
    out.mkdir()

    path = resealed(trained / "checkpoint.pt", out / "checkpoint.pt", edit)
    before = path.read_bytes()
    code, lines = cli(["train", "ppo", "--out", out, "--resume", "--frames", "128", *PPO], capsys)
    assert code == 2 and len(lines) == 1, lines
    assert f"{path}: " in lines[0] and reason in lines[0], lines[0]
    assert path.read_bytes() == before and not _outputs(out)
    with pytest.raises(FileFormatError, match=f"^{path}: "):
        load_checkpoint(path)


def test_counters_are_bounded_by_int64(trained: Path, tmp_path: Path):
    """The limits themselves load (counters of 0 and 2**63 - 1, an integer wall time); one past is
    refused."""
    def edit(doc: dict) -> None:
        doc["counters"].update(frames=2**63 - 1, iterations=0, wall_seconds=0, last_eval_frames=2**63 - 1)

    path = resealed(trained / "checkpoint.pt", tmp_path / "checkpoint.pt", edit)
    assert load_checkpoint(path)["counters"]["frames"] == 2**63 - 1
    path = resealed(path, tmp_path / "past.pt", _counter("updates", 2**63))
    with pytest.raises(FileFormatError, match=r"counters.updates .* got 9223372036854775808$"):
        load_checkpoint(path)


# ---------------------------------------------------------------------------------------- row 1: writing
def _net() -> PolicyNet:
    torch.manual_seed(0)
    return PolicyNet(RunningNorm(11), 11, 2, (8, 8), "tanh", scale="param")


def _save_policy(path: Path, net: PolicyNet) -> None:
    save_policy(path, net, {"task": "altitude"})


def _atomic_save_document(path: Path, net: PolicyNet) -> None:
    atomic_save(policy_document(net, {"task": "altitude"}), path)


def _save_checkpoint(path: Path, net: PolicyNet) -> None:
    optimizer = torch.optim.Adam(net.parameters())
    save_checkpoint(path, algorithm="ppo", config={"task": "altitude"}, counters={"frames": 0},
                    modules={"actor": net}, optimizers={"optimizer": optimizer}, norm=net.norm.stats())


def _nan_weight(net: PolicyNet) -> None:
    with torch.no_grad():
        net.mlp[0].weight[1, :2] = NAN


def _inf_var(net: PolicyNet) -> None:
    net.norm.var[3] = INF


def _nan_log_std(net: PolicyNet) -> None:
    with torch.no_grad():
        net.log_std[0] = NAN


SAVE_CASES = [  # (id, writer, spoil, expected reason)
    ("save_policy-nan-weight", _save_policy, _nan_weight,
     "actor weight 'mlp.0.weight' has 2 non-finite values"),
    ("save_policy-inf-var", _save_policy, _inf_var, "observation normaliser statistic 'norm.var'"),
    ("atomic_save-nan-weight", _atomic_save_document, _nan_weight, "actor weight 'mlp.0.weight'"),
    ("atomic_save-inf-var", _atomic_save_document, _inf_var, "'norm.var' has 1 non-finite value"),
    ("save_checkpoint-nan-weight", _save_checkpoint, _nan_weight,
     "network weight 'modules.actor.mlp.0.weight'"),
    ("save_checkpoint-nan-log-std", _save_checkpoint, _nan_log_std, "network weight 'modules.actor.log_std'"),
    ("save_checkpoint-inf-var", _save_checkpoint, _inf_var, "observation normaliser statistic 'norm.var'"),
]


@pytest.mark.parametrize(("writer", "spoil", "reason"), [c[1:] for c in SAVE_CASES],
                         ids=[c[0] for c in SAVE_CASES])
def test_non_finite_weights_are_never_written(writer, spoil, reason, tmp_path: Path):
    """A ValueError naming the entry, before anything is written: the earlier file stays byte for byte,
    and no temporary is left."""
    path = tmp_path / "file.pt"
    net = _net()
    writer(path, net)
    before = path.read_bytes()
    spoil(net)
    with pytest.raises(ValueError) as caught:
        writer(path, net)
    assert str(caught.value).startswith(f"{path}: not written, ") and reason in str(caught.value)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["file.pt"]


def test_a_run_whose_weights_turn_nan_keeps_its_last_checkpoint(trained: Path, tmp_path: Path, capsys,
                                                                 monkeypatch):
    """End to end: a resumed run whose optimiser step makes the weights NaN stops with one line at its
    next save; the checkpoint it resumed from stays, and no policy.pt or policy.ts is written."""
    out = tmp_path / "run"
    out.mkdir()
    shutil.copy(trained / "checkpoint.pt", out / "checkpoint.pt")
    before = (out / "checkpoint.pt").read_bytes()
    step = torch.optim.Adam.step

    def poisoned(self, *args, **kwargs):
        loss = step(self, *args, **kwargs)
        with torch.no_grad():
            for group in self.param_groups:
                for param in group["params"]:
                    param.fill_(NAN)
        return loss

    monkeypatch.setattr(torch.optim.Adam, "step", poisoned)
    code, lines = cli(["train", "ppo", "--out", out, "--resume", "--frames", "128", *PPO], capsys)
    assert code == 2 and len(lines) == 1, lines
    assert f"{out / 'checkpoint.pt'}: not written, network weight 'modules.actor." in lines[0], lines[0]
    assert (out / "checkpoint.pt").read_bytes() == before and not _outputs(out)


# ---------------------------------------------------------------------------------------- row 3: TorchScript
SHAPES = [  # (id, observation shape, expected action shape or the error's shape text)
    ("one-observation", (11,), (2,)),
    ("two-batch-dims", (2, 3, 11), (2, 3, 2)),
    ("wrong-1d", (5,), "got [5]"),
    ("wrong-width", (3, 5), "got [3, 5]"),
    ("one-too-many", (3, 12), "got [3, 12]"),
    ("scalar", (), "got []"),
]


@pytest.fixture(scope="module")
def exported(trained: Path, tmp_path_factory) -> tuple[torch.jit.ScriptModule, object, dict]:
    """(the exported policy.ts loaded with torch.jit.load, the Python policy, the extra files)."""
    path = export_torchscript(tmp_path_factory.mktemp("ts") / "policy.ts", trained / "policy.pt")
    extra = {"meta.txt": ""}
    return torch.jit.load(str(path), _extra_files=extra), read_policy(trained / "policy.pt")[0], extra


@pytest.mark.parametrize(("shape", "expected"), [c[1:] for c in SHAPES], ids=[c[0] for c in SHAPES])
def test_torchscript_policy_checks_the_observation_shape(shape, expected, exported):
    scripted, policy, extra = exported
    obs = torch.linspace(-1.0, 1.0, math.prod(shape)).reshape(shape)
    if isinstance(expected, str):
        message = f"observation must have shape [N, D=11] (or [D], [..., D]), {expected}"
        with pytest.raises(torch.jit.Error) as caught:
            scripted(obs)
        assert str(caught.value).strip().splitlines()[-1] == f"builtins.ValueError: {message}"
        with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
            policy(obs)  # the Python policy says the same
        return
    action = scripted(obs)
    assert action.shape == expected
    rows = scripted(obs.reshape(-1, 11)).reshape(expected)  # the same actions row by row
    torch.testing.assert_close(action, rows)
    torch.testing.assert_close(action, policy(obs).detach())
    assert b"'task': 'altitude'" in extra["meta.txt"]
