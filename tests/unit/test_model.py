"""RobotModel against closed-form two-link dynamics, payloads, gravity vectors, joint mapping."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from akarm import ModelError
from akarm.config import Payload, RobotConfig
from akarm.dynamics.model import RobotModel
from akarm.robotfile.load import load_robot

from .conftest import ROBOTS

# ----------------------------------------------------------------------------- planar2 closed form
#
# robots/planar2.urdf: both joints turn about (0, -1, 0), so with q1, q2 the link angles above the
# horizontal are θ1 = q1 and θ2 = q1 + q2 (x forward, z up). From the URDF:
#   upper arm: m1 = 0.432 kg, COM c1 = 0.2594 m along it, I1 = Iyy = 3.06e-3 kg·m² about the COM;
#   forearm:   m2 = 0.209 kg, COM c2 = 0.2148 m along it, I2 = Iyy = 9.69e-4 kg·m²; L1 = 0.30 m.
# (The inertia about the joint axis direction is Iyy, whatever the axis' sign.)
#
# COM positions relative to the shoulder:
#   p1 = c1 (cos θ1, sin θ1),  p2 = L1 (cos θ1, sin θ1) + c2 (cos θ2, sin θ2)
# Potential energy V = g (m1 c1 sin q1 + m2 (L1 sin q1 + c2 sin(q1 + q2))), so the holding torques
# g(q) = ∂V/∂q are
#   g1 = g ((m1 c1 + m2 L1) cos q1 + m2 c2 cos(q1 + q2)),   g2 = g m2 c2 cos(q1 + q2).
# Kinetic energy T = ½ v1² (I1 + m1 c1²) + ½ m2 |ṗ2|² + ½ I2 (v1 + v2)² gives the mass matrix
#   M11 = I1 + I2 + m1 c1² + m2 (L1² + c2² + 2 L1 c2 cos q2)
#   M12 = I2 + m2 (c2² + L1 c2 cos q2),   M22 = I2 + m2 c2²
# and, with h = m2 L1 c2 sin q2, the Coriolis/centrifugal torques
#   c1 = -h (2 v1 v2 + v2²),   c2 = h v1²
# so τ = M(q) a + c(q, v) + g(q).

M1, C1, I1 = 0.432, 0.2594, 3.06e-3
M2, C2, I2 = 0.209, 0.2148, 9.69e-4
L1, L2, Z0 = 0.30, 0.25, 0.15
G = 9.81


def g_closed(q: np.ndarray, g: float = G) -> np.ndarray:
    q1, q2 = q
    return np.array([g * ((M1 * C1 + M2 * L1) * math.cos(q1) + M2 * C2 * math.cos(q1 + q2)),
                     g * M2 * C2 * math.cos(q1 + q2)])


def m_closed(q: np.ndarray) -> np.ndarray:
    c2 = math.cos(q[1])
    m11 = I1 + I2 + M1 * C1**2 + M2 * (L1**2 + C2**2 + 2 * L1 * C2 * c2)
    m12 = I2 + M2 * (C2**2 + L1 * C2 * c2)
    m22 = I2 + M2 * C2**2
    return np.array([[m11, m12], [m12, m22]])


def tau_closed(q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    h = M2 * L1 * C2 * math.sin(q[1])
    coriolis = np.array([-h * (2 * v[0] * v[1] + v[1] ** 2), h * v[0] ** 2])
    return m_closed(q) @ a + coriolis + g_closed(q)


@pytest.fixture(scope="module")
def arm6() -> RobotConfig:
    return load_robot(ROBOTS / "arm6.yaml")


def grid(config: RobotConfig, n: int = 9) -> np.ndarray:
    lo = [j.limits.lower for j in config.joints]
    hi = [j.limits.upper for j in config.joints]
    axes = [np.linspace(a, b, n) for a, b in zip(lo, hi, strict=True)]
    return np.array(np.meshgrid(*axes)).reshape(len(axes), -1).T


def test_planar2_gravity_matches_the_two_link_formula(planar2: RobotConfig) -> None:
    model = RobotModel(planar2)
    assert model.joint_names == ("shoulder", "elbow")
    for q in grid(planar2, 21):
        np.testing.assert_allclose(model.gravity(q), g_closed(q), rtol=0, atol=1e-9)
    # arm straight out: the shoulder holds everything, by hand
    assert model.gravity([0, 0])[0] == pytest.approx(G * (M1 * C1 + M2 * (L1 + C2)), abs=1e-12)
    # hanging straight down: nothing to hold
    np.testing.assert_allclose(model.gravity([-math.pi / 2, 0]), [0, 0], atol=1e-12)


def test_planar2_inverse_dynamics_and_mass_matrix_match_the_closed_form(planar2: RobotConfig) -> None:
    model = RobotModel(planar2)
    rng = np.random.default_rng(1)
    for _ in range(200):
        q = rng.uniform([-1.8, -2.4], [1.8, 2.4])
        v = rng.uniform(-4, 4, 2)
        a = rng.uniform(-20, 20, 2)
        np.testing.assert_allclose(model.inverse_dynamics(q, v, a), tau_closed(q, v, a), rtol=0, atol=1e-9)
        np.testing.assert_allclose(model.mass_matrix(q), m_closed(q), rtol=0, atol=1e-12)
        # ABA inverts RNEA
        tau = model.inverse_dynamics(q, v, a)
        np.testing.assert_allclose(model.forward_dynamics(q, v, tau), a, rtol=0, atol=1e-8)
        np.testing.assert_allclose(model.nonlinear_effects(q, v), tau_closed(q, v, np.zeros(2)), atol=1e-9)


def test_planar2_tool_pose_is_the_two_link_forward_kinematics(planar2: RobotConfig) -> None:
    model = RobotModel(planar2)
    assert model.tool_frame == "tool0"
    for q1, q2 in [(0.0, 0.0), (0.7, -1.1), (-1.5, 2.0)]:
        pose = model.tool_pose([q1, q2])
        assert pose.shape == (4, 4)
        x = L1 * math.cos(q1) + L2 * math.cos(q1 + q2)
        z = Z0 + L1 * math.sin(q1) + L2 * math.sin(q1 + q2)
        np.testing.assert_allclose(pose[:3, 3], [x, 0, z], atol=1e-12)
        # the tool's x axis points along the forearm
        np.testing.assert_allclose(pose[:3, 0], [math.cos(q1 + q2), 0, math.sin(q1 + q2)], atol=1e-12)
    jac = model.jacobian([0.3, 0.4])
    assert jac.shape == (6, 2)
    # moving the shoulder at q1 = q2 = 0 lifts the tip at (L1 + L2) m/rad
    np.testing.assert_allclose(model.jacobian([0, 0])[:3, 0], [0, 0, L1 + L2], atol=1e-12)


def test_planar2_payload_adds_m_g_r_and_clearing_restores_exactly(planar2: RobotConfig) -> None:
    model = RobotModel(planar2)
    rng = np.random.default_rng(2)
    qs = [rng.uniform([-1.8, -2.4], [1.8, 2.4]) for _ in range(50)]
    before = [model.gravity(q) for q in qs]
    v, a = np.array([0.5, -1.0]), np.array([2.0, 3.0])
    id_before = model.inverse_dynamics(qs[0], v, a)
    mass, com = 0.8, (0.05, 0.0, 0.02)  # in the tool frame: 5 cm further out, 2 cm "above" the forearm
    model.set_payload(mass, com)
    for q, g0 in zip(qs, before, strict=True):
        t = q[0] + q[1]
        # payload COM relative to the shoulder (x horizontal): tool0 at L1 + L2 along the links,
        # then com x along the forearm and com z perpendicular to it (tool z = (-sin t, cos t))
        x_shoulder = L1 * math.cos(q[0]) + (L2 + com[0]) * math.cos(t) - com[2] * math.sin(t)
        x_elbow = (L2 + com[0]) * math.cos(t) - com[2] * math.sin(t)
        np.testing.assert_allclose(model.gravity(q) - g0, [mass * G * x_shoulder, mass * G * x_elbow],
                                   rtol=0, atol=1e-9)
    model.clear_payload()
    for q, g0 in zip(qs, before, strict=True):
        assert np.array_equal(model.gravity(q), g0)
    assert np.array_equal(model.inverse_dynamics(qs[0], v, a), id_before)
    # replacing, not adding: two set_payload calls leave only the second
    model.set_payload(5.0)
    model.set_payload(mass, com)
    model.set_payload(mass, com)
    t = qs[0][0] + qs[0][1]
    x = L1 * math.cos(qs[0][0]) + (L2 + com[0]) * math.cos(t) - com[2] * math.sin(t)
    assert model.gravity(qs[0])[0] - before[0][0] == pytest.approx(mass * G * x, abs=1e-9)
    model.set_payload(0.0)
    assert np.array_equal(model.gravity(qs[0]), before[0]) and model.payload is None


def test_arm6_payload_at_full_reach_adds_m_g_r(arm6: RobotConfig) -> None:
    model = RobotModel(arm6)
    q = [0.0, math.pi / 2, 0.0, 0.0, 0.0, 0.0]  # arm horizontal along +x
    g0 = model.gravity(q)
    mass = 1.0
    model.set_payload(mass, (0.0, 0.0, 0.04))  # 4 cm beyond tool0, along the tool's z (now +x)
    dg = model.gravity(q) - g0
    # distances from each pitch axis to the payload, from arm6.urdf's lengths:
    # tool0 is 0.42 + 0.08 + 0.36 + 0.07 + 0.06 = 0.99 m from shoulder_lift.
    r_lift, r_elbow, r_wrist = 0.99 + 0.04, 0.99 - 0.42 + 0.04, 0.07 + 0.06 + 0.04
    # the pitch axes are +y: leaning forward is positive, so the holding torque is -m g r
    np.testing.assert_allclose(dg, [0, -mass * G * r_lift, -mass * G * r_elbow, 0, -mass * G * r_wrist, 0],
                               rtol=0, atol=1e-9)
    np.testing.assert_allclose(model.tool_pose(q)[:3, 3], [0.99, 0, 0.12 + 0.10], atol=1e-12)
    model.clear_payload()
    assert np.array_equal(model.gravity(q), g0)


def test_arm6_payload_matches_virtual_work_anywhere(arm6: RobotConfig) -> None:
    model = RobotModel(arm6)
    rng = np.random.default_rng(3)
    mass = 0.7
    for q in rng.uniform(model.lower, model.upper, size=(20, 6)):
        g0 = model.gravity(q)
        model.set_payload(mass, (0.0, 0.0, 0.0))
        dg = model.gravity(q) - g0
        model.clear_payload()
        # a point mass at tool0: Δτ = -J_vᵀ m g_vec (virtual work)
        jv = model.jacobian(q)[:3]
        np.testing.assert_allclose(dg, -jv.T @ (mass * np.array([0, 0, -G])), atol=1e-9)


def test_payload_from_the_config_is_applied_at_construction(planar2: RobotConfig) -> None:
    with_payload = RobotModel(replace(planar2, payload=Payload(0.5, (0.0, 0.0, 0.0))))
    manual = RobotModel(planar2)
    manual.set_payload(0.5)
    q = [0.3, -0.4]
    np.testing.assert_array_equal(with_payload.gravity(q), manual.gravity(q))
    assert with_payload.gravity([0, 0])[0] - RobotModel(planar2).gravity([0, 0])[0] == pytest.approx(
        0.5 * G * (L1 + L2), abs=1e-9)


def test_wall_and_ceiling_mounts(planar2: RobotConfig) -> None:
    rng = np.random.default_rng(4)
    qs = rng.uniform([-1.8, -2.4], [1.8, 2.4], size=(30, 2))
    # wall mount: gravity along -x of the URDF base. V = g Σ m x, x = c cos θ, so g(q) is the
    # formula with sin for cos and the opposite sign.
    wall = RobotModel(replace(planar2, gravity=(-G, 0.0, 0.0)))
    for q in qs:
        q1, q2 = q
        expect = [-G * ((M1 * C1 + M2 * L1) * math.sin(q1) + M2 * C2 * math.sin(q1 + q2)),
                  -G * M2 * C2 * math.sin(q1 + q2)]
        np.testing.assert_allclose(wall.gravity(q), expect, atol=1e-9)
    # ceiling mount: the opposite of the floor's torques; gravity along the joint axes: none
    ceiling = RobotModel(replace(planar2, gravity=(0.0, 0.0, G)))
    along_axis = RobotModel(planar2)
    along_axis.set_gravity((0.0, G, 0.0))
    np.testing.assert_allclose(along_axis.gravity_vector, [0, G, 0])
    for q in qs:
        np.testing.assert_allclose(ceiling.gravity(q), -g_closed(q), atol=1e-9)
        np.testing.assert_allclose(along_axis.gravity(q), [0, 0], atol=1e-12)
    # set_gravity at run time
    m = RobotModel(planar2)
    m.set_gravity((0, 0, -1.62))  # the Moon
    np.testing.assert_allclose(m.gravity(qs[0]), g_closed(qs[0], 1.62), atol=1e-9)
    with pytest.raises(ModelError):
        m.set_gravity((0, 0))


def test_armature_adds_reflected_rotor_inertia_to_the_diagonal(planar2: RobotConfig) -> None:
    plain, geared = RobotModel(planar2), RobotModel(planar2, armature=True)
    refl = [j.motor.reflected_inertia for j in planar2.joints]
    assert refl[0] == pytest.approx(6.1e-5 * 81) and refl[1] == pytest.approx(2.4e-5 * 36)
    np.testing.assert_allclose(geared.armature, refl)
    q = [0.4, -0.9]
    np.testing.assert_allclose(geared.mass_matrix(q) - plain.mass_matrix(q), np.diag(refl), atol=1e-15)
    np.testing.assert_allclose(geared.gravity(q), plain.gravity(q), atol=1e-15)
    a = np.array([1.0, 2.0])
    np.testing.assert_allclose(geared.inverse_dynamics(q, [0, 0], a) - plain.inverse_dynamics(q, [0, 0], a),
                               np.array(refl) * a, atol=1e-12)


def test_arm6_forward_dynamics_inverts_inverse_dynamics(arm6: RobotConfig) -> None:
    model = RobotModel(arm6, armature=True)
    rng = np.random.default_rng(5)
    for _ in range(20):
        q = rng.uniform(model.lower, model.upper)
        v, a = rng.uniform(-2, 2, 6), rng.uniform(-10, 10, 6)
        tau = model.inverse_dynamics(q, v, a)
        np.testing.assert_allclose(model.forward_dynamics(q, v, tau), a, atol=1e-8)
        mm = model.mass_matrix(q)
        np.testing.assert_array_equal(mm, mm.T)
        np.testing.assert_allclose(mm @ a, tau - model.nonlinear_effects(q, v), atol=1e-9)


def test_momentum_is_the_mass_matrix_times_v_and_beta_is_gravity_less_coriolis_transposed(arm6: RobotConfig,
                                                                                          tmp_path: Path) -> None:
    rng = np.random.default_rng(8)
    # arm6 with its rotors (armature) in Pinocchio's order, and a chain whose config order is not Pinocchio's
    for model in (RobotModel(arm6, armature=True), RobotModel(chain(tmp_path, "revolute"))):
        n = len(model.lower)
        for _ in range(10):
            q = rng.uniform(-1.5, 1.5, n)
            v = rng.uniform(-2, 2, n)
            p, beta = model.momentum(q, v)
            assert isinstance(p, list) and isinstance(beta, list) and len(p) == len(beta) == n
            np.testing.assert_allclose(p, model.mass_matrix(q) @ v, rtol=0, atol=1e-12)
            np.testing.assert_allclose(beta, model.gravity(q) - model.coriolis_matrix(q, v).T @ v, rtol=0, atol=1e-12)
            assert np.abs(p).max() > 1e-3  # (not trivially zero)


def test_inputs_accept_sequences_and_return_float_arrays(planar2: RobotConfig) -> None:
    model = RobotModel(planar2)
    for q in ([0.1, 0.2], (0.1, 0.2), np.array([0.1, 0.2], dtype=np.float32), np.array([0, 1])):
        g = model.gravity(q)
        assert isinstance(g, np.ndarray) and g.dtype == np.float64 and g.shape == (2,)
    g = model.gravity([0.0, 0.0])
    g[:] = 99  # a copy: does not corrupt the next call
    assert model.gravity([0.0, 0.0])[0] != 99
    with pytest.raises(ModelError, match="expected \\(2,\\)"):
        model.gravity([0.0, 0.0, 0.0])
    with pytest.raises(ModelError, match="payload mass"):
        model.set_payload(-1.0)


def test_unknown_tool_frame_and_joint_are_model_errors(planar2: RobotConfig) -> None:
    with pytest.raises(ModelError, match="tool frame 'flange'"):
        RobotModel(replace(planar2, tool_frame="flange"))
    renamed = replace(planar2.joints[1], name="wrist")
    with pytest.raises(ModelError, match="'wrist'"):
        RobotModel(replace(planar2, joints=(planar2.joints[0], renamed)))
    with pytest.raises(ModelError, match="Pinocchio cannot load"):
        RobotModel(replace(planar2, urdf=Path("/nonexistent/robot.urdf")))
    # no tool_frame: the last link
    assert RobotModel(replace(planar2, tool_frame=None)).tool_frame == "tool0"


# ----------------------------------------------------------------------------- continuous joints

CHAIN = """<?xml version="1.0"?>
<robot name="chain">
  <link name="base"/>
  <joint name="a" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="10" velocity="5"/></joint>
  <link name="l1"><inertial><origin xyz="0 0 0.1"/><mass value="0.5"/>
    <inertia ixx="1e-3" iyy="1e-3" izz="2e-4" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="b" type="{b_type}"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.2"/><axis xyz="0 1 0"/>
    <limit lower="-10" upper="10" effort="10" velocity="5"/></joint>
  <link name="l2"><inertial><origin xyz="0.05 0 0.1"/><mass value="0.4"/>
    <inertia ixx="8e-4" iyy="9e-4" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="c" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0 0 0.2"/><axis xyz="1 0 0"/>
    <limit lower="-2" upper="2" effort="10" velocity="5"/></joint>
  <link name="l3"><inertial><origin xyz="0 0.02 0.05"/><mass value="0.3"/>
    <inertia ixx="3e-4" iyy="3e-4" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial></link>
</robot>
"""

CHAIN_YAML = """name: chain
urdf: {urdf}
defaults:
  gains: {{kp: 10, kd: 0.5}}
  limits: {{velocity: 2, acceleration: 10, jerk: 100}}
joints:          # config order c, b, a: the reverse of the URDF's
  - {{name: c, can_id: 3, motor: AK60-6}}
  - {{name: b, can_id: 2, motor: AK60-6, limits: {{lower: -6, upper: 6}}}}
  - {{name: a, can_id: 1, motor: AK60-6}}
"""


def chain(tmp_path: Path, b_type: str) -> RobotConfig:
    (tmp_path / f"{b_type}.urdf").write_text(CHAIN.format(b_type=b_type))
    (tmp_path / f"{b_type}.yaml").write_text(CHAIN_YAML.format(urdf=f"{b_type}.urdf"))
    return load_robot(tmp_path / f"{b_type}.yaml")


def test_continuous_joint_maps_through_cos_sin(tmp_path: Path) -> None:
    cont = RobotModel(chain(tmp_path, "continuous"))
    rev = RobotModel(chain(tmp_path, "revolute"))
    pm = cont.pin_model
    assert (pm.nq, pm.nv) == (4, 3)
    b = pm.joints[pm.getJointId("b")]
    assert b.nq == 2
    q = np.array([0.3, 2.5, -0.7])  # c, b, a
    qp = cont.to_pin_q(q)
    a_idx, c_idx = pm.joints[pm.getJointId("a")].idx_q, pm.joints[pm.getJointId("c")].idx_q
    assert qp[a_idx] == -0.7 and qp[c_idx] == 0.3
    assert qp[b.idx_q] == pytest.approx(math.cos(2.5)) and qp[b.idx_q + 1] == pytest.approx(math.sin(2.5))
    np.testing.assert_allclose(cont.from_pin_q(qp), q, atol=1e-15)
    # beyond ±π the continuous joint comes back wrapped
    np.testing.assert_allclose(cont.from_pin_q(cont.to_pin_q([0.3, 4.0, -0.7])), [0.3, 4.0 - 2 * math.pi, -0.7])
    # the same physics as the revolute version
    rng = np.random.default_rng(6)
    for _ in range(20):
        q = rng.uniform(-2, 2, 3) * [1, 3, 1]
        v, a = rng.uniform(-2, 2, 3), rng.uniform(-5, 5, 3)
        np.testing.assert_allclose(cont.gravity(q), rev.gravity(q), atol=1e-12)
        np.testing.assert_allclose(cont.inverse_dynamics(q, v, a), rev.inverse_dynamics(q, v, a), atol=1e-12)
        np.testing.assert_allclose(cont.mass_matrix(q), rev.mass_matrix(q), atol=1e-12)
        np.testing.assert_allclose(cont.forward_dynamics(q, v, a), rev.forward_dynamics(q, v, a), atol=1e-9)
        np.testing.assert_allclose(cont.tool_pose(q), rev.tool_pose(q), atol=1e-12)
    # velocity mapping follows Pinocchio's idx_v, config order c, b, a
    vp = cont.to_pin_v([1.0, 2.0, 3.0])
    assert vp[pm.joints[pm.getJointId("c")].idx_v] == 1.0 and vp[b.idx_v] == 2.0
    np.testing.assert_array_equal(cont.from_pin_v(vp), [1.0, 2.0, 3.0])
    # limits: the URDF's, and the YAML's for the continuous joint
    np.testing.assert_array_equal(cont.lower, [-2, -6, -2])
    np.testing.assert_array_equal(cont.upper, [2, 6, 2])


def test_reordered_joints_map_by_name(tmp_path: Path) -> None:
    model = RobotModel(chain(tmp_path, "revolute"))
    pm = model.pin_model
    # config order c, b, a is the reverse of the URDF's: a's angle lands in a's slot of Pinocchio's q
    q = np.array([0.1, -0.2, 0.5])
    g = model.gravity(q)
    qp = model.to_pin_q(q)
    assert qp[pm.joints[pm.getJointId("a")].idx_q] == 0.5
    import pinocchio as pin

    data = pm.createData()
    direct = pin.computeGeneralizedGravity(pm, data, qp)
    assert g[2] == direct[pm.joints[pm.getJointId("a")].idx_v]
    assert g[1] == direct[pm.joints[pm.getJointId("b")].idx_v]
    assert g[0] == direct[pm.joints[pm.getJointId("c")].idx_v]
    assert list(direct) != list(g)  # the orders really differ
