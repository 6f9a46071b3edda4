"""The policy file format (the acting network with its observation normaliser baked in), and the
sealed, weights-only files it shares with the training checkpoints.

A policy file (``policy.pt``) is a weights-only ``torch.save`` of

    {"format": "falcon-rl-policy/2", "arch": {obs_dim, act_dim, out_dim, cells, activation},
     "mlp": state_dict, "norm": {"mean", "var", "enabled", "clip", "min_std"},
     "meta": {"algorithm", "task", "airframe", "frames", "seed", ...}, "sha256": str}

and acts as ``action = tanh(mlp(clip((obs - mean) / max(sqrt(var), min_std)))[..., :act_dim])`` [N, A] in
[-1, 1]: the deterministic action of PPO and SAC (TanhNormal's mean) and TD3's action.
:func:`export_torchscript` writes the same function as a TorchScript file that needs no falcon-rl.

Sealed files: ``sha256`` is :func:`content_digest` of everything else (every tensor's dtype, shape and
bytes, every plain value), checked on reading. :func:`read_document` loads weights-only (no pickled
code ever runs) and turns every unreadable, corrupt or foreign file into one :class:`FileFormatError`
line ``<path>: <reason>``; the network a file declares is checked against size limits and against its
tensors' shapes before anything is allocated. Files of format ``falcon-rl-policy/1`` (no checksum,
such as the shipped ones) load as legacy after the same structure and shape checks.

Finite values: a sound checksum only says that a file is as written, so the values are checked too
(:func:`value_problem`): every floating-point tensor an actor acts with (the ``mlp`` weights, the
normaliser's ``mean``, ``var``, ``clip``, ``min_std``) must be finite, ``var`` non-negative, ``clip``
and ``min_std`` positive. A file that breaks this is refused on reading (:class:`FileFormatError`
naming the entry, e.g. ``actor weight 'mlp.0.weight' has 3 non-finite values (NaN or inf)``) and never
written (:func:`save_policy` and :func:`atomic_save` of a policy document raise ValueError before
anything is written, so an earlier file stays as it was).

TorchScript export: :func:`export_torchscript` scripts :class:`DeployedPolicy` (not a trace, which
would fix the batch rank), so the exported module checks its input: obs ``[N, D]`` -> action
``[N, A]``, and as in Python ``[D]`` -> ``[A]`` (one observation) and ``[..., D]`` -> ``[..., A]``;
any other shape raises ``observation must have shape [N, D] ...`` (in TorchScript a ``torch.jit.Error``
whose last line is that ValueError).

Writing a file needs only a :class:`PolicyNetwork` (the training recipes' ``PolicyNet`` is one), so this
module knows nothing about training.
"""

from __future__ import annotations

import hashlib
import itertools
import pickle
import warnings
import zipfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any, Protocol

import torch
from tensordict.nn import TensorDictModule
from torch import nn

from ..atomic_files import serialized, write_atomic

FORMAT = "falcon-rl-policy/2"
#: Earlier formats still read: /1 had no checksum.
LEGACY_FORMATS = ("falcon-rl-policy/1",)

#: Limits on a declared network, checked before anything is allocated.
MAX_LAYERS = 32
MAX_WIDTH = 16_384
MAX_PARAMETERS = 50_000_000

#: Activation names of the ``arch`` entry -> module classes.
ACTIVATIONS: dict[str, type[nn.Module]] = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "silu": nn.SiLU}


class FileFormatError(ValueError):
    """An unreadable, corrupt, foreign or mismatched file: one line ``<path>: <reason>``."""

    def __init__(self, path: str | Path, reason: str):
        super().__init__(f"{path}: {reason}")
        self.path, self.reason = Path(path), reason


# ---------------------------------------------------------------------------------------- sealed files
def content_digest(doc: dict) -> str:
    """sha256 (hex) of ``doc`` without its ``sha256`` entry: dict keys in sorted order, each tensor's
    dtype, shape and bytes, each plain value's type and repr."""
    digest = hashlib.sha256()
    _feed(digest, {k: v for k, v in doc.items() if k != "sha256"})
    return digest.hexdigest()


def _feed(digest: Any, value: Any) -> None:
    """Add ``value`` (a tensor, a dict, a list / tuple or a plain value) to the hashlib ``digest``."""
    if isinstance(value, torch.Tensor):
        flat = value.detach().cpu().contiguous().reshape(-1)
        digest.update(f"T{value.dtype}{tuple(value.shape)};".encode())
        digest.update(flat.view(torch.uint8).numpy().tobytes())
    elif isinstance(value, dict):
        digest.update(f"D{len(value)};".encode())
        for key, item in sorted(value.items(), key=lambda kv: repr(kv[0])):
            _feed(digest, key)
            _feed(digest, item)
    elif isinstance(value, (list, tuple)):
        digest.update(f"L{len(value)};".encode())
        for item in value:
            _feed(digest, item)
    else:
        digest.update(f"{type(value).__name__}:{value!r};".encode())


def seal(doc: dict) -> dict:
    """``doc`` with its ``sha256`` entry."""
    return {**doc, "sha256": content_digest(doc)}


def verify_seal(doc: dict, path: str | Path) -> None:
    """FileFormatError unless ``doc`` holds the sha256 of its contents."""
    expected = doc.get("sha256")
    if not isinstance(expected, str):
        raise FileFormatError(path, "no content checksum (corrupt or not written by falcon-rl)")
    try:
        actual = content_digest(doc)
    except Exception:
        raise FileFormatError(path, "corrupt (its contents cannot be checksummed)") from None
    if actual != expected:
        raise FileFormatError(path, "content checksum mismatch: the file is corrupt or was edited")


def _is_torchscript(path: Path) -> bool:
    """Whether ``path`` is a TorchScript archive (a zip holding ``constants.pkl`` or ``code/``)."""
    try:
        with zipfile.ZipFile(path) as archive:
            return any(n.endswith("/constants.pkl") or "/code/" in n for n in archive.namelist())
    except (zipfile.BadZipFile, OSError, ValueError, EOFError):
        return False


def read_document(path: str | Path, what: str, map_location: str | torch.device = "cpu") -> dict:
    """The dict saved at ``path``, loaded weights-only (tensors and plain containers; pickled objects
    and code are refused unread). ``what`` names the expected kind of file in the one-line
    :class:`FileFormatError` that any unreadable, truncated, corrupt or foreign file raises."""
    path = Path(path)
    try:
        if path.is_dir():
            raise FileFormatError(path, f"is a folder, not a {what}")
        with open(path, "rb") as f:
            head = f.read(1)
    except FileNotFoundError:
        raise FileFormatError(path, f"no such file (expected a {what})") from None
    except OSError as exc:
        raise FileFormatError(path, f"cannot be read ({exc.strerror or type(exc).__name__})") from None
    if not head:
        raise FileFormatError(path, f"empty file (0 bytes), not a {what}")
    if _is_torchscript(path):
        raise FileFormatError(path, f"a TorchScript file (such as policy.ts), not a {what}")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            doc = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:  # the loader's errors on broken archives vary (zip, EOF, key, runtime)
        plain_pickle, pickled_objects = head == b"\x80", "global" in str(exc).lower()
        pickled = isinstance(exc, pickle.UnpicklingError) and (plain_pickle or pickled_objects)
        reason = ("truncated, corrupt or not a torch file" if not pickled
                  else "a plain Python pickle, not a torch file" if plain_pickle
                  else "holds pickled Python objects, not only tensors")
        refused = "refused unread; " if pickled else ""
        raise FileFormatError(path, f"{reason} ({refused}expected a {what})") from None
    if not isinstance(doc, dict):
        raise FileFormatError(path, f"holds a {type(doc).__name__}, not a {what}")
    return doc


def atomic_save(obj: Any, path: str | Path) -> Path:
    """``torch.save(obj)`` to ``path`` atomically (:func:`falcon_rl.atomic_files.write_atomic`: serialised
    in memory, written through a temporary of a unique name, moved over ``path``). A policy document
    (a dict whose ``format`` is a policy format) with non-finite values is refused first (ValueError,
    :func:`refuse_unsound`): nothing is written."""
    if isinstance(obj, dict) and isinstance(obj.get("format"), str) and obj["format"] in (FORMAT,
                                                                                       *LEGACY_FORMATS):
        refuse_unsound(obj, POLICY_ENTRIES, path)
    return write_atomic(path, serialized(lambda stream: torch.save(obj, stream)))


# ---------------------------------------------------------------------------------------- finite values
#: What a tensor under each top-level entry of a policy file or a checkpoint is called in an error.
ENTRY_NAMES = {"mlp": "actor weight", "norm": "observation normaliser statistic", "modules": "network weight",
               "optimizers": "optimiser state", "extra": "entry"}
#: The entries of a policy file whose values an actor acts with (checked by :func:`value_problem`).
POLICY_ENTRIES = ("mlp", "norm")
#: Normaliser statistics that must be >= 0 and those that must be > 0 (besides finite).
NON_NEGATIVE_STATS, POSITIVE_STATS = ("var", "count"), ("clip", "min_std")


def _tensors(value: Any, key: str) -> Iterator[tuple[str, torch.Tensor]]:
    """(dotted key, tensor) of every tensor in ``value`` (nested dicts, lists and tuples)."""
    if isinstance(value, torch.Tensor):
        yield key, value
    elif isinstance(value, dict):
        for name, item in value.items():
            yield from _tensors(item, f"{key}.{name}")
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            yield from _tensors(item, f"{key}.{i}")


def _plural(count: int, noun: str) -> str:
    return f"{count} {noun}{'' if count == 1 else 's'}"


def value_problem(doc: dict, entries: Iterable[str]) -> str | None:
    """The first unsound value under ``doc[entry]`` for each of ``entries`` (see the module docstring):
    a floating-point tensor holding NaN or inf, or a normaliser statistic (``norm`` entry) out of its
    range; None when every value is sound. Integer and bool tensors (generator states) are not checked.
    """
    for entry in entries:
        what = ENTRY_NAMES.get(entry, "entry")
        for key, tensor in _tensors(doc.get(entry), entry):
            if not tensor.is_floating_point():
                continue
            bad = int((~torch.isfinite(tensor)).sum())
            if bad:
                return f"{what} {key!r} has {_plural(bad, 'non-finite value')} (NaN or inf)"
            stat = key.removeprefix("norm.") if entry == "norm" else None
            if stat in NON_NEGATIVE_STATS and bool((tensor < 0).any()):
                return f"{what} {key!r} has {_plural(int((tensor < 0).sum()), 'negative value')}"
            if stat in POSITIVE_STATS and not bool((tensor > 0).all()):
                return f"{what} {key!r} must be > 0, got {tensor.flatten()[0].item():g}"
    return None


def refuse_unsound(doc: dict, entries: Iterable[str], path: str | Path) -> None:
    """ValueError ``<path>: not written, <problem>`` when :func:`value_problem` finds one: called
    before a file is written, so that an earlier file at ``path`` stays as it was."""
    problem = value_problem(doc, entries)
    if problem is not None:
        raise ValueError(f"{path}: not written, {problem}")


# ---------------------------------------------------------------------------------------- policies
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


def layer_sizes(arch: Any) -> list[int]:
    """``[obs_dim, *cells, out_dim]`` of a declared ``arch``, checked (types, activation, limits on
    layers, widths and parameters) before anything is built; ValueError (one line) otherwise."""
    if not isinstance(arch, dict):
        raise ValueError("no network description (arch)")
    cells = arch.get("cells")
    dims = [arch.get("obs_dim"), arch.get("act_dim"), arch.get("out_dim")]
    if not isinstance(cells, (list, tuple)) or not all(type(v) is int for v in [*dims, *cells]):
        raise ValueError("network description (arch) lacks integer obs_dim, act_dim, out_dim and cells")
    sizes = [dims[0], *cells, dims[2]]
    if not cells or len(cells) > MAX_LAYERS or not all(1 <= v <= MAX_WIDTH for v in [*sizes, dims[1]]):
        raise ValueError(f"declared network {sizes} is outside the limits (1 to {MAX_LAYERS} hidden layers, "
                         f"widths 1 to {MAX_WIDTH})")
    if not dims[1] <= dims[2]:
        raise ValueError(f"declared act_dim {dims[1]} exceeds out_dim {dims[2]}")
    parameters = sum(a * b + b for a, b in itertools.pairwise(sizes))
    if parameters > MAX_PARAMETERS:
        raise ValueError(f"declared network {sizes} is too large ({parameters:,} parameters, "
                         f"at most {MAX_PARAMETERS:,})")
    if arch.get("activation") not in ACTIVATIONS:
        raise ValueError(f"unknown activation {arch.get('activation')!r}")
    return sizes


def check_policy_document(doc: dict, path: str | Path) -> None:
    """FileFormatError unless ``doc`` is a sound policy file: its format, checksum (legacy /1 files
    have none), declared network (limits), ``mlp`` tensors of exactly that network and normaliser, all
    of them finite (:func:`value_problem`)."""
    fmt = doc.get("format")
    if fmt not in (FORMAT, *LEGACY_FORMATS):
        reason = ("a training checkpoint, not a policy file (use <out>/policy.pt)" if isinstance(fmt, int)
                  else f"not a falcon-rl policy file (format {fmt!r})")
        raise FileFormatError(path, reason)
    if fmt == FORMAT:
        verify_seal(doc, path)
    try:
        sizes = layer_sizes(doc.get("arch"))
    except ValueError as exc:
        raise FileFormatError(path, str(exc)) from None
    expected = {}
    for i, (a, b) in enumerate(itertools.pairwise(sizes)):
        expected[f"{2 * i}.weight"], expected[f"{2 * i}.bias"] = (b, a), (b,)
    mlp, norm = doc.get("mlp"), doc.get("norm")
    if not isinstance(mlp, dict) or {k: tuple(getattr(v, "shape", ())) for k, v in mlp.items()} != expected \
            or not all(isinstance(v, torch.Tensor) and v.is_floating_point() for v in mlp.values()):
        raise FileFormatError(path, f"network weights do not match the declared network {sizes}")
    vectors, scalars = ("mean", "var"), ("enabled", "clip", "min_std")
    if not isinstance(norm, dict) or not all(
            isinstance(norm.get(k), torch.Tensor) and tuple(norm[k].shape) == (sizes[0],) for k in vectors) \
            or not all(isinstance(norm.get(k), torch.Tensor) and norm[k].numel() == 1 for k in scalars):
        raise FileFormatError(path, f"observation normaliser does not match obs_dim {sizes[0]}")
    if not isinstance(doc.get("meta"), dict):
        raise FileFormatError(path, "no meta entry")
    problem = value_problem(doc, POLICY_ENTRIES)
    if problem is not None:
        raise FileFormatError(path, problem)


class DeployedPolicy(nn.Module):
    """obs [N, D] -> action [N, A] in [-1, 1] (also [D] -> [A] and [..., D] -> [..., A]; any other shape
    is a ValueError); the normaliser lives in buffers. Built uninitialised (no random draws): its
    weights come from a file. Scriptable (:func:`export_torchscript`)."""

    def __init__(self, arch: dict, norm: dict[str, torch.Tensor]):
        super().__init__()
        self.act_dim = int(arch["act_dim"])
        sizes = layer_sizes(arch)
        self.obs_dim = sizes[0]
        layers: list[nn.Module] = []
        for a, b in itertools.pairwise(sizes):
            layers += [nn.utils.skip_init(nn.Linear, a, b), ACTIVATIONS[arch["activation"]]()]
        self.mlp = nn.Sequential(*layers[:-1])
        enabled = bool(norm["enabled"])
        dim = sizes[0]
        self.register_buffer("mean", norm["mean"].float().clone() if enabled else torch.zeros(dim))
        std = norm["var"].float().sqrt().clamp_min(float(norm["min_std"])) if enabled else torch.ones(dim)
        self.register_buffer("std", std)
        self.clip = float(norm["clip"]) if enabled else float("inf")

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        if obs.dim() == 0 or obs.shape[-1] != self.obs_dim:
            raise ValueError(f"observation must have shape [N, D={self.obs_dim}] (or [D], [..., D]), "
                             f"got {list(obs.shape)}")
        x = ((obs.to(self.mean.dtype) - self.mean) / self.std).clamp(-self.clip, self.clip)
        return torch.tanh(self.mlp(x)[..., : self.act_dim])


def policy_document(net: PolicyNetwork, meta: dict) -> dict:
    """The policy file's contents for ``net`` (a trained :class:`PolicyNetwork`), sealed."""
    return seal({"format": FORMAT, "arch": net.arch(),
                 "mlp": {k: v.detach().cpu().clone() for k, v in net.mlp.state_dict().items()},
                 "norm": {k: v.cpu() for k, v in net.norm.stats().items() if k != "count"},
                 "meta": dict(meta)})


def policy_from_document(doc: dict) -> DeployedPolicy:
    """The :class:`DeployedPolicy` (CPU, eval mode) of a policy file's contents."""
    policy = DeployedPolicy(doc["arch"], doc["norm"])
    policy.mlp.load_state_dict(doc["mlp"])
    return policy.eval()


def save_policy(path: str | Path, net: PolicyNetwork, meta: dict) -> Path:
    """Write the policy file for ``net`` atomically; ValueError (nothing written) when its weights or
    normaliser hold non-finite values."""
    return atomic_save(policy_document(net, meta), path)


def read_policy(path: str | Path) -> tuple[DeployedPolicy, dict]:
    """(DeployedPolicy on CPU in eval mode, meta) from a policy file, loaded weights-only and checked
    (:func:`check_policy_document`); FileFormatError (one line naming the file) otherwise."""
    doc = read_document(path, "falcon-rl policy file (.pt)")
    check_policy_document(doc, path)
    return policy_from_document(doc), doc["meta"]


def load_policy(path: str | Path, env=None) -> TensorDictModule:
    """The policy at ``path`` as a TensorDictModule reading "observation" and writing "action"
    (moved to ``env``'s device and dtype). Checks the observation and action sizes against ``env``."""
    policy, meta = read_policy(path)
    if env is not None:
        obs_dim, act_dim = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
        arch = (policy.mlp[0].in_features, policy.act_dim)
        if arch != (obs_dim, act_dim):
            raise FileFormatError(path, f"policy for obs/action sizes {arch}, env has {(obs_dim, act_dim)} "
                                        f"(policy trained on task {meta.get('task')!r})")
        policy = policy.to(device=env.device, dtype=env.action_spec.dtype)
    module = TensorDictModule(policy, in_keys=["observation"], out_keys=["action"])
    module.meta = meta
    return module


def export_torchscript(path: str | Path, policy_path: str | Path) -> Path:
    """Script the policy file at ``policy_path`` into a TorchScript file: obs [N, D] -> action [N, A]
    (or [D] -> [A], [..., D] -> [..., A]; another shape raises), ``meta.txt`` (the file's meta) among
    its extra files. Load it with ``torch.jit.load(path)`` (no falcon-rl needed)."""
    policy, meta = read_policy(policy_path)
    scripted = torch.jit.script(policy)
    return write_atomic(path, serialized(lambda stream: torch.jit.save(scripted, stream,
                                                                     _extra_files={"meta.txt": repr(meta)})))


__all__ = ["ACTIVATIONS", "ENTRY_NAMES", "FORMAT", "LEGACY_FORMATS", "MAX_LAYERS", "MAX_PARAMETERS",
           "MAX_WIDTH", "POLICY_ENTRIES", "DeployedPolicy", "FileFormatError", "PolicyNetwork",
           "RunningStats", "atomic_save", "check_policy_document", "content_digest", "export_torchscript",
           "layer_sizes", "load_policy", "policy_document", "policy_from_document", "read_document",
           "read_policy", "refuse_unsound", "save_policy", "seal", "value_problem", "verify_seal"]
