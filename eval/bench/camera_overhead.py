"""The corrector's time per step beside a camera policy's own inference, in the same run (issue #61, item 4).

    .venv/bin/python eval/bench/camera_overhead.py [--steps 150] [--size 128] [--out eval/results/bench_camera_overhead]

On LIBERO-Spatial task 0 (init state 0) with the agentview camera at `size` pixels, each camera recipe of
backbones/train_camera.py (ACT, Diffusion Policy) is built with untrained weights (seed 0: a policy's inference time
does not depend on what it learned) and loaded as the harness loads a checkpoint (backbones.LeRobotBackbone: its
saved processors, CPU, one torch thread). The scripted expert drives the arm through every phase, so the corrector
(the shipped default) sees the states a real episode gives; at each step the camera policy is called on that step's
observation as the harness calls it, and the three are timed side by side:
    observation   the frame rendered (where the policy reads it) and the state arranged as lerobot-eval gives them
    policy        pre-processor, select_action, post-processor: one call per step (ACT pops its chunk between
                  calls, Diffusion reads every frame), reported per step and per call that ran the network
    corrector     `Corrector(PhysVLAConfig())` on the step's action and state
Prints each row and, last, `camera policy <name>: corrector / policy per step <r>` for each policy.
Writes README.md and results.json to --out.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "backbones"))
sys.path.insert(0, str(ROOT / "eval"))


def untrained_checkpoint(recipe: str, size: int, out: Path) -> Path:
    """A checkpoint folder of the recipe with seed-0 weights and unit statistics (what inference costs is the same)."""
    import torch

    import device_train
    import train_camera
    from lerobot.policies.factory import make_pre_post_processors

    cfg = train_camera.policy_config(recipe, size)
    dims = {train_camera.IMAGE: (3, 1, 1), train_camera.STATE: (8,), "action": (7,)}
    stats = {k: {"mean": np.zeros(d, np.float32), "std": np.ones(d, np.float32), "min": -np.ones(d, np.float32),
                 "max": np.ones(d, np.float32)} for k, d in dims.items()}
    torch.manual_seed(0)
    policy = device_train.policy_class(cfg.type)(cfg)
    pre, post = make_pre_post_processors(cfg, dataset_stats=stats)
    for part in (policy, pre, post):
        part.save_pretrained(out)
    return out


def bench(recipe: str, size: int, steps: int, tmp: Path) -> dict:
    import torch

    from backbones import LeRobotBackbone

    from lerobot_physvla.core.config import PhysVLAConfig
    from lerobot_physvla.core.corrector import Corrector
    from lerobot_physvla.sim.experts import PickPlaceExpert
    from lerobot_physvla.sim.scenes import make_scene

    backbone = LeRobotBackbone(str(untrained_checkpoint(recipe, size, tmp / recipe)))
    scene = make_scene(f"libero_spatial+agentview{size}/0")
    scene.reset(0)
    backbone.reset(0)
    expert, corr = PickPlaceExpert(), Corrector(PhysVLAConfig(), batch_size=1)
    t_obs, t_policy, t_corr, calls = [], [], [], []
    for _ in range(steps):
        s = scene.read()
        reads = backbone.reads_observation()
        ran = not _queued(backbone.policy)  # this call runs the network (its action queue is empty)
        t0 = time.perf_counter()
        obs = scene.policy_observation(s, frame=reads)
        t1 = time.perf_counter()
        a_policy = backbone._runner.act(obs, scene.task.language)
        t2 = time.perf_counter()
        raw = expert.act(s.eef_pos[0], s.obj_pos[0], s.target_pos[0])[None]
        t3 = time.perf_counter()
        a = corr(raw, s)
        t4 = time.perf_counter()
        assert np.isfinite(a_policy).all() and np.isfinite(a).all()
        t_obs.append(t1 - t0)
        t_policy.append(t2 - t1)
        t_corr.append(t4 - t3)
        calls.append(ran)
        scene.step(a[0])
    scene.env.close()
    pol, cor, calls = np.asarray(t_policy), np.asarray(t_corr), np.asarray(calls)
    net = pol[calls]  # the steps that ran the network
    return {"policy": recipe, "steps": steps, "size": size, "torch_threads": torch.get_num_threads(),
            "observation_ms_mean": 1e3 * float(np.mean(t_obs)),
            "policy_ms_per_step_mean": 1e3 * float(np.mean(pol)),
            "policy_ms_per_network_call_p50": 1e3 * float(np.median(net)), "network_calls": int(len(net)),
            "corrector_us_p50": 1e6 * float(np.median(cor)), "corrector_us_p99": 1e6 * float(np.percentile(cor, 99)),
            "corrector_us_mean": 1e6 * float(np.mean(cor)),
            "ratio_corrector_to_policy_per_step": float(np.mean(cor) / np.mean(pol)),
            "ratio_corrector_to_network_call": float(np.mean(cor) / np.median(net))}


def _queued(policy) -> int:
    """How many actions the policy holds from its last network call (ACT's _action_queue, Diffusion's queue)."""
    queue = getattr(policy, "_action_queue", None)
    if queue is None:
        queue = getattr(policy, "_queues", {}).get("action", ())
    return len(queue)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--out", default="eval/results/bench_camera_overhead")
    args = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for recipe in ("act", "diffusion"):
            r = bench(recipe, args.size, args.steps, Path(tmp))
            rows.append(r)
            print(json.dumps(r))
    cpu = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    lines = [f"<!-- made by: .venv/bin/python eval/bench/camera_overhead.py --steps {args.steps} --size {args.size} "
             f"--out {args.out} -->",
             "# The corrector beside a camera policy's inference (CPU)", "",
             f"LIBERO-Spatial task 0, agentview {args.size} x {args.size}, {args.steps} steps driven by the scripted "
             f"expert; untrained ACT / Diffusion Policy of backbones/train_camera.py's recipes (inference time does "
             f"not depend on the weights), one torch thread; {cpu}. Generated by eval/bench/camera_overhead.py.", "",
             "| policy | policy per step (ms, mean) | policy per network call (ms, p50) | render + observation (ms, mean) "
             "| corrector (us, p50 / p99) | corrector / policy per step | corrector / one network call |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['policy']} | {r['policy_ms_per_step_mean']:.1f} | {r['policy_ms_per_network_call_p50']:.1f} "
                     f"({r['network_calls']} calls) | {r['observation_ms_mean']:.1f} | {r['corrector_us_p50']:.0f} / "
                     f"{r['corrector_us_p99']:.0f} | {r['ratio_corrector_to_policy_per_step']:.4f} | "
                     f"{r['ratio_corrector_to_network_call']:.4f} |")
    out = ROOT / args.out
    out.mkdir(parents=True, exist_ok=True)
    (out / "README.md").write_text("\n".join(lines) + "\n")
    (out / "results.json").write_text(json.dumps({"cpu": cpu, "rows": rows}, indent=1) + "\n")
    for r in rows:
        print(f"camera policy {r['policy']}: corrector / policy per step {r['ratio_corrector_to_policy_per_step']:.4f}")


if __name__ == "__main__":
    main()
