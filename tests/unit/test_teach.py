"""Recordings on their own: keyframe and path files round trip, bad files get clear errors, the
recorder keeps its grid through a stall (teach and replay on the simulator:
tests/system/test_teach_lockstep.py)."""

from __future__ import annotations

import os
import re

import numpy as np
import pytest

from akarm import RecordingError
from akarm.motion import recording as rec
from akarm.motion.trajectory import JointLimits

from ..system.test_teach_lockstep import NAMES, sweep


def test_keyframes_round_trip_and_are_readable(tmp_path) -> None:
    kf = rec.Keyframes(NAMES, (rec.Keyframe((0.1, -0.2), "pick"), rec.Keyframe((0.3, 0.25))), robot="planar2")
    path = kf.save(tmp_path / "k.yaml")
    text = path.read_text()
    assert "pick" in text and "units: rad" in text and "shoulder" in text
    back = rec.load(path, NAMES)
    assert back == kf
    assert not list(tmp_path.glob(".*.tmp"))
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask  # like open(), not mkstemp's 0600


def test_path_round_trip_with_header_naming_joints_and_units(tmp_path) -> None:
    p = sweep()
    path = p.save(tmp_path / "p.csv")
    assert path.read_text().splitlines()[0] == "t [s],shoulder [rad],elbow [rad]"
    back = rec.load(path, NAMES)
    np.testing.assert_allclose(back.q, p.q, atol=1e-6)
    np.testing.assert_allclose(back.t, p.t, atol=1e-6)


@pytest.mark.parametrize(("name", "content", "message"), [
    ("trunc.csv", "t [s],shoulder [rad],elbow [rad]\n0.0,0.1,0.2\n0.01,0.1", "row 3 has 2 values"),
    ("nan.csv", "t [s],shoulder [rad],elbow [rad]\n0.0,0.1,0.2\n0.01,nan,0.2\n", "not finite"),
    ("text.csv", "t [s],shoulder [rad],elbow [rad]\n0.0,0.1,0.2\n0.01,abc,0.2\n", "not a number"),
    ("back.csv", "t [s],shoulder [rad],elbow [rad]\n0.0,0.1,0.2\n0.0,0.1,0.2\n", "time does not increase"),
    ("head.csv", "time,a,b\n0,0,0\n", "header must start"),
    ("short.csv", "t [s],shoulder [rad],elbow [rad]\n0.0,0.1,0.2\n", "fewer than two samples"),
    ("bad.yaml", "joints: [shoulder, elbow]\nkeyframes:\n  - {q: [0.1, 0.2\n", "line 4: not valid YAML"),
    ("k.yaml", "joints: [shoulder, elbow]\nkeyframes:\n  - {q: [0.1]}\n", "keyframe 0 needs `q:` with 2"),
    ("none.yaml", "just: text\n", "not an akarm keyframe file"),
    ("other.yaml", "joints: [a, b]\nkeyframes:\n  - {q: [0.1, 0.2]}\n", "recorded for joints"),
    ("x.txt", "", "unknown recording type"),
])
def test_corrupt_or_truncated_recordings_get_clear_errors(tmp_path, name, content, message) -> None:
    f = tmp_path / name
    f.write_text(content)
    with pytest.raises(RecordingError, match=re.escape(message)):
        rec.load(f, NAMES)


def test_missing_file_is_a_recording_error(tmp_path) -> None:
    with pytest.raises(RecordingError, match="path recording not found"):
        rec.load(tmp_path / "nope.csv", NAMES)


WIDE_LIMITS = JointLimits(NAMES, np.array([-3.0, -3.0]), np.array([3.0, 3.0]), np.array([100.0, 100.0]),
                          np.array([1e4, 1e4]), np.array([1e6, 1e6]))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_path_with_a_value_that_is_not_finite_is_refused_before_replay(bad: float) -> None:
    p = sweep()
    q = p.q.copy()
    q[120:130, 1] = bad  # a damaged recording: NaN compares False with every limit, so it passed before
    plan = rec.PathPlan(rec.PathRecording(NAMES, p.t, q), 0.0, 1.0)
    message = r"the path's position is (nan|inf|-inf) at t = 1\.\d\d s: not a number"
    with pytest.raises(RecordingError, match=message) as e:
        rec.check_path(plan, WIDE_LIMITS)
    assert e.value.joint == "elbow"
    rec.check_path(rec.PathPlan(p, 0.0, 1.0), WIDE_LIMITS)  # the same path without them passes


def test_a_path_of_other_width_than_the_arms_joints_is_refused() -> None:
    p = sweep()
    wide = rec.PathRecording(NAMES, p.t, np.column_stack([p.q, p.q[:, :1]]))  # 3 values for 2 joints
    with pytest.raises(RecordingError, match=r"the path has 3 values per sample, the arm 2 joints \(shoulder, elbow\)"):
        rec.check_path(rec.PathPlan(wide, 0.0, 1.0), WIDE_LIMITS)


def test_the_recorder_keeps_its_grid_through_a_stall() -> None:
    from akarm.control.motions import PathRecorder as _PathRecorder

    rec = _PathRecorder(100.0, duration=0.1)
    cycles = [k * 0.002 for k in range(20)] + [0.0615 + k * 0.002 for k in range(40)]  # 21.5 ms stall at 40 ms
    for now in cycles:
        rec.sample(now, np.zeros(2))
    # the 10 ms grid up to the stall; the first cycle after it stands for 60 ms (40 and 50 are lost,
    # not sent in a burst), then the first cycle at or after each grid point, the last at 100 ms
    assert np.allclose(rec.times, [0.0, 0.01, 0.02, 0.03, 0.0615, 0.0715, 0.0815, 0.0915, 0.1015])
    assert rec.finished


def test_a_stall_across_the_end_of_a_timed_recording_does_not_stretch_it() -> None:
    from akarm.control.motions import PathRecorder

    rec = PathRecorder(100.0, duration=0.1)
    for now in [k * 0.002 for k in range(49)] + [0.1768]:  # a 79 ms stall across the last grid point
        rec.sample(now, np.zeros(2))
    assert rec.finished and rec.times[-1] == pytest.approx(0.09) and len(rec.times) == 10
