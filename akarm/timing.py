"""Timing profiles: the loop rate, watchdog and simulator rate a machine can keep, as one named choice.

A control loop at 500 Hz with a 20 ms feedback watchdog and a 0.2 s stall limit, against a simulator
integrating at 2 kHz, is what a normal machine does (and what the hardware needs). A slow or shared machine (an emulated
virtual machine, a busy CI runner) cannot keep that: the simulator falls behind, replies come late
and the watchdog stops the arm. A profile names a set of numbers that such a machine can keep::

    arm = akarm.Arm(config, timing="slow")                   # the loop and the watchdog
    sim = SimulatedRobot(config, timing="slow")              # the simulator's integration rate
    akarm move robots/arm6.yaml ready -i socketcan -c vcan0 --profile slow

The profiles are data (:data:`PROFILES`): whatever scales with the loop rate or the watchdog reads
them from the :class:`TimingProfile` in force (``arm.timing``). ``normal`` is the default everywhere
and changes nothing. The numbers of ``slow`` come from measurement inside ``../shared/tools/vcan-vm``
(``benchmarks/bench_profiles.py``; see the README's Timing section).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from akarm.errors import ArgumentError

if TYPE_CHECKING:
    from akarm.config import JointConfig, RobotConfig

__all__ = ["PROFILES", "TimingProfile", "get_profile"]


@dataclass(frozen=True)
class TimingProfile:
    """The timing a machine can keep (times in s, rates in Hz).

    Attributes:
        name: the profile's name (``--profile NAME``).
        description: one line, for ``--help``.
        max_rate_hz: the control loop runs at the robot file's ``rate_hz``, but at most this
            (``None``: no cap).
        feedback_timeout: the watchdog's limit for joints that set none of their own (servo joints:
            at least three status periods).
        min_feedback_timeout: no joint's watchdog limit is shorter, its own setting included
            (0: a joint's own setting wins).
        enable_timeout: how long :meth:`~akarm.Arm.enable` waits for every joint's first answer.
        sim_rate_hz: the simulator's integration rate (``akarm sim --plant-rate``).
        lag: s a joint's reading may trail the commands on such a machine (a simulator that falls
            behind answers late, then several frames with one state): the supervisor's following-error
            and stuck-travel limits grow by the joint's velocity limit times this.
        stall_limit: s the control loop itself may fail to run (this process stopped or starved: load,
            a long garbage collection, SIGSTOP) and resume without a stop; longer stops the arm with
            :class:`~akarm.LoopStall` (see the README's Timing section for why 0.2 s).
        contact_rate_hz: an enable's contact (and the first cycle carrying the arm) runs at this rate,
            between the loop's own cycles, when it is above the loop's, for at most
            :data:`akarm.control.enabler.CONTACT_BURST` s (``None``: at the loop's). The drivers are
            limp until contact is made and the arm is carried: at 25 Hz that took three cycles, 120 ms,
            in which an arm carrying weight falls.
    """

    name: str
    description: str
    max_rate_hz: float | None
    feedback_timeout: float
    min_feedback_timeout: float
    enable_timeout: float
    sim_rate_hz: float
    lag: float = 0.0
    stall_limit: float = 0.2
    contact_rate_hz: float | None = None

    def loop_rate(self, rate_hz: float) -> float:
        """The loop rate for a robot file's ``rate_hz``, Hz."""
        return rate_hz if self.max_rate_hz is None else min(rate_hz, self.max_rate_hz)

    def apply(self, config: RobotConfig) -> RobotConfig:
        """``config`` as this profile runs it: the loop rate capped, and each joint's own
        ``feedback_timeout`` at least :attr:`min_feedback_timeout` (the same object when nothing changes)."""
        rate = self.loop_rate(config.rate_hz)
        joints = tuple(self._floored(j) for j in config.joints)
        if rate == config.rate_hz and all(a is b for a, b in zip(joints, config.joints, strict=True)):
            return config
        return replace(config, rate_hz=rate, joints=joints)

    def _floored(self, joint: JointConfig) -> JointConfig:
        own = joint.feedback_timeout
        if own is None or own >= self.min_feedback_timeout:
            return joint
        return replace(joint, feedback_timeout=self.min_feedback_timeout)


#: The named profiles. ``slow``: measured in vcan-vm (an emulated 2-CPU guest, about 15x slower than
#: our 2-core development machines, which other test runs kept busy), six MIT joints over vcan0
#: against ``akarm sim`` in another process (benchmarks/bench_profiles.py): a 2 kHz simulator needs a
#: whole CPU there and its replies come seconds late. At 250 Hz and a 50 Hz loop the simulator
#: needs 74-93 % of a CPU and falls behind when the host is busy (feedback up to 758 ms old, the
#: plant 2 s behind in 30 s); with a 25 Hz loop 44-54 %, feedback at most 177 ms old, the plant
#: 0.07 s behind at most. The watchdog of 1 s is more than five times the worst gap seen at 25 Hz;
#: a reading was seen to trail by up to 0.25 s then; in later runs (Nov 26, the guest alone on the host)
#: the controller and the simulator sharing the guest left readings up to 0.9 s behind the commands
#: while the simulator worked through its backlog, so a reading may trail by up to the watchdog's
#: 1 s: the tracking checks allow for that. (Those figures are from a simulator whose ticker woke at
#: every plant step; since it sleeps until something is due, Nov 26, the arm6 vcan test's frames waited
#: 0.06-0.14 s at most, where one run of it before saw 4-29 s.) Such a
#: machine also stalls the controller itself for longer: its loop may miss up to 1 s (the watchdog's
#: time) before a LoopStall, where a normal one gets 0.2 s.
PROFILES: dict[str, TimingProfile] = {
    "normal": TimingProfile("normal", "the robot file's rate_hz, 20 ms watchdog, 0.2 s stall limit, simulator at "
                                      "2 kHz (default)",
                            max_rate_hz=None, feedback_timeout=0.020, min_feedback_timeout=0.0, enable_timeout=0.5,
                            sim_rate_hz=2000.0, stall_limit=0.2),
    "slow": TimingProfile("slow", "slow or shared machines (virtual machines, CI): loop at most 25 Hz, 1 s "
                                  "watchdog and stall limit, simulator at 250 Hz",
                          max_rate_hz=25.0, feedback_timeout=1.0, min_feedback_timeout=1.0, enable_timeout=5.0,
                          sim_rate_hz=250.0, lag=1.0, stall_limit=1.0, contact_rate_hz=500.0),
}


def get_profile(profile: str | TimingProfile | None = None) -> TimingProfile:
    """The profile named ``profile`` (``None``: ``normal``); a :class:`TimingProfile` is returned as is.

    Raises:
        ArgumentError: no profile of that name (the message lists them).
    """
    if isinstance(profile, TimingProfile):
        return profile
    key = "normal" if profile is None else str(profile).strip().lower()
    try:
        return PROFILES[key]
    except KeyError:
        raise ArgumentError(f"no timing profile named {profile!r}",
                            fix="use one of: " + "; ".join(f"{p.name} ({p.description})"
                                                           for p in PROFILES.values())) from None
