"""Cartesian poses and inverse kinematics on their own: pose conventions, IK accuracy and choice of
solution, refusals with the reason (the arm moving in them: tests/system/test_cartesian_lockstep.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import akarm
from akarm.cli import main
from akarm.dynamics.ik import IKSolver, as_pose, make_pose, pose_error, quaternion
from akarm.dynamics.model import RobotModel
from akarm.errors import LimitError, SingularityError, UnreachableError

from .conftest import ROBOTS

ARM6 = akarm.load_robot(ROBOTS / "arm6.yaml")
PLANAR2 = akarm.load_robot(ROBOTS / "planar2.yaml")


def solver(config) -> IKSolver:
    lim = [j.limits for j in config.joints]
    return IKSolver(RobotModel(config), [x.lower for x in lim], [x.upper for x in lim])


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
def test_what_is_not_a_pose_is_an_argument_error(bad: object) -> None:
    with pytest.raises(akarm.ArgumentError):
        as_pose(bad, np.eye(4))


def test_a_position_that_is_not_finite_is_shown_as_numbers_with_a_fix() -> None:
    with pytest.raises(akarm.ArgumentError) as e:
        as_pose(np.array([math.nan, 0.0, 0.3]), np.eye(4))
    assert str(e.value) == ("a position (m) must be 3 finite numbers, not [nan, 0.0, 0.3] "
                            "(fix: give 3 finite numbers)")


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


def test_cli_move_needs_a_target_or_xyz(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["move", str(ROBOTS / "planar2.yaml")]) == 1
    assert "--xyz" in capsys.readouterr().err
    assert main(["move", str(ROBOTS / "planar2.yaml"), "home", "--linear"]) == 1
