"""Camera frame sizes akarm takes: the one check the simulated camera (:mod:`akarm.sim.camera`) and the
datasets' video (:mod:`akarm.datasets.video`) share, so a size one accepts the other can encode."""

from __future__ import annotations

from akarm.errors import ArgumentError

__all__ = ["MAX_SIZE", "check_frame_size"]

MAX_SIZE = 4096  #: pixels on a side at most


def check_frame_size(width: object, height: object) -> tuple[int, int]:
    """``(width, height)`` as pixels, each an even number (what yuv420p video takes) of 8 to :data:`MAX_SIZE`."""
    ok = all(isinstance(v, int) and not isinstance(v, bool) and 8 <= v <= MAX_SIZE and v % 2 == 0
             for v in (width, height))
    if not ok:
        raise ArgumentError(f"a camera of {width!r} × {height!r} pixels: each side must be an even number of "
                            f"8 to {MAX_SIZE}", fix="e.g. 96x96")
    return int(width), int(height)  # type: ignore[call-overload]
