"""Teleoperation: a hand guides a leader arm, a follower arm copies it, with force feedback, and
episodes are recorded as LeRobotDataset v3.0 (:mod:`akarm.datasets`).

:class:`Teleop` (:mod:`akarm.teleop.session`) drives two :class:`~akarm.Arm`\\ s through their public
API; :class:`Pairing` (:mod:`akarm.teleop.pairing`) says which joints pair; :class:`EpisodeRecorder`
(:mod:`akarm.teleop.recording`, needs the ``data`` extra) samples the session into episodes.
"""

from __future__ import annotations

from akarm.teleop.pairing import Pair, Pairing
from akarm.teleop.session import Step, Summary, Teleop, stopping_distance

__all__ = ["Pair", "Pairing", "Step", "Summary", "Teleop", "stopping_distance"]
