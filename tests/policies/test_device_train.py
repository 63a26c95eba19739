"""backbones/device_train.py: the state recipes' policy, the action chunks it trains on, prepare -> train -> assemble.

One tiny state dataset (LIBERO-Spatial task 0, init state 0) is recorded once for the module.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "backbones"))
sys.path.insert(0, str(ROOT / "eval"))

import device_train  # noqa: E402


def test_act_chunk_long_is_act_chunks_policy():
    """act_chunk_long's ACTConfig is the one lerobot-train wrote for act_chunk on LIBERO-Goal (the committed
    checkpoint's config.json), field by field: only the update (batch, steps) differs."""
    committed = ROOT / "backbones/checkpoints/goal_act_chunk"
    want = json.loads((committed / "config.json").read_text())
    meta = SimpleNamespace(features={"observation.state": {"shape": [8]},
                                     "observation.environment_state": {"shape": [6]}, "action": {"shape": [7]}})
    cfg = device_train.state_policy_config("act_chunk_long", meta)
    got = json.loads(json.dumps(cfg.__dict__ | {"type": cfg.type}, default=lambda o: getattr(o, "value", o.__dict__)))
    for io in ("input_features", "output_features"):
        got[io] = {k: {"type": v["type"], "shape": list(v["shape"])} for k, v in got[io].items()}
    diff = {k: (got.get(k), v) for k, v in want.items() if got.get(k) != v}
    assert diff == {}
    assert json.loads((committed / "recipe.json").read_text())["command"].count("--batch_size=32") == 1
    assert device_train.STATE_RECIPES["act_chunk_long"]["batch_size"] == 128
    assert device_train.STATE_RECIPES["act_chunk_b128"]["policy"] == device_train.STATE_RECIPES["act_chunk_long"]["policy"]


def test_a_run_returns_the_recipes_return_steps_only():
    """What fits the device tool's 64 MiB: the recipe's return_steps ("last": where the run stopped), else all."""
    saved = [2000, 4000, 6000, 7300]
    assert device_train.returned_steps({"return_steps": [2000, "last"]}, saved, 7300) == [2000, 7300]
    assert device_train.returned_steps({"return_steps": [2000, "last"]}, [2], 2) == [2]  # a run stopped before 2000
    assert device_train.returned_steps({}, saved, 7300) == saved


def test_half_safetensors_casts_floats_and_keeps_integers(tmp_path):
    import torch
    from safetensors.torch import load_file, save_file

    save_file({"w": torch.randn(3, 2), "n": torch.tensor([5], dtype=torch.int64)}, str(tmp_path / "m.safetensors"))
    sha = device_train.half_safetensors(tmp_path / "m.safetensors", tmp_path / "h.safetensors")
    h = load_file(str(tmp_path / "h.safetensors"))
    assert h["w"].dtype == torch.float16 and h["n"].dtype == torch.int64 and h["n"].item() == 5
    assert sha == __import__("hashlib").sha256((tmp_path / "h.safetensors").read_bytes()).hexdigest()
    assert device_train.half_safetensors(tmp_path / "h.safetensors", tmp_path / "h2.safetensors") == sha  # idempotent


def test_chunk_index_clamps_and_pads_at_episode_ends():
    idx, pad = device_train.chunk_index(np.array([0, 0, 0, 1, 1]), 3)
    np.testing.assert_array_equal(idx, [[0, 1, 2], [1, 2, 2], [2, 2, 2], [3, 4, 4], [4, 4, 4]])
    np.testing.assert_array_equal(pad, [[0, 0, 0], [0, 0, 1], [0, 1, 1], [0, 0, 1], [0, 1, 1]])


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    ds = tmp_path_factory.mktemp("state") / "ds"
    rec = subprocess.run([sys.executable, str(ROOT / "backbones/record_dataset.py"), "--tasks", "0", "--seeds", "0",
                          "--dart-sigma", "0", "--workers", "1", "--out", str(ds)],
                         capture_output=True, text=True, cwd=ROOT)
    assert rec.returncode == 0, rec.stderr[-2000:]
    return ds


@pytest.mark.slow
def test_chunks_are_lerobot_datasets(dataset):
    """The action chunk and pad mask train() draws for a frame are what LeRobotDataset gives ACT there."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    arrays = device_train.dataset_arrays(dataset, ["observation.state", "observation.environment_state"])
    idx, pad = device_train.chunk_index(arrays["episode_index"], 20)
    ds = LeRobotDataset(f"local/{dataset.name}", root=dataset, delta_timestamps={"action": [i / 20 for i in range(20)]})
    n = len(arrays["episode_index"])
    for k in (0, n // 2, n - 5, n - 1):
        item = ds[k]
        np.testing.assert_allclose(arrays["action"][idx[k]], item["action"].numpy(), atol=1e-6)
        np.testing.assert_array_equal(pad[k], item["action_is_pad"].numpy())
        np.testing.assert_allclose(arrays["observation.state"][k], item["observation.state"].numpy(), atol=1e-6)


@pytest.mark.slow
def test_prepare_train_assemble_gives_checkpoints_the_harness_runs(dataset, tmp_path):
    """prepare -> train (4 steps on the CPU, a checkpoint every 2, in a subprocess as the GPU machine runs it) ->
    assemble gives both checkpoints and `last`, refuses a damaged part, and the policy acts on the scene."""
    carry, back, run = tmp_path / "carry", tmp_path / "back", tmp_path / "run"
    device_train.prepare_state(dataset, "act_chunk_long", carry)
    assert not (carry / "init" / "model.safetensors").exists()
    recipe = json.loads((carry / "recipe.json").read_text())
    (carry / "recipe.json").write_text(json.dumps(recipe | {"save_every": 2}))
    tr = subprocess.run([sys.executable, str(ROOT / "backbones/device_train.py"), "train", "--carry", str(carry),
                         "--out", str(back), "--device", "cpu", "--steps", "4"], capture_output=True, text=True,
                        cwd=ROOT, env={**os.environ, "OMP_NUM_THREADS": "1"})
    assert tr.returncode == 0, tr.stderr[-2000:]
    assert json.loads((back / "run.json").read_text())["saved"] == [2, 4]
    last = device_train.assemble(back, run)
    steps = sorted(p.name for p in (run / "checkpoints").iterdir())
    assert steps == ["000002", "000004", "last"]
    a = (run / "checkpoints/000002/pretrained_model/model.safetensors").read_bytes()
    b = (last / "model.safetensors").read_bytes()
    assert a != b  # two steps of AdamW moved the weights
    parts = sorted(back.glob("run.tar.part*"))
    parts[0].write_bytes(b"x" + parts[0].read_bytes()[1:])
    with pytest.raises(SystemExit, match="sha256"):
        device_train.assemble(back, tmp_path / "run2")

    from backbones import LeRobotBackbone

    from lerobot_physvla.sim.scenes import make_scene

    policy = LeRobotBackbone(str(last))
    scene = make_scene("libero_spatial/0")
    scene.reset(0)
    policy.reset(0)
    for _ in range(12):
        act = policy.act(scene, scene.read())
        assert act.shape == (7,) and np.isfinite(act).all()
        scene.step(np.clip(act, -1, 1))
