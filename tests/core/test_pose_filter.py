"""The pose filter (core/pose_filter.py, pose_noise_m > 0): what it leaves of the noise on a pose at rest and on
an object the hand carries, when it starts afresh, that a look-ahead step leaves it alone, what the corrections
are told, and the release veto it keeps from deciding by the noise."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrections import params
from lerobot_physvla.core.corrections.base import N_GEO, N_MEM, OBJ, POSE_ERROR_M, POSE_NOISE_M, TGT
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.pose_filter import FILTER_GAIN, OUTLIER_STEPS, POSE_OBJ, pose_filter, residual_m
from lerobot_physvla.core.state import PhysState, field_offsets

F = field_offsets(7)
SIGMA = 0.01  # m
REST_Z = 0.9
OPEN, HOLDING = 0.08, 0.012  # the fingers' opening: wide open, stopped on a bowl's rim (m)


def _p(sigma=SIGMA) -> np.ndarray:
    return params(PhysVLAConfig(pose_noise_m=sigma), PhysVLAConfig().action_layout)


def _row(eef, obj, tgt, rest=REST_Z) -> np.ndarray:
    row = np.zeros(max(F.values()) + 10)
    row[F["eef_pos"]:F["eef_pos"] + 3], row[F["obj_pos"]:F["obj_pos"] + 3] = eef, obj
    row[F["target_pos"]:F["target_pos"] + 3], row[F["obj_rest_z"]] = tgt, rest
    return row


def _run(true_obj, true_tgt, eef, fingers, rng, p=None, mem=None, rest=None, sigma=SIGMA):
    """The filtered object and target of each step (T, 3) each, for true poses (T, 3) seen with noise sigma."""
    p = _p(sigma) if p is None else p
    mem = np.zeros(N_MEM) if mem is None else mem
    g, est_o, est_t = np.zeros(N_GEO), [], []
    for k in range(len(true_obj)):
        z_o, z_t = true_obj[k] + rng.normal(0, sigma, 3), true_tgt[k] + rng.normal(0, sigma, 3)
        row = _row(eef[k], z_o, z_t, REST_Z if rest is None else rest[k])
        pose_filter(row, F["eef_pos"], F["obj_pos"], F["obj_rest_z"], F["target_pos"], fingers[k], p, mem, True, g)
        est_o.append(g[OBJ:OBJ + 3].copy())
        est_t.append(g[TGT:TGT + 3].copy())
    return np.array(est_o), np.array(est_t)


def test_a_pose_at_rest_keeps_the_residual_the_corrections_are_told():
    rng = np.random.default_rng(0)
    t = 4000
    obj, tgt = np.tile([0.0, 0.0, REST_Z], (t, 1)), np.tile([0.2, 0.1, REST_Z], (t, 1))
    eef = np.tile([0.1, -0.2, 1.1], (t, 1))  # an open hand away from the object
    est_o, est_t = _run(obj, tgt, eef, np.full(t, OPEN), rng)
    for est, true in ((est_o, obj), (est_t, tgt)):
        sd = (est[100:] - true[100:]).std(axis=0)
        np.testing.assert_allclose(sd, residual_m(SIGMA), rtol=0.2)  # 0.23 sigma per axis, not sigma
    assert residual_m(SIGMA) == pytest.approx(SIGMA * np.sqrt(FILTER_GAIN / (2 - FILTER_GAIN)))


@pytest.mark.parametrize("fingers, lags", [(HOLDING, False), (OPEN, True), (0.001, True)])
def test_an_object_moves_with_the_hand_only_while_the_fingers_hold_it(fingers, lags):
    """Held (the fingers stopped on something): the prediction moves the object with the hand, so a carry 2 cm a
    step leaves no lag; open, or closed on nothing, the object is taken to rest: a carry lags behind it (the outlier
    gate starts it afresh every few steps)."""
    rng = np.random.default_rng(1)
    t = 60
    eef = np.array([[0.0, 0.0, 1.0]] * 20 + [[0.02 * k, 0.0, 1.0 + 0.005 * k] for k in range(1, t - 19)])
    obj = eef + [0.0, 0.047, -0.02]  # a rim grasp: the bowl's centre 4.7 cm off the hand
    tgt = np.tile([0.5, 0.0, REST_Z], (t, 1))
    widest = np.r_[np.full(10, OPEN), np.full(t - 10, fingers)]  # the hand opened wide first, then closed
    est_o, _ = _run(obj, tgt, eef, widest, rng, sigma=0.002)
    err = np.linalg.norm(est_o[-20:] - obj[-20:], axis=1).mean()
    if lags:
        assert err > 0.01  # behind a carry it cannot see
    else:
        assert err < 0.004  # ~ the residual of 2 mm of noise


def test_a_pose_that_jumps_starts_afresh_after_outlier_steps_and_a_new_object_at_once():
    rng = np.random.default_rng(2)
    t = 60
    obj = np.array([[0.0, 0.0, REST_Z]] * 30 + [[0.3, 0.0, REST_Z]] * 30)  # the object slid 30 cm (pushed)
    tgt = np.tile([0.2, 0.1, REST_Z], (t, 1))
    eef = np.tile([0.1, -0.2, 1.1], (t, 1))
    est_o, _ = _run(obj, tgt, eef, np.full(t, OPEN), rng, sigma=0.002)
    assert np.linalg.norm(est_o[29 + OUTLIER_STEPS - 1] - obj[29]) < 0.01  # kept its estimate for the outliers
    assert np.linalg.norm(est_o[30 + OUTLIER_STEPS - 1] - obj[30]) < 0.01  # then started afresh at the pose
    # a new followed object (the resting height changes: a sub-goal switch) starts afresh on its first step
    rest = np.r_[np.full(30, REST_Z), np.full(30, REST_Z + 0.05)]
    obj2 = obj.copy()
    obj2[30:, 2] = REST_Z + 0.05
    est_o, est_t = _run(obj2, tgt, eef, np.full(t, OPEN), np.random.default_rng(3), rest=rest, sigma=0.002)
    assert np.linalg.norm(est_o[30] - obj2[30]) < 0.01


def test_a_look_ahead_step_reads_the_filter_and_leaves_its_memory():
    rng = np.random.default_rng(4)
    mem, p, g = np.zeros(N_MEM), _p(), np.zeros(N_GEO)
    t = 30
    _run(np.tile([0.0, 0.0, REST_Z], (t, 1)), np.tile([0.2, 0.1, REST_Z], (t, 1)), np.tile([0.1, -0.2, 1.1], (t, 1)),
         np.full(t, OPEN), rng, p=p, mem=mem)
    before = mem.copy()
    row = _row([0.1, -0.2, 1.1], [0.05, 0.0, REST_Z], [0.2, 0.1, REST_Z])
    pose_filter(row, F["eef_pos"], F["obj_pos"], F["obj_rest_z"], F["target_pos"], OPEN, p, mem, False, g)
    np.testing.assert_array_equal(mem, before)
    expect = before[POSE_OBJ:POSE_OBJ + 3] + FILTER_GAIN * (row[F["obj_pos"]:F["obj_pos"] + 3]
                                                            - before[POSE_OBJ:POSE_OBJ + 3])
    np.testing.assert_allclose(g[OBJ:OBJ + 3], expect)


def test_the_corrections_are_told_the_bias_and_twice_the_filtered_noise_and_the_setting_is_checked():
    cfg = PhysVLAConfig(pose_error_m=0.01, pose_noise_m=0.02)
    assert cfg.pose_error_told_m == pytest.approx(0.01 + 2 * residual_m(0.02))
    p = params(cfg, cfg.action_layout)
    assert p[POSE_ERROR_M] == pytest.approx(cfg.pose_error_told_m) and p[POSE_NOISE_M] == 0.02
    assert PhysVLAConfig().pose_noise_m == 0.0 and PhysVLAConfig().pose_error_told_m == 0.0
    for bad in (-0.01, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="pose_noise_m"):
            PhysVLAConfig(pose_noise_m=bad)
    d = PhysVLAConfig().to_dict()
    del d["pose_noise_m"], d["version"]  # saved before the field existed (and before versions)
    assert PhysVLAConfig.from_dict(d) == PhysVLAConfig()


def _over_target(k: int, rng, sigma: float) -> PhysState:
    """The bowl held 1 cm off the plate's centre (inside the release tolerance), its pose and the plate's seen
    with noise sigma; the hand still, the fingers closed on the rim."""
    s = PhysState.empty(1, 7)
    s.valid[:], s.dt[:], s.episode_step[:], s.gripper[:] = 1.0, 0.05, k, (OPEN if k == 0 else HOLDING)
    s.eef_pos[:] = [0.2, 0.0, 1.0]
    s.obj_pos[:] = np.array([0.21, 0.0, 0.95]) + rng.normal(0, sigma, 3)
    s.target_pos[:] = np.array([0.2, 0.0, 0.90]) + rng.normal(0, sigma, 3)
    s.obj_rest_z[:] = 0.90
    s.M[:] = np.eye(7)
    s.J_pos[:, :, :3] = np.eye(3)
    return s


@pytest.mark.parametrize("filtered, most_held", [(False, 5), (True, 0)])
def test_a_release_on_target_is_held_back_by_the_noise_only_without_the_filter(filtered, most_held):
    """The traced failure (docs/decisions/22-pose-error.md): told 1 cm of noise as an error bound (2 cm), the
    release veto holds back a release 1 cm from the target's centre on the steps the noise puts it beyond
    2 + 2 cm; told it as noise, the filter leaves it a third of a centimetre and the release goes through."""
    cfg = PhysVLAConfig(pose_noise_m=SIGMA) if filtered else PhysVLAConfig(pose_error_m=2 * SIGMA)
    c = Corrector(cfg.replace(mode="phys", release_assist_m=0.0, lowpass="off"))
    rng = np.random.default_rng(5)
    opens = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0]])
    held = 0
    for k in range(400):
        out = c(opens, _over_target(k, rng, SIGMA))
        if k >= 30 and out[0, 6] > 0.0:  # past the filter's first steps: a release held back (gripper closed)
            held += 1
    assert (held <= most_held) if filtered else (held >= most_held), held
