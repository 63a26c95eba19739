"""The real `lerobot-eval` console script on `--env.type=so101 --env.task=SO101PickPlace-v0` with
`--policy.postprocess=physvla`, in a subprocess, with a random-weight ACT made by lerobot's own factory."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

BIN = Path(sys.executable).parent
pytestmark = pytest.mark.slow  # subprocess console script, rendering


def make_policy(out: Path) -> None:
    """A tiny ACT for the so101 pick-and-place features (observation.state 14, observation.environment_state 6:
    the block and the goal, action 4), identity normalisation."""
    import torch

    from lerobot.policies.factory import make_policy as factory, make_policy_config, make_pre_post_processors

    from lerobot_physvla.envs.so101_physvla import SO101PhysVLAEnvConfig

    torch.manual_seed(0)
    env_cfg = SO101PhysVLAEnvConfig(task="SO101PickPlace-v0")
    cfg = make_policy_config("act", device="cpu", chunk_size=10, n_action_steps=10, dim_model=64,
                             dim_feedforward=128, n_heads=4, n_encoder_layers=1, n_decoder_layers=1, use_vae=False,
                             pretrained_backbone_weights=None)
    policy = factory(cfg, env_cfg=env_cfg)
    assert cfg.input_features["observation.environment_state"].shape == (6,)

    def ident(shape):
        return {"mean": torch.zeros(shape), "std": torch.ones(shape), "min": -torch.ones(shape),
                "max": torch.ones(shape)}

    stats = {"observation.state": ident(14), "observation.environment_state": ident(6), "action": ident(4)}
    pre, post = make_pre_post_processors(cfg, dataset_stats=stats)
    for part in (policy, pre, post):
        part.save_pretrained(out)


def test_so101_pick_place_eval_is_corrected_in_the_so101_layout_at_the_envs_action_scale(tmp_path):
    make_policy(tmp_path / "policy")
    out = tmp_path / "eval"
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), "OMP_NUM_THREADS": "1"}
    r = subprocess.run(
        [str(BIN / "lerobot-eval"), f"--policy.path={tmp_path / 'policy'}", f"--output_dir={out}",
         "--env.type=so101", "--env.task=SO101PickPlace-v0", "--env.episode_length=8", "--env.action_scale=0.025",
         "--eval.n_episodes=1", "--eval.batch_size=1", "--policy.device=cpu", "--policy.postprocess=physvla"],
        capture_output=True, text=True, timeout=600, env=env, stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stderr[-4000:]
    diag = json.loads((out / "physvla_diagnostics.json").read_text())
    # the env's layout at its action_scale, no --physvla.layout given; Branch B's weighting with it
    assert diag["physvla_config"]["layout"] == {"dim": 4, "pos": [0, 1, 2], "rot": [], "gripper": 3,
                                                "metres_per_unit": 0.025, "gripper_open": 1.0, "low": -1.0,
                                                "high": 1.0, "absolute": False, "gripper_closed": 0.0,
                                                "step_gain": 1.0}
    assert diag["physvla_config"]["weighting"] == "task_space"
    assert diag["episodes"] == 1 and diag["steps"] == 8 and diag["passthrough"] == {}
    episodes = [json.loads(line) for line in (out / "physvla_episodes.jsonl").read_text().splitlines()]
    info = json.loads((out / "eval_info.json").read_text())
    assert [(t["task_group"], t["task_id"]) for t in info["per_task"]] == [("SO101PickPlace-v0", 0)]
    (ep,) = episodes
    assert (ep["task_id"], ep["steps"], ep["passthrough"]) == (0, 8, {})
    # corrected, and the simulator executed the corrected actions (echoed in physvla_extra a step later)
    assert ep["frames_changed"] > 0
    executed = [(t, a) for t, a in enumerate(ep["executed_actions"]) if a is not None]
    assert len(executed) == 7
    for t, a in executed:
        np.testing.assert_allclose(a, ep["corrected_actions"][t], atol=1e-6)
    assert "1 episodes, 8 frames" in r.stdout and "pass-throughs: none" in r.stdout
