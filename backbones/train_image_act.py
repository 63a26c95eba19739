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
small pure-Python needs), and hands back `model.safetensors` in parts under 16 MiB that `assemble`
joins and checks against the sha256 the run recorded.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np

DATASET = "outputs/datasets/physvla_libero_spatial_agentview128"
CARRY = Path(".device/image_act")  # what the GPU machine gets (ignored by git: .git/info/exclude)
OUT_RUN = "outputs/train/libero_spatial/act_image"  # where the assembled checkpoint lands
IMAGE, STATE, ACTION = "observation.images.image", "observation.state", "action"
PART_BYTES = 15 * 2**20  # the device tool returns files of at most 16 MiB
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
    import torch

    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata
    from lerobot.policies.act.modeling_act import ACTPolicy
    from lerobot.policies.factory import make_pre_post_processors

    meta = LeRobotDatasetMetadata(f"local/{dataset.name}", root=dataset)
    size = int(meta.features[IMAGE]["shape"][0])
    cfg = policy_config(size)
    torch.manual_seed(RECIPE["seed"])
    policy = ACTPolicy(cfg)
    pre, post = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    if carry.exists():
        shutil.rmtree(carry)
    init = carry / "init"
    policy.save_pretrained(init)
    (init / "model.safetensors").unlink()  # `train` draws the same initial weights from the seed
    pre.save_pretrained(init)
    post.save_pretrained(init)
    images, state, action, episode = _frames(dataset)
    (carry / "video").mkdir(parents=True)
    for e in np.unique(episode):
        encode_video(images[episode == e], carry / "video" / f"episode_{e:04d}.mp4", RECIPE["video_crf"])
    np.savez(carry / "arrays.npz", state=state, action=action, episode=episode)
    (carry / "recipe.json").write_text(json.dumps({**RECIPE, "dataset": str(dataset), "episodes": int(len(np.unique(episode))),
                                                   "frames": int(len(episode)), "camera_size": size}, indent=1))
    mb = sum(p.stat().st_size for p in carry.rglob("*") if p.is_file()) / 2**20
    print(f"prepared {carry}: {len(np.unique(episode))} episodes, {len(episode)} frames, {mb:.1f} MiB to carry")


def assemble(back: Path, out_run: Path) -> Path:
    """Join the returned parts into <out_run>/checkpoints/last/pretrained_model and check the sha256."""
    import tarfile

    rest = back / "checkpoint_rest.tar"
    if not rest.exists():
        raise SystemExit(f"train_image_act: {rest} missing; copy the device run's files there first")
    dst = out_run / "checkpoints" / "last" / "pretrained_model"
    if dst.exists():
        shutil.rmtree(dst)
    dst.mkdir(parents=True)
    with tarfile.open(rest) as t:
        t.extractall(dst, filter="data")
    parts = sorted(back.glob("model.safetensors.part*"))
    with open(dst / "model.safetensors", "wb") as f:
        for p in parts:
            f.write(p.read_bytes())
    recipe = json.loads((dst / "recipe.json").read_text())
    digest = hashlib.sha256((dst / "model.safetensors").read_bytes()).hexdigest()
    if digest != recipe["model_sha256"]:
        raise SystemExit(f"train_image_act: the joined weights' sha256 {digest} is not the run's {recipe['model_sha256']}")
    print(f"assembled {dst} ({len(parts)} parts, sha256 {digest[:12]}), {recipe['steps_done']} steps in "
          f"{recipe['train_seconds'] / 60:.1f} min on {recipe['device']}")
    return dst


# ---------------------------------------------------------------- the GPU machine (or here): train
def _import_lerobot():
    """ACTPolicy, PreTrainedConfig and PolicyProcessorPipeline. On a machine with lerobot but without its dataset extra (PyAV: a
    bare GPU machine), lerobot.policies' package init fails on the dataset stack it imports; the two modules
    needed here do not use it, so they load with that init skipped."""
    import importlib.util

    if importlib.util.find_spec("av") is None:  # lerobot without its dataset extra: skip lerobot.policies' init
        import types

        import lerobot

        pkg = types.ModuleType("lerobot.policies")
        pkg.__path__ = [str(Path(lerobot.__file__).parent / "policies")]
        sys.modules.setdefault("lerobot.policies", pkg)
    from lerobot.policies.act.modeling_act import ACTPolicy
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.processor import PolicyProcessorPipeline

    return ACTPolicy, PreTrainedConfig, PolicyProcessorPipeline


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


def chunk_index(episode: np.ndarray, chunk: int) -> tuple[np.ndarray, np.ndarray]:
    """(N, chunk) frame indices of each frame's action chunk, clamped to its episode's last frame, and the pad
    mask (True past the episode's end), as LeRobotDataset's delta_timestamps give them to ACT."""
    n = len(episode)
    last = np.empty(n, np.int64)
    for e in np.unique(episode):
        idx = np.flatnonzero(episode == e)
        last[idx] = idx[-1]
    raw = np.arange(n)[:, None] + np.arange(chunk)[None]
    return np.minimum(raw, last[:, None]), raw > last[:, None]


def train(carry: Path, out: Path, device: str, steps: int | None, max_minutes: float) -> None:
    import tarfile

    import torch

    ACTPolicy, PreTrainedConfig, PolicyProcessorPipeline = _import_lerobot()
    recipe = json.loads((carry / "recipe.json").read_text())
    steps = int(steps or recipe["steps"])
    torch.manual_seed(recipe["seed"])
    np.random.seed(recipe["seed"])
    t0 = time.time()
    arrays = np.load(carry / "arrays.npz")
    episode = arrays["episode"]
    images = np.concatenate([decode_video(carry / "video" / f"episode_{e:04d}.mp4") for e in np.unique(episode)])
    if len(images) != len(episode):
        raise SystemExit(f"train_image_act: {len(images)} decoded frames for {len(episode)} recorded")
    print(f"data: {len(episode)} frames of {len(np.unique(episode))} episodes decoded in {time.time() - t0:.0f} s", flush=True)

    cfg = PreTrainedConfig.from_pretrained(str(carry / "init"))
    cfg.device = device
    torch.manual_seed(recipe["seed"])  # the initial weights, as `prepare` drew them
    policy = ACTPolicy(cfg)
    policy.to(device).train()
    pre = PolicyProcessorPipeline.from_pretrained(str(carry / "init"), config_filename="policy_preprocessor.json",
                                                  overrides={"device_processor": {"device": device}})
    optim_cfg = policy.config.get_optimizer_preset()
    optimizer = optim_cfg.build(policy.get_optim_params())
    idx, pad = chunk_index(episode, policy.config.chunk_size)
    dev = torch.device(device)
    img_t = torch.from_numpy(images).to(dev).permute(0, 3, 1, 2).contiguous()  # (N, 3, H, W) uint8
    state_t, action_t = torch.from_numpy(arrays["state"]).to(dev), torch.from_numpy(arrays["action"]).to(dev)
    idx_t, pad_t = torch.from_numpy(idx).to(dev), torch.from_numpy(pad).to(dev)
    gen = torch.Generator(device=dev).manual_seed(recipe["seed"])
    bs, t_train, done, losses = recipe["batch_size"], time.time(), 0, []
    for step in range(1, steps + 1):
        b = torch.randint(0, len(episode), (bs,), device=dev, generator=gen)
        batch = {IMAGE: img_t[b].float() / 255.0, STATE: state_t[b], ACTION: action_t[idx_t[b]],
                 "action_is_pad": pad_t[b]}
        batch = pre(batch)
        loss, _ = policy.forward(batch)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(policy.parameters(), optim_cfg.grad_clip_norm)
        optimizer.step()
        done = step
        losses.append(float(loss.detach()) if step % 50 == 0 or step == 1 else None)
        if step % 500 == 0 or step == 1:
            rate = step / (time.time() - t_train)
            print(f"step {step}/{steps}  loss {float(loss.detach()):.4f}  {rate:.1f} steps/s", flush=True)
        if (time.time() - t0) / 60 > max_minutes:
            print(f"stopping at step {step}: the {max_minutes} min bound", flush=True)
            break
    secs = time.time() - t_train
    ckpt = out / "pretrained_model"
    policy.config.device = "cpu"
    policy.to("cpu").save_pretrained(ckpt)
    for f in (carry / "init").iterdir():  # the processors, as prepared (their device step says cpu)
        if f.name.startswith("policy_") and not (ckpt / f.name).exists():
            shutil.copy(f, ckpt / f.name)
    weights = (ckpt / "model.safetensors").read_bytes()
    name = torch.cuda.get_device_name(0) + " (cuda)" if device.startswith("cuda") else f"CPU, {os.cpu_count()} cores"
    (ckpt / "recipe.json").write_text(json.dumps({
        **recipe, "steps_done": done, "train_seconds": secs, "device": name, "torch": torch.__version__,
        "loss_every_50": [x for x in losses if x is not None], "model_sha256": hashlib.sha256(weights).hexdigest(),
        "command": " ".join(sys.argv)}, indent=1))
    with tarfile.open(out / "checkpoint_rest.tar", "w") as t:
        for f in sorted(ckpt.iterdir()):
            if f.name != "model.safetensors":
                t.add(f, arcname=f.name)
    for i in range(0, len(weights), PART_BYTES):
        (out / f"model.safetensors.part{i // PART_BYTES:02d}").write_bytes(weights[i:i + PART_BYTES])
    shutil.rmtree(ckpt)
    print(f"trained {done} steps in {secs / 60:.1f} min on {name}; {len(weights) / 2**20:.1f} MiB of weights in "
          f"{-(-len(weights) // PART_BYTES)} parts -> {out}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("prepare", help="here: the initial checkpoint and the data the GPU machine needs")
    p.add_argument("--dataset", default=DATASET)
    p.add_argument("--carry", default=str(CARRY))
    t = sub.add_parser("train", help="the GPU machine (or here): train RECIPE's steps")
    t.add_argument("--carry", default=str(CARRY))
    t.add_argument("--out", default=os.environ.get("OUT", "outputs/image_act_run"))
    t.add_argument("--device", default="cuda")
    t.add_argument("--steps", type=int, default=None, help="override the recipe's steps (smoke tests)")
    t.add_argument("--max-minutes", type=float, default=7.5, help="save and stop once this much time has passed")
    a = sub.add_parser("assemble", help="here: join what the device run returned into a checkpoint")
    a.add_argument("back", help="the folder holding checkpoint_rest.tar and model.safetensors.part*")
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
