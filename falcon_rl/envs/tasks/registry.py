"""One record per task: :class:`TaskSpec` holds everything that is known about a task by its name.

    spec = task_spec("altitude")
    env = make_env(spec.name, "volantex_ranger")                     # spec.task, spec.config
    policy = spec.controller("lqr")(env)                              # a baseline that applies
    result = spec.protocol_function()(airframe, label, factory, episodes=20)
    defaults = spec.training_defaults("ppo", "airship_v7")            # recipe fields of the task
    spec.defaults                                                     # what make_env builds by default

Every task module registers its own spec beside its Task and config classes; a task defined
elsewhere (a user's module, a test) registers one the same way and is then reached by ``make_env``,
the Gymnasium ids (after ``register_gym_envs()``), the evaluation harness and ``falcon-rl eval``.

Layering: the task modules sit below the evaluation, baseline and recipe code their spec names, so
the protocol, the controllers and the figure are references (:data:`Ref`): either the object itself
or a ``"package.module:attribute"`` string that :func:`resolve` imports at use. The training
defaults are plain data.
"""

from __future__ import annotations

import copy
import dataclasses
import importlib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Generic, TypeVar

from .base import Task, TaskConfig

#: A callable, or the "package.module:attribute.path" of one (imported at use).
Ref = str | Callable[..., Any]

#: The controller every task has: hold the trim command in the action channels.
TRIM_HOLD: str = "falcon_rl.evaluation.controllers:TrimHold"

#: Recipe names the training defaults may be given for.
ALGORITHMS: tuple[str, ...] = ("ppo", "sac", "td3")

#: Env-level settings (fields of ``FixedWingEnvConfig``) a task's ``defaults`` may set; every other
#: name in ``defaults`` must be a field of the task's config dataclass.
ENV_DEFAULT_FIELDS: tuple[str, ...] = ("decimation", "dt", "integrator", "ground_effect")

#: Control at 20 Hz (decimation 5 of the 10 ms physics step): the rate every recipe trains at (gamma
#: 0.99 then looks ~5 s ahead) and the env's default; the evaluation protocols fly the paper's 10 ms
#: control step (decimation 1) unless told otherwise.
TRAINING_DECIMATION = 5


def resolve(ref: Ref) -> Callable[..., Any]:
    """The object named by ``ref`` ("module:attr.attr") or ``ref`` itself when it is callable."""
    if not isinstance(ref, str):
        return ref
    module_name, sep, attribute = ref.partition(":")
    if not sep or not attribute:
        raise ValueError(f"reference {ref!r} must read 'package.module:attribute'")
    target: Any = importlib.import_module(module_name)
    for name in attribute.split("."):
        target = getattr(target, name)
    return target


@dataclass(frozen=True)
class Metric:
    """One column of a task's protocol summary: its key, a short label and its unit."""

    #: Key in ``ProtocolResult.summary`` (prefixed "<case>/" for protocols with cases, e.g. maneuvers).
    key: str
    label: str
    #: SI unit ("m", "m/s", "s", "deg"); "" for fractions and counts.
    unit: str = ""

    @property
    def header(self) -> str:
        """Column header, e.g. "RMSE (m)"."""
        return f"{self.label} ({self.unit})" if self.unit else self.label


@dataclass(frozen=True, eq=False)
class TaskSpec:
    """Everything about one task, found from its name (see the module docstring). Read-only; compared
    and hashed by identity (one record per registered task).

    ``protocol`` is called as ``protocol(airframe, controller_label, factory, episodes=..., seed=...,
    backend=..., device=..., episode_seconds=None, **options) -> ProtocolResult`` where ``factory``
    builds the policy for the protocol's env. ``controllers`` maps a controller name to a factory
    ``(env) -> policy`` (TensorDictModule reading the env's keys, writing "action"). ``figure`` is
    called as ``figure(result, path) -> path``. ``training`` maps a recipe name (ppo, sac, td3) to the
    fields of its config that this task sets on top of the recipe's own defaults, and
    ``airframe_training`` maps an airframe name to the recipe fields that airframe sets on top of those
    (e.g. another batch shape for the Airship V7's altitude PPO). ``defaults`` are the
    settings an env of this task is built with unless the caller gives others (``make_env``,
    ``FixedWingEnvConfig``, the Gymnasium ids): env fields of :data:`ENV_DEFAULT_FIELDS` and fields of
    the task config (reward settings); they are what the recipes train on, so the env a user builds
    is the env the shipped policies learned in.
    """

    name: str
    task: type[Task]
    config: type[TaskConfig]
    #: Gymnasium id, "falcon_rl/<Task>-v0".
    gym_id: str
    #: Report section heading.
    title: str
    protocol: Ref | None = None
    #: The summary columns the protocol produces, in report order.
    metrics: tuple[Metric, ...] = ()
    controllers: Mapping[str, Ref] = field(default_factory=dict)
    figure: Ref | None = None
    #: The summary metric (lower is better, averaged over cases) by which a recipe with ``keep_best``
    #: picks its policy, after survival and acquisition (see :mod:`falcon_rl.recipes.selection`).
    select_on: str | None = None
    training: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    airframe_training: Mapping[str, Mapping[str, Mapping[str, Any]]] = field(default_factory=dict)
    defaults: Mapping[str, Any] = field(default_factory=lambda: {"decimation": TRAINING_DECIMATION})

    def __post_init__(self) -> None:
        unknown = set(self.training).union(*map(set, self.airframe_training.values())) - set(ALGORITHMS)
        if unknown:
            raise ValueError(f"task {self.name!r}: training defaults for unknown recipes {sorted(unknown)}; "
                             f"recipes: {list(ALGORITHMS)}")
        config_fields = {f.name for f in dataclasses.fields(self.config)}
        unknown = set(self.defaults) - config_fields - set(ENV_DEFAULT_FIELDS)
        if unknown:
            raise ValueError(f"task {self.name!r}: defaults {sorted(unknown)} are neither env settings "
                             f"{list(ENV_DEFAULT_FIELDS)} nor fields of {self.config.__name__}")
        object.__setattr__(self, "defaults", MappingProxyType(dict(self.defaults)))
        object.__setattr__(self, "controllers", MappingProxyType(dict(self.controllers)))

        def freeze(per: Mapping[str, Mapping[str, Any]]) -> Mapping[str, Mapping[str, Any]]:
            return MappingProxyType({name: MappingProxyType(dict(values)) for name, values in per.items()})

        object.__setattr__(self, "training", freeze(self.training))
        object.__setattr__(self, "airframe_training", MappingProxyType(
            {airframe: freeze(per) for airframe, per in self.airframe_training.items()}))

    def controller(self, name: str) -> Callable[..., Any]:
        """Factory ``(env) -> policy`` of baseline ``name``; one-line ValueError naming the baselines
        that apply when ``name`` is not one of them."""
        if name not in self.controllers:
            raise ValueError(f"controller {name!r} does not apply to task {self.name!r}; its controllers: "
                             f"{sorted(self.controllers)} (or a policy file of this task)")
        return resolve(self.controllers[name])

    def protocol_function(self) -> Callable[..., Any]:
        """The evaluation protocol (see the class docstring); ValueError when the task has none."""
        if self.protocol is None:
            raise ValueError(f"task {self.name!r} has no evaluation protocol")
        return resolve(self.protocol)

    def figure_function(self) -> Callable[..., Any] | None:
        """``figure(result, path) -> path``, or None when the task has no figure."""
        return None if self.figure is None else resolve(self.figure)

    @property
    def metric_keys(self) -> list[str]:
        """The protocol's summary keys (without a case prefix), in report order."""
        return [metric.key for metric in self.metrics]

    def env_default(self, name: str, fallback: Any) -> Any:
        """The task's default for env setting ``name`` (one of :data:`ENV_DEFAULT_FIELDS`), else
        ``fallback``."""
        return copy.deepcopy(self.defaults.get(name, fallback))

    def default_config(self, **overrides: Any) -> TaskConfig:
        """The task config with the task's ``defaults`` applied, then ``overrides`` (config fields)."""
        fields = {k: copy.deepcopy(v) for k, v in self.defaults.items() if k not in ENV_DEFAULT_FIELDS}
        return self.config(**{**fields, **overrides})

    def training_defaults(self, algorithm: str, airframe: str | None = None) -> dict[str, Any]:
        """A fresh (deep) copy of the config fields this task sets for recipe ``algorithm``, with those
        of ``airframe`` (its ``airframe_training`` entry, when it has one) on top."""
        per_airframe = self.airframe_training.get(airframe, {}) if airframe is not None else {}
        return copy.deepcopy({**self.training.get(algorithm, {}), **per_airframe.get(algorithm, {})})


_SPECS: dict[str, TaskSpec] = {}

#: Read-only live view: task name -> TaskSpec.
TASK_SPECS: Mapping[str, TaskSpec] = MappingProxyType(_SPECS)


def register_task(spec: TaskSpec, replace: bool = False) -> TaskSpec:
    """Add ``spec`` to the registry (``replace`` to overwrite a task of the same name); returns it."""
    if spec.name in _SPECS and not replace:
        raise ValueError(f"task {spec.name!r} is already registered (pass replace=True to overwrite it)")
    taken = {other.gym_id: other.name for other in _SPECS.values() if other.name != spec.name}
    if spec.gym_id in taken:
        raise ValueError(f"gym id {spec.gym_id!r} of task {spec.name!r} is taken by {taken[spec.gym_id]!r}")
    _SPECS[spec.name] = spec
    return spec


def unregister_task(name: str) -> TaskSpec:
    """Remove task ``name`` from the registry (a test's teardown); returns its spec."""
    return _SPECS.pop(task_spec(name).name)


def task_spec(name: str) -> TaskSpec:
    """The spec of task ``name``; a one-line ValueError listing the registered tasks otherwise."""
    try:
        return _SPECS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown task {name!r}; registered tasks: {sorted(_SPECS)}") from None


def task_names() -> list[str]:
    """Registered task names, in registration order."""
    return list(_SPECS)


V = TypeVar("V")


class SpecView(Mapping[str, V], Generic[V]):
    """Read-only live view of the registry: task name -> ``pick(spec)``."""

    def __init__(self, pick: Callable[[TaskSpec], V]):
        self._pick = pick

    def __getitem__(self, name: str) -> V:
        return self._pick(_SPECS[name])

    def __iter__(self) -> Iterator[str]:
        return iter(list(_SPECS))

    def __len__(self) -> int:
        return len(_SPECS)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({dict(self)!r})"


__all__ = ["ALGORITHMS", "ENV_DEFAULT_FIELDS", "TASK_SPECS", "TRAINING_DECIMATION", "TRIM_HOLD",
           "Metric", "Ref", "SpecView", "TaskSpec", "register_task", "resolve", "task_names", "task_spec",
           "unregister_task"]
