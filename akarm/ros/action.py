"""``NS/CONTROLLER/follow_joint_trajectory``: the ``control_msgs/action/FollowJointTrajectory`` action
server that MoveIt drives controllers through, over Cyclone DDS as rcl_action lays an action out.

The wire (rcl_action ``names.c``, ``default_qos.h``; rmw_cyclonedds_cpp ``rmw_node.cpp``):

- services ``_action/send_goal``, ``_action/cancel_goal``, ``_action/get_result`` under the action's
  name (:class:`~akarm.ros.dds.ServiceServer`: rmw_cyclonedds_cpp's request header, and the
  ``serviceid`` USER_DATA a client's ``action_server_is_ready()`` looks for);
- topics ``_action/feedback`` (ROS 2's default QoS) and ``_action/status`` (reliable, transient
  local, keep last 1: a client that joins late gets the last status; a client counts the server
  ready only once both topics have a matched publisher).

The semantics are JointTrajectoryController's (ros2_controllers ``joint_trajectory_controller.cpp``,
``tolerances.hpp``):

- a goal too big for akarm's limits is refused from its size before it is decoded
  (:func:`akarm.ros.trajectory.check_size`), as a topic message is, and so is one that does not
  decode (a string that is not UTF-8): accepted and aborted with ``INVALID_GOAL``;
- a goal is checked as the ``joint_trajectory`` topic is (:func:`akarm.ros.trajectory.check_trajectory`):
  joints by name, a subset allowed; and its tolerances name joints of the arm. A goal that fails is
  accepted and aborted at once with ``INVALID_JOINTS``, ``INVALID_GOAL`` or ``OLD_HEADER_TIMESTAMP``
  and the reason (JointTrajectoryController rejects it, which tells the client nothing); nothing moves;
- the points are followed through the jerk-limited planner at their ``time_from_start``
  (:meth:`ArmServerCore.follow <akarm.server.server.ArmServerCore.follow>`), as a topic message is:
  the two share one motion, the last one wins;
- tolerances: 0 takes the server's default, -1 none, more than 0 that value (rad, rad/s). Path
  tolerances are checked while the plan runs, goal tolerances from its end; ``goal_time_tolerance``
  (0: no limit) is how long after its end the goal tolerances may take to be met. A violation
  aborts with ``PATH_TOLERANCE_VIOLATED`` or ``GOAL_TOLERANCE_VIOLATED``, naming the joint, and
  stops the arm, jerk-limited. Acceleration tolerances are taken and never violated (no joint
  measures its acceleration), as JointTrajectoryController without an acceleration state does;
- feedback (desired, actual, error) at :data:`FEEDBACK_HZ` while a goal executes;
- a cancel stops the arm, jerk-limited, and the goal ends CANCELED; a new goal preempts the running
  one (ABORTED, ``INVALID_GOAL``, "preempted by a new goal"), its motion blending into the new one;
- a safety stop aborts the goal with its text (``PATH_TOLERANCE_VIOLATED``: the arm no longer
  follows the path); so do a collision, a disable and the server stopping. Another command that
  replaces the motion (``joint_trajectory``, ``akarm move``) aborts it with ``INVALID_GOAL``;
- a finished goal's result is kept :data:`RESULT_TIMEOUT` s (rcl_action's default), then forgotten;
  at most :data:`MAX_RESULTS` of them.

Everything runs in the ROS 2 node's thread (:class:`akarm.ros.node.RosNode` calls :meth:`ActionServer.poll`),
which never waits for the server's command lock (an enable or a disable holds it for 0.3 s and more):
a goal's start and the stops the action makes wait in a :class:`~akarm.ros.commands.CommandQueue`,
shared with the ``joint_trajectory`` topic, in the order they came; the status, the feedback and the
running goal's checks go on meanwhile.
"""

from __future__ import annotations

import contextlib
import math
import struct
import time
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import numpy as np

from akarm.errors import AkarmError, ArgumentError
from akarm.ros import action_types as at
from akarm.ros import msgs
from akarm.ros.commands import CommandQueue
from akarm.ros.dds import Node, RawSample, ServiceServer, latched_qos, qos, topic_name
from akarm.ros.trajectory import (
    GOAL_TOLERANCE_VIOLATED,
    INVALID_GOAL,
    INVALID_JOINTS,
    PATH_TOLERANCE_VIOLATED,
    SUCCESSFUL,
    TimedPoints,
    TrajectoryRefused,
    check_joint_names,
    check_size,
    check_trajectory,
    refusal,
)

if TYPE_CHECKING:
    from akarm.arm import Motion
    from akarm.server.server import ArmServerCore

__all__ = [
    "ABORTED",
    "ACCEPTED",
    "CANCELED",
    "CANCELING",
    "EXECUTING",
    "FEEDBACK_HZ",
    "MAX_RESULTS",
    "RESULT_TIMEOUT",
    "STOPPED_VELOCITY",
    "SUCCEEDED",
    "UNKNOWN",
    "ActionServer",
    "Goal",
    "Tolerances",
    "action_name",
    "cancel_choice",
    "goal_tolerances",
    "violation",
]

# action_msgs/msg/GoalStatus
UNKNOWN, ACCEPTED, EXECUTING, CANCELING, SUCCEEDED, CANCELED, ABORTED = range(7)
# action_msgs/srv/CancelGoal's return codes
ERROR_NONE, ERROR_REJECTED, ERROR_UNKNOWN_GOAL_ID, ERROR_GOAL_TERMINATED = range(4)

#: Feedback messages per second while a goal executes (the tolerances are checked twice as often).
FEEDBACK_HZ = 50.0
#: s a finished goal's result stays available (rcl_action's default ``result_timeout``).
RESULT_TIMEOUT = 10.0
#: Finished goals kept at most (the oldest are forgotten first): a flood of goals keeps no memory.
MAX_RESULTS = 100
#: rad/s: the default goal tolerance on velocity. JointTrajectoryController's
#: ``stopped_velocity_tolerance`` is 0.01 rad/s, but an AK driver reports velocity in steps of
#: 2·v_max/4095 (0.022-0.024 rad/s) and a joint at rest reads half a step: 0.01 could never be met.
STOPPED_VELOCITY = 0.05
_REPLY_WAIT = 0.1  # s a reply waits for the client's reader (rmw_cyclonedds_cpp's 100 ms)


def action_name(controller: str) -> str:
    """The action's name under the namespace: ``CONTROLLER/follow_joint_trajectory``."""
    return f"{controller.strip('/')}/follow_joint_trajectory"


@dataclass(frozen=True)
class Tolerances:
    """Per joint (config order; 0: not checked) path and goal tolerances, rad and rad/s, and the goal
    time tolerance, s (0: no limit)."""

    path_position: np.ndarray
    path_velocity: np.ndarray
    goal_position: np.ndarray
    goal_velocity: np.ndarray
    goal_time: float

    @classmethod
    def defaults(cls, n: int) -> Tolerances:
        """JointTrajectoryController's defaults, with :data:`STOPPED_VELOCITY` at the goal."""
        return cls(np.zeros(n), np.zeros(n), np.zeros(n), np.full(n, STOPPED_VELOCITY), 0.0)


def _resolve(default: float, value: float, what: str) -> float:
    """A goal's tolerance over the default (tolerances.hpp ``resolve_tolerance_source``)."""
    if not math.isfinite(value):
        raise TrajectoryRefused(f"{what} is {value}", INVALID_GOAL, fix="0: the default, -1: none, or a value > 0")
    if value > 0.0:
        return value
    if abs(value + 1.0) < 1.1920929e-07:
        return 0.0
    if value < 0.0:
        raise TrajectoryRefused(f"{what} is {value:g}", INVALID_GOAL, fix="0: the default, -1: none, or a value > 0")
    return default


def goal_tolerances(goal: at.FollowJointTrajectoryGoal, names: Sequence[str], defaults: Tolerances) -> Tolerances:
    """The tolerances of ``goal`` for the arm's joints ``names``, over ``defaults``.

    Raises:
        TrajectoryRefused: a tolerance names a joint the arm lacks (``INVALID_JOINTS``; component
            tolerances are for multi-DOF joints, which it has none of), or a value that is not 0, -1
            or more than 0 (``INVALID_GOAL``).
    """
    names = list(names)
    path_q, path_dq = defaults.path_position.copy(), defaults.path_velocity.copy()
    goal_q, goal_dq = defaults.goal_position.copy(), defaults.goal_velocity.copy()
    for kind, tols, q, dq in (("path_tolerance", goal.path_tolerance, path_q, path_dq),
                              ("goal_tolerance", goal.goal_tolerance, goal_q, goal_dq)):
        check_joint_names([t.name for t in tols], names, kind)
        for t in tols:
            i = names.index(t.name)
            q[i] = _resolve(q[i], t.position, f"{kind} position of {t.name!r}")
            dq[i] = _resolve(dq[i], t.velocity, f"{kind} velocity of {t.name!r}")
            _resolve(0.0, t.acceleration, f"{kind} acceleration of {t.name!r}")
    for kind, ctols in (("component_path_tolerance", goal.component_path_tolerance),
                        ("component_goal_tolerance", goal.component_goal_tolerance)):
        if ctols:
            raise TrajectoryRefused(f"{kind} names {ctols[0].joint_name!r}: this arm has no multi-DOF joints",
                                    INVALID_JOINTS, fix="leave the component tolerances empty")
    gt = _resolve(defaults.goal_time, goal.goal_time_tolerance.sec + goal.goal_time_tolerance.nanosec * 1e-9,
                  "goal_time_tolerance")
    return Tolerances(path_q, path_dq, goal_q, goal_dq, gt)


def violation(names: Sequence[str], error_q: np.ndarray, error_dq: np.ndarray, position: np.ndarray,
              velocity: np.ndarray) -> str | None:
    """The first joint whose position or velocity error passes its tolerance (0: not checked), as
    text, or ``None``."""
    for i, name in enumerate(names):
        for what, err, tol, unit in (("position", error_q[i], position[i], "rad"),
                                     ("velocity", error_dq[i], velocity[i], "rad/s")):
            if tol > 0.0 and abs(err) > tol:
                return f"joint {name!r}: {what} error {err:+.4f} {unit} is past the tolerance {tol:g} {unit}"
    return None


class _Cancelable(Protocol):
    id: bytes
    stamp: Any

    @property
    def terminal(self) -> bool: ...


_G = TypeVar("_G", bound=_Cancelable)


def cancel_choice(goals: Mapping[bytes, _G], req: at.CancelGoalRequest) -> tuple[int, list[_G]]:
    """rcl_action ``rcl_action_process_cancel_request``'s choice: the return code, and the goals (of
    ``goals``, by id) a cancel request asks for: one by id, every one up to a stamp (and that id), or all."""
    goal_id = bytes(req.goal_info.goal_id.uuid)
    stamp = req.goal_info.stamp.sec * 1_000_000_000 + req.goal_info.stamp.nanosec
    if any(goal_id) and stamp == 0:
        goal = goals.get(goal_id)
        code = ERROR_UNKNOWN_GOAL_ID if goal is None else (ERROR_GOAL_TERMINATED if goal.terminal else ERROR_NONE)
        return code, ([goal] if goal is not None and not goal.terminal else [])
    limit = stamp if stamp else math.inf
    return ERROR_NONE, [g for g in goals.values() if not g.terminal and
                        (g.stamp.sec * 1_000_000_000 + g.stamp.nanosec <= limit or g.id == goal_id)]


class Goal:
    """One goal of the action: its id, when it was accepted, its status and result, and its motion."""

    def __init__(self, goal_id: bytes, stamp: msgs.Time) -> None:
        self.id = goal_id
        self.stamp = stamp
        self.status = ACCEPTED
        self.code = SUCCESSFUL
        self.text = ""
        self.motion: Motion | None = None
        self.points: TimedPoints | None = None
        self.tolerances: Tolerances | None = None
        self.ended: float | None = None  # monotonic time it reached a terminal status
        self.waiting: list[at.GetResultRequest] = []  # get_result requests to answer when it ends

    @property
    def terminal(self) -> bool:
        return self.status in (SUCCEEDED, CANCELED, ABORTED)

    def info(self) -> at.GoalInfo:
        return at.GoalInfo(at.UUID(list(self.id)), self.stamp)


class ActionServer:
    """The FollowJointTrajectory action of ``server``'s arm, on ``node``, at ``NS/CONTROLLER/follow_joint_trajectory``.

    :attr:`conditions` go into the node's WaitSet; call :meth:`poll` whenever it wakes and by
    :meth:`next_due`; :meth:`close` before the node closes.
    """

    def __init__(self, node: Node, server: ArmServerCore, controller: str = "arm_controller",
                 distro: str = "jazzy", log: Callable[[str], None] | None = None,
                 heard: Callable[[str], None] | None = None, commands: CommandQueue | None = None) -> None:
        self.server = server
        self.commands = commands if commands is not None else CommandQueue(server)  # waiting for the server
        self.heard = heard  # told of every goal and cancel taken, with the participant that sent it
        self.name = action_name(controller)
        self.distro = at.check_distro(distro)
        self.log = log or server.log
        base = self.name + "/_action/"
        bad = heard or self.log  # a request that does not decode: dropped, said with who sent it
        self.send_goal = ServiceServer(node, base + "send_goal", at.SendGoalRequest, at.SendGoalResponse, bad)
        self.cancel_goal = ServiceServer(node, base + "cancel_goal", at.CancelGoalRequest, at.CancelGoalResponse, bad)
        self.get_result = ServiceServer(node, base + "get_result", at.GetResultRequest, at.GetResultResponse, bad)
        self._feedback_type = at.feedback_message_type(distro)
        self.feedback = node.writer(topic_name(node.namespace, base + "feedback"), self._feedback_type, qos())
        self.status = node.writer(topic_name(node.namespace, base + "status"), at.GoalStatusArray, latched_qos())
        self.conditions = [s.condition for s in (self.send_goal, self.cancel_goal, self.get_result)]
        self.names = list(server.arm.names)
        self.limits = server.arm.limits
        self.defaults = Tolerances.defaults(len(self.names))
        self.goals: OrderedDict[bytes, Goal] = OrderedDict()
        self.active: Goal | None = None
        self._pending: list[tuple[ServiceServer, Any, Any, float]] = []  # replies waiting for a client's reader
        self._next_check = math.inf
        self._checks = 0
        self._changed = True  # publish the (empty) status at once: a late joiner gets it

    # -- the node's thread ---------------------------------------------------------------------
    def next_due(self) -> float:
        """Monotonic time :meth:`poll` has work next (a check, a reply to retry, a result to forget)."""
        due = self._next_check if self.active is not None else math.inf
        if self._pending or self._changed or len(self.commands):
            due = min(due, time.monotonic() + 0.005)
        ended = [g.ended for g in self.goals.values() if g.ended is not None]
        return min([due, *(t + RESULT_TIMEOUT for t in ended)])

    def poll(self) -> None:
        """Answer the requests waiting, check the active goal and send its feedback, retry replies,
        forget old results, publish the status if it changed."""
        self.commands.run()  # what waited for the server, if it is free now
        for raw in self.send_goal.take_raw():
            if self.heard is not None:
                self.heard(f"{self.name} goal from {self.send_goal.caller(raw)}")
            self._take_goal(raw)
        for creq in self.cancel_goal.take():
            if self.heard is not None:
                self.heard(f"{self.name} cancel from {self.cancel_goal.caller(creq)}")
            self._on_cancel(creq)
        for rreq in self.get_result.take():
            self._on_get_result(rreq)
        now = time.monotonic()
        if self.active is not None and now >= self._next_check:
            self._check(self.active)
            period = 0.5 / FEEDBACK_HZ
            self._next_check += period * (1 + int((now - self._next_check) / period))  # skip, never burst
        self._retry_replies(now)
        self._forget(now)
        if self._changed:
            self._changed = False
            self.status.write(at.GoalStatusArray([at.GoalStatus(g.info(), g.status) for g in self.goals.values()]))

    def _forget(self, now: float) -> None:
        """Drop the results older than RESULT_TIMEOUT, and the oldest past MAX_RESULTS."""
        ended = [(g.id, g.ended) for g in self.goals.values() if g.ended is not None]
        excess = max(0, len(ended) - MAX_RESULTS)
        for k, (gid, t) in enumerate(ended):
            if k < excess or now > t + RESULT_TIMEOUT:
                del self.goals[gid]
                self._changed = True

    def close(self) -> None:
        """The server is stopping: abort the active goal (the arm is disabled by now) and the goals that
        waited to start, and say so."""
        for goal in [g for g in self.goals.values() if not g.terminal]:
            self._end(goal, ABORTED, PATH_TOLERANCE_VIOLATED, "akarm serve stopped: the arm was damped and disabled")
        with contextlib.suppress(Exception):
            self._retry_replies(math.inf)
            self.status.write(at.GoalStatusArray([at.GoalStatus(g.info(), g.status) for g in self.goals.values()]))

    # -- replies ---------------------------------------------------------------------------------
    def _reply(self, service: ServiceServer, request: Any, response: Any) -> None:
        if service.reply(request, response, wait=0.0) == "maybe":
            self._pending.append((service, request, response, time.monotonic() + _REPLY_WAIT))

    def _retry_replies(self, now: float) -> None:
        pending, self._pending = self._pending, []
        for service, request, response, deadline in pending:
            if service.reply(request, response, wait=0.0) == "maybe" and now < deadline:
                self._pending.append((service, request, response, deadline))

    # -- goals -----------------------------------------------------------------------------------
    def _take_goal(self, raw: RawSample) -> None:
        """A ``send_goal`` request as taken: one too big is accepted and aborted from its size alone, and
        so is one that does not decode (a string that is not UTF-8), its request header and goal ID read
        from the bytes (a request too short for them is dropped); others are decoded."""
        try:
            check_size(raw.data, 36, self.names)  # encapsulation, guid, seq, goal_id: the trajectory follows
            req = self.send_goal.decode(raw)
        except ArgumentError as e:
            if len(raw.data) < 36:
                self.send_goal.drop(raw, e)
                return
            guid, seq = struct.unpack_from("<Qq", raw.data, 4)
            req = at.SendGoalRequest(guid, seq, at.UUID(list(raw.data[20:36])))
            req.sample_info = raw.sample_info  # type: ignore[attr-defined]  # for the reply
            self._on_send_goal(req, refused=refusal(e))
            return
        self._on_send_goal(req)

    def _on_send_goal(self, req: at.SendGoalRequest, refused: TrajectoryRefused | None = None) -> None:
        goal_id = bytes(req.goal_id.uuid)
        stamp = msgs.Time.from_seconds(time.time())
        if goal_id in self.goals:  # rcl_action refuses a goal ID it already has
            self._reply(self.send_goal, req, at.SendGoalResponse(accepted=False, stamp=stamp))
            return
        goal = self.goals[goal_id] = Goal(goal_id, stamp)
        self._reply(self.send_goal, req, at.SendGoalResponse(accepted=True, stamp=stamp))
        self._changed = True
        if refused is not None:
            refused.report(self.server)
            self._end(goal, ABORTED, refused.code, str(refused))
            return
        try:  # started when the server is free (now, unless an enable or a disable runs)
            self.commands.add(lambda: self._begin(goal, req.goal), len(req.goal.trajectory.points))
        except AkarmError as e:  # too much waits for the server
            self.server.note_refusal(e)
            self._end(goal, ABORTED, INVALID_GOAL, str(e))

    def _begin(self, goal: Goal, spec: at.FollowJointTrajectoryGoal) -> None:
        """(Holding the server's command lock) start the goal, unless it was canceled while it waited."""
        if goal.terminal:
            return
        try:
            self._start(goal, spec)
        except TrajectoryRefused as e:
            e.report(self.server)
            self._end(goal, ABORTED, e.code, str(e))
        except AkarmError as e:  # refused by the server (a stop latched, the arm disabled, a path past a limit)
            self._end(goal, ABORTED, INVALID_GOAL, str(e))

    def _start(self, goal: Goal, spec: at.FollowJointTrajectoryGoal) -> None:
        """Check the goal and start its motion (raises what refuses it; nothing moves then)."""
        try:
            self.server.check_motion_allowed()
        except AkarmError as e:  # a stop latched, the arm disabled: counted as the topic's refusals are
            self.server.note_refusal(e)
            raise
        mdof = spec.multi_dof_trajectory
        if mdof.joint_names or mdof.points:
            raise TrajectoryRefused("the goal has a multi-DOF trajectory: this arm has no multi-DOF joints",
                                    INVALID_JOINTS, fix="leave multi_dof_trajectory empty")
        points = check_trajectory(spec.trajectory, self.names, self.limits)
        if not points.time_from_start:
            raise TrajectoryRefused("the goal's trajectory has no points", INVALID_GOAL,
                                    fix="give at least one point (to stop the arm, cancel the goal instead)")
        tolerances = goal_tolerances(spec, self.names, self.defaults)
        motion = self.server.follow(points.joint_names, points.times, points.positions, points.velocities)
        previous, self.active = self.active, goal
        if previous is not None:  # its motion blended into this one's: JointTrajectoryController's words
            self._end(previous, ABORTED, INVALID_GOAL, "preempted by a new goal")
        goal.motion, goal.points, goal.tolerances, goal.status = motion, points, tolerances, EXECUTING
        self._next_check = time.monotonic()
        self._checks = 0

    def _end(self, goal: Goal, status: int, code: int, text: str) -> None:
        goal.status, goal.code, goal.text = status, code, text
        goal.ended = time.monotonic()
        goal.motion = None
        if goal is self.active:
            self.active = None
        self._changed = True
        for req in goal.waiting:
            self._reply(self.get_result, req, self._result(goal))
        goal.waiting.clear()
        if status == ABORTED:
            self.log(f"akarm serve: {self.name} goal {goal.id.hex()[:8]} aborted: {text}")

    def _stop_arm(self, motion: Motion | None) -> None:
        """Bring the arm to rest, jerk-limited, and hold (nothing if it is not enabled), when the server
        is free: unless another command replaced ``motion`` (the goal's) meanwhile."""
        def stop() -> None:
            if motion is None or not motion.superseded:
                with contextlib.suppress(AkarmError):
                    self.server.follow([], [], [])
        self.commands.add(stop, always=True)

    # -- cancel, result ----------------------------------------------------------------------------
    def _on_cancel(self, req: at.CancelGoalRequest) -> None:
        """rcl_action ``rcl_action_process_cancel_request``: a goal by id, every goal up to a stamp, or all."""
        code, chosen = cancel_choice(self.goals, req)
        self._reply(self.cancel_goal, req, at.CancelGoalResponse(return_code=code,
                                                                 goals_canceling=[g.info() for g in chosen]))
        for goal in chosen:
            goal.status = CANCELING
            self._changed = True
            if goal is self.active:
                self._stop_arm(goal.motion)
            self._end(goal, CANCELED, SUCCESSFUL, "canceled: the arm stops, jerk-limited, and holds")

    def _result(self, goal: Goal) -> at.GetResultResponse:
        return at.GetResultResponse(status=goal.status, result=at.FollowJointTrajectoryResult(goal.code, goal.text))

    def _on_get_result(self, req: at.GetResultRequest) -> None:
        goal = self.goals.get(bytes(req.goal_id.uuid))
        if goal is None:
            self._reply(self.get_result, req, at.GetResultResponse(status=UNKNOWN))
        elif goal.terminal:
            self._reply(self.get_result, req, self._result(goal))
        else:
            goal.waiting.append(req)

    # -- the running goal --------------------------------------------------------------------------
    def _check(self, goal: Goal) -> None:
        """Tolerances, the end, whatever cut the motion short; feedback."""
        motion, points, tol = goal.motion, goal.points, goal.tolerances
        assert motion is not None and points is not None and tol is not None
        arm = self.server.arm
        fault = arm.fault
        if fault is not None:
            self._end(goal, ABORTED, PATH_TOLERANCE_VIOLATED, f"safety stop: {type(fault).__name__}: {fault}")
            return
        if motion.error is not None:
            self._end(goal, ABORTED, PATH_TOLERANCE_VIOLATED, f"{type(motion.error).__name__}: {motion.error}")
            return
        if motion.superseded:
            if not arm.enabled:
                self._end(goal, ABORTED, PATH_TOLERANCE_VIOLATED, "the arm was disabled")
            else:
                self._end(goal, ABORTED, INVALID_GOAL,
                          "another command replaced the goal's motion (joint_trajectory, akarm move, a hold)")
            return
        t = arm.clock.now() - arm.observe.plan_lag  # the plan's time: it trails the clock by the slots the loop missed
        plan = motion.plan
        q_d, dq_d, ddq_d = plan.sample(t)
        state = arm.state()
        err_q, err_dq = q_d - state.q, dq_d - state.dq
        if t < plan.t_end:
            bad = violation(self.names, err_q, err_dq, tol.path_position, tol.path_velocity)
            if bad is not None:
                self._stop_arm(motion)
                self._end(goal, ABORTED, PATH_TOLERANCE_VIOLATED, f"path tolerance violated: {bad}")
                return
        else:
            bad = violation(self.names, err_q, err_dq, tol.goal_position, tol.goal_velocity)
            if bad is None:
                self._send_feedback(goal, q_d, dq_d, ddq_d, state)
                self._end(goal, SUCCEEDED, SUCCESSFUL, "goal reached")
                return
            late = t - plan.t_end
            if tol.goal_time > 0.0 and late > tol.goal_time:
                self._stop_arm(motion)
                self._end(goal, ABORTED, GOAL_TOLERANCE_VIOLATED,
                          f"goal tolerance not met {late:.3f} s after the trajectory's end (goal_time_tolerance "
                          f"{tol.goal_time:g} s): {bad}")
                return
        self._checks += 1
        if self._checks % 2 == 1:
            self._send_feedback(goal, q_d, dq_d, ddq_d, state)

    def _send_feedback(self, goal: Goal, q_d: np.ndarray, dq_d: np.ndarray, ddq_d: np.ndarray, state: Any) -> None:
        points = goal.points
        assert points is not None
        now = time.time()
        elapsed = max(0.0, now - points.start)
        since = msgs.Duration(int(elapsed), int((elapsed % 1.0) * 1e9))
        desired = msgs.JointTrajectoryPoint(q_d.tolist(), dq_d.tolist(), ddq_d.tolist(), [], since)
        actual = msgs.JointTrajectoryPoint(state.q.tolist(), state.dq.tolist(), [], state.tau.tolist(), since)
        error = msgs.JointTrajectoryPoint((q_d - state.q).tolist(), (dq_d - state.dq).tolist(), [], [], since)
        fields: dict[str, Any] = {"header": msgs.Header(msgs.Time.from_seconds(now), ""), "joint_names": self.names,
                                  "desired": desired, "actual": actual, "error": error}
        if self.distro == "rolling":
            fields["index"] = points.index(now)
        fb_type = at.FeedbackRolling if self.distro == "rolling" else at.FeedbackHumble
        self.feedback.write(self._feedback_type(at.UUID(list(goal.id)), fb_type(**fields)))
