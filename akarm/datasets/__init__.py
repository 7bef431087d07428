"""Learning data: episodes written and read as LeRobotDataset v3.0 (:mod:`akarm.datasets.lerobot`).

Needs pyarrow (the ``data`` extra: ``pip install "akarm[data]"``).
"""

from __future__ import annotations

from akarm.datasets.lerobot import (
    CODEBASE_VERSION,
    GRIPPER,
    DatasetWriter,
    Episode,
    EpisodeFrames,
    LeRobotDataset,
    read_dataset,
)

__all__ = ["CODEBASE_VERSION", "GRIPPER", "DatasetWriter", "Episode", "EpisodeFrames", "LeRobotDataset", "read_dataset"]
