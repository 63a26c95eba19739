"""The scripted expert as a LeRobot policy (`physvla_scripted`): saved with
backbones/make_scripted_policy.py, loaded with from_pretrained, it acts as the expert does, in
the LIBERO layout and, with --scene, in another scene's layout and geometry."""

import pytest
import subprocess
import sys
from pathlib import Path

import numpy as np
import torch

from lerobot_physvla.core.config import LAYOUTS
from lerobot_physvla.sim.experts import ExpertConfig, PickPlaceExpert
from lerobot_physvla.sim.fetch_sim import FetchScene
from lerobot_physvla.policies.physvla_scripted.modeling_physvla_scripted import PhysVLAScriptedPolicy

ROOT = Path(__file__).resolve().parents[2]


def _save(tmp_path, *args) -> PhysVLAScriptedPolicy:
    out = tmp_path / "policy"
    done = subprocess.run([sys.executable, str(ROOT / "backbones/make_scripted_policy.py"), str(out), *args],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    return PhysVLAScriptedPolicy.from_pretrained(str(out))


def _compare(policy, expert, state_dim, steps=30):
    rng = np.random.default_rng(0)
    eef = np.array([0.0, -0.2, 1.1])
    obj, tgt = np.array([0.05, 0.0, 0.9]), np.array([0.2, 0.1, 0.9])
    for _ in range(steps):
        state = np.zeros((1, state_dim), np.float32)
        state[0, :3] = eef
        batch = {"observation.state": torch.from_numpy(state),
                 "observation.environment_state": torch.from_numpy(np.concatenate([obj, tgt])[None].astype(np.float32))}
        got = policy.select_action(batch)[0].double().numpy()
        want = expert.act(state[0, :3].astype(np.float64), obj.astype(np.float32).astype(np.float64),
                          tgt.astype(np.float32).astype(np.float64))
        np.testing.assert_allclose(got, want, atol=1e-6)
        eef = eef + got[:3] * 0.05 + rng.normal(0, 0.002, 3)


@pytest.mark.slow
def test_libero_default_matches_the_expert(tmp_path):
    policy = _save(tmp_path, "--action_noise", "0.2", "--seed", "4")
    assert policy.config.output_features["action"].shape == (7,)
    _compare(policy, PickPlaceExpert(cfg=ExpertConfig(action_noise=0.2, seed=4)), 8)


@pytest.mark.slow
def test_fetch_scene_gives_the_4d_layout_and_the_scene_geometry(tmp_path):
    policy = _save(tmp_path, "--scene", "fetch_pick_place", "--action_noise", "0.3", "--noise_stage", "grasp")
    assert policy.config.layout == "fetch_4d" and policy.config.output_features["action"].shape == (4,)
    geometry = {k: tuple(v) if isinstance(v, list) else v for k, v in FetchScene.expert.items()}
    expert = PickPlaceExpert(LAYOUTS["fetch_4d"], ExpertConfig(**geometry, action_noise=0.3, noise_stage="grasp"))
    _compare(policy, expert, 8)
