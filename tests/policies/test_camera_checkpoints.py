"""The committed camera checkpoints (backbones/checkpoints/camera): each one's weights are the ones every episode of
its study recorded for it (eval/results/camera_libero_pro, camera_spatial_diffusion, camera_diffusion_spatial), in float16 and under 30 MiB,
with the recipe that trained them; the harness runs one on the CPU."""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "backbones"))
sys.path.insert(0, str(ROOT / "eval"))

import train_camera  # noqa: E402

# name -> (the study whose episodes recorded its weights, its recipe, where it trained, its step)
COMMITTED = {
    "object_act_camera": ("camera_libero_pro", "act_cpu", "CPU", 5000),
    "object_act_camera_weak": ("camera_libero_pro", "act_cpu", "CPU", 2000),
    "object_diffusion_camera": ("camera_spatial_diffusion", "diffusion64", "H200", 6913),
    "object_diffusion_camera_weak": ("camera_spatial_diffusion", "diffusion64", "H200", 2000),
    "spatial_act_camera": ("camera_spatial_diffusion", "act", "H200", 6792),
    "spatial_act_camera_weak": ("camera_spatial_diffusion", "act", "H200", 2000),
    "spatial_diffusion_camera": ("camera_diffusion_spatial", "diffusion64", "H200", 10000),
    "spatial_diffusion_camera_weak": ("camera_diffusion_spatial", "diffusion64", "H200", 2000),
}
# committed, not yet run by their study: the test fails once one runs, so that its weights are then checked
NOT_YET_RUN: set[str] = set()


def test_each_committed_camera_checkpoint_is_the_one_the_study_ran_in_fp16():
    from safetensors import safe_open

    from store import Store

    names = sorted(p.name for p in train_camera.COMMITTED.iterdir() if (p / "model.safetensors").exists())
    assert names == sorted(COMMITTED)
    for name in names:
        study, recipe_name, device, step = COMMITTED[name]
        ckpt = train_camera.COMMITTED / name
        weights = ckpt / "model.safetensors"
        sha = hashlib.sha256(weights.read_bytes()).hexdigest()
        ran_with = Store(ROOT / "eval/results" / study).meta["backbones"]
        if name in NOT_YET_RUN:
            assert name not in ran_with, f"{name} ran in {study}: take it out of NOT_YET_RUN"
        else:
            assert ran_with[name] == {"policy_sha256": sha}, name
        assert weights.stat().st_size <= train_camera.COMMIT_MAX_MIB * 2**20
        with safe_open(str(weights), "pt") as f:
            assert {str(f.get_slice(k).get_dtype()) for k in f.keys()} <= {"F16", "I64"}
        recipe = json.loads((ckpt / "recipe.json").read_text())
        assert recipe["committed"] == {**recipe["committed"], "name": name, "dtype": "float16", "model_sha256": sha}
        assert recipe["recipe"] == recipe_name and device in recipe["device"] and recipe["step"] == step
        if "returned" in recipe:  # a GPU run handed it back in fp16: committing kept those bytes
            assert recipe["returned"]["model_sha256"] == sha


def test_the_committed_camera_act_acts_on_a_camera_scene():
    from backbones import LeRobotBackbone

    from lerobot_physvla.sim.scenes import make_scene

    scene = make_scene("libero_object+agentview64/0")
    policy = LeRobotBackbone(str(train_camera.COMMITTED / "object_act_camera"))
    scene.reset(30)
    policy.reset(30)
    a = policy.act(scene, scene.read())
    assert a.shape == (7,) and np.isfinite(a).all() and np.abs(a).max() <= 1.5
    scene.env.close()
