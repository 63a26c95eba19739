"""An image-input LeRobot ACT on LIBERO-Spatial: the agentview camera and the arm's state, no object positions.

    .venv/bin/python backbones/record_dataset.py --camera-size 128 --seeds 10-29 --dart-sigma 0.1  # the demonstrations
    .venv/bin/python backbones/train_image_act.py prepare          # here: the initial checkpoint and the data to carry
    python3 backbones/train_image_act.py train --device cuda       # on a GPU machine (the device tool), or here (slow)
    .venv/bin/python backbones/train_image_act.py assemble         # here: the trained checkpoint from what came back

The policy sees what a VLA sees in `lerobot-eval --env.type=libero --env.observation_height=128
--env.observation_width=128`: `observation.images.image` (the agentview frame, 128 x 128) and
`observation.state` (eef xyz, eef axis-angle, finger qpos); nothing tells it where the bowl or the plate is
but the picture. The recipe (RECIPE; fixed before it trained): LeRobot's ACTPolicy with a ResNet-18 trained
from scratch (no pretrained weights can be fetched here), chunk 20 executing 10, lerobot-train's update
(the policy's AdamW preset, gradient norm clipped at 10, batch 64, uniform frames, action chunks padded
at episode ends as LeRobotDataset pads them), seed 1000, its final checkpoint kept (no selection).

Why not `lerobot-train` on the GPU machine: that machine has no registry, and what can travel is 64 MiB.
So `prepare` builds the policy, its normalisation (the dataset's statistics) and processors here with
lerobot, saves them as an ordinary checkpoint, and exports the frames as lossless-in-practice H.264
(crf 10, 4:4:4; mean absolute error under 1 of 255 per pixel: what training saw) plus the state and
action arrays; `train` needs only torch, torchvision, OpenCV and the lerobot wheel (carried, with its
small pure-Python needs) and runs backbones/device_train.py's loop, which hands back the checkpoint in
parts under 16 MiB that `assemble` joins and checks against the sha256 the run recorded.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import device_train  # noqa: E402
from device_train import ACTION, EPISODE, assemble  # noqa: E402,F401 - assemble is this script's API too

DATASET = "outputs/datasets/physvla_libero_spatial_agentview128"
CARRY = Path(".device/image_act")  # what the GPU machine gets (ignored by git: .git/info/exclude)
OUT_RUN = "outputs/train/libero_spatial/act_image"  # where the assembled checkpoint lands
IMAGE, STATE = "observation.images.image", "observation.state"
RECIPE = {
    "policy": "act",
    "chunk_size": 20, "n_action_steps": 10,  # as backbones/train_backbones.py act_chunk
    "dim_model": 256, "n_heads": 8, "dim_feedforward": 1024, "n_encoder_layers": 2, "n_decoder_layers": 1,
    "n_vae_encoder_layers": 2, "latent_dim": 32, "vision_backbone": "resnet18", "pretrained_backbone_weights": None,
    "optimizer_lr": 1e-4, "optimizer_lr_backbone": 1e-4,
    "batch_size": 64, "steps": 10000, "seed": 1000, "video_crf": 10,
}


# ---------------------------------------------------------------- here: prepare, assemble
def policy_config(camera_size: int):
    """The ACTConfig of RECIPE on the image dataset's features."""
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.policies.act.configuration_act import ACTConfig

    r = RECIPE
    return ACTConfig(
        input_features={IMAGE: PolicyFeature(FeatureType.VISUAL, (3, camera_size, camera_size)),
                        STATE: PolicyFeature(FeatureType.STATE, (8,))},
        output_features={ACTION: PolicyFeature(FeatureType.ACTION, (7,))},
        chunk_size=r["chunk_size"], n_action_steps=r["n_action_steps"], dim_model=r["dim_model"], n_heads=r["n_heads"],
        dim_feedforward=r["dim_feedforward"], n_encoder_layers=r["n_encoder_layers"],
        n_decoder_layers=r["n_decoder_layers"], n_vae_encoder_layers=r["n_vae_encoder_layers"], latent_dim=r["latent_dim"], vision_backbone=r["vision_backbone"],
        pretrained_backbone_weights=r["pretrained_backbone_weights"], optimizer_lr=r["optimizer_lr"],
        optimizer_lr_backbone=r["optimizer_lr_backbone"], device="cpu", push_to_hub=False)


def _frames(dataset: Path):
    """(images (N, H, W, 3) uint8, state (N, 8), action (N, 7), episode index (N,)) of a LeRobotDataset on disk."""
    import io

    import pyarrow.parquet as pq
    from PIL import Image

    imgs, state, action, episode = [], [], [], []
    for f in sorted((dataset / "data").glob("chunk-*/file-*.parquet")):
        t = pq.read_table(f, use_threads=False).to_pydict()
        imgs += [np.asarray(Image.open(io.BytesIO(d["bytes"])).convert("RGB")) for d in t[IMAGE]]
        state += t[STATE]
        action += t[ACTION]
        episode += t["episode_index"]
    if not imgs:
        raise SystemExit(f"train_image_act: no frames under {dataset}/data; record them first "
                         "(backbones/record_dataset.py --camera-size 128)")
    return (np.stack(imgs), np.asarray(state, np.float32), np.asarray(action, np.float32), np.asarray(episode, np.int64))


def encode_video(frames: np.ndarray, path: Path, crf: int) -> None:
    """(T, H, W, 3) uint8 -> H.264 4:4:4 at `crf` (PyAV, which lerobot's dataset extra installs)."""
    import av

    with av.open(str(path), "w") as c:
        s = c.add_stream("libx264", rate=20)
        s.width, s.height, s.pix_fmt, s.options = frames.shape[2], frames.shape[1], "yuv444p", {"crf": str(crf)}
        for im in frames:
            for p in s.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(im), format="rgb24")):
                c.mux(p)
        for p in s.encode():
            c.mux(p)


def prepare(dataset: Path, carry: Path) -> None:
    """The initial checkpoint (policy, processors with the dataset's statistics) and the frames to carry."""
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata

    meta = LeRobotDatasetMetadata(f"local/{dataset.name}", root=dataset)
    size = int(meta.features[IMAGE]["shape"][0])
    if carry.exists():
        shutil.rmtree(carry)
    device_train.write_init(policy_config(size), meta, RECIPE["seed"], carry)
    images, state, action, episode = _frames(dataset)
    (carry / "video").mkdir(parents=True)
    for e in np.unique(episode):
        encode_video(images[episode == e], carry / "video" / f"episode_{e:04d}.mp4", RECIPE["video_crf"])
    np.savez(carry / "arrays.npz", **{STATE: state, ACTION: action, EPISODE: episode})
    (carry / "recipe.json").write_text(json.dumps({**RECIPE, "dataset": str(dataset), "episodes": int(len(np.unique(episode))),
                                                   "frames": int(len(episode)), "camera_size": size}, indent=1))
    mb = sum(p.stat().st_size for p in carry.rglob("*") if p.is_file()) / 2**20
    print(f"prepared {carry}: {len(np.unique(episode))} episodes, {len(episode)} frames, {mb:.1f} MiB to carry")


# ---------------------------------------------------------------- the GPU machine (or here): train
def decode_video(path: Path) -> np.ndarray:
    """(T, H, W, 3) uint8 RGB frames of an H.264 file (OpenCV)."""
    import cv2

    cap, out = cv2.VideoCapture(str(path)), []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        out.append(frame[:, :, ::-1])
    cap.release()
    if not out:
        raise SystemExit(f"train_image_act: OpenCV decoded no frame of {path}")
    return np.stack(out)


def train(carry: Path, out: Path, device: str, steps: int | None, max_minutes: float) -> None:
    """device_train's loop with the decoded frames as the image input."""
    arrays = np.load(carry / "arrays.npz")
    episode = arrays[EPISODE]
    images = np.concatenate([decode_video(carry / "video" / f"episode_{e:04d}.mp4") for e in np.unique(episode)])
    if len(images) != len(episode):
        raise SystemExit(f"train_image_act: {len(images)} decoded frames for {len(episode)} recorded")
    device_train.train(carry, out, device, steps, max_minutes, frames={IMAGE: images})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("prepare", help="here: the initial checkpoint and the data the GPU machine needs")
    p.add_argument("--dataset", default=DATASET)
    p.add_argument("--carry", default=str(CARRY))
    device_train.add_train_parser(sub, "the GPU machine (or here): train RECIPE's steps", str(CARRY),
                                  "outputs/image_act_run", 7.5)
    a = sub.add_parser("assemble", help="here: join what the device run returned into a checkpoint")
    a.add_argument("back", help="the folder holding run.json and run.tar.part*")
    a.add_argument("--out", default=OUT_RUN)
    args = ap.parse_args()
    if args.cmd == "prepare":
        prepare(Path(args.dataset), Path(args.carry))
    elif args.cmd == "train":
        train(Path(args.carry), Path(args.out), args.device, args.steps, args.max_minutes)
    else:
        assemble(Path(args.back), Path(args.out))


if __name__ == "__main__":
    main()
