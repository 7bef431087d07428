"""A URDF's ``<visual>`` elements, read: what each link looks like, as the URDF says it (origin,
geometry and colour), for whatever draws the arm (:mod:`akarm.view`, the simulated camera
:mod:`akarm.sim.camera`).

:func:`read_visuals` reads the ``<visual>`` elements of the links that are direct children of
``<robot>`` (as :mod:`akarm.config.urdf` reads joints and links): origin, geometry (``box``,
``cylinder``, ``sphere`` or ``mesh``) and colour (an inline ``<material>`` or one named at the robot
level). Turning them into triangles is the view's (:func:`akarm.view.visuals.visual_mesh`).
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from akarm.errors import ModelError

__all__ = ["KINDS", "Visual", "origin_matrix", "read_visuals"]

#: the geometry elements of the URDF specification that akarm draws
KINDS = ("box", "cylinder", "sphere", "mesh")


@dataclass(frozen=True)
class Visual:
    """One ``<visual>`` of a link.

    Attributes:
        link: the link it belongs to. index: its place among that link's visuals (0, 1, ...).
        origin: 4×4 transform from the link's frame to the geometry's, m.
        kind: ``box``, ``cylinder``, ``sphere`` or ``mesh``.
        size: box (x, y, z) m; cylinder (radius, length) m; sphere (radius,) m; mesh its scale (x, y, z).
        filename: a mesh's ``filename`` as written (``""`` for primitives).
        rgba: its colour, 0-1, or ``None`` when the URDF gives none.
    """

    link: str
    index: int
    origin: np.ndarray
    kind: str
    size: tuple[float, ...]
    filename: str = ""
    rgba: tuple[float, float, float, float] | None = None


def _numbers(text: str | None, n: int, default: tuple[float, ...]) -> tuple[float, ...]:
    if text is None:
        return default
    try:
        values = tuple(float(x) for x in text.split())
    except ValueError:
        return default
    if len(values) == 1 and n == 3:  # a uniform mesh scale written once
        values = values * 3
    return values if len(values) == n and all(math.isfinite(x) for x in values) else default


def origin_matrix(xyz: tuple[float, ...], rpy: tuple[float, ...]) -> np.ndarray:
    """The 4×4 transform of a URDF ``<origin xyz rpy>``: rotation ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    m = np.eye(4)
    m[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                 [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                 [-sp, cp * sr, cp * cr]]
    m[:3, 3] = xyz
    return m


def _rgba(material: ET.Element | None, named: Mapping[str, tuple[float, float, float, float]]
          ) -> tuple[float, float, float, float] | None:
    if material is None:
        return None
    color = material.find("color")
    if color is not None:
        rgba = _numbers(color.get("rgba"), 4, ())
        if len(rgba) == 4:
            return (rgba[0], rgba[1], rgba[2], rgba[3])
    return named.get(material.get("name", ""))


def read_visuals(path: str | os.PathLike[str]) -> list[Visual]:
    """Every ``<visual>`` of the robot's links, in file order. A visual without a geometry akarm
    draws (none, or an unknown element) is left out.

    Raises:
        ModelError: the file cannot be read or is not XML.
    """
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as e:
        raise ModelError(f"cannot read the visuals of URDF {path}: {e}", fix="check the URDF (akarm check)") from None
    named: dict[str, tuple[float, float, float, float]] = {}
    for m in root.findall("material"):
        rgba = _rgba(m, {})
        if rgba is not None:
            named[m.get("name", "")] = rgba
    out: list[Visual] = []
    for link in root.findall("link"):
        name = link.get("name", "")
        for k, vis in enumerate(link.findall("visual")):
            o = vis.find("origin")
            origin = origin_matrix(_numbers(o.get("xyz") if o is not None else None, 3, (0.0, 0.0, 0.0)),
                                   _numbers(o.get("rpy") if o is not None else None, 3, (0.0, 0.0, 0.0)))
            geometry = vis.find("geometry")
            shape = next((g for g in (geometry if geometry is not None else []) if g.tag in KINDS), None)
            if shape is None:
                continue
            rgba = _rgba(vis.find("material"), named)
            if shape.tag == "box":
                size = _numbers(shape.get("size"), 3, (0.0, 0.0, 0.0))
            elif shape.tag == "cylinder":
                size = (float(shape.get("radius", 0) or 0), float(shape.get("length", 0) or 0))
            elif shape.tag == "sphere":
                size = (float(shape.get("radius", 0) or 0),)
            else:
                size = _numbers(shape.get("scale"), 3, (1.0, 1.0, 1.0))
            out.append(Visual(name, k, origin, shape.tag, size, shape.get("filename", ""), rgba))
    return out
