"""Motion planning in joint and Cartesian space; recordings to replay.

- :mod:`akarm.motion.trajectory`: jerk-limited plans (ruckig), exact extrema, limit checks, stops.
- :mod:`akarm.motion.timed`: plans through points reached at given times (ROS 2 trajectories).
- :mod:`akarm.motion.cartesian`: straight lines of the tool, timed on the path parameter.
- :mod:`akarm.motion.recording`: keyframes and recorded paths, their files and their checks.
"""
