"""Branch B: the Euler-Lagrange gate (paper eq. 4-6, App. A) and its MuJoCo dynamics oracle.

The residual is of the *proposed* motion (SPEC 1): the action's position channels give a
Cartesian velocity v = a_pos * metres_per_unit / dt, mapped to joints with a damped
least-squares pseudo-inverse of the translational Jacobian,
    qdot_des = J^T (J J^T + lambda^2 I)^-1 v,   qddot = (qdot_des - qdot) / dt,
    r_EL = M(q) qddot + C(q, qdot) qdot + G(q) - tau                      (eq. 4)
Weights (eq. 5):  w = rho(|r_EL|) * softmax(1 / diag(M)),  rho(r) = clip((r - eps)/(r0 - eps), 0, 1).
The work-energy residual of App. A,  qdot^T M qddot + 1/2 qdot^T Mdot qdot + qdot^T G - qdot^T tau,
equals qdot . r_EL exactly, because qdot^T (Mdot - 2 C) qdot = 0 (skew symmetry), so it is
computed from r_EL with no finite-differenced Mdot. It is logged, never gating.

The oracle reads M via mj_fullM, the bias via qfrc_bias and tau via qfrc_actuator +
qfrc_applied from a live MjData: no dynamics are re-implemented in Python.
"""

from __future__ import annotations

import mujoco
import numpy as np

from .config import PhysVLAConfig


def proposed_qddot(
    J_pos: np.ndarray, qdot: np.ndarray, v_des: np.ndarray, dt: np.ndarray, damping: float
) -> np.ndarray:
    """Joint acceleration (B, n) implied by a desired end-effector velocity v_des (B, 3), m/s."""
    JJt = J_pos @ J_pos.transpose(0, 2, 1)  # (B, 3, 3)
    JJt[:, [0, 1, 2], [0, 1, 2]] += damping * damping
    y = np.linalg.solve(JJt, v_des[:, :, None])  # (B, 3, 1)
    qdot_des = (J_pos.transpose(0, 2, 1) @ y)[:, :, 0]
    return (qdot_des - qdot) / dt[:, None]


def el_residual(M: np.ndarray, qddot: np.ndarray, bias: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """r_EL = M qddot + bias - tau, (B, n) in N m  (eq. 4)."""
    return (M @ qddot[:, :, None])[:, :, 0] + bias - tau


def work_energy_residual(qdot: np.ndarray, r_el: np.ndarray) -> np.ndarray:
    """|qdot . r_EL| (B,), W: the App. A work-energy residual (see module docstring)."""
    return np.abs(np.einsum("bi,bi->b", qdot, r_el))


def gate(r_norm: np.ndarray, eps: float, r0: float) -> np.ndarray:
    """rho(r) = clip((r - eps) / (r0 - eps), 0, 1)  (eq. 5)."""
    return np.clip((r_norm - eps) / (r0 - eps), 0.0, 1.0)


def softmax(x: np.ndarray) -> np.ndarray:
    e = np.exp(x - x.max(axis=-1, keepdims=True))
    return e / e.sum(axis=-1, keepdims=True)


def joint_diag_weights(M: np.ndarray) -> np.ndarray:
    """softmax(1 / diag(M)) over the arm joints, (B, n)  (eq. 5)."""
    return softmax(1.0 / np.diagonal(M, axis1=1, axis2=2))


def task_space_weights(M: np.ndarray, J_pos: np.ndarray) -> np.ndarray:
    """softmax(1 / diag(Lambda)) over x, y, z with Lambda = (J M^-1 J^T)^-1, (B, 3).

    Lambda is the operational-space inertia (kg) of the end-effector's translation; as in the
    paper's joint weighting, the axis with the smaller effective mass gets the larger weight.
    """
    Minv_Jt = np.linalg.solve(M, J_pos.transpose(0, 2, 1))  # (B, n, 3)
    lam = np.linalg.inv(J_pos @ Minv_Jt)  # (B, 3, 3)
    return softmax(1.0 / np.diagonal(lam, axis1=1, axis2=2))


class ELGate:
    """Branch B: blends Branch A's candidate with the raw action, weighted by inertia and residual.

    Attributes:
        cfg: corrector configuration (el_mode, weighting, eps_nm, r0_nm, dls_damping).
    Returns from __call__: (a_B, r_el_norm (B,) N m, r_energy (B,) W, weights (B, A)).
    """

    def __init__(self, cfg: PhysVLAConfig):
        self.cfg = cfg
        self.layout = cfg.action_layout

    def residual(self, a_pos_units: np.ndarray, state) -> tuple[np.ndarray, np.ndarray]:
        """r_EL (B, n) in N m and qddot (B, n) of the motion proposed by the position channels."""
        v_des = a_pos_units * (self.layout.metres_per_unit / state.dt[:, None])  # m/s
        qddot = proposed_qddot(state.J_pos, state.qdot, v_des, state.dt, self.cfg.dls_damping)
        return el_residual(state.M, qddot, state.bias, state.tau), qddot

    def __call__(self, a_raw: np.ndarray, a_phys: np.ndarray, state):
        cfg, lay = self.cfg, self.layout
        pos = lay.pos_index
        r_el, _ = self.residual(a_phys[:, pos], state)
        r_norm = np.sqrt(np.einsum("bi,bi->b", r_el, r_el))
        r_energy = work_energy_residual(state.qdot, r_el)
        rho = np.ones_like(r_norm) if cfg.el_mode == "soft" else gate(r_norm, cfg.eps_nm, cfg.r0_nm)

        w = np.zeros_like(a_raw)
        if cfg.weighting == "joint_diag":
            if state.n_joints != lay.dim:
                raise ValueError(
                    f"physvla: weighting='joint_diag' applies {state.n_joints} joint weights to "
                    f"{lay.dim} action entries; use weighting='task_space' for this arm/layout"
                )
            w[:] = rho[:, None] * joint_diag_weights(state.M)
            a = w * a_phys + (1.0 - w) * a_raw  # eq. 6
        else:
            w[:, pos] = rho[:, None] * task_space_weights(state.M, state.J_pos)
            a = a_phys.copy()  # rotation and gripper keep Branch A's value
            a[:, pos] = w[:, pos] * a_phys[:, pos] + (1.0 - w[:, pos]) * a_raw[:, pos]
        return a, r_norm, r_energy, w


class MujocoDynamicsOracle:
    """Reads q, qdot, M (arm block), bias, tau and the end-effector Jacobian from a live MjData.

    Attributes:
        model: the MjModel.
        dof_ids: (n,) dof (qvel) addresses of the arm joints.
        qpos_ids: (n,) qpos addresses of the arm joints.
        site_id: the end-effector site, or body_id if the end-effector is a body.
    """

    def __init__(self, model: mujoco.MjModel, joint_names: list[str], eef_site: str | None = None, eef_body: str | None = None):
        self.model = model
        ids = []
        for name in joint_names:
            jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if jid < 0:
                names = [model.joint(i).name for i in range(model.njnt)]
                raise ValueError(f"physvla: joint {name!r} not in the model; joints are: {names}")
            ids.append(jid)
        self.dof_ids = np.array([model.jnt_dofadr[j] for j in ids], dtype=np.intp)
        self.qpos_ids = np.array([model.jnt_qposadr[j] for j in ids], dtype=np.intp)
        self.site_id = self.body_id = -1
        if eef_site is not None:
            self.site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, eef_site)
            if self.site_id < 0:
                names = [model.site(i).name for i in range(model.nsite)]
                raise ValueError(f"physvla: end-effector site {eef_site!r} not in the model; sites are: {names}")
        elif eef_body is not None:
            self.body_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, eef_body)
            if self.body_id < 0:
                names = [model.body(i).name for i in range(model.nbody)]
                raise ValueError(f"physvla: end-effector body {eef_body!r} not in the model; bodies are: {names}")
        else:
            raise ValueError("physvla: give eef_site or eef_body")
        self._scratch = mujoco.MjData(model)
        self._full_m = np.zeros((model.nv, model.nv))
        self._jacp = np.zeros((3, model.nv))
        self._block = np.ix_(self.dof_ids, self.dof_ids)

    @property
    def n_joints(self) -> int:
        return len(self.dof_ids)

    def eef_pos(self, data: mujoco.MjData | None = None) -> np.ndarray:
        """End-effector position, m; from the scratch data of the last read() if data is None."""
        data = self._scratch if data is None else data
        return (data.site_xpos[self.site_id] if self.site_id >= 0 else data.xpos[self.body_id]).copy()

    def read(self, data: mujoco.MjData) -> dict[str, np.ndarray]:
        """q, qdot, M, bias, tau, J_pos of the arm at data's current state.

        The live `data` is never written: its state is copied into a scratch MjData and
        forwarded there, so reading cannot perturb the simulation (solver warm-start included).
        """
        m, s = self.model, self._scratch
        s.time = data.time
        s.qpos[:] = data.qpos
        s.qvel[:] = data.qvel
        s.act[:] = data.act
        s.ctrl[:] = data.ctrl
        s.qfrc_applied[:] = data.qfrc_applied
        s.xfrc_applied[:] = data.xfrc_applied
        s.mocap_pos[:] = data.mocap_pos
        s.mocap_quat[:] = data.mocap_quat
        mujoco.mj_forward(m, s)
        data = s
        mujoco.mj_fullM(m, self._full_m, data.qM)  # mujoco 3.3.7 signature
        if self.site_id >= 0:
            mujoco.mj_jacSite(m, data, self._jacp, None, self.site_id)
        else:
            mujoco.mj_jacBody(m, data, self._jacp, None, self.body_id)
        d = self.dof_ids
        return {
            "q": data.qpos[self.qpos_ids].copy(),
            "qdot": data.qvel[d].copy(),
            "M": self._full_m[self._block],
            "bias": data.qfrc_bias[d].copy(),
            "tau": data.qfrc_actuator[d] + data.qfrc_applied[d],
            "J_pos": self._jacp[:, d].copy(),
        }
