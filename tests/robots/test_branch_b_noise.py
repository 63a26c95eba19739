"""Branch B on the simulated arms with the reading noise the paper cites (~1 deg/s of velocity noise
at 30 Hz: 0.024 deg on each joint reading), through the robot step lerobot-rollout runs: where the
residual stands above the noise the guard lets Branch B run and the residual stays close to the
noise-free one; where noise dominates (holding still, fine motions) it is off, counted; the velocity
filter lowers the residual's noise floor, so Branch B can run on more ticks.

The robot executes the policy's targets (not the corrected ones), so the noisy and the noise-free
runs move the arm identically and their residuals compare tick by tick."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from lerobot.processor import RobotProcessorPipeline
from lerobot.processor.converters import robot_action_observation_to_transition, transition_to_robot_action

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep
from lerobot_physvla.robots.physvla_sim_panda import SimPanda, SimPandaConfig
from lerobot_physvla.robots.physvla_sim_so101 import SimSO101, SimSO101Config

NOISE_DEG = 0.024
WARM = 30  # ticks before the reading-noise estimate and the velocity filter settle


def _run(tmp_path, arm, noise, amp_deg, cutoff=5.0, snr_min=3.0, ticks=150, seed=0, quiet=True):
    """|r_EL| per tick (NaN where Branch B was off) and the step, for a joint sweep of amp_deg."""
    robot_cls, cfg_cls = {"panda": (SimPanda, SimPandaConfig), "so101": (SimSO101, SimSO101Config)}[arm]
    robot = robot_cls(cfg_cls(joint_noise_deg=noise, seed=seed, calibration_dir=tmp_path))
    robot.connect()
    spec = robot.spec
    q0 = np.asarray(getattr(robot.config, "start_q", np.zeros(len(spec.joints))))
    step = PhysVLARobotActionStep(arm=arm, object_xyz=[0.5, 0.3, 0.0], target_xyz=[0.5, -0.2, 0.0],
                                  config=PhysVLAConfig.paper(mode="phys_el").to_dict(), velocity_cutoff_hz=cutoff,
                                  noise_snr_min=snr_min)
    proc = RobotProcessorPipeline(steps=[step], to_transition=robot_action_observation_to_transition,
                                  to_output=transition_to_robot_action)
    r = []
    for t in range(ticks):
        q = q0 + np.deg2rad(amp_deg) * np.sin(2 * np.pi * t / 90 + np.arange(len(q0))) / spec.to_radians
        action = {**{f"{m}.pos": float(v) for m, v in zip(spec.motors, q)}, "gripper.pos": 100.0}
        with warnings.catch_warnings():
            if quiet:
                warnings.simplefilter("ignore")
            proc((dict(action), robot.get_observation()))
        r.append(step.corrector.last.r_el[0])
        robot.send_action(action)
    return np.array(r[WARM:]), step


def test_holding_still_branch_b_is_off_and_says_why(tmp_path):
    r, step = _run(tmp_path, "panda", NOISE_DEG, 0.0)
    assert np.isnan(r).mean() > 0.9
    assert step.branch_b_off["noise_dominated"] > 0.9 * len(r) and step.branch_b_off["noise_unknown"] > 0
    with pytest.warns(RuntimeWarning, match="Branch B off"):
        _run(tmp_path, "panda", NOISE_DEG, 0.0, ticks=12, quiet=False)


def test_moving_branch_b_runs_and_its_residual_stays_near_the_noise_free_one(tmp_path):
    clean, _ = _run(tmp_path, "panda", 0.0, 5.0, snr_min=0.0)
    noisy, step = _run(tmp_path, "panda", NOISE_DEG, 5.0)
    assert not np.isnan(noisy).any() and step.branch_b_off["noise_dominated"] == 0
    assert np.median(np.abs(noisy - clean) / clean) < 0.06  # measured ~0.03
    so101, step = _run(tmp_path, "so101", NOISE_DEG, 20.0)  # its residual is ~50x the noise (servo sag)
    assert not np.isnan(so101).any() and step.branch_b_off["noise_dominated"] == 0


def test_the_velocity_filter_lowers_the_noise_floor_so_branch_b_runs_on_more_ticks(tmp_path):
    floor = {c: np.median(_run(tmp_path, "panda", NOISE_DEG, 0.0, cutoff=c, snr_min=0.0)[0]) for c in (5.0, None)}
    assert floor[5.0] < 0.75 * floor[None]  # measured 2.6 vs 3.8 N m
    clean, _ = _run(tmp_path, "panda", 0.0, 1.0, snr_min=0.0)
    on, err = {}, {}
    for c in (5.0, None):  # a fine motion: 1 degree of sweep
        r, _ = _run(tmp_path, "panda", NOISE_DEG, 1.0, cutoff=c)
        ran = ~np.isnan(r)
        on[c], err[c] = ran.mean(), np.median(np.abs(r[ran] - clean[ran]) / clean[ran])
    assert on[5.0] > on[None] + 0.1  # measured ~0.7 vs ~0.45
    assert err[5.0] < 0.2  # where it runs, within 20 % of the noise-free residual (measured ~0.13)
