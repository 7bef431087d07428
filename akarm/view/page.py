"""The view's web page: a viser server drawing the arm, its plots, its state and its controls.

:class:`ViewServer` serves one page (http://127.0.0.1:8080 by default) for a robot and a source
(:mod:`akarm.view.sources`, :mod:`akarm.view.recorded`):

- **3D**: the measured pose solid, the commanded pose as a ghost, the tool frame
  (:mod:`akarm.view.figure`: the URDF's visuals, or capsules from joint to joint);
- **state**: mode, the latched stop, the loop's rate and missed slots, and per joint the measured
  and commanded position, error, torque, temperature and feedback age (:mod:`akarm.view.panel`);
- **plots** per joint over the last 10 s: position (desired, measured), tracking error, torque;
- **controls** when the source has them (a server): enable, hold, disable, and a jog slider per
  joint, limited to its range and disabled while the arm is not enabled; and "jog to": a joint, an
  angle typed in a box that takes any number, and a Jog button: a target past the joint's range is
  refused there, and said on the page, before anything is sent;
- **playback** for a recording: a time slider, play/pause and the speed.

Threads: viser's own (its web server, and a pool that runs the page's callbacks); ``akarm-view``,
which asks the source for a snapshot about 30 times a second (``rate_hz``), draws it, and updates
the plots and the panel about 10 times a second (``plot_hz``), drawing nothing while no browser is
connected; ``akarm-view-jog``, which sends the newest jog target of the sliders, one at a time (a
drag makes many). None of them is the control loop's; a snapshot holds the controller's lock for
one copy of the joints' state (:func:`akarm.server.snapshot.take`).

Who can reach the port can press every control: the server binds 127.0.0.1 unless told otherwise.
"""

from __future__ import annotations

import collections
import contextlib
import math
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from akarm.dynamics.model import RobotModel
from akarm.errors import AkarmError, ArgumentError, StateError
from akarm.server.snapshot import Snapshot
from akarm.view.figure import Figure, Poser, build_figure, finger_slides, wxyz
from akarm.view.history import History, Window
from akarm.view.panel import state_html
from akarm.view.recorded import RecordedSource

if TYPE_CHECKING:
    import viser

    from akarm.config import RobotConfig
    from akarm.view.sources import Source

__all__ = ["DEFAULT_HOST", "DEFAULT_PORT", "ViewServer"]

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8080
#: the commanded pose's colour (RGB) and opacity
GHOST = ((70, 150, 255), 0.3)
#: m: the jaws drawn at the tool frame of a gripper whose fingers the URDF does not draw (x, y, z)
JAW_SIZE = (0.012, 0.008, 0.04)
#: triangles above which the ghost is the kinematic figure rather than a second copy of the meshes
#: (a browser without a GPU draws every triangle in software)
GHOST_FACES = 20_000
#: s after a user moved a jog slider before the slider follows the commanded position again
SLIDER_HANDS_OFF = 1.5
#: °C under a joint's max_temperature from which the panel marks its temperature
HOT_MARGIN = 10.0
SPEEDS = ("0.25", "0.5", "1", "2", "4")


def import_viser() -> Any:
    """The viser module, or an :class:`~akarm.AkarmError` naming the extra that brings it."""
    try:
        import viser
    except ImportError as e:
        raise AkarmError(f"the view needs viser, which is not installed ({e})",
                         fix='pip install "akarm[view]"') from None
    return viser


def check_options(host: str, port: int, rate_hz: float, plot_hz: float) -> None:
    """Raise :class:`~akarm.ArgumentError` for a host, port or rate a view cannot serve with."""
    if not isinstance(host, str) or not host:
        raise ArgumentError(f"host {host!r} must be an address to bind", fix="e.g. 127.0.0.1 (this machine only)")
    if not isinstance(port, int) or isinstance(port, bool) or not 0 <= port <= 65535:
        raise ArgumentError(f"port {port!r} must be a whole number 0-65535 (0: any free port)", fix="e.g. --port 8080")
    for what, hz in (("rate_hz", rate_hz), ("plot_hz", plot_hz)):
        if not (isinstance(hz, int | float) and 0 < hz <= 120):
            raise ArgumentError(f"{what} {hz!r} must be a number of Hz in (0, 120]", fix="the view draws at ~30 Hz")


def page_url(host: str, port: int) -> str:
    """The address a browser opens for a page served on ``host``:``port`` (localhost for loopback)."""
    return f"http://{'localhost' if host in ('127.0.0.1', '::1') else host}:{port}"


def _check_bindable(host: str) -> None:
    """Raise :class:`~akarm.StateError` when no port of ``host`` can be bound (not an address of this
    machine, a name that does not resolve)."""
    import socket

    try:
        family, kind, proto, _, address = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)[0]
        with socket.socket(family, kind, proto) as probe:
            probe.bind(address)
    except OSError as e:
        raise StateError(f"cannot serve the view on {host}: {getattr(e, 'strerror', None) or e}",
                         fix="choose another --host: an address of this machine (127.0.0.1, 0.0.0.0, ...)") from None


class ViewServer:
    """The page for ``config``'s robot, showing ``source``, until :meth:`stop`.

    Args:
        config: the robot (its URDF, joint order and ranges).
        source: what to show (:mod:`akarm.view.sources`, :class:`~akarm.view.recorded.RecordedSource`).
        host, port: where to serve (port 0: any free one; a port in use: the next free one, viser's
            way; :attr:`url` says which). The default host is this machine only.
        rate_hz: snapshots per second (3D). plot_hz: updates of the plots and the panel per second.
        history: s of the plots. visuals: draw the URDF's visuals (False: the kinematic figure).
        log: where one-line reports go (default stderr).

    Raises:
        ArgumentError: a bad host, port or rate. AkarmError: viser is not installed (the ``view`` extra).
    """

    def __init__(self, config: RobotConfig, source: Source, *, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT,
                 rate_hz: float = 30.0, plot_hz: float = 10.0, history: float = 10.0, visuals: bool = True,
                 log: Callable[[str], None] | None = None) -> None:
        check_options(host, port, rate_hz, plot_hz)
        self.config = config
        self.source = source
        self.host, self.port = host, port
        self.rate_hz, self.plot_hz, self.seconds = float(rate_hz), float(plot_hz), float(history)
        self.log = log or (lambda text: print(text, file=sys.stderr, flush=True))
        self.names = config.joint_names
        self.model = RobotModel(config)
        self.figure: Figure = build_figure(self.model, visuals=visuals)
        self.ghost = self.figure if self.figure.faces <= GHOST_FACES else build_figure(self.model, visuals=False)
        self.poser = Poser(self.model)
        self.history = History(len(self.names), self.seconds, capacity=int(self.seconds * self.rate_hz * 2) + 16)
        self.recording = source if isinstance(source, RecordedSource) else None
        self.playing = False
        self.speed = 1.0
        self.last: Snapshot | None = None
        self.lost: AkarmError | None = None  # the source's error while it is gone, else None
        self.message = ""  # the controls' last outcome: what was done, or "refused: ..."
        self.refusals = 0
        self.snapshot_seconds = 0.0  # wall time spent taking snapshots (what the view asks of the arm)
        self.draws = 0
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._server: viser.ViserServer | None = None
        self._rates: collections.deque[tuple[float, int]] = collections.deque(maxlen=64)
        self._drawn: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._jog_cv = threading.Condition()
        self._jog_pending: tuple[str, float] | None = None
        self._hot = tuple(j.max_temperature - HOT_MARGIN for j in config.joints)
        self._touched = dict.fromkeys(self.names, 0.0)  # monotonic time a user last moved each slider
        self._gui: dict[str, Any] = {}
        self._sliders: dict[str, Any] = {}
        self._sliders_disabled: bool | None = None
        self._plots: list[tuple[Any, Any, Any]] = []
        self._nodes: dict[str, list[tuple[int, Any]]] = {"measured": [], "commanded": []}
        self.slides = finger_slides(self.model)  # the finger links: drawn at the width measured
        self._sliding: dict[str, list[tuple[Any, np.ndarray]]] = {"measured": [], "commanded": []}

    # ------------------------------------------------------------------------------------------
    # lifecycle
    # ------------------------------------------------------------------------------------------
    @property
    def url(self) -> str:
        """The page's address (:attr:`port` is the one bound, once started)."""
        return page_url(self.host, self.port)

    def start(self) -> ViewServer:
        """Serve the page and start drawing. Raises when viser is missing or the port cannot be bound."""
        viser = import_viser()
        _check_bindable(self.host)  # viser tries the next port forever on any error binding one
        try:
            with _quiet():  # viser's banner: the caller says where the page is
                self._server = viser.ViserServer(host=self.host, port=self.port, verbose=False)
        except OSError as e:
            raise StateError(f"cannot serve the view on {self.host}:{self.port}: {e.strerror or e}",
                             fix="choose another --host/--port") from None
        # viser would open a tunnel through its public share server for any page that asks: never
        setattr(self._server, "request_share_url", _no_share_url)  # noqa: B010 (mypy: a method is not assignable)
        self.port = int(self._server.get_port())
        try:
            self._build(self._server)
        except BaseException:
            self.stop()
            raise
        self._spawn(self._run, "akarm-view")
        if self.source.controls is not None:
            self._spawn(self._jog_loop, "akarm-view-jog")
        return self

    def _spawn(self, target: Callable[[], None], name: str) -> None:
        thread = threading.Thread(target=target, name=name, daemon=True)
        thread.start()
        self._threads.append(thread)

    def stop(self) -> None:
        """Stop drawing and serving (the arm and the source are left as they are)."""
        self._stop.set()
        with self._jog_cv:
            self._jog_cv.notify_all()
        for thread in self._threads:
            if thread is not threading.current_thread():
                thread.join(5.0)
        self._threads.clear()
        server, self._server = self._server, None
        if server is not None:
            with _quiet():  # viser prints "Server stopped"
                server.stop()

    def __enter__(self) -> ViewServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def clients(self) -> int:
        """How many browsers are connected now."""
        return len(self._server.get_clients()) if self._server is not None else 0

    # ------------------------------------------------------------------------------------------
    # the page
    # ------------------------------------------------------------------------------------------
    def _build(self, server: viser.ViserServer) -> None:
        server.gui.configure_theme(control_width="large", show_logo=False, show_share_button=False)
        server.scene.set_up_direction("+z")
        self._build_scene(server)
        fig = self.figure
        where = (f"drawn from the URDF's visuals ({fig.visuals} shapes)" if fig.kind == "visuals"
                 else "drawn from the kinematics: capsules from joint to joint, sized by the links' masses")
        if fig.problems:
            where += f"; {len(fig.problems)} visuals not drawn: " + "; ".join(fig.problems[:3])
        if self.ghost is not fig:
            where += f"; {fig.faces} triangles: the commanded pose is drawn as capsules"
        server.gui.add_html(f"<div style='font-size:13px'><b>{_esc(self.config.name)}</b> · {_esc(self.source.title)}"
                            f"<br><span data-field='figure' data-kind='{fig.kind}' data-parts='{len(fig.parts)}' "
                            f"style='color:#777'>{_esc(where)}</span></div>")
        self._gui["panel"] = server.gui.add_html(state_html(None))
        if self.source.controls is not None:
            self._build_controls(server)
        if self.recording is not None:
            self._build_playback(server, self.recording)
        self._build_plots(server)
        with server.gui.add_folder("Display", expand_by_default=False):
            ghost = server.gui.add_checkbox("commanded pose (ghost)", initial_value=True)
            tool = server.gui.add_checkbox("tool frame", initial_value=True)
        ghost.on_update(lambda _: self._set_visible("/commanded", ghost.value))
        tool.on_update(lambda _: self._set_visible("/tool", tool.value))

    def _build_scene(self, server: viser.ViserServer) -> None:
        poses = self.poser.poses(np.zeros(len(self.names)))
        reach = max(0.2, float(np.max(np.linalg.norm(poses[:, :3, 3], axis=1))),
                    float(np.linalg.norm(self.poser.tool(poses)[:3, 3])))
        server.scene.add_grid("/grid", width=2 * reach, height=2 * reach, cell_size=0.1, section_size=0.5)
        server.initial_camera.position = (0.95 * reach, -1.15 * reach, 0.8 * reach)
        server.initial_camera.look_at = (0.0, 0.0, 0.35 * reach)
        self._gui["roots"] = {"/commanded": server.scene.add_frame("/commanded", show_axes=False)}
        for kind, figure, color, opacity in (("measured", self.figure, None, None), ("commanded", self.ghost, *GHOST)):
            for k in sorted({p.body for p in figure.parts}):
                node = server.scene.add_frame(f"/{kind}/b{k}", show_axes=False)
                self._nodes[kind].append((k, node))
                for part in (p for p in figure.parts if p.body == k):
                    mesh = server.scene.add_mesh_simple(
                        f"/{kind}/b{k}/{part.name}", part.vertices, part.faces,
                        color=part.color if color is None else color,
                        opacity=(part.opacity if part.opacity < 1 else None) if opacity is None else opacity,
                        cast_shadow=False, receive_shadow=False)  # shadows: costly in a software-rendered browser
                    if part.link in self.slides:
                        self._sliding[kind].append((mesh, self.slides[part.link]))
        size = min(0.1, max(0.03, 0.08 * reach))
        self._gui["roots"]["/tool"] = server.scene.add_frame("/tool", axes_length=size, axes_radius=size / 20)
        self._build_jaws(server)

    def _build_jaws(self, server: viser.ViserServer) -> None:
        """The gripper's jaws (two boxes at the tool frame, when the URDF draws no fingers) and the
        label of its width."""
        if self.config.gripper is None:
            return
        if not self._sliding["measured"]:
            jaws = server.scene.add_frame("/jaws", show_axes=False)
            self._gui["jaws"] = (jaws, [server.scene.add_box(f"/jaws/{side}", color=(120, 124, 134),
                                                               dimensions=JAW_SIZE, cast_shadow=False,
                                                               receive_shadow=False)
                                        for side in ("left", "right")])
        self._gui["jaw_label"] = server.scene.add_label("/jaw_label", "gripper", font_screen_scale=0.8)

    def _set_visible(self, name: str, visible: bool) -> None:
        self._gui["roots"][name].visible = visible

    def _build_controls(self, server: viser.ViserServer) -> None:
        with server.gui.add_folder("Controls"):
            server.gui.add_button("Enable", color="green").on_click(lambda _: self._command("enable"))
            server.gui.add_button("Hold", color="blue").on_click(lambda _: self._command("hold"))
            server.gui.add_button("Disable", color="red").on_click(lambda _: self._command("disable"))
            self._gui["message"] = server.gui.add_html(self._message_html())
            self._gui["jog_speed"] = server.gui.add_slider("jog speed", min=0.05, max=1.0, step=0.05, initial_value=0.3)
            server.gui.add_markdown("Jog (jerk-limited, within each joint's range; enabled arm only):")
            for jc in self.config.joints:
                lo, hi = jc.limits.lower, jc.limits.upper
                slider = server.gui.add_slider(jc.name, min=round(lo, 4), max=round(hi, 4), step=0.001,
                                               initial_value=round(min(max(0.0, lo), hi), 4), disabled=True)
                slider.on_update(self._slider_callback(jc.name))
                self._sliders[jc.name] = slider
            server.gui.add_markdown("Jog to a typed angle (rad; refused past the joint's range):")
            self._gui["jog_joint"] = server.gui.add_dropdown("jog joint", options=tuple(self.names),
                                                             initial_value=self.names[0])
            self._gui["jog_to"] = server.gui.add_number("jog to [rad]", initial_value=0.0, step=0.001)  # no range
            server.gui.add_button("Jog").on_click(self._on_jog_button)

    def _build_playback(self, server: viser.ViserServer, rec: RecordedSource) -> None:
        with server.gui.add_folder("Playback"):
            step = max(0.001, round(1.0 / rec.rate_hz, 4)) if rec.rate_hz > 0 else 0.01
            slider = server.gui.add_slider("time [s]", min=0.0, max=max(step, round(rec.duration, 3)), step=step,
                                           initial_value=0.0)
            play = server.gui.add_button("Play")
            speed = server.gui.add_dropdown("speed", options=SPEEDS, initial_value="1")

        def seek(event: Any) -> None:
            if event.client is not None:
                rec.position = float(slider.value)

        def toggle(_: Any) -> None:
            if not self.playing and rec.position >= rec.duration:
                rec.position = 0.0
            self.playing = not self.playing
            play.label = "Pause" if self.playing else "Play"

        def set_speed(_: Any) -> None:
            self.speed = float(speed.value)

        slider.on_update(seek)
        play.on_click(toggle)
        speed.on_update(set_speed)
        self._gui["time"] = slider
        self._gui["play"] = play

    def _build_plots(self, server: viser.ViserServer) -> None:
        empty = np.array([-self.seconds, 0.0])
        nan = np.full(2, np.nan)
        x_axis = {"x": {"time": False, "auto": False, "range": (-self.seconds, 0.0)}}
        with server.gui.add_folder(f"Plots (last {self.seconds:g} s)", expand_by_default=True):
            for k, name in enumerate(self.names):
                with server.gui.add_folder(name, expand_by_default=k == 0):
                    pos = server.gui.add_uplot(
                        (empty, nan, nan), ({"label": "t [s]"}, {"label": "desired", "stroke": "#4c8dff", "width": 1.5},
                                            {"label": "measured", "stroke": "#e8892f", "width": 1.5}),
                        title="position [rad]", scales=x_axis, aspect=2.6)  # type: ignore[arg-type]
                    err = server.gui.add_uplot(
                        (empty, nan), ({"label": "t [s]"}, {"label": "error [mrad]", "stroke": "#c92a2a"}),
                        title="tracking error [mrad]", scales=x_axis, aspect=2.6)  # type: ignore[arg-type]
                    tau = server.gui.add_uplot(
                        (empty, nan), ({"label": "t [s]"}, {"label": "torque [N·m]", "stroke": "#2b8a3e"}),
                        title="torque [N·m]", scales=x_axis, aspect=2.6)  # type: ignore[arg-type]
                self._plots.append((pos, err, tau))

    # ------------------------------------------------------------------------------------------
    # drawing (the akarm-view thread)
    # ------------------------------------------------------------------------------------------
    def _run(self) -> None:
        period = 1.0 / self.rate_hz
        every = max(1, round(self.rate_hz / self.plot_hz))
        tick = 0
        due = time.monotonic()
        last = due
        while True:
            wait = due - time.monotonic()
            if self._stop.wait(max(0.0, wait)):
                return
            now = time.monotonic()
            due = max(due + period, now)  # late: carry on from now, never a burst
            if self.recording is not None and self.playing:
                self._advance(now - last)
            last = now
            try:
                self.update(full=tick % every == 0)
            except Exception as e:  # a bug in drawing must not end the view silently
                self.log(f"akarm view: drawing failed: {e!r}")
            tick += 1

    def _advance(self, dt: float) -> None:
        rec = self.recording
        assert rec is not None
        rec.position = min(rec.duration, rec.position + dt * self.speed)
        if rec.position >= rec.duration:
            self.playing = False
            if "play" in self._gui:
                self._gui["play"].label = "Play"

    def update(self, full: bool = True) -> Snapshot | None:
        """Take a snapshot and draw it (``full``: the plots, the panel and the controls too). The
        drawing thread calls it; a test may too. Returns the snapshot (``None``: the source is gone)."""
        t0 = time.perf_counter()
        try:
            snap = self.source.snapshot()
        except AkarmError as e:
            self.snapshot_seconds += time.perf_counter() - t0
            if self.lost is None:
                self.log(f"akarm view: lost the source: {e}")
            self.lost = e
            if full:
                self._set_html("panel", state_html(self.last, note=f"lost the source: {e}"))
            return None
        self.snapshot_seconds += time.perf_counter() - t0
        self.lost = None
        self.last = snap
        if self.recording is None:
            self.history.add(snap)
            self._rates.append((snap.t, snap.cycles))
        if self._server is None or not self._server.get_clients():
            return snap  # nobody looks: keep the history, draw nothing
        self._draw(snap)
        if full:
            self._set_html("panel", state_html(snap, self._recent_rate(), self._hot, note=self._note()))
            self._update_plots()
            self._sync_controls(snap)
        return snap

    def _note(self) -> str:
        return "" if self.recording is None else f"playing back {self.recording.duration:.2f} s"

    def _recent_rate(self) -> float | None:
        if len(self._rates) < 2:
            return None
        (t0, c0), (t1, c1) = self._rates[0], self._rates[-1]
        return (c1 - c0) / (t1 - t0) if t1 - t0 > 0.5 and c1 >= c0 else None

    def _draw(self, snap: Snapshot) -> None:
        q, q_des = np.array(snap.q), np.array(snap.q_des)
        grip = np.array([snap.gripper_width, snap.gripper_target, snap.gripper_force])
        if self._drawn is not None and np.array_equal(q, self._drawn[0]) and \
                np.array_equal(q_des, self._drawn[1], equal_nan=True) and \
                np.array_equal(grip, self._drawn[2], equal_nan=True):
            return
        self._drawn = (q, q_des, grip)
        assert self._server is not None
        measured = self.poser.poses(q)
        ghost = bool(np.all(np.isfinite(q_des)))
        with self._server.atomic():
            self._place("measured", measured)
            if ghost:
                self._place("commanded", self.poser.poses(q_des))
            tool = self.poser.tool(measured)
            node = self._gui["roots"]["/tool"]
            node.position = tuple(tool[:3, 3])
            node.wxyz = wxyz(tool[:3, :3])
            self._draw_jaws(snap, tool)
        self.draws += 1

    def _draw_jaws(self, snap: Snapshot, tool: np.ndarray) -> None:
        """The fingers (or the jaws at the tool frame) at the width measured, the ghost's at the width
        asked, and the label: width and squeeze."""
        if "jaw_label" not in self._gui:
            return
        for kind, width in (("measured", snap.gripper_width), ("commanded", snap.gripper_target)):
            half = 0.5 * width if math.isfinite(width) else 0.0  # each finger joint: half the width
            for mesh, slide in self._sliding[kind]:
                mesh.position = tuple(slide * half)
        if "jaws" in self._gui:
            frame, (left, right) = self._gui["jaws"]
            frame.position = tuple(tool[:3, 3])
            frame.wxyz = wxyz(tool[:3, :3])
            half = 0.5 * snap.gripper_width if math.isfinite(snap.gripper_width) else 0.0
            left.position = (0.0, half + JAW_SIZE[1] / 2, 0.0)
            right.position = (0.0, -half - JAW_SIZE[1] / 2, 0.0)
        label = self._gui["jaw_label"]
        label.position = tuple(tool[:3, 3])
        label.text = jaw_text(snap)

    def _place(self, kind: str, poses: np.ndarray) -> None:
        for k, node in self._nodes[kind]:
            node.position = tuple(poses[k][:3, 3])
            node.wxyz = wxyz(poses[k][:3, :3])

    def _window(self) -> Window:
        if self.recording is not None:
            return self.recording.window(self.recording.position, self.seconds)
        return self.history.window()

    def _update_plots(self) -> None:
        w = self._window()
        if len(w.t) < 2:
            return
        for k, (pos, err, tau) in enumerate(self._plots):
            t, q_des, q, error, torque = w.joint(k)
            pos.data = (t, q_des, q)
            err.data = (t, error * 1e3)
            tau.data = (t, torque)
        if self.recording is not None:
            self._gui["time"].value = round(self.recording.position, 3)

    def _set_html(self, key: str, content: str) -> None:
        handle = self._gui.get(key)
        if handle is not None and handle.content != content:
            handle.content = content

    # ------------------------------------------------------------------------------------------
    # controls (viser's callback threads, and akarm-view-jog)
    # ------------------------------------------------------------------------------------------
    def _message_html(self) -> str:
        style = "color:#c92a2a;font-weight:600" if self.message.startswith("refused") else "color:#555"
        return f"<div data-field='message' style='font-size:12px;{style}'>{_esc(self.message) or '&nbsp;'}</div>"

    def _say(self, text: str) -> None:
        self.message = text
        self._set_html("message", self._message_html())

    def refuse(self, error: AkarmError, joint: str | None = None) -> None:
        """Say on the page that a command was refused, and why; the joint's slider goes back to the arm."""
        self.refusals += 1
        self._say(f"refused: {error}")
        self.log(f"akarm view: refused: {error}")
        if joint in self._touched:
            self._touched[joint] = 0.0

    def _command(self, op: str) -> None:
        controls = self.source.controls
        assert controls is not None
        with self._jog_cv:
            self._jog_pending = None  # a jog waiting to be sent is dropped by any button
        try:
            getattr(controls, op)()
        except AkarmError as e:
            self.refuse(e)
            return
        self._say({"enable": "enabled: holding", "hold": "holding", "disable": "disabled"}[op])
        with contextlib.suppress(Exception):
            self.update()

    def _slider_callback(self, joint: str) -> Callable[[Any], None]:
        return lambda event: self._on_slider(joint, event)

    def _on_slider(self, joint: str, event: Any) -> None:
        if event.client is None:  # the view moved it to follow the arm
            return
        self._touched[joint] = time.monotonic()
        self.request_jog(joint, float(self._sliders[joint].value))

    def _on_jog_button(self, event: Any) -> None:
        self.request_jog(str(self._gui["jog_joint"].value), self._gui["jog_to"].value)

    def request_jog(self, joint: str, value: Any) -> None:
        """A jog the page asked for (a slider, or Jog with a typed angle): checked here (the joint's
        range, the arm enabled) and refused on the page, or handed to ``akarm-view-jog``."""
        controls = self.source.controls
        assert controls is not None
        try:
            value = controls.check_jog(joint, value)
            if self.last is None or not self.last.enabled:
                raise StateError("the arm is not enabled", joint=joint, fix="press Enable first")
        except AkarmError as e:
            self.refuse(e, joint)
            return
        with self._jog_cv:
            self._jog_pending = (joint, value)
            self._jog_cv.notify()

    def jog(self, joint: str, value: float) -> None:
        """Jog ``joint`` to ``value`` rad as the page's slider does (refusals are said on the page and raised)."""
        controls = self.source.controls
        if controls is None:
            raise StateError("this view has no controls (it is not attached to a server)")
        try:
            controls.jog(joint, value, float(self._gui["jog_speed"].value))
        except AkarmError as e:
            self.refuse(e, joint)
            raise
        self._say(f"jog {joint} → {value:+.4f} rad")

    def _jog_loop(self) -> None:
        while not self._stop.is_set():
            with self._jog_cv:
                while self._jog_pending is None and not self._stop.is_set():
                    self._jog_cv.wait(0.5)
                pending, self._jog_pending = self._jog_pending, None
            if pending is not None:
                with contextlib.suppress(AkarmError):  # said on the page by jog()
                    self.jog(*pending)

    def _sync_controls(self, snap: Snapshot) -> None:
        if not self._sliders:
            return
        disabled = not snap.enabled
        if disabled != self._sliders_disabled:
            for slider in self._sliders.values():
                slider.disabled = disabled
            self._sliders_disabled = disabled
        now = time.monotonic()
        for k, (name, slider) in enumerate(self._sliders.items()):
            if now - self._touched[name] < SLIDER_HANDS_OFF or (self._jog_pending or ("",))[0] == name:
                continue
            target = snap.q_des[k] if math.isfinite(snap.q_des[k]) else snap.q[k]
            if not math.isfinite(target):
                continue
            target = round(min(max(target, slider.min), slider.max), 4)
            if abs(float(slider.value) - target) > 5e-4:
                slider.value = target


def jaw_text(snap: Snapshot) -> str:
    """The label at the jaws: their width (mm), and the squeeze while they hold something."""
    if not math.isfinite(snap.gripper_width):
        return f"{snap.gripper or 'gripper'}: not heard"
    text = f"{snap.gripper_width * 1e3:.1f} mm"
    return text + (f" · {snap.gripper_force:.1f} N" if snap.gripper_grasped else "")


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """Rich's console (viser prints through it) says nothing while inside."""
    import rich

    console = rich.get_console()
    before, console.quiet = console.quiet, True
    try:
        yield
    finally:
        console.quiet = before


def _no_share_url(verbose: bool = True) -> None:
    """In place of viser's share URL: the page is never published beyond the address it binds."""
    return None


def _esc(text: str) -> str:
    from html import escape

    return escape(text, quote=True)
