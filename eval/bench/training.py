"""CPU training speed of the backbone recipes, with and without lerobot's data-loader workers.

    .venv/bin/python eval/bench/training.py [--recipes act_single,act_chunk,diffusion_chunk]
        [--num-workers 0,1] [--steps 400] [--out eval/results/bench_training]

Each recipe of backbones/train_backbones.py runs for --steps steps with each --num-workers value,
one run at a time (nothing else should run beside it), through the recipe's own lerobot-train
command (only --steps, --num_workers and the output directory differ). lerobot-train logs, every
--log-freq steps, the mean time a step spent waiting for data (`data_s`) and updating the model
(`updt_s`); the first log period (start-up, first reads) is dropped. A recipe's projected time is
its full step count x (data_s + updt_s). Writes README.md and results.json to --out and prints the
speed-up of each worker count over reading in the training process (num_workers = 0), measured in
the same invocation.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "backbones"))
import train_backbones  # noqa: E402

LOG = re.compile(r"step:(\S+) .*updt_s:([0-9.]+) data_s:([0-9.]+)")


def log_periods(text: str) -> list[tuple[float, float]]:
    """(updt_s, data_s) of each of lerobot-train's log lines, in order."""
    return [(float(m.group(2)), float(m.group(3))) for m in LOG.finditer(text.replace("\r", "\n"))]


def run(name: str, dataset: str, steps: int, workers: int, log_freq: int) -> dict:
    with tempfile.TemporaryDirectory(prefix="bench_training_") as tmp:
        cmd = train_backbones.command(name, dataset, tmp, steps=steps, num_workers=workers)
        cmd = [a for a in cmd if not a.startswith("--log_freq=")] + [f"--log_freq={log_freq}"]
        env = {**os.environ, "OMP_NUM_THREADS": "1"}  # as train_backbones.train runs it
        t0 = time.time()
        p = subprocess.run(cmd, env=env, capture_output=True, text=True)
        wall = time.time() - t0
    if p.returncode != 0:
        raise SystemExit(f"bench_training: lerobot-train failed for {name} (num_workers={workers}):\n"
                         + p.stderr[-3000:])
    periods = log_periods(p.stdout + p.stderr)[1:]  # the first period holds start-up
    if not periods:
        raise SystemExit(f"bench_training: no log periods after the first for {name}; raise --steps above "
                         f"2 x --log-freq")
    updt = sum(u for u, _ in periods) / len(periods)
    data = sum(d for _, d in periods) / len(periods)
    full = train_backbones.RECIPES[name][1]
    return {"recipe": name, "num_workers": workers, "steps": steps, "wall_s": wall, "updt_s": updt, "data_s": data,
            "step_s": updt + data, "recipe_steps": full, "projected_min": full * (updt + data) / 60}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--recipes", default="act_single,act_chunk,diffusion_chunk")
    ap.add_argument("--num-workers", default="0,1")
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--log-freq", type=int, default=100)
    ap.add_argument("--dataset", default=train_backbones.DATASET)
    ap.add_argument("--out", default=str(ROOT / "eval" / "results" / "bench_training"))
    args = ap.parse_args()
    if not (Path(args.dataset) / "meta" / "info.json").exists():
        raise SystemExit(f"bench_training: no dataset at {args.dataset}; run backbones/record_dataset.py first")
    names, workers = args.recipes.split(","), [int(w) for w in args.num_workers.split(",")]
    rows = []
    for n in names:
        for w in workers:
            r = run(n, args.dataset, args.steps, w, args.log_freq)
            rows.append(r)
            print(f"{n:16s} num_workers={w}: {r['step_s'] * 1e3:6.1f} ms/step (data {r['data_s'] * 1e3:5.1f}, "
                  f"update {r['updt_s'] * 1e3:5.1f}); recipe ({r['recipe_steps']} steps) ~ {r['projected_min']:.0f} min",
                  flush=True)
    info = json.loads((Path(args.dataset) / "meta" / "info.json").read_text())
    base = {r["recipe"]: r for r in rows if r["num_workers"] == workers[0]}
    cmd = " ".join([".venv/bin/python", "eval/bench/training.py", *sys.argv[1:]])
    lines = ["# CPU training speed of the recipes, by lerobot data-loader workers", "",
             f"Command: `{cmd}`  ",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, one torch thread per run, one run at a time; "
             f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.  ",
             f"Dataset: {args.dataset} ({info.get('total_episodes')} episodes, {info.get('total_frames')} frames, "
             "state only: no video to decode). Each run: the recipe's own lerobot-train command for "
             f"{args.steps} steps; ms/step = lerobot-train's logged data wait + update, averaged over the log "
             f"periods after the first (every {args.log_freq} steps).", "",
             f"| recipe | num_workers | data wait, ms/step | update, ms/step | ms/step | speed-up over num_workers={workers[0]} "
             "| projected recipe time, min (steps) |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        b = base[r["recipe"]]
        lines.append(f"| {r['recipe']} | {r['num_workers']} | {r['data_s'] * 1e3:.1f} | {r['updt_s'] * 1e3:.1f} | "
                     f"{r['step_s'] * 1e3:.1f} | {b['step_s'] / r['step_s']:.2f}x | {r['projected_min']:.0f} "
                     f"({r['recipe_steps']}) |")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "README.md").write_text("\n".join(lines) + "\n")
    (out / "results.json").write_text(json.dumps(rows, indent=1))
    print("\n".join(lines[-len(rows) - 2:]))


if __name__ == "__main__":
    main()
