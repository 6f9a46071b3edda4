"""Parameter-table machinery: model parameters declared once, as rows, and everything generated.

A :class:`ParamRow` names one parameter with its shape, dtype, whether it is per env and
randomisable, its Warp element type and where its value comes from (the airframe, or a
:class:`Derivation` from other rows). From a table (a sequence of rows) this module generates the
torch container class (:func:`make_container`), the tensors of a new container
(:func:`build_values`), the Warp struct (:func:`make_warp_struct`), its zero-copy binding
(:func:`bind_warp`) and a markdown description (:func:`table_markdown`). The rows themselves live in
:mod:`.params`.

Shapes are strings of dimensions, ``"[N, M, 3]"``: symbols are sizes known when building (N envs,
T aero monomials, M motors), integers are fixed. The Warp element type takes the trailing
dimensions (vec3 one of 3, mat33 two of 3); the rest become the array dimensions.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import torch

from ..airframe import Airframe
from ..constants import G0
from ._warp import warp_struct, wp
from .switches import ModelSwitches

#: Row dtypes: "float" is the build dtype (float32 for the warp backend).
TORCH_DTYPES: dict[str, torch.dtype | None] = {
    "float": None, "int32": torch.int32, "int64": torch.int64, "bool": torch.bool}


@dataclass(frozen=True)
class BuildOptions:
    """Simulator settings that are parameters without being airframe data."""

    gravity: float = G0
    ground_effect: bool | str = True
    switches: ModelSwitches = field(default_factory=ModelSwitches)


#: The value of a source row for one env (any array-like of the row's shape without N).
Source = Callable[[Airframe, BuildOptions], Any]


@dataclass(frozen=True)
class Derivation:
    """A row computed from other rows: ``fn(*inputs)`` maps input tensors [B, ...] to [B, ...]."""

    inputs: tuple[str, ...]
    fn: Callable[..., torch.Tensor]


@dataclass(frozen=True)
class ParamRow:
    """One model parameter.

    Attributes:
        name: attribute name in the container and the Warp struct.
        shape: e.g. ``"[N]"``, ``"[N, 3]"``, ``"[N, T, 6]"`` (per env rows start with N).
        source: the value from the airframe, or a :class:`Derivation` from other rows.
        dtype: "float", "int32", "int64" or "bool".
        per_env: one value per env (else shared by all envs, and not assignable).
        randomizable: domain randomisation may overwrite it (see :func:`check_randomizable`).
        warp: Warp element type name ("float32", "vec3", "mat33", a key of the custom types), or
            None for a row the Warp struct does not carry.
        unit, doc: for the docstring and :func:`table_markdown`.
    """

    name: str
    shape: str
    source: Source | Derivation
    dtype: str = "float"
    per_env: bool = True
    randomizable: bool = False
    warp: str | None = "float32"
    unit: str = ""
    doc: str = ""

    @property
    def dims(self) -> tuple[str | int, ...]:
        """The shape as symbols and integers, ``"[N, 3]"`` -> ("N", 3)."""
        inner = self.shape.strip().removeprefix("[").removesuffix("]")
        return tuple(int(d) if d.isdigit() else d for d in (s.strip() for s in inner.split(",")) if d)

    @property
    def derived(self) -> bool:
        return isinstance(self.source, Derivation)

    def resolve(self, sizes: Mapping[str, int]) -> tuple[int, ...]:
        """The concrete shape given the symbol sizes (e.g. {"N": 8, "T": 20, "M": 1})."""
        return tuple(d if isinstance(d, int) else sizes[d] for d in self.dims)


@dataclass(frozen=True)
class WarpExtra:
    """A Warp struct field that is not a container row: ``value(params)`` gives it at binding.
    ``ndim`` 0 makes a scalar field of type ``warp``, else an array of that many dimensions."""

    name: str
    warp: str
    ndim: int
    value: Callable[[Any], Any]
    doc: str = ""


def check_table(table: Sequence[ParamRow]) -> None:
    """Raise ValueError on duplicate names, a bad dtype, a per-env row not led by N or a derivation
    whose inputs are not earlier source rows."""
    seen: dict[str, ParamRow] = {}
    for row in table:
        if row.name in seen:
            raise ValueError(f"parameter {row.name!r} declared twice")
        if row.dtype not in TORCH_DTYPES:
            raise ValueError(f"parameter {row.name!r}: unknown dtype {row.dtype!r}")
        if row.per_env != (row.dims[:1] == ("N",)):
            raise ValueError(f"parameter {row.name!r}: per-env rows, and only they, start with N")
        if row.derived and row.randomizable:
            raise ValueError(f"parameter {row.name!r}: a derived row cannot be randomisable")
        if isinstance(row.source, Derivation):
            for name in row.source.inputs:
                if name not in seen or seen[name].derived:
                    raise ValueError(f"parameter {row.name!r}: input {name!r} is not an earlier source row")
        seen[row.name] = row


def check_randomizable(table: Sequence[ParamRow], names: Iterable[str]) -> None:
    """Raise KeyError for a name that is not a row, ValueError for one not flagged randomisable."""
    rows = {row.name: row for row in table}
    for name in names:
        if name not in rows:
            raise KeyError(f"unknown parameter {name!r}")
        if not rows[name].randomizable:
            allowed = [row.name for row in table if row.randomizable]
            raise ValueError(f"parameter {name!r} is not randomisable; randomisable: {allowed}")


# ------------------------------------------------------------------------------------ torch container
class ParameterSet:
    """Base of generated containers: one tensor attribute per row of ``TABLE``, nothing else (so
    ``vars(params)`` holds exactly the tensors)."""

    TABLE: ClassVar[tuple[ParamRow, ...]] = ()

    if TYPE_CHECKING:
        def __init__(self, **tensors: torch.Tensor) -> None: ...
        def __getattr__(self, name: str) -> torch.Tensor: ...

    @property
    def num_envs(self) -> int:
        return next(getattr(self, row.name) for row in self.TABLE if row.per_env).shape[0]

    def per_env_fields(self) -> list[str]:
        """Names of the per-env rows, in table order."""
        return [row.name for row in self.TABLE if row.per_env]

    def to(self, device: torch.device | str | None = None, dtype: torch.dtype | None = None) -> Any:
        """A copy on ``device``; floating rows also cast to ``dtype`` (integer and bool rows keep theirs)."""
        out = {}
        for row in self.TABLE:
            value = getattr(self, row.name)
            out[row.name] = value.to(device=device, dtype=dtype if value.is_floating_point() else None)
        return type(self)(**out)

    def assign(self, mask: torch.Tensor, *, randomizable_only: bool = False, **values: torch.Tensor) -> None:
        """Overwrite named per-env rows where ``mask`` [N] is True (in place; values broadcast to
        the row's [N, ...] shape), then recompute there the derived rows whose inputs were
        assigned. With ``randomizable_only`` a row not flagged randomisable raises ValueError."""
        per_env = self.per_env_fields()
        for name in values:
            if name not in per_env:
                raise KeyError(f"unknown per-env parameter {name!r}")
        if randomizable_only:
            check_randomizable(self.TABLE, values)
        for name, value in values.items():
            target = getattr(self, name)
            target[mask] = value.to(target.dtype).expand_as(target)[mask]
        for row in self.TABLE:
            if isinstance(row.source, Derivation) and not values.keys().isdisjoint(row.source.inputs):
                target = getattr(self, row.name)
                inputs = [getattr(self, name)[mask] for name in row.source.inputs]
                target[mask] = row.source.fn(*inputs).to(target.dtype)


def container_doc(table: Sequence[ParamRow], header: str) -> str:
    """``header`` followed by one line per row: name, shape, dtype, unit, doc."""
    width = max(len(row.name) for row in table)
    lines = [header, ""]
    for row in table:
        kind = "" if row.dtype == "float" else f" {row.dtype}"
        shared = "" if row.per_env else " (shared)"
        unit = f" {row.unit}" if row.unit else ""
        lines.append(f"    {row.name:<{width}} {row.shape}{kind}{unit}{shared}: {row.doc}".rstrip(": "))
    return "\n".join(lines) + "\n"


def make_container(table: Sequence[ParamRow], name: str, header: str, module: str) -> type[ParameterSet]:
    """A dataclass subclass of :class:`ParameterSet` with one ``torch.Tensor`` field per row."""
    check_table(table)
    namespace = {"TABLE": tuple(table), "__doc__": container_doc(table, header), "__module__": module}
    return dataclasses.make_dataclass(name, [(row.name, torch.Tensor) for row in table],
                                      bases=(ParameterSet,), namespace=namespace)


def build_values(table: Sequence[ParamRow], airframe: Airframe, sizes: Mapping[str, int],
                 options: BuildOptions, device: torch.device | str, dtype: torch.dtype
                 ) -> dict[str, torch.Tensor]:
    """Tensors of every row: per-env rows [N, ...] (N = ``sizes["N"]``, contiguous, each env its
    own copy), shared rows as declared. Float values and derivations are computed in float64 and
    then cast to ``dtype``."""
    nominal: dict[str, torch.Tensor] = {}
    for row in table:
        shape = row.resolve(sizes)[1 if row.per_env else 0:]
        if isinstance(row.source, Derivation):
            value = row.source.fn(*(nominal[name] for name in row.source.inputs))
        else:
            raw = row.source(airframe, options)
            value = torch.as_tensor(raw, dtype=torch.float64 if row.dtype == "float" else None)
        if tuple(value.shape) != shape and (value.numel() or math.prod(shape)):  # empty: M = 0 motors
            raise ValueError(f"parameter {row.name!r} has shape {tuple(value.shape)}, declared {shape}")
        nominal[row.name] = value.reshape(shape)
    out = {}
    for row in table:
        value = nominal[row.name].to(TORCH_DTYPES[row.dtype] or dtype)
        if row.per_env:
            value = value.unsqueeze(0).repeat(sizes["N"], *([1] * value.dim()))
        out[row.name] = value.to(device).contiguous()
    return out


# ---------------------------------------------------------------------------------------- warp struct
def warp_element(name: str, custom: Mapping[str, Any]) -> Any:
    """The Warp type named ``name``: a key of ``custom`` or an attribute of ``warp``."""
    return custom[name] if name in custom else getattr(wp, name)


def warp_annotation(row: ParamRow, custom: Mapping[str, Any]) -> Any:
    """The struct field type of ``row``: an array of its element type over the leading dimensions."""
    assert row.warp is not None
    element = warp_element(row.warp, custom)
    element_shape = tuple(getattr(element, "_shape_", ()))
    dims = row.dims
    trailing = dims[len(dims) - len(element_shape):] if element_shape else ()
    if len(element_shape) >= len(dims) or any(
            isinstance(d, int) and d != e for d, e in zip(trailing, element_shape, strict=True)):
        raise ValueError(f"parameter {row.name!r}: Warp type {row.warp} does not fit shape {row.shape}")
    return wp.array(dtype=element, ndim=len(dims) - len(element_shape))


def make_warp_struct(table: Sequence[ParamRow], extras: Sequence[WarpExtra], name: str, doc: str,
                     module: str, custom: Mapping[str, Any]) -> Any:
    """A ``wp.struct`` with one field per row that has a Warp type, then the ``extras`` (a plain
    class when Warp is missing). ``custom`` maps type names to Warp types (e.g. vector(6))."""
    annotations: dict[str, Any] = {}
    if wp is not None:
        for row in table:
            if row.warp is not None:
                annotations[row.name] = warp_annotation(row, custom)
        for extra in extras:
            element = warp_element(extra.warp, custom)
            annotations[extra.name] = element if extra.ndim == 0 else wp.array(dtype=element, ndim=extra.ndim)
    cls = type(name, (), {"__annotations__": annotations, "__doc__": doc, "__module__": module,
                          "__qualname__": name})
    return warp_struct(cls)


def bind_warp(struct: Any, table: Sequence[ParamRow], extras: Sequence[WarpExtra], params: ParameterSet,
              custom: Mapping[str, Any]) -> Any:
    """A ``struct`` instance viewing ``params``' float32, contiguous tensors zero-copy."""
    out = struct()
    for row in table:
        if row.warp is None:
            continue
        tensor = getattr(params, row.name)
        if tensor.is_floating_point() and tensor.dtype != torch.float32:
            raise TypeError(f"the warp backend runs in float32; {row.name} is {tensor.dtype}")
        if not tensor.is_contiguous():
            raise ValueError(f"parameter {row.name} must be contiguous to be bound zero-copy")
        element = warp_element(row.warp, custom)
        setattr(out, row.name, wp.from_torch(tensor, dtype=element if hasattr(element, "_shape_") else None))
    for extra in extras:
        setattr(out, extra.name, extra.value(params))
    return out


# ------------------------------------------------------------------------------------------ describe
def table_markdown(table: Sequence[ParamRow]) -> str:
    """A markdown table of the rows: name, shape, dtype, unit, randomisable, Warp type, doc."""
    lines = ["| name | shape | dtype | unit | randomisable | warp | doc |",
             "|---|---|---|---|---|---|---|"]
    for row in table:
        doc = row.doc
        if isinstance(row.source, Derivation):
            doc += f" (derived from {', '.join(row.source.inputs)})"
        lines.append(f"| `{row.name}` | {row.shape} | {row.dtype} | {row.unit} | "
                     f"{'yes' if row.randomizable else 'no'} | {row.warp or '-'} | {doc} |")
    return "\n".join(lines) + "\n"
