"""Branch B: the Euler-Lagrange gate (paper eq. 4-6, App. A).

The residual is of the *proposed* motion (the paper leaves it open; this is the project's reading): the action's
position channels give a Cartesian velocity v = a_pos * metres_per_unit / dt, mapped to joints with a damped
least-squares pseudo-inverse of the translational Jacobian,
    qdot_des = J^T (J J^T + lambda^2 I)^-1 v,   qddot = (qdot_des - qdot) / dt,
    r_EL = M(q) qddot + C(q, qdot) qdot + G(q) - tau                      (eq. 4)
Weights (eq. 5):  w = rho(|r_EL|) * softmax(1 / diag(M)),  rho(r) = clip((r - eps)/(r0 - eps), 0, 1).
The work-energy residual of App. A,  qdot^T M qddot + 1/2 qdot^T Mdot qdot + qdot^T G - qdot^T tau,
equals qdot . r_EL exactly, because qdot^T (Mdot - 2 C) qdot = 0 (skew symmetry), so it is
computed from r_EL with no finite-differenced Mdot. It is logged, never gating.

M, the bias and tau come from the state source (sources/mujoco.py reads them from MuJoCo: no
dynamics are re-implemented in Python); the noise guard for joint readings is core/noise_guard.py.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.state import field_offsets

# numba caches a compiled function by its own file only: every cached kernel here calls njit
# functions of this module alone, so editing this file invalidates all of them together.
SOFT, GATED = 0, 1
JOINT_DIAG, TASK_SPACE = 0, 1


# ---------------------------------------------------------------- per-env arithmetic (numba)
@njit(cache=True, error_model="numpy")
def _sym3_inverse(a, inv):
    """Inverse of a symmetric 3x3 matrix by cofactors; returns the determinant."""
    c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    c01 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    c02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
    inv[0, 0] = c00 / det
    inv[0, 1] = inv[1, 0] = c01 / det
    inv[0, 2] = inv[2, 0] = c02 / det
    inv[1, 1] = (a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]) / det
    inv[1, 2] = inv[2, 1] = (a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]) / det
    inv[2, 2] = (a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]) / det
    return det


@njit(cache=True, error_model="numpy")
def _j_times(J, X, a):
    """a (3, 3) = J (3, n) @ X (n, 3)."""
    for r in range(3):
        for c in range(3):
            acc = 0.0
            for k in range(J.shape[1]):
                acc += J[r, k] * X[k, c]
            a[r, c] = acc


@njit(cache=True, error_model="numpy")
def qddot_row(J, qdot, v, dt, damping, out):
    """qddot = (J^T (J J^T + lambda^2 I)^-1 v - qdot) / dt for one env; v in m/s, out (n,) rad/s^2."""
    n = qdot.shape[0]
    a = np.empty((3, 3))
    inv = np.empty((3, 3))
    _j_times(J, J.T, a)
    for r in range(3):
        a[r, r] += damping * damping
    _sym3_inverse(a, inv)
    y0 = inv[0, 0] * v[0] + inv[0, 1] * v[1] + inv[0, 2] * v[2]
    y1 = inv[1, 0] * v[0] + inv[1, 1] * v[1] + inv[1, 2] * v[2]
    y2 = inv[2, 0] * v[0] + inv[2, 1] * v[1] + inv[2, 2] * v[2]
    for k in range(n):
        out[k] = (J[0, k] * y0 + J[1, k] * y1 + J[2, k] * y2 - qdot[k]) / dt


@njit(cache=True, error_model="numpy")
def residual_row(M, qdd, bias, tau, out):
    """r_EL = M qddot + bias - tau for one env, N m (eq. 4)."""
    n = qdd.shape[0]
    for r in range(n):
        acc = bias[r] - tau[r]
        for c in range(n):
            acc += M[r, c] * qdd[c]
        out[r] = acc


@njit(cache=True, error_model="numpy")
def rho(r, eps, r0):
    """rho(r) = clip((r - eps) / (r0 - eps), 0, 1): the gate of eq. 5, r in N m."""
    return min(max((r - eps) / (r0 - eps), 0.0), 1.0)


@njit(cache=True, error_model="numpy")
def softmax_inverse_row(x, out):
    """softmax(1 / x) (eq. 5's weighting of inertias), numerically stable."""
    m = -np.inf
    for k in range(x.shape[0]):
        m = max(m, 1.0 / x[k])
    s = 0.0
    for k in range(x.shape[0]):
        out[k] = math.exp(1.0 / x[k] - m)
        s += out[k]
    for k in range(x.shape[0]):
        out[k] /= s


@njit(cache=True, error_model="numpy")
def task_space_diag_row(M, J, out):
    """diag(Lambda), Lambda = (J M^-1 J^T)^-1, the end-effector's translational inertia (kg).

    Returns False (and leaves out untouched) if M is not positive definite.
    """
    n = M.shape[0]
    L = np.zeros((n, n))
    for j in range(n):  # Cholesky M = L L^T
        s = M[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return False
        L[j, j] = math.sqrt(s)
        for i in range(j + 1, n):
            t = M[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / L[j, j]
    X = np.empty((n, 3))  # M^-1 J^T by two triangular solves
    for c in range(3):
        for i in range(n):
            t = J[c, i]
            for k in range(i):
                t -= L[i, k] * X[k, c]
            X[i, c] = t / L[i, i]
        for i in range(n - 1, -1, -1):
            t = X[i, c]
            for k in range(i + 1, n):
                t -= L[k, i] * X[k, c]
            X[i, c] = t / L[i, i]
    a = np.empty((3, 3))
    inv = np.empty((3, 3))
    _j_times(J, X, a)
    det = _sym3_inverse(a, inv)
    if not det > 0.0:
        return False
    for k in range(3):
        out[k] = inv[k, k]
    return True


@njit(cache=True, error_model="numpy")
def el_gate_row(a_raw, a_phys, row, o, n, pos, p, flags, a_out, w, diag):
    """Branch B for one env reading its packed state row; 0 if it ran, 1 if M is not usable, 2 if
    dt is not a positive finite number (then a_out and w are untouched).

    o: offsets [dt, qdot, M, bias, tau, J_pos] into row; p: [metres_per_unit, damping, eps, r0];
    flags: [el_mode (SOFT/GATED), weighting (JOINT_DIAG/TASK_SPACE)];
    diag (2,) receives [|r_EL| (N m), work-energy residual (W)].
    """
    dt = row[o[0]]
    if not (dt > 0.0 and dt < np.inf):
        return 2
    qdot = row[o[1] : o[1] + n]
    M = row[o[2] : o[2] + n * n].reshape((n, n))
    bias = row[o[3] : o[3] + n]
    tau = row[o[4] : o[4] + n]
    J = row[o[5] : o[5] + 3 * n].reshape((3, n))
    v = np.empty(3)
    for k in range(3):
        v[k] = a_phys[pos[k]] * p[0] / dt  # action units -> m/s
    qdd = np.empty(n)
    r = np.empty(n)
    qddot_row(J, qdot, v, dt, p[1], qdd)
    residual_row(M, qdd, bias, tau, r)
    rn = 0.0
    power = 0.0
    for k in range(n):
        rn += r[k] * r[k]
        power += qdot[k] * r[k]  # = qdot^T M qddot + 1/2 qdot^T Mdot qdot + qdot^T G - qdot^T tau
    rn = math.sqrt(rn)
    diag[0] = rn
    diag[1] = abs(power)
    g = rho(rn, p[2], p[3]) if flags[0] == GATED else 1.0  # eq. 5
    for k in range(a_raw.shape[0]):
        w[k] = 0.0
        a_out[k] = a_phys[k]
    if flags[1] == JOINT_DIAG:
        d = np.empty(n)
        for k in range(n):
            d[k] = M[k, k]
            if not d[k] > 0.0:
                return 1
        softmax_inverse_row(d, w)
        for k in range(n):
            w[k] *= g
            a_out[k] = w[k] * a_phys[k] + (1.0 - w[k]) * a_raw[k]  # eq. 6
    else:
        lam = np.empty(3)
        if not task_space_diag_row(M, J, lam):
            return 1
        ws = np.empty(3)
        softmax_inverse_row(lam, ws)
        for k in range(3):
            w[pos[k]] = g * ws[k]
            a_out[pos[k]] = w[pos[k]] * a_phys[pos[k]] + (1.0 - w[pos[k]]) * a_raw[pos[k]]
    return 0


# ---------------------------------------------------------------- batched functions (B envs)
@njit(cache=True, error_model="numpy")
def proposed_qddot(J_pos, qdot, v_des, dt, damping):
    """(B, n) joint accelerations implied by end-effector velocities v_des (B, 3) in m/s."""
    out = np.empty_like(qdot)
    for i in range(qdot.shape[0]):
        qddot_row(J_pos[i], qdot[i], v_des[i], dt[i], damping, out[i])
    return out


@njit(cache=True, error_model="numpy")
def el_residual(M, qddot, bias, tau):
    """r_EL = M qddot + bias - tau, (B, n) in N m  (eq. 4)."""
    out = np.empty_like(qddot)
    for i in range(qddot.shape[0]):
        residual_row(M[i], qddot[i], bias[i], tau[i], out[i])
    return out


def gate(r_norm: np.ndarray, eps: float, r0: float) -> np.ndarray:
    """rho(r) for (B,) residual norms (eq. 5)."""
    return np.array([rho(float(r), eps, r0) for r in np.atleast_1d(r_norm)])


@njit(cache=True, error_model="numpy")
def joint_diag_weights(M):
    """softmax(1 / diag(M)) over the arm joints, (B, n)  (eq. 5)."""
    b, n = M.shape[0], M.shape[1]
    out = np.empty((b, n))
    for i in range(b):
        softmax_inverse_row(np.diag(M[i]).copy(), out[i])
    return out


@njit(cache=True, error_model="numpy")
def task_space_weights(M, J_pos):
    """softmax(1 / diag(Lambda)) over x, y, z with Lambda = (J M^-1 J^T)^-1, (B, 3).

    As in the paper's joint weighting, the axis with the smaller effective mass gets the larger weight.
    """
    out = np.empty((M.shape[0], 3))
    lam = np.empty(3)
    for i in range(M.shape[0]):
        task_space_diag_row(M[i], J_pos[i], lam)
        softmax_inverse_row(lam, out[i])
    return out


@njit(cache=True, error_model="numpy")
def el_gate(a_raw, a_phys, flat, o, n, pos, p, flags, status, singular, invalid_dt):
    """Branch B over B envs; runs where status == 0, sets status = singular where M is unusable
    and invalid_dt where dt is not positive and finite.

    Returns (a_B (B, A), weights (B, A), diag (B, 2) [|r_EL| N m, r_energy W]).
    """
    b = a_raw.shape[0]
    out = a_phys.copy()
    w = np.zeros_like(a_raw)
    diag = np.full((b, 2), np.nan)
    for i in range(b):
        if status[i] == 0:
            code = el_gate_row(a_raw[i], a_phys[i], flat[i], o, n, pos, p, flags, out[i], w[i], diag[i])
            if code == 1:
                status[i] = singular
            elif code == 2:
                status[i] = invalid_dt
    return out, w, diag


class ELGate:
    """Branch B: blends Branch A's candidate with the raw action, weighted by inertia and residual.

    Attributes:
        cfg: corrector configuration (el_mode, weighting, eps_nm, r0_nm, dls_damping).
    """

    def __init__(self, cfg: PhysVLAConfig):
        self.cfg = cfg
        self.layout = cfg.action_layout
        self.pos = self.layout.pos_index
        self.params = np.array([self.layout.metres_per_unit, cfg.dls_damping, cfg.eps_nm, cfg.r0_nm])
        self.flags = np.array(
            [GATED if cfg.el_mode == "gated" else SOFT, TASK_SPACE if cfg.weighting == "task_space" else JOINT_DIAG],
            dtype=np.int64,
        )
        self._offsets: dict[int, np.ndarray] = {}

    def offsets(self, n: int) -> np.ndarray:
        if n not in self._offsets:
            f = field_offsets(n)
            self._offsets[n] = np.array([f[k] for k in ("dt", "qdot", "M", "bias", "tau", "J_pos")], dtype=np.int64)
        return self._offsets[n]

    def check_arm(self, n: int) -> None:
        if self.cfg.weighting == "joint_diag" and n != self.layout.dim:
            raise ValueError(
                f"physvla: weighting='joint_diag' applies {n} joint weights to {self.layout.dim} "
                "action entries; use weighting='task_space' for this arm/layout"
            )

    def residual(self, a_pos_units: np.ndarray, state) -> tuple[np.ndarray, np.ndarray]:
        """r_EL (B, n) in N m and qddot (B, n) of the motion proposed by the position channels."""
        v_des = a_pos_units * (self.layout.metres_per_unit / state.dt[:, None])  # m/s
        qddot = proposed_qddot(state.J_pos, state.qdot, v_des, state.dt, self.cfg.dls_damping)
        return el_residual(state.M, qddot, state.bias, state.tau), qddot

    def __call__(self, a_raw: np.ndarray, a_phys: np.ndarray, state):
        """(a_B, |r_EL| (B,) N m, r_energy (B,) W, weights (B, A), ok (B,) False where M is unusable)."""
        n = state.n_joints
        self.check_arm(n)
        status = np.zeros(a_raw.shape[0], np.int8)
        a, w, diag = el_gate(a_raw, a_phys, state.pack(), self.offsets(n), n, self.pos, self.params, self.flags, status, 1, 2)
        return a, diag[:, 0], diag[:, 1], w, status == 0


_MOVED_TO_SOURCES = ("MujocoDynamicsOracle", "pack_live_row", "pack_live_buf", "arm_mass_block")


def __getattr__(name: str):
    """The MuJoCo oracle moved to lerobot_physvla.sources.mujoco (the state sources' package); its old
    import path here keeps working, with a FutureWarning naming the new one."""
    if name in _MOVED_TO_SOURCES:
        import importlib
        import warnings

        warnings.warn(f"lerobot_physvla.core.dynamics.{name} moved to lerobot_physvla.sources.mujoco; import it "
                      "from there", FutureWarning, stacklevel=2)
        return getattr(importlib.import_module("lerobot_physvla.sources.mujoco"), name)
    raise AttributeError(f"module 'lerobot_physvla.core.dynamics' has no attribute {name!r}")
