"""``NS/CONTROLLER/gripper_cmd``: the ``control_msgs/action/GripperCommand`` action server of the arm's
gripper (``arm.gripper``), beside the FollowJointTrajectory action (:mod:`akarm.ros.action`), laid out on
DDS as rcl_action lays an action out (the same services, topics and QoS as that one).

A goal is ``command.position``, the width between the jaws asked (m, 0 = closed .. the gripper's
``stroke``), and ``command.max_effort``, the most the jaws may squeeze (N; 0 or less: the gripper's
default force, a fraction of its ``force_limit``). The semantics are ros2_controllers' gripper
controllers' (``gripper_action_controller``, ``parallel_gripper_action_controller``):

- every goal is accepted; a new goal preempts the running one, which ends CANCELED (its result empty,
  as ros2_controllers' ``preempt_active_goal`` leaves it);
- a goal the gripper refuses (a width outside 0..stroke or not a number, a force it refuses, the arm
  disabled or a safety stop latched) is aborted at once, nothing moves; GripperCommand's result has no
  text, so the reason is in the server's log and in ``akarm/status`` (``last_refusal``), as a refused
  trajectory's is;
- the goal is checked at :data:`MONITOR_HZ` (the controllers' ``action_monitor_rate``), each time with
  feedback (``position`` m, ``effort`` N: the squeeze the gripper estimates, ``stalled`` and
  ``reached_goal`` false while it runs);
- **reached**: the jaws at rest within :data:`GOAL_TOLERANCE` of the width asked: SUCCEEDED,
  ``reached_goal`` true, ``stalled`` false;
- **grasped**: the jaws stopped short of the width asked on something and press it (the gripper's
  ``grasped``): SUCCEEDED, ``stalled`` true, ``reached_goal`` false: parallel_gripper_controller with
  ``allow_stalling: true``. Holding an object is what a close is for (MoveIt's pick counts it a success);
- **stalled**: the jaws did not move faster than :data:`STALL_VELOCITY` for :data:`STALL_TIMEOUT` s, short
  of the width asked, without a grasp: ABORTED, ``stalled`` true (a jam, not an object);
- a cancel holds the jaws where they are (the gripper asked for its own width now, at the default force),
  and the goal ends CANCELED, as the controllers' ``set_hold_position``;
- a safety stop, a disable and the server stopping abort the goal (``stalled`` and ``reached_goal``
  false, the last position and effort).

Everything runs in the ROS 2 node's thread; a goal's start and a cancel's hold wait for the server's
command lock in the node's :class:`~akarm.ros.commands.CommandQueue`, in order with the arm's goals.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections import OrderedDict
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from akarm.errors import AkarmError
from akarm.ros import action_types as at
from akarm.ros import msgs
from akarm.ros.action import (
    ABORTED,
    ACCEPTED,
    CANCELED,
    CANCELING,
    EXECUTING,
    MAX_RESULTS,
    RESULT_TIMEOUT,
    SUCCEEDED,
    UNKNOWN,
    cancel_choice,
)
from akarm.ros.commands import CommandQueue
from akarm.ros.dds import Node, ServiceServer, latched_qos, qos, topic_name

if TYPE_CHECKING:
    from akarm.control.gripper import Gripper, GripperState
    from akarm.server.server import ArmServerCore

__all__ = [
    "GOAL_TOLERANCE",
    "MONITOR_HZ",
    "STALL_TIMEOUT",
    "STALL_VELOCITY",
    "GripperActionServer",
    "GripperGoal",
    "gripper_action_name",
    "outcome",
]

#: Checks (and feedback messages) per second while a goal runs (the controllers' ``action_monitor_rate``).
MONITOR_HZ = 20.0
#: m: a goal is reached when the jaws rest this close to the width asked (the gripper's own tolerance is 1 mm).
GOAL_TOLERANCE = 0.002
#: m/s: slower than this the jaws count as not moving (an AK motor's velocity reads in steps of ~0.02 rad/s,
#: some 1 mm/s of width on a typical rack and pinion: ros2_controllers' 0.001 could never be seen).
STALL_VELOCITY = 0.005
#: s the jaws may rest short of the width asked, without a grasp, before the goal aborts as stalled
#: (ros2_controllers' ``stall_timeout``).
STALL_TIMEOUT = 1.0


def gripper_action_name(controller: str) -> str:
    """The action's name under the namespace: ``CONTROLLER/gripper_cmd``."""
    return f"{controller.strip('/')}/gripper_cmd"


def outcome(reading: GripperState, target: float, still_since: float | None,
            now: float) -> tuple[int, bool, bool] | None:
    """How a running goal for the width ``target`` ends given the gripper's ``reading`` now, the jaws
    having been still since ``still_since`` (None: they move): ``(status, stalled, reached_goal)``, or
    None while it runs. See the module's text."""
    err = abs(reading.width - target)
    at_rest = not reading.moving or (still_since is not None and now - still_since >= STALL_TIMEOUT)
    if err < GOAL_TOLERANCE and at_rest:
        return SUCCEEDED, False, True
    if reading.grasped:
        return SUCCEEDED, True, False
    if still_since is not None and now - still_since >= STALL_TIMEOUT:
        return ABORTED, True, False
    return None


class GripperGoal:
    """One goal of the action: its id, status, result, and the width and force asked."""

    def __init__(self, goal_id: bytes, stamp: msgs.Time, width: float, force: float | None) -> None:
        self.id = goal_id
        self.stamp = stamp
        self.width = width
        self.force = force
        self.status = ACCEPTED
        self.result = at.GripperCommandResult()
        self.ended: float | None = None
        self.still_since: float | None = None
        self.waiting: list[at.GripperGetResultRequest] = []

    @property
    def terminal(self) -> bool:
        return self.status in (SUCCEEDED, CANCELED, ABORTED)

    def info(self) -> at.GoalInfo:
        return at.GoalInfo(at.UUID(list(self.id)), self.stamp)


class GripperActionServer:
    """The GripperCommand action of ``gripper`` (the arm's, served by ``server``), on ``node``, at
    ``NS/CONTROLLER/gripper_cmd``. Like :class:`~akarm.ros.action.ActionServer`: :attr:`conditions` go
    into the node's WaitSet; call :meth:`poll` whenever it wakes and by :meth:`next_due`; :meth:`close`
    before the node closes."""

    def __init__(self, node: Node, server: ArmServerCore, gripper: Gripper,
                 controller: str = "gripper_controller", log: Callable[[str], None] | None = None,
                 heard: Callable[[str], None] | None = None, commands: CommandQueue | None = None) -> None:
        self.server = server
        self.gripper = gripper
        self.commands = commands if commands is not None else CommandQueue(server)
        self.heard = heard
        self.name = gripper_action_name(controller)
        self.log = log or server.log
        base = self.name + "/_action/"
        bad = heard or self.log
        self.send_goal = ServiceServer(node, base + "send_goal", at.GripperSendGoalRequest,
                                       at.GripperSendGoalResponse, bad)
        self.cancel_goal = ServiceServer(node, base + "cancel_goal", at.CancelGoalRequest, at.CancelGoalResponse, bad)
        self.get_result = ServiceServer(node, base + "get_result", at.GripperGetResultRequest,
                                        at.GripperGetResultResponse, bad)
        self.feedback = node.writer(topic_name(node.namespace, base + "feedback"), at.GripperFeedbackMessage, qos())
        self.status = node.writer(topic_name(node.namespace, base + "status"), at.GoalStatusArray, latched_qos())
        self.conditions = [s.condition for s in (self.send_goal, self.cancel_goal, self.get_result)]
        self.goals: OrderedDict[bytes, GripperGoal] = OrderedDict()
        self.active: GripperGoal | None = None
        self._pending: list[tuple[ServiceServer, Any, Any, float]] = []
        self._next_check = math.inf
        self._changed = True

    # -- the node's thread ---------------------------------------------------------------------
    def next_due(self) -> float:
        """Monotonic time :meth:`poll` has work next."""
        due = self._next_check if self.active is not None and self.active.status == EXECUTING else math.inf
        if self._pending or self._changed or len(self.commands):
            due = min(due, time.monotonic() + 0.005)
        ended = [g.ended for g in self.goals.values() if g.ended is not None]
        return min([due, *(t + RESULT_TIMEOUT for t in ended)])

    def poll(self) -> None:
        """Answer the requests waiting, check the running goal and send its feedback, retry replies,
        forget old results, publish the status if it changed."""
        self.commands.run()
        for req in self.send_goal.take():
            if self.heard is not None:
                self.heard(f"{self.name} goal from {self.send_goal.caller(req)}")
            self._on_send_goal(req)
        for creq in self.cancel_goal.take():
            if self.heard is not None:
                self.heard(f"{self.name} cancel from {self.cancel_goal.caller(creq)}")
            self._on_cancel(creq)
        for rreq in self.get_result.take():
            self._on_get_result(rreq)
        now = time.monotonic()
        goal = self.active
        if goal is not None and goal.status == EXECUTING and now >= self._next_check:
            self._check(goal, now)
            period = 1.0 / MONITOR_HZ
            self._next_check += period * (1 + int((now - self._next_check) / period))  # skip, never burst
        self._retry_replies(now)
        self._forget(now)
        if self._changed:
            self._changed = False
            self.status.write(at.GoalStatusArray([at.GoalStatus(g.info(), g.status) for g in self.goals.values()]))

    def close(self) -> None:
        """The server is stopping: abort the goals not ended, and say so."""
        for goal in [g for g in self.goals.values() if not g.terminal]:
            self._end(goal, ABORTED, "akarm serve stopped")
        with contextlib.suppress(Exception):
            self._retry_replies(math.inf)
            self.status.write(at.GoalStatusArray([at.GoalStatus(g.info(), g.status) for g in self.goals.values()]))

    def _forget(self, now: float) -> None:
        ended = [(g.id, g.ended) for g in self.goals.values() if g.ended is not None]
        excess = max(0, len(ended) - MAX_RESULTS)
        for k, (gid, t) in enumerate(ended):
            if k < excess or now > t + RESULT_TIMEOUT:
                del self.goals[gid]
                self._changed = True

    # -- replies ---------------------------------------------------------------------------------
    def _reply(self, service: ServiceServer, request: Any, response: Any) -> None:
        if service.reply(request, response, wait=0.0) == "maybe":
            self._pending.append((service, request, response, time.monotonic() + 0.1))

    def _retry_replies(self, now: float) -> None:
        pending, self._pending = self._pending, []
        for service, request, response, deadline in pending:
            if service.reply(request, response, wait=0.0) == "maybe" and now < deadline:
                self._pending.append((service, request, response, deadline))

    # -- goals -----------------------------------------------------------------------------------
    def _on_send_goal(self, req: at.GripperSendGoalRequest) -> None:
        goal_id = bytes(req.goal_id.uuid)
        stamp = msgs.Time.from_seconds(time.time())
        if goal_id in self.goals:  # rcl_action refuses a goal ID it already has
            self._reply(self.send_goal, req, at.GripperSendGoalResponse(accepted=False, stamp=stamp))
            return
        effort = req.goal.command.max_effort
        force = None if effort == 0.0 or (math.isfinite(effort) and effort < 0.0) else effort  # 0, <0: the default
        goal = self.goals[goal_id] = GripperGoal(goal_id, stamp, req.goal.command.position, force)
        self._reply(self.send_goal, req, at.GripperSendGoalResponse(accepted=True, stamp=stamp))
        self._changed = True
        try:
            self.commands.add(lambda: self._begin(goal))
        except AkarmError as e:  # too much waits for the server
            self.server.note_refusal(e)
            self._end(goal, ABORTED, str(e))

    def _begin(self, goal: GripperGoal) -> None:
        """(Holding the server's command lock) start the goal, unless it was canceled while it waited."""
        if goal.terminal:
            return
        try:
            self.server.check_motion_allowed()
            self.gripper.move_to(goal.width, goal.force, wait=False)
        except AkarmError as e:  # a width past the stroke, a bad force, the arm disabled, a stop latched
            self.server.note_refusal(e)
            self._end(goal, ABORTED, f"{type(e).__name__}: {e}")
            return
        previous, self.active = self.active, goal
        if previous is not None and not previous.terminal:  # preempted: canceled, with an empty result
            self._end(previous, CANCELED, "preempted by a new goal", empty=True)
        goal.status = EXECUTING
        self._changed = True
        self._next_check = time.monotonic() + 1.0 / MONITOR_HZ

    def _end(self, goal: GripperGoal, status: int, text: str, *, stalled: bool = False, reached: bool = False,
             empty: bool = False) -> None:
        if not empty:
            with contextlib.suppress(Exception):  # the last reading (a fault leaves one too)
                s = self.gripper.state()
                goal.result = at.GripperCommandResult(float(s.width), float(s.force), stalled, reached)
        goal.status = status
        goal.ended = time.monotonic()
        if goal is self.active:
            self.active = None
        self._changed = True
        for req in goal.waiting:
            self._reply(self.get_result, req, at.GripperGetResultResponse(status=status, result=goal.result))
        goal.waiting.clear()
        if status == ABORTED:
            self.log(f"akarm serve: {self.name} goal {goal.id.hex()[:8]} (width {goal.width:g} m) aborted: {text}")

    # -- cancel, result ----------------------------------------------------------------------------
    def _on_cancel(self, req: at.CancelGoalRequest) -> None:
        """rcl_action ``rcl_action_process_cancel_request``: a goal by id, every goal up to a stamp, or all."""
        code, chosen = cancel_choice(self.goals, req)
        self._reply(self.cancel_goal, req, at.CancelGoalResponse(return_code=code,
                                                                 goals_canceling=[g.info() for g in chosen]))
        for goal in chosen:
            goal.status = CANCELING
            if goal is self.active:
                self.commands.add(self._hold, always=True)
            self._end(goal, CANCELED, "canceled")

    def _hold(self) -> None:
        """(Holding the server's command lock) the jaws stay where they are, at the default force."""
        with contextlib.suppress(AkarmError):
            self.server.check_motion_allowed()
            s = self.gripper.state()
            width = min(max(float(s.width), 0.0), float(self.gripper.stroke))
            if math.isfinite(width):
                self.gripper.move_to(width, None, wait=False)

    def _on_get_result(self, req: at.GripperGetResultRequest) -> None:
        goal = self.goals.get(bytes(req.goal_id.uuid))
        if goal is None:
            self._reply(self.get_result, req, at.GripperGetResultResponse(status=UNKNOWN))
        elif goal.terminal:
            self._reply(self.get_result, req, at.GripperGetResultResponse(status=goal.status, result=goal.result))
        else:
            goal.waiting.append(req)

    # -- the running goal --------------------------------------------------------------------------
    def _check(self, goal: GripperGoal, now: float) -> None:
        arm = self.server.arm
        fault = arm.fault
        if fault is not None:
            self._end(goal, ABORTED, f"safety stop: {type(fault).__name__}: {fault}")
            return
        if not arm.enabled:
            self._end(goal, ABORTED, "the arm was disabled")
            return
        s = self.gripper.state()
        if abs(float(s.velocity)) > STALL_VELOCITY:
            goal.still_since = None
        elif goal.still_since is None:
            goal.still_since = now
        end = outcome(s, goal.width, goal.still_since, now)
        self.feedback.write(at.GripperFeedbackMessage(at.UUID(list(goal.id)), at.GripperCommandFeedback(
            float(s.width), float(s.force), False if end is None else end[1], False if end is None else end[2])))
        if end is not None:
            status, stalled, reached = end
            what = "reached" if reached else ("holds an object" if status == SUCCEEDED else "stalled, no grasp")
            self._end(goal, status, what, stalled=stalled, reached=reached)
