"""lerobot-env-so101's scripted pick-and-place controller as the teacher of the `so101_env` scene, with failure modes.

The controller (`lerobot_env_so101.scripted.PickPlaceController`) hovers over the block, descends, closes, lifts,
traverses, lowers onto the goal, opens and retreats; each step it reads the point the action moves (the env's
`ik_point_pos`), the block's centre and the goal from the simulation, as the package's own demonstration recorder
does, and returns [dx, dy, dz, grasp] (the so101 layout: 0.025 m a unit; grasp 1 open, 0 closed). It keeps its
phase between steps, so `reset` starts it afresh.

Failure modes (sim/experts.py's names; each drawn per episode from `reset(seed)`; all off by default):
    action_noise     sigma of Gaussian noise on the executed x, y action channels, action units, every step
    premature_close  probability per episode that the grasp closes early: from the first step the grasp point
                     comes within PREMATURE_XY_M (xy) of the block while the controller still hovers or descends,
                     the grasp is 0 (closed) until the controller closes by itself
Any other ExpertConfig field raises a ValueError naming what this teacher takes.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

PREMATURE_XY_M = 0.03  # the early close fires within this of the block (xy): over it, before the jaws reach it


@dataclass
class SO101EnvExpertConfig:
    """The teacher's failure modes (module docstring); `seed`: the draws before any reset."""

    action_noise: float = 0.0
    premature_close: float = 0.0
    seed: int = 0

    @classmethod
    def from_failure(cls, failure: dict) -> SO101EnvExpertConfig:
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(failure) - known)
        if unknown:
            raise ValueError(f"physvla: the so101 teacher takes {', '.join(sorted(known - {'seed'}))}; not "
                             f"{', '.join(unknown)}")
        return cls(**failure)


class SO101EnvExpert:
    """The package's controller on one `so101_env` scene, with this config's failure modes."""

    def __init__(self, cfg: SO101EnvExpertConfig | None = None):
        from lerobot_env_so101.scripted import PickPlaceController
        from lerobot_env_so101.scripted.pick_place import Phase

        from lerobot_physvla.sim.so101_env_sim import ACTION_SCALE

        self.cfg = cfg or SO101EnvExpertConfig()
        self.controller = PickPlaceController(action_scale=ACTION_SCALE)
        self._before_grasp = (Phase.HOVER, Phase.DESCEND)  # where a premature close can fire
        self.reset(self.cfg.seed)

    def reset(self, seed: int = 0) -> None:
        self.controller.reset()
        self.rng = np.random.default_rng(int(seed))
        self.close_early = bool(self.rng.random() < self.cfg.premature_close)
        self.closing = False

    def act(self, scene) -> np.ndarray:
        """The next action on `scene` (an SO101EnvScene), failure modes applied."""
        src = scene.source  # the env's own ik_point_pos, block_pos sensor and goal_pos, as the controller reads them
        grasp, block = src.eef(), src.object_pos()
        a = np.asarray(self.controller.act(grasp, block, src.target_pos()), dtype=np.float64)
        early = self.controller.phase in self._before_grasp
        if self.close_early and early and (self.closing or np.hypot(*(grasp[:2] - block[:2])) < PREMATURE_XY_M):
            self.closing = True
            a[3] = 0.0
        if self.cfg.action_noise > 0:
            a[:2] = np.clip(a[:2] + self.rng.normal(0.0, self.cfg.action_noise, 2), -1.0, 1.0)
        return a
