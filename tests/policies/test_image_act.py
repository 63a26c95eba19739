"""The image-input backbone's pipeline: camera scenes, recorded frames, and backbones/train_image_act.py.

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

import train_image_act  # noqa: E402

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


def test_prepare_train_assemble_gives_a_policy_the_harness_runs(dataset, tmp_path, monkeypatch):
    """prepare -> train (2 steps on the CPU, in a subprocess as the GPU machine runs it) -> assemble gives a
    checkpoint whose weights are the run's (sha256), that reads the camera frame, and acts on a camera scene."""
    carry, back, run = tmp_path / "carry", tmp_path / "back", tmp_path / "run"
    train_image_act.prepare(dataset, carry)
    assert not (carry / "init" / "model.safetensors").exists()  # drawn from the seed where it trains
    frames = train_image_act.decode_video(next((carry / "video").glob("*.mp4")))
    images, *_ = train_image_act._frames(dataset)
    assert frames.shape == images.shape
    assert np.abs(frames.astype(int) - images).mean() < 1.5  # H.264 at crf 10: under 1.5 of 255 per pixel
    tr = subprocess.run([sys.executable, str(ROOT / "backbones/train_image_act.py"), "train", "--carry", str(carry),
                         "--out", str(back), "--device", "cpu", "--steps", "2"], capture_output=True, text=True,
                        cwd=ROOT, env={**__import__("os").environ, "OMP_NUM_THREADS": "1"})
    assert tr.returncode == 0, tr.stderr[-2000:]
    parts = sorted(back.glob("run.tar.part*"))
    assert parts and all(p.stat().st_size <= train_image_act.device_train.PART_BYTES for p in parts)
    ckpt = train_image_act.assemble(back, run)
    (parts[0]).write_bytes(b"x" + parts[0].read_bytes()[1:])  # a damaged part is refused
    with pytest.raises(SystemExit, match="sha256"):
        train_image_act.assemble(back, tmp_path / "run2")

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
