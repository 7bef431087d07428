"""The view's state panel as HTML: mode, the latched stop, the loop, and a row per joint.

Pure text from a :class:`~akarm.server.snapshot.Snapshot`. Each value is also marked for programs
that read the page (tests, scrapers): the table rows carry ``data-joint``, the cells ``data-field``
(``q``, ``q_des``, ``error``, ``tau``, ``temperature``, ``age``), and the header ``data-field``
``mode``, ``stop``, ``loop``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from html import escape

from akarm.server.snapshot import Snapshot

__all__ = ["gripper_html", "state_html"]

_STYLE = ("<style>.akarm-state{font-size:11.5px;line-height:1.35}.akarm-state table{border-collapse:collapse;"
          "width:100%}.akarm-state td,.akarm-state th{padding:1px 3px;text-align:right;white-space:nowrap}"
          ".akarm-state td:first-child,.akarm-state th:first-child{text-align:left}"
          ".akarm-state .stop{color:#c92a2a;font-weight:600}.akarm-state .hot{color:#c92a2a}</style>")


def _num(x: float, fmt: str) -> str:
    return "–" if not math.isfinite(x) else format(x, fmt)


def _age(age: float) -> str:
    if not math.isfinite(age):
        return "–"
    return f"{age * 1e3:.1f}" if age < 0.1 else f"{age * 1e3:.0f}" if age < 10 else f">{10_000:,}".replace(",", " ")


def _loop(snap: Snapshot, recent_hz: float | None) -> str:
    if snap.cycles == 0 and snap.loop_rate_hz == 0:
        return "no control loop here" if snap.mode != "recorded" else f"recorded at {snap.rate_hz:.0f} Hz"
    if snap.mode == "recorded":
        return f"recorded at {snap.rate_hz:.0f} Hz, cycle {snap.cycles}"
    rate = recent_hz if recent_hz is not None else snap.loop_rate_hz
    return (f"loop {rate:.1f} Hz (target {snap.rate_hz:g}, {snap.loop_rate_hz:.1f} on average), "
            f"missed slots {snap.missed_slots}")


def state_html(snap: Snapshot | None, recent_hz: float | None = None, hot: Sequence[float] = (),
               note: str = "") -> str:
    """The panel for ``snap`` (``None``: nothing yet; ``note`` says why). ``recent_hz``: the loop's rate
    over the last second, when the view measured it; a joint's temperature at or over its ``hot`` (°C,
    per joint) is marked."""
    if snap is None:
        return _STYLE + f"<div class='akarm-state'><p data-field='mode'>waiting for the arm… {escape(note)}</p></div>"
    stop = (f"<p class='stop' data-field='stop'>safety stop: {escape(snap.stop)}</p>" if snap.stop
            else "<p data-field='stop'>no safety stop</p>")
    rows = ["<tr><th>joint</th><th>measured<br>rad</th><th>commanded<br>rad</th><th>error<br>mrad</th>"
            "<th>torque<br>N·m</th><th>temp<br>°C</th><th>age<br>ms</th></tr>"]
    for k, name in enumerate(snap.names):
        temp = snap.temperature[k]
        warm = k < len(hot) and temp >= hot[k]
        temp_cell = f"<td data-field='temperature'{' class=hot' if warm else ''}>{_num(temp, '.1f')}</td>"
        fault = f" <span class='stop'>E{snap.fault[k]}</span>" if snap.fault[k] else ""
        rows.append(f"<tr data-joint='{escape(name, quote=True)}'><td>{escape(name)}{fault}</td>"
                    f"<td data-field='q'>{_num(snap.q[k], '+.5f')}</td>"
                    f"<td data-field='q_des'>{_num(snap.q_des[k], '+.5f')}</td>"
                    f"<td data-field='error'>{_num(snap.error[k] * 1e3, '+.2f')}</td>"
                    f"<td data-field='tau'>{_num(snap.tau[k], '+.3f')}</td>{temp_cell}"
                    f"<td data-field='age'>{_age(snap.age[k])}</td></tr>")
    return (_STYLE + "<div class='akarm-state'>"
            f"<p><b>mode</b> <span data-field='mode'>{escape(snap.mode)}</span>"
            + (f" · t = {snap.t:.3f} s" if snap.mode == "recorded" else "") + f"</p>{stop}"
            f"<p data-field='loop'>{escape(_loop(snap, recent_hz))}</p>"
            f"<table>{''.join(rows)}</table>" + gripper_html(snap)
            + (f"<p>{escape(note)}</p>" if note else "") + "</div>")


def gripper_html(snap: Snapshot) -> str:
    """The gripper's line of the panel: width and width asked (mm), squeeze (N), grasp, temperature;
    ``""`` without a gripper."""
    if not snap.gripper:
        return ""
    held = "holds something" if snap.gripper_grasped else "empty"
    return (f"<p data-field='gripper'><b>{escape(snap.gripper)}</b> "
            f"<span data-field='gripper_width'>{_num(snap.gripper_width * 1e3, '.1f')}</span> mm "
            f"(asked <span data-field='gripper_target'>{_num(snap.gripper_target * 1e3, '.1f')}</span> mm), "
            f"squeeze <span data-field='gripper_force'>{_num(snap.gripper_force, '.1f')}</span> N, "
            f"<span data-field='gripper_grasped'>{held}</span>, "
            f"{_num(snap.gripper_temperature, '.1f')} °C</p>")
