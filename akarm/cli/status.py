"""``akarm status ROBOT.yaml``: each joint's position, velocity, torque, temperature and fault.

::

    akarm status robots/arm6.yaml                 # a table, joint side, SI units
    akarm status robots/arm6.yaml --json          # machine-readable
    akarm status robots/arm6.yaml --watch         # again every 0.5 s until Ctrl-C

Reading needs no control loop: a running controller's replies are simply listened to; a silent
MIT joint is asked with EXIT, which leaves it **disabled** (the table says which joints were asked).
Exit status 0 when every joint answered, 1 when one did not (it is still listed, as "no answer").
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, TextIO

from akarm.cli.common import add_robot_arguments, format_table, load_from_args
from akarm.cli.options import count, duration

if TYPE_CHECKING:
    from akarm.cli.served import RemoteArm
    from akarm.config import RobotConfig
    from akarm.control.probe import JointStatus


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    add_robot_arguments(parser)
    parser.add_argument("--json", action="store_true", help="print JSON (one object per reading) instead of a table")
    parser.add_argument("--watch", action="store_true", help="read again every --interval s until Ctrl-C")
    parser.add_argument("--interval", type=duration, default=0.5, metavar="S",
                        help="seconds between readings with --watch (default 0.5)")
    parser.add_argument("--count", type=count, metavar="N", help="with --watch: stop after N readings")
    parser.add_argument("--timeout", type=duration, metavar="S",
                        help="seconds to wait for the joints (default: 0.25, or 2.5 periods of the slowest servo "
                             "status rate)")


def _num(x: float | None, fmt: str) -> str:
    return "-" if x is None else format(x, fmt)


def status_table(states: Sequence[JointStatus]) -> str:
    """The status table: one row per joint, SI units in the headers."""
    rows = [["joint", "mode", "bus/ID", "position (rad)", "velocity (rad/s)", "torque (N·m)", "temperature (°C)",
             "fault", "age (s)"]]
    for s in states:
        if s.missing:
            rows.append([s.name, s.mode, f"{s.bus}/{s.can_id}", "no answer", "-", "-", "-", "-", "-"])
            continue
        rows.append([s.name, s.mode, f"{s.bus}/{s.can_id}", _num(s.position, "+.4f"), _num(s.velocity, "+.3f"),
                     _num(s.torque, "+.3f"), _num(s.temperature, ".1f"), s.fault_text(), _num(s.age, ".3f")])
    text = format_table(rows, [False, False, False, True, True, True, True, False, True])
    asked = [s.name for s in states if s.queried and not s.missing]
    if asked:
        text += f"\n(asked with EXIT, so now disabled: {', '.join(asked)})"
    return text


def gripper_reading(config: RobotConfig, states: Sequence[JointStatus]) -> dict[str, Any] | None:
    """The gripper's width (m), squeeze (N) and temperature (°C) from its motor's row; ``None`` without one."""
    g = config.gripper
    if g is None:
        return None
    row = next((s for s in states if s.name == g.name), None)
    if row is None or row.missing or row.position is None:
        return {"name": g.name, "width": None, "force": None, "temperature": None}
    slope = g.slope_at(row.position)
    force = max(0.0, -(row.torque or 0.0)) / slope
    return {"name": g.name, "width": g.width_at(row.position), "force": force, "temperature": row.temperature}


def gripper_line(reading: dict[str, Any] | None) -> str:
    if reading is None:
        return ""
    if reading["width"] is None:
        return f"gripper {reading['name']!r}: no answer"
    return (f"gripper {reading['name']!r}: width {reading['width'] * 1e3:.1f} mm, force {reading['force']:.1f} N, "
            f"temperature {_num(reading['temperature'], '.1f')} °C")


def _print(states: Sequence[JointStatus], args: argparse.Namespace, out: TextIO, clear: bool,
           about: dict[str, Any] | None) -> None:
    config = getattr(args, "config", None)
    grip = gripper_reading(config, states) if config is not None else None
    if args.json:
        doc = {"time": time.time(), "joints": [s.as_dict() for s in states], **(about or {})}
        if grip is not None:
            doc["gripper"] = grip
        print(json.dumps(doc, allow_nan=False), file=out, flush=True)
        return
    if clear:
        print("\x1b[H\x1b[2J", end="", file=out)
    print(status_table(states), file=out, flush=True)
    if grip is not None:
        print(gripper_line(grip), file=out, flush=True)
    if about and about.get("text"):
        print(about["text"], file=out, flush=True)


def watch(args: argparse.Namespace, read: Callable[[], list[JointStatus]],
          about: Callable[[], dict[str, Any]] | None = None) -> list[JointStatus]:
    """Print ``read()`` once, or with --watch every --interval s (--count times, else until Ctrl-C);
    ``about()``, read after each ``read()``, adds its keys to the JSON and its ``text`` under the
    table. Returns the last states read."""
    out = sys.stdout
    tty = out.isatty()
    n = 0
    next_t = time.monotonic()
    while True:
        states = read()
        n += 1
        if args.watch and n > 1 and not args.json and not tty:
            print(file=out)
        _print(states, args, out, clear=args.watch and tty and not args.json, about=about() if about else None)
        if not args.watch or (args.count is not None and n >= args.count):
            return states
        next_t += args.interval
        time.sleep(max(0.0, next_t - time.monotonic()))


def run(args: argparse.Namespace) -> int:
    """Read the joints once (or repeatedly with --watch); 1 if a joint did not answer."""
    from akarm.cli.served import via_server

    if (served := via_server(args, _served)) is not None:  # an `akarm serve` drives this robot: ask it
        return served
    from akarm.control.probe import Probe

    config = args.config = load_from_args(args)
    with Probe(config) as probe:
        states = watch(args, lambda: probe.read_state(args.timeout))
    missing = [s.name for s in states if s.missing]
    if missing:
        from akarm.buses.bus import no_answer_hint

        bus_of = {m.name: m.bus for m in config.motors}
        for bus in dict.fromkeys(bus_of[name] for name in missing):
            names = [n for n in missing if bus_of[n] == bus]
            print(f"akarm status: no answer from {', '.join(names)}: {no_answer_hint(config.buses[bus])}",
                  file=sys.stderr)
        return 1
    return 0


def _served(arm: RemoteArm, args: argparse.Namespace) -> int:
    """Read the joints through ``akarm serve``: live while it holds the arm; a disabled arm's joints
    are asked first, as without a server. Each reading says its age; a latched safety stop is shown."""
    from akarm.control.probe import JointStatus

    last: dict[str, Any] = {}

    def read() -> list[JointStatus]:
        d = last["doc"] = arm.call("state", read=True)
        return [JointStatus(name, mode, bus, can_id, q, dq, tau, temp, fault, False, False, age)
                for name, mode, bus, can_id, q, dq, tau, temp, fault, age in
                zip(d["names"], d["modes"], d["buses"], d["can_ids"], d["q"], d["dq"], d["tau"],
                    d["temperature"], d["fault"], d["age"], strict=True)]

    def about() -> dict[str, Any]:
        d = last["doc"]
        stop = d.get("stop")
        lines = [f"({d['mode']}; {arm.held})" if d["enabled"] else
                 f"({d['mode']}; read through akarm serve pid {arm.pid}"
                 + ("; silent joints asked with EXIT)" if d.get("asked") else ")")]
        old = [(n, a) for n, a in zip(d["names"], d["age"], strict=True) if a is not None and a > 1.0]
        if old:
            lines.append("(readings not fresh: " + ", ".join(f"{n} {a:.1f} s old" for n, a in old) + ")")
        grip = None
        if arm.config.gripper is not None:
            g = arm.call("gripper_state")
            grip = {"name": arm.config.gripper.name, "width": g["width"], "force": g["force"],
                    "temperature": g["temperature"]}
            lines.append(gripper_line(grip))
        if stop:
            clock = time.strftime("%H:%M:%S", time.localtime(stop["time"]))
            lines.append(f"SAFETY STOP latched since {clock}: {stop['error']}: {stop['text']}\n"
                         f"nothing moves until `akarm enable {args.robot}` acknowledges it")
        doc = {"mode": d["mode"], "stop": stop, "server_pid": arm.pid, "text": "\n".join(lines)}
        if grip is not None:
            doc["gripper"] = grip
        return doc

    def json_about() -> dict[str, Any]:
        doc = about()
        del doc["text"]
        return doc

    watch(args, read, json_about if args.json else about)
    return 0
