"""The SO-101 engine of the harness (scene "so101_pick_place"): a scripted pick-and-place expert
(lerobot-env-so101's controller, joint targets) on the simulated SO-101 robot, its actions either sent
as they are or through lerobot's robot action processor with `PhysVLARobotActionStep`.

Each episode: the block and the goal drawn in lerobot-env-so101's pick-and-place sampling box
(0.15-0.30 m x -0.1-0.1 m, at least 0.08 m apart) from the episode's seed; the robot
(`physvla_sim_so101`, 10 Hz, the rate the controller was written for) runs the expert's joint
targets for at most 200 ticks (the step: the configuration, the block from the robot's `block.*`
readings, the goal as a fixed target). Success is lerobot-env-so101's: the block was carried (rose
above 5 cm), rests within 3 cm of the goal, and the gripper is open. Jerk: of the end-effector
(m/s^3, from the joint readings through the arm model). The study is eval/studies/so101_faults.toml.
"""

from __future__ import annotations

import tempfile
import time
import warnings
from dataclasses import asdict
from pathlib import Path

import numpy as np
from lerobot.processor import RobotProcessorPipeline
from lerobot.processor.converters import robot_action_observation_to_transition, transition_to_robot_action

from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep
from lerobot_physvla.robots.physvla_sim_so101 import SimSO101, SimSO101Config
from lerobot_physvla.arms.model import ArmModel
from lerobot_physvla.sim.so101_expert import ARM, CONTROL_HZ, SO101ExpertConfig, SO101PickPlaceExpert

BOX = (np.array([0.15, -0.1]), np.array([0.3, 0.1]))  # lerobot-env-so101's pick-and-place sampling box
TICKS = 200


def draw(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    block = rng.uniform(*BOX)
    goal = rng.uniform(*BOX)
    while np.linalg.norm(goal - block) < 0.08:
        goal = rng.uniform(*BOX)
    return np.append(block, 0.02), np.append(goal, 0.02)


def episode(seed: int, faults: dict, corrected: dict | None, arm: ArmModel, calib: Path) -> dict:
    """One episode of the expert with `faults` (SO101ExpertConfig fields); corrected: None (uncorrected) or
    the configuration (PhysVLAConfig.to_dict()) the step applies."""
    block, goal = draw(seed)
    robot = SimSO101(SimSO101Config(fps=CONTROL_HZ, block_xyz=list(block), calibration_dir=calib))
    robot.connect()
    expert = SO101PickPlaceExpert(goal, SO101ExpertConfig(**{**faults, "seed": seed}))
    proc = step = None
    if corrected:
        step = PhysVLARobotActionStep(arm="so101", fps=CONTROL_HZ, object_key="block", target_xyz=list(goal),
                                      config=corrected)
        proc = RobotProcessorPipeline(steps=[step], to_transition=robot_action_observation_to_transition,
                                      to_output=transition_to_robot_action)
    top, eef = 0.0, []
    for _ in range(TICKS):
        obs = robot.get_observation()
        top = max(top, obs["block.z"])
        eef.append(arm.eef_at(np.deg2rad([obs[f"{j}.pos"] for j in ARM])))
        action = expert(obs)
        robot.send_action(proc((action, obs)) if proc else action)
        if expert.phase.name == "DONE":
            break
    for _ in range(5):  # let the block settle
        robot.send_action(robot.last_action)
    obs = robot.get_observation()
    off = float(np.hypot(obs["block.x"] - goal[0], obs["block.y"] - goal[1]))
    jerk = np.diff(np.asarray(eef), n=3, axis=0) * CONTROL_HZ**3
    return {"seed": seed, "off_m": off,
            "success": bool(top > 0.05 and off < 0.03 and obs["gripper.pos"] > 50),
            "mean_jerk": float(np.mean(np.linalg.norm(jerk, axis=1))) if len(jerk) else float("nan"),
            "passthrough": dict(step.passthrough_counts) if step else {}}


def compute_unit(unit) -> dict:
    """A harness unit on the SO-101 (scene "so101_pick_place"): the expert with `unit.expert`'s faults,
    uncorrected when the configuration's mode is baseline, else through the step with that configuration."""
    arm, calib = ArmModel("so101"), Path(tempfile.mkdtemp())
    corrected = None if unit.config.get("mode") == "baseline" else unit.config
    t0 = time.time()
    records = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k in range(unit.episodes):
            rec = episode(unit.first_seed + k, unit.expert, corrected, arm, calib)
            rec.update(backbone=unit.backbone, config=unit.config_name, task_id=unit.task_id, scene=unit.scene)
            records.append(rec)
    return {"unit": asdict(unit), "seconds": time.time() - t0, "records": records}
