"""MetaWorld's own scripted policy of a task as the teacher, with the paper's failure modes injected.

The policy is the task's class in `metaworld.policies` (lerobot's TASK_POLICY_MAPPING names the same ones). It is
memoryless: each step it reads MetaWorld's 39-D observation (hand xyz, finger opening, the object's pose, the
previous frame's 18, the goal) and returns [dx, dy, dz, grab] (the `metaworld` layout; its grab is 0 or -1 for
open and 0.1-1 for closed, as the task's policy sets it). The failures act on a copy of that observation and on
the returned action only: the simulation, the scene's observation and the state the corrector reads are never
touched. Each is drawn per episode from `reset(seed)` (the harness: the episode's seed + draw_offset), in the
order of sim/experts.py's PickPlaceExpert (aim, then place bias, then premature close; the action noise per step).

Failure modes (ExpertConfig's names, meanings as close as this teacher allows):
    action_noise     sigma of Gaussian noise on the executed x, y action channels, action units (1 unit = 1 cm
                     of mocap motion per step); drawn every step; with noise_stage = "grasp" added only near the
                     grasp: the hand within GRASP_ZONE_M (xy) of the object the policy sees, before the carry (below).
    aim_noise_m      sigma (per axis) of a lateral offset, drawn per episode, of where the policy sees the object
                     (this frame's and the previous frame's copy), for the whole episode: it aims its grasp that far
                     off the object and misses or grasps it off-centre; held, the object is where the policy
                     believes it (offset from the hand by the same vector), so it does not chase it.
    place_bias_m     a persistent lateral place error: direction ~ U(0, 2 pi), size ~ U(0, place_bias_m), m. From the
                     carry on (below), the policy sees the hand and the object (both frames) shifted by -bias, so
                     it brings them to its goal + bias. Shifting the frame, not the goal, is what works for
                     every policy: bin-picking's drives to a fixed bin point, shelf-place's and basketball's read
                     only the goal's x.
    premature_close  probability per episode that the gripper closes early: from the first step the hand comes
                     within PREMATURE_XY_M (xy) of the object while the policy still commands open, the grab is
                     +1 until the policy closes by itself (its fingers then come down shut on the object).
    no_decel         no deceleration while carrying: from the carry on, every move command with a component
                     above NO_DECEL_MIN_UNITS is scaled to full speed (largest component 1), so the policy's
                     proportional approach to its goal becomes a bang-bang one that overshoots by up to 1 cm a step.
    noise_stage      "all" or "grasp" (see action_noise).
The carry starts (latched for the episode) at the first step the policy commands its gripper closed (its own
command, last step) while the object is more than CARRY_M from where it rested at the episode's start: the object
goes with the hand. Not a height: pick-place's goals can be at the table's height, where the puck is slid to its
goal raised under 1 cm (seed 0).
ExpertConfig's other fields are the bowl expert's waypoint geometry and gains (hover_m, grasp_offset_m,
place_offset_m, close_steps, release_steps, gain, tol_m), its release switch (release) and an action bias while
placing (place_bias_units): this teacher has no waypoints of its own to change, so each raises a ValueError.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, fields

import numpy as np

# Each modelled task's scripted policy (metaworld.policies; lerobot's TASK_POLICY_MAPPING has the same).
POLICIES: dict[str, str] = {
    "pick-place-v3": "SawyerPickPlaceV3Policy",
    "pick-place-wall-v3": "SawyerPickPlaceWallV3Policy",
    "bin-picking-v3": "SawyerBinPickingV3Policy",
    "shelf-place-v3": "SawyerShelfPlaceV3Policy",
    "basketball-v3": "SawyerBasketballV3Policy",
    "pick-out-of-hole-v3": "SawyerPickOutOfHoleV3Policy",
}
# ExpertConfig fields this teacher cannot take, and why (module docstring).
UNSUPPORTED_FIELDS: dict[str, str] = {
    **{f: "the bowl expert's waypoint geometry; MetaWorld's policy has its own"
       for f in ("hover_m", "grasp_offset_m", "place_offset_m", "close_steps", "release_steps", "gain", "tol_m")},
    "release": "MetaWorld's policies release (or not) as their task needs",
    "place_bias_units": "an action bias while placing has no stage to attach to here; use place_bias_m",
}
OBJ = slice(4, 7)  # the object's xyz in the 39-D observation
HAND = slice(0, 3)
PREV = 18  # the previous frame's 18 start here
CARRY_M = 0.02  # the carry: the policy's gripper closed and the object this far from its rest (module docstring)
GRASP_ZONE_M = 0.06  # as PickPlaceExpert: where grasp-stage noise applies, before the carry
PREMATURE_XY_M = 0.12  # as PickPlaceExpert: the early close fires within this of the object (xy)
NO_DECEL_MIN_UNITS = 0.05  # no_decel leaves commands below this (action units) as they are: a hold stays a hold


@dataclass
class MetaworldExpertConfig:
    """The teacher's failure modes, all off by default (module docstring); `seed`: the draws before any reset."""

    action_noise: float = 0.0
    aim_noise_m: float = 0.0
    place_bias_m: float = 0.0
    premature_close: float = 0.0
    no_decel: bool = False
    noise_stage: str = "all"
    seed: int = 0

    def __post_init__(self) -> None:
        if self.noise_stage not in ("all", "grasp"):
            raise ValueError(f"physvla: noise_stage must be 'all' or 'grasp', got {self.noise_stage!r}")
        for f in ("action_noise", "aim_noise_m", "place_bias_m"):
            if getattr(self, f) < 0:
                raise ValueError(f"physvla: metaworld teacher: {f} must be >= 0, got {getattr(self, f)}")
        if not 0.0 <= self.premature_close <= 1.0:
            raise ValueError(f"physvla: metaworld teacher: premature_close is a probability, got "
                             f"{self.premature_close}")

    @classmethod
    def from_failure(cls, failure: dict) -> MetaworldExpertConfig:
        """From a study's `expert = {...}` fields (teacher and draw_offset already taken out); a clear error for a
        field this teacher cannot take."""
        mine = {f.name for f in fields(cls)}
        for k in failure:
            if k in UNSUPPORTED_FIELDS:
                raise ValueError(f"physvla: the metaworld teacher (MetaWorld's scripted policy) does not support "
                                 f"{k!r}: {UNSUPPORTED_FIELDS[k]}")
            if k not in mine:
                raise ValueError(f"physvla: unknown field {k!r} for the metaworld teacher; it takes "
                                 f"{', '.join(sorted(mine))}")
        return cls(**failure)


def make_policy(task: str):
    """The scripted policy of a MetaWorld v3 task: POLICIES for a modelled one, metaworld's own ENV_POLICY_MAP for
    the others (the pass-through scenes); ValueError for a name MetaWorld does not know."""
    import metaworld.policies as policies

    task = task.removeprefix("metaworld-")
    if task in POLICIES:
        return getattr(policies, POLICIES[task])()
    if task in policies.ENV_POLICY_MAP:
        return policies.ENV_POLICY_MAP[task]()
    raise ValueError(f"physvla: no metaworld teacher for {task!r}; it covers MetaWorld's v3 tasks, e.g. "
                     f"{', '.join(POLICIES)}")


class MetaworldExpert:
    """MetaWorld's scripted policy of `task` with the failure modes of `cfg`; `reset(seed)` each episode, then
    `act(obs)` with MetaWorld's 39-D observation each step.

    Attributes (this episode's draws and state):
        aim: the lateral offset of the object the policy sees, m (3, z = 0).
        place_bias: the lateral place bias, m (3, z = 0).
        close_early: whether the gripper closes early this episode.
        carrying: the carry has started (module docstring; latched for the episode).
        closing_early: the early close is commanding the gripper now.
        seen: the observation the policy saw last (the faults applied).
        clean: the policy's action on `seen`, clipped, before the action faults.
    """

    def __init__(self, task: str, cfg: MetaworldExpertConfig | None = None):
        self.task = task.removeprefix("metaworld-")
        self.policy = make_policy(self.task)
        self.cfg = cfg or MetaworldExpertConfig()
        self.rng = np.random.default_rng(self.cfg.seed)
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        c = self.cfg
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        self.aim = np.append(self.rng.normal(0.0, c.aim_noise_m, 2), 0.0) if c.aim_noise_m > 0 else np.zeros(3)
        theta, size = self.rng.uniform(0, 2 * np.pi), self.rng.uniform(0, c.place_bias_m)
        self.place_bias = np.array([np.cos(theta) * size, np.sin(theta) * size, 0.0])
        self.close_early = bool(self.rng.uniform() < c.premature_close)
        self.carrying = False
        self.closing_early = False
        self._early_on = False  # the early close has fired (it holds until the policy closes by itself)
        self._early_done = False  # the policy has closed by itself: the early close is over
        self._rest: np.ndarray | None = None  # the object's position at the episode's start
        self.seen = np.zeros(39)
        self.clean = np.zeros(4)

    def observe(self, obs: np.ndarray) -> np.ndarray:
        """The observation the policy sees: a copy of `obs` with the aim offset and (once carrying) the place bias
        applied. Updates the carry's latch."""
        obs = np.asarray(obs, dtype=np.float64)
        if self._rest is None:
            self._rest = obs[OBJ].copy()
        self.carrying = self.carrying or bool(self.clean[3] > 0 and np.linalg.norm(obs[OBJ] - self._rest) > CARRY_M)
        seen = obs.copy()
        if self.aim.any():
            seen[4:6] += self.aim[:2]
            seen[PREV + 4 : PREV + 6] += self.aim[:2]
        if self.carrying and self.place_bias.any():
            for at in (0, 4, PREV, PREV + 4):  # hand and object, this frame and the previous one
                seen[at : at + 2] -= self.place_bias[:2]
        return seen

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The teacher's action (4,) for MetaWorld's 39-D observation `obs` (not modified)."""
        c = self.cfg
        seen = self.seen = self.observe(obs)
        with warnings.catch_warnings():  # metaworld's move() warns whenever its gain saturates the command
            warnings.simplefilter("ignore")
            a = np.clip(np.asarray(self.policy.get_action(seen), dtype=np.float64), -1.0, 1.0)
        self.clean = a.copy()
        near_xy = float(np.linalg.norm(seen[HAND][:2] - seen[OBJ][:2]))
        self.closing_early = False
        if self.close_early and not self._early_done:
            if a[3] > 0:  # the policy closes by itself: from now on its own command
                self._early_done = True
            elif self._early_on or near_xy < PREMATURE_XY_M:
                self._early_on = self.closing_early = True
                a[3] = 1.0
        if c.no_decel and self.carrying:
            n = float(np.abs(a[:3]).max())
            if n > NO_DECEL_MIN_UNITS:
                a[:3] /= n
        if c.action_noise > 0:
            noise = self.rng.normal(0.0, c.action_noise, 2)  # drawn every step: streams match across stages
            if c.noise_stage == "all" or (not self.carrying and near_xy < GRASP_ZONE_M):
                a[:2] += noise
        return np.clip(a, -1.0, 1.0)
