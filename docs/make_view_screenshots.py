"""Take the screenshots of the live view's page (docs/view.md): ``docs/view-arm6-live.png`` and
``docs/view-recorded.png``.

Run from the repository root (needs the ``view-test`` extra and Chromium, as tests/system/test_view.py)::

    .venv/bin/python docs/make_view_screenshots.py

Live: arm6 simulated in this process (in lock step with its Arm), moving through the demo's
figure-eight path (``akarm/data/demo_path.csv``), watched as ``akarm demo --view`` watches it (an
Arm's view has no controls: those come with a server), in a headless Chromium, shot mid-path.
Recorded: that run's telemetry saved as CSV and played back (``akarm view --play``), shot half
way through, with the time slider there.
"""

from __future__ import annotations

import contextlib
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import akarm  # noqa: E402
from akarm.sim import SimulatedRobot  # noqa: E402
from akarm.view import browser  # noqa: E402
from akarm.view.page import ViewServer  # noqa: E402
from akarm.view.recorded import RecordedSource, read_telemetry  # noqa: E402
from akarm.view.sources import ArmSource  # noqa: E402

DOCS = ROOT / "docs"
PATH = ROOT / "akarm" / "data" / "demo_path.csv"
SHOT_AT = 4.6  # s into the path: the arm out on the figure eight, away from where it began


def dismiss_notices(page: Any) -> None:
    """Close the browser's notices (headless Chromium draws WebGL in software, and viser says so)."""
    for button in page.locator(".mantine-Notification-closeButton").all():
        with contextlib.suppress(Exception):
            button.click(timeout=1000)
    time.sleep(0.5)


def main() -> None:
    why_not = browser.unavailable()
    if why_not:
        sys.exit(why_not)
    # the simulator in lock step with the Arm (its loop steps the simulated time): nothing here waits on
    # the wall clock, so a loaded machine cannot stop the arm; the view watches it as it watches a live one
    config = akarm.load_robot(ROOT / "robots" / "arm6.yaml").with_bus(interface="virtual", channel="view-shots")
    with tempfile.TemporaryDirectory() as d, SimulatedRobot(config, realtime=False) as sim, \
            akarm.Arm(config, clock=sim.clock) as arm:
        arm.enable()
        arm.move_to("ready")
        with ViewServer(config, ArmSource(arm, title="live: arm6, simulated"), port=0, log=lambda text: None) as view, \
                browser.headless_page(view.url, width=1400, height=900) as page:
            start = arm.state().time
            arm.sleep(2.0)  # two seconds held at ready, then the 7 s path (it ends where it began)
            motion = arm.replay(PATH, wait=False)
            # mid-path, paced at about the wall clock's rate, so the view's 30 Hz snapshots fill its plots
            # (in lock step the arm waits between the steps; unpaced, 7 s of path pass in a moment)
            for _ in range(int(SHOT_AT / 0.05)):
                arm.sleep(0.05)
                time.sleep(0.05)
            time.sleep(2.0)  # for the page to draw the last of it
            dismiss_notices(page)
            page.screenshot(path=str(DOCS / "view-arm6-live.png"))
            motion.wait()
            run = arm.telemetry(since=start).save(Path(d) / "run.csv")
            rec = RecordedSource(read_telemetry(run), config.joint_names, title=f"recording: {run.name}")
    rec.position = rec.duration / 2
    with ViewServer(config, rec, port=0, log=lambda text: None) as view, \
            browser.headless_page(view.url, width=1400, height=900) as page:
        time.sleep(3.0)
        dismiss_notices(page)
        page.screenshot(path=str(DOCS / "view-recorded.png"))
    print("wrote docs/view-arm6-live.png, docs/view-recorded.png")


if __name__ == "__main__":
    main()
