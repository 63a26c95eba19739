"""The Branch B noise guard: its noise model of r_EL matches a Monte Carlo of reading and velocity
noise through eq. 4, and it turns Branch B off exactly when that noise dominates the residual."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_physvla.core.dynamics import qddot_row, residual_row
from lerobot_physvla.arms.model import ArmModel
from lerobot_physvla.core.noise_guard import (NOISE_DOMINATED, NOISE_UNKNOWN, BranchBNoiseGuard,
                                                residual_noise_std)

DT, DAMP = 1 / 30, 1e-2


def _panda_at(q):
    dyn = ArmModel("panda").dynamics(np.asarray(q, float), np.zeros(7))
    return dyn["M"], dyn["J_pos"], dyn["bias"]


def _r(M, J, qdot, bias, v):
    qdd, r = np.empty(7), np.empty(7)
    qddot_row(J, qdot, v, DT, DAMP, qdd)
    residual_row(M, qdd, bias, bias, r)
    return r


def test_the_residual_noise_model_matches_a_monte_carlo():
    """Reading noise dq moves FK(q) by J dq (so v by -J dq / dt) and the velocity estimate by dqdot:
    E ||r(noisy) - r||^2 must equal sigma_r^2."""
    M, J, bias = _panda_at([0.0, 0.3, 0.0, -2.0, 0.0, 2.3, 0.785])
    rng = np.random.default_rng(0)
    sq, sv = np.full(7, 4e-4), np.linspace(5e-3, 2e-2, 7)  # rad, rad/s
    v, qdot = np.array([0.05, -0.02, 0.01]), np.full(7, 0.1)
    r0 = _r(M, J, qdot, bias, v)
    d2 = [np.sum((_r(M, J, qdot + rng.normal(0, sv), bias, v - J @ rng.normal(0, sq) / DT) - r0) ** 2)
          for _ in range(4000)]
    predicted = residual_noise_std(M, J, sq, sv, DT, DAMP)
    assert np.sqrt(np.mean(d2)) == pytest.approx(predicted, rel=0.05)
    assert residual_noise_std(M, J, 2 * sq, 2 * sv, DT, DAMP) == pytest.approx(2 * predicted)


def test_it_turns_branch_b_off_where_noise_dominates():
    M, J, bias = _panda_at([0.0, 0.3, 0.0, -2.0, 0.0, 2.3, 0.785])
    sq = np.full(7, np.deg2rad(0.024))  # ~1 deg/s of velocity noise at 30 Hz
    sv = sq * np.sqrt(2) / DT
    args = lambda v: (M, J, np.zeros(7), bias, bias, np.asarray(v, float), DT, DAMP)  # noqa: E731
    g = BranchBNoiseGuard(snr_min=3.0, window=1)
    assert g.check(*args([0.0, 0.0, 0.0]), np.full(7, np.nan), sv) == NOISE_UNKNOWN
    assert g.check(*args([0.0, 0.0, 0.0]), sq, sv) == NOISE_DOMINATED and g.last_snr == 0.0  # holding still
    assert g.check(*args([0.3, 0.0, 0.0]), sq, sv) is None and g.last_snr > 3  # 1 cm per tick
    g = BranchBNoiseGuard(snr_min=3.0, window=5)  # the median of 5 ticks: one loud tick does not switch it
    for v in ([0.3, 0, 0], [0.3, 0, 0], [0, 0, 0], [0.3, 0, 0]):
        assert g.check(*args(v), sq, sv) is None
    g.reset()
    assert g.check(*args([0.0, 0.0, 0.0]), sq, sv) == NOISE_DOMINATED
