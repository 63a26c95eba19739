"""Branch B off when sensor noise dominates its residual (the paper: noisy joint velocities block
Branch B on hardware).

On a robot, r_EL (eq. 4) is the residual of the motion a joint-target action proposes (see
joint_state.py: tau is taken as the bias torque), r = M qddot with
    qddot = (J^+ (FK(q_target) - FK(q)) / dt - qdot) / dt          (dynamics.qddot_row)
Noise dq on the joint readings moves FK(q) by J dq, hence qddot by -P dq / dt^2 with
P = J^T (J J^T + lambda^2 I)^-1 J, and noise dqdot on the velocity estimate moves it by
-dqdot / dt. Taking the two as independent, the residual's noise has std
    sigma_r^2 = ||M P diag(sigma_q)||_F^2 / dt^4 + ||M diag(sigma_qdot)||_F^2 / dt^2   (N m)^2.
The guard lets Branch B run on a tick only when the median of |r_EL| / sigma_r over the last
`window` ticks is at least snr_min; otherwise the residual says more about the sensors than about
the motion, and Branch B is off for that tick. (The median, because a threshold on one noisy tick
lets through exactly the ticks whose noise happened to inflate |r_EL|.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lerobot_physvla.core.dynamics import qddot_row, residual_row

NOISE_UNKNOWN = "noise_unknown"  # the reading noise is not estimated yet (first readings)
NOISE_DOMINATED = "noise_dominated"  # |r_EL| < snr_min * sigma_r


def residual_noise_std(M: np.ndarray, J: np.ndarray, sigma_q: np.ndarray, sigma_qdot: np.ndarray, dt: float,
                       damping: float) -> float:
    """sigma_r, N m: the std of |r_EL|'s noise from reading noise sigma_q (rad) and velocity noise
    sigma_qdot (rad/s) per joint (module docstring); M (n, n) kg m^2, J (3, n) m/rad, dt s."""
    P = J.T @ np.linalg.solve(J @ J.T + damping * damping * np.eye(3), J)
    a = (M @ P) * sigma_q[None, :]
    b = M * sigma_qdot[None, :]
    return math.sqrt(float(np.sum(a * a)) / dt**4 + float(np.sum(b * b)) / dt**2)


def proposed_residual(M: np.ndarray, J: np.ndarray, qdot: np.ndarray, bias: np.ndarray, tau: np.ndarray,
                      v: np.ndarray, dt: float, damping: float) -> float:
    """|r_EL|, N m, of an end-effector velocity v (m/s) proposed over one tick of dt s (eq. 4)."""
    n = qdot.shape[0]
    qdd, r = np.empty(n), np.empty(n)
    qddot_row(J, qdot, v, dt, damping, qdd)
    residual_row(M, qdd, bias, tau, r)
    return float(np.sqrt(r @ r))


@dataclass
class BranchBNoiseGuard:
    """Decides, per tick, whether Branch B's residual stands above the sensors' noise.

    Attributes:
        snr_min: Branch B runs when the median |r_EL| / sigma_r of the last `window` ticks is >= snr_min.
        window: ticks in that median (the current one included).
        last_snr: that median at the latest tick (NaN before, or while the noise is unknown).
    """

    snr_min: float = 3.0
    window: int = 5
    last_snr: float = float("nan")

    def __post_init__(self) -> None:
        self._snr = np.full(max(1, int(self.window)), np.nan)
        self._i = 0

    def warm_up(self, n: int) -> None:
        """Run every kernel once for an arm of n joints (so no compilation or cache load falls inside
        a control tick) and forget it."""
        M, J = np.eye(n), np.zeros((3, n))
        J[:, :3] = np.eye(3)
        z = np.zeros(n)
        self.check(M, J, z, z, z, np.zeros(3), 0.05, 1e-2, np.full(n, 1e-3), np.full(n, 1e-2))
        self.reset()

    def reset(self) -> None:
        """An episode starts: forget the past ticks' ratios."""
        self._snr[:] = np.nan
        self._i = 0

    def check(self, M, J, qdot, bias, tau, v, dt, damping, sigma_q, sigma_qdot) -> str | None:
        """None if Branch B may run this tick, else the reason it may not (NOISE_UNKNOWN,
        NOISE_DOMINATED). Arguments as `residual_noise_std` and `proposed_residual`."""
        self.last_snr = float("nan")
        if not (np.isfinite(sigma_q).all() and np.isfinite(sigma_qdot).all()):
            return NOISE_UNKNOWN
        r = proposed_residual(M, J, qdot, bias, tau, v, dt, damping)
        s = residual_noise_std(M, J, sigma_q, sigma_qdot, dt, damping)
        self._snr[self._i % self._snr.shape[0]] = r / s if s > 0 else np.inf
        self._i += 1
        seen = self._snr[: min(self._i, self._snr.shape[0])]
        self.last_snr = float(np.median(seen))
        return None if self.last_snr >= self.snr_min else NOISE_DOMINATED
