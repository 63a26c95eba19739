"""Training recipes for the learned backbones: LeRobot ACT and Diffusion on the expert dataset, CPU.

    .venv/bin/python policies/record_dataset.py                 # once: the dataset
    .venv/bin/python policies/train_backbones.py act_chunk      # one recipe (or: all)
    .venv/bin/python policies/train_backbones.py --list

Each recipe is one `lerobot-train` command (printed before it runs, and saved beside the
checkpoint as recipe.json) on the local dataset, state inputs only (observation.state +
observation.environment_state), fixed seed, no hub, no wandb, no env (so no evaluation during training),
data loaded in the training process (a step costs ~130 ms of dataset reads and ~40 ms of compute
here, so one core per recipe is the efficient split: run two recipes side by side on 2 cores).
The checkpoint lands in outputs/train/<recipe>/checkpoints/last/pretrained_model, which is what
eval/experiments.py learned uses (or `lerobot-eval --policy.path=... --env.type=libero_physvla
--env.cameras=false`). Sizes are chosen to train in minutes on 2 CPU cores:
    act_single        ACT, chunk 1 (a single-step policy)
    act_chunk         ACT, chunk 20, executes 10 before re-planning
    diffusion_single  Diffusion (DDIM, 10 denoising steps), re-plans every step
    diffusion_chunk   Diffusion, executes 8 of its 16-step horizon before re-planning
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

DATASET = "outputs/datasets/physvla_libero_spatial"
REPO_ID = "local/physvla_libero_spatial"
SEED = 1000

_COMMON = ["--policy.device=cpu", "--policy.push_to_hub=false", "--wandb.enable=false",
           "--num_workers=0", "--log_freq=200", f"--seed={SEED}"]
_ACT = ["--policy.type=act", "--policy.dim_model=128", "--policy.n_heads=4", "--policy.dim_feedforward=512",
        "--policy.n_encoder_layers=2", "--policy.n_decoder_layers=1", "--policy.latent_dim=16",
        "--policy.optimizer_lr=3e-4", "--batch_size=32"]
_DIFFUSION = ["--policy.type=diffusion", "--policy.n_obs_steps=2", "--policy.horizon=16",
              "--policy.down_dims=[64,128,256]", "--policy.diffusion_step_embed_dim=64",
              "--policy.noise_scheduler_type=DDIM", "--policy.num_inference_steps=10", "--policy.optimizer_lr=3e-4",
              "--batch_size=32"]

RECIPES: dict[str, list[str]] = {
    # a chunk-1 sample reads 1 action frame instead of 20, so 5x the steps cost about the same time
    "act_single": _ACT + ["--policy.chunk_size=1", "--policy.n_action_steps=1", "--policy.use_vae=false",
                          "--steps=15000", "--save_freq=15000"],
    "act_chunk": _ACT + ["--policy.chunk_size=20", "--policy.n_action_steps=10", "--steps=3000", "--save_freq=3000"],
    "diffusion_single": _DIFFUSION + ["--policy.n_action_steps=1", "--steps=4000", "--save_freq=4000"],
    "diffusion_chunk": _DIFFUSION + ["--policy.n_action_steps=8", "--steps=4000", "--save_freq=4000"],
}


def command(name: str, dataset: str, out_root: str, steps: int | None = None) -> list[str]:
    """The lerobot-train argv of a recipe (optionally with fewer steps, for smoke tests)."""
    args = list(RECIPES[name])
    if steps is not None:
        args = [a for a in args if not a.startswith(("--steps=", "--save_freq="))]
        args += [f"--steps={steps}", f"--save_freq={steps}"]
    exe = Path(sys.executable).with_name("lerobot-train")
    return [str(exe), f"--dataset.repo_id={REPO_ID}", f"--dataset.root={dataset}", *_COMMON, *args,
            f"--output_dir={out_root}/{name}", f"--job_name=physvla_{name}"]


def checkpoint(name: str, out_root: str = "outputs/train") -> Path:
    return Path(out_root) / name / "checkpoints" / "last" / "pretrained_model"


def train(name: str, dataset: str, out_root: str, steps: int | None = None) -> Path:
    if not (Path(dataset) / "meta" / "info.json").exists():
        raise SystemExit(f"train_backbones: no dataset at {dataset}; run policies/record_dataset.py first")
    out = Path(out_root) / name
    if out.exists():  # lerobot-train refuses an existing output dir without --resume
        shutil.rmtree(out)
    cmd = command(name, dataset, out_root, steps)
    print("+ " + " ".join(cmd), flush=True)
    t0 = time.time()
    # One torch thread: on a busy 2-core machine, 2 OpenMP threads spin-wait and a step takes ~25x
    # longer (measured: 1.7 s vs 66 ms for act_chunk's forward + backward at batch 64).
    env = {**os.environ, "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS", "1")}
    if subprocess.run(cmd, env=env).returncode != 0:
        raise SystemExit(f"train_backbones: lerobot-train failed for {name} (its error is above)")
    ckpt = checkpoint(name, out_root)
    (ckpt / "recipe.json").write_text(json.dumps({"recipe": name, "command": cmd, "train_seconds": time.time() - t0}, indent=1))
    print(f"{name}: trained in {(time.time() - t0) / 60:.1f} min -> {ckpt}")
    return ckpt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("recipe", nargs="?", choices=[*RECIPES, "all"], default="all")
    ap.add_argument("--dataset", default=DATASET)
    ap.add_argument("--out", default="outputs/train")
    ap.add_argument("--steps", type=int, default=None, help="override the recipe's step count (smoke tests)")
    ap.add_argument("--list", action="store_true", help="print each recipe's command and exit")
    ap.add_argument("--parallel", type=int, default=os.cpu_count() or 1, help="recipes trained side by side")
    args = ap.parse_args()
    names = list(RECIPES) if args.recipe == "all" else [args.recipe]
    if args.list:
        for n in names:
            print(n + ":\n  " + " ".join(command(n, args.dataset, args.out)))
        return
    with ThreadPoolExecutor(max_workers=max(1, args.parallel)) as pool:  # each recipe is its own process
        for f in [pool.submit(train, n, args.dataset, args.out, args.steps) for n in names]:
            f.result()


if __name__ == "__main__":
    main()
