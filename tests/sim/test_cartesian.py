"""Cartesian moves: poses, inverse kinematics, straight lines, and the refusals before motion.

The motion tests run arm6 (and planar2) against the simulator in lock step and measure the tool's
pose from the *simulator's* joint positions (the plant's truth, not the replies the arm reads).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

import akarm
from akarm.arm import Arm
from akarm.cli import main
from akarm.dynamics.ik import IKSolver, as_pose, make_pose, pose_error, quaternion
from akarm.dynamics.model import RobotModel
from akarm.errors import LimitError, SingularityError, StateError, UnreachableError
from akarm.sim import SimulatedRobot

from .conftest import ROBOTS, relaxed_robot, wait_until

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
BENT = [-0.5, 1.2]  # planar2, elbow bent (stretched out straight, it is at a singularity)
PLANAR2 = akarm.load_robot(ROBOTS / "planar2.yaml")


def solver(config) -> IKSolver:
    lim = [j.limits for j in config.joints]
    return IKSolver(RobotModel(config), [x.lower for x in lim], [x.upper for x in lim])


@contextmanager
def lockstep(config, channel: str, q0) -> Iterator[tuple[Arm, SimulatedRobot]]:
    cfg = config.with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(cfg, realtime=False, q0=q0) as sim, Arm(cfg, clock=sim.clock) as arm:
        arm.enable()
        yield arm, sim


def sim_pose(sim: SimulatedRobot) -> np.ndarray:
    return sim.model.tool_pose(sim.q)


def line_deviation(arm: Arm, sim: SimulatedRobot, motion, p0: np.ndarray, p1: np.ndarray) -> float:
    """The largest distance (m) of the simulator's tool position from the line p0-p1, every cycle."""
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    worst = 0.0
    while not motion.done:
        arm.sleep(1.0 / arm.config.rate_hz)
        d = sim_pose(sim)[:3, 3] - p0
        worst = max(worst, float(np.linalg.norm(d - (d @ u) * u)))
    return worst


# ------------------------------------------------------------------------------------------------
# poses
# ------------------------------------------------------------------------------------------------
def test_make_pose_follows_the_urdf_rpy_convention_and_quaternions_round_trip() -> None:
    T = make_pose([0.1, 0.2, 0.3], rpy=[0.3, -0.2, 1.1])
    c, s = math.cos, math.sin
    Rz = np.array([[c(1.1), -s(1.1), 0], [s(1.1), c(1.1), 0], [0, 0, 1]])
    Ry = np.array([[c(-0.2), 0, s(-0.2)], [0, 1, 0], [-s(-0.2), 0, c(-0.2)]])
    Rx = np.array([[1, 0, 0], [0, c(0.3), -s(0.3)], [0, s(0.3), c(0.3)]])
    assert np.allclose(T[:3, :3], Rz @ Ry @ Rx) and np.allclose(T[:3, 3], [0.1, 0.2, 0.3])
    same, oriented = as_pose(([0.1, 0.2, 0.3], quaternion(T)), np.eye(4))
    assert oriented and np.allclose(same, T)


def test_a_position_alone_keeps_the_current_orientation() -> None:
    current = make_pose([0, 0, 1], rpy=[0.1, 0.2, 0.3])
    T, oriented = as_pose([0.4, 0.0, 0.2], current)
    assert not oriented and np.allclose(T[:3, :3], current[:3, :3]) and np.allclose(T[:3, 3], [0.4, 0, 0.2])


@pytest.mark.parametrize("bad", ["home", [1, 2], np.eye(3), np.diag([1, 1, 2, 1]), [0.1, math.nan, 0.2],
                                 ([0, 0, 0], [0, 0, 0, 2])])
def test_what_is_not_a_pose_is_a_limit_error(bad: object) -> None:
    with pytest.raises(LimitError):
        as_pose(bad, np.eye(4))


# ------------------------------------------------------------------------------------------------
# inverse kinematics
# ------------------------------------------------------------------------------------------------
def test_ik_solves_reachable_arm6_poses_within_a_micrometre() -> None:
    ik = solver(ARM6)
    rng = np.random.default_rng(7)
    seed = np.array(ARM6.pose("home"))
    solved = 0
    while solved < 25:
        q_true = ik.lower + rng.random(6) * (ik.upper - ik.lower)
        if ik.sigma_min(q_true, False) < 0.01:  # keep away from singularities (tested below)
            continue
        T = ik.model.tool_pose(q_true)
        q = ik.solve(T, seed)
        assert np.all(q >= ik.lower) and np.all(q <= ik.upper)
        dp, dr = pose_error(ik.model.tool_pose(q), T)
        assert dp < 1e-6 and dr < 1e-5
        solved += 1


def test_ik_prefers_the_solution_nearest_the_start() -> None:
    ik = solver(ARM6)
    q_true = np.array([0.3, 0.5, 1.0, 0.4, 0.8, -0.5])
    q = ik.solve(ik.model.tool_pose(q_true), q_true + 0.05)
    assert np.allclose(q, q_true, atol=1e-5)


class _SeedFails(IKSolver):
    """The solve from the seed does not converge; every solution the other starts find is kept."""

    def iterate(self, q0, target, position_only, bounded=True, max_iterations=None):
        if not hasattr(self, "found"):
            self.found: list[np.ndarray] = []
            return np.asarray(q0, dtype=float), np.ones(6), False
        q, e, ok = super().iterate(q0, target, position_only, bounded, max_iterations)
        if ok and bounded:
            self.found.append(q)
        return q, e, ok


def test_when_the_seed_fails_the_solution_nearest_the_seed_wins_not_the_one_nearest_the_last_start() -> None:
    lim = [j.limits for j in ARM6.joints]
    ik = _SeedFails(RobotModel(ARM6), [x.lower for x in lim], [x.upper for x in lim])
    q_true = np.array([-1.13, 0.82, 1.11, -1.58, 1.32, 0.95])
    seed = q_true + 0.05
    q = ik.solve(ik.model.tool_pose(q_true), seed)
    dist = [float(np.max(np.abs(x - seed))) for x in ik.found]
    assert len(ik.found) == 3 and max(dist) > 3.0  # the starts found other solutions (a wrist flip)
    assert float(np.max(np.abs(q - seed))) == pytest.approx(min(dist), abs=1e-9) and min(dist) < 0.06


def test_the_solve_without_ranges_starts_from_the_seed() -> None:
    class NothingConverges(IKSolver):
        def iterate(self, q0, target, position_only, bounded=True, max_iterations=None):
            return np.asarray(q0, dtype=float), np.ones(6), False

        def _without_ranges(self, target, seed, position_only):
            self.seen = np.array(seed)
            return seed, None

    lim = [j.limits for j in ARM6.joints]
    ik = NothingConverges(RobotModel(ARM6), [x.lower for x in lim], [x.upper for x in lim], starts=4)
    seed = np.array(ARM6.pose("home"), dtype=float)
    ik.solve(ik.model.tool_pose(seed), seed, check_singular=False)
    assert np.array_equal(ik.seen, seed)


def test_a_pose_out_of_reach_is_unreachable_and_says_how_far() -> None:
    ik = solver(ARM6)
    with pytest.raises(UnreachableError) as e:
        ik.solve(make_pose([2.0, 0.0, 0.5]), ARM6.pose("home"), position_only=True)
    # arm6 reaches about 0.99 m from its shoulder (0.22 m up), 2.02 m from (2, 0, 0.5): the tool
    # comes no closer than about 1.03 m (the search may stop a little short of the best)
    assert 1.0 < e.value.distance[0] < 1.2
    assert "out of reach" in str(e.value)


def test_a_pose_past_a_joint_limit_names_the_joint() -> None:
    # planar2's tool 0.155 m from the shoulder needs the elbow folded to ±2.6 rad; its range is ±2.4
    ik = solver(PLANAR2)
    with pytest.raises(LimitError) as e:
        ik.solve(make_pose([0.155, 0.0, 0.15]), PLANAR2.pose("home"), position_only=True)
    assert type(e.value) is LimitError and e.value.joint == "elbow" and "2.599" in str(e.value)


def test_a_pose_reached_only_at_a_singularity_is_refused() -> None:
    ik = solver(ARM6)
    upright = ik.model.tool_pose(ARM6.pose("upright"))  # stretched straight up, wrist axes in line
    with pytest.raises(SingularityError) as e:
        ik.solve(upright, ARM6.pose("home"))
    assert e.value.sigma < 1e-3


def test_planar2_takes_position_only_targets_in_its_plane() -> None:
    ik = solver(PLANAR2)
    assert ik.position_only(orientation_given=False) and not solver(ARM6).position_only(False)
    q = ik.solve(make_pose([0.35, 0.0, 0.35]), PLANAR2.pose("home"), position_only=True)
    assert np.linalg.norm(ik.model.tool_pose(q)[:3, 3] - [0.35, 0.0, 0.35]) < 1e-6
    with pytest.raises(UnreachableError):  # out of its plane
        ik.solve(make_pose([0.35, 0.1, 0.35]), PLANAR2.pose("home"), position_only=True)


# ------------------------------------------------------------------------------------------------
# moves on the simulator
# ------------------------------------------------------------------------------------------------
def test_tool_pose_is_the_pose_at_the_measured_joints(channel: str) -> None:
    with lockstep(ARM6, channel, ARM6.pose("home")) as (arm, sim):
        assert np.allclose(arm.tool_pose(), sim_pose(sim), atol=2e-3)
        assert np.allclose(arm.tool_pose(ARM6.pose("ready")), sim.model.tool_pose(ARM6.pose("ready")))


def test_move_to_pose_arrives_within_a_millimetre_and_a_hundredth_of_a_radian(channel: str) -> None:
    target = make_pose([0.40, 0.20, 0.50], rpy=[0.0, 2.0, 0.3])
    with lockstep(ARM6, channel, ARM6.pose("home")) as (arm, sim):
        arm.move_to_pose(target)
        arm.sleep(0.3)
        dp, dr = pose_error(sim_pose(sim), target)
        assert dp < 1e-3 and dr < 0.01
        # a position alone: the orientation stays
        before = sim_pose(sim)
        arm.move_to_pose(([0.30, -0.20, 0.60], quaternion(before)))
        arm.move_to_pose([0.35, -0.10, 0.55], speed=0.5)
        arm.sleep(0.3)
        after = sim_pose(sim)
        assert np.linalg.norm(after[:3, 3] - [0.35, -0.10, 0.55]) < 1e-3
        assert pose_error(after, before)[1] < 0.01


def test_move_linear_stays_within_a_millimetre_of_the_line(channel: str) -> None:
    with lockstep(ARM6, channel, ARM6.pose("home")) as (arm, sim):
        start = arm.tool_pose()
        target = start.copy()
        target[:3, 3] += [0.10, 0.15, -0.20]
        target[:3, :3] = start[:3, :3] @ pin.rpy.rpyToMatrix(0.2, 0.0, 0.3)
        motion = arm.move_linear(target, wait=False)
        deviation = line_deviation(arm, sim, motion, start[:3, 3], target[:3, 3])
        arm.sleep(0.3)
        dp, dr = pose_error(sim_pose(sim), target)
    assert deviation < 1e-3, f"{deviation * 1e3:.2f} mm off the line"
    assert dp < 1e-3 and dr < 0.01


def test_move_linear_respects_every_joint_limit_at_every_speed(channel: str) -> None:
    with lockstep(ARM6, channel, ARM6.pose("home")) as (arm, sim):
        target = arm.tool_pose()
        target[:3, 3] += [0.0, 0.30, -0.10]
        for speed in (1.0, 0.3):
            plan = akarm.motion.cartesian.plan_linear(arm._ik(), arm.limits, arm.state().q_des, target, speed=speed)
            _, q, v, a, j = plan.joint_profile()
            lim = arm.limits
            assert np.all(np.abs(v) <= lim.velocity * speed * (1 + 1e-6))
            assert np.all(np.abs(a) <= lim.acceleration * speed**2 * (1 + 1e-6))
            assert np.all(np.abs(j) <= lim.jerk * speed**3 * (1 + 1e-6))
            # one of them is at its limit: the line is as fast as the joints allow
            top = max(np.max(np.abs(v) / lim.velocity) / speed, np.max(np.abs(a) / lim.acceleration) / speed**2,
                      np.max(np.abs(j) / lim.jerk) / speed**3)
            assert top > 0.97
        capped = akarm.motion.cartesian.plan_linear(arm._ik(), arm.limits, arm.state().q_des, target, max_velocity=0.05)
        assert capped.duration > 0.316 / 0.05  # 0.316 m at 5 cm/s at most


def _nothing_moved(arm: Arm, sim: SimulatedRobot, q_before: np.ndarray) -> None:
    """No motion was started: the command is where enable() held the arm, the arm still there."""
    arm.sleep(0.2)
    assert not arm.moving
    log = arm.telemetry()
    assert np.all(np.ptp(log.q_des[log.t > 0.45], axis=0) == 0.0)  # after enable's ramp: not one change
    assert np.allclose(arm.state().q_des, q_before, atol=1e-3)
    assert np.allclose(sim.q, q_before, atol=3e-3)


def test_unreachable_poses_and_paths_through_limits_are_refused_with_nothing_moved(channel: str) -> None:
    home = np.array(ARM6.pose("home"))
    with lockstep(ARM6, channel, home) as (arm, sim):
        start = arm.tool_pose()
        far = start.copy()
        far[:3, 3] = [1.5, 0.0, 0.4]
        with pytest.raises(UnreachableError):
            arm.move_to_pose(far)
        with pytest.raises(UnreachableError) as e:
            arm.move_linear(far)
        assert "along the line" in str(e.value)
        _nothing_moved(arm, sim, home)

    # the tool turned 0.8 rad about its own axis with wrist_roll at 2.6 rad: the line needs 3.4 rad,
    # past the joint's 3.0 (the same pose is fine by a joint-space move: wrist_roll -2.88 rad)
    q0 = home.copy()
    q0[5] = 2.6
    with lockstep(ARM6, channel + "-b", q0) as (arm, sim):
        target = arm.tool_pose(q0) @ make_pose([0, 0, 0], rpy=[0, 0, 0.8])
        with pytest.raises(LimitError) as e:
            arm.move_linear(target)
        assert e.value.joint == "wrist_roll" and "along the line" in str(e.value)
        _nothing_moved(arm, sim, q0)
        arm.move_to_pose(target)
        assert arm.state().q_des[5] == pytest.approx(2.6 + 0.8 - 2 * math.pi, abs=1e-3)


def test_a_line_through_a_singularity_is_refused(channel: str) -> None:
    ready = np.array(ARM6.pose("ready"))  # wrist_pitch 0: forearm_roll and wrist_roll in line
    with lockstep(ARM6, channel, ready) as (arm, sim):
        sideways = arm.tool_pose()
        sideways[1, 3] += 0.1  # needs a turn about the axis the aligned wrist cannot turn about
        with pytest.raises(SingularityError) as e:
            arm.move_linear(sideways)
        assert "singular" in str(e.value)
        _nothing_moved(arm, sim, ready)
        forward = arm.tool_pose()
        forward[0, 3] += 0.1  # along the forearm: fine at the same pose
        arm.move_linear(forward)


def test_move_linear_starts_from_rest(channel: str) -> None:
    with lockstep(ARM6, channel, ARM6.pose("home")) as (arm, sim):
        arm.move_to("ready", wait=False)
        arm.sleep(0.1)
        with pytest.raises(StateError):
            arm.move_linear([0.5, 0.0, 0.5])


def test_planar2_moves_to_positions_and_along_lines(channel: str) -> None:
    with lockstep(PLANAR2, channel, PLANAR2.pose("home")) as (arm, sim):
        arm.move_to_pose([0.30, 0.0, 0.40])
        arm.sleep(0.3)
        assert np.linalg.norm(sim_pose(sim)[:3, 3] - [0.30, 0.0, 0.40]) < 1e-3
        start = sim_pose(sim)[:3, 3]
        end = np.array([0.45, 0.0, 0.20])
        motion = arm.move_linear(end, wait=False)
        deviation = line_deviation(arm, sim, motion, start, end)
        arm.sleep(0.3)
        assert deviation < 1e-3 and np.linalg.norm(sim_pose(sim)[:3, 3] - end) < 1e-3


# ------------------------------------------------------------------------------------------------
# akarm move --xyz
# ------------------------------------------------------------------------------------------------
@pytest.fixture
def relaxed_planar2(tmp_path: Path) -> str:
    """planar2.yaml lying flat (gravity along its joint axes: a limp arm stays where it is), its
    supervisor relaxed (the real-time simulator shares this process)."""
    path = relaxed_robot(ROBOTS / "planar2.yaml", tmp_path)
    doc = yaml.safe_load(path.read_text())
    doc["gravity"] = [0.0, -9.81, 0.0]
    path.write_text(yaml.safe_dump(doc))
    return str(path)


def _cli_move(robot: str, channel: str, q0, argv: list[str]) -> tuple[int, np.ndarray]:
    cfg = akarm.load_robot(robot).with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(cfg, realtime=True, q0=q0) as sim:
        result: list[int] = []
        th = threading.Thread(target=lambda: result.append(main(["move", robot, "-i", "virtual", "-c", channel,
                                                                  *argv])), daemon=True)
        th.start()
        th.join(20.0)
        assert result, "akarm move did not end"
        assert wait_until(lambda: not any(d.enabled for d in sim.drivers), 2.0)
        time.sleep(0.05)
        return result[0], sim_pose(sim)


def test_cli_move_xyz_linear_reaches_the_point(relaxed_planar2: str, channel: str,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    code, _ = _cli_move(relaxed_planar2, channel, BENT, ["--xyz", "0.40", "0", "0.30", "--linear"])
    out, err = capsys.readouterr()
    assert code == 0, out + err
    assert "in a straight line" in out and "disabled" in out
    mm = float(out.split("arrived: tool at")[1].split(" m, ")[1].split(" mm")[0])
    assert mm < 2.0


def test_cli_move_refuses_an_unreachable_point_before_moving(relaxed_planar2: str, channel: str,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    code, pose = _cli_move(relaxed_planar2, channel, BENT, ["--xyz", "0.9", "0", "0.3"])
    err = capsys.readouterr().err
    assert code == 1 and "out of reach" in err
    bent = akarm.dynamics.model.RobotModel(PLANAR2).tool_pose(BENT)
    assert np.linalg.norm(pose[:3, 3] - bent[:3, 3]) < 2e-3


def test_cli_move_needs_a_target_or_xyz(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["move", str(ROBOTS / "planar2.yaml")]) == 1
    assert "--xyz" in capsys.readouterr().err
    assert main(["move", str(ROBOTS / "planar2.yaml"), "home", "--linear"]) == 1
