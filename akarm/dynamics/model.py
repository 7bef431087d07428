"""The arm's rigid-body dynamics: URDF → Pinocchio, in config joint order.

:class:`RobotModel` wraps a Pinocchio model built from the config's URDF. Every joint vector going
in or out is in **config order** (``config.joint_names``), SI units (rad, rad/s, rad/s², N·m); the
mapping to Pinocchio's ``q``/``v`` (which follow the URDF tree, and give a continuous joint two
entries, cos and sin) lives in :meth:`RobotModel.to_pin_q`, :meth:`RobotModel.from_pin_q`,
:meth:`RobotModel.to_pin_v` and :meth:`RobotModel.from_pin_v` only.

URDF joints that the config does not drive (a gripper's fingers, a mimic joint, a joint the YAML
lists under ``locked:``) are locked with Pinocchio's ``buildReducedModel``: held at
``config.locked[name]`` (or their neutral position), so their links still count in the masses and
inertias of the joint that carries them, but have no degree of freedom of their own.

A ``RobotModel`` owns one ``pinocchio.Data``: use one instance per thread.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, TypeAlias

import numpy as np
import pinocchio as pin

from akarm.config import RobotConfig
from akarm.errors import ModelError

__all__ = ["RobotModel"]

# (declared an alias: where numpy's types are missing, as in the build that compiles the cycle, it
# is still a type)
ArrayLike: TypeAlias = np.ndarray | Sequence[float]


def _reduced_model(config: RobotConfig) -> tuple[pin.Model, dict[str, float]]:
    """The URDF's Pinocchio model with every joint the config does not drive locked, and the
    positions they are locked at (1-DOF joints only)."""
    try:
        full = pin.buildModelFromUrdf(str(config.urdf))
    except Exception as e:  # Pinocchio raises ValueError/RuntimeError
        raise ModelError(f"Pinocchio cannot load URDF {config.urdf}: {str(e).strip() or type(e).__name__}",
                         fix="check the path and the URDF (akarm check ROBOT.yaml)") from None
    driven = set(config.joint_names)
    q_ref = pin.neutral(full)
    lock: list[int] = []
    held: dict[str, float] = {}
    for jid in range(1, full.njoints):
        name = str(full.names[jid])
        if name in driven:
            continue
        lock.append(jid)
        joint = full.joints[jid]
        if joint.nv != 1:
            continue  # floating, planar: neutral
        x = float(config.locked.get(name, 0.0))
        if joint.nq == 1:
            q_ref[joint.idx_q] = x
        else:  # continuous: (cos, sin)
            q_ref[joint.idx_q:joint.idx_q + 2] = (np.cos(x), np.sin(x))
        held[name] = x
    if not lock:
        return full, held
    return pin.buildReducedModel(full, lock, q_ref), held


class RobotModel:
    """Dynamics and kinematics of a configured arm.

    Args:
        config: the robot (URDF, joint order, gravity, payload, tool frame).
        armature: add each motor's reflected rotor inertia (``rotor_inertia · gear_ratio²``, kg·m²)
            to its joint's diagonal of the mass matrix (Pinocchio's ``model.armature``).

    Attributes:
        config: the configuration this was built from.
        joint_names: joint names in config order.
        lower, upper: position limits, rad, config order: the URDF's (a continuous joint, which has
            none in the URDF, gets the YAML's).
        tool_frame: name of the frame :meth:`tool_pose` reports and the payload is attached to.
        locked: the URDF joints held still, and where (rad, or m for prismatic joints; floating and
            planar joints are held at their neutral configuration and not listed).
        pin_model, pin_data: the Pinocchio model (the URDF's, with the locked joints removed) and data.

    Raises:
        ModelError: the URDF cannot be loaded, or a config joint or the tool frame is not in it.
    """

    def __init__(self, config: RobotConfig, *, armature: bool = False) -> None:
        self.config = config
        self.joint_names: tuple[str, ...] = config.joint_names
        model, self.locked = _reduced_model(config)
        self.pin_model = model
        self.pin_data = model.createData()
        n = len(self.joint_names)
        self.n = n

        rev_cfg, rev_q, cont_cfg, cont_q, idx_v = [], [], [], [], []
        lower, upper = np.empty(n), np.empty(n)
        for i, jc in enumerate(config.joints):
            if not model.existJointName(jc.name):
                raise ModelError(f"joint {jc.name!r} is not a movable joint of URDF {config.urdf}",
                                 joint=jc.name, fix="use the URDF's joint names in the robot YAML")
            joint = model.joints[model.getJointId(jc.name)]
            if joint.nv != 1:
                raise ModelError(f"joint {jc.name!r} has {joint.nv} degrees of freedom; akarm drives 1-DOF joints",
                                 joint=jc.name, fix="make it revolute or continuous in the URDF")
            idx_v.append(joint.idx_v)
            if joint.nq == 1:
                rev_cfg.append(i)
                rev_q.append(joint.idx_q)
                lower[i] = model.lowerPositionLimit[joint.idx_q]
                upper[i] = model.upperPositionLimit[joint.idx_q]
            elif joint.nq == 2:  # continuous: (cos θ, sin θ)
                cont_cfg.append(i)
                cont_q.append(joint.idx_q)
                lower[i] = jc.limits.lower
                upper[i] = jc.limits.upper
            else:
                raise ModelError(f"joint {jc.name!r} has nq = {joint.nq}; akarm drives revolute and continuous joints",
                                 joint=jc.name, fix="make it revolute or continuous in the URDF")
        self.lower, self.upper = lower, upper
        self._rev_cfg = np.array(rev_cfg, dtype=np.intp)
        self._rev_q = np.array(rev_q, dtype=np.intp)
        self._cont_cfg = np.array(cont_cfg, dtype=np.intp)
        self._cont_cos = np.array(cont_q, dtype=np.intp)
        self._cont_sin = self._cont_cos + 1
        self._vi = np.array(idx_v, dtype=np.intp)
        self._q_neutral = pin.neutral(model)
        # Fast paths: config order is Pinocchio's order and there is nothing else in q/v.
        self._q_identity = (not cont_cfg and model.nq == n and rev_q == list(range(n)))
        self._v_identity = (model.nv == n and idx_v == list(range(n)))
        self._below_diagonal = np.tril_indices(model.nv, -1)  # crba fills the upper triangle: mirrored into these
        self._zero_v = np.zeros(model.nv)  # (read only) the zero velocity of the momentum's RNEA pass
        self._vi_list = [int(k) for k in self._vi]  # Pinocchio's v index of each joint, config order

        # tool frame
        if config.tool_frame is not None:
            if not model.existFrame(config.tool_frame):
                raise ModelError(f"tool frame {config.tool_frame!r} is not in URDF {config.urdf}",
                                 fix="set tool_frame to one of the URDF's link names")
            self._tool_id = model.getFrameId(config.tool_frame)
        else:
            bodies = [i for i, f in enumerate(model.frames) if f.type == pin.FrameType.BODY]
            if not bodies:
                raise ModelError(f"URDF {config.urdf} has no links", fix="check the URDF")
            self._tool_id = bodies[-1]
        self.tool_frame: str = model.frames[self._tool_id].name
        frame = model.frames[self._tool_id]
        self._payload_joint: int = int(frame.parentJoint)
        self._payload_placement: pin.SE3 = frame.placement.copy()
        self._inertias0 = [pin.Inertia(inertia) for inertia in model.inertias]  # copies, for clear_payload
        self.payload: tuple[float, np.ndarray] | None = None

        self._armature = armature
        if armature:
            arm = np.array(model.armature, dtype=float)
            for i, jc in enumerate(config.joints):
                arm[self._vi[i]] += jc.motor.reflected_inertia
            model.armature = arm

        self.set_gravity(config.gravity)
        if config.payload is not None and config.payload.mass > 0:
            self.set_payload(config.payload.mass, config.payload.com)

    # ------------------------------------------------------------------ joint-space mapping

    def _vec(self, x: ArrayLike, what: str) -> np.ndarray:
        a = np.asarray(x, dtype=float)
        if a.shape != (self.n,):
            raise ModelError(f"{what} has shape {a.shape}, expected ({self.n},) in the order "
                             + ", ".join(self.joint_names), fix="give one value per joint, in config order")
        return a

    @property
    def identity_mapping(self) -> bool:
        """Config order is Pinocchio's order, and its ``q`` and ``v`` hold nothing else (no continuous
        joints): a config-order vector may be handed to Pinocchio as it is."""
        return bool(self._q_identity and self._v_identity)

    def to_pin_q(self, q: ArrayLike) -> np.ndarray:
        """Config-order joint positions (rad) → Pinocchio configuration ``q`` (continuous: cos, sin)."""
        q = self._vec(q, "q")
        if self._q_identity:
            return q
        qp = self._q_neutral.copy()
        qp[self._rev_q] = q[self._rev_cfg]
        if self._cont_cfg.size:
            th = q[self._cont_cfg]
            qp[self._cont_cos] = np.cos(th)
            qp[self._cont_sin] = np.sin(th)
        return qp

    def from_pin_q(self, q_pin: ArrayLike) -> np.ndarray:
        """Pinocchio configuration → config-order joint positions, rad (continuous: atan2(sin, cos))."""
        qp = np.asarray(q_pin, dtype=float)
        if qp.shape != (self.pin_model.nq,):
            raise ModelError(f"Pinocchio q has shape {qp.shape}, expected ({self.pin_model.nq},)")
        q = np.empty(self.n)
        q[self._rev_cfg] = qp[self._rev_q]
        if self._cont_cfg.size:
            q[self._cont_cfg] = np.arctan2(qp[self._cont_sin], qp[self._cont_cos])
        return q

    def to_pin_v(self, v: ArrayLike) -> np.ndarray:
        """Config-order velocities (or accelerations, torques) → Pinocchio's ``v`` order."""
        v = self._vec(v, "v")
        if self._v_identity:
            return v
        vp = np.zeros(self.pin_model.nv)
        vp[self._vi] = v
        return vp

    def from_pin_v(self, v_pin: ArrayLike) -> np.ndarray:
        """Pinocchio ``v``-ordered vector (velocities, accelerations, torques) → config order (a copy)."""
        vp = np.asarray(v_pin, dtype=float)
        return vp.copy() if self._v_identity else vp[self._vi]

    # ------------------------------------------------------------------ dynamics

    def gravity(self, q: ArrayLike) -> np.ndarray:
        """Joint torques holding the arm still against gravity at ``q`` (rad): g(q), N·m."""
        g = pin.computeGeneralizedGravity(self.pin_model, self.pin_data, self.to_pin_q(q))
        return self.from_pin_v(g)

    def inverse_dynamics(self, q: ArrayLike, v: ArrayLike, a: ArrayLike) -> np.ndarray:
        """Joint torques (N·m) for positions q (rad), velocities v (rad/s), accelerations a (rad/s²): RNEA."""
        tau = pin.rnea(self.pin_model, self.pin_data, self.to_pin_q(q), self.to_pin_v(v), self._pv(a, "a"))
        return self.from_pin_v(tau)

    def nonlinear_effects(self, q: ArrayLike, v: ArrayLike) -> np.ndarray:
        """Coriolis, centrifugal and gravity torques C(q, v)·v + g(q), N·m."""
        nle = pin.nonLinearEffects(self.pin_model, self.pin_data, self.to_pin_q(q), self.to_pin_v(v))
        return self.from_pin_v(nle)

    def coriolis_matrix(self, q: ArrayLike, v: ArrayLike) -> np.ndarray:
        """Pinocchio's Coriolis matrix C(q, v) (n × n, config order): ``C·v`` is the Coriolis and
        centrifugal torque and ``Ṁ = C + Cᵀ`` (what the collision observer needs)."""
        c = pin.computeCoriolisMatrix(self.pin_model, self.pin_data, self.to_pin_q(q), self.to_pin_v(v))
        return c.copy() if self._v_identity else c[np.ix_(self._vi, self._vi)]

    def forward_dynamics(self, q: ArrayLike, v: ArrayLike, tau: ArrayLike) -> np.ndarray:
        """Joint accelerations (rad/s²) under joint torques tau (N·m) at q (rad), v (rad/s): ABA."""
        ddq = pin.aba(self.pin_model, self.pin_data, self.to_pin_q(q), self.to_pin_v(v), self._pv(tau, "tau"))
        return self.from_pin_v(ddq)

    def mass_matrix(self, q: ArrayLike) -> np.ndarray:
        """Joint-space inertia matrix M(q), kg·m² (n × n, symmetric, config order)."""
        return self._symmetric(pin.crba(self.pin_model, self.pin_data, self.to_pin_q(q)))

    def _symmetric(self, upper: np.ndarray) -> np.ndarray:
        """Pinocchio's upper-triangle mass matrix, mirrored, in config order (a new array). (Indexing
        the lower triangle: a tenth of ``np.triu``'s cost, which took 30 µs a cycle.)"""
        m = upper.copy()
        low = self._below_diagonal
        m[low] = m.T[low]
        return m if self._v_identity else m[np.ix_(self._vi, self._vi)]

    def momentum(self, q: ArrayLike, v: ArrayLike) -> tuple[list[float], list[float]]:
        """The momentum ``M(q)·v`` and ``g(q) - C(q, v)ᵀ·v`` (config order, as lists of floats): what
        the collision observer needs each cycle, with ``q`` and ``v`` converted once.

        The momentum is RNEA's torque at zero velocity with ``v`` as the acceleration, less gravity:
        the mass matrix itself (CRBA, mirrored, times ``v``) cost twice as much. (Pinocchio's
        ``computeAllTerms`` does not fill the Coriolis matrix: three passes.) The arithmetic after
        them is done on floats, not as numpy operations: dearer warm (11 against 7.5 µs for arm6), but
        the control loop's core sleeps between cycles and each numpy operation starts cold there
        (arm6 at 480 Hz, three pairs of runs: 36-59 µs a cycle with numpy arithmetic, 35-44 without)."""
        model, data = self.pin_model, self.pin_data
        qp, vp = self.to_pin_q(q), self.to_pin_v(v)
        c = pin.computeCoriolisMatrix(model, data, qp, vp).tolist()
        g = pin.computeGeneralizedGravity(model, data, qp).tolist()
        mv = pin.rnea(model, data, qp, self._zero_v, vp).tolist()
        vl = vp.tolist()
        ctv = [0.0] * len(vl)  # Cᵀ·v
        for row, x in zip(c, vl, strict=True):
            for k, ck in enumerate(row):
                ctv[k] += ck * x
        p = [a - b for a, b in zip(mv, g, strict=True)]
        beta = [a - b for a, b in zip(g, ctv, strict=True)]
        if self._v_identity:
            return p, beta
        return [p[k] for k in self._vi_list], [beta[k] for k in self._vi_list]

    def _pv(self, x: ArrayLike, what: str) -> np.ndarray:
        x = self._vec(x, what)
        if self._v_identity:
            return x
        out = np.zeros(self.pin_model.nv)
        out[self._vi] = x
        return out

    # ------------------------------------------------------------------ kinematics

    def _frame_id(self, frame: str | None) -> int:
        if frame is None:
            return self._tool_id
        if not self.pin_model.existFrame(frame):
            raise ModelError(f"frame {frame!r} is not in URDF {self.config.urdf}", fix="name a URDF link or joint")
        return int(self.pin_model.getFrameId(frame))

    def frame_pose(self, q: ArrayLike, frame: str | None = None) -> np.ndarray:
        """4×4 homogeneous transform of ``frame`` (default: the tool frame) in the base frame, metres."""
        fid = self._frame_id(frame)
        pin.forwardKinematics(self.pin_model, self.pin_data, self.to_pin_q(q))
        return pin.updateFramePlacement(self.pin_model, self.pin_data, fid).homogeneous.copy()

    def tool_pose(self, q: ArrayLike) -> np.ndarray:
        """4×4 homogeneous transform of the tool frame in the base frame at ``q`` (rad); translation in m."""
        return self.frame_pose(q)

    def jacobian(self, q: ArrayLike, frame: str | None = None) -> np.ndarray:
        """6 × n Jacobian of ``frame`` (default: tool frame): rows (vx, vy, vz, wx, wy, wz) in base axes."""
        fid = self._frame_id(frame)
        j = pin.computeFrameJacobian(self.pin_model, self.pin_data, self.to_pin_q(q), fid, pin.LOCAL_WORLD_ALIGNED)
        return j.copy() if self._v_identity else j[:, self._vi]

    # ------------------------------------------------------------------ payload and gravity

    def set_payload(self, mass: float, com: ArrayLike = (0.0, 0.0, 0.0), inertia: Any = None) -> None:
        """Attach a payload to the tool frame, replacing any earlier one.

        Args:
            mass: kg (0 removes the payload).
            com: its centre of mass in the tool frame, m.
            inertia: optional 3×3 rotational inertia about the COM, tool-frame axes, kg·m²
                (default: a point mass).

        The payload is added to the inertia of the tool frame's parent joint, at the frame's placement;
        the original inertias are kept, so :meth:`clear_payload` restores them exactly.
        """
        m = float(mass)
        c = np.asarray(com, dtype=float)
        if not np.isfinite(m) or m < 0:
            raise ModelError(f"payload mass must be a number ≥ 0 kg, got {mass!r}", fix="give the mass in kg")
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise ModelError(f"payload com must be 3 numbers (m, tool frame), got {com!r}", fix="e.g. (0, 0, 0.04)")
        i3 = np.zeros((3, 3)) if inertia is None else np.asarray(inertia, dtype=float)
        if i3.shape != (3, 3):
            raise ModelError(f"payload inertia must be 3×3, got shape {i3.shape}", fix="give a 3×3 matrix in kg·m²")
        jid = self._payload_joint
        if m == 0:
            self.clear_payload()
            return
        try:
            added = self._payload_placement.act(pin.Inertia(m, c, i3))
        except Exception as e:
            raise ModelError(f"payload inertia is not valid: {e}", fix="give a symmetric positive 3×3 matrix") from None
        self.pin_model.inertias[jid] = self._inertias0[jid] + added
        self.payload = (m, c.copy())

    @property
    def payload_placement(self) -> np.ndarray:
        """4×4 pose of the tool frame in the frame of the body the payload is attached to (the tool
        frame's parent joint): where :meth:`payload_regressor`'s parameters are expressed."""
        return self._payload_placement.homogeneous.copy()

    def payload_regressor(self, q: ArrayLike, v: ArrayLike, a: ArrayLike) -> np.ndarray:
        """n × 10: joint torques (config order) per unit of each inertial parameter of the body that
        carries the tool frame, ``(m, m·c, I)`` in that body's frame (Pinocchio's dynamic parameters:
        m, m·cx, m·cy, m·cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz about the body's origin). A payload adds to
        these parameters, so its torque is linear in them: identification by least squares."""
        Y = pin.computeJointTorqueRegressor(self.pin_model, self.pin_data, self.to_pin_q(q), self._pv(v, "v"),
                                            self._pv(a, "a"))
        jid = self._payload_joint
        block = Y[:, 10 * (jid - 1):10 * jid]
        return block.copy() if self._v_identity else block[self._vi]

    def link_regressor(self, q: ArrayLike, v: ArrayLike, a: ArrayLike) -> np.ndarray:
        """n × 10·b: joint torques (config order) per unit of each inertial parameter of every moving body
        (``b`` bodies, Pinocchio's order; per body ``(m, m·c, I)`` as :meth:`payload_regressor` has them):
        the torques are linear in all of them, so a fit can correct the URDF's masses and centres of mass
        (:func:`akarm.identify.fit.fit_runs`). Motor rotors (the armature) are not in it."""
        Y = pin.computeJointTorqueRegressor(self.pin_model, self.pin_data, self.to_pin_q(q), self._pv(v, "v"),
                                            self._pv(a, "a"))
        return Y.copy() if self._v_identity else Y[self._vi]

    def scale_links(self, factors: dict[str, tuple[float, float]]) -> None:
        """Make the bodies that joints move heavier or lighter (a real arm is not its URDF): per joint
        name, ``(mass factor, centre-of-mass factor)``: the body's mass and rotational inertia times
        the first, its centre of mass's offset from the joint times the second. For simulators
        (:class:`akarm.sim.Variation`); a payload set before is kept."""
        pm = self.pin_model
        for name, (fm, fc) in factors.items():
            if not (fm > 0 and fc > 0 and math.isfinite(fm) and math.isfinite(fc)):
                raise ModelError(f"link factors of joint {name!r} must be positive numbers, got {(fm, fc)!r}")
            jid = pm.getJointId(name)
            if jid >= pm.njoints:
                raise ModelError(f"no joint {name!r} in the URDF")
            base = self._inertias0[jid]
            self._inertias0[jid] = pin.Inertia(base.mass * fm, base.lever * fc, base.inertia * fm)
        if self.payload is not None:
            self.set_payload(*self.payload)
        else:
            for jid, inertia in enumerate(self._inertias0):
                pm.inertias[jid] = pin.Inertia(inertia)

    def clear_payload(self) -> None:
        """Remove the payload (the config's too): the tool's parent body gets back its URDF inertia, exactly."""
        jid = self._payload_joint
        self.pin_model.inertias[jid] = pin.Inertia(self._inertias0[jid])
        self.payload = None

    @property
    def gravity_vector(self) -> np.ndarray:
        """Gravity acceleration in the base frame, m/s² (a copy)."""
        return np.array(self.pin_model.gravity.linear)

    def set_gravity(self, g: ArrayLike) -> None:
        """Set the gravity vector (m/s², base frame), e.g. ``(0, 9.81, 0)`` for a wall mount."""
        v = np.asarray(g, dtype=float)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ModelError(f"gravity must be 3 numbers (m/s²), got {g!r}", fix="e.g. (0, 0, -9.81)")
        self.pin_model.gravity.linear = v

    @property
    def armature(self) -> np.ndarray:
        """Armature (reflected rotor inertia) per joint, kg·m², config order."""
        return self.from_pin_v(self.pin_model.armature)
