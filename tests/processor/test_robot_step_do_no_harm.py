"""Do-no-harm of the arm's step for every input, as lerobot-rollout hands it over (an action dict of
joint targets and a raw observation dict of readings): any reading or target extreme, zero,
negative, non-finite or not a number at all, mid-episode, in any preset or mode, with the object
from a fixed point or from observation keys. After a first call with sane inputs: no exception,
every target the robot receives finite, a joint the correction moved inside the model's range, and
a target the policy sent finite and untouched unless the step says why (a counted pass-through,
a held non-finite target, or a correction)."""

from __future__ import annotations

import math
import warnings

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st_

from lerobot.processor import RobotProcessorPipeline
from lerobot.processor.converters import robot_action_observation_to_transition, transition_to_robot_action

from lerobot_physvla.core.config import PRESETS, PhysVLAConfig
from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep

MOTORS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")
KEYS = [f"{m}.pos" for m in MOTORS] + ["gripper.pos"]
EXTREME = [0.0, -1.0, 1e-300, 1e6, -1e6, 1e300, math.nan, math.inf, -math.inf, "garbage", None]
CONFIGS = {"arm": PRESETS["arm"], "default": PRESETS["default"], "phys_el": PhysVLAConfig.paper(mode="phys_el"),
           "paper_alg1": PRESETS["paper_alg1"]}
STEPS: dict = {}


def _step(config: str, object_key: bool) -> tuple[PhysVLARobotActionStep, RobotProcessorPipeline]:
    key = (config, object_key)
    if key not in STEPS:
        where = {"object_key": "block"} if object_key else {"object_xyz": [0.2, 0.1, 0.02]}
        step = PhysVLARobotActionStep(arm="so101", target_xyz=[0.3, -0.2, 0.0], config=CONFIGS[config].to_dict(), **where)
        STEPS[key] = step, RobotProcessorPipeline(steps=[step], to_transition=robot_action_observation_to_transition,
                                                  to_output=transition_to_robot_action)
    return STEPS[key]


def _sane(t: int):
    deg = [10 * math.sin(0.1 * t + k) for k in range(5)]
    obs = {**{k: v for k, v in zip(KEYS, deg)}, "gripper.pos": 60.0, "block.x": 0.2, "block.y": 0.1, "block.z": 0.02}
    act = {**{k: v + 1.0 for k, v in zip(KEYS, deg)}, "gripper.pos": 0.0}
    return act, obs


@settings(max_examples=300, deadline=None)
@given(
    config=st_.sampled_from(sorted(CONFIGS)),
    object_key=st_.booleans(),
    in_obs=st_.booleans(),
    key=st_.sampled_from(KEYS + ["block.x", "block.z"]),
    value=st_.sampled_from(EXTREME),
    also=st_.sampled_from([None, *KEYS]),
    ticks=st_.integers(1, 4),
)
def test_any_reading_or_target_mid_episode_reaches_the_robot_finite(config, object_key, in_obs, key, value, also, ticks):
    step, p = _step(config, object_key)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        p(_sane(0))  # the first call: sane (a bad one would raise before the robot moves)
        for t in range(1, ticks + 1):
            act, obs = _sane(t)
            if in_obs or key.startswith("block"):
                obs[key] = value
                if also is not None:
                    obs[also] = value
            else:
                act[key] = value
                if also is not None:
                    act[also] = value
            before = sum(step.passthrough_counts.values())
            out = p((dict(act), dict(obs)))
            for k in KEYS:
                assert isinstance(out[k], float) and math.isfinite(out[k]), (k, out[k], act, obs)
            for k, lo, hi in zip(KEYS[:5], np.rad2deg(step._q_lo), np.rad2deg(step._q_hi)):
                corrected = isinstance(act[k], float) and math.isfinite(act[k]) and out[k] != act[k]
                if corrected and k not in obs or corrected and out[k] != obs.get(k):  # moved by the correction
                    assert lo - 1e-9 <= out[k] <= hi + 1e-9, (k, out[k])
            bad_target = [k for k in KEYS if not (isinstance(act[k], float) and math.isfinite(act[k]))]
            if bad_target:  # held: counted
                assert sum(step.passthrough_counts.values()) > before
