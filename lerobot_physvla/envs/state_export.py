"""What the env types' state exports share (`libero_physvla`, `metaworld_physvla`, `so101_physvla`).

Each env type wraps one sub-env of lerobot's own env in a `StateExport` (a gym.Wrapper, so it works in the
main process and in async workers) that adds to every observation
    robot_state["physvla_state"]  the packed PhysState of this env (core/state.py), read by its state source
    robot_state["physvla_extra"]  [task_id, is_success, the action executed last step]
which `PhysVLAStateCaptureStep`, first in the env preprocessor, takes out before the policy sees anything.
Where the source is missing or its read raises, the row is one the corrector passes through: valid = 0, or
UNSUPPORTED_GOAL_VALID for a task outside the model (said once per process, counted per episode), with the
episode step and the control period still filled so episodes split where they do. A subclass builds its source
at reset and says its control period (`control_dt`).
"""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from lerobot_physvla.core.state import UNSUPPORTED_GOAL_VALID, field_offsets, packed_size
from lerobot_physvla.processor.physvla_processor import EXTRA_KEY, STATE_KEY
from lerobot_physvla.sources.perception import Perception, PerceptionConfig

_WARNED_GOALS: set[str] = set()  # goals outside the model already said, once per process


class StateExport(gym.Wrapper):
    """Adds one sub-env's physical state to its observations (see module docstring).

    Attributes:
        task_id: the task's id as lerobot-eval numbers it (exported in physvla_extra).
        source: the state source (None: no state; the corrector passes actions through).
        read_failures: state reads (or source builds) that raised; those steps export a row with valid = 0.
        unsupported_goal: the task's goal in words where it is outside what the corrector models; its rows export
            valid = UNSUPPORTED_GOAL_VALID and pass through as unsupported_goal.
        perception: the perception model between the simulator and physvla_state (None: exact poses).
    """

    def __init__(self, env, n_joints: int, action_dim: int, task_id: int = 0,
                 perception: PerceptionConfig | None = None):
        super().__init__(env)
        self.task_id = int(task_id)
        self.perception = None if perception is None or perception.exact else Perception(perception)
        self.source = None
        self.read_failures = 0
        self.unsupported_goal: str | None = None
        self._size = packed_size(n_joints)
        self._f = field_offsets(n_joints)
        self._action_dim = int(action_dim)
        self._steps = 0  # control steps since the last reset: a row with no source still counts them
        self._last_action = np.zeros(self._action_dim)

    def control_dt(self) -> float:
        """The env's control period, s (what a row without a source says)."""
        raise NotImplementedError

    def _state_spaces(self, obs_space: dict) -> spaces.Dict:
        """The observation space with physvla_state and physvla_extra under robot_state."""
        obs_space = dict(obs_space)
        rs = dict(obs_space["robot_state"].spaces) if "robot_state" in obs_space else {}
        rs[STATE_KEY] = spaces.Box(-np.inf, np.inf, (self._size,), np.float64)
        rs[EXTRA_KEY] = spaces.Box(-np.inf, np.inf, (2 + self._action_dim,), np.float64)
        obs_space["robot_state"] = spaces.Dict(rs)
        return spaces.Dict(obs_space)

    def _read_row(self) -> np.ndarray:
        """This step's packed state: the source's read, else a row the corrector passes through."""
        row = None
        if self.source is not None:
            try:
                row = self.source.read_packed()
            except Exception as err:  # noqa: BLE001 - do-no-harm: an unreadable state turns correction off
                self.read_failures += 1
                if self.read_failures == 1:
                    warnings.warn(f"physvla: the state source failed ({err!r}); the corrector passes actions "
                                  "through while it does", RuntimeWarning, stacklevel=3)
        if row is None or row.shape != (self._size,):
            row = np.zeros(self._size)  # valid = 0: the corrector passes through
            row[self._f["episode_step"]] = self._steps  # episodes still split where they do
            row[self._f["dt"]] = self.control_dt()
            if self.unsupported_goal is not None:
                row[self._f["valid"]] = UNSUPPORTED_GOAL_VALID
        return row

    def _export(self, obs: dict, success: bool, row: np.ndarray) -> dict:
        """obs with physvla_state (through the perception model, if any) and physvla_extra under robot_state."""
        obs = dict(obs)
        rs = dict(obs.get("robot_state", {}))
        rs[STATE_KEY] = row if self.perception is None else self.perception.apply(row[None])[0]
        rs[EXTRA_KEY] = np.concatenate([[self.task_id, float(success)], self._last_action])
        obs["robot_state"] = rs
        return obs

    def _unsupported(self, goal: str, message: str) -> None:
        """Mark this env's task as outside the model (its goal in words) and say so once per process."""
        self.unsupported_goal = goal
        if goal not in _WARNED_GOALS:
            _WARNED_GOALS.add(goal)
            warnings.warn(message, RuntimeWarning, stacklevel=3)

    def _no_source(self, err: Exception, what: str) -> None:
        """A source that could not be built: counted and said; the corrector passes actions through."""
        self.source = None
        self.read_failures += 1
        warnings.warn(f"physvla: no {what} state source ({err!r}); the corrector passes actions through",
                      RuntimeWarning, stacklevel=3)

    def _begin_episode(self, seed=None) -> None:
        self._steps = 0
        self._last_action = np.zeros(self._action_dim)
        if self.perception is not None:
            self.perception.reset(seed=seed)

    def _executed(self, action) -> None:
        """The action about to be executed (exported next step) and one more control step."""
        self._last_action = np.asarray(action, dtype=np.float64).copy()
