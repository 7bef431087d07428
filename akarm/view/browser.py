"""The view in a headless browser: for tests, screenshots and benchmarks.

Debian's Chromium (``apt-get install chromium``) driven by playwright's Python driver (``pip install
playwright``; the ``view-test`` extra), never a browser that playwright downloads itself: there is
no ``playwright install`` here. The browser renders WebGL in software (no GPU needed).

::

    from akarm.view.browser import headless_page, unavailable
    if unavailable() is None:
        with headless_page("http://localhost:8080") as page:
            page.screenshot(path="view.png")
            print(joint_values(page))          # {"elbow": 1.2999, ...}, as the page shows them
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from playwright.sync_api import Locator, Page

__all__ = ["CHROMIUM_FLAGS", "canvas_image", "chromium", "drawn_fraction", "headless_page", "jog_box", "jog_to",
           "joint_values", "page_text", "unavailable", "wait_for_view"]

#: how Chromium runs here: no sandbox (root in a container), software WebGL, nothing fetched in the background
CHROMIUM_FLAGS = ("--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-dev-shm-usage",
                  "--disable-extensions", "--no-first-run", "--mute-audio")

# scripts run in the page: each reads what it needs in one go (the panel is redrawn ten times a
# second, and the plots' canvases with it, so an element found now may be gone a moment later)
_TEXT = "f => { const e = document.querySelector(`[data-field=${f}]`); return e ? e.textContent : ''; }"
_COLUMN = """f => Array.from(document.querySelectorAll('tr[data-joint]'),
    r => [r.dataset.joint, (r.querySelector(`td[data-field=${f}]`) || {}).textContent || ''])"""
_VIEW_SHOWN = "() => !!document.querySelector('canvas') && !!document.querySelector('tr[data-joint] td[data-field=q]')"
_LARGEST_CANVAS = """() => {
    let best = null;
    for (const c of document.querySelectorAll('canvas')) {
        const r = c.getBoundingClientRect();
        if (!best || r.width * r.height > best.width * best.height)
            best = {x: r.x, y: r.y, width: r.width, height: r.height};
    }
    return best;
}"""


def chromium() -> str | None:
    """The Chromium executable: ``$AKARM_CHROMIUM``, else Debian's (``chromium``, ``chromium-browser``)."""
    named = os.environ.get("AKARM_CHROMIUM")
    if named:
        return named if os.path.isfile(named) else None
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


def unavailable() -> str | None:
    """Why no headless browser can be had here (for a skip reason), or ``None`` when one can."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "playwright is not installed (pip install -e \".[view-test]\")"
    if chromium() is None:
        return "no Chromium (apt-get install chromium, or set AKARM_CHROMIUM to its executable)"
    return None


@contextlib.contextmanager
def headless_page(url: str, width: int = 1280, height: int = 800, timeout: float = 180.0) -> Iterator[Page]:
    """A page of a headless Chromium showing ``url``, with the view loaded (:func:`wait_for_view`)."""
    from playwright.sync_api import sync_playwright

    executable = chromium()
    if executable is None:
        raise RuntimeError(unavailable() or "no Chromium")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=executable, headless=True, args=list(CHROMIUM_FLAGS))
        try:
            page = browser.new_page(viewport={"width": width, "height": height})
            page.set_default_timeout(timeout * 1000)
            page.goto(url)
            wait_for_view(page, timeout)
            yield page
        finally:
            browser.close()


def wait_for_view(page: Page, timeout: float = 180.0) -> None:
    """Until the page has its 3D canvas and its state panel shows the arm."""
    # (a script polled every 250 ms, not wait_for_selector: the panel's cells are replaced ten times a
    # second, and playwright's handle on the first one found may never come back)
    page.wait_for_function(_VIEW_SHOWN, polling=250, timeout=timeout * 1000)


def page_text(page: Page, field: str) -> str:
    """The text of the page's first ``data-field`` element (``mode``, ``stop``, ``loop``, ``message``,
    ``figure``); ``""`` when there is none. Read in one go: the panel is redrawn ten times a second."""
    text = page.evaluate(_TEXT, field)
    return str(text).strip()


def joint_values(page: Page, field: str = "q") -> dict[str, float]:
    """A column of the state panel as the page shows it (``q``, ``q_des``, ``error``, ``tau``, ...): joint → value;
    NaN where it shows none."""
    cells = page.evaluate(_COLUMN, field)
    out: dict[str, float] = {}
    for name, text in cells:
        try:
            out[str(name)] = float(str(text).strip().replace("−", "-"))
        except ValueError:
            out[str(name)] = float("nan")
    return out


def jog_box(page: Page, joint: str) -> Locator:
    """The number box beside ``joint``'s jog slider (typing a value there and pressing Enter jogs)."""
    return page.locator(f"xpath=//label[normalize-space()='{joint}']/ancestor::div[contains(@class,"
                        "'mantine-Flex-root')][1]//input[not(@type='hidden')]").first


def jog_to(page: Page, joint: str, value: str) -> None:
    """Jog as a user does with a typed angle: choose ``joint``, type ``value`` (as typed) in the
    "jog to" box, press Jog."""
    page.get_by_label("jog joint").first.click()
    page.get_by_role("option", name=joint, exact=True).click()
    box = page.get_by_label("jog to [rad]").first
    box.fill(value)
    box.press("Tab")  # the box hands its value over when it loses the focus
    page.get_by_role("button", name="Jog", exact=True).click()


def canvas_image(page: Page) -> np.ndarray:
    """The 3D canvas (the page's largest: the plots draw in canvases too) as pixels, (height, width, 3)
    uint8 (Pillow decodes the screenshot)."""
    from PIL import Image

    box = page.evaluate(_LARGEST_CANVAS)
    if not box or box["width"] * box["height"] == 0:
        raise RuntimeError("the page has no canvas")
    png = page.screenshot(clip=box)
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def drawn_fraction(image: np.ndarray) -> float:
    """The share of pixels that are neither the white background nor the grey grid: colour (the
    links, the ghost, the axes) or dark (the motors)."""
    rgb = image.astype(int)
    spread = rgb.max(axis=2) - rgb.min(axis=2)
    return float(np.mean((spread > 50) | (rgb.max(axis=2) < 90)))
