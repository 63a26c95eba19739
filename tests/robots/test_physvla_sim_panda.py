"""The MuJoCo-simulated Panda behind LeRobot's Robot interface: lerobot builds it from its config,
its servos track joint targets, its gripper opens and closes, and its end-effector is where the
arm model the corrector reads puts it."""

from __future__ import annotations

import mujoco
import numpy as np

from lerobot.robots.utils import make_robot_from_config

from lerobot_physvla.arms.model import EEF_SITE, ArmModel
from lerobot_physvla.robots.physvla_sim_panda import SimPanda, SimPandaConfig

JOINTS = tuple(f"joint{i}" for i in range(1, 8))


def test_lerobot_builds_it_and_its_servos_and_gripper_track_targets(tmp_path):
    robot = make_robot_from_config(SimPandaConfig(calibration_dir=tmp_path))
    assert isinstance(robot, SimPanda)
    robot.connect()
    obs = robot.get_observation()
    np.testing.assert_allclose([obs[f"{j}.pos"] for j in JOINTS], robot.config.start_q)
    target = {f"{j}.pos": obs[f"{j}.pos"] + d for j, d in zip(JOINTS, (0.3, 0.2, -0.2, 0.3, 0.2, -0.3, 0.5))}
    for grip, check in ((100.0, lambda g: g > 95), (0.0, lambda g: g < 5)):
        for _ in range(60):  # 2 s at 30 Hz
            robot.send_action({**target, "gripper.pos": grip})
        obs = robot.get_observation()
        for j in JOINTS:  # rad
            assert abs(obs[f"{j}.pos"] - target[f"{j}.pos"]) < 0.01, (j, obs)
        assert check(obs["gripper.pos"]), obs
    assert robot.steps == 120 and abs(obs["block.z"] - 0.02) < 2e-3


def test_its_end_effector_is_the_arm_models(tmp_path):
    """The corrector computes the end-effector from joint readings with ArmModel('panda'); the
    simulated robot's own end-effector site must be the same point."""
    robot = SimPanda(SimPandaConfig(calibration_dir=tmp_path))
    robot.connect()
    arm = ArmModel("panda")
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = np.asarray(robot.config.start_q) + rng.uniform(-0.4, 0.4, 7)
        robot.data.qpos[robot._qpos] = q
        mujoco.mj_kinematics(robot.model, robot.data)
        np.testing.assert_allclose(arm.eef_at(q), robot.data.site(EEF_SITE).xpos, atol=1e-9)
