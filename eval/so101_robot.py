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
With perception faults (a configuration's `perception`), the step reads the block and the goal as a
perception step would report them (sources/perception.py; observation keys `seen_block.*`, `seen_goal.*`
and `pose_age`), the expert the robot's own readings.
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

from lerobot_physvla.core.state import PhysState
from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep
from lerobot_physvla.sources.perception import Perception, PerceptionConfig
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


def episode(seed: int, faults: dict, corrected: dict | None, arm: ArmModel, calib: Path,
            perception: PerceptionConfig | None = None) -> dict:
    """One episode of the expert with `faults` (SO101ExpertConfig fields); corrected: None (uncorrected) or
    the configuration (PhysVLAConfig.to_dict()) the step applies; perception: faults on the poses it reads."""
    block, goal = draw(seed)
    robot = SimSO101(SimSO101Config(fps=CONTROL_HZ, block_xyz=list(block), calibration_dir=calib))
    robot.connect()
    expert = SO101PickPlaceExpert(goal, SO101ExpertConfig(**{**faults, "seed": seed}))
    proc = step = seen = None
    if corrected and perception is not None and not perception.exact:
        seen = Perception(perception)
        seen.reset(seed=seed)
        step = PhysVLARobotActionStep(arm="so101", fps=CONTROL_HZ, object_key="seen_block", target_key="seen_goal",
                                      pose_age_key="pose_age", config=corrected)
    elif corrected:
        step = PhysVLARobotActionStep(arm="so101", fps=CONTROL_HZ, object_key="block", target_xyz=list(goal),
                                      config=corrected)
    if step is not None:
        proc = RobotProcessorPipeline(steps=[step], to_transition=robot_action_observation_to_transition,
                                      to_output=transition_to_robot_action)
    top, eef = 0.0, []
    for _ in range(TICKS):
        obs = robot.get_observation()
        top = max(top, obs["block.z"])
        eef.append(arm.eef_at(np.deg2rad([obs[f"{j}.pos"] for j in ARM])))
        action = expert(obs)
        robot.send_action(proc((action, obs if seen is None else _perceived(obs, goal, seen))) if proc else action)
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
            "passthrough": dict(step.passed_through) if step else {}}


def _perceived(obs: dict, goal: np.ndarray, perception: Perception) -> dict:
    """The robot's observation plus the block and the goal as the perception model reports them."""
    st = PhysState.empty(1, 1)
    st.valid[:], st.episode_step[:] = 1.0, perception.counts["steps"]
    st.obj_pos[:] = [obs["block.x"], obs["block.y"], obs["block.z"]]
    st.target_pos[:] = goal
    out = PhysState.unpack(perception.apply(st.pack()))
    return {**obs, **{f"seen_block.{c}": float(out.obj_pos[0, k]) for k, c in enumerate("xyz")},
            **{f"seen_goal.{c}": float(out.target_pos[0, k]) for k, c in enumerate("xyz")},
            "pose_age": float(out.pose_age[0])}


def compute_unit(unit) -> dict:
    """A harness unit on the SO-101 (scene "so101_pick_place"): the expert with `unit.expert`'s faults,
    uncorrected when the configuration's mode is baseline, else through the step with that configuration."""
    arm, calib = ArmModel("so101"), Path(tempfile.mkdtemp())
    config = dict(unit.config)
    perception = PerceptionConfig.from_dict(config.pop("perception", {}))
    corrected = None if config.get("mode") == "baseline" else config
    t0 = time.time()
    records = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k in range(unit.episodes):
            rec = episode(unit.first_seed + k, unit.expert, corrected, arm, calib, perception)
            rec.update(backbone=unit.backbone, config=unit.config_name, task_id=unit.task_id, scene=unit.scene)
            records.append(rec)
    return {"unit": asdict(unit), "seconds": time.time() - t0, "records": records}
