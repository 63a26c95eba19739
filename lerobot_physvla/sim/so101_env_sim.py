"""lerobot-env-so101's pick-and-place env (`SO101PickPlace-v0`) as a PhysVLA scene: state-only, seeded.

Scene `so101_env`: the env `lerobot-eval --env.type=so101_physvla --env.task=SO101PickPlace-v0
--env.random_block_position=true --env.action_scale=0.025` builds (`SO101PickPlaceGymEnv`), with no renderer:

    random_block_position  true: the block and the goal drawn in the task's sampling box (0.15-0.30 m x -0.1-0.1 m,
                           at least 8 cm apart) from the env's np_random, which `reset(seed)` seeds (the env's
                           `reset(seed=s)`, what lerobot-eval's `seed` does); false puts every episode on one pose
    action_scale           0.025 m per unit, the package's scripted controller's and BC policy's (DEFAULT_ACTION_SCALE)
    horizon                100 control steps at 10 Hz (the env config's episode_length); the episode stops at the
                           env's own success (`succeed`: the block carried 3 cm up, resting within 3 cm of the goal,
                           the jaw open). The env also ends an episode whose block leaves the workspace; the harness
                           runs on to the horizon (the block cannot come back to the goal by itself)

The state is read by `SO101StateSource` (sources/so101.py); `policy_observation` is what a state policy sees under
`lerobot-eval --env.type=so101_physvla` with those flags: observation.state = agent_pos (14: the arm's 5 joint
positions and velocities, the gripper command in [-1, 1], the `gripperframe` site's xyz) and
observation.environment_state = the block's xyz and the goal's xyz (6). The corrector's configuration for this
scene needs the so101 layout at 0.025 m a unit and task-space weighting (a study: `[scene_overrides] so101_env =
{layout = "so101", weighting = "task_space"}`; the layout's scale is this scene's).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from lerobot_physvla.core.config import so101_layout
from lerobot_physvla.core.state import PhysState

TASK = "SO101PickPlace-v0"
ACTION_SCALE = 0.025  # m per unit: lerobot_env_so101.policy.DEFAULT_ACTION_SCALE (a test compares)
HORIZON = 100  # lerobot_env_so101's SO101Env.episode_length


@dataclass(frozen=True)
class SO101Task:
    """The scene's task: lerobot-eval gives an so101 policy no instruction (the empty string)."""

    index: int = 0
    name: str = TASK
    language: str = ""


class SO101EnvScene:
    """`SO101PickPlace-v0` under the `Scene` protocol (scenes.py; module docstring).

    Attributes:
        name: "so101_env".
        task: SO101Task.
        env: the package's SO101PickPlaceGymEnv.
        source: its SO101StateSource.
        raw_obs: the env's latest observation (agent_pos, environment_state).
        teacher: the scripted backbone ExpertBackbone runs here unless a study names another (the package's
            pick-and-place controller, sim/so101_env_expert.py).
    """

    layout = so101_layout(ACTION_SCALE)
    horizon = HORIZON
    stop_on_success = True
    expert: dict = {}
    teacher = "so101"
    name = "so101_env"

    def __init__(self):
        from lerobot_env_so101.pick_place_env import SO101PickPlaceGymEnv

        from lerobot_physvla.sources.so101 import SO101StateSource

        self.task = SO101Task()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self.env = SO101PickPlaceGymEnv(random_block_position=True, action_scale=ACTION_SCALE)
        self.source = SO101StateSource(self.env, TASK)
        self.raw_obs: dict = {}
        self.reset(0)

    def reset(self, seed: int) -> None:
        self.raw_obs, _ = self.env.reset(seed=int(seed))
        self.source.reset()

    def read(self) -> PhysState:
        return self.source.read()

    def step(self, action: np.ndarray) -> tuple[bool, float]:
        self.raw_obs, reward, _, _, info = self.env.step(np.asarray(action, dtype=np.float32))
        self.source.step()
        return bool(info.get("succeed", False)), float(reward)

    def policy_observation(self, state: PhysState | None = None) -> dict[str, np.ndarray]:
        """What a state-based LeRobot policy sees under `lerobot-eval --env.type=so101_physvla` (module
        docstring): observation.state = agent_pos (14), observation.environment_state = block xyz, goal xyz (6)."""
        return {"observation.state": np.asarray(self.raw_obs["agent_pos"], dtype=np.float32),
                "observation.environment_state": np.asarray(self.raw_obs["environment_state"], dtype=np.float32)}
