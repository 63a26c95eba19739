"""MetaWorld (Sawyer, mocap) as a PhysVLA scene: state-only, seeded, MetaWorld's own horizon and success.

Scenes `metaworld/<k>`, k an index into TASKS, the tasks the corrector models (sources/metaworld.py MODELLED), in
this fixed order (a study block's `tasks = [0, 5]` is all six):

    0 pick-place-v3   1 pick-place-wall-v3   2 bin-picking-v3   3 shelf-place-v3   4 basketball-v3
    5 pick-out-of-hole-v3

Scenes `metaworld/6` .. `metaworld/49` are the other 44 MetaWorld v3 tasks (PASS_THROUGH, sorted by name): the
corrector does not model them, so their state rows are marked unsupported_goal (valid = -1, with the hand and the
control period read) and every action passes through; MetaWorld's own scripted policy of each runs on them (the
`metaworld` teacher), which makes the 50 tasks a harm suite (eval/studies/metaworld50.toml).

The env is built the way lerobot's `MetaworldEnv` builds it (`metaworld.MT1(task, seed=42)`, its train task 0,
then `_freeze_rand_vec = False`, `seeded_rand_vec = True`), with no renderer. `reset(seed)` does what
`MetaworldEnv.reset(seed=seed)` does to the simulation: `env.seed(seed)` (the env's `np_random`, from which
MetaWorld draws the object's and the goal's positions: `_get_state_rand_vec`), then `env.reset()`. So a seed fixes
the object and the goal, different seeds draw others, and seed s here is the scene `lerobot-eval
--env.type=metaworld_physvla` starts from with seed s.

Horizon: MetaWorld's 500 control steps (`max_path_length`; stepping past it raises), what `--env.type=metaworld`
runs. Success: MetaWorld's own `info["success"]` of the step; the episode stops at the first success (lerobot's
MetaworldEnv terminates there too). The state is read by `MetaworldStateSource`; `policy_observation` is what a
state policy sees under `--env.type=metaworld_physvla --env.cameras=false --env.obs_type=pixels_agent_pos`.
The corrector's configuration for these scenes needs the `metaworld` layout and task-space weighting (a study:
`[scene_overrides] metaworld = {layout = "metaworld", weighting = "task_space"}`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from lerobot_physvla.core.config import LAYOUTS
from lerobot_physvla.core.state import UNSUPPORTED_GOAL_VALID, PhysState
from lerobot_physvla.sources.metaworld import UNSUPPORTED

TASKS: tuple[str, ...] = ("pick-place-v3", "pick-place-wall-v3", "bin-picking-v3", "shelf-place-v3", "basketball-v3",
                          "pick-out-of-hole-v3")
# lerobot's task descriptions (lerobot/envs/metaworld_config.json TASK_DESCRIPTIONS; a test compares): what
# lerobot-eval gives a language-conditioned policy. Copied, since a simulator here never imports lerobot.
DESCRIPTIONS: dict[str, str] = {
    "pick-place-v3": "Pick and place a puck to a goal",
    "pick-place-wall-v3": "Pick a puck, bypass a wall and place the puck",
    "bin-picking-v3": "Grasp the puck from one bin and place it into another bin",
    "shelf-place-v3": "Pick and place a puck onto a shelf",
    "basketball-v3": "Dunk the basketball into the basket",
    "pick-out-of-hole-v3": "Pick up a puck from a hole",
}
# the 44 tasks the corrector does not model, sorted by name: scenes metaworld/6 .. metaworld/49 (module docstring)
PASS_THROUGH: tuple[str, ...] = tuple(sorted(UNSUPPORTED))
ALL_TASKS: tuple[str, ...] = TASKS + PASS_THROUGH
HORIZON = 500  # SawyerXYZEnv.max_path_length
MT1_SEED = 42  # lerobot's MetaworldEnv: metaworld.MT1(task, seed=42), train task 0


def task_name(index: int) -> str:
    """The MetaWorld task of scene index `index` (TASKS); a clear ValueError for another index."""
    if not isinstance(index, (int, np.integer)) or not 0 <= index < len(ALL_TASKS):
        listed = ", ".join(f"{k} {t}" for k, t in enumerate(TASKS))
        raise ValueError(f"physvla: no MetaWorld scene index {index!r}; the scenes are metaworld/<k> with k one of: "
                         f"{listed} (the tasks the corrector models), or 6-{len(ALL_TASKS) - 1} (the other MetaWorld "
                         "tasks, sorted by name, whose actions pass through)")
    return ALL_TASKS[int(index)]


@dataclass(frozen=True)
class MetaworldTask:
    """A scene's task: its index (TASKS), MetaWorld name and (lerobot's) instruction."""

    index: int
    name: str

    @property
    def modelled(self) -> bool:
        """The corrector models this task (TASKS); else its actions pass through (PASS_THROUGH)."""
        return self.name in TASKS

    @property
    def language(self) -> str:
        """lerobot's task description, what lerobot-eval gives a language-conditioned policy (the task's name for
        a pass-through task)."""
        return DESCRIPTIONS.get(self.name, self.name)


def make_metaworld_env(task: str):
    """metaworld's SawyerXYZEnv of `task` as lerobot's MetaworldEnv builds it, without a renderer, its resets
    seeded (`env.seed(s)` then `env.reset()`)."""
    import metaworld

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mt1 = metaworld.MT1(task, seed=MT1_SEED)
        env = mt1.train_classes[task](render_mode=None)
        env.set_task(mt1.train_tasks[0])
        env.reset()
    env._freeze_rand_vec = False  # randomise the object and the goal at every reset ...
    env.seeded_rand_vec = True  # ... from the env's np_random, which env.seed(s) seeds
    return env


class MetaworldScene:
    """One modelled MetaWorld task under the `Scene` protocol (scenes.py; module docstring).

    Attributes:
        name: "metaworld/<k>".
        task: MetaworldTask (index, name, language).
        env: metaworld's SawyerXYZEnv.
        source: its MetaworldStateSource.
        raw_obs: MetaWorld's latest 39-D observation (hand xyz, finger opening, object pose(s), the previous frame's
            18, the goal): what its scripted policies read (the `metaworld` teacher, sim/metaworld_expert.py).
        info: MetaWorld's info of the last step.
        teacher: the scripted backbone ExpertBackbone runs here unless a study names another.
    """

    layout = LAYOUTS["metaworld"]
    horizon = HORIZON
    stop_on_success = True
    expert: dict = {}  # no geometry of the bowl expert: the teacher is MetaWorld's own policy
    teacher = "metaworld"

    def __init__(self, index: int = 0):
        from lerobot_physvla.sources.metaworld import MetaworldStateSource

        self.task = MetaworldTask(int(index), task_name(index))
        self.name = f"metaworld/{self.task.index}"
        self.env = make_metaworld_env(self.task.name)
        self.source = MetaworldStateSource(self.env, self.task.name) if self.task.modelled else None
        self.raw_obs = np.zeros(39)
        self.info: dict = {}
        self.reset(0)

    def reset(self, seed: int) -> None:
        self.env.seed(int(seed))
        obs, _ = self.env.reset()
        self.raw_obs = np.asarray(obs, dtype=np.float64)
        self.info = {}
        self._step = 0
        if self.source is not None:
            self.source.reset()

    def read(self) -> PhysState:
        if self.source is not None:
            return self.source.read()
        return self._pass_through()

    def _pass_through(self) -> PhysState:
        """The row of a task outside the model: unsupported_goal (valid -1), the hand and the control period read
        (the metrics' trajectory), the rest empty: the corrector passes every action through."""
        st = PhysState.empty(1, 7)
        st.valid[0], st.episode_step[0], st.dt[0] = UNSUPPORTED_GOAL_VALID, self._step, float(self.env.dt)
        st.eef_pos[0] = np.asarray(self.env.tcp_center, dtype=np.float64)
        return st

    def step(self, action: np.ndarray) -> tuple[bool, float]:
        obs, reward, _, _, self.info = self.env.step(np.asarray(action, dtype=np.float64))
        self.raw_obs = np.asarray(obs, dtype=np.float64)
        self._step += 1
        if self.source is not None:
            self.source.step()
        return bool(self.info.get("success", False)), float(reward)

    def policy_observation(self, state: PhysState) -> dict[str, np.ndarray]:
        """What a state-based LeRobot policy sees under `lerobot-eval --env.type=metaworld_physvla
        --env.cameras=false` (obs_type pixels_agent_pos): observation.state = MetaWorld's agent_pos (hand xyz,
        finger opening: the observation's first 4) and observation.environment_state = object xyz, target xyz
        (6, from the state), float32."""
        env_state = np.concatenate([state.obj_pos[0], state.target_pos[0]])
        return {"observation.state": self.raw_obs[:4].astype(np.float32),
                "observation.environment_state": env_state.astype(np.float32)}


def scene_index(name: str) -> int:
    """k of a scene name "metaworld/<k>"; ValueError naming the scenes otherwise."""
    _, _, k = name.partition("/")
    if not name.startswith("metaworld/") or not k.isdigit():
        raise ValueError(f"physvla: MetaWorld scenes are named metaworld/<k>, k in 0-{len(ALL_TASKS) - 1} "
                         f"({', '.join(f'{i} {t}' for i, t in enumerate(TASKS))}); got {name!r}")
    task_name(int(k))
    return int(k)
