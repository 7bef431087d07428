"""A URDF's ``<visual>`` elements: what each link looks like, as triangle meshes in the link's frame.

:func:`read_visuals` (:mod:`akarm.config.visuals`, re-exported here) reads the ``<visual>`` elements
of the links that are direct children of ``<robot>``: origin, geometry (``box``, ``cylinder``,
``sphere`` or ``mesh``) and colour. :func:`visual_mesh` turns one into triangles: primitives are
built, mesh files are loaded with trimesh (STL, OBJ, PLY, and COLLADA ``.dae`` with pycollada, all in
the ``view`` extra) from where :func:`resolve_mesh` finds them (``package://``, ``file://``, or a path
relative to the URDF).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from akarm.config.visuals import KINDS, Visual, origin_matrix, read_visuals
from akarm.errors import ModelError

if TYPE_CHECKING:
    import trimesh

__all__ = ["KINDS", "Visual", "origin_matrix", "read_visuals", "resolve_mesh", "visual_mesh"]


def _env_dirs(variable: str, suffix: tuple[str, ...] = ()) -> Iterator[Path]:
    for entry in os.environ.get(variable, "").split(os.pathsep):
        if entry:
            yield Path(entry, *suffix)


def resolve_mesh(filename: str, urdf: str | os.PathLike[str]) -> Path | None:
    """Where the mesh ``filename`` of ``urdf`` is, or ``None``.

    ``package://PKG/rest`` is looked for as ROS does (``ROS_PACKAGE_PATH``, then
    ``AMENT_PREFIX_PATH``/``share/PKG``), then up from the URDF's folder: a folder named PKG, or one
    holding ``PKG/`` or ``share/PKG/`` (a package installed or checked out around the URDF). ``file://``
    is a path; anything else is relative to the URDF's folder.
    """
    base = Path(urdf).resolve().parent
    if filename.startswith("file://"):
        p = Path(filename[len("file://"):])
        return p if p.is_file() else None
    if not filename.startswith("package://"):
        p = Path(filename)
        p = p if p.is_absolute() else base / p
        return p if p.is_file() else None
    package, _, rest = filename[len("package://"):].partition("/")
    candidates: list[Path] = []
    for d in _env_dirs("ROS_PACKAGE_PATH"):
        candidates += [d / package, d] if d.name == package else [d / package]
    candidates += list(_env_dirs("AMENT_PREFIX_PATH", ("share", package)))
    for up in (base, *base.parents):
        candidates += [up] if up.name == package else []
        candidates += [up / package, up / "share" / package]
    for root in candidates:
        p = root / rest
        if p.is_file():
            return p
    return None


def visual_mesh(visual: Visual, urdf: str | os.PathLike[str]) -> trimesh.Trimesh:
    """The triangles of ``visual`` in its link's frame (its origin applied), m.

    Raises:
        ModelError: a mesh file that is not found or cannot be loaded, or a primitive of no size.
    """
    import trimesh

    if visual.kind == "box":
        if min(visual.size) <= 0:
            raise ModelError(f"link {visual.link!r}: a box of size {visual.size}", fix="give three positive sizes, m")
        mesh = trimesh.creation.box(extents=visual.size)
    elif visual.kind == "cylinder":
        radius, length = visual.size
        if radius <= 0 or length <= 0:
            raise ModelError(f"link {visual.link!r}: a cylinder of radius {radius} and length {length}",
                             fix="give a positive radius and length, m")
        mesh = trimesh.creation.cylinder(radius=radius, height=length, sections=24)
    elif visual.kind == "sphere":
        if visual.size[0] <= 0:
            raise ModelError(f"link {visual.link!r}: a sphere of radius {visual.size[0]}", fix="give a positive radius")
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=visual.size[0])
    else:
        path = resolve_mesh(visual.filename, urdf)
        if path is None:
            raise ModelError(f"link {visual.link!r}: mesh {visual.filename} not found",
                             fix="install its package (or set ROS_PACKAGE_PATH), or give a path relative to the URDF")
        try:
            loaded = trimesh.load(path, force="mesh")
        except Exception as e:  # trimesh raises what its loaders raise (a missing pycollada, a bad file)
            raise ModelError(f"link {visual.link!r}: cannot load mesh {path}: {e}",
                             fix="STL, OBJ, PLY and COLLADA (.dae, with pycollada) are read") from None
        if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
            raise ModelError(f"link {visual.link!r}: mesh {path} holds no triangles", fix="export it as a mesh")
        mesh = loaded
        mesh.apply_scale(visual.size)
    mesh.apply_transform(visual.origin)
    return mesh
