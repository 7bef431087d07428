"""`akarm view` in a real browser: Debian's Chromium, headless, driven by playwright.

The simulator runs in its own process (its control channel tells the truth about the drivers);
`akarm serve --view` in another, serving the page; this process is the browser's user. A recorded
run is played back by `akarm view --play`. For a URDF with meshes, example-robot-data's SO-100 arm
(the `view-test` extra) is drawn. Skipped, with the reason, where playwright or Chromium is missing.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from akarm.buses.ownership import find_server
from akarm.robotfile.load import load_robot
from akarm.server.snapshot import Snapshot
from akarm.sim.process import SimulatorProcess
from akarm.view import browser
from akarm.view.sources import RemoteSource

from .conftest import ROBOTS, relaxed_robot, wait_until

pytestmark = [pytest.mark.slow, pytest.mark.skipif(browser.unavailable() is not None,
                                                    reason=f"no headless browser: {browser.unavailable()}")]
pytest.importorskip("viser", reason="the view extra is not installed (pip install -e \".[view]\")")

ARM6 = ROBOTS / "arm6.yaml"
_count = itertools.count()
#: s a browser on a loaded machine gets to show a change: with software WebGL on 2 cores shared by
#: other work (load average 15), the page took 50 s to load and a screenshot of its canvas 30 s
PAGE_TIMEOUT = 240.0


def shown(url: str) -> contextlib.AbstractContextManager[browser.Page]:
    """The page in a headless Chromium's small window (every frame is drawn in software)."""
    return browser.headless_page(url, width=960, height=640, timeout=PAGE_TIMEOUT)


class Process:
    """An akarm verb in a child process whose output is read as it comes; ``url`` is its view's."""

    def __init__(self, *args: str) -> None:
        self.command = [sys.executable, "-m", "akarm", *args]
        self.lines: list[str] = []
        self.url = ""
        self.proc: subprocess.Popen[str] | None = None

    def __enter__(self) -> Process:
        self.proc = subprocess.Popen(self.command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        started = threading.Event()

        def read() -> None:
            for line in self.proc.stdout:  # type: ignore[union-attr]
                self.lines.append(line)
                found = re.match(r"view: (http://\S+)", line)
                if found:
                    self.url = found.group(1)
                    started.set()
            started.set()

        threading.Thread(target=read, daemon=True).start()
        if not started.wait(PAGE_TIMEOUT) or not self.url:
            self.__exit__()
            pytest.fail(f"{' '.join(self.command[2:4])} did not serve its view:\n" + "".join(self.lines))
        return self

    def __exit__(self, *exc: object) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait(60)


class Served:
    def __init__(self, robot: Path, channel: str, sim: SimulatorProcess, server: Process) -> None:
        self.robot, self.channel, self.sim, self.server = robot, channel, sim, server
        self.config = load_robot(robot)

    def sim_q(self) -> dict[str, float]:
        return {s.name: s.position for s in self.sim.control.state()}

    def sim_enabled(self) -> list[bool]:
        return [s.enabled for s in self.sim.control.state()]

    def server_snapshot(self) -> Snapshot:
        """The server's own state, through its socket (the page may show it late on a starved machine)."""
        info = find_server(self.config.with_bus(interface="akarm_local", channel=self.channel), wait=10.0)
        assert info is not None, "akarm serve no longer holds the bus"
        source = RemoteSource(self.config, info, timeout=PAGE_TIMEOUT)
        try:
            return source.snapshot()
        finally:
            source.close()


def calm_robot(directory: Path) -> Path:
    """arm6 with the relaxed supervisor of a loaded machine (:func:`relaxed_robot`, and a 2 s watchdog)
    and no collision thresholds: on 2 busy cores a late reply reads as a push, and these tests are
    about the page."""
    import yaml

    path = relaxed_robot(ARM6, directory)
    doc = yaml.safe_load(path.read_text())
    # the watchdog waits 2 s: seen here, with the load average at 16, the server's first feedback
    # came 0.5 s late while it enabled (the simulator's process starved), and the fixture failed
    doc["defaults"]["feedback_timeout"] = 2.0
    for joint in doc["joints"]:
        joint.pop("collision", None)
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    robot = calm_robot(tmp_path_factory.mktemp("view"))
    channel = f"view{os.getpid()}_{next(_count)}"
    with SimulatorProcess(robot, channel=channel, pose="home", control=True) as sim, \
            Process("serve", str(robot), "-i", "akarm_local", "-c", channel, "--no-ros", "--view",
                    "--view-port", "0", "--stall-limit", "2.0") as server:  # (Chromium shares the 2 cores)
        yield Served(robot, channel, sim, server)


def diagnosis(page: browser.Page, served: Served) -> str:
    """What a failed check needs: the page's mode, stop and message, every simulated driver, the last
    command each took in (decoded), and the server's output."""
    from akarm.protocol import mit

    lines = [f"page: mode {browser.page_text(page, 'mode')!r} stop {browser.page_text(page, 'stop')!r} "
             f"message {browser.page_text(page, 'message')!r}"]
    lines += [str(s) for s in served.sim.control.state()]
    frames, _ = served.sim.control.frames()
    last: dict[str, str] = {}
    for f in frames:
        if f.to_motor and f.joint is not None:
            j = served.config.joint(f.joint)
            special = mit.special_frame(f.data)
            last[f.joint] = (f"t {f.t:.3f} {special}" if special is not None else
                             f"t {f.t:.3f} {mit.codec(j.motor).decode_command(f.data, firmware=j.firmware)}")
    lines += [f"last command to {name}: {text}" for name, text in last.items()]
    snap = served.server_snapshot()
    lines.append(f"server: mode {snap.mode!r} stop {snap.stop!r} q {np.round(snap.q, 4).tolist()}")
    return "\n".join(lines) + "\nserver:\n" + "".join(served.server.lines[-40:])


#: the stops a starved machine causes (the loop or the simulator's process not run for seconds): the
#: server stopped the arm as it must, and the page showed it; these tests are about the page
LOAD_STOPS = ("the control loop did not run for", "no reply to its last", "out of motor mode")


def until_done_or_stopped(page: browser.Page, served: Served, done: Callable[[], bool]) -> None:
    """Wait for ``done``; when the server latched a stop instead (asked through its socket), skip if
    the stop is one a starved machine causes (:data:`LOAD_STOPS`), else fail; either way with
    :func:`diagnosis`."""
    def stopped() -> str:
        return served.server_snapshot().stop

    if wait_until(lambda: done() or bool(stopped()), PAGE_TIMEOUT) and done():
        return
    stop = stopped()
    if stop and any(s in stop for s in LOAD_STOPS):
        pytest.skip(f"the machine could not keep time, and the server stopped the arm: {stop}\n"
                    + diagnosis(page, served))
    pytest.fail(("the server stopped the arm" if stop else "the arm did not get there") + "\n"
                + diagnosis(page, served))


def enabled(page: browser.Page, served: Served) -> None:
    """The arm enabled through the page (Enable), holding."""
    if browser.page_text(page, "mode") != "holding":
        page.get_by_role("button", name="Enable").click()
    assert wait_until(lambda: browser.page_text(page, "mode") == "holding", PAGE_TIMEOUT), \
        (browser.page_text(page, "mode"), browser.page_text(page, "stop"), browser.page_text(page, "message"),
         "".join(served.server.lines))
    assert all(served.sim_enabled())


def test_the_page_draws_the_arm(served: Served) -> None:
    with shown(served.server.url) as page:
        assert "URDF's visuals" in browser.page_text(page, "figure")  # arm6.urdf's shapes
        # the canvas is not blank: the links (orange), motors (dark) and ghost (blue) cover part of it
        assert wait_until(lambda: browser.drawn_fraction(browser.canvas_image(page)) > 0.01, PAGE_TIMEOUT), \
            browser.drawn_fraction(browser.canvas_image(page))
        # hiding the arm (Display: the ghost, the tool frame) takes colour away: the colour was the arm's
        with_arm = browser.drawn_fraction(browser.canvas_image(page))
        page.get_by_text("Display").click()
        page.get_by_label("commanded pose (ghost)").uncheck()
        page.get_by_label("tool frame").uncheck()
        assert wait_until(lambda: browser.drawn_fraction(browser.canvas_image(page)) < with_arm, PAGE_TIMEOUT)


def test_the_values_shown_follow_the_simulator(served: Served) -> None:
    with shown(served.server.url) as page:
        enabled(page, served)
        before = browser.joint_values(page)
        # to whichever of ready (elbow 1.3) and home (0.6) is farther from where the page shows the arm
        name = "ready" if abs(before["elbow"] - 1.3) > abs(before["elbow"] - 0.6) else "home"
        pose = dict(zip(served.config.joint_names, served.config.pose(name), strict=True))
        done = subprocess.run([sys.executable, "-m", "akarm", "move", str(served.robot), name, "-i", "akarm_local",
                               "-c", served.channel], capture_output=True, text=True, timeout=PAGE_TIMEOUT)
        assert done.returncode == 0, done.stdout + done.stderr

        def shown_matches() -> bool:  # the page's measured positions against the simulator's truth
            truth, shown = served.sim_q(), browser.joint_values(page)
            return all(abs(shown[n] - truth[n]) < 1e-3 for n in truth)

        until_done_or_stopped(page, served, shown_matches)
        after = browser.joint_values(page)
        assert abs(after["elbow"] - before["elbow"]) > 0.3  # the values shown did change, with the arm
        assert all(abs(after[n] - pose[n]) < 0.02 for n in pose)


def test_a_jog_past_a_joint_limit_is_refused(served: Served) -> None:
    upper = served.config.joint("elbow").limits.upper
    with shown(served.server.url) as page:
        enabled(page, served)
        start = served.sim_q()["elbow"]
        browser.jog_to(page, "elbow", f"{upper + 0.4:.2f}")  # the box takes any number; the page checks it
        assert wait_until(lambda: "refused" in browser.page_text(page, "message"), PAGE_TIMEOUT)
        assert "past the upper limit" in browser.page_text(page, "message")
        time.sleep(1.0)
        assert abs(served.sim_q()["elbow"] - start) < 0.01  # nothing moved
        assert browser.page_text(page, "mode") == "holding"  # and the arm is still held
        # a jog within the range goes through the planner to the simulated joint
        target = round(min(upper - 0.2, start + 0.3), 2)
        browser.jog_to(page, "elbow", f"{target:.2f}")
        until_done_or_stopped(page, served, lambda: abs(served.sim_q()["elbow"] - target) < 2e-3)
        assert served.sim_q()["elbow"] <= upper


def test_disable_in_the_page_disables_the_simulated_drivers(served: Served) -> None:
    with shown(served.server.url) as page:
        enabled(page, served)
        page.get_by_role("button", name="Disable").click()
        assert wait_until(lambda: not any(served.sim_enabled()), PAGE_TIMEOUT), served.sim.control.state()
        assert wait_until(lambda: browser.page_text(page, "mode") == "disabled", PAGE_TIMEOUT)


def test_a_recorded_run_plays_back(tmp_path: Path) -> None:
    from akarm.telemetry.log import TelemetryLog

    config = load_robot(ARM6)
    n = len(config.joints)
    t = np.linspace(0.0, 4.0, 401)
    q = np.outer(np.minimum(t, 2.0) / 2.0, np.array(config.pose("ready")))  # home-ish to ready in 2 s, then still
    log = TelemetryLog(config.joint_names, t, q, np.zeros_like(q), q + 1e-3, np.zeros_like(q), np.ones((len(t), n)),
                       np.zeros_like(q))
    path = log.save(tmp_path / "run.csv")
    with Process("view", str(ARM6), "--play", str(path), "--port", "0") as viewer, \
            shown(viewer.url) as page:
        assert browser.page_text(page, "mode") == "recorded"
        assert abs(browser.joint_values(page)["elbow"] - 1e-3) < 1e-4  # the first cycle
        page.get_by_role("button", name="Play").click()
        end = config.pose("ready")[2] + 1e-3
        assert wait_until(lambda: abs(browser.joint_values(page)["elbow"] - end) < 1e-4, PAGE_TIMEOUT)


def test_a_urdf_with_meshes_is_drawn_with_them(tmp_path: Path) -> None:
    urdf = _example_robot_data("so_arm_description/urdf/so100.urdf")
    robot = tmp_path / "so100.yaml"
    made = subprocess.run([sys.executable, "-m", "akarm", "init", str(urdf), "-o", str(robot)], capture_output=True,
                          text=True, timeout=300)
    assert robot.is_file(), made.stdout + made.stderr
    from akarm.telemetry.log import TelemetryLog

    config = load_robot(robot)
    q = np.zeros((2, len(config.joints)))
    path = TelemetryLog(config.joint_names, np.array([0.0, 1.0]), q, q, q, q, q, q).save(tmp_path / "still.csv")
    with Process("view", str(robot), "--play", str(path), "--port", "0") as viewer, \
            shown(viewer.url) as page:
        figure = page.locator("[data-field=figure]")
        assert figure.get_attribute("data-kind") == "visuals"
        assert int(figure.get_attribute("data-parts") or 0) == 13  # so100.urdf's 13 STL visuals, all drawn
        assert "not drawn" not in figure.inner_text()
        assert wait_until(lambda: browser.drawn_fraction(browser.canvas_image(page)) > 0.01, PAGE_TIMEOUT)


def _example_robot_data(relative: str) -> Path:
    import site

    for base in [*site.getsitepackages(), site.getusersitepackages()]:
        path = Path(base) / "cmeel.prefix" / "share" / "example-robot-data" / "robots" / relative
        if path.is_file():
            return path
    pytest.skip("example-robot-data is not installed (pip install -e \".[view-test]\"): no URDF with meshes")

