"""Branch B against the real Panda of a LIBERO scene: the oracle, the residual, the weights."""

import mujoco
import numpy as np
import pytest

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.dynamics import (
    ELGate,
    gate,
    joint_diag_weights,
    proposed_qddot,
    task_space_weights,
)
from lerobot_physvla.sources.robosuite import RobosuiteStateSource

from conftest import make_state


@pytest.fixture(scope="module")
def panda(libero_task0):
    _, env = libero_task0
    src = RobosuiteStateSource(env.env)
    src.reset()
    return env, src


def test_mass_matrix_is_spd_and_the_simulators_own(panda):
    env, src = panda
    m, d = src.model, env.env.sim.data._data
    mujoco.mj_forward(m, d)
    st = src.read()
    M = st.M[0]
    np.testing.assert_allclose(M, M.T, atol=1e-12)
    assert np.linalg.eigvalsh(M).min() > 0
    # independent check: M v via mj_mulM on the live data (arm dofs only) equals M_arm v
    v = np.zeros(m.nv)
    v[src.oracle.dof_ids] = np.arange(1.0, 8.0)
    res = np.zeros(m.nv)
    mujoco.mj_mulM(m, d, res, v)
    np.testing.assert_allclose(M @ np.arange(1.0, 8.0), res[src.oracle.dof_ids], rtol=1e-9)
    np.testing.assert_allclose(st.bias[0], d.qfrc_bias[src.oracle.dof_ids], rtol=1e-9, atol=1e-12)


def test_reading_does_not_perturb_the_simulation(panda):
    env, src = panda
    d = env.env.sim.data._data
    before = (d.qpos.copy(), d.qvel.copy(), d.qacc_warmstart.copy(), d.qacc.copy())
    src.read()
    after = (d.qpos, d.qvel, d.qacc_warmstart, d.qacc)
    for x, y in zip(before, after):
        np.testing.assert_array_equal(x, y)


def _consistent_state(src):
    """The real arm, with qdot and tau set so that action v1 is exactly consistent (r_EL = 0)."""
    st = src.read()
    st.valid[:] = True
    cfg = PhysVLAConfig.paper()
    dt = st.dt
    v0, v1 = np.array([[0.05, 0.0, -0.02]]), np.array([[0.1, 0.02, -0.05]])
    zero = np.zeros_like(st.qdot)
    qdot0 = proposed_qddot(st.J_pos, zero, v0, np.ones(1), cfg.dls_damping)  # J^+ v0 (row space of J)
    st.qdot[:] = qdot0
    qdd = proposed_qddot(st.J_pos, st.qdot, v1, dt, cfg.dls_damping)
    st.tau[:] = st.bias + (st.M @ qdd[:, :, None])[:, :, 0]
    a_pos = v1 * dt[:, None] / 0.05  # m/s -> action units over one control period
    return st, a_pos


def test_residual_zero_for_consistent_and_large_for_inconsistent_action(panda):
    _, src = panda
    st, a_pos = _consistent_state(src)
    g = ELGate(PhysVLAConfig.paper())
    r, _ = g.residual(a_pos, st)
    assert np.linalg.norm(r) < 1e-6
    r_bad, _ = g.residual(-a_pos, st)
    assert np.linalg.norm(r_bad) > 1.0  # N m


def test_gated_mode_is_a_no_op_below_eps(panda):
    _, src = panda
    st, a_pos = _consistent_state(src)
    a_raw = np.zeros((1, 7))
    a_raw[0, :3] = a_pos[0]
    a_raw[0, 6] = 1.0  # close: Branch A's approach veto changes only the gripper, not the residual
    st.obj_pos[:] = st.eef_pos + [0.5, 0.0, 0.0]  # far from the object -> approach
    st.obj_rest_z[:] = st.obj_pos[:, 2]
    phys = Corrector(PhysVLAConfig.paper(mode="phys"))
    assert phys(a_raw, st)[0, 6] == pytest.approx(0.9)  # the veto through the 5 % cap
    gated = Corrector(PhysVLAConfig.paper(mode="phys_el", el_mode="gated"))
    out = gated(a_raw, st)
    assert gated.last.r_el[0] < 0.05  # below eps
    np.testing.assert_allclose(out, a_raw, rtol=0, atol=1e-15)
    assert gated.last.weights.sum() == 0
    soft = Corrector(PhysVLAConfig.paper(mode="phys_el", el_mode="soft"))
    assert soft(a_raw, st)[0, 6] < 1.0  # soft mode still passes part of the veto


def test_gate_ramp():
    r = np.array([0.0, 0.05, 0.775, 1.5, 10.0])
    np.testing.assert_allclose(gate(r, 0.05, 1.5), [0, 0, 0.5, 1, 1])


def test_weights_are_on_the_simplex_and_favour_light_joints():
    st = make_state(batch_size=2)
    st.M[0] = np.diag([5.0, 4, 3, 2, 1, 0.5, 0.25])
    w = joint_diag_weights(st.M)
    np.testing.assert_allclose(w.sum(axis=1), 1.0)
    assert (np.diff(w[0]) > 0).all()  # lighter joint -> larger weight
    wt = task_space_weights(st.M, st.J_pos)
    assert wt.shape == (2, 3)
    np.testing.assert_allclose(wt.sum(axis=1), 1.0)


def test_task_space_leaves_rotation_and_gripper_to_branch_a():
    st = make_state()
    cfg = PhysVLAConfig.paper(weighting="task_space")
    a_raw = np.array([[0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 1.0]])
    a_phys = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0]])
    a, _, _, w, ok = ELGate(cfg)(a_raw, a_phys, st)
    assert ok.all()
    np.testing.assert_array_equal(a[0, 3:], a_phys[0, 3:])
    assert (w[0, 3:] == 0).all() and w[0, :3].sum() == pytest.approx(1.0)
    np.testing.assert_allclose(a[0, :3], (1 - w[0, :3]) * a_raw[0, :3])


def test_joint_diag_refuses_a_layout_that_does_not_match_the_arm():
    st = make_state(n=6)
    with pytest.raises(ValueError, match="task_space"):
        Corrector(PhysVLAConfig.paper(mode="phys_el"))(np.zeros((1, 7)), st)


def test_work_energy_residual_is_power_of_the_el_residual():
    st = make_state()
    g = ELGate(PhysVLAConfig.paper())
    a = np.array([[0.2, -0.1, 0.3, 0, 0, 0, -1.0]])
    _, r_norm, r_energy, _, _ = g(a, a, st)
    r, _ = g.residual(a[:, :3], st)
    assert r_energy[0] == pytest.approx(abs(st.qdot[0] @ r[0]))
    assert r_norm[0] == pytest.approx(np.linalg.norm(r[0]))


_TREE = """
<mujoco>
  <worldbody>
    <body name="base"><joint name="slide" type="slide" axis="1 0 0"/><geom size=".1" mass="2"/>
      <body name="l1" pos="0 .2 0"><joint name="l1" axis="0 0 1"/><geom size=".05" pos=".1 0 0" mass="1"/>
        <body name="l2" pos=".2 0 0"><joint name="l2" axis="0 1 0"/><geom size=".04" pos=".1 0 0" mass=".5"/>
          <site name="tip" pos=".2 0 0"/></body></body>
      <body name="r1" pos="0 -.2 0"><joint name="r1" axis="0 0 1"/><geom size=".05" pos=".1 0 0" mass="1"/></body>
    </body>
    <body name="box" pos="1 0 0"><freejoint/><geom size=".03" mass=".1"/></body>
  </worldbody>
</mujoco>
"""


def _random_tree_data(m, seed: int):
    """An MjData of the _TREE model at a random state (unit quaternion for the free body)."""
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    d.qpos[:] = rng.normal(size=m.nq)
    d.qpos[-4:] /= np.linalg.norm(d.qpos[-4:])
    d.qvel[:] = rng.normal(size=m.nv)
    return d


@pytest.mark.parametrize("joints", [["slide", "l1", "l2"], ["l2", "r1", "l1"], ["r1", "l2"]])
def test_compiled_live_read_equals_mj_fullM_on_a_branching_tree(joints):
    """Arm dofs in any order, on separate branches (uncoupled, M = 0 there), after a free body."""
    m = mujoco.MjModel.from_xml_string(_TREE)
    d = _random_tree_data(m, 0)
    mujoco.mj_forward(m, d)
    from lerobot_physvla.sources.mujoco import MujocoDynamicsOracle
    from lerobot_physvla.core.state import PhysState, packed_size

    oracle = MujocoDynamicsOracle(m, joints, eef_site="tip")
    row = np.full(packed_size(len(joints)), np.nan)
    oracle.read_live_into(d, row)
    st = PhysState.unpack(row)
    for name, value in oracle.read(d).items():
        np.testing.assert_allclose(getattr(st, name)[0], value, atol=1e-12, err_msg=name)
    np.testing.assert_allclose(st.eef_pos[0], d.site_xpos[0], atol=1e-12)
    if "r1" in joints and "l2" in joints:
        assert st.M[0][joints.index("r1"), joints.index("l2")] == 0.0


@pytest.mark.parametrize("eef, constraint, fingers", [("site", False, None), ("body", True, [0]), ("site", True, [1, 2])])
def test_the_one_buffer_read_equals_the_field_by_field_read(eef, constraint, fingers):
    """read_live_into reads every field through one view of the MjData buffer and computes the
    Jacobian itself (pack_live_buf); the field-by-field read with MuJoCo's mj_jacSite /
    mj_jacBody (pack_live_row) gives the same row, bit for bit."""
    from lerobot_physvla.sources.mujoco import MujocoDynamicsOracle
    from lerobot_physvla.core.state import packed_size

    m = mujoco.MjModel.from_xml_string(_TREE)
    joints = ["l2", "slide", "l1"]
    kw = {"eef_site": "tip"} if eef == "site" else {"eef_body": "l2"}
    oracle = MujocoDynamicsOracle(m, joints, include_constraint=constraint, **kw)
    fingers = None if fingers is None else np.asarray(fingers, np.intp)
    consts = np.array([[0.0, 1.0], [2.0, 0.05]])
    for seed in (1, 2):  # a second MjData of the same model (robosuite builds one at every reset)
        d = _random_tree_data(m, seed)
        mujoco.mj_step(m, d)  # derived quantities of the last forward pass, as a simulator leaves them
        d.qfrc_applied[:] = np.random.default_rng(seed).normal(size=m.nv)
        one = np.full(packed_size(len(joints)), np.nan)
        oracle.read_live_into(d, one, None, consts, fingers)
        assert oracle._arena[0] is d and oracle._arena[3] is not None  # the one-buffer path, this data
        by_field = np.full_like(one, np.nan)
        oracle._buffer_arena = lambda *a: None  # the fallback path
        oracle.read_live_into(d, by_field, None, consts, fingers)
        del oracle._buffer_arena
        np.testing.assert_array_equal(one, by_field)
        assert np.isfinite(one[2:]).sum() > 3 * len(joints)  # J_pos and the rest were written
        # a row or consts the direct call may not take (strided, Fortran order): numba's dispatch, same row
        wide, f_consts = np.full(2 * one.size, np.nan), np.asfortranarray(consts)
        assert not f_consts.flags.c_contiguous
        oracle.read_live_into(d, wide[::2], None, f_consts, fingers)
        np.testing.assert_array_equal(wide[::2], one)
