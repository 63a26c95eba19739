"""Per-step overhead of the corrector, side by side with a no-op corrector and the env step.

    .venv/bin/python eval/bench_overhead.py [--steps 200] [--repeats 20] [--out eval/results/bench_overhead]

1. Records a real LIBERO-Spatial task-0 episode (state-only, no cameras): the scripted expert's
   raw actions and the packed physical state at every step, timing `env.step` and the state read.
2. Replays those inputs through the corrector for B = 1 and B = 8 envs (env i starts i*17 steps
   into the episode, so the batch mixes phases), for a no-op corrector and each mode, the
   configs interleaved repeat by repeat so that machine noise falls on all of them alike.
3. Prints per env-step p50 / p99 of the whole call and of Branch A / Branch B, and the ratios
   to the no-op corrector and to the env step, all measured in this one run. Writes a markdown
   table and a JSON next to it.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from lerobot_physvla.sim import libero_sim
from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.sim.experts import PickPlaceExpert
from lerobot_physvla.sim.robosuite_source import RobosuiteStateSource
from lerobot_physvla.core.state import PhysState

CONFIGS = {
    "no-op (identity function)": None,
    "baseline mode (phases only)": PhysVLAConfig(mode="baseline"),
    "temporal": PhysVLAConfig(mode="temporal"),
    "phys": PhysVLAConfig(mode="phys"),
    "phys_el joint_diag": PhysVLAConfig(mode="phys_el"),
    "phys_el task_space": PhysVLAConfig(mode="phys_el", weighting="task_space"),
    "phys_el gated": PhysVLAConfig(mode="phys_el", el_mode="gated"),
}


def record(steps: int):
    task = libero_sim.load_task("libero_spatial", 0)
    env = libero_sim.make_libero_env(task)
    libero_sim.reset_to_init_state(env, task, 0)
    src = RobosuiteStateSource(env.env)
    src.reset()
    expert = PickPlaceExpert()
    rows, actions, t_step, t_read = [], [], [], []
    for _ in range(steps):
        t0 = time.perf_counter()
        row = src.read_packed()
        t1 = time.perf_counter()
        a = expert.act(row[3:6], row[7:10], row[11:14])
        t2 = time.perf_counter()
        env.step(a)
        t3 = time.perf_counter()
        src.step()
        rows.append(row.copy())
        actions.append(a)
        t_read.append(t1 - t0)
        t_step.append(t3 - t2)
    env.close()
    return np.array(rows), np.array(actions), np.array(t_step), np.array(t_read)


def bench(configs: dict, rows, actions, batch: int, repeats: int) -> dict:
    """Time every config on the same inputs, interleaved (repeat r runs all configs in turn),
    so machine noise falls on all of them alike."""
    n = len(rows)
    idx = (np.arange(n)[:, None] + 17 * np.arange(batch)[None]) % n  # (steps, B)
    states = [PhysState.unpack(rows[i]) for i in idx]
    acts = [np.ascontiguousarray(actions[i]) for i in idx]
    correctors = {name: (Corrector(cfg, batch) if cfg is not None else None) for name, cfg in configs.items()}
    res = {name: {"total": [], "a": [], "b": []} for name in configs}
    for _ in range(repeats + 1):  # the first round warms up (numba compiles on first use)
        for name, c in correctors.items():
            call = c if c is not None else (lambda a, s: a.copy())  # the no-op corrector
            if c is not None:
                c.reset()
            r = res[name]
            for s, a in zip(states, acts):
                t0 = time.perf_counter()
                call(a, s)
                r["total"].append(time.perf_counter() - t0)
                r["a"].append(c.last.t_branch_a_s if c else 0.0)
                r["b"].append(c.last.t_branch_b_s if c else 0.0)
    out = {}
    for name, r in res.items():
        c = correctors[name]
        out[name] = {k: np.asarray(v[n:]) * 1e6 / batch for k, v in r.items()}  # drop warm-up; us / env-step
        out[name]["passthrough"] = dict(c.passthrough_counts) if c else {}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--out", default="eval/results/bench_overhead")
    args = ap.parse_args()

    print(f"recording {args.steps} steps of LIBERO-Spatial task 0 (state-only) ...", flush=True)
    rows, actions, t_step, t_read = record(args.steps)
    step_us = np.median(t_step) * 1e6
    read_us = np.median(t_read) * 1e6
    lines = [
        f"# Corrector overhead\n",
        f"Command: `{' '.join(['.venv/bin/python', *sys.argv])}`  ",
        f"Machine: {platform.processor() or platform.machine()}, {platform.python_version()}, "
        f"{len(__import__('os').sched_getaffinity(0))} cores; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}  ",
        f"Inputs: {args.steps} recorded steps x {args.repeats} repeats per row; times are per env-step (call time / B).\n",
        f"LIBERO env step (no cameras): p50 {step_us:.0f} us; state read (RobosuiteStateSource.read_packed: kinematics + CRB + RNE on a scratch MjData): p50 {read_us:.1f} us.\n",
        "| config | B | p50 total (us) | p99 total (us) | p50 Branch A (us) | p50 Branch B + blend (us) | total / no-op | total / env step |",
        "|---|---|---|---|---|---|---|---|",
    ]
    results = {"env_step_us_p50": step_us, "state_read_us_p50": read_us, "rows": []}
    for batch in (1, 8):
        noop = None
        timings = bench(CONFIGS, rows, actions, batch, args.repeats)
        for name in CONFIGS:
            r = timings[name]
            p50, p99 = np.percentile(r["total"], [50, 99])
            noop = p50 if noop is None else noop
            row = {
                "config": name, "batch": batch, "p50_us": p50, "p99_us": p99, "p50_a_us": float(np.median(r["a"])),
                "p50_b_us": float(np.median(r["b"])), "ratio_noop": p50 / noop, "ratio_env_step": p50 / step_us,
                "passthrough": r["passthrough"],
            }
            results["rows"].append(row)
            line = (f"| {name} | {batch} | {p50:.1f} | {p99:.1f} | {row['p50_a_us']:.1f} | {row['p50_b_us']:.1f} | "
                    f"{row['ratio_noop']:.2f} | {row['ratio_env_step']:.4f} |")
            lines.append(line)
            print(line, flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "README.md").write_text("\n".join(lines) + "\n")
    (out / "results.json").write_text(json.dumps(results, indent=1, default=float))
    print(f"\nwrote {out}/README.md and results.json")


if __name__ == "__main__":
    main()
