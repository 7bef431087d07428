"""The ROS 2 face of an arm server (:class:`~akarm.server.server.ArmServerCore`), over Cyclone DDS.

With ``NS`` the namespace:

- ``NS/joint_states`` (sensor_msgs/JointState), out: the configured joint names, measured
  positions (rad), velocities (rad/s) and torques (N·m), stamped with the wall clock;
- ``NS/joint_trajectory`` (trajectory_msgs/JointTrajectory), in: executed with the semantics of
  ros2_control's JointTrajectoryController topic (:meth:`~akarm.server.server.ArmServerCore.follow`);
- ``NS/akarm/status`` (diagnostic_msgs/DiagnosticArray), out: mode, a latched safety stop (ERROR:
  its error, joint, time and text), loop statistics, the oldest feedback's age, the last refused
  trajectory;
- ``NS/akarm/enable`` (acknowledges a latched stop), ``NS/akarm/disable``, ``NS/akarm/hold`` (std_srvs/Trigger);
- ``NS/CONTROLLER/follow_joint_trajectory`` (control_msgs/action/FollowJointTrajectory): MoveIt's
  way in (:mod:`akarm.ros.action`); it and ``joint_trajectory`` share one motion, the last one wins;
- ``ros_discovery_info``, naming the node ``NS/NODE`` and its endpoints (:mod:`akarm.ros.graph`).

``joint_states`` is stamped with the time of its readings (the oldest joint's), not the time it is
sent: a disabled arm's silent joints show their age. Whom the node talks to is :func:`akarm.ros.dds.discovery`'s
(this machine only, unless opened); every command it takes (a trajectory, a service call) is logged
with the DDS participant that sent it.

One thread waits on a DDS WaitSet for trajectories and service requests and publishes on time;
service requests are answered in threads of their own (enabling and disabling take a while). That
thread never waits for the server's command lock, which an enable or a disable holds throughout:
trajectories and goals wait for it in a :class:`~akarm.ros.commands.CommandQueue`, in order, while
``joint_states`` and the running goal's checks go on.

:class:`RosNode` is a :class:`~akarm.server.server.Frontend` of the server; :class:`akarm.ArmServer`
(:mod:`akarm.serving`) puts the two together.
"""

from __future__ import annotations

import contextlib
import threading
import time
from typing import TYPE_CHECKING

from cyclonedds.core import DDSException, GuardCondition, ReadCondition, WaitSet

from akarm.errors import AkarmError, ArgumentError
from akarm.ros import msgs
from akarm.ros.action import ActionServer
from akarm.ros.commands import RETRY, CommandQueue
from akarm.ros.dds import ANY, Discovery, Node, RawSample, TriggerServer, decode, sender, take_raw
from akarm.ros.graph import DiscoveryInfo
from akarm.ros.gripper import GripperActionServer
from akarm.ros.trajectory import TrajectoryRefused, check_size, check_trajectory, refusal

if TYPE_CHECKING:
    from akarm.control.gripper import Gripper
    from akarm.server.server import ArmServerCore

__all__ = ["MAX_TWIST_BYTES", "RosNode"]

_LEVEL = {"holding": 0, "moving": 0, "teach": 0, "disabled": 1, "fault": 2}


#: bytes a servo/twist sample may have (a TwistStamped is 68 bytes and its frame_id)
MAX_TWIST_BYTES = 1024


class RosNode:
    """Publishes and serves for ``server`` in a DDS domain and ROS 2 namespace, in a thread of its own:
    the node ``node_name``, whose FollowJointTrajectory action is ``controller``'s, with the message
    layouts of ROS 2 ``distro`` (``humble``, ``jazzy``, ``rolling``)."""

    def __init__(self, server: ArmServerCore, domain: int, namespace: str, joint_states_hz: float,
                 status_hz: float, reach: Discovery | None = None, *, controller: str = "arm_controller",
                 distro: str = "jazzy", node_name: str = "akarm",
                 gripper_controller: str = "gripper_controller") -> None:
        self.server = server
        self.gripper: Gripper | None = server.arm.gripper
        self.gripper_action: GripperActionServer | None = None
        self._said = (0.0, 0)  # when a command was last logged, and how many were not since
        try:
            self.node = Node(domain, namespace, reach)
            self._open(controller, distro, node_name, gripper_controller)
        except AkarmError:  # a bad controller or node name, an unknown distribution: nothing left open
            with contextlib.suppress(Exception):
                self.node.close()
            raise
        except DDSException as e:  # a bad CYCLONEDDS_URI (an interface this machine lacks), no network
            with contextlib.suppress(Exception):
                self.node.close()
            raise AkarmError(f"Cyclone DDS could not start the ROS 2 node in domain {domain}: {e}",
                             fix="check CYCLONEDDS_URI (its network interface must exist here; unset it for "
                                 "the default), or serve without ROS 2 (akarm serve --no-ros)") from None
        if reach is not None:
            for warning in reach.warnings:
                server.log(f"akarm serve: warning: {warning}")
            server.log(f"akarm serve: ROS 2 reaches {reach.describe()}")
        if self.node.note:
            server.log(f"akarm serve: warning: {self.node.note}; it applies")
        self.js_period = 1.0 / joint_states_hz
        self.status_period = 1.0 / status_hz
        self._running = threading.Event()
        self._thread: threading.Thread | None = None
        self.names = list(server.arm.names)
        self.published = 0
        self.errors = 0

    def _open(self, controller: str, distro: str, node_name: str, gripper_controller: str) -> None:
        n = self.node
        self._js = n.publisher("joint_states", msgs.JointState)
        self._status = n.publisher("akarm/status", msgs.DiagnosticArray)
        self._traj = n.subscription("joint_trajectory", msgs.JointTrajectory)
        self._twist = n.subscription("servo/twist", msgs.TwistStamped)  # as MoveIt Servo takes it
        self.commands = CommandQueue(self.server)  # the topic's and the action's, in order
        self._services = [TriggerServer(n, "akarm/enable", self._enable, self._heard),
                          TriggerServer(n, "akarm/disable", self._disable, self._heard),
                          TriggerServer(n, "akarm/hold", self._hold, self._heard)]
        self.action = ActionServer(n, self.server, controller, distro, heard=self._heard, commands=self.commands)
        actions: list[ActionServer | GripperActionServer] = [self.action]
        if self.gripper is not None:
            self.gripper_action = GripperActionServer(n, self.server, self.gripper, gripper_controller,
                                                      heard=self._heard, commands=self.commands)
            actions.append(self.gripper_action)
        self._actions = actions
        self.discovery = DiscoveryInfo(n, node_name, distro)
        self.discovery.publish()  # every endpoint is open by now
        self._traj_cond = ReadCondition(self._traj, ANY)
        self._twist_cond = ReadCondition(self._twist, ANY)
        self._wake = GuardCondition(n.participant)
        self._waitset = WaitSet(n.participant)
        for c in (self._traj_cond, self._twist_cond, self._wake, *(s.condition for s in self._services),
                  *(c for a in self._actions for c in a.conditions)):
            self._waitset.attach(c)

    def _heard(self, text: str) -> None:
        """Log a command taken from DDS: five a second in full, then counted (said when the second is over)."""
        start, count = self._said
        now = time.monotonic()
        if now - start >= 1.0:
            if count > 5:
                self.server.log(f"akarm serve: ROS 2: {count - 5} more commands in that second, not shown")
            start, count = now, 0
        self._said = (start, count + 1)
        if count < 5:
            self.server.log(f"akarm serve: ROS 2: {text}")

    # -- services ------------------------------------------------------------------------------
    def _enable(self) -> tuple[bool, str]:
        self.server.enable()
        return True, "enabled: holding where it is"

    def _disable(self) -> tuple[bool, str]:
        self.server.disable()
        return True, "disabled: damped, then motor mode exited (the arm is limp)"

    def _hold(self) -> tuple[bool, str]:
        self.server.hold()
        return True, f"holding ({self.server.mode})"

    # -- the thread ----------------------------------------------------------------------------
    def start(self) -> None:
        self._running.set()
        self._thread = threading.Thread(target=self._run, name="akarm-ros", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._running.clear()
        with contextlib.suppress(Exception):
            self._wake.set(True)
        if self._thread is not None:
            self._thread.join(5.0)
        for a in self._actions:
            a.close()
        self.node.close()

    def _run(self) -> None:
        """Serve until :meth:`stop`. An error of DDS (or a bug) is logged and counted, and serving goes
        on: this thread ending silently would leave the arm held with nothing published."""
        self._next = [time.monotonic(), time.monotonic()]  # joint_states, status
        while self._running.is_set():
            try:
                self._serve_once()
            except Exception as e:
                self.errors += 1
                if self.errors <= 10 or self.errors % 1000 == 0:
                    self.server.log(f"akarm serve: the ROS 2 interface failed ({type(e).__name__}: {e}); "
                                    f"going on ({self.errors} so far)")
                time.sleep(0.05)

    def _serve_once(self) -> None:
        next_js, next_status = self._next
        wait = max(0.0, min(next_js, next_status, *(a.next_due() for a in self._actions)) - time.monotonic())
        if len(self.commands):  # waiting for the server's command lock: try again soon
            wait = min(wait, RETRY)
        self._waitset.wait(int(min(wait, 1.0) * 1e9))
        if not self._running.is_set():
            return
        for raw in take_raw(self._traj, 16):
            self.take_topic(raw)
        twists = take_raw(self._twist, 16)
        if twists:
            self.take_twist(twists[-1])  # the latest: older ones are already out of date
        for a in self._actions:
            a.poll()
        for s in self._services:  # answered in threads of their own: enabling takes a while, and
            for req in s.take():  # joint_states must go on meanwhile
                self._heard(f"{s.name} called by {s.caller(req)}")
                threading.Thread(target=s.answer, args=(req,), name="akarm-ros-service", daemon=True).start()
        now = time.monotonic()
        if now >= next_js:
            self.publish_joint_states()
            next_js += self.js_period * (1 + int((now - next_js) / self.js_period))  # skip, never burst
        if now >= next_status:
            self.publish_status()
            next_status = now + self.status_period
        self._next = [next_js, next_status]

    def take_topic(self, raw: RawSample) -> None:
        """A ``joint_trajectory`` sample as taken: refused from its size before it is decoded, or when it
        does not decode (a string that is not UTF-8: that sample alone; counted and reported as the
        server's refusals are), else decoded and :meth:`follow_topic` when the server is free (now,
        unless an enable or a disable runs: then after it, in order with the action's goals)."""
        try:
            check_size(raw.data, 4, self.names)
            msg = decode(msgs.JointTrajectory, raw)
        except ArgumentError as e:
            refusal(e).report(self.server)
            self._heard(f"joint_trajectory from {sender(self._traj, raw)}: {len(raw.data)} bytes: refused "
                        f"({type(e).__name__}: {e.what})")
            return
        try:
            self.commands.add(lambda: self.follow_topic(msg), len(msg.points))
        except AkarmError as e:  # too much waits for the server
            self.server.note_refusal(e)
            self._heard(f"joint_trajectory from {sender(self._traj, raw)}: refused ({type(e).__name__})")

    def take_twist(self, raw: RawSample) -> None:
        """A ``servo/twist`` sample (geometry_msgs/TwistStamped): servo the tool by it
        (:meth:`~akarm.server.server.ArmServerCore.servo_twist`), in the tool's axes when ``frame_id``
        names the tool frame, else the base's; a refusal is logged (rate-limited) and nothing moves."""
        who = sender(self._twist, raw)
        try:
            if len(raw.data) > MAX_TWIST_BYTES:
                raise ArgumentError(f"a TwistStamped of {len(raw.data)} bytes (at most {MAX_TWIST_BYTES})")
            msg = decode(msgs.TwistStamped, raw)
            t = msg.twist
            frame = "tool" if msg.header.frame_id == self.server.arm.ik.model.tool_frame else "base"
            self.server.servo_twist([t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y, t.angular.z],
                                    frame=frame)
        except AkarmError as e:
            self._heard(f"servo/twist from {who}: refused ({type(e).__name__}: {e.what})")

    def follow_topic(self, msg: msgs.JointTrajectory) -> None:
        """A ``joint_trajectory`` message: checked as the action's goals are, then followed (no points:
        a stop); a refusal is reported by the server (its log, ``akarm/status``) and nothing moves. Logged
        with the participant that sent it (a joint name that is not printable, as Python writes it: a
        line break or a terminal escape in it would forge the server's log lines)."""
        who = sender(self._traj, msg)
        names = ", ".join(n if n.isprintable() else repr(n) for n in msg.joint_names[:20])[:200]
        what = f"joint_trajectory from {who}: {len(msg.points)} points for {names}"
        try:
            points = check_trajectory(msg, self.server.arm.names, self.server.arm.limits)
        except TrajectoryRefused as e:
            e.report(self.server)
            self._heard(f"{what}: refused ({type(e).__name__})")
            return
        try:
            self.server.follow(points.joint_names, points.times, points.positions, points.velocities)
        except AkarmError as e:  # refused: reported by the server (status, log)
            self._heard(f"{what}: refused ({type(e).__name__})")
            return
        self._heard(f"{what}: accepted")

    def publish_joint_states(self) -> None:
        """``joint_states`` stamped with when its readings were taken (the oldest joint's); the gripper's
        joints after the arm's (:meth:`gripper_joints`)."""
        s = self.server.arm.state()
        age = max((j.age for j in s.joints), default=0.0)
        stamp = time.time() - (age if age < 1e9 else 0.0)  # never heard: now (the positions are NaN)
        names, q, dq, tau = list(self.names), s.q.tolist(), s.dq.tolist(), s.tau.tolist()
        for name, position, velocity, effort in self.gripper_joints():
            names.append(name)
            q.append(position)
            dq.append(velocity)
            tau.append(effort)
        self._js.write(msgs.JointState(msgs.Header(msgs.Time.from_seconds(stamp), ""), names, q, dq, tau))
        self.published += 1

    def gripper_joints(self) -> list[tuple[str, float, float, float]]:
        """The gripper's joints in ``joint_states``: (name, position, velocity, effort). The gripper's
        own name (the robot file's ``gripper.name``) with the width between the jaws (m), its rate (m/s)
        and the squeeze (N); then each finger joint the robot file names (``gripper.fingers``: the
        URDF's, prismatic) at half the width (m) and half the rate, each jaw moving half the width.
        None without a gripper; NaN while the gripper's motor is not heard."""
        g = self.gripper
        if g is None:
            return []
        try:
            s = g.state()
            width, velocity, force = float(s.width), float(s.velocity), float(s.force)
        except AkarmError:
            width = velocity = force = float("nan")
        joints = [(g.name, width, velocity, force)]
        cfg = self.server.arm.config.gripper
        fingers = cfg.fingers if cfg is not None else ()
        joints += [(f, width / 2.0, velocity / 2.0, force) for f in fingers if f != g.name]
        return joints

    def publish_status(self) -> None:
        doc = self.server.status()
        mode = doc["mode"]
        text = f"safety stop latched: {doc['stop_error']}: {doc['fault']}" if mode == "fault" else mode
        values = [msgs.KeyValue(k, str(v)) for k, v in doc.items()]
        cfg = self.server.arm.config
        st = msgs.DiagnosticStatus(_LEVEL.get(mode, 1), f"akarm: {cfg.name}", text, cfg.name, values)
        self._status.write(msgs.DiagnosticArray(msgs.Header(msgs.Time.from_seconds(time.time()), ""), [st]))
