"""Learned backbones end to end: expert rollouts -> LeRobotDataset v3 -> lerobot-train -> a policy
the harness runs (policies/record_dataset.py, policies/train_backbones.py, eval/backbones.py)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "policies"))
sys.path.insert(0, str(ROOT / "eval"))
import record_dataset  # noqa: E402
import train_backbones  # noqa: E402


def test_parse_range():
    assert record_dataset.parse_range("10-12,15") == [10, 11, 12, 15]


def test_every_recipe_is_state_only_seeded_and_cpu():
    for name in train_backbones.RECIPES:
        cmd = " ".join(train_backbones.command(name, "ds", "out"))
        assert "--policy.device=cpu" in cmd and f"--seed={train_backbones.SEED}" in cmd
        assert "--wandb.enable=false" in cmd and "--policy.push_to_hub=false" in cmd
        assert "image" not in cmd


def test_record_train_and_run_a_learned_backbone(tmp_path):
    ds = tmp_path / "ds"
    rec = subprocess.run([sys.executable, str(ROOT / "policies/record_dataset.py"), "--tasks", "0", "--seeds", "10",
                          "--workers", "1", "--out", str(ds)], capture_output=True, text=True, cwd=ROOT)
    assert rec.returncode == 0, rec.stderr[-2000:]
    info = json.loads((ds / "meta" / "info.json").read_text())
    assert info["total_episodes"] == 1 and info["features"]["observation.environment_state"]["shape"] == [6]
    assert 50 < info["total_frames"] < 280  # one successful expert episode

    train = subprocess.run([sys.executable, str(ROOT / "policies/train_backbones.py"), "act_chunk", "--dataset", str(ds),
                            "--out", str(tmp_path / "train"), "--steps", "2"], capture_output=True, text=True, cwd=ROOT)
    assert train.returncode == 0, train.stdout[-2000:] + train.stderr[-2000:]
    ckpt = train_backbones.checkpoint("act_chunk", str(tmp_path / "train"))
    assert json.loads((ckpt / "recipe.json").read_text())["recipe"] == "act_chunk"

    from backbones import LeRobotBackbone

    from lerobot_physvla.sim.scenes import LiberoScene

    scene = LiberoScene("libero_spatial", 0)
    policy = LeRobotBackbone(str(ckpt))
    scene.reset(0)
    policy.reset(0)
    actions = []
    for _ in range(3):
        a = policy.act(scene, scene.read())
        assert a.shape == (7,) and np.isfinite(a).all()
        actions.append(a)
        scene.step(np.clip(a, -1, 1))
    assert policy.policy.config.n_action_steps == 10  # chunked: the 3 actions come from one chunk
