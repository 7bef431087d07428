"""The control loop's real clock and real-time requests, on real threads and the wall clock (the
stepped clock: tests/unit/test_loop.py)."""

from __future__ import annotations

import gc
import math
import os
import subprocess
import sys
import threading
import time

import pytest

import akarm
from akarm import Arm, load_robot
from akarm.clock import RealClock
from akarm.control.controller import WAIT_SLICE, WAKE_BACKSTOP
from akarm.control.cpuidle import PM_QOS_PATH
from akarm.control.loop import TIMER_SLACK, ControlLoop, request_realtime, timer_slack
from akarm.sim import SimulatedRobot

from .conftest import ROBOTS, wait_until


@pytest.fixture
def default_switch_interval():
    """Python's default switch interval, 5 ms, for the test (``request_realtime`` lowers it for
    good); the process's own is restored after."""
    before = sys.getswitchinterval()
    sys.setswitchinterval(0.005)
    yield
    sys.setswitchinterval(before)


@pytest.mark.parametrize("busy", [False, True])
def test_real_clock_wakes_at_the_deadline_and_lets_other_threads_run(busy, default_switch_interval):
    # (a thread that only computes keeps the interpreter lock for the switch interval, 5 ms by
    # default: the control loop shortens it, as here)
    sys.setswitchinterval(1e-4)
    c = RealClock(busy=busy)
    counted = [0]
    stop = threading.Event()

    def count() -> None:
        while not stop.is_set():
            counted[0] += 1

    th = threading.Thread(target=count)
    th.start()
    try:
        late = []
        for _ in range(20):
            t = c.now() + 0.005
            c.sleep_until(t)
            late.append(c.now() - t)
    finally:
        stop.set()
        th.join()
    assert min(late) >= 0.0
    assert counted[0] > 1000  # the other thread got the interpreter while the clock waited
    # the median wake-up is not a whole 5 ms switch interval late; bound generously, as a loaded
    # machine takes the core away for a time slice (~3 ms); the real numbers are bench_loop's
    assert sorted(late)[10] < 0.02


def test_request_realtime_never_raises_and_keeps_python_pauses_short(default_switch_interval):
    report: list[str] = []
    th = threading.Thread(target=lambda: report.append(request_realtime(lock_memory=False, switch_interval=1e-4)))
    try:
        th.start()
        th.join()
        assert "SCHED_FIFO priority 80 granted" in report[0] or "real-time priority refused" in report[0]
        assert "garbage collector frozen" in report[0] and gc.get_freeze_count() > 0
        assert sys.getswitchinterval() == pytest.approx(1e-4, abs=2e-6)
        assert "switch interval 100 µs" in report[0]
    finally:
        gc.unfreeze()


_IDLE_CHILD = """
import os, struct, time
from akarm.clock import RealClock
from akarm.control.cpuidle import PM_QOS_PATH
from akarm.control.loop import ControlLoop
def bound():  # the kernel's request in force, µs (reading the device gives it)
    with open(PM_QOS_PATH, "rb") as f:
        return struct.unpack("=i", f.read(4))[0]
before = bound()
loop = ControlLoop(200.0, RealClock(), lambda now, slot: None, realtime_priority=True)
loop.start()
time.sleep(0.2)
during, report = bound(), loop.realtime_report
loop.stop()
time.sleep(0.05)
print(before, during, bound(), report, sep="|")
"""


@pytest.mark.skipif(not os.access(PM_QOS_PATH, os.R_OK | os.W_OK), reason="needs write access to " + PM_QOS_PATH)
def test_a_real_time_loop_holds_cpus_out_of_deep_idle_only_while_it_runs():
    # in a child: a real-time loop locks memory and changes the scheduling of its process
    out = subprocess.run([sys.executable, "-c", _IDLE_CHILD], capture_output=True, text=True, timeout=60, check=True)
    before, during, after, report = out.stdout.strip().split("|")
    assert "CPU idle latency held at 0 µs" in report
    assert int(during) == 0
    assert int(after) == int(before)  # withdrawn when the loop's thread ended (or another holder's own)


def test_a_running_loop_makes_other_threads_hand_over_the_interpreter_quickly(default_switch_interval):
    ran = threading.Event()
    loop = ControlLoop(500.0, RealClock(), lambda now, slot: ran.set())
    try:
        loop.start()
        assert ran.wait(5.0)
        assert sys.getswitchinterval() == pytest.approx(100e-6, abs=2e-6)  # a twentieth of the 2 ms period
        slower = ControlLoop(100.0, RealClock(), lambda now, slot: None)  # two loops: the smaller interval
        slower.start()
        slower.wait_cycle(5.0)
        assert sys.getswitchinterval() == pytest.approx(100e-6, abs=2e-6)
        slower.stop()
        assert sys.getswitchinterval() == pytest.approx(100e-6, abs=2e-6)  # the faster one still runs
    finally:
        loop.stop()
    assert sys.getswitchinterval() == 0.005  # the last loop stopped: Python's own again


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="timer slack is Linux's")
def test_the_loop_thread_sleeps_with_a_microsecond_of_timer_slack_and_leaves_the_others_theirs():
    seen: list[int | None] = []
    loop = ControlLoop(500.0, RealClock(), lambda now, slot: seen.append(timer_slack()))
    before = timer_slack()
    try:
        loop.start()
        loop.wait_cycle(5.0)
        loop.wait_cycle(5.0)
    finally:
        loop.stop()
    assert before is not None and before != TIMER_SLACK  # (Linux's default: 50 µs)
    assert seen and set(seen) == {TIMER_SLACK}
    assert timer_slack() == before  # the caller's thread keeps its own


class _Waits:
    """Counts, in the calling thread only, the times it goes to sleep in ``Condition.wait`` and
    ``time.sleep`` (the ways a caller of the Arm waits for the loop)."""

    def __init__(self) -> None:
        self.count = 0

    def __call__(self, frame, event, arg):  # sys.setprofile's hook
        if (event == "call" and frame.f_code.co_name == "wait" and frame.f_code.co_filename.endswith("threading.py")
                and "self" in frame.f_locals and isinstance(frame.f_locals["self"], threading.Condition)) or (
                event == "c_call" and arg is time.sleep):
            self.count += 1

    def __enter__(self) -> _Waits:
        sys.setprofile(self)
        return self

    def __exit__(self, *exc: object) -> None:
        sys.setprofile(None)


def test_a_caller_waiting_for_a_move_or_a_time_is_not_woken_every_cycle(channel):
    """A waiting move sleeps until its motion ends (its event; a stop, a close and a crash end it too, and
    it looks every WAKE_BACKSTOP anyway), ``Arm.sleep`` until its time (looking for a stop or a close
    every WAIT_SLICE meanwhile): not woken after every cycle (each wake-up
    cost the process about 40 µs of CPU a cycle); the move still returns within a few cycles of its end."""
    config = load_robot(ROBOTS / "planar2.yaml").with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(config, realtime=True, q0=[-math.pi / 2, 0.0]), \
            Arm(config, remember_positions=False) as arm:
        arm.enable()
        period = 1.0 / config.rate_hz
        motion = arm.move_to([-math.pi / 2 + 0.3, 0.2], wait=False)
        t0 = time.perf_counter()
        with _Waits() as waits:
            motion.wait()
        waited = time.perf_counter() - t0  # (longer than the plan where the loop missed slots)
        assert motion.done and not motion.superseded and waited > 0.2
        assert waits.count <= waited / WAKE_BACKSTOP + 10  # (every WAIT_SLICE before: 0.1 the backstop)
        assert waits.count < 0.5 * waited / period  # (one per cycle before that)
        s0 = arm.stats().cycles
        t0 = time.perf_counter()
        with _Waits() as waits:
            arm.sleep(0.3)
        assert time.perf_counter() - t0 >= 0.3
        assert arm.stats().cycles - s0 >= 0.3 / period / 2  # the loop ran meanwhile
        assert waits.count <= 0.3 / WAIT_SLICE + 5
        # and a move still returns at its end, not a slice or more after it (generous: a loaded machine)
        t0 = time.perf_counter()
        back = arm.move_to([-math.pi / 2, 0.0])
        assert back.done and not arm.state().moving
        assert time.perf_counter() - t0 < back.duration + 0.25
        assert arm.state().q_des == pytest.approx([-math.pi / 2, 0.0])


def test_a_caller_waiting_for_a_move_learns_of_a_crash_of_the_loop_at_once(channel):
    """Its wait looks for a crash only every WAKE_BACKSTOP by itself: the crash ends the motion, which
    wakes it, and it raises the crash (not a motion that merely ended)."""
    config = load_robot(ROBOTS / "planar2.yaml").with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(config, realtime=True, q0=[-math.pi / 2, 0.0]), \
            Arm(config, remember_positions=False) as arm:
        arm.enable()
        motion = arm.move_to([-math.pi / 2 + 0.6, 0.4], wait=False)
        ended = threading.Event()
        errors: list[BaseException] = []

        def wait() -> None:
            try:
                motion.wait()
            except BaseException as e:  # (what the caller would see)
                errors.append(e)
            ended.set()

        th = threading.Thread(target=wait)
        th.start()
        time.sleep(0.05)  # the caller waits for the motion's end
        loop = arm.observe.loop
        cycle = loop.cycle
        crashed = threading.Event()

        def crash(now: float, slot: int) -> None:
            crashed.set()
            raise RuntimeError("a bug in a cycle")

        loop.cycle = crash
        assert crashed.wait(5.0)
        t0 = time.perf_counter()
        assert ended.wait(5.0)
        woke = time.perf_counter() - t0
        th.join()
        loop.cycle = cycle
        assert len(errors) == 1 and isinstance(errors[0], akarm.StateError) and "crashed" in str(errors[0])
        assert woke < 10 * WAKE_BACKSTOP  # (at once here; generous for a loaded machine)
        end = time.perf_counter() + 2.0
        while not motion.done and time.perf_counter() < end:
            time.sleep(0.005)
        assert motion.done and motion.superseded  # the crash ended it: what woke the caller
        assert not loop.running


def test_a_crash_of_the_loop_damps_then_disables_the_arm_and_leaves_it_in_fault(channel):
    """The crashed loop sent the exit frames once, straight from a held pose (no damping: the arm
    dropped), a driver that missed them stayed powered holding kp = 20 with no loop running, and the
    arm still said it was enabled. Now its last act is a stop's own steps: damping for the stop's
    time, then the exit frames on RELEASES cycles; then FAULT, with a LoopCrashed that enable raises."""
    from akarm.control.controller import RELEASES
    from akarm.protocol import mit

    config = load_robot(ROBOTS / "planar2.yaml").with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(config, realtime=True, q0=[-math.pi / 2, 0.0], log_frames=True) as sim, \
            Arm(config, remember_positions=False) as arm:
        arm.enable()
        arm.move_to([-math.pi / 2 + 0.3, 0.2], wait=False)
        time.sleep(0.1)
        sim.wait_received()
        _, since = sim.logged_frames()
        loop = arm.observe.loop
        crashed = threading.Event()

        def crash(now: float, slot: int) -> None:
            crashed.set()
            raise RuntimeError("a bug in a cycle")

        cycle, loop.cycle = loop.cycle, crash
        try:
            assert crashed.wait(5.0)
            assert wait_until(lambda: arm.mode is akarm.Mode.FAULT, 5.0), arm.mode
        finally:
            loop.cycle = cycle
        assert isinstance(arm.fault, akarm.LoopCrashed) and isinstance(arm.fault.__cause__, RuntimeError)
        assert not arm.enabled
        sim.wait_received()
        frames, _ = sim.logged_frames(since)
        model = config.joints[1].motor
        elbow = [f for f in frames if f.to_motor and f.joint == "elbow"]
        exits = [f.t for f in elbow if bytes(f.data) == mit.EXIT]
        commands = [(f.t, mit.decode_command(model, bytes(f.data))) for f in elbow
                    if mit.special_frame(bytes(f.data)) is None]
        damping = [t for t, c in commands if c.kp == 0.0 and c.kd > 0.0]  # (the exit's neutral command: kd 0)
        assert len(set(exits)) >= RELEASES, exits
        assert damping and max(damping) - min(damping) > 0.2, "damped for the stop's time before the exit"
        assert max(damping) < min(exits)
        assert not any(s.enabled for s in sim.driver_states())
        with pytest.raises(akarm.LoopCrashed):
            arm.enable()
