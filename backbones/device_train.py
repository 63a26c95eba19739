"""Train a LeRobot ACT or Diffusion Policy on a lent GPU machine from arrays carried to it, and bring its checkpoints back.

    .venv/bin/python backbones/device_train.py prepare --suite libero_goal --recipe act_chunk_long   # here
    python3 backbones/device_train.py train --carry .device/libero_goal_act_chunk_long --out $OUT/goal  # GPU machine
    .venv/bin/python backbones/device_train.py assemble BACK --out outputs/train/libero_goal/act_chunk_long  # here

Why not `lerobot-train` there: the GPU machine has no registry and 64 MiB travel to it, and lerobot-train's
data loader ran the small state ACT at 25 steps/s on an H100 (eval/results/learned/recipes). So `prepare`
builds the policy's config and processors (normalised with the dataset's statistics) here with lerobot and
writes the frames as arrays; `train` needs only torch and the lerobot wheel (carried, with its small
pure-Python needs), holds every frame on the device, and runs lerobot-train's update: the policy's AdamW
preset, gradient norm clipped at its preset, frames drawn uniformly, action chunks clamped and padded at
episode ends as LeRobotDataset pads them. It saves a checkpoint every `save_every` steps as
outputs/train/<suite>/<recipe>/checkpoints/<step>/pretrained_model, packs them in one tar in parts of at most
15 MiB (the device tool returns files of at most 16 MiB), and `assemble` joins and checks them (sha256).

backbones/train_camera.py prepares the camera policies (ACT, Diffusion Policy) the same way; their frames travel as H.264.

State recipes (STATE_RECIPES) are the lerobot-train recipes of backbones/train_backbones.py with the same
policy (a test compares the configs), trained longer at a larger batch.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import sys
import tarfile
import time
from pathlib import Path

import numpy as np

ACTION, EPISODE = "action", "episode_index"
PART_BYTES = 15 * 2**20  # the device tool returns files of at most 16 MiB
CARRY_ROOT = Path(".device")  # ignored by git (.git/info/exclude); what the GPU machine gets

# name -> the recipe. `policy` holds ACTConfig's fields; the rest is the update. act_chunk_long is act_chunk's
# policy (backbones/train_backbones.py RECIPES, lerobot-train's config of it) at batch 128 for 40,000 steps
# (~240 passes over LIBERO-Goal's 21,671 frames, against act_chunk's ~18), a checkpoint every 8,000.
STATE_RECIPES: dict[str, dict] = {
    "act_chunk_long": {
        "policy": {"chunk_size": 20, "n_action_steps": 10, "dim_model": 128, "n_heads": 4, "dim_feedforward": 512,
                   "n_encoder_layers": 2, "n_decoder_layers": 1, "latent_dim": 16, "optimizer_lr": 3e-4,
                   "normalization_mapping": {"VISUAL": "MEAN_STD", "STATE": "MEAN_STD", "ENV": "MEAN_STD",
                                             "ACTION": "MEAN_STD"}},
        "batch_size": 128, "steps": 40000, "save_every": 8000, "seed": 1000,
    },
}
# act_chunk_b128: the same policy and batch for 12,000 steps, a checkpoint every 2,000: sized to what a lent GPU's
# 15 minutes leave (act_chunk_long ran 33-36 steps/s, two runs side by side on an H200: 15,400-16,000 steps in its
# 7.5-min bound, eval/studies/learned_goal_ten_long_select.toml).
STATE_RECIPES["act_chunk_b128"] = {**STATE_RECIPES["act_chunk_long"], "steps": 12000, "save_every": 2000}


# ---------------------------------------------------------------- here: prepare, assemble
def dataset_arrays(dataset: Path, keys: list[str]) -> dict[str, np.ndarray]:
    """The columns `keys` (+ action, episode_index) of a LeRobotDataset v3 on disk, frame order kept."""
    import pyarrow.parquet as pq

    cols = [*keys, ACTION, EPISODE]
    out: dict[str, list] = {k: [] for k in cols}
    files = sorted((dataset / "data").glob("chunk-*/file-*.parquet"))
    if not files:
        raise SystemExit(f"device_train: no frames under {dataset}/data; record them first "
                         "(backbones/record_dataset.py)")
    for f in files:
        t = pq.read_table(f, columns=cols, use_threads=False).to_pydict()
        for k in cols:
            out[k] += t[k]
    return {k: np.asarray(v, np.int64 if k == EPISODE else np.float32) for k, v in out.items()}


def state_policy_config(recipe: str, meta):
    """The ACTConfig of a state recipe on a dataset's features (every non-image observation feature)."""
    from lerobot.configs.types import FeatureType, NormalizationMode, PolicyFeature
    from lerobot.policies.act.configuration_act import ACTConfig

    kinds = {"observation.state": FeatureType.STATE, "observation.environment_state": FeatureType.ENV}
    inputs = {k: PolicyFeature(t, tuple(meta.features[k]["shape"])) for k, t in kinds.items() if k in meta.features}
    p = dict(STATE_RECIPES[recipe]["policy"])
    p["normalization_mapping"] = {k: NormalizationMode(v) for k, v in p["normalization_mapping"].items()}
    return ACTConfig(input_features=inputs,
                     output_features={ACTION: PolicyFeature(FeatureType.ACTION, tuple(meta.features[ACTION]["shape"]))},
                     device="cpu", push_to_hub=False, **p)


def write_init(cfg, meta, seed: int, carry: Path) -> None:
    """carry/init: the config and the processors (the dataset's statistics); no weights (`train` draws them
    from the seed)."""
    import torch

    from lerobot.policies.factory import make_pre_post_processors

    torch.manual_seed(seed)
    policy = policy_class(cfg.type)(cfg)
    pre, post = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    init = carry / "init"
    policy.save_pretrained(init)
    (init / "model.safetensors").unlink()
    pre.save_pretrained(init)
    post.save_pretrained(init)


def prepare_state(dataset: Path, recipe: str, carry: Path) -> None:
    """The initial checkpoint and the arrays of a state recipe, under `carry`."""
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata

    if recipe not in STATE_RECIPES:
        raise SystemExit(f"device_train: unknown recipe {recipe!r}; one of {sorted(STATE_RECIPES)}")
    meta = LeRobotDatasetMetadata(f"local/{dataset.name}", root=dataset)
    cfg = state_policy_config(recipe, meta)
    if carry.exists():
        shutil.rmtree(carry)
    r = STATE_RECIPES[recipe]
    write_init(cfg, meta, r["seed"], carry)
    arrays = dataset_arrays(dataset, list(cfg.input_features))
    np.savez(carry / "arrays.npz", **arrays)
    n_ep = len(np.unique(arrays[EPISODE]))
    (carry / "recipe.json").write_text(json.dumps({
        "recipe": recipe, **{k: v for k, v in r.items() if k != "policy"}, "dataset": str(dataset),
        "episodes": n_ep, "frames": int(len(arrays[EPISODE]))}, indent=1))
    mb = sum(p.stat().st_size for p in carry.rglob("*") if p.is_file()) / 2**20
    print(f"prepared {carry}: {recipe}, {n_ep} episodes, {len(arrays[EPISODE])} frames, {mb:.1f} MiB to carry")


def assemble(back: Path, out_run: Path) -> Path:
    """Join the parts a `train` run returned, check the sha256, unpack its checkpoints under out_run (the last
    one also as checkpoints/last) and return last's pretrained_model."""
    manifest = back / "run.json"
    if not manifest.exists():
        raise SystemExit(f"device_train: {manifest} missing; copy the device run's files there first")
    run = json.loads(manifest.read_text())
    parts = sorted(back.glob("run.tar.part*"))
    blob = b"".join(p.read_bytes() for p in parts)
    digest = hashlib.sha256(blob).hexdigest()
    if digest != run["tar_sha256"]:
        raise SystemExit(f"device_train: the joined parts' sha256 {digest} is not the run's {run['tar_sha256']}")
    tar = back / "run.tar"
    tar.write_bytes(blob)
    if out_run.exists():
        shutil.rmtree(out_run)
    (out_run / "checkpoints").mkdir(parents=True)
    with tarfile.open(tar) as t:
        t.extractall(out_run / "checkpoints", filter="data")
    tar.unlink()
    last = out_run / "checkpoints" / f"{run['steps_done']:06d}"
    shutil.copytree(last, out_run / "checkpoints" / "last")
    print(f"assembled {out_run}: checkpoints {', '.join(map(str, run['saved']))} ({len(parts)} parts, sha256 "
          f"{digest[:12]}), {run['steps_done']} steps in {run['train_seconds'] / 60:.1f} min on {run['device']}")
    return out_run / "checkpoints" / "last" / "pretrained_model"


# ---------------------------------------------------------------- the GPU machine (or here): train
def policy_class(kind: str):
    """The LeRobot policy class of a config type the recipes use (act, diffusion)."""
    if kind == "act":
        from lerobot.policies.act.modeling_act import ACTPolicy

        return ACTPolicy
    if kind == "diffusion":
        from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy

        return DiffusionPolicy
    raise SystemExit(f"device_train: no recipe trains a {kind!r} policy; act or diffusion")


def import_lerobot():
    """ACTPolicy, PreTrainedConfig and PolicyProcessorPipeline. On a machine with lerobot but without its dataset
    extra (PyAV: a bare GPU machine), lerobot.policies' package init fails on the dataset stack it imports; the
    modules needed here do not use it, so they load with that init skipped."""
    import importlib.util

    if importlib.util.find_spec("av") is None:
        import types

        import lerobot

        pkg = types.ModuleType("lerobot.policies")
        pkg.__path__ = [str(Path(lerobot.__file__).parent / "policies")]
        sys.modules.setdefault("lerobot.policies", pkg)
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.act.modeling_act import ACTPolicy
    from lerobot.policies.diffusion import configuration_diffusion  # noqa: F401 - registers the `diffusion` type
    from lerobot.processor import PolicyProcessorPipeline

    return ACTPolicy, PreTrainedConfig, PolicyProcessorPipeline


def frame_index(episode: np.ndarray, deltas) -> tuple[np.ndarray, np.ndarray]:
    """(N, len(deltas)) frame indices of each frame's t + delta, clamped to its episode's first and last frames,
    and the pad mask (True outside the episode), as LeRobotDataset's delta_timestamps give them to a policy."""
    n = len(episode)
    first, last = np.empty(n, np.int64), np.empty(n, np.int64)
    for e in np.unique(episode):
        idx = np.flatnonzero(episode == e)
        first[idx], last[idx] = idx[0], idx[-1]
    raw = np.arange(n)[:, None] + np.asarray(list(deltas), np.int64)[None]
    return np.clip(raw, first[:, None], last[:, None]), (raw > last[:, None]) | (raw < first[:, None])


def chunk_index(episode: np.ndarray, chunk: int) -> tuple[np.ndarray, np.ndarray]:
    """(N, chunk) frame indices of each frame's action chunk, clamped to its episode's last frame, and the pad
    mask (True past the episode's end), as LeRobotDataset's delta_timestamps give them to ACT."""
    return frame_index(episode, range(chunk))


def train(carry: Path, out: Path, device: str, steps: int | None, max_minutes: float,
          frames: dict[str, np.ndarray] | None = None, data: Path | None = None) -> None:
    """Train the carried recipe; `frames` adds inputs not in arrays.npz (the camera policies' decoded video);
    `data` is where arrays.npz lies (default `carry`; the camera recipes of one suite share theirs)."""
    import torch

    _, PreTrainedConfig, PolicyProcessorPipeline = import_lerobot()
    recipe = json.loads((carry / "recipe.json").read_text())
    steps = int(steps or recipe["steps"])
    every = int(recipe.get("save_every") or steps)
    t0 = time.time()
    arrays = {k: np.asarray(v) for k, v in np.load((data or carry) / "arrays.npz").items()}
    arrays.update(frames or {})
    episode = arrays[EPISODE]
    cfg = PreTrainedConfig.from_pretrained(str(carry / "init"))
    cfg.device = device
    torch.manual_seed(recipe["seed"])  # the initial weights, as `prepare` drew them
    np.random.seed(recipe["seed"])
    policy = policy_class(cfg.type)(cfg)
    policy.to(device).train()
    pre = PolicyProcessorPipeline.from_pretrained(str(carry / "init"), config_filename="policy_preprocessor.json",
                                                  overrides={"device_processor": {"device": device}})
    optim_cfg = policy.config.get_optimizer_preset()
    optimizer = optim_cfg.build(policy.get_optim_params())
    idx, pad = frame_index(episode, policy.config.action_delta_indices)
    obs_deltas = policy.config.observation_delta_indices  # None: this frame only (ACT); Diffusion: its history
    dev = torch.device(device)
    obs_idx = torch.from_numpy(frame_index(episode, obs_deltas)[0]).to(dev) if obs_deltas else None
    inputs = {}
    for k in policy.config.input_features:
        x = torch.from_numpy(np.ascontiguousarray(arrays[k])).to(dev)
        inputs[k] = x.permute(0, 3, 1, 2).contiguous() if x.dtype == torch.uint8 else x  # images: (N, 3, H, W)
    action_t = torch.from_numpy(arrays[ACTION]).to(dev)
    idx_t, pad_t = torch.from_numpy(idx).to(dev), torch.from_numpy(pad).to(dev)
    gen = torch.Generator(device=dev).manual_seed(recipe["seed"])
    name = torch.cuda.get_device_name(0) + " (cuda)" if device.startswith("cuda") else f"CPU, {os.cpu_count()} cores"
    print(f"data: {len(episode)} frames of {len(np.unique(episode))} episodes on {name} in {time.time() - t0:.0f} s",
          flush=True)
    ckpts = out / "checkpoints"
    bs, t_train, done, losses, saved = recipe["batch_size"], time.time(), 0, [], []

    def save(step: int) -> None:
        ckpt = ckpts / f"{step:06d}" / "pretrained_model"
        policy.config.device = "cpu"
        policy.to("cpu").save_pretrained(ckpt)
        policy.to(dev)
        policy.config.device = device
        for f in (carry / "init").iterdir():  # the processors, as prepared (their device step says cpu)
            if f.name.startswith("policy_") and not (ckpt / f.name).exists():
                shutil.copy(f, ckpt / f.name)
        weights = (ckpt / "model.safetensors").read_bytes()
        (ckpt / "recipe.json").write_text(json.dumps({
            **recipe, "step": step, "train_seconds": time.time() - t_train, "device": name,
            "torch": torch.__version__, "loss_every_50": [x for x in losses if x is not None],
            "model_sha256": hashlib.sha256(weights).hexdigest(), "command": " ".join(sys.argv)}, indent=1))
        saved.append(step)

    for step in range(1, steps + 1):
        b = torch.randint(0, len(episode), (bs,), device=dev, generator=gen)
        rows = b if obs_idx is None else obs_idx[b]  # (B,) or (B, n_obs_steps)
        batch = {k: (v[rows].float() / 255.0 if v.dtype == torch.uint8 else v[rows]) for k, v in inputs.items()}
        batch[ACTION], batch["action_is_pad"] = action_t[idx_t[b]], pad_t[b]
        loss, _ = policy.forward(pre(batch))
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(policy.parameters(), optim_cfg.grad_clip_norm)
        optimizer.step()
        done = step
        losses.append(float(loss.detach()) if step % 50 == 0 or step == 1 else None)
        if step % 1000 == 0 or step == 1:
            print(f"step {step}/{steps}  loss {float(loss.detach()):.4f}  {step / (time.time() - t_train):.1f} steps/s",
                  flush=True)
        if step % every == 0 or step == steps:
            save(step)
        if (time.time() - t0) / 60 > max_minutes:
            print(f"stopping at step {step}: the {max_minutes} min bound", flush=True)
            if saved[-1:] != [step]:
                save(step)
            break
    secs = time.time() - t_train
    out.mkdir(parents=True, exist_ok=True)
    back = returned_steps(recipe, saved, done)
    if recipe.get("return_dtype") == "float16":
        for s in back:
            ckpt = ckpts / f"{s:06d}" / "pretrained_model"
            meta = json.loads((ckpt / "recipe.json").read_text())
            meta["returned"] = {"dtype": "float16", "model_sha256": half_safetensors(ckpt / "model.safetensors")}
            (ckpt / "recipe.json").write_text(json.dumps(meta, indent=1))
    with tarfile.open(out / "run.tar", "w") as t:
        for s in back:
            t.add(ckpts / f"{s:06d}", arcname=f"{s:06d}")
    blob = (out / "run.tar").read_bytes()
    (out / "run.tar").unlink()
    shutil.rmtree(ckpts)
    for i in range(0, len(blob), PART_BYTES):
        (out / f"run.tar.part{i // PART_BYTES:02d}").write_bytes(blob[i:i + PART_BYTES])
    (out / "run.json").write_text(json.dumps({"recipe": recipe, "steps_done": done, "saved": back, "saved_there": saved,
                                              "train_seconds": secs, "device": name,
                                              "tar_sha256": hashlib.sha256(blob).hexdigest()}, indent=1))
    print(f"trained {done} steps in {secs / 60:.1f} min on {name}; checkpoints {saved}, returning {back}; "
          f"{len(blob) / 2**20:.1f} MiB in {-(-len(blob) // PART_BYTES)} parts -> {out}")


def returned_steps(recipe: dict, saved: list[int], done: int) -> list[int]:
    """The saved checkpoints a run hands back: all of them, or the recipe's `return_steps` (step numbers, "last" for
    the step the run stopped at) where only some fit what the device tool returns (64 MiB a call)."""
    want = recipe.get("return_steps")
    if not want:
        return list(saved)
    steps = {done if w == "last" else int(w) for w in want}
    return [s for s in saved if s in steps]


def half_safetensors(src: Path, dst: Path | None = None) -> str:
    """Write `src`'s weights with every floating tensor in fp16 to `dst` (default: over `src`); the file's sha256."""
    from safetensors.torch import load_file, save_file

    half = {k: (v.half() if v.is_floating_point() else v).contiguous() for k, v in load_file(str(src)).items()}
    save_file(half, str(dst or src), metadata={"format": "pt"})
    return hashlib.sha256(Path(dst or src).read_bytes()).hexdigest()


def add_train_parser(sub, help: str, carry: str | None, out: str, max_minutes: float, name: str = "train"):
    """The `train` subcommand (what the GPU machine runs), shared with train_camera.py (also its `train-all`)."""
    t = sub.add_parser(name, help=help)
    t.add_argument("--carry", required=carry is None, default=carry)
    t.add_argument("--out", default=os.environ.get("OUT", out))
    t.add_argument("--device", default="cuda")
    t.add_argument("--steps", type=int, default=None, help="override the recipe's steps (smoke tests)")
    t.add_argument("--max-minutes", type=float, default=max_minutes,
                   help="save and stop once this much time has passed")
    return t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("prepare", help="here: the initial checkpoint and the arrays of a state recipe")
    p.add_argument("--suite", required=True, help="libero_spatial, libero_object, libero_goal, libero_10, metaworld")
    p.add_argument("--recipe", required=True, choices=sorted(STATE_RECIPES))
    p.add_argument("--dataset", default=None, help="dataset root (default outputs/datasets/physvla_<suite>)")
    p.add_argument("--carry", default=None, help=f"default {CARRY_ROOT}/<suite>_<recipe>")
    add_train_parser(sub, "the GPU machine (or here): train the carried recipe", None, "outputs/device_run", 8.0)
    a = sub.add_parser("assemble", help="here: unpack what a device run returned into a training folder")
    a.add_argument("back", help="the folder holding run.json and run.tar.part*")
    a.add_argument("--out", required=True, help="e.g. outputs/train/libero_goal/act_chunk_long")
    args = ap.parse_args()
    if args.cmd == "prepare":
        dataset = Path(args.dataset or f"outputs/datasets/physvla_{args.suite}")
        prepare_state(dataset, args.recipe, Path(args.carry or CARRY_ROOT / f"{args.suite}_{args.recipe}"))
    elif args.cmd == "train":
        train(Path(args.carry), Path(args.out), args.device, args.steps, args.max_minutes)
    else:
        assemble(Path(args.back), Path(args.out))


if __name__ == "__main__":
    main()
