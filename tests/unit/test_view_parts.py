"""`akarm view`'s pure parts: what is drawn (URDF visuals, the kinematic figure), the plots' window,
the state panel, the jog check, recordings played back and the snapshot's wire form. The page
itself, in a real browser, is tests/system/test_view.py."""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest

from akarm.dynamics.model import RobotModel
from akarm.errors import ArgumentError, LimitError, RecordingError, StateError
from akarm.robotfile.load import load_robot
from akarm.robotfile.starter import suggest
from akarm.server.snapshot import Snapshot
from akarm.telemetry.log import TelemetryLog
from akarm.view import recorded
from akarm.view.figure import Poser, build_figure, finger_slides, link_radius
from akarm.view.history import MAX_POINTS, History
from akarm.view.page import jaw_text
from akarm.view.panel import gripper_html, state_html
from akarm.view.recorded import RecordedSource, read_telemetry, register_reader
from akarm.view.sources import Controls
from akarm.view.visuals import Visual, read_visuals

from ..conftest import ROBOTS

pytest.importorskip("trimesh", reason="the view extra is not installed (pip install -e \".[view]\")")

SHIPPED = ("arm6", "biarm", "planar2", "servo3")


def snap(t: float = 0.0, q: tuple[float, ...] = (0.1, -0.2), **changes: object) -> Snapshot:
    n = len(q)
    fields: dict[str, object] = dict(
        t=t, names=("a", "b")[:n], q=q, q_des=tuple(x + 1e-3 for x in q), error=(1e-3,) * n, tau=(0.5,) * n,
        tau_ff=(0.0,) * n, temperature=(31.5, math.nan)[:n], age=(0.002,) * n, fault=(0,) * n, mode="holding",
        enabled=True, moving=False, stop="", rate_hz=500.0, loop_rate_hz=499.8, cycles=1000, missed_slots=3)
    fields.update(changes)
    return Snapshot(**fields)  # type: ignore[arg-type]


def describe(v: Visual) -> tuple[object, ...]:
    return (v.link, v.index, v.origin.tolist(), v.kind, v.size, v.filename, v.rgba)


@pytest.mark.parametrize("robot", SHIPPED)
def test_every_shipped_urdf_has_visuals_on_its_moving_links_and_the_view_draws_them_all(robot: str) -> None:
    config = load_robot(ROBOTS / f"{robot}.yaml")
    visuals = read_visuals(config.urdf)
    assert {v.kind for v in visuals} <= {"box", "cylinder"}
    model = RobotModel(config)
    figure = build_figure(model)
    assert figure.kind == "visuals" and figure.problems == ()
    assert figure.visuals == len(visuals) > 0
    moved = {p.body for p in figure.parts}
    # every driven joint moves at least one drawn shape
    assert set(range(1, model.pin_model.njoints)) <= moved


def test_visuals_only_add_shapes_the_dynamics_is_unchanged(tmp_path: Path) -> None:
    config = load_robot(ROBOTS / "arm6.yaml")
    text = Path(config.urdf).read_text()
    assert "<visual>" in text
    bare = re.sub(r"\s*<visual>.*?</visual>", "", text, flags=re.S)
    assert "<visual" not in bare
    stripped = tmp_path / "arm6_no_visuals.urdf"
    stripped.write_text(bare)
    plain = RobotModel(dataclasses.replace(config, urdf=stripped))
    model = RobotModel(config)
    q = np.array(config.pose("ready"))
    np.testing.assert_allclose(model.gravity(q), plain.gravity(q), rtol=0, atol=1e-12)
    # without visuals, the view falls back to the figure from the kinematics
    assert build_figure(plain).kind == "kinematics"


def test_the_kinematic_figure_is_capsules_sized_by_mass_and_follows_the_pose() -> None:
    model = RobotModel(load_robot(ROBOTS / "arm6.yaml"))
    figure = build_figure(model, visuals=False)
    assert figure.kind == "kinematics" and figure.visuals == 0
    links = [p for p in figure.parts if p.name.startswith("link")]
    joints = [p for p in figure.parts if p.name.startswith("joint")]
    assert len(joints) == model.pin_model.njoints - 1 and len(links) >= len(joints)
    # a capsule's half thickness is its link's radius: heavier links are thicker
    assert link_radius(8.0) > link_radius(1.0) > link_radius(0.1)
    assert link_radius(1.0) == pytest.approx(0.03) and link_radius(1e6) == 0.06 and link_radius(0.0) == 0.008
    poser = Poser(model)
    home = poser.poses(model.config.pose("home"))
    ready = poser.poses(model.config.pose("ready"))
    assert home.shape == (model.pin_model.njoints, 4, 4)
    assert not np.allclose(poser.tool(home)[:3, 3], poser.tool(ready)[:3, 3])  # the tool moved
    np.testing.assert_allclose(poser.poses([math.nan] * 6), poser.poses([0.0] * 6))


def test_init_keeps_the_urdfs_visuals(tmp_path: Path) -> None:
    urdf = ROBOTS / "arm6.urdf"
    before = read_visuals(urdf)
    out = tmp_path / "mine.yaml"
    out.write_text(suggest(urdf, out).text)  # what akarm init writes
    config = load_robot(out)
    assert Path(config.urdf).resolve() == urdf.resolve()  # the robot file refers to the URDF as it is
    assert [describe(v) for v in read_visuals(config.urdf)] == [describe(v) for v in before]
    assert build_figure(RobotModel(config)).visuals == len(before)


def test_the_history_keeps_the_last_seconds_thinned_and_starts_over_on_a_new_clock() -> None:
    h = History(joints=2, seconds=10.0, capacity=4096)
    for k in range(3000):  # 30 s at 100 Hz
        h.add(snap(t=k * 0.01, q=(k * 1e-3, 0.0)))
    w = h.window()
    assert w.t[0] >= -10.0 - 1e-9 and w.t[-1] == 0.0 and len(w.t) <= MAX_POINTS
    assert w.q[-1, 0] == pytest.approx(2.999) and w.q_des[-1, 0] == pytest.approx(3.0)
    assert np.all(np.diff(w.t) > 0)
    h.add(snap(t=1.0))  # older than the newest: a restarted server
    assert len(h) == 1


def test_the_state_panel_shows_mode_stop_loop_and_each_joint() -> None:
    html = state_html(snap(stop="following error on b"), recent_hz=498.0, hot=(30.0, 80.0))
    assert "data-field='mode'>holding<" in html
    assert "safety stop: following error on b" in html
    assert "loop 498.0 Hz" in html and "missed slots 3" in html
    assert "<td data-field='q'>+0.10000</td>" in html
    assert "<td data-field='temperature' class=hot>31.5</td>" in html  # at or over its limit
    assert "<td data-field='age'>2.0</td>" in html
    assert "<td data-field='temperature'>–</td>" in html  # NaN: not reported
    assert "no safety stop" in state_html(snap())
    assert "<script>" not in state_html(snap(mode="<script>"))


def test_a_jog_is_checked_against_the_joint_range_before_anything_is_sent() -> None:
    config = load_robot(ROBOTS / "arm6.yaml")
    sent: list[tuple[str, dict[str, object]]] = []
    controls = Controls(lambda op, args: sent.append((op, args)), config)
    upper = config.joint("elbow").limits.upper
    with pytest.raises(LimitError, match="past the upper limit") as e:
        controls.jog("elbow", upper + 0.01)
    assert e.value.joint == "elbow"
    with pytest.raises(LimitError, match="past the lower limit"):
        controls.jog("elbow", config.joint("elbow").limits.lower - 0.01)
    with pytest.raises(ArgumentError, match="no joint named"):
        controls.jog("knee", 0.0)
    with pytest.raises(ArgumentError, match="not a finite angle"):
        controls.jog("elbow", math.nan)
    with pytest.raises(ArgumentError, match="speed"):
        controls.jog("elbow", 0.0, speed=2.0)
    assert sent == []
    controls.jog("elbow", upper - 0.1)
    controls.disable()
    assert sent == [("move", {"target": {"elbow": upper - 0.1}, "speed": 0.3}), ("disable", {})]


def test_the_view_process_commands_run_only_the_controls_operations_checked_as_a_jog() -> None:
    config = load_robot(ROBOTS / "arm6.yaml")
    sent: list[tuple[str, dict[str, object]]] = []
    controls = Controls(lambda op, args: sent.append((op, args)), config)
    upper = config.joint("elbow").limits.upper
    with pytest.raises(ArgumentError, match="do not run 'zero'"):
        controls.call("zero", {})
    with pytest.raises(ArgumentError, match="do not run 'move'"):
        controls.call("move", [])  # type: ignore[arg-type]
    with pytest.raises(ArgumentError, match="one joint"):
        controls.call("move", {"target": {"elbow": 0.0, "wrist": 0.0}})
    with pytest.raises(ArgumentError, match="one joint"):
        controls.call("move", {"target": {"elbow": 0.0}, "pose": "home"})
    with pytest.raises(ArgumentError, match="not a number"):
        controls.call("move", {"target": {"elbow": 0.0}, "speed": "fast"})
    with pytest.raises(LimitError, match="past the upper limit"):
        controls.call("move", {"target": {"elbow": upper + 0.01}, "speed": 0.5})
    with pytest.raises(ArgumentError, match="takes no arguments"):
        controls.call("enable", {"kick": True})
    assert sent == []
    controls.call("move", {"target": {"elbow": upper - 0.1}, "speed": 0.5})
    controls.call("hold", {})
    assert sent == [("move", {"target": {"elbow": upper - 0.1}, "speed": 0.5}), ("hold", {})]


def test_the_snapshot_travels_as_json_and_a_foreign_one_is_refused() -> None:
    import json

    s = snap(temperature=(math.nan, 40.0))
    doc = json.loads(json.dumps(s.to_doc()))
    back = Snapshot.from_doc(doc)
    assert back.q == s.q and back.mode == s.mode and back.missed_slots == 3 and math.isnan(back.temperature[0])
    with pytest.raises(StateError, match="not one this akarm reads"):
        Snapshot.from_doc({**doc, "q": [0.0]})
    with pytest.raises(StateError, match="not one this akarm reads"):
        Snapshot.from_doc({k: v for k, v in doc.items() if k != "mode"})


def test_a_recording_plays_back_at_any_instant_and_by_suffix(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    names = ("b", "a")
    t = np.linspace(10.0, 12.0, 201)
    q = np.column_stack([t - 10.0, -(t - 10.0)])
    log = TelemetryLog(names, t, q, np.zeros_like(q), q + 0.01, np.zeros_like(q), np.ones_like(q), np.zeros_like(q))
    for suffix in (".csv", ".npz"):
        path = log.save(tmp_path / f"run{suffix}")
        rec = RecordedSource(read_telemetry(path), ("a", "b"))
        assert rec.duration == pytest.approx(2.0) and rec.rate_hz == pytest.approx(100.0)
        s = rec.at(1.005)
        assert s.t == pytest.approx(1.0) and s.mode == "recorded"
        assert s.q_des == pytest.approx((-1.0, 1.0)) and s.q == pytest.approx((-0.99, 1.01))  # measured: +0.01
        assert rec.at(-5).t == 0.0 and rec.at(99).t == pytest.approx(2.0)  # clamped
        w = rec.window(2.0, seconds=0.5)
        assert w.t[0] == pytest.approx(-0.5) and w.t[-1] == 0.0 and w.q.shape[1] == 2
    with pytest.raises(RecordingError, match="has no joint c"):
        RecordedSource(log, ("a", "c"))
    with pytest.raises(RecordingError, match=r"no reader for \.bag"):
        read_telemetry(tmp_path / "run.bag")
    with pytest.raises(RecordingError, match="no such file"):
        read_telemetry(tmp_path / "missing.csv")
    monkeypatch.setattr(recorded, "READERS", dict(recorded.READERS))  # (this test's reader stays in this test)
    register_reader(".bag", lambda p: log)  # a format of another module joins by suffix
    (tmp_path / "run.bag").write_text("")
    assert read_telemetry(tmp_path / "run.bag") is log


def test_the_fingers_slide_to_where_the_urdf_puts_them_at_half_the_width() -> None:
    import pinocchio as pin

    config = load_robot(ROBOTS / "arm6g.yaml")
    model = RobotModel(config)
    slides = finger_slides(model)
    assert set(slides) == {"left_finger", "right_finger"}
    np.testing.assert_allclose(slides["left_finger"], -slides["right_finger"])
    # the left finger's frame with its joint at 15 mm (a 30 mm width), in the full URDF model, is where
    # the view puts it: the locked (closed) placement, slid by 15 mm along its slide
    full = pin.buildModelFromUrdf(str(config.urdf))
    data = full.createData()
    q = pin.neutral(full)
    q[full.idx_qs[full.getJointId("left_finger_joint")]] = 0.015
    pin.framesForwardKinematics(full, data, q)
    wrist = full.getJointId(config.joint_names[-1])
    truth = (data.oMi[wrist].inverse() * data.oMf[full.getFrameId("left_finger")]).translation
    pm = model.pin_model
    closed = pm.frames[pm.getFrameId("left_finger")].placement.translation
    np.testing.assert_allclose(closed + slides["left_finger"] * 0.015, truth, atol=1e-9)
    assert finger_slides(RobotModel(load_robot(ROBOTS / "arm6.yaml"))) == {}


def test_the_gripper_is_in_the_snapshot_the_panel_and_the_label() -> None:
    import json

    plain = snap()
    assert plain.gripper == "" and gripper_html(plain) == "" and "gripper" not in state_html(plain)
    s = snap(gripper="gripper", gripper_width=0.0301, gripper_target=0.0, gripper_force=19.84, gripper_grasped=True,
             gripper_temperature=31.0)
    back = Snapshot.from_doc(json.loads(json.dumps(s.to_doc())))
    assert [getattr(back, f.name) for f in dataclasses.fields(back) if f.name.startswith("gripper")] == \
        ["gripper", 0.0301, 0.0, 19.84, True, 31.0]
    html = state_html(back)
    assert "<span data-field='gripper_width'>30.1</span> mm" in html
    assert "<span data-field='gripper_target'>0.0</span> mm" in html
    assert "<span data-field='gripper_force'>19.8</span> N" in html and "holds something" in html
    assert jaw_text(back) == "30.1 mm · 19.8 N"
    assert jaw_text(dataclasses.replace(back, gripper_grasped=False, gripper_width=0.08)) == "80.0 mm"
    assert jaw_text(dataclasses.replace(back, gripper_width=math.nan)) == "gripper: not heard"
    old = {k: v for k, v in plain.to_doc().items() if not k.startswith("gripper")}  # an older server's
    assert Snapshot.from_doc(old).gripper == "" and math.isnan(Snapshot.from_doc(old).gripper_width)
