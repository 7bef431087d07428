"""Camera frames as video, the way LeRobot stores them: MP4, AV1 (SVT-AV1), yuv420p, a keyframe every
2 frames, CRF 30 (LeRobot's own defaults, so a dataset akarm records decodes as one LeRobot records).

Written with PyAV (the ``video`` extra: ``pip install "akarm[video]"``), the FFmpeg binding LeRobot
itself encodes and decodes with.

:func:`encode_episode` encodes in a process of its own (``python -m akarm.datasets.video``): PyAV and
the stats' numpy hold the interpreter for 20-40 ms at a time (measured here: a thread ticking every
1 ms saw gaps of 33-41 ms while 30-300 frames were encoded in its process), which would starve the
arms' loops of a teleoperation session that saves an episode.
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from akarm.config.frames import MAX_SIZE, check_frame_size
from akarm.errors import ArgumentError, RecordingError
from akarm.files import atomic_write

__all__ = ["CODEC", "MAX_SIZE", "PIX_FMT", "QUANTILES", "check_frame_size", "decode_video", "encode_episode",
           "encode_video", "image_stats", "main", "require_av", "video_info"]

CODEC = "libsvtav1"  #: the encoder (FFmpeg's name); LeRobot's default
PIX_FMT = "yuv420p"
GOP = 2  #: frames between keyframes (LeRobot's ``g``: a frame is found fast when training samples it)
CRF = 30
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)  #: the quantiles LeRobot's stats carry (q01 ... q99)


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


def image_stats(frames: np.ndarray) -> dict[str, np.ndarray]:
    """Per colour channel (0-1), shaped (3, 1, 1) as LeRobot's image stats: min, max, mean, std, count
    (the frames looked at) and the quantiles, of ``frames`` (n × height × width × 3 uint8; at most 100
    of them, evenly spread)."""
    step = max(1, len(frames) // 100)
    x = frames[::step].reshape(-1, 3).astype(np.float64) / 255.0
    out = {"min": x.min(axis=0), "max": x.max(axis=0), "mean": x.mean(axis=0), "std": x.std(axis=0)}
    for q in QUANTILES:
        out[f"q{round(q * 100):02d}"] = np.quantile(x, q, axis=0)
    stats = {k: v.reshape(3, 1, 1) for k, v in out.items()}
    stats["count"] = np.array([len(frames[::step])])
    return stats


def encode_episode(path: str | os.PathLike[str], frames: np.ndarray, fps: int,
                   timeout: float = 600.0) -> dict[str, np.ndarray]:
    """:func:`encode_video` and :func:`image_stats` of ``frames``, in a process of their own (see the
    module's docstring); the stats.

    Raises:
        ArgumentError: frames of another shape or type. RecordingError: PyAV missing, or the encoding failed.
    """
    target = Path(path)
    if not (isinstance(frames, np.ndarray) and frames.ndim == 4 and frames.dtype == np.uint8):
        raise ArgumentError(f"camera frames of shape {getattr(frames, 'shape', None)}: n × height × width × 3 uint8",
                            fix="give RGB frames, as the camera makes them")
    require_av()
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, raw = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".npy", dir=target.parent)
    os.close(fd)
    try:
        np.save(raw, frames)
        done = subprocess.run([sys.executable, "-m", "akarm.datasets.video", raw, str(target), str(int(fps))],
                              capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        raise RecordingError(f"encoding {target} took over {timeout:g} s", fix="record shorter episodes") from None
    finally:
        Path(raw).unlink(missing_ok=True)
    if done.returncode != 0:
        lines = [line for line in done.stderr.splitlines() if line.strip() and not line.startswith("Svt[")]
        raise RecordingError(f"cannot encode {target}: {lines[-1] if lines else done.returncode}",
                             fix="check PyAV's FFmpeg has SVT-AV1 (PyPI's wheels do)")
    return {k: np.asarray(v) for k, v in json.loads(done.stdout).items()}


def main(argv: list[str] | None = None) -> int:
    """``python -m akarm.datasets.video FRAMES.npy OUT.mp4 FPS``: encode, print the stats as JSON."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 3:
        print("usage: python -m akarm.datasets.video FRAMES.npy OUT.mp4 FPS", file=sys.stderr)
        return 2
    try:
        frames = np.load(args[0], allow_pickle=False)
        encode_video(args[1], frames, int(args[2]))
        stats = image_stats(frames)
    except (ArgumentError, RecordingError, OSError, ValueError) as e:
        print(f"akarm.datasets.video: {e}", file=sys.stderr)
        return 1
    print(json.dumps({k: v.tolist() for k, v in stats.items()}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
