"""JSBSim ``<function>`` elements as NumPy expressions, for sampling an aircraft's aerodynamics.

A function is read once into a tree (:func:`parse_function`) and evaluated on a context that maps
property names to arrays (broadcast together). Supported: property, value, table (1-3D, JSBSim's
row/column/table lookup, clamped at the edges), product, sum, difference, quotient, abs, pow, sqrt,
min, max, sin, cos, tan, exp, lt/le/gt/ge (0/1), ifthen and lag-free ``integer``. Anything else
raises :class:`UnsupportedFunctionError` naming the element, so the importer can report the function by
name instead of dropping it.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

Context = Callable[[str], np.ndarray]


class UnsupportedFunctionError(ValueError):
    """A function element (or a property) the importer cannot evaluate."""


@dataclass(frozen=True)
class Table:
    """A JSBSim table: its independent variables (row, column, table) and breakpoints and data."""

    variables: tuple[str, ...]  # property names, lookup order row, column, table
    breakpoints: tuple[np.ndarray, ...]
    data: np.ndarray  # shape = breakpoint counts

    def __call__(self, context: Context) -> np.ndarray:
        out = self.data
        inputs = [np.asarray(context(v), dtype=np.float64) for v in self.variables]
        shape = np.broadcast_shapes(*(x.shape for x in inputs))
        grids = tuple(self.breakpoints)
        points = [np.broadcast_to(x, shape).reshape(-1) for x in inputs]
        return multilinear(grids, out, points).reshape(shape)


def multilinear(grids: tuple[np.ndarray, ...], data: np.ndarray, points: list[np.ndarray]) -> np.ndarray:
    """Multilinear interpolation of ``data`` on ``grids`` at ``points`` (one [P] array per axis), each
    axis clamped at its first and last breakpoint (JSBSim's table lookup)."""
    weights, cells = [], []
    for grid, x in zip(grids, points, strict=True):
        if grid.size == 1:
            cells.append(np.zeros(x.shape, dtype=int))
            weights.append(np.zeros(x.shape))
            continue
        xc = np.clip(x, grid[0], grid[-1])
        cell = np.clip(np.searchsorted(grid, xc, side="right") - 1, 0, grid.size - 2)
        cells.append(cell)
        weights.append((xc - grid[cell]) / (grid[cell + 1] - grid[cell]))
    out = np.zeros(points[0].shape if points else ())
    for corner in range(2 ** len(grids)):
        w = np.ones_like(out)
        index = []
        for a in range(len(grids)):
            upper = (corner >> a) & 1
            w = w * (weights[a] if upper else 1.0 - weights[a])
            index.append(np.minimum(cells[a] + upper, grids[a].size - 1))
        out = out + w * data[tuple(index)]
    return out


@dataclass(frozen=True)
class Node:
    """One element of a function tree: an operation over its children, a property or a value."""

    op: str
    children: tuple[Node, ...] = ()
    name: str = ""
    value: float = 0.0
    table: Table | None = None
    properties: frozenset[str] = field(default_factory=frozenset)

    def __call__(self, context: Context) -> np.ndarray:
        op = self.op
        if op == "property":
            return np.asarray(context(self.name), dtype=np.float64)
        if op == "value":
            return np.asarray(self.value)
        if op == "table":
            assert self.table is not None
            return self.table(context)
        args = [c(context) for c in self.children]
        return _OPERATIONS[op](args)


def _fold(fn: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> Callable[[list[np.ndarray]], np.ndarray]:
    def run(args: list[np.ndarray]) -> np.ndarray:
        out = args[0]
        for a in args[1:]:
            out = fn(out, a)
        return out

    return run


_OPERATIONS: Mapping[str, Callable[[list[np.ndarray]], np.ndarray]] = {
    "product": _fold(np.multiply),
    "sum": _fold(np.add),
    "difference": _fold(np.subtract),
    "quotient": _fold(np.divide),
    "max": _fold(np.maximum),
    "min": _fold(np.minimum),
    "pow": lambda a: np.power(a[0], a[1]),
    "abs": lambda a: np.abs(a[0]),
    "sqrt": lambda a: np.sqrt(a[0]),
    "sin": lambda a: np.sin(a[0]),
    "cos": lambda a: np.cos(a[0]),
    "tan": lambda a: np.tan(a[0]),
    "exp": lambda a: np.exp(a[0]),
    "integer": lambda a: np.trunc(a[0]),
    "lt": lambda a: (a[0] < a[1]).astype(float),
    "le": lambda a: (a[0] <= a[1]).astype(float),
    "gt": lambda a: (a[0] > a[1]).astype(float),
    "ge": lambda a: (a[0] >= a[1]).astype(float),
    "ifthen": lambda a: np.where(a[0] != 0, a[1], a[2]),
}


def parse_table(element: ET.Element) -> Table:
    """A ``<table>`` element (1-3D)."""
    lookups = {"row": 0, "column": 1, "table": 2}
    variables: dict[int, str] = {}
    for iv in element.findall("independentVar"):
        variables[lookups[iv.get("lookup", "row")]] = (iv.text or "").strip()
    datas = element.findall("tableData")
    if not datas or not variables:
        raise UnsupportedFunctionError("table without tableData or independentVar")
    if len(variables) == 1:
        rows = _numbers(datas[0].text)
        grid = rows.reshape(-1, 2)
        return Table((variables[0],), (grid[:, 0],), grid[:, 1])
    pages, page_breaks = [], []
    for data in datas:
        lines = [line.split() for line in (data.text or "").strip().splitlines() if line.split()]
        columns = np.array(lines[0], dtype=float)
        body = np.array(lines[1:], dtype=float)
        pages.append((body[:, 0], columns, body[:, 1:]))
        page_breaks.append(float(data.get("breakPoint", "0")))
    if len(variables) == 2:
        rows, columns, values = pages[0]
        return Table((variables[0], variables[1]), (rows, columns), values)
    rows, columns = pages[0][0], pages[0][1]
    cube = np.stack([p[2] for p in pages], axis=-1)
    return Table((variables[0], variables[1], variables[2]), (rows, columns, np.array(page_breaks)), cube)


def _numbers(text: str | None) -> np.ndarray:
    return np.array((text or "").split(), dtype=float)


def parse_function(element: ET.Element) -> Node:
    """The tree of a ``<function>`` element (its single child operation)."""
    children = [c for c in element if c.tag not in ("description",)]
    if len(children) != 1:
        raise UnsupportedFunctionError(f"function with {len(children)} top-level elements")
    return parse_node(children[0])


def parse_node(element: ET.Element) -> Node:
    tag = element.tag
    if tag == "property":
        name = (element.text or "").strip()
        return Node("property", name=name, properties=frozenset({name}))
    if tag == "value":
        return Node("value", value=float((element.text or "0").strip()))
    if tag == "table":
        table = parse_table(element)
        return Node("table", table=table, properties=frozenset(table.variables))
    if tag not in _OPERATIONS:
        raise UnsupportedFunctionError(f"element <{tag}>")
    children = tuple(parse_node(c) for c in element if c.tag != "description")
    props = frozenset().union(*(c.properties for c in children)) if children else frozenset()
    return Node(tag, children, properties=props)


def table_breakpoints(node: Node) -> dict[str, np.ndarray]:
    """Property -> the union of the breakpoints of the tables indexed by it, within ``node``."""
    out: dict[str, np.ndarray] = {}
    stack = [node]
    while stack:
        n = stack.pop()
        if n.table is not None:
            for name, bp in zip(n.table.variables, n.table.breakpoints, strict=True):
                out[name] = np.union1d(out.get(name, np.array([])), bp)
        stack.extend(n.children)
    return out
