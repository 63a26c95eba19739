"""Camera-input LeRobot policies (ACT, Diffusion Policy) on a LIBERO suite: the agentview camera and the arm's
state, no object positions.

    .venv/bin/python backbones/record_dataset.py --suite libero_object --camera-size 128 --seeds 10-29 --dart-sigma 0.1
    .venv/bin/python backbones/train_camera.py prepare --suite libero_object     # here: both recipes' inits, the frames
    python3 backbones/train_camera.py train-all --carry .device/camera --device cuda   # GPU machine: every prepared run
    .venv/bin/python backbones/train_camera.py assemble BACK/libero_object_act --out outputs/train/libero_object/act_camera
    .venv/bin/python backbones/train_camera.py commit <run>/checkpoints/005000/pretrained_model --name object_act_camera

The policies see what a VLA sees in `lerobot-eval --env.type=libero --env.observation_height=128
--env.observation_width=128`: `observation.images.image` (the agentview frame) and `observation.state` (eef xyz,
eef axis-angle, finger qpos); nothing tells them where the object or the target is but the picture. One policy per
suite covers its ten tasks: on LIBERO-Spatial and -Object each task has its own layout, so the frame says which task
it is (LIBERO-Goal, one scene for ten tasks, would need the task as an input: no recipe here covers it). The
recipes (RECIPES, fixed before they train): LeRobot's ACTPolicy and DiffusionPolicy with a ResNet-18 trained from
scratch (no pretrained weights can be fetched here), lerobot-train's update (the policy's own optimizer preset,
uniform frames, action chunks and observation histories clamped and padded at episode ends as LeRobotDataset
gives them), seed 1000; a checkpoint every `save_every` steps, so a weaker sibling is an earlier checkpoint of the
same run (chosen on a selection block by a rule fixed before).

Why not `lerobot-train` on the GPU machine: that machine has no registry, and what can travel is 64 MiB.
So `prepare` builds each policy's config, normalisation (the dataset's statistics) and processors here with
lerobot, saves them as an ordinary checkpoint without weights, and exports the suite's frames once as
lossless-in-practice H.264 (crf 10, 4:4:4; mean absolute error under 1 of 255 per pixel: what training saw) plus
the state and action arrays; `train` needs only torch, torchvision, OpenCV and the lerobot wheel (carried, with
its small pure-Python needs, diffusers for Diffusion Policy) and runs backbones/device_train.py's loop, which
hands back the checkpoints in parts under 16 MiB that `assemble` joins and checks against the sha256 the run
recorded. Layout of what travels: <carry>/<suite>/{video/, arrays.npz, <recipe>/{init/, recipe.json}}.
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

SUITES = ("libero_spatial", "libero_object")
CARRY = Path(".device/camera")
COMMITTED = Path(__file__).resolve().parent / "checkpoints" / "camera"  # fp16 camera checkpoints the studies run
COMMIT_MAX_MIB = 30.0  # a committed checkpoint's weights at most  # what the GPU machine gets (ignored by git: .git/info/exclude)
IMAGE, STATE = "observation.images.image", "observation.state"
VIDEO_CRF = 10
# name -> recipe: `policy` (act | diffusion) and its config's fields, then the update. `act` is the recipe of the
# image ACT behind eval/results/image_act (chunk 20 executing 10, as backbones/train_backbones.py act_chunk).
# `diffusion`: Diffusion Policy's own choices for a camera policy (2 observations, horizon 16 executing 8, a random
# 112-pixel crop of the 128 frame in training, GroupNorm in the ResNet as it trains from scratch), a U-Net narrowed
# to (64, 128, 256) with kernel 3 (fp16 weights under 30 MiB), DDIM with 10 denoising steps (a cheap call on a CPU).
RECIPES: dict[str, dict] = {
    "act": {"policy": "act", "chunk_size": 20, "n_action_steps": 10, "dim_model": 256, "n_heads": 8,
            "dim_feedforward": 1024, "n_encoder_layers": 2, "n_decoder_layers": 1, "n_vae_encoder_layers": 2,
            "latent_dim": 32, "vision_backbone": "resnet18", "pretrained_backbone_weights": None,
            "optimizer_lr": 1e-4, "optimizer_lr_backbone": 1e-4,
            "batch_size": 64, "steps": 10000, "save_every": 2000, "seed": 1000},
    "diffusion": {"policy": "diffusion", "n_obs_steps": 2, "horizon": 16, "n_action_steps": 8,
                  "vision_backbone": "resnet18", "pretrained_backbone_weights": None, "use_group_norm": True,
                  "crop_shape": (112, 112), "down_dims": (64, 128, 256), "kernel_size": 3, "noise_scheduler_type": "DDIM",
                  "num_inference_steps": 10,
                  "batch_size": 64, "steps": 10000, "save_every": 2000, "seed": 1000},
}
# diffusion64: `diffusion` on 64-pixel frames, its random crop scaled with the frame (56 of 64, as 112 of 128).
RECIPES["diffusion64"] = {**RECIPES["diffusion"], "crop_shape": (56, 56)}
# What a lent GPU hands back: the device tool returns 64 MiB a call and a camera checkpoint is ~30 MiB in fp16, so a
# GPU run returns two checkpoints in fp16 (the cast `commit` makes), fixed before it trains: its last (the strong
# policy) and step 2,000 (its weaker sibling, the first save, as the state ACTs' `_weak` siblings).
for _name in ("act", "diffusion", "diffusion64"):
    RECIPES[_name].update(return_steps=[2000, "last"], return_dtype="float16")
# act_cpu: `act` as this 2-core CPU can train it when no GPU is lent (on 64-pixel frames: 0.44 s a step at batch 32
# here, against 3.4 s at 128 pixels and batch 64): batch 32, 5,000 steps (~40 min), a checkpoint every 1,000.
RECIPES["act_cpu"] = {**RECIPES["act"], "batch_size": 32, "steps": 5000, "save_every": 1000,
                      "return_steps": None, "return_dtype": None}
UPDATE = ("policy", "batch_size", "steps", "save_every", "seed", "return_steps", "return_dtype")  # not config fields
GPU_RECIPES = ("act", "diffusion")  # what `prepare` readies for a lent GPU unless told otherwise


# ---------------------------------------------------------------- here: prepare, assemble
def policy_config(recipe: str, camera_size: int):
    """The ACTConfig / DiffusionConfig of RECIPES[recipe] on the camera dataset's features."""
    from lerobot.configs.types import FeatureType, PolicyFeature

    if recipe not in RECIPES:
        raise SystemExit(f"train_camera: unknown recipe {recipe!r}; one of {', '.join(RECIPES)}")
    r = RECIPES[recipe]
    fields = {k: v for k, v in r.items() if k not in UPDATE}
    features = dict(input_features={IMAGE: PolicyFeature(FeatureType.VISUAL, (3, camera_size, camera_size)),
                                    STATE: PolicyFeature(FeatureType.STATE, (8,))},
                    output_features={ACTION: PolicyFeature(FeatureType.ACTION, (7,))}, device="cpu",
                    push_to_hub=False)
    if r["policy"] == "act":
        from lerobot.policies.act.configuration_act import ACTConfig

        return ACTConfig(**features, **fields)
    from lerobot.policies.diffusion.configuration_diffusion import DiffusionConfig

    crop = fields.get("crop_shape")
    if crop is not None and max(crop) > camera_size:  # a frame smaller than the crop (a smoke test's): no crop
        fields["crop_shape"] = None
    return DiffusionConfig(**features, **fields)


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
        raise SystemExit(f"train_camera: no frames under {dataset}/data; record them first "
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


def prepare(dataset: Path, carry: Path, recipes=GPU_RECIPES) -> None:
    """Under `carry` (one suite's folder): the frames once (video/, arrays.npz) and each recipe's initial checkpoint
    (policy config, processors with the dataset's statistics; no weights: `train` draws them from the seed)."""
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata

    meta = LeRobotDatasetMetadata(f"local/{dataset.name}", root=dataset)
    size = int(meta.features[IMAGE]["shape"][0])
    if carry.exists():
        shutil.rmtree(carry)
    images, state, action, episode = _frames(dataset)
    (carry / "video").mkdir(parents=True)
    for e in np.unique(episode):
        encode_video(images[episode == e], carry / "video" / f"episode_{e:04d}.mp4", VIDEO_CRF)
    np.savez(carry / "arrays.npz", **{STATE: state, ACTION: action, EPISODE: episode})
    for name in recipes:
        r = RECIPES[name]
        device_train.write_init(policy_config(name, size), meta, r["seed"], carry / name)
        (carry / name / "recipe.json").write_text(json.dumps({
            "recipe": name, **{k: v for k, v in r.items() if k in UPDATE}, "dataset": str(dataset),
            "episodes": int(len(np.unique(episode))), "frames": int(len(episode)), "camera_size": size,
            "video_crf": VIDEO_CRF}, indent=1))
    mb = sum(p.stat().st_size for p in carry.rglob("*") if p.is_file()) / 2**20
    print(f"prepared {carry}: {', '.join(recipes)} on {len(np.unique(episode))} episodes, {len(episode)} frames, "
          f"{mb:.1f} MiB to carry")


def commit(ckpt: Path, name: str, root: Path = COMMITTED) -> Path:
    """Copy a trained checkpoint (a pretrained_model folder) to root/name with its weights in fp16: what a study runs
    and the repository keeps (at most COMMIT_MAX_MIB). Its recipe.json keeps the trained fp32 weights' sha256 and
    adds `committed` (dtype, the fp16 file's sha256)."""
    import torch

    weights = ckpt / "model.safetensors"
    if not weights.exists() or not (ckpt / "recipe.json").exists():
        raise SystemExit(f"train_camera: {ckpt} holds no model.safetensors and recipe.json; give a checkpoint's "
                         "pretrained_model folder (outputs/camera_run/<run>/checkpoints/<step>/pretrained_model)")
    dst = root / name
    if dst.exists():
        shutil.rmtree(dst)
    dst.mkdir(parents=True)
    for f in ckpt.iterdir():
        if f.is_file() and f.name not in ("model.safetensors", "recipe.json"):
            shutil.copy(f, dst / f.name)
    sha = device_train.half_safetensors(weights, dst / "model.safetensors")
    mib = (dst / "model.safetensors").stat().st_size / 2**20
    if mib > COMMIT_MAX_MIB:
        shutil.rmtree(dst)
        raise SystemExit(f"train_camera: {name}'s fp16 weights are {mib:.1f} MiB, over {COMMIT_MAX_MIB} MiB")
    recipe = json.loads((ckpt / "recipe.json").read_text())
    recipe["committed"] = {"name": name, "dtype": str(torch.float16).removeprefix("torch."), "from": str(ckpt),
                           "model_sha256": sha}
    (dst / "recipe.json").write_text(json.dumps(recipe, indent=1))
    print(f"committed {ckpt} -> {dst}: fp16 weights {mib:.1f} MiB (step {recipe.get('step')})")
    return dst


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
        raise SystemExit(f"train_camera: OpenCV decoded no frame of {path}")
    return np.stack(out)


def train(carry: Path, out: Path, device: str, steps: int | None, max_minutes: float) -> None:
    """device_train's loop for one recipe (`carry`: <suite>/<recipe>) with its suite's decoded frames."""
    data = carry.parent
    arrays = np.load(data / "arrays.npz")
    episode = arrays[EPISODE]
    images = np.concatenate([decode_video(data / "video" / f"episode_{e:04d}.mp4") for e in np.unique(episode)])
    if len(images) != len(episode):
        raise SystemExit(f"train_camera: {len(images)} decoded frames for {len(episode)} recorded")
    device_train.train(carry, out, device, steps, max_minutes, frames={IMAGE: images}, data=data)


def train_all(root: Path, out: Path, device: str, steps: int | None, max_minutes: float) -> None:
    """Every prepared run under `root` (<suite>/<recipe>/recipe.json) side by side, one process each, into
    out/<suite>_<recipe>: what one call to the GPU machine runs."""
    import subprocess

    runs = sorted(p.parent for p in root.glob("*/*/recipe.json"))
    if not runs:
        raise SystemExit(f"train_camera: nothing prepared under {root}; run `train_camera.py prepare` first")
    out.mkdir(parents=True, exist_ok=True)
    procs = []
    for run in runs:
        cmd = [sys.executable, __file__, "train", "--carry", str(run), "--out", str(out / f"{run.parent.name}_{run.name}"),
               "--device", device, "--max-minutes", str(max_minutes)] + (["--steps", str(steps)] if steps else [])
        log = open(out / f"{run.parent.name}_{run.name}.log", "w")  # noqa: SIM115 - held while the run lasts
        procs.append((run, subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)))
    failed = [str(run) for run, p in procs if p.wait() != 0]
    print(f"train-all: {len(procs) - len(failed)} of {len(procs)} runs done -> {out}"
          + (f"; failed: {', '.join(failed)} (their .log)" if failed else ""))
    if failed:
        raise SystemExit(1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("prepare", help="here: the recipes' initial checkpoints and the frames the GPU machine needs")
    p.add_argument("--suite", choices=SUITES, required=True)
    p.add_argument("--dataset", default=None, help="default outputs/datasets/physvla_<suite>_agentview128")
    p.add_argument("--carry", default=str(CARRY), help="the carry root; the suite's folder goes under it")
    p.add_argument("--recipes", default=",".join(GPU_RECIPES), help=f"of {', '.join(RECIPES)}")
    device_train.add_train_parser(sub, "the GPU machine (or here): train one prepared recipe (<root>/<suite>/<recipe>)",
                                  None, "outputs/camera_run", 7.5)
    device_train.add_train_parser(sub, "the GPU machine: every prepared recipe side by side", str(CARRY),
                                  "outputs/camera_run", 7.5, name="train-all")
    a = sub.add_parser("assemble", help="here: join what a device run returned into a checkpoint folder")
    a.add_argument("back", help="the folder holding run.json and run.tar.part*")
    a.add_argument("--out", required=True, help="e.g. outputs/train/libero_object/act_camera")
    c = sub.add_parser("commit", help="here: a trained checkpoint into backbones/checkpoints/camera/<name> in fp16")
    c.add_argument("checkpoint", help="a pretrained_model folder")
    c.add_argument("--name", required=True, help="e.g. object_act_camera")
    args = ap.parse_args()
    if args.cmd == "commit":
        commit(Path(args.checkpoint), args.name)
    elif args.cmd == "prepare":
        dataset = Path(args.dataset or f"outputs/datasets/physvla_{args.suite}_agentview128")
        prepare(dataset, Path(args.carry) / args.suite, tuple(args.recipes.split(",")))
    elif args.cmd == "train":
        train(Path(args.carry), Path(args.out), args.device, args.steps, args.max_minutes)
    elif args.cmd == "train-all":
        train_all(Path(args.carry), Path(args.out), args.device, args.steps, args.max_minutes)
    else:
        assemble(Path(args.back), Path(args.out))


if __name__ == "__main__":
    main()
