"""Small builders for JSBSim XML: function trees, triplets and coordinates (the unit conversions
are ``falcon_rl.constants``).

A function tree is written as nested tuples: ``("sum", a, b)`` becomes ``<sum>a b</sum>``, a
``str`` leaf is a ``<property>`` and a number leaf a ``<value>``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from ..constants import IN

Expr = str | float | int | tuple


def expr(parent: ET.Element, node: Expr) -> ET.Element:
    """Append the function tree ``node`` under ``parent``; returns the new element."""
    if isinstance(node, str):
        el = ET.SubElement(parent, "property")
        el.text = node
        return el
    if isinstance(node, int | float):
        el = ET.SubElement(parent, "value")
        el.text = f"{float(node):.17g}"
        return el
    tag, *children = node
    el = ET.SubElement(parent, tag)
    for child in children:
        expr(el, child)
    return el


def function(parent: ET.Element, name: str | None, node: Expr, description: str = "") -> ET.Element:
    """``<function name=...>`` holding ``node``; ``name`` is the property it publishes."""
    el = ET.SubElement(parent, "function", {"name": name} if name else {})
    if description:
        ET.SubElement(el, "description").text = description
    expr(el, node)
    return el


def text(parent: ET.Element, tag: str, value: float | str, unit: str | None = None) -> ET.Element:
    """``<tag unit=...>value</tag>``."""
    el = ET.SubElement(parent, tag, {"unit": unit} if unit else {})
    el.text = value if isinstance(value, str) else f"{float(value):.17g}"
    return el


def triplet(parent: ET.Element, tag: str, xyz: tuple[float, float, float], unit: str | None = None,
            **attrs: str) -> ET.Element:
    """``<tag unit=... attrs><x/><y/><z/></tag>``."""
    el = ET.SubElement(parent, tag, {**({"unit": unit} if unit else {}), **attrs})
    for axis, value in zip("xyz", xyz, strict=True):
        text(el, axis, value)
    return el


def clamp(node: Expr, lo: float, hi: float) -> tuple:
    """max(min(node, hi), lo)."""
    return ("max", ("min", node, hi), lo)


def body_to_structural_in(xyz_m: tuple[float, float, float]) -> tuple[float, float, float]:
    """Body FRD offset from the CG (m) -> JSBSim structural frame (x aft, y right, z up), inches,
    with the CG at the structural origin."""
    x, y, z = xyz_m
    return (-x / IN, y / IN, -z / IN)
