"""Env cards: one page per registered task, generated at build time from the task registry and a
constructed env (``make_env(task, num_envs=1, backend="torch")``, a fraction of a second each).

A card states what a user of the env needs before writing a policy: keys, shapes and dtypes from the
env's specs, the horizon in steps and seconds, control rate and physics step, action channels and
bounds, observation size and clip, reward and termination, the task's evaluation protocol and metric
columns, its baselines, its defaults and the recipes' training settings, and the Gymnasium id. The
MDP's equations are the task module's docstring, shown as they are written there.

    from gen_env_cards import env_cards
    pages = env_cards()        # {"tasks/index.md": ..., "tasks/altitude.md": ..., ...}
"""

from __future__ import annotations

import dataclasses
import inspect
import re
import sys
from collections.abc import Callable, Mapping
from typing import Any

from prose import autoref, inline, to_markdown

#: The backend the cards' envs are built on (no kernel compilation at build time).
BACKEND = "torch"


# ---------------------------------------------------------------------------------------------- format
def fmt(value: Any) -> str:
    """Short, stable text of a default or setting value."""
    if isinstance(value, float):
        return repr(value) if len(repr(value)) <= 8 else f"{value:.6g}"
    if isinstance(value, tuple | list):
        inner = ", ".join(fmt(v) for v in value)
        return f"({inner}{',' if len(value) == 1 else ''})" if isinstance(value, tuple) else f"[{inner}]"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k}={fmt(v)}" for k, v in value.items()) + "}"
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return type(value).__name__ + "(...)"
    return repr(value)


def code(text: str) -> str:
    """``text`` as a Markdown code span that survives table cells."""
    text = str(text).replace("|", "\\|")
    return f"``{text}``" if "`" in text else f"`{text}`"


def ref_identifier(ref: Any) -> tuple[str, str]:
    """(identifier, shown text) of a registry reference: "pkg.mod:attr.path" or a callable."""
    if isinstance(ref, str):
        module, _, attribute = ref.partition(":")
        return f"{module}.{attribute}", attribute or module
    module = getattr(ref, "__module__", "")
    qualname = getattr(ref, "__qualname__", getattr(ref, "__name__", repr(ref)))
    return f"{module}.{qualname}", qualname


def link(ref: Any) -> str:
    """A cross-reference to the object behind ``ref`` (plain code when it is not on the site)."""
    identifier, shown = ref_identifier(ref)
    return autoref(identifier, shown)


def class_link(cls: type) -> str:
    return autoref(f"{cls.__module__}.{cls.__qualname__}", cls.__name__)


def shape_text(shape: Any) -> str:
    """Shape with the batch dim written N: [N, 11]."""
    dims = ["N", *(str(int(d)) for d in tuple(shape)[1:])]
    return "[" + ", ".join(dims) + "]"


def dtype_text(dtype: Any) -> str:
    return str(dtype).removeprefix("torch.")


def spec_text(spec: Any) -> str:
    """Kind and bounds of a leaf spec: Bounded [-3, 3], Categorical (n = 2), Unbounded."""
    kind = type(spec).__name__
    space = getattr(spec, "space", None)
    if hasattr(space, "n"):
        return f"Categorical (n = {int(space.n)})"
    low, high = getattr(space, "low", None), getattr(space, "high", None)
    if low is not None and high is not None and "Unbounded" not in kind:
        lo, hi = float(low.min()), float(high.max())
        if float(low.max()) == lo and float(high.min()) == hi:
            return f"Bounded [{fmt(lo)}, {fmt(hi)}]"
        return f"Bounded [{fmt(lo)}..{fmt(float(low.max()))}, {fmt(float(high.min()))}..{fmt(hi)}]"
    return "Unbounded" if "Unbounded" in kind else kind


def key_text(key: Any) -> str:
    return code(key) if isinstance(key, str) else code("(" + ", ".join(repr(k) for k in key) + ")")


def table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|",
            *("| " + " | ".join(row) + " |" for row in rows), ""]


# ---------------------------------------------------------------------------------------------- facts
def module_doc(task_cls: type) -> str:
    module = sys.modules.get(task_cls.__module__)
    return inspect.cleandoc(getattr(module, "__doc__", None) or "")


def module_resolver(task_cls: type) -> Callable[[str], str | None]:
    """Role targets of a task module's docstring -> identifiers (relative names, then its globals)."""
    module_name = task_cls.__module__
    module = sys.modules.get(module_name)
    package = module_name.rpartition(".")[0]

    def resolve(name: str) -> str | None:
        if name.startswith("."):
            base = package
            for _ in range(len(name) - len(name.lstrip(".")) - 1):
                base = base.rpartition(".")[0]
            return f"{base}.{name.lstrip('.')}"
        head, _, rest = name.partition(".")
        target = getattr(module, head, None)
        if target is None:
            return None
        if inspect.ismodule(target):
            full = target.__name__
        else:
            full = f"{getattr(target, '__module__', module_name)}.{getattr(target, '__qualname__', head)}"
        return f"{full}.{rest}" if rest else full

    return resolve


def termination_text(env: Any, spec: Any) -> str:
    """The termination conditions: the task's docstring sentence when it has one, the reasons it
    checks (a live call on the built env) and the env's own (non-finite state, horizon)."""
    task = env.task
    doc = module_doc(spec.task)
    match = re.search(r"Termination:\s*(.+?\.)(?=\s|$)", doc, flags=re.S)
    parts = []
    if match:
        parts.append(inline(" ".join(match.group(1).split()), module_resolver(spec.task), in_table=True))
    else:
        method = getattr(type(task), "termination_checks", None) or type(task).terminated
        summary = (inspect.getdoc(method) or "").split("\n\n")[0]
        if summary:
            parts.append(inline(" ".join(summary.split()), in_table=True))
    checks = getattr(task, "termination_checks", None)
    if callable(checks):
        reasons = list(checks(env.sim.state))
        parts.append("reasons checked, in order: " + ", ".join(code(r) for r in reasons)
                     + " (published as `termination_reason`)")
    parts.append("a state that leaves the finite numbers also terminates (outputs zeroed)")
    return "; ".join(parts)


def config_defaults(config_cls: type, applied: Mapping[str, Any]) -> list[tuple[str, ...]]:
    """(field, dataclass default, the task's default when it sets one) rows of a config dataclass."""
    rows = []
    for f in dataclasses.fields(config_cls):
        if f.default is not dataclasses.MISSING:
            default = fmt(f.default)
        elif f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
            default = fmt(f.default_factory())  # type: ignore[misc]
        else:
            default = "required"
        task_value = fmt(applied[f.name]) if f.name in applied else ""
        rows.append((code(f.name), code(default), code(task_value) if task_value else ""))
    return rows


def env_facts(env: Any, spec: Any) -> dict[str, Any]:
    """Numbers of a built env: physics dt, decimation, control rate, horizon."""
    base = getattr(env, "base_env", env)
    dt = float(base.config.dt)
    control_dt = float(getattr(base, "control_dt", dt))
    return {"dt": dt, "control_dt": control_dt, "decimation": round(control_dt / dt),
            "steps": int(base.max_episode_steps), "seconds": float(base.task.episode_seconds),
            "integrator": base.config.integrator, "ground_effect": base.config.ground_effect}


def training_rows(spec: Any, facts: Mapping[str, Any]) -> list[tuple[str, ...]]:
    """Per recipe (and per airframe with its own training defaults): its task fields and the control rate
    and horizon they give."""
    rows = []
    task_defaults = dict(getattr(spec, "defaults", {}) or {})
    per_airframe = [(f"{algorithm} ({airframe})", spec.training_defaults(algorithm, airframe))
                    for airframe, recipes in getattr(spec, "airframe_training", {}).items()
                    for algorithm in recipes]
    for algorithm, fields in [*spec.training.items(), *per_airframe]:
        fields = dict(fields)
        env_options = {**task_defaults, **dict(fields.get("env_options", {}) or {})}
        dt = float(env_options.get("dt", facts["dt"]))
        decimation = int(env_options.get("decimation", facts["decimation"]) or 1)
        seconds = float(fields.get("episode_seconds", env_options.get("episode_seconds", facts["seconds"])))
        steps = max(1, round(seconds / (dt * decimation)))
        shown = ", ".join(f"{k}={fmt(v)}" for k, v in fields.items())
        rows.append((code(algorithm), f"{fmt(1.0 / (dt * decimation))} Hz",
                     f"{fmt(seconds)} s = {steps} steps", code(shown) if shown else "(recipe defaults)"))
    return rows


# ---------------------------------------------------------------------------------------------- cards
def build_env(name: str) -> Any:
    """The card's env: the task's defaults, one env, the torch backend, seed 0."""
    from falcon_rl.envs import make_env

    return make_env(name, num_envs=1, backend=BACKEND, seed=0)


def default_airframe() -> str:
    from falcon_rl.envs import make_env

    return inspect.signature(make_env).parameters["airframe"].default


def card(spec: Any, env: Any) -> str:
    """Markdown of one task's card."""
    from falcon_rl.physics.state import COMMAND_CHANNELS

    base = getattr(env, "base_env", env)
    task = base.task
    facts = env_facts(env, spec)
    doc = module_doc(spec.task)
    resolve = module_resolver(spec.task)
    summary = to_markdown(doc.split("\n\n")[0], resolve) if doc else ""
    action_spec = env.action_spec
    channels = [COMMAND_CHANNELS[int(c)] for c in spec.task.action_channels]
    observation_spec = env.observation_spec["observation"]
    reward_spec = env.reward_spec
    reward = (f"{spec_text(reward_spec)} spec (the task declares no range): the per-step reward is the "
              "weighted sum of the [MDP definition](#mdp-definition)")
    airframe = default_airframe()
    overview = [
        ("task", f"{code(spec.name)}: {class_link(spec.task)} with {class_link(spec.config)}"),
        ("Gymnasium id", f"{code(spec.gym_id)} (one aircraft, NumPy, float32 `Box` spaces)"),
        ("horizon", f"{fmt(facts['seconds'])} s = {facts['steps']} env steps, then truncated"),
        ("control rate", f"{fmt(1.0 / facts['control_dt'])} Hz: env step {fmt(facts['control_dt'])} s = "
                         f"decimation {facts['decimation']} x physics dt"),
        ("physics", f"dt {fmt(facts['dt'])} s, integrator {code(facts['integrator'])}, ground effect "
                    f"{code(facts['ground_effect'])}"),
        ("action", f"{task.action_dim} channels {', '.join(code(c) for c in channels)}; "
                   f"{spec_text(action_spec)}, {dtype_text(action_spec.dtype)}"),
        ("observation", f"{task.observation_dim} entries, clipped to +-{fmt(float(task.observation_clip))}, "
                        f"{dtype_text(observation_spec.dtype)}"),
        ("reward", f"{shape_text(reward_spec.shape)} {dtype_text(reward_spec.dtype)}; {reward}"),
        ("termination", termination_text(base, spec)),
    ]
    lines = [f"# {spec.title} (`{spec.name}`)", "", summary, "",
             *table(("", "this task"), [(f"**{k}**", v) for k, v in overview]),
             f"Generated from `make_env({spec.name!r}, num_envs=1, backend={BACKEND!r}, seed=0)` on the "
             f"default airframe `{airframe}` with the task's defaults; the shapes are per env "
             "(batch dim N), the same on every backend and airframe.", "",
             "```python",
             "import gymnasium",
             "from falcon_rl import make_env",
             "",
             f'env = make_env("{spec.name}", "volantex_ranger", num_envs=64)  # TorchRL, batch [64]',
             f'gym_env = gymnasium.make("{spec.gym_id}")  # Gymnasium, one aircraft',
             "```", ""]

    rows = []
    for group, group_spec in (("observation", env.full_observation_spec), ("action", env.full_action_spec),
                              ("reward", env.full_reward_spec), ("done", env.full_done_spec)):
        for key in group_spec.keys(include_nested=True, leaves_only=True):
            leaf = group_spec[key]
            rows.append((key_text(key), group, shape_text(leaf.shape), dtype_text(leaf.dtype),
                         spec_text(leaf)))
    lines += ["## Keys and specs", "",
              "Every entry of a step's TensorDict (`env.rollout(...)` puts the step's results under "
              '`"next"`). `("state", ...)` is the true simulator state (metrics, privileged critics), '
              '`("task", ...)` the task\'s references and errors; policies read `"observation"`.', "",
              *table(("key", "group", "shape", "dtype", "bounds"), rows)]

    lines += ["## Evaluation protocol", ""]
    if spec.protocol is not None:
        lines += [f"Protocol {link(spec.protocol)}, run by `falcon-rl eval --task {spec.name}` "
                  "(see the [CLI reference](../cli.md)). Summary columns, in report order:", ""]
        lines += table(("key", "column", "unit"),
                       [(code(m.key), inline(m.label, in_table=True), m.unit or "") for m in spec.metrics])
    else:
        lines += ["No evaluation protocol is registered for this task.", ""]
    controllers = [(code(name), link(ref)) for name, ref in spec.controllers.items()]
    if controllers:
        lines += ["Baselines (`falcon-rl eval --controller NAME`; a policy file of this task also works):",
                  "",
                  *table(("controller", "factory (env) -> policy"), controllers)]
    if spec.figure is not None:
        lines += [f"Figure: {link(spec.figure)}.", ""]

    applied = {k: v for k, v in dict(getattr(spec, "defaults", {}) or {}).items()}
    lines += ["## Settings", "",
              f"Config dataclass {class_link(spec.config)} (pass any field to `make_env`). The third "
              "column is what the task's registered defaults set on top of the dataclass.", "",
              *table(("field", "dataclass default", "task default"), config_defaults(spec.config, applied))]
    config_fields = {f.name for f in dataclasses.fields(spec.config)}
    env_defaults = {k: v for k, v in applied.items() if k not in config_fields}
    if env_defaults:
        lines += ["Env settings the task sets by default: "
                  + ", ".join(code(f"{k}={fmt(v)}") for k, v in env_defaults.items()) + ".", ""]
    train = training_rows(spec, facts)
    if train:
        lines += [f"Training (`falcon-rl train ALGORITHM --task {spec.name}`): the fields this task sets on "
                  "each recipe's config, and the control rate and horizon they give.", "",
                  *table(("recipe", "control rate", "episode", "task fields"), train)]

    lines += ["## MDP definition", "",
              f"The docstring of {autoref(spec.task.__module__, spec.task.__module__)}, where the task is "
              "written:", "", to_markdown(doc, resolve), ""]
    return "\n".join(lines)


def index(specs: list[Any], envs: Mapping[str, Any]) -> str:
    rows = []
    for spec in specs:
        env = envs[spec.name]
        facts = env_facts(env, spec)
        task = getattr(env, "base_env", env).task
        rows.append((f"[{spec.title}]({spec.name}.md)", code(spec.name), code(spec.gym_id),
                     str(task.observation_dim), str(task.action_dim),
                     f"{fmt(facts['seconds'])} s / {facts['steps']}", f"{fmt(1.0 / facts['control_dt'])} Hz",
                     ", ".join(code(name) for name in spec.controllers)))
    return "\n".join([
        "# Env cards", "",
        "One card per registered task (`falcon_rl.envs.tasks.task_spec(name)`), generated when the site "
        "is built from the registry and an env built with the task's defaults, so a task registered in "
        "the package gets its card without editing the site.", "",
        *table(("task", "name", "Gymnasium id", "obs", "act", "horizon (s / steps)", "control",
                "baselines"), rows)])


def env_cards() -> dict[str, str]:
    """{docs path: Markdown}: ``tasks/index.md`` and ``tasks/<name>.md`` for every registered task."""
    from falcon_rl.envs.tasks import task_names, task_spec

    specs = [task_spec(name) for name in task_names()]
    envs = {spec.name: build_env(spec.name) for spec in specs}
    pages = {"tasks/index.md": index(specs, envs)}
    for spec in specs:
        pages[f"tasks/{spec.name}.md"] = card(spec, envs[spec.name])
        close = getattr(envs[spec.name], "close", None)
        if callable(close):
            close()
    return pages


__all__ = ["card", "env_cards", "index"]
