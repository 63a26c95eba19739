"""The camera policies' pipeline: camera scenes, recorded frames, and backbones/train_camera.py (ACT, Diffusion).

One tiny dataset (LIBERO-Spatial task 0, init state 0, agentview at 64 x 64) is recorded once for the module.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "backbones"))
sys.path.insert(0, str(ROOT / "eval"))

import train_camera  # noqa: E402

pytestmark = pytest.mark.slow
SIZE = 64


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    ds = tmp_path_factory.mktemp("image") / "ds"
    rec = subprocess.run([sys.executable, str(ROOT / "backbones/record_dataset.py"), "--tasks", "0", "--seeds", "0",
                          "--dart-sigma", "0", "--workers", "1", "--camera-size", str(SIZE), "--out", str(ds)],
                         capture_output=True, text=True, cwd=ROOT)
    assert rec.returncode == 0, rec.stderr[-2000:]
    return ds


def test_camera_scene_names_parse_and_bad_ones_say_how():
    from lerobot_physvla.sim.scenes import make_scene, parse_suite

    assert parse_suite("libero_spatial") == ("libero_spatial", 0)
    assert parse_suite("libero_object+agentview128") == ("libero_object", 128)
    with pytest.raises(ValueError, match=r"libero_spatial\+agentview128/0"):
        make_scene("libero_spatial+agentviewbig/0")


def test_recorded_frames_are_what_lerobot_eval_feeds_an_image_policy(dataset):
    """The dataset holds the image a policy sees in lerobot-eval's LIBERO env with cameras (turned by its
    env processor) and no object state: the recorded episode replayed there gives the recorded frame
    and state at its first frames; the harness's own (lazy) frame is close to it."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset
    from lerobot.envs.utils import preprocess_observation

    from lerobot_physvla.envs.libero_physvla import LiberoPhysVLAEnvConfig
    from lerobot_physvla.sim.scenes import LiberoScene

    data = LeRobotDataset("local/image", root=dataset)
    assert "observation.environment_state" not in data.features
    assert tuple(data.features["observation.images.image"]["shape"]) == (SIZE, SIZE, 3)
    cfg_env = LiberoPhysVLAEnvConfig(task="libero_spatial", task_ids=[0], observation_height=SIZE,
                                     observation_width=SIZE)
    vec = cfg_env.create_envs(n_envs=1)["libero_spatial"][0]
    env_pre, _ = cfg_env.get_env_processors()
    try:
        obs, _ = vec.reset(seed=[0])
        for t in range(6):
            seen = env_pre(preprocess_observation(obs))
            frame = data[t]
            img = seen["observation.images.image"][0].numpy()
            assert img.shape == (3, SIZE, SIZE)
            np.testing.assert_array_equal(img, frame["observation.images.image"].numpy(), err_msg=f"frame {t}")
            if t == 1:  # the harness's frame, rendered after the step: close, not equal (the arm moved 2 ms more)
                lazy = LiberoScene("libero_spatial", 0, camera_size=SIZE)
                lazy.reset(0)
                lazy.step(data[0]["action"].numpy().astype(np.float64))
                diff = np.abs(lazy.frame().astype(int) - np.asarray(frame["observation.images.image"].numpy() * 255).round().transpose(1, 2, 0))
                assert 0 < (diff > 0).mean() < 0.1 and diff.mean() < 1.0
            np.testing.assert_allclose(seen["observation.state"][0].numpy(), frame["observation.state"].numpy(),
                                       atol=1e-4)
            obs, *_ = vec.step(frame["action"].numpy()[None].astype(np.float64))
    finally:
        vec.close()


@pytest.fixture(scope="module")
def trained(dataset, tmp_path_factory) -> Path:
    """prepare (both recipes) -> train-all (2 steps each on the CPU, in subprocesses as the GPU machine runs them);
    the folder the runs came back in."""
    root = tmp_path_factory.mktemp("camera") / "carry"
    train_camera.prepare(dataset, root / "libero_spatial")
    back = root.parent / "back"
    tr = subprocess.run([sys.executable, str(ROOT / "backbones/train_camera.py"), "train-all", "--carry", str(root),
                         "--out", str(back), "--device", "cpu", "--steps", "2"], capture_output=True, text=True,
                        cwd=ROOT, env={**__import__("os").environ, "OMP_NUM_THREADS": "1"})
    assert tr.returncode == 0, tr.stdout[-2000:] + tr.stderr[-2000:]
    assert "2 of 2 runs done" in tr.stdout
    return back


def test_prepare_carries_the_frames_once_and_each_recipe_without_weights(dataset, trained):
    suite = trained.parent / "carry" / "libero_spatial"
    for recipe in train_camera.GPU_RECIPES:
        assert (suite / recipe / "init" / "config.json").exists()
        assert not (suite / recipe / "init" / "model.safetensors").exists()  # drawn from the seed where it trains
    frames = train_camera.decode_video(next((suite / "video").glob("*.mp4")))
    images, *_ = train_camera._frames(dataset)
    assert frames.shape == images.shape
    assert np.abs(frames.astype(int) - images).mean() < 1.5  # H.264 at crf 10: under 1.5 of 255 per pixel


def test_the_diffusion_policy_trains_on_observation_histories_and_acts(trained, tmp_path):
    """Diffusion Policy's batch holds its 2-frame history (clamped at an episode's first frame) and its 16-step
    horizon from t - 1; the assembled checkpoint acts on a camera scene every step (it reads every frame)."""
    from device_train import frame_index

    idx, pad = frame_index(np.array([0, 0, 0, 1, 1]), [-1, 0, 1])
    np.testing.assert_array_equal(idx, [[0, 0, 1], [0, 1, 2], [1, 2, 2], [3, 3, 4], [3, 4, 4]])
    np.testing.assert_array_equal(pad, [[1, 0, 0], [0, 0, 0], [0, 0, 1], [1, 0, 0], [0, 0, 1]])
    ckpt = train_camera.assemble(trained / "libero_spatial_diffusion", tmp_path / "run")

    from backbones import LeRobotBackbone

    from lerobot_physvla.sim.scenes import make_scene

    policy = LeRobotBackbone(str(ckpt))
    assert policy.policy.config.type == "diffusion" and policy.actions_per_call == 8
    scene = make_scene(f"libero_spatial+agentview{SIZE}/0")
    scene.reset(0)
    policy.reset(0)
    for _ in range(3):
        assert policy.reads_observation()
        a = policy.act(scene, scene.read())
        assert a.shape == (7,) and np.isfinite(a).all()
        scene.step(np.clip(a, -1, 1))


def test_prepare_train_assemble_gives_a_policy_the_harness_runs(trained, tmp_path, monkeypatch):
    """The ACT run's checkpoint: its weights are the run's (sha256), it reads the camera frame, and acts on a camera
    scene, rendering one frame a chunk."""
    back, run = trained / "libero_spatial_act", tmp_path / "run"
    parts = sorted(back.glob("run.tar.part*"))
    assert parts and all(p.stat().st_size <= train_camera.device_train.PART_BYTES for p in parts)
    ckpt = train_camera.assemble(back, run)
    import json

    from safetensors.torch import load_file

    recipe = json.loads((ckpt / "recipe.json").read_text())  # handed back in fp16, as `commit` casts
    assert {str(v.dtype) for v in load_file(str(ckpt / "model.safetensors")).values() if v.is_floating_point()} \
        == {"torch.float16"}
    assert recipe["returned"]["model_sha256"] == __import__("hashlib").sha256(
        (ckpt / "model.safetensors").read_bytes()).hexdigest()
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    for f in back.iterdir():
        (damaged / f.name).write_bytes(f.read_bytes())
    first = sorted(damaged.glob("run.tar.part*"))[0]
    first.write_bytes(b"x" + first.read_bytes()[1:])  # a damaged part is refused
    with pytest.raises(SystemExit, match="sha256"):
        train_camera.assemble(damaged, tmp_path / "run2")

    from backbones import LeRobotBackbone

    from lerobot_physvla.sim.scenes import make_scene

    policy = LeRobotBackbone(str(ckpt))
    assert set(policy.policy.config.input_features) == {"observation.images.image", "observation.state"}
    scene = make_scene(f"libero_spatial+agentview{SIZE}/0")

    def run(lazy: bool) -> tuple[np.ndarray, int]:
        """25 steps (three chunks of 10): the actions, and how many frames were rendered."""
        scene.reset(0)
        policy.reset(0)
        rendered, acts, frame = [0], [], scene.frame

        def counted():
            rendered[0] += 1
            return frame()

        monkeypatch.setattr(scene, "frame", counted)
        if not lazy:
            monkeypatch.setattr(policy, "reads_observation", lambda: True)
        for _ in range(25):
            a = policy.act(scene, scene.read())
            assert a.shape == (7,) and np.isfinite(a).all()
            acts.append(a)
            scene.step(np.clip(a, -1, 1))
        monkeypatch.undo()
        return np.asarray(acts), rendered[0]

    lazy, n_lazy = run(lazy=True)
    eager, n_eager = run(lazy=False)
    assert (n_lazy, n_eager) == (3, 25)  # one frame a chunk
    np.testing.assert_array_equal(lazy, eager)  # frames the policy does not read change nothing


def test_commit_keeps_a_checkpoint_in_fp16_that_acts_as_the_trained_one(trained, tmp_path):
    """train_camera.commit of what a GPU run hands back (fp16 already, `return_dtype`): the weights in float16, the
    recipe with the committed file's sha256 (the returned one: the cast is tested in test_device_train), and a policy
    that acts as the assembled checkpoint does."""
    import hashlib
    import json

    from safetensors.torch import load_file

    from backbones import LeRobotBackbone

    from lerobot_physvla.sim.scenes import make_scene

    ckpt = train_camera.assemble(trained / "libero_spatial_act", tmp_path / "run")
    dst = train_camera.commit(ckpt, "act_x", root=tmp_path / "committed")
    w = load_file(str(dst / "model.safetensors"))
    assert {str(v.dtype) for v in w.values() if v.is_floating_point()} == {"torch.float16"}
    recipe = json.loads((dst / "recipe.json").read_text())
    assert recipe["committed"]["model_sha256"] == hashlib.sha256((dst / "model.safetensors").read_bytes()).hexdigest()
    # the run handed it back in fp16 already: committing it keeps those bytes (the cast is tested in test_device_train)
    assert recipe["committed"]["model_sha256"] == recipe["returned"]["model_sha256"]
    scene = make_scene(f"libero_spatial+agentview{SIZE}/0")
    acts = []
    for path in (ckpt, dst):
        policy = LeRobotBackbone(str(path))
        scene.reset(0)
        policy.reset(0)
        acts.append(np.asarray(policy.act(scene, scene.read())))
    assert np.isfinite(acts[1]).all() and np.abs(acts[0] - acts[1]).max() < 1e-2
    with pytest.raises(SystemExit, match="no model.safetensors"):
        train_camera.commit(tmp_path, "nothing", root=tmp_path / "committed")
