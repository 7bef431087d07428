"""Robot YAML → :class:`~akarm.config.RobotConfig`, validated in one pass.

A robot is described once, in a YAML file next to its URDF; ``docs/robot-file.md`` lists every key
(written from :mod:`akarm.robotfile.schema`, the format's one description). :func:`load_robot`:

1. reads the file as YAML nodes, which keep their lines (:mod:`akarm.robotfile.nodes`);
2. reads those with the schema: unknown keys, wrong types, values out of range, missing keys
   (:mod:`akarm.robotfile.schema`);
3. checks what depends on more than one value: the URDF, the motor catalogue, limits against the
   motors, CAN IDs, the bus load, locked and mimic joints, gravity (:mod:`akarm.robotfile.checks`).

Every problem found is collected, with its file, 1-based line and a fix, and raised together as one
:class:`~akarm.ConfigError`; YAML syntax errors and URDF parse errors become problems too.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

from akarm.config import RobotConfig
from akarm.config.urdf import UrdfJoint, read_urdf
from akarm.errors import ConfigError, ConfigProblem, ConfigWarning
from akarm.protocol.motors import Catalogue, default_catalogue
from akarm.robotfile import checks
from akarm.robotfile.nodes import Findings, compose
from akarm.robotfile.schema import INVALID, ROBOT_FILE, Context, Fields

__all__ = ["UrdfJoint", "load_robot", "read_urdf_joints"]


def read_urdf_joints(path: Path) -> tuple[dict[str, UrdfJoint], set[str]]:
    """Joints (by name, in file order) and link names of a URDF: the robot's own, not those named in
    ``<transmission>``, ``<gazebo>`` or ``<ros2_control>`` blocks (see :func:`akarm.config.urdf.read_urdf`).

    Raises:
        ValueError: the file is not a URDF, or has problems; the message says where.
        OSError: the file cannot be read.
    """
    if not Path(path).is_file():
        raise FileNotFoundError(f"URDF {path} not found")
    urdf, found = read_urdf(path)
    if found:
        raise ValueError("; ".join(f"URDF line {p.line}: {p.message}" if p.line else p.message for p in found))
    assert urdf is not None
    return dict(urdf.joints), set(urdf.links)


def load_robot(
    path: str | os.PathLike[str],
    *,
    interface: str | None = None,
    channel: str | Mapping[str, str] | None = None,
    bitrate: int | None = None,
    rate_hz: float | None = None,
    catalogue: Catalogue | None = None,
) -> RobotConfig:
    """Read and validate a robot YAML file.

    Args:
        path: the robot YAML (its ``urdf:`` is relative to it).
        interface, channel, bitrate: bus overrides, applied with :meth:`RobotConfig.with_bus`
            (``channel`` may map bus names to channels).
        rate_hz: loop-rate override, Hz (validated against the bus load like the file's own).
        catalogue: the motor catalogue to start from (default: :func:`akarm.protocol.motors.default_catalogue`).

    Returns:
        the configuration; ``config.warnings`` lists what was accepted with a warning (URDF joints held
        at a default position, gravity above a motor's rated torque), each with its line and fix.

    Warns:
        ConfigWarning: for each URDF joint held at a default position (the file does not say where).

    Raises:
        ConfigError: listing every problem found, each with file, line and fix.
    """
    p = Path(path)
    found = Findings(str(p))
    config = _load(p, found, rate_hz, catalogue if catalogue is not None else default_catalogue())
    for w in found.issued:
        warnings.warn(str(w), ConfigWarning, stacklevel=2)
    if interface is not None or channel is not None or bitrate is not None:
        config = config.with_bus(interface=interface, channel=channel, bitrate=bitrate)
    return config


def _load(path: Path, found: Findings, rate_override: float | None, cat: Catalogue) -> RobotConfig:
    root = compose(path)
    if root is None:
        raise ConfigError([ConfigProblem(str(path), None, "the robot file is empty",
                                         "describe the robot: name, urdf, joints (see docs/robot-file.md)")])
    top = ROBOT_FILE.read(root, "", "", found, Context())
    if top is INVALID:
        found.raise_if_any()
    urdf_path, urdf = checks.urdf_file(found, top.get("urdf"), path.parent)
    cat, failed = checks.catalogue(found, top.get("motors"), cat)
    buses = checks.buses(found, top.get("buses"))
    rate_hz, rate_line = checks.rate(found, top.get("rate_hz"), rate_override)
    tool_frame = checks.tool_frame(found, top.get("tool_frame"), urdf)
    joints = checks.Joints(found, buses, cat, failed, urdf)
    configs = joints.read(top.get("joints"), top.value("defaults", Fields()))
    at = top["joints"].key if "joints" in top and top["joints"].ok else root
    gripper = checks.gripper(found, top.get("gripper"), joints, urdf)
    fingers = set(gripper.fingers) if gripper is not None else set()
    locked = checks.locked(found, top.get("locked"), urdf, joints.driven, at, fingers) if urdf is not None else {}
    poses = checks.poses(found, top.get("poses"), configs, joints.entries)
    walls = checks.workspace(found, top.get("workspace"))
    motors = configs + ([gripper.joint] if gripper is not None else [])  # the gripper's motor loads its bus too
    checks.bus_load(found, buses, motors, rate_hz, rate_line)
    checks.serial_ports(found, buses, motors, top.get("buses"))
    found.raise_if_any()
    assert urdf_path is not None and rate_hz is not None
    g = top.value("gravity", ROBOT_FILE["gravity"].default)
    config = RobotConfig(name=top.value("name", path.stem), urdf=urdf_path, buses=buses, joints=tuple(configs),
                         rate_hz=rate_hz, source=path, tool_frame=tool_frame, gravity=(g[0], g[1], g[2]),
                         payload=checks.payload(top.get("payload")), poses=poses, catalogue=cat, locked=locked,
                         gripper=gripper, workspace=walls,
                         self_collision=checks.self_collision(top.get("self_collision")))
    checks.gravity(found, config, top.get("urdf"), joints.torque_lines)
    found.raise_if_any()
    return replace(config, warnings=tuple(found.sorted(found.warnings)))
