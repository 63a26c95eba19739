"""The frozen policies the harness corrects: scripted experts and trained LeRobot policies.

A backbone is an object with `reset(seed)` (new episode) and `act(scene, state) -> (A,)` (the
raw action for the current step, in the scene's action layout). The corrector never sees which
kind it is.

- Scripted experts (`ExpertBackbone`): experts.PickPlaceExpert (or the shape-planning expert, or on
  MetaWorld the task's own scripted policy) with the paper's failure modes injected (BACKBONES below),
  geometry from the scene (`scene.expert`).
- Learned backbones (`LeRobotBackbone`): a LeRobot policy checkpoint (backbones/train_backbones.py)
  with its own pre/post-processors (normalisation), fed the state observation that
  `lerobot-eval --env.type=libero_physvla --env.cameras=false` gives it, and on a camera scene
  (`<suite>+agentview<N>`) the agentview frame that `--env.type=libero` gives it.
"""

from __future__ import annotations

import numpy as np

# Scripted backbones: the expert with failure modes injected (experts.ExpertConfig fields).
BACKBONES: dict[str, dict] = {
    "expert_clean": {},
    # per-step lateral jitter and a grasp-aim error: a memoryless policy's imprecision
    "expert_jitter": {"action_noise": 0.3, "aim_noise_m": 0.015},
    # premature closes, a persistent place bias, no deceleration near the target
    "expert_faulty": {"premature_close": 0.3, "place_bias_m": 0.04, "no_decel": True},
}


class ExpertBackbone:
    """The scripted expert on one scene: `failure` = ExpertConfig fields of the failure modes,
    and optionally `draw_offset` (int, default 0): the episode on init state s draws its failures
    (noise, aim error, place bias, premature close) from seed s + draw_offset. The LIBERO init
    states are few (0-39 used, 40-49 untouched), so a fresh offset gives a block of failure draws
    that no decision has looked at on init states that have been seen; and `teacher` ("bowl": sim/experts.py,
    the LIBERO-Spatial bowl expert; "shape": sim/shape_expert.py, which plans each grasp from the object's
    shape and follows a goal's sub-goals: the other LIBERO suites; "metaworld": the task's own scripted policy
    from metaworld.policies, sim/metaworld_expert.py, on the metaworld/<k> scenes only; "so101":
    lerobot-env-so101's pick-and-place controller, sim/so101_env_expert.py, on the so101_env scene only). Unnamed, the teacher
    is the scene's own (`scene.teacher`: "metaworld" on MetaWorld scenes), else "bowl"."""

    TEACHERS = ("bowl", "shape", "metaworld", "so101")

    def __init__(self, scene, failure: dict):
        from lerobot_physvla.sim.experts import ExpertConfig, PickPlaceExpert

        failure = dict(failure)
        self.draw_offset = int(failure.pop("draw_offset", 0))
        self.teacher = str(failure.pop("teacher", getattr(scene, "teacher", "bowl")))
        if self.teacher == "shape":
            from lerobot_physvla.sim.shape_expert import ShapeExpert, ShapeExpertConfig

            self.expert = ShapeExpert(layout=scene.layout, cfg=ShapeExpertConfig(**failure))
        elif self.teacher == "bowl":
            self.expert = PickPlaceExpert(layout=scene.layout, cfg=ExpertConfig(**{**scene.expert, **failure}))
        elif self.teacher == "metaworld":
            from lerobot_physvla.sim.metaworld_expert import MetaworldExpert, MetaworldExpertConfig

            task = getattr(getattr(scene, "task", None), "name", None)
            if not str(getattr(scene, "name", "")).startswith("metaworld/") or task is None:
                raise ValueError(f"physvla: the metaworld teacher runs on the metaworld/<k> scenes only, not on "
                                 f"{getattr(scene, 'name', scene)!r}")
            self.expert = MetaworldExpert(task, MetaworldExpertConfig.from_failure(failure))
        elif self.teacher == "so101":
            from lerobot_physvla.sim.so101_env_expert import SO101EnvExpert, SO101EnvExpertConfig

            if getattr(scene, "name", "") != "so101_env":
                raise ValueError(f"physvla: the so101 teacher runs on the so101_env scene only, not on "
                                 f"{getattr(scene, 'name', scene)!r}")
            self.expert = SO101EnvExpert(SO101EnvExpertConfig.from_failure(failure))
        else:
            raise ValueError(f"physvla: unknown expert teacher {self.teacher!r}; choose {', '.join(self.TEACHERS)}")

    def reset(self, seed: int) -> None:
        self.expert.reset(seed=seed + self.draw_offset)

    def act(self, scene, state) -> np.ndarray:
        if self.teacher == "shape":
            return self.expert.act_source(scene.source)
        if self.teacher == "metaworld":  # MetaWorld's 39-D observation of this step (the teacher copies it)
            return self.expert.act(scene.raw_obs)
        if self.teacher == "so101":
            return self.expert.act(scene)
        return self.expert.act(state.eef_pos[0], state.obj_pos[0], state.target_pos[0])


class LeRobotBackbone:
    """A trained LeRobot policy (checkpoint directory `path`) acting on a LIBERO scene: the replay's
    `LeRobotPolicy` (saved pre/post-processors, CPU) fed the scene's state observation.

    Attributes:
        policy: the PreTrainedPolicy (eval mode, CPU).
    """

    def __init__(self, path: str):
        from lerobot_physvla.replay.policy import LeRobotPolicy

        self._runner = LeRobotPolicy(path)
        self.policy = self._runner.policy
        # actions executed open loop per policy call (ACT / Diffusion: n_action_steps; else 1)
        self.actions_per_call = int(getattr(self.policy.config, "n_action_steps", 1) or 1)

    def reset(self, seed: int) -> None:
        self._runner.reset(seed)  # diffusion sampling noise: matched across modes per seed

    def reads_observation(self) -> bool:
        """Whether the policy's next action reads this step's observation. An ACT executing a chunk (n_action_steps
        > 1, no temporal ensembling) pops its queue and ignores the batch until the queue is empty; every other
        policy reads every observation (Diffusion keeps an observation history)."""
        cfg = self.policy.config
        queue = getattr(self.policy, "_action_queue", None)
        if cfg.type != "act" or queue is None or getattr(cfg, "temporal_ensemble_coeff", None) is not None:
            return True
        return len(queue) == 0

    def act(self, scene, state) -> np.ndarray:
        # a camera scene renders its frame only for the steps the policy reads (the actions are the same)
        kw = {"frame": self.reads_observation()} if getattr(scene, "camera_size", 0) else {}
        return self._runner.act(scene.policy_observation(state, **kw), scene.task.language)
