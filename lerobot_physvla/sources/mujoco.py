"""The MuJoCo state source: a live MjData read into the corrector's packed state (M, bias, tau,
the end-effector Jacobian), with no dynamics re-implemented in Python.

The oracle reads M via mj_fullM, the bias via qfrc_bias and tau via qfrc_actuator +
qfrc_applied from a live MjData. Its fast path (`read_live_into`) copies them, the arm block of the
sparse qM and the end-effector Jacobian straight into a packed state row in one compiled call,
from the simulator's own last forward pass (see its docstring for what that means in robosuite:
one physics substep old). The simulators' and the robots' state sources (sources/robosuite.py,
sources/joint_state.py, sim/fetch_sim.py, arms/model.py) build on it.
"""

from __future__ import annotations

import ctypes

import mujoco
import numpy as np
from numba import njit

from lerobot_physvla.core.direct_call import direct_entry
from lerobot_physvla.core.state import field_offsets


@njit(cache=True, error_model="numpy")
def arm_mass_block(row, o_m, qm, qm0, dof_ids, madr, parent, arm_col):
    """Writes the arm block of MuJoCo's sparse joint-space inertia (qM, read from qm[qm0:]) into
    row[o_m:] as an n x n matrix: dof i holds M[i, i] at madr[i], then M[i, j] for j = parent(i),
    parent(parent(i)), ...; arm_col[j] = column of dof j in the arm block, -1 off the arm."""
    n = dof_ids.shape[0]
    for k in range(n * n):
        row[o_m + k] = 0.0  # dofs on separate branches of the tree are not coupled
    for k in range(n):
        i = dof_ids[k]
        adr = madr[i]
        j = i
        while j >= 0:  # M[i, j] for j = i and i's ancestors, in qM's order
            c = arm_col[j]
            if c >= 0:
                v = qm[qm0 + adr]
                row[o_m + k * n + c] = v
                row[o_m + c * n + k] = v
            j = parent[j]
            adr += 1


@njit(cache=True, error_model="numpy")
def pack_live_row(row, o, qpos, qvel, qM, bias, tau_a, tau_b, tau_c, jacp, xpos, site_xpos, qpos_ids, dof_ids,
                  madr, parent, arm_col, points, consts, fingers):
    """Writes the arm's q, qdot, M, bias, tau, J_pos, the given points and constants into a packed row.

    o: offsets [q, qdot, M, bias, tau, J_pos, gripper] into row (gripper < 0: not written); tau =
    tau_a + tau_b + tau_c (N m) at the arm dofs; M: the arm block of qM, MuJoCo's sparse
    joint-space inertia in the layout mj_fullM reads (dof i holds M[i, i] at madr[i], then M[i, j]
    for j = parent(i), parent(parent(i)), ...), arm_col[j] = column of dof j in the arm block, -1
    off the arm; points: rows (offset, kind, id), kind 0 = body (xpos), 1 = site (site_xpos), each
    written as 3 floats at row[offset:]; consts: rows (offset, value) written as they are (after
    the points: a constant overrides a point); fingers: qpos addresses whose |q| sum (m) is the
    gripper opening written at row[o[6]].
    """
    if o[6] >= 0:
        g = 0.0
        for k in range(fingers.shape[0]):
            g += abs(qpos[fingers[k]])
        row[o[6]] = g
    n = qpos_ids.shape[0]
    for k in range(n):
        d = dof_ids[k]
        row[o[0] + k] = qpos[qpos_ids[k]]
        row[o[1] + k] = qvel[d]
        row[o[3] + k] = bias[d]
        row[o[4] + k] = tau_a[d] + tau_b[d] + tau_c[d]
        for r in range(3):
            row[o[5] + r * n + k] = jacp[r, d]
    arm_mass_block(row, o[2], qM, 0, dof_ids, madr, parent, arm_col)
    for p in range(points.shape[0]):
        src = xpos if points[p, 1] == 0 else site_xpos
        for r in range(3):
            row[points[p, 0] + r] = src[points[p, 2], r]
    for k in range(consts.shape[0]):
        row[int(consts[k, 0])] = consts[k, 1]


# pack_live_buf's int64 arena `li`: row offsets [q, qdot, M, bias, tau, J_pos, gripper (-1: none)],
# field offsets into the MjData buffer view (float64 units) [qpos, qvel, qM, qfrc_bias,
# qfrc_actuator, qfrc_applied, qfrc_constraint (-1: not added), xpos, site_xpos, cdof, subtree_com],
# n arm joints, nv, the Jacobian's point (kind 0 body / 1 site, id), the root body whose subtree
# centre of mass MuJoCo's Jacobian refers to, the number of points and of finger joints; then
# qpos_ids (n), dof_ids (n), on_chain (n: 1 where the dof moves the point), madr, parent, arm_col
# (nv each), points (3 per point: offset, kind, id), fingers
(L_O, L_F, L_N, L_NV, L_PT, L_PID, L_ROOT, L_NPTS, L_NFING, N_L) = (0, 7, 18, 19, 20, 21, 22, 23, 24, 25)
F_QPOS, F_QVEL, F_QM, F_BIAS, F_TAU_A, F_TAU_B, F_TAU_C, F_XPOS, F_SITE_XPOS, F_CDOF, F_SUBTREE_COM = range(11)


# pack_live_buf's compiled overload for (C float64 row, its buffer view, its int arena, C float64 (k, 2)
# consts): read_live_into checks row and consts before it calls it; the view and arena are its own
_PACK_LIVE_BUF: list = [None]


@njit(cache=True, error_model="numpy")
def pack_live_buf(row, buf, li, consts):
    """As pack_live_row, reading every MjData field from one float64 view of the data's buffer
    (`buf`, offsets in li; layout above) and computing the point's translational Jacobian as
    MuJoCo's mj_jac does (cdof_lin + cdof_ang x (point - subtree_com[root]) over the dofs that
    move it), so a read is one compiled call with four arguments and no binding call (each
    array argument costs ~0.7 us when the caches are cold, as they are after a physics step)."""
    n, nv = li[L_N], li[L_NV]
    f = li[L_F : L_F + 11]
    qpos_ids = li[N_L : N_L + n]
    dof_ids = li[N_L + n : N_L + 2 * n]
    on_chain = li[N_L + 2 * n : N_L + 3 * n]
    a = N_L + 3 * n
    madr, parent, arm_col = li[a : a + nv], li[a + nv : a + 2 * nv], li[a + 2 * nv : a + 3 * nv]
    a += 3 * nv
    n_pts = li[L_NPTS]
    points = li[a : a + 3 * n_pts]
    fingers = li[a + 3 * n_pts : a + 3 * n_pts + li[L_NFING]]
    o0, o1, o2, o3, o4, o5, o6 = li[0], li[1], li[2], li[3], li[4], li[5], li[6]
    if o6 >= 0:
        g = 0.0
        for k in range(fingers.shape[0]):
            g += abs(buf[f[F_QPOS] + fingers[k]])
        row[o6] = g
    pt = f[F_XPOS] if li[L_PT] == 0 else f[F_SITE_XPOS]
    pt += 3 * li[L_PID]
    com = f[F_SUBTREE_COM] + 3 * li[L_ROOT]
    off0, off1, off2 = buf[pt] - buf[com], buf[pt + 1] - buf[com + 1], buf[pt + 2] - buf[com + 2]
    for k in range(n):
        d = dof_ids[k]
        row[o0 + k] = buf[f[F_QPOS] + qpos_ids[k]]
        row[o1 + k] = buf[f[F_QVEL] + d]
        row[o3 + k] = buf[f[F_BIAS] + d]
        tau = buf[f[F_TAU_A] + d] + buf[f[F_TAU_B] + d]
        if f[F_TAU_C] >= 0:
            tau += buf[f[F_TAU_C] + d]
        row[o4 + k] = tau
        if on_chain[k]:
            c = f[F_CDOF] + 6 * d  # [angular (3), linear (3)]
            row[o5 + k] = buf[c + 3] + (buf[c + 1] * off2 - buf[c + 2] * off1)
            row[o5 + n + k] = buf[c + 4] + (buf[c + 2] * off0 - buf[c] * off2)
            row[o5 + 2 * n + k] = buf[c + 5] + (buf[c] * off1 - buf[c + 1] * off0)
        else:
            row[o5 + k] = row[o5 + n + k] = row[o5 + 2 * n + k] = 0.0
    arm_mass_block(row, o2, buf, f[F_QM], dof_ids, madr, parent, arm_col)
    for p in range(n_pts):
        src = f[F_XPOS] if points[3 * p + 1] == 0 else f[F_SITE_XPOS]
        src += 3 * points[3 * p + 2]
        for r in range(3):
            row[points[3 * p] + r] = buf[src + r]
    for k in range(consts.shape[0]):
        row[int(consts[k, 0])] = consts[k, 1]


class MujocoDynamicsOracle:
    """Reads q, qdot, M (arm block), bias, tau and the end-effector Jacobian from a live MjData.

    Attributes:
        model: the MjModel.
        dof_ids: (n,) dof (qvel) addresses of the arm joints.
        qpos_ids: (n,) qpos addresses of the arm joints.
        site_id: the end-effector site, or body_id if the end-effector is a body.
        include_constraint: add qfrc_constraint to tau (arms driven by a mocap weld, e.g. Fetch,
            have no arm actuators; note it then also holds contact forces on the arm).
    """

    def __init__(self, model: mujoco.MjModel, joint_names: list[str], eef_site: str | None = None,
                 eef_body: str | None = None, include_constraint: bool = False):
        self.model = model
        self.include_constraint = include_constraint
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
        self._bias = np.zeros(model.nv)
        self._block = np.ix_(self.dof_ids, self.dof_ids)
        self._arm_col = np.full(model.nv, -1, dtype=np.intp)
        self._arm_col[self.dof_ids] = np.arange(len(self.dof_ids))
        self._madr = np.asarray(model.dof_Madr, dtype=np.intp)
        self._parent = np.asarray(model.dof_parentid, dtype=np.intp)
        f = field_offsets(len(self.dof_ids))
        self._o = np.array([f[k] for k in ("q", "qdot", "M", "bias", "tau", "J_pos")] + [-1], dtype=np.intp)
        self._o_grip = self._o.copy()
        self._o_grip[6] = f["gripper"]
        self._no_consts, self._no_fingers = np.zeros((0, 2)), np.zeros(0, dtype=np.intp)
        self._eef_point = np.array([[f["eef_pos"], 1, self.site_id] if self.site_id >= 0
                                    else [f["eef_pos"], 0, self.body_id]], dtype=np.intp)
        self._live = None  # (MjData, its field views) of the last read_live_into
        self._arena = None  # (MjData, points, fingers, (buffer view, pack_live_buf's arena) or None)
        self._li = None  # ((id(points), id(fingers)), points, fingers, the static part of that arena)
        self._layout = None  # the MjData fields' layout in its buffer (_buffer_layout), the same for every MjData

    @property
    def n_joints(self) -> int:
        return len(self.dof_ids)

    def eef_pos(self, data: mujoco.MjData | None = None) -> np.ndarray:
        """End-effector position, m; from the scratch data of the last read() if data is None."""
        data = self._scratch if data is None else data
        return (data.site_xpos[self.site_id] if self.site_id >= 0 else data.xpos[self.body_id]).copy()

    def _views(self, data: mujoco.MjData) -> tuple:
        """The MjData fields read_live_into reads, as numpy views (made once per MjData: each
        attribute access of the binding costs ~0.5 us)."""
        if self._live is None or self._live[0] is not data:
            zeros = np.zeros(self.model.nv)
            self._live = (data, (data.qpos, data.qvel, data.qM, data.qfrc_bias, data.qfrc_actuator, data.qfrc_applied,
                                 data.qfrc_constraint if self.include_constraint else zeros), data.xpos, data.site_xpos)
        return self._live

    _BUFFER_FIELDS = ("qpos", "qvel", "qM", "qfrc_bias", "qfrc_actuator", "qfrc_applied", "qfrc_constraint", "xpos",
                      "site_xpos", "cdof", "subtree_com")  # in the order of F_*

    def _buffer_arena(self, data: mujoco.MjData, points, fingers) -> tuple | None:
        """(one float64 view over the MjData fields read_live_into reads, pack_live_buf's int
        arena), or None where the fields are not laid out in one buffer at float64 boundaries
        (the read then takes the fields one by one). The arena is made once per (points,
        fingers) and the fields' layout once per model; a new MjData (robosuite builds one at
        every reset) costs two addresses and a view (~2 us, not ~25 us of field lookups)."""
        cached = self._arena
        if cached is not None and cached[0] is data and cached[1] is points and cached[2] is fingers:
            return cached[3]
        li = self._static_li(points, fingers)
        qpos = data.qpos.ctypes.data
        lay = self._layout
        if lay is None or data.cdof.ctypes.data - qpos != lay[2]:
            lay = self._layout = self._buffer_layout(data)
        fast = None
        if lay[0] is not None:
            view_type, start, _, offsets = lay
            li[L_F : L_F + 11] = offsets
            fast = (np.frombuffer(view_type.from_address(qpos + start), np.float64), li)
        self._arena = (data, points, fingers, fast)  # holds the data: its buffer lives as long as the view
        return fast

    def _buffer_layout(self, data: mujoco.MjData) -> tuple:
        """(ctypes array type spanning the fields or None, the span's start relative to qpos (bytes),
        cdof's address relative to qpos (the check that a new MjData has this layout), the
        fields' offsets in the span (float64 units, F_* order; -1 for a force not added))."""
        fields = [getattr(data, name) for name in self._BUFFER_FIELDS]
        addr = [a.ctypes.data for a in fields]
        base, qpos = min(addr), addr[F_QPOS]
        end = max(a + x.nbytes for a, x in zip(addr, fields))
        check = addr[F_CDOF] - qpos
        if not all((a - base) % 8 == 0 and x.dtype == np.float64 and x.flags.c_contiguous
                   for a, x in zip(addr, fields)):
            return None, 0, check, None
        offsets = [(a - base) // 8 for a in addr]
        if not self.include_constraint:
            offsets[F_TAU_C] = -1
        return ctypes.c_double * ((end - base) // 8), base - qpos, check, offsets

    def _static_li(self, points, fingers) -> np.ndarray:
        """pack_live_buf's int arena but for the field offsets (layout above), made once per (points, fingers)."""
        key = (id(points), id(fingers))
        if self._li is not None and self._li[0] == key and self._li[1] is points and self._li[2] is fingers:
            return self._li[3]
        m = self.model
        o = self._o if fingers is None else self._o_grip
        pts = self._eef_point if points is None else np.asarray(points, np.int64)
        fing = self._no_fingers if fingers is None else np.asarray(fingers, np.int64)
        if self.site_id >= 0:
            kind, pid, body = 1, self.site_id, int(m.site_bodyid[self.site_id])
        else:
            kind, pid, body = 0, self.body_id, self.body_id
        root = int(m.body_rootid[body])
        while body and not m.body_dofnum[body]:  # as mj_jac: the first body up the tree that moves
            body = int(m.body_parentid[body])
        chain = set()
        i = int(m.body_dofadr[body] + m.body_dofnum[body] - 1) if body else -1
        while i >= 0:
            chain.add(i)
            i = int(m.dof_parentid[i])
        n = len(self.dof_ids)
        head = [*o, *([0] * 11), n, m.nv, kind, pid, root, len(pts), len(fing)]
        li = np.concatenate([np.asarray(head, np.int64), self.qpos_ids, self.dof_ids,
                             [int(d) in chain for d in self.dof_ids], self._madr, self._parent, self._arm_col,
                             pts.reshape(-1), fing]).astype(np.int64)
        self._li = (key, points, fingers, li)
        return li

    def read_live_into(self, data: mujoco.MjData, row: np.ndarray, points: np.ndarray | None = None,
                       consts: np.ndarray | None = None, fingers: np.ndarray | None = None) -> None:
        """Writes q, qdot, M, bias, tau, J_pos, eef_pos (and `points`, `consts`, the gripper
        opening from `fingers`) into a packed state row, in one compiled call.

        Reads the live data's own derived quantities (qM, qfrc_bias, qfrc_actuator, body and site
        positions) with no recomputation and no write to the data: ~10 us instead of ~50 for
        `read`. They are those of the simulator's last forward pass. robosuite's step runs
        `sim.forward(); sim.step()` per substep and no forward after the last one, so M, bias,
        tau, the Jacobian and the positions are one physics substep (2 ms in LIBERO) older than
        q and qdot, all of them mutually consistent; `read` recomputes them at the current q.

        points: (k, 3) int rows (offset into row, 0 body / 1 site, id) of further positions.
        consts: (k, 2) rows (offset into row, value) written as they are (header fields).
        fingers: qpos addresses of the gripper's finger joints; the sum of their |q| (m) is
            written as the gripper opening (not written when None).
        """
        fast = self._buffer_arena(data, points, fingers)
        if fast is not None:
            consts = self._no_consts if consts is None else consts
            if (type(row) is np.ndarray and row.dtype == np.float64 and row.ndim == 1 and row.flags.carray
                    and type(consts) is np.ndarray and consts.dtype == np.float64 and consts.ndim == 2
                    and consts.flags.carray):
                call = _PACK_LIVE_BUF[0]
                if call is None:  # the compiled overload, called without numba's dispatch (core/direct_call.py)
                    call = _PACK_LIVE_BUF[0] = direct_entry(pack_live_buf, row, fast[0], fast[1], consts)
                call(row, fast[0], fast[1], consts)
            else:
                pack_live_buf(row, fast[0], fast[1], consts)
            return
        _, forces, xpos, site_xpos = self._views(data)
        if self.site_id >= 0:
            mujoco.mj_jacSite(self.model, data, self._jacp, None, self.site_id)
        else:
            mujoco.mj_jacBody(self.model, data, self._jacp, None, self.body_id)
        o = self._o
        if fingers is None:
            fingers = self._no_fingers
        else:
            o = self._o_grip
        pack_live_row(row, o, *forces, self._jacp, xpos, site_xpos, self.qpos_ids, self.dof_ids, self._madr,
                      self._parent, self._arm_col, self._eef_point if points is None else points,
                      self._no_consts if consts is None else consts, fingers)

    def read(self, data: mujoco.MjData) -> dict[str, np.ndarray]:
        """q, qdot, M, bias, tau, J_pos of the arm at data's current state.

        The live `data` is never written: qpos/qvel are copied into a scratch MjData where only
        what the corrector needs is recomputed (kinematics, composite inertia, RNE bias; no
        collision detection, ~5x cheaper than mj_forward), so reading cannot perturb the
        simulation. tau is the live qfrc_actuator + qfrc_applied: the torques being applied.
        """
        m, s = self.model, self._scratch
        s.qpos[:] = data.qpos
        s.qvel[:] = data.qvel
        s.mocap_pos[:] = data.mocap_pos
        s.mocap_quat[:] = data.mocap_quat
        mujoco.mj_kinematics(m, s)
        mujoco.mj_comPos(m, s)
        mujoco.mj_makeM(m, s)  # qM: composite rigid body inertia + armature
        mujoco.mj_comVel(m, s)
        mujoco.mj_rne(m, s, 0, self._bias)  # C(q, qdot) qdot + G(q)
        tau = data.qfrc_actuator[self.dof_ids] + data.qfrc_applied[self.dof_ids]
        if self.include_constraint:  # mocap-driven arms (Fetch): the weld constraint moves the arm
            tau = tau + data.qfrc_constraint[self.dof_ids]
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
            "bias": self._bias[d].copy(),
            "tau": tau,
            "J_pos": self._jacp[:, d].copy(),
        }
