"""Take the screenshots of the documentation site: ``docs/site-home.png`` (the home page) and
``docs/site-api.png`` (the API reference of ``akarm.teleop``).

Run from the repository root, with the ``docs`` extra and Debian's Chromium (``apt-get install
chromium``; never a browser build of its own)::

    .venv/bin/python docs/make_site_screenshots.py

It builds the site strictly into a temporary folder, serves it on a free port of 127.0.0.1 and has a
headless Chromium (a fresh profile, nothing fetched from the network) shoot each page.
"""

from __future__ import annotations

import functools
import http.server
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
#: page of the site -> screenshot in docs/
SHOTS = {"": "site-home.png", "api/teleop/": "site-api.png"}
SIZE = (1280, 800)


def chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    sys.exit("no chromium: apt-get install chromium")


def shoot(browser: str, url: str, out: Path, profile: Path) -> None:
    subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                    "--disable-background-networking", "--disable-component-update", "--disable-sync",
                    f"--user-data-dir={profile}", "--hide-scrollbars", "--force-device-scale-factor=1",
                    f"--window-size={SIZE[0]},{SIZE[1]}", "--virtual-time-budget=3000",
                    f"--screenshot={out}", url], check=True, capture_output=True, timeout=120)
    print(f"{out.relative_to(ROOT)}: {url} ({out.stat().st_size // 1024} KiB)")


class Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:
        pass


def main() -> None:
    browser = chromium()
    with tempfile.TemporaryDirectory() as tmp:
        site = Path(tmp) / "site"
        subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)],
                       cwd=ROOT, check=True)
        handler = functools.partial(Quiet, directory=str(site))
        with http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler) as server:
            threading.Thread(target=server.serve_forever, daemon=True).start()
            base = f"http://127.0.0.1:{server.server_address[1]}/"
            try:
                for page, name in SHOTS.items():
                    shoot(browser, base + page, DOCS / name, Path(tmp) / f"profile-{name}")
            finally:
                server.shutdown()


if __name__ == "__main__":
    main()
