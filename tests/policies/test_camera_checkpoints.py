"""The committed camera checkpoints (backbones/checkpoints/camera): each one's weights are the ones every episode of
eval/results/camera_libero_pro recorded for it, in float16 and under 30 MiB, with the recipe that trained them; the
harness runs one on the CPU."""

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

STUDY = ROOT / "eval/results/camera_libero_pro"


def test_each_committed_camera_checkpoint_is_the_one_the_study_ran_in_fp16():
    from safetensors import safe_open

    from store import Store

    ran_with = Store(STUDY).meta["backbones"]
    names = sorted(p.name for p in train_camera.COMMITTED.iterdir() if (p / "model.safetensors").exists())
    assert names == ["object_act_camera", "object_act_camera_weak"]
    for name in names:
        ckpt = train_camera.COMMITTED / name
        weights = ckpt / "model.safetensors"
        sha = hashlib.sha256(weights.read_bytes()).hexdigest()
        assert ran_with[name] == {"policy_sha256": sha}, name
        assert weights.stat().st_size <= train_camera.COMMIT_MAX_MIB * 2**20
        with safe_open(str(weights), "pt") as f:
            assert {str(f.get_slice(k).get_dtype()) for k in f.keys()} <= {"F16", "I64"}
        recipe = json.loads((ckpt / "recipe.json").read_text())
        assert recipe["committed"] == {**recipe["committed"], "name": name, "dtype": "float16", "model_sha256": sha}
        assert recipe["recipe"] == "act_cpu" and "CPU" in recipe["device"]
        assert recipe["step"] == {"object_act_camera": 5000, "object_act_camera_weak": 2000}[name]


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
