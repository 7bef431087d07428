"""A starting robot file for a URDF (``akarm init``): every joint, a motor per joint, limits, gains,
poses and the bus load, each suggestion commented as one.

:func:`suggest` reads the URDF (as the loader does: only the robot's own joints and links) and works
out, per movable joint in chain order:

- **driven or locked**: revolute and continuous joints are driven (CAN IDs 1..n on one bus); other
  joints (a gripper's prismatic fingers), and joints that others ``<mimic>`` (a gripper's finger
  joint, moved by the gripper's own motor), are held under ``locked:``; ``<mimic>`` joints follow;
- **range**: the URDF's, within the motors' MIT position range (±12.5 rad); continuous joints ±π;
- **gravity**: the largest gravity torque over the ranges (:mod:`akarm.dynamics.gravity`), with ``payload``
  kg at the tool frame;
- **motor**: the smallest catalogue model (by rated torque, then mass) whose rated (continuous)
  torque covers ``margin`` × that gravity, plus the torque to accelerate the joint's largest
  inertia at :data:`A_REF`; failing that the smallest whose range ``t_max`` holds the gravity
  (with the margin if one does), failing that the strongest (and :attr:`Suggestion.short` names the
  joint: ``akarm check`` will refuse the file);
- **gains**: kp for a natural frequency of :data:`F_NATURAL` with the joint's largest inertia (motor
  rotor included), lower where kd's range (5 N·m·s/rad) could not damp that critically; kd for
  critical damping. kp is raised where needed to keep the static error under :data:`STATIC_ERROR`
  against 10 % of the joint's gravity torque (the feed-forward carries the rest), which leaves heavy
  joints below critical damping; the comment says how far;
- **limits**: velocity a quarter of the motor's (at most 2 rad/s, and the URDF's); acceleration what
  half the motor's ``t_max`` left over from gravity gives the largest inertia (1-10 rad/s²); jerk
  ten times that;
- **rate**: 500 Hz, or the highest multiple of 50 Hz whose worst-case bus load stays under 80 %;
- **poses**: ``zero`` (every joint at 0, within its range) and ``rest`` (of sampled poses at least
  :data:`REST_DISTANCE` from ``zero``, the one with the least gravity load on the rated torques).

The result loads with :func:`akarm.load_robot` and passes ``akarm check`` unless a joint is short of
torque (:attr:`Suggestion.short`).
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from akarm._version import __version__
from akarm.config import BusConfig, Gains, GripperConfig, JointConfig, Limits, Payload, RobotConfig
from akarm.config.busload import LOAD_LIMIT, load_of
from akarm.config.urdf import Urdf, UrdfJoint, pinocchio_complaint, read_urdf
from akarm.dynamics.gravity import GravityPeak, gravity_peaks, sample_box
from akarm.errors import ConfigError, ConfigProblem
from akarm.files import over
from akarm.protocol.motors import Catalogue, MotorModel, default_catalogue
from akarm.robotfile.nodes import MAX_JOINTS
from akarm.robotfile.schema import JOINT, PAYLOAD, ROBOT_FILE, Section

__all__ = ["A_REF", "F_NATURAL", "JointSuggestion", "Suggestion", "suggest"]

#: Hz: the natural frequency the suggested kp gives each joint (with its largest inertia)
F_NATURAL = 4.0
#: rad/s²: the acceleration a suggested motor can hold continuously on top of gravity
A_REF = 2.0
#: rad: static error the suggested kp keeps under, against 10 % of the joint's gravity torque
STATIC_ERROR = 0.05
#: rad: the motors' MIT position range (every v2 catalogue model's p_max)
P_MAX = 12.5
#: rad: how far from ``zero`` (in some joint) the suggested ``rest`` pose is at least
REST_DISTANCE = 0.3


@dataclass(frozen=True)
class JointSuggestion:
    """What :func:`suggest` chose for one driven joint (SI units).

    Attributes:
        urdf: the URDF joint.
        lower, upper: the suggested range, rad.
        gravity: the largest gravity torque over the ranges (payload included), N·m, and where.
        inertia: the largest inertia the joint moves (its diagonal of the mass matrix, motor rotor
            included), kg·m².
        motor: the suggested model; ``covered``: ``"rated"``, ``"peak"`` or ``""`` (not covered).
        needed: the rated torque asked of it, N·m.
        kp, kd: suggested gains. velocity, acceleration, jerk: suggested limits.
    """

    urdf: UrdfJoint
    lower: float
    upper: float
    gravity: GravityPeak
    inertia: float
    motor: MotorModel
    covered: str
    needed: float
    kp: float
    kd: float
    velocity: float
    acceleration: float
    jerk: float


@dataclass(frozen=True)
class Suggestion:
    """A starting robot file and what went into it.

    Attributes:
        text: the YAML, commented.
        joints: per driven joint, in chain order.
        locked: URDF joints held still, and where (rad or m).
        tool_frame: the suggested tool frame.
        rate_hz: the suggested loop rate.
        short: names of joints no catalogue motor covers (``akarm check`` will refuse the file).
    """

    text: str
    joints: tuple[JointSuggestion, ...]
    locked: dict[str, float] = field(default_factory=dict)
    tool_frame: str | None = None
    rate_hz: float = 500.0
    short: tuple[str, ...] = ()


def _problems(path: Path, found: list[tuple[int | None, str, str]]) -> ConfigError:
    return ConfigError([ConfigProblem(str(path), line, message, fix) for line, message, fix in found])


def _candidates(cat: Catalogue) -> list[MotorModel]:
    """Catalogue models to choose from: the base models (not firmware variants), with known torques."""
    out = [cat.get(n) for n in cat.names() if re.fullmatch(r"AK\d+-\d+", n)]
    return [m for m in out if m.rated_torque is not None and m.firmware == "v2"]


def _choose_motor(needed: float, gravity: float, margin: float, models: list[MotorModel]
                  ) -> tuple[MotorModel, str]:
    """The smallest model whose rated torque covers ``needed``; else whose range covers the gravity
    with the margin, else at all; else the strongest (``covered`` is then ``""``)."""
    by_rated = sorted(models, key=lambda m: (m.rated_torque or 0.0, m.mass or 0.0))
    for m in by_rated:
        if (m.rated_torque or 0.0) >= needed:
            return m, "rated"
    by_peak = sorted(models, key=lambda m: (m.t_max, m.mass or 0.0))
    for factor in (margin, 1.0):
        for m in by_peak:
            if m.t_max >= factor * gravity:
                return m, "peak"
    return by_peak[-1], ""


def _tool_frame(urdf: Urdf, driven: list[UrdfJoint]) -> str | None:
    """The link at the end of the driven chain: past the last driven joint, through fixed joints only,
    preferring a link named like a tool point (tcp, tool, flange, ee), else the farthest."""
    if not driven:
        return None
    children: dict[str, list[UrdfJoint]] = {}
    for j in urdf.joints.values():
        children.setdefault(j.parent, []).append(j)
    reach: list[tuple[int, str]] = []
    todo = [(0, driven[-1].child)]
    while todo:
        depth, link = todo.pop()
        reach.append((depth, link))
        todo.extend((depth + 1, j.child) for j in children.get(link, []) if j.type == "fixed")
    for word in ("tcp", "tool", "flange", "ee"):
        named = [(d, n) for d, n in reach if word in n.lower()]
        if named:
            return max(named)[1]
    return max(reach)[1]


def _round(x: float, digits: int = 2) -> float:
    """``x`` to ``digits`` significant digits."""
    if x == 0 or not math.isfinite(x):
        return x
    return round(x, digits - 1 - math.floor(math.log10(abs(x))))


def _held_at(j: UrdfJoint) -> float:
    """Where a joint no motor drives is held: 0, or the limit nearest it, as :func:`_num` prints it
    (6 decimals), rounded into the range: printed, it must not pass the URDF's limits."""
    if j.lower is None or j.upper is None:
        return 0.0
    lo, hi = math.ceil(round(j.lower * 1e6, 6)) / 1e6, math.floor(round(j.upper * 1e6, 6)) / 1e6
    return min(max(lo, round(min(max(0.0, j.lower), j.upper), 6)), hi)


def _num(x: float) -> str:
    """A number for the YAML: up to 6 decimals, no exponent (YAML 1.1 reads ``1e-05`` as text)."""
    text = f"{x:.6f}".rstrip("0").rstrip(".")
    return "0.0" if text in ("0", "-0", "") else text


def _name(text: str) -> str:
    """A YAML scalar for a name: quoted when YAML would read it as something else."""
    try:
        if yaml.safe_load(text) == text and ":" not in text and "#" not in text:
            return text
    except yaml.YAMLError:
        pass
    return json.dumps(text)


def _driven(path: Path, movable: list[UrdfJoint]) -> list[UrdfJoint]:
    """The joints a motor drives: revolute and continuous ones, not a ``<mimic>`` nor one others mimic
    (a gripper's, a Robotiq's finger_joint: its own motor, not an AK; held).

    Raises:
        ConfigError: none, or more than :data:`~akarm.robotfile.nodes.MAX_JOINTS` (before Pinocchio is asked).
    """
    mimicked = {j.mimic.joint for j in movable if j.mimic is not None}
    driven = [j for j in movable if j.type in ("revolute", "continuous") and j.mimic is None and j.name not in mimicked]
    if not driven:
        raise _problems(path, [(None, "the URDF has no revolute or continuous joint for a motor to drive",
                                "akarm drives revolute and continuous joints")])
    if len(driven) > MAX_JOINTS:
        raise _problems(path, [(driven[MAX_JOINTS].line, over(f"the URDF has {len(driven)} revolute and continuous "
                                                              "joints for motors to drive", MAX_JOINTS, "joints",
                                                              "MAX_JOINTS"),
                                f"a robot file drives at most {MAX_JOINTS}: make the joints no motor drives fixed "
                                "in a copy of the URDF, or split the robot")])
    return driven


def suggest(urdf_path: str | os.PathLike[str], output: str | os.PathLike[str], *, payload: float = 0.0,
            margin: float = 1.5, catalogue: Catalogue | None = None, gripper: bool = False) -> Suggestion:
    """A starting robot file for ``urdf_path``, to be written at ``output`` (its ``urdf:`` is relative to it).

    Args:
        urdf_path: the robot's URDF.
        output: where the YAML will be written (only its folder matters here).
        payload: kg at the tool frame the motors must hold too.
        margin: the motors' rated torque must cover ``margin`` × the gravity torque (≥ 1).
        gripper: add a `gripper:` entry (its motor on the bus too): fingers, the URDF's prismatic joints
            no motor of the arm drives; stroke, their travel added up (80 mm without any).

    Raises:
        ConfigError: the URDF has problems (each at its line), or has no joint a motor can drive.
    """
    path = Path(urdf_path).resolve()
    cat = catalogue if catalogue is not None else default_catalogue()
    if not math.isfinite(payload) or payload < 0 or not math.isfinite(margin) or margin < 1:
        raise ConfigError([ConfigProblem(str(path), None, f"payload {payload:g} kg and margin {margin:g} must be "
                                         "≥ 0 and ≥ 1", "e.g. --payload 0.5 --margin 1.5")])
    if not path.is_file():
        raise _problems(path, [(None, "URDF file not found", "check the path")])
    urdf, found = read_urdf(path)
    if urdf is None or found:
        raise _problems(path, [(p.line, p.message, p.fix) for p in found])
    movable = urdf.movable
    driven = _driven(path, movable)
    complaint = pinocchio_complaint(path)
    if complaint is not None:
        raise _problems(path, [(None, f"not a valid robot model: {complaint}", "fix the URDF")])
    held = {j.name: _held_at(j) for j in movable if j not in driven and j.mimic is None
            and j.type in ("revolute", "continuous", "prismatic")}
    locked = dict(held)
    for _ in movable:  # mimic joints follow their (locked) masters
        for j in movable:
            if j.mimic is not None and j.mimic.joint in locked and j.name not in locked:
                locked[j.name] = j.mimic.multiplier * locked[j.mimic.joint] + j.mimic.offset
    ranges = []
    for j in driven:  # (rounded inwards to 4 decimals: printed, they must not pass the URDF's)
        if j.type == "continuous" or j.lower is None or j.upper is None:
            lo, hi = -math.pi, math.pi
        else:
            lo, hi = max(j.lower, -P_MAX), min(j.upper, P_MAX)
        ranges.append((math.ceil(round(lo * 1e4, 6)) / 1e4, math.floor(round(hi * 1e4, 6)) / 1e4))
    tool = _tool_frame(urdf, driven)

    # a provisional arm (the strongest motor everywhere) to compute gravity and inertia with
    strongest = max(_candidates(cat), key=lambda m: m.t_max)
    provisional = RobotConfig(
        name=urdf.name, urdf=path, buses={"arm": BusConfig("arm")},
        joints=tuple(JointConfig(name=j.name, bus="arm", can_id=k + 1, motor=strongest, mode="mit",
                                 limits=Limits(lo, hi, 1.0, 1.0, 1.0, strongest.t_max))
                     for k, (j, (lo, hi)) in enumerate(zip(driven, ranges, strict=True))),
        tool_frame=tool, payload=Payload(payload) if payload else None, locked=locked)
    from akarm.dynamics.model import RobotModel

    model = RobotModel(provisional)
    peaks = gravity_peaks(provisional)
    lower = np.array([r[0] for r in ranges])
    upper = np.array([r[1] for r in ranges])
    samples = sample_box(lower, upper, 64, seed=2)
    inertia = np.max([np.diag(model.mass_matrix(q)) for q in samples], axis=0)

    models = _candidates(cat)
    joints: list[JointSuggestion] = []
    for k, (j, (lo, hi), peak) in enumerate(zip(driven, ranges, peaks, strict=True)):
        needed = margin * peak.torque + A_REF * float(inertia[k])
        motor, covered = _choose_motor(needed, peak.torque, margin, models)
        inertia_k = float(inertia[k]) + motor.reflected_inertia
        w = min(2 * math.pi * F_NATURAL, motor.kd_max / (2.0 * inertia_k))  # critically damped within kd_max
        kp = _round(min(motor.kp_max, max(inertia_k * w * w, 0.1 * peak.torque / STATIC_ERROR, 0.5)))
        kd = _round(min(motor.kd_max, max(0.01, 2.0 * math.sqrt(kp * inertia_k))))
        velocity = min(2.0, 0.25 * motor.v_max, j.velocity if j.velocity else math.inf)
        velocity = max(0.1, math.floor(velocity * 10) / 10)
        headroom = 0.5 * motor.t_max - peak.torque
        acceleration = min(10.0, max(1.0, headroom / inertia_k if headroom > 0 else 1.0))
        acceleration = math.floor(acceleration * 2) / 2
        joints.append(JointSuggestion(j, lo, hi, peak, inertia_k, motor, covered, needed, kp, kd, velocity,
                                      acceleration, 10 * acceleration))

    # the loop rate the bus carries: 500 Hz, else the highest multiple of 50 under 80 % worst case
    final = [JointConfig(name=s.urdf.name, bus="arm", can_id=k + 1, motor=s.motor, mode="mit",
                         limits=Limits(s.lower, s.upper, s.velocity, s.acceleration, s.jerk, s.motor.t_max),
                         gains=Gains(s.kp, s.kd)) for k, s in enumerate(joints)]
    grip = _gripper(urdf, driven, cat, len(final) + 1) if gripper else None
    motors = final if grip is None else [*final, grip.joint]  # the gripper's motor is on the bus too
    load = load_of("arm", 1_000_000, 500.0, motors)
    rate = 500.0 if not load.worst_case_over_limit else max(50.0, math.floor(load.max_rate_hz / 50) * 50)
    load = load_of("arm", 1_000_000, rate, motors)

    # poses: zero, and the sampled pose with the least gravity load on the chosen motors
    zero = np.clip(np.zeros(len(joints)), lower, upper)
    cfg = RobotConfig(name=urdf.name, urdf=path, buses={"arm": BusConfig("arm")}, joints=tuple(final),
                      tool_frame=tool, locked=locked)
    final_model = RobotModel(cfg)
    rated = np.array([s.motor.rated_torque or s.motor.t_max for s in joints])
    away = [q for q in samples if np.max(np.abs(q - zero)) > REST_DISTANCE] or list(samples)
    load_of_pose = [float(np.sum(np.abs(final_model.gravity(q)) / rated)) for q in away]
    rest = np.clip(np.round(away[int(np.argmin(load_of_pose))], 3), lower, upper)

    short = tuple(s.urdf.name for s in joints if not s.covered)
    text = _render(urdf, path, Path(output), joints, locked, held, tool, rate, load, zero, rest, payload, margin)
    if grip is not None:
        text += _render_gripper(grip, urdf)
    return Suggestion(text, tuple(joints), locked, tool, rate, short)


def _gripper(urdf: Urdf, driven: list[UrdfJoint], cat: Catalogue, can_id: int) -> GripperConfig:
    """A suggested gripper: an AK40-10 moving the URDF's prismatic joints that no motor of the arm drives
    (a parallel gripper's fingers), its stroke their travel added up (a master and the joints that mimic
    it; 80 mm without any), 2 rad of travel, 40 N."""
    fingers = [j for j in urdf.movable if j.type == "prismatic" and j not in driven
               and j.lower is not None and j.upper is not None]
    stroke = 0.0
    for j in fingers:
        assert j.lower is not None and j.upper is not None
        stroke += abs(j.mimic.multiplier if j.mimic is not None else 1.0) * (j.upper - j.lower)
    if not 0.0 < stroke <= 1.0:
        stroke, fingers = 0.08, []
    motor = cat.get("AK40-10") if "AK40-10" in cat else min(_candidates(cat), key=lambda m: m.t_max)
    return GripperConfig(name="gripper", motor=motor, can_id=can_id, bus="arm", stroke=round(stroke, 4),
                         travel=2.0, force_limit=40.0, fingers=tuple(j.name for j in fingers))


def _render_gripper(g: GripperConfig, urdf: Urdf) -> str:
    names = ", ".join(g.fingers)
    return "\n".join([
        "",
        f"gripper:   # suggested: the URDF's prismatic joints {names} look like a parallel gripper's fingers "
        "(docs/gripper.md)",
        f"  motor: {g.motor.name}   # suggested: a small motor on a rack and pinion; set yours",
        f"  can_id: {g.can_id}   # suggested: the next free ID",
        "  mode: mit",
        f"  kp: {g.kp:g}",
        f"  kd: {g.kd:g}",
        f"  stroke: {g.stroke:g}   # m, the fingers' travel added up (URDF)",
        f"  travel: {g.travel:g}   # suggested: rad of motor output from closed to fully open: measure yours",
        f"  force_limit: {g.force_limit:g}   # N: the most the jaws may squeeze; set what your object and jaws take",
        f"  fingers: [{names}]",
    ]) + "\n"


def _units(section: Section) -> str:
    """``mass (kg), com (m)``: a section's keys with their units, from the schema."""
    units = ((k.name, getattr(k.kind, "unit", "")) for k in section.keys)
    return ", ".join(f"{name} ({unit})" for name, unit in units if unit)


def _also(section: Section, written: set[str], indent: str, where: str) -> list[str]:
    """Comment lines naming the section's keys the starter does not write: the schema's others."""
    rest = [k.name for k in section.keys if k.name not in written]
    if not rest:
        return []
    lines, line = [], f"{indent}# {where} (docs/robot-file.md):"
    for name in rest:
        if len(line) + len(name) + 2 > 100:
            lines.append(line + ",")
            line = f"{indent}#  "
        line += ("" if line.endswith(":") or line.endswith("#  ") else ",") + " " + name
    return [*lines, line]


def _render(urdf: Urdf, path: Path, output: Path, joints: list[JointSuggestion], locked: dict[str, float],
            held: dict[str, float], tool: str | None, rate: float, load: object, zero: np.ndarray, rest: np.ndarray,
            payload: float, margin: float) -> str:
    from akarm.config.busload import BusLoad

    assert isinstance(load, BusLoad)
    out_dir = output.resolve().parent
    try:
        urdf_ref = os.path.relpath(path, out_dir)
    except ValueError:  # another drive (Windows)
        urdf_ref = str(path)
    stem = output.stem
    n = len(joints)
    names = ", ".join(s.urdf.name for s in joints)
    lines = [
        f"# {urdf.name}: a starting robot file, written by `akarm init` (akarm {__version__}) from {path.name}.",
        "#",
        "# Every value marked `suggested` is a suggestion worked out from the URDF, not a fact about your arm:",
        "# check each one (motors, CAN IDs, bus, limits, gains, poses) before the first enable. Then:",
        f"#   akarm check {output.name}",
        f"#   akarm sim {output.name} -i akarm_local -c try          # the simulated arm, in one terminal",
        f"#   akarm move {output.name} rest -i akarm_local -c try    # and move it, in another",
        "#",
        f"# Motors were sized for gravity over the joint ranges, {payload:g} kg payload at the tool, with rated",
        f"# (continuous) torque >= {margin:g} x the largest gravity torque + {A_REF:g} rad/s² x the joint's largest",
        "# inertia. The numbers per joint are in the comment above it.",
        f"name: {_name(stem)}",
        f"urdf: {_name(urdf_ref)}",
    ]
    if tool:
        lines.append(f"tool_frame: {_name(tool)}   # suggested: the end of the chain (payload, Cartesian queries)")
    pay = f"payload: {{mass: {payload:g}, com: [0.0, 0.0, 0.0]}}"
    lines.append(f"# {pay}   # the motors were sized for this (--payload): uncomment it while it is carried"
                 if payload else f"# payload: {{mass: 0.5, com: [0.0, 0.0, 0.0]}}   # {ROBOT_FILE['payload'].doc}: "
                 f"{_units(PAYLOAD)}, when the gripper carries something")
    ceiling = math.floor(load.max_rate_hz)
    lines += [
        f"rate_hz: {rate:g}   # suggested: {n} MIT joints on one 1 Mbit/s bus use {load.percent_nominal:.0f} % "
        f"({load.percent:.0f} % worst case; under {100 * LOAD_LIMIT:.0f} % up to {ceiling} Hz)",
        "buses:",
        "  arm: {interface: socketcan, channel: can0, bitrate: 1000000}   # suggested: your adapter "
        "(python-can interface and channel)",
        *_also(ROBOT_FILE, {"name", "urdf", "tool_frame", "payload", "rate_hz", "buses", "defaults", "locked", "poses",
                            "joints"}, "", "also possible"),
        "",
        "defaults:",
        "  bus: arm",
        "  mode: mit   # suggested: MIT (force control) mode; `mode: servo` for servo-mode motors",
        f"  max_temperature: {JOINT['max_temperature'].default!r}",   # °C, the schema's default
        *_also(JOINT, {"name", "bus", "can_id", "motor", "mode", "max_temperature", "limits", "gains"}, "  ",
               "also possible here or per joint"),
    ]
    if locked:
        lines += ["", f"locked:   # {ROBOT_FILE['locked'].doc} (rad, or m)"]
        for name, x in held.items():
            j = urdf.joints[name]
            followers = [f.name for f in urdf.joints.values() if f.mimic is not None and f.mimic.joint == name]
            unit = "m" if j.type == "prismatic" else "rad"
            rng = f", {j.lower:g}..{j.upper:g} {unit}" if j.lower is not None and j.upper is not None else ""
            also = f"; {', '.join(followers)} follow{'s' if len(followers) == 1 else ''} it (mimic)" if followers \
                else ""
            if followers and j.type != "prismatic":
                also += "; a gripper's joint? move it under joints: if an AK motor drives it"
            lines.append(f"  {_name(name)}: {_num(x)}   # suggested: where it is held ({j.type}{rng}){also}")
    lines += [
        "",
        f"poses:   # {ROBOT_FILE['poses'].doc}: {names} (rad)",
        f"  zero: [{', '.join(_num(x) for x in zero)}]   # every joint at 0, within its range",
        f"  rest: [{', '.join(_num(x) for x in rest)}]   # suggested: of sampled poses away from zero, "
        "the least gravity load on the motors; check that it is clear of obstacles",
        "",
        "joints:",
    ]
    for k, s in enumerate(joints):
        j = s.urdf
        g = s.gravity
        where = f" at {g.pose()}" if g.torque > 0.005 else ""
        m = s.motor
        if s.covered == "rated":
            why = f"the smallest whose rated {m.rated_torque:g} N·m covers {s.needed:.1f} N·m"
        elif s.covered == "peak":
            why = (f"NO model's rated torque covers {s.needed:.1f} N·m; its range {m.t_max:g} N·m holds the "
                   "gravity, above its rated torque: it heats when such poses are held")
        else:
            why = (f"NO catalogue model holds {g.torque:.1f} N·m: akarm check refuses this; give this joint more "
                   "reduction or a lighter arm")
        w = math.sqrt(s.kp / s.inertia)
        zeta = s.kd / (2.0 * math.sqrt(s.kp * s.inertia))
        damping = f"damping ratio {zeta:.2f}" + (f" (kd at its {s.motor.kd_max:g} maximum; kp holds 10 % of the "
                                                   "gravity torque within 0.05 rad)" if zeta < 0.9 else "")
        rng_note = "" if j.type != "continuous" else " (continuous in the URDF: ±π suggested)"
        lines += [
            f"  # {j.name} ({j.type}, URDF line {j.line}): gravity max {g.torque:.2f} N·m{where}; "
            f"inertia up to {s.inertia:.3g} kg·m² (rotor included)",
            f"  - name: {_name(j.name)}",
            f"    can_id: {k + 1}   # suggested: 1..{n} in chain order; set each motor's ID to match",
            f"    motor: {m.name}   # suggested: {why}",
            f"    limits: {{lower: {_num(s.lower)}, upper: {_num(s.upper)}, velocity: {_num(s.velocity)}, "
            f"acceleration: {_num(s.acceleration)}, jerk: {_num(s.jerk)}}}   # suggested: conservative{rng_note}",
            f"    gains: {{kp: {_num(s.kp)}, kd: {_num(s.kd)}}}   # suggested: {w / (2 * math.pi):.1f} Hz natural "
            f"frequency, {damping}",
        ]
    return "\n".join(lines) + "\n"
