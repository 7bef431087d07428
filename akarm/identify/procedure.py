"""Identification on an arm: drives an :class:`~akarm.Arm` through its public API only, and fits
with :mod:`akarm.identify.fit`.

:func:`identify`: the arm follows the excitation (:func:`akarm.identify.fit.excitation`) around where
it holds, its gains alternating between full and :data:`GAIN_LOW` of them every :data:`GAIN_BLOCK` s
(how the fit tells friction from the bias of the torque samples), with a rough payload estimate at rest
carried first; the telemetry is fitted, the thresholds suggested, and (``apply``) the arm told
(:func:`apply_identification`: payload and friction).

:func:`estimate_payload`: the arm visits a few poses (:func:`akarm.identify.fit.payload_poses`),
holds still in each, and the torques held are fitted for mass and centre of mass.

The collision reflex only watches while either runs (an unknown payload is an external torque); its
thresholds are restored at the end::

    import akarm.identify
    with arm:
        arm.enable()
        result = akarm.identify.identify(arm, duration=30.0)
        print(result.table())
        result.save("robots/arm6.yaml")   # or print(result.fragment())
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from akarm.control.collision import velocity_resolution
from akarm.control.modes import Mode
from akarm.dynamics.model import RobotModel
from akarm.errors import ArgumentError, LimitError, StateError, finite_number
from akarm.identify.fit import (
    TORQUE_SHARE,
    Identification,
    PayloadFit,
    Run,
    estimate_payload_at_rest,
    excitation,
    fit,
    fit_runs,
    payload_poses,
    suggest_thresholds,
    torque_speed,
)
from akarm.motion.recording import PathRecording
from akarm.telemetry.log import TelemetryLog

if TYPE_CHECKING:
    from akarm.arm import Arm, Motion, Target

__all__ = ["GAIN_BLOCK", "GAIN_LOW", "Weight", "apply_identification", "estimate_payload", "identify", "identify_unit"]

#: s: identify() changes the gains this often, between full and GAIN_LOW of them (see akarm.identify.fit.fit)
GAIN_BLOCK = 3.0
GAIN_LOW = 0.5


def _require_holding(arm: Arm, what: str) -> None:
    """Raise unless the arm is enabled and holding still: its safety stop, or a StateError."""
    if arm.fault is not None:
        raise arm.fault
    if arm.mode is not Mode.ACTIVE:
        raise StateError(f"the arm is {arm.mode}, not enabled", fix="call arm.enable() first")
    if arm.moving:
        raise StateError(f"{what} starts from rest and the arm is moving", fix="wait for the motion to end")


def _excitation(arm: Arm, speed: float | None, center: Target | None, amplitude: float,
                duration: float) -> PathRecording:
    """(Either identification) The speed argument checked, the arm holding, the excitation about ``center``
    (default: where the arm is)."""
    if speed is not None and not (isinstance(speed, int | float) and 0 < speed <= 1):
        raise ArgumentError(f"speed {speed} must be in (0, 1]", fix="e.g. 0.5: half as fast")
    _require_holding(arm, "identification")
    c = arm.state().q_des if center is None else arm.target_positions(center)
    return excitation(arm.limits, c, amplitude=amplitude, duration=duration, rate_hz=arm.config.rate_hz)


def _excitation_speed(arm: Arm, rec: PathRecording, model: RobotModel, speed: float | None, duration: float,
                      share: float, needs: str, why: str, smaller: str) -> float:
    """(Either identification) The speed ``rec`` runs at: the fastest that keeps ``model``'s torque within
    ``share`` of the joints' limits, or ``speed`` checked against it; the telemetry long enough, and the
    replay checked against every limit before anything moves. ``needs``, ``why``, ``smaller``: the
    refusal's words (what needs the torque, why the share, what else to make smaller)."""
    fastest, worst, peak = torque_speed(model, rec, [j.limits.torque for j in arm.config.joints], share)
    if speed is None:
        speed = math.floor(fastest * 100) / 100
    elif speed > fastest + 1e-9:
        raise LimitError(f"at speed {speed:g} {needs} {peak * speed**2:.1f} N·m, over {share:.0%} of the joint's "
                         f"torque limit{why}", joint=arm.names[worst],
                         fix=f"use speed {math.floor(fastest * 100) / 100:g} or less, or {smaller}")
    needed = duration / speed + 5.0
    if needed > arm.telemetry_seconds:
        raise StateError(f"the telemetry keeps {arm.telemetry_seconds:.0f} s, the identification needs "
                         f"{needed:.0f} s", fix="Arm(..., telemetry_seconds=...) longer")
    arm.check_replay(rec, speed)  # before anything moves
    return speed


def identify(arm: Arm, duration: float = 30.0, speed: float | None = None, *, amplitude: float = 0.5,
             center: Target | None = None, payload: bool = True, offsets: bool = True,
             apply: bool = True, torque_scale: bool = False) -> Identification:
    """Identify each joint's friction (and torque offset) and the payload (see the module's docstring).

    The arm follows a slow multi-sine excitation around ``center`` (default: where it is),
    ``amplitude`` rad per joint at most (less near a limit, or where a large one would take the start and
    end ramps past 80 % of the joint's limits), for ``duration`` s at ``speed``
    (time scaling, (0, 1]; default: as fast as the joint limits and half the torque limits
    allow); like any replay, it is checked against every limit before anything moves; its
    gains alternate between full and half every 3 s (how the fit tells friction from the bias
    of the torque samples). ``torque_scale``: fit also each joint's torque scale (N·m the joint gets per
    N·m reported: a real unit's) and Coulomb friction's load share; do it with nothing at the tool and
    ``payload=False`` (the excitation cannot tell a payload's weight from a stronger or weaker motor:
    a 0.5 kg payload came out 0.37 kg with both fitted), then identify the payload with the scale known.
    With ``apply`` the arm uses the results at once (payload, friction). The result
    suggests collision thresholds; ``.fragment()`` is YAML for the robot file, ``.save(path)``
    writes it in, with a backup.

    Raises:
        ArgumentError: a speed outside (0, 1], an amplitude or duration out of range, an unknown target.
        LimitError: the excitation breaks a limit at this speed (names the joint, a speed that passes).
        StateError: the arm is not enabled, or moving, or its telemetry is too short for the duration.
    """
    rec = _excitation(arm, speed, center, amplitude, duration)
    model = RobotModel(arm.config, armature=True)
    if not payload and arm.payload is not None:  # the known payload is part of the model
        model.set_payload(*arm.payload)
    else:
        model.clear_payload()
    speed = _excitation_speed(arm, rec, model, speed, duration, TORQUE_SHARE, "the excitation needs",
                              " (the rest is for a payload not yet known)", "a smaller amplitude")
    mit = np.array([j.mode == "mit" for j in arm.config.joints])
    kp0, kd0 = arm.gains
    switches = [(-math.inf, 1.0)]
    before = arm.payload  # the rough estimate below replaces it: restored unless the result is applied
    applied = False
    try:
        motion = _excite(arm, rec, speed, payload, kp0, kd0, switches)
        result = _evaluate(arm, model, rec, motion, switches, mit, kp0, kd0, payload, offsets, speed, torque_scale)
        if apply:
            apply_identification(arm, result)
            applied = True
    finally:
        if payload and not applied:
            _restore_payload(arm, before)
    return result


#: identify_unit's excitation with the weight stays within this share of each joint's torque limit (the
#: weight is known, unlike identify's payload; the rest is for the feedback and a unit's weaker motor)
WEIGHT_SHARE = 0.65

#: A known weight for :func:`identify_unit`: kg, and its centre of mass in the tool frame (m).
Weight = tuple[float, Sequence[float]]


def identify_unit(arm: Arm, weight: Weight, hang: Callable[[bool], object], duration: float = 20.0,
                  speed: float | None = None, *, amplitude: float = 0.5, center: Target | None = None,
                  reach: Target | None = None, offsets: bool = True, apply: bool = True) -> Identification:
    """Identify a real unit: each joint's torque scale (N·m it gets per N·m its motor reports), friction
    (Coulomb with its load share, viscous, offset), with a known weight: the way real identification
    tells a motor that gives 20 % more torque from a link that is 20 % lighter.

    The arm, with nothing at the tool, follows the excitation (as :func:`identify`); then ``hang(True)``
    is called and must return once the known ``weight`` (kg, centre of mass in the tool frame, m: hang
    it off the tool's axis, e.g. 4 cm aside, so the roll joints feel it too) is at the tool; the arm,
    told about it, follows the same excitation again; ``hang(False)``: take it off. The fit
    (:func:`akarm.identify.fit.fit_runs`) takes both runs at once, with every link's inertial
    parameters free: the weight's torque, known in N·m, is what fixes each joint's scale. The thresholds
    are suggested from the run without the weight. With ``apply`` the arm uses the friction and scales.

    A joint the weight loads only through its inertia (a vertical axis: arm6's shoulder_pan) turns mostly
    against its friction in that excitation, and friction that grows with the motor's torque then looks
    just like a weaker motor (seed 0's pan came out 5.5 % weak: 0.903 - its load share 0.046). So each
    run is followed by ``INERTIAL_SECONDS`` (10) s of such joints alone, at their own full acceleration
    (80 % of the limit), the others held at ``reach`` (default: ``center``; as far out as their torque
    allows: the arm's inertia about the axis, and the weight's, is the signal): braking, the torque
    opposes the motion, and that tells the load share from the scale. Their fit takes these runs too.

    Raises:
        ArgumentError: a weight that is not a mass > 0 and three numbers, and as :func:`identify`.
        LimitError, StateError: as :func:`identify` (the speed is chosen, or checked, with the weight).
    """
    mass = finite_number(weight[0], "the weight's mass", above=0.0, unit="kg", fix="e.g. (1.0, (0.04, 0, 0.05))")
    com = np.asarray(weight[1], dtype=float)
    if com.shape != (3,) or not np.all(np.isfinite(com)):
        raise ArgumentError(f"the weight's centre of mass must be 3 numbers (m, tool frame), got {weight[1]!r}",
                            fix="e.g. (0.04, 0, 0.05)")
    rec = _excitation(arm, speed, center, amplitude, duration)
    model = RobotModel(arm.config, armature=True)
    model.set_payload(mass, com)  # the speed is for the heavier run (the weight is known: a larger share)
    speed = _excitation_speed(arm, rec, model, speed, duration, WEIGHT_SHARE, "the excitation with the weight needs",
                              "", "a lighter weight")
    alone = _inertial_only(model, rec)
    excitations: list[tuple[PathRecording, float, tuple[int, ...] | None]] = [(rec, speed, None)]
    if alone:
        held = _excitation(arm, None, reach if reach is not None else center, amplitude, INERTIAL_SECONDS)
        keep = np.ones(arm.n, bool)
        keep[list(alone)] = False
        held.q[:, keep] = held.q[0, keep]  # (the others hold: at the centre, where the envelope starts)
        fast = _excitation_speed(arm, held, model, None, INERTIAL_SECONDS, WEIGHT_SHARE,
                                 "the inertial excitation with the weight needs", "", "a lighter weight")
        excitations.append((held, fast, alone))
    model.clear_payload()
    mit = np.array([j.mode == "mit" for j in arm.config.joints])
    kp0, kd0 = arm.gains
    before = arm.payload
    runs: list[Run] = []
    judged = np.ones(0, bool)  # the first run's rows at full gains, the observer settled: the thresholds' data
    try:
        with _reflex_watching(arm):
            for load in (None, (mass, (float(com[0]), float(com[1]), float(com[2])))):
                if load is None:
                    arm.clear_payload()
                else:
                    hang(True)
                    arm.set_payload(*load)
                    arm.sleep(0.5)  # the hold takes the weight before the excitation starts
                for path, pace, joints in excitations:
                    switches = [(-math.inf, 1.0)]
                    motion = _excite(arm, path, pace, False, kp0, kd0, switches)
                    log, factor, use, settled = _samples(arm, motion, switches)
                    kp = np.where(mit, kp0, 0.0)[None, :] * factor[:, None]
                    kd = np.where(mit, kd0, 0.0)[None, :] * factor[:, None]
                    runs.append(Run(log, kp, kd, use, load, joints))
                    if load is None and joints is None:
                        judged = settled & (factor == 1.0)
        hang(False)
    finally:
        _restore_payload(arm, before)
    fits = fit_runs(model, runs, offsets=offsets)
    gain = arm.collision_gain
    deadband = [velocity_resolution(j) for j in arm.config.joints]
    # (the model as the first run had it: nothing at the tool)
    thresholds = suggest_thresholds(model, runs[0].log, fits, deadband, gain,
                                    [j.limits.torque for j in arm.config.joints], runs[0].kp, runs[0].kd, judged)
    room = np.ptp(rec.q, axis=0) / 2
    fits = [replace(f, threshold=th, amplitude=float(a)) for f, th, a in zip(fits, thresholds, room, strict=True)]
    notes = tuple(f"{f.name}: moved only ±{f.amplitude:.2f} rad (near its limits): its values are less sure"
                  for f in fits if f.amplitude < 0.1)
    notes += tuple(f"{f.name}: the weight hardly loads it: its torque scale is not determined (1 kept)"
                   for f in fits if f.torque_scale == 1.0)
    result = Identification(tuple(fits), None, sum(len(r.log) for r in runs),
                            float(sum(r.log.t[-1] - r.log.t[0] for r in runs)), offsets, notes, speed)
    if apply:
        apply_identification(arm, result)
    return result


#: s of excitation, per run, of the joints the weight loads only through inertia, alone (identify_unit)
INERTIAL_SECONDS = 10.0


def _inertial_only(model: RobotModel, rec: PathRecording) -> tuple[int, ...]:
    """The joints whose torque the weight (``model``'s payload) never changes through gravity along
    ``rec`` (a vertical axis): only its inertia tells their torque scale."""
    step = max(1, len(rec.t) // 50)
    loaded = np.array([model.gravity(q) for q in rec.q[::step]])
    weight = model.payload
    model.clear_payload()
    try:
        bare = np.array([model.gravity(q) for q in rec.q[::step]])
    finally:
        assert weight is not None
        model.set_payload(*weight)
    change = np.max(np.abs(loaded - bare), axis=0)
    return tuple(int(i) for i in np.nonzero(change < 1e-6 * max(float(np.max(change)), 1e-12))[0])


def _samples(arm: Arm, motion: Motion, switches: list[tuple[float, float]]
             ) -> tuple[TelemetryLog, np.ndarray, np.ndarray, np.ndarray]:
    """The excitation's telemetry, each row's gain factor (the command before it), the rows to fit (not
    just after a change of gains) and the rows where the observer has settled after one."""
    gain = arm.collision_gain
    excite = motion.plan.plans[-1]  # type: ignore[attr-defined]  # after the soft start
    log = arm.telemetry(since=excite.t0)
    period = 1.0 / arm.config.rate_hz
    factor = np.ones(len(log.t))
    use = np.ones(len(log.t), bool)
    settled = np.ones(len(log.t), bool)  # the observer's memory of a change of gains has faded (5 time constants)
    for ts, f in switches[1:]:
        factor[log.t - period >= ts - 1e-9] = f
        use &= np.abs(log.t - ts) > 0.03
        settled &= (log.t < ts) | (log.t > ts + 5.0 / gain)
    return log, factor, use, settled


def _restore_payload(arm: Arm, before: tuple[float, np.ndarray] | None) -> None:
    if before is None:
        arm.clear_payload()
    else:
        arm.set_payload(before[0], before[1].tolist())


def _excite(arm: Arm, rec: PathRecording, speed: float, payload: bool, kp0: np.ndarray, kd0: np.ndarray,
            switches: list[tuple[float, float]]) -> Motion:
    """Follow the excitation, full and reduced gains in turn (see fit()), noting each switch."""
    with _reflex_watching(arm) if payload else contextlib.nullcontext():
        if payload:  # carry the payload's weight during the excitation: a rough estimate at rest first
            estimate_payload(arm, settle=1.0, average=0.3, passes=1, apply=True)
        motion = arm.replay(rec, speed=speed, wait=False)
        try:
            while not motion.done:
                arm.sleep(min(GAIN_BLOCK, max(motion.plan.t_end - arm.clock.now(), 0.0) + 1e-3))
                if not motion.done:
                    f = GAIN_LOW if switches[-1][1] == 1.0 else 1.0
                    arm.set_gains(kp=(kp0 * f).tolist(), kd=(kd0 * f).tolist())
                    switches.append((arm.clock.now(), f))
            motion.wait()
        finally:
            arm.set_gains(kp=kp0.tolist(), kd=kd0.tolist())
    return motion


def _evaluate(arm: Arm, model: RobotModel, rec: PathRecording, motion: Motion, switches: list[tuple[float, float]],
              mit: np.ndarray, kp0: np.ndarray, kd0: np.ndarray, payload: bool, offsets: bool,
              speed: float, torque_scale: bool = False) -> Identification:
    """The fit, the thresholds and the result from the excitation's telemetry."""
    gain = arm.collision_gain
    log, factor, use, settled = _samples(arm, motion, switches)
    kp = np.where(mit, kp0, 0.0)[None, :] * factor[:, None]
    kd = np.where(mit, kd0, 0.0)[None, :] * factor[:, None]
    fits, pay, _ = fit(model, log, kp=kp, kd=kd, payload=payload, offsets=offsets, use=use,
                       torque_scale=torque_scale)
    if pay is not None:
        model.set_payload(pay.mass, pay.com)
    deadband = [velocity_resolution(j) for j in arm.config.joints]
    # the thresholds are for the arm at its own gains: judged on the full-gain stretches only
    thresholds = suggest_thresholds(model, log, fits, deadband, gain, [j.limits.torque for j in arm.config.joints],
                                    kp, kd, settled & (factor == 1.0))
    room = np.ptp(rec.q, axis=0) / 2
    fits = [replace(f, threshold=th, amplitude=float(a)) for f, th, a in zip(fits, thresholds, room, strict=True)]
    notes = tuple(f"{f.name}: moved only ±{f.amplitude:.2f} rad (near its limits): its values are less sure"
                  for f in fits if f.amplitude < 0.1)
    return Identification(tuple(fits), pay, len(log), float(log.t[-1] - log.t[0]) if len(log) else 0.0, offsets,
                          notes, speed)


def apply_identification(arm: Arm, result: Identification) -> None:
    """Tell the arm what was identified: the payload (feed-forward and collision observer) and the
    friction (the collision observer; the feed-forward, where friction is compensated, takes the
    Coulomb and viscous terms, not the offset)."""
    if result.payload is not None:
        arm.set_payload(result.payload.mass, result.payload.com)
    if result.joints:  # a fit's noise can leave a joint without friction a little below 0: none
        fr = [j.friction() for j in result.joints]
        arm.set_friction([f.coulomb for f in fr], [f.viscous for f in fr], [j.offset for j in result.joints],
                         torque_scale=[f.torque_scale for f in fr], load=[f.load for f in fr])


def estimate_payload(arm: Arm, poses: Sequence[Target] | None = None, *, speed: float = 0.5, settle: float = 3.0,
                     average: float = 0.5, passes: int = 2, apply: bool = True) -> PayloadFit:
    """Estimate the payload's mass and centre of mass (tool frame) from the torques held at rest.

    The arm moves (``speed`` as in :meth:`~akarm.Arm.move_to`) to each of ``poses`` (default: where
    it is, and each of the three joints nearest the tool turned by ±0.9 rad, the one before them
    ±0.45), waits until it is still (``settle`` s at most), averages the torques, and comes back;
    a least-squares fit of gravity's torque on Pinocchio's regressor gives mass and centre of
    mass (:func:`akarm.identify.fit.estimate_payload_at_rest`). With ``apply`` the arm then carries
    it (:meth:`~akarm.Arm.set_payload`).

    With an unknown load, the hold integral winds up to carry it, and the joints creep back against
    their friction while it does: torques measured then are off by up to the friction. So the
    estimate is made ``passes`` times, each with the last one carried by the feed-forward (the
    joints then hardly creep), and the last one is kept; in each pose the torques are averaged over
    ``average`` s once no joint has moved more than 1 mrad for that long, or after ``settle`` s. The
    collision reflex only watches meanwhile (an unknown load is an external torque); its thresholds
    are restored at the end.
    """
    _require_holding(arm, "the payload estimate")
    q0 = arm.state().q_des
    targets = payload_poses(arm.limits, q0) if poses is None else [arm.target_positions(p) for p in poses]
    model = RobotModel(arm.config, armature=True)
    model.clear_payload()
    offsets = [j.friction_model().offset for j in arm.config.joints]
    still = 1e-3  # rad the joints may move over ``average`` s and count as still: two steps of the position field
    before = arm.payload
    result = None
    with _reflex_watching(arm):
        try:
            for k in range(max(1, passes)):
                held_q, held_tau = [], []
                for q in targets:
                    arm.move_to(q, speed=speed)
                    log = _held(arm, settle, average, still)
                    held_q.append(np.mean(log.q, axis=0))
                    held_tau.append(np.mean(log.tau, axis=0))
                result = estimate_payload_at_rest(model, held_q, held_tau, offsets)
                if k + 1 < passes or apply:
                    arm.set_payload(result.mass, result.com)
            arm.move_to(q0, speed=speed)
        finally:
            if not apply:
                if before is None:
                    arm.clear_payload()
                else:
                    arm.set_payload(before[0], before[1].tolist())
    assert result is not None
    return result


def _held(arm: Arm, settle: float, average: float, still: float) -> TelemetryLog:
    """The last ``average`` s of telemetry once the arm has read still that long (or ``settle`` s passed)."""
    start = arm.clock.now()
    arm.sleep(average)
    while True:
        log = arm.telemetry(since=arm.clock.now() - average)
        if np.all(np.ptp(log.q, axis=0) <= still) or arm.clock.now() - start >= settle:
            return log
        arm.sleep(0.1)


@contextlib.contextmanager
def _reflex_watching(arm: Arm) -> Iterator[None]:
    """The collision reflex only watches inside (thresholds off); they are restored on the way out."""
    saved = arm.collision_thresholds
    arm.set_collision(thresholds=[None] * arm.n)
    try:
        yield
    finally:
        arm.set_collision(thresholds=list(saved.values()))
