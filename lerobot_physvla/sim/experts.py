"""Scripted reach -> grasp -> lift -> transport -> place expert, from privileged state.

A plain numpy state machine producing actions in a Cartesian delta layout (see
`config.ActionLayout`): it reads the end-effector, object and target positions, so it runs on
any env whose state source fills a `PhysState`. Used by the demo, the tests and (wrapped as a
LeRobot policy) the evaluation backbones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lerobot_physvla.core.config import LIBERO_OSC_POSE, ActionLayout


@dataclass
class ExpertConfig:
    """Waypoint geometry (metres) and gains of the scripted expert.

    Attributes:
        hover_m: height above the object / target for the approach and transport legs.
        grasp_offset_m: grasp point relative to the object's origin (LIBERO bowls: on the rim,
            on the robot's side, so the fingers straddle the rim wall).
        place_offset_m: release point relative to the target's origin (same xy offset, so the
            object's centre ends over the target).
        close_steps: control steps spent closing the gripper before lifting.
        release_steps: control steps spent opening the gripper at the target.
        gain: action units per metre of waypoint error, divided by metres_per_unit (1 = reach
            the waypoint in one step if the controller tracked perfectly).
        tol_m: waypoint reached when the error is below this.
    """

    hover_m: float = 0.10
    grasp_offset_m: tuple[float, float, float] = (0.0, -0.047, 0.035)
    place_offset_m: tuple[float, float, float] = (0.0, -0.047, 0.07)
    close_steps: int = 12
    release_steps: int = 8
    gain: float = 0.6
    tol_m: float = 0.012
    # Injectable failure modes of the paper (all off by default; drawn per episode from `seed`).
    action_noise: float = 0.0  # sigma of Gaussian noise on the x, y action channels, action units
    aim_noise_m: float = 0.0  # sigma of a lateral (x, y) grasp-aim offset, m
    place_bias_m: float = 0.0  # persistent x, y bias at place: direction ~ U(0, 2 pi), size ~ U(0, this), m
    premature_close: float = 0.0  # probability that the gripper closes during the approach
    no_decel: bool = False  # full-speed moves to the target (no deceleration profile)
    # Where action_noise applies: "all" steps, or only "grasp" (within GRASP_ZONE_M of the grasp
    # point, before lifting: the paper's Lift sweep injects its noise there).
    noise_stage: str = "all"
    # Persistent x, y bias on the action while moving to the release point (within GRASP_ZONE_M of
    # it after lifting; a mis-predicted release point, so not while releasing): direction
    # ~ U(0, 2 pi), size ~ U(0, this), action units (paper: 1.7).
    place_bias_units: float = 0.0
    release: bool = True  # open the gripper at the target; False holds it there (goals in the air)
    seed: int = 0

    def __post_init__(self) -> None:
        if self.noise_stage not in ("all", "grasp"):
            raise ValueError(f"physvla: noise_stage must be 'all' or 'grasp', got {self.noise_stage!r}")


class PickPlaceExpert:
    """One env's scripted expert; call `reset()` at each episode start, then `act(...)` per step."""

    STAGES = ("hover_obj", "descend", "close", "lift", "hover_tgt", "lower", "release", "done")
    STALL_STEPS = 15
    GRASP_ZONE_M = 0.06  # the corrector's delta_grasp: where grasp-stage noise and place bias apply

    def __init__(self, layout: ActionLayout = LIBERO_OSC_POSE, cfg: ExpertConfig | None = None):
        self.layout = layout
        self.cfg = cfg or ExpertConfig()
        self.rng = np.random.default_rng(self.cfg.seed)
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        """New episode: stage machine restarts and the episode's failure draws are made."""
        c = self.cfg
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        self.stage = 0
        self.count = 0
        self._lift_z = None  # lift waypoint height, m (set when the lift starts)
        self._best, self._stall = np.inf, 0
        self.aim = np.append(self.rng.normal(0.0, c.aim_noise_m, 2), 0.0) if c.aim_noise_m > 0 else np.zeros(3)
        theta, size = self.rng.uniform(0, 2 * np.pi), self.rng.uniform(0, c.place_bias_m)
        self.place_bias = np.array([np.cos(theta) * size, np.sin(theta) * size, 0.0])
        self.close_early = bool(self.rng.uniform() < c.premature_close)
        self.place_bias_units = np.zeros(3)
        if c.place_bias_units > 0:  # drawn only when on, so other configs keep their random streams
            theta, size = self.rng.uniform(0, 2 * np.pi), self.rng.uniform(0, c.place_bias_units)
            self.place_bias_units = np.array([np.cos(theta) * size, np.sin(theta) * size, 0.0])

    def _progress(self, e: float, done: bool) -> bool:
        """A blocked move (contact, workspace edge) counts as done after STALL_STEPS without progress; e: what is
        left of the move, m."""
        self._stall = 0 if e < self._best - 0.002 else self._stall + 1
        self._best = min(self._best, e)
        return done or self._stall >= self.STALL_STEPS

    def _advance(self) -> None:
        """On to the next stage, its counters afresh."""
        self.stage = min(self.stage + 1, len(self.STAGES) - 1)
        self.count = 0
        self._best, self._stall = np.inf, 0

    def _faults(self, d: np.ndarray, near_grasp: bool, placing: bool) -> np.ndarray:
        """The injected failure modes on the position command d (action units): the action noise (drawn every
        step either way, so streams match across noise_stage) and, while placing, the place bias."""
        c = self.cfg
        if c.action_noise > 0:
            noise = np.append(self.rng.normal(0.0, c.action_noise, 2), 0.0)
            if c.noise_stage == "all" or near_grasp:
                d = d + noise
        if c.place_bias_units > 0 and placing:
            d = d + self.place_bias_units
        return d

    def _move(self, eef: np.ndarray, goal: np.ndarray, fast: bool = False) -> tuple[np.ndarray, float]:
        err = goal - eef
        d = self.cfg.gain * err / self.layout.metres_per_unit
        if fast:  # no deceleration: full speed along the error until within tolerance
            n = np.abs(d).max()
            d = d / n if n > 1e-9 and np.linalg.norm(err) > self.cfg.tol_m else d
        return np.clip(d, -1.0, 1.0), float(np.linalg.norm(err))

    def act(self, eef_pos: np.ndarray, obj_pos: np.ndarray, target_pos: np.ndarray) -> np.ndarray:
        c, lay = self.cfg, self.layout
        a = np.zeros(lay.dim)
        close = -lay.gripper_open
        grip = lay.gripper_open
        name = self.STAGES[self.stage]
        grasp = obj_pos + np.asarray(c.grasp_offset_m) + self.aim
        place = target_pos + np.asarray(c.place_offset_m) + self.place_bias
        up = np.array([0.0, 0.0, c.hover_m])
        if name == "hover_obj":
            d, err = self._move(eef_pos, grasp + up)
            done = np.linalg.norm((grasp - eef_pos)[:2]) < c.tol_m
            if self.close_early and np.linalg.norm((grasp - eef_pos)[:2]) < 0.12:
                grip = close  # premature close, mid-flight
        elif name == "descend":
            d, err = self._move(eef_pos, grasp)
            done = err < c.tol_m
        elif name == "close":
            d, _ = self._move(eef_pos, grasp)
            grip, self.count = close, self.count + 1
            done = self.count >= c.close_steps
        elif name == "lift":  # clear both the start and the target heights
            if self._lift_z is None:  # fixed at the lift's start: the grasp point rises with the object
                self._lift_z = max(place[2], grasp[2]) + c.hover_m
            d, err = self._move(eef_pos, np.array([*eef_pos[:2], self._lift_z]))
            grip, done = close, err < c.tol_m
        elif name == "hover_tgt":
            d, _ = self._move(eef_pos, place + up, fast=c.no_decel)
            grip, done = close, np.linalg.norm((place - eef_pos)[:2]) < c.tol_m
        elif name == "lower":
            d, err = self._move(eef_pos, place, fast=c.no_decel)
            grip, done = close, err < c.tol_m
        elif name == "release" and not c.release:  # hold the object at the target
            d, _ = self._move(eef_pos, place)
            grip, done = close, False
        elif name == "release":
            d, self.count = np.zeros(3), self.count + 1
            done = self.count >= c.release_steps
        else:
            d, done = self._move(eef_pos, place + up)[0], False
        if name in ("hover_obj", "descend", "lift", "hover_tgt", "lower"):
            done = self._progress(float(np.linalg.norm((grasp if name in ("hover_obj", "descend") else place) - eef_pos)),
                                  done)
        if done:
            self._advance()
        near_grasp = name in ("descend", "close") or (
            name == "hover_obj" and np.linalg.norm((grasp - eef_pos)[:2]) < self.GRASP_ZONE_M)
        placing = name == "lower" or (name == "hover_tgt" and np.linalg.norm((place - eef_pos)[:2]) < self.GRASP_ZONE_M)
        d = self._faults(d, near_grasp, placing)
        a[list(lay.pos)] = d
        if lay.gripper is not None:
            a[lay.gripper] = grip
        return np.clip(a, lay.low, lay.high)
