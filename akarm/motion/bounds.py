"""How large a motion may be: the bounds every reader and planner of motions checks first.

A recording, a trajectory or a replay past one of these is refused, naming the bound, before anything
is read in full, planned or moved; whatever is within them is read, checked and planned in time and
memory proportional to its size. One place, so that the file readers (``akarm.motion.recording``),
the planner's callers (``Arm.follow``, ``Arm.replay``, ``move_through``) and the server agree.

The values: a one-hour path taught at 500 Hz (1.8 million samples) fits; so do 5000 keyframes; a
ROS 2 trajectory of 100 000 points does not (MoveIt sends hundreds).
"""

from __future__ import annotations

#: Keyframes in one keyframe file or one ``move_through``.
MAX_KEYFRAMES = 10_000
#: Samples in one recorded path (a one-hour path at 500 Hz is 1 800 000).
MAX_PATH_SAMPLES = 2_000_000
#: Points in one timed trajectory (``Arm.follow``, a ROS 2 JointTrajectory or action goal).
MAX_TRAJECTORY_POINTS = 10_000
#: Seconds a recording, a trajectory or a replay may last.
MAX_DURATION = 4 * 3600.0

__all__ = ["MAX_DURATION", "MAX_KEYFRAMES", "MAX_PATH_SAMPLES", "MAX_TRAJECTORY_POINTS"]
