"""Camera frames as video, the way LeRobot stores them: MP4, AV1 (SVT-AV1), yuv420p, a keyframe every
2 frames, CRF 30 (LeRobot's own defaults, so a dataset akarm records decodes as one LeRobot records).

Written with PyAV (the ``video`` extra: ``pip install "akarm[video]"``), the FFmpeg binding LeRobot
itself encodes and decodes with.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Any

import numpy as np

from akarm.errors import ArgumentError, RecordingError
from akarm.files import atomic_write

__all__ = ["CODEC", "MAX_SIZE", "PIX_FMT", "check_frame_size", "decode_video", "encode_video", "require_av",
           "video_info"]

CODEC = "libsvtav1"  #: the encoder (FFmpeg's name); LeRobot's default
PIX_FMT = "yuv420p"
GOP = 2  #: frames between keyframes (LeRobot's ``g``: a frame is found fast when training samples it)
CRF = 30
MAX_SIZE = 4096  #: pixels on a side at most


def check_frame_size(width: object, height: object) -> tuple[int, int]:
    """``(width, height)`` as pixels, each an even number (what yuv420p video takes) of 8 to :data:`MAX_SIZE`."""
    ok = all(isinstance(v, int) and not isinstance(v, bool) and 8 <= v <= MAX_SIZE and v % 2 == 0
             for v in (width, height))
    if not ok:
        raise ArgumentError(f"a camera of {width!r} × {height!r} pixels: each side must be an even number of "
                            f"8 to {MAX_SIZE}", fix="e.g. 96x96")
    return int(width), int(height)  # type: ignore[call-overload]


def require_av() -> Any:
    """PyAV (the ``av`` module), or a RecordingError saying how to install it."""
    try:
        import av
    except ImportError:
        raise RecordingError("camera frames are stored as video, which needs PyAV, not installed",
                             fix='pip install "akarm[video]" (or pip install av)') from None
    return av


def video_info(height: int, width: int, fps: int) -> dict[str, Any]:
    """The ``info`` of a video feature in meta/info.json, as LeRobot writes it."""
    return {"video.height": height, "video.width": width, "video.codec": "av1", "video.pix_fmt": PIX_FMT,
            "video.is_depth_map": False, "video.fps": fps, "video.channels": 3, "has_audio": False}


def encode_video(path: str | os.PathLike[str], frames: np.ndarray, fps: int) -> Path:
    """Write ``frames`` (n × height × width × 3, RGB uint8) as an MP4 at ``path``, atomically.

    Raises:
        ArgumentError: frames of another shape or type. RecordingError: PyAV missing, or it failed.
    """
    if not (isinstance(frames, np.ndarray) and frames.ndim == 4 and frames.shape[-1] == 3
            and frames.dtype == np.uint8 and len(frames) > 0 and frames.shape[1] % 2 == 0 and frames.shape[2] % 2 == 0):
        raise ArgumentError(f"camera frames of shape {getattr(frames, 'shape', None)} and type "
                            f"{getattr(frames, 'dtype', None)}: n × height × width × 3 uint8 (even sides) are needed",
                            fix="give RGB frames, as the camera makes them")
    av = require_av()
    os.environ.setdefault("SVT_LOG", "1")  # SVT-AV1's banner and notes on stderr: errors only

    def write(f: io.BufferedWriter) -> None:
        with av.open(f, mode="w", format="mp4") as out:
            stream = out.add_stream(CODEC, rate=fps, options={"g": str(GOP), "crf": str(CRF), "preset": "10"})
            stream.pix_fmt = PIX_FMT
            stream.width, stream.height = int(frames.shape[2]), int(frames.shape[1])
            for img in frames:
                for packet in stream.encode(av.VideoFrame.from_ndarray(img, format="rgb24")):
                    out.mux(packet)
            for packet in stream.encode():
                out.mux(packet)

    try:
        return atomic_write(path, write)
    except RecordingError:
        raise
    except Exception as e:  # FFmpeg's errors (av.FFmpegError and its kin): the file was not written
        raise RecordingError(f"cannot encode {path}: {e}", fix="check PyAV's FFmpeg has SVT-AV1 (PyPI's wheels do)") \
            from None


def decode_video(path: str | os.PathLike[str]) -> np.ndarray:
    """Every frame of the video at ``path``, n × height × width × 3 RGB uint8 (for tests and checks)."""
    av = require_av()
    try:
        with av.open(str(path)) as f:
            return np.stack([frame.to_ndarray(format="rgb24") for frame in f.decode(video=0)])
    except Exception as e:
        raise RecordingError(f"cannot decode {path}: {e}", fix="the dataset is damaged; record it again") from None
