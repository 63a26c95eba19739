"""What a training step of the learned backbones costs on this CPU, and how much lerobot's own
data-loader workers take off it: one recipe of policies/train_backbones.py, the same short run
with `--num_workers` 0, 1, 2 side by side in one invocation (this machine is noisy; compare the
ratios).

    .venv/bin/python eval/bench_train_data.py [--recipe act_chunk] [--steps 300] [--workers 0,1,2]

Per run it reads lerobot-train's own log line at the last step: `data_s` (seconds a step waited for
its batch) and `updt_s` (forward + backward + optimizer), and times the whole run. Writes
eval/results/bench_train_data/README.md with the command at its top.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "policies"))
import train_backbones  # noqa: E402

OUT = ROOT / "eval" / "results" / "bench_train_data"
_LOG = re.compile(r"step:(\S+).*?updt_s:([\d.]+).*?data_s:([\d.]+)")


def run(recipe: str, steps: int, workers: int, dataset: str) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        cmd = train_backbones.command(recipe, dataset, tmp, steps=steps, num_workers=workers)
        cmd = [a for a in cmd if not a.startswith(("--log_freq=", "--save_freq="))]
        cmd += [f"--log_freq={steps // 3}", f"--save_freq={steps}"]
        env = {**os.environ, "OMP_NUM_THREADS": "1"}
        t0 = time.time()
        p = subprocess.run(cmd, env=env, capture_output=True, text=True)
        wall = time.time() - t0
    if p.returncode != 0:
        raise SystemExit(f"bench_train_data: lerobot-train failed ({recipe}, {workers} workers):\n{p.stderr[-3000:]}")
    found = _LOG.findall(p.stdout + p.stderr)
    if not found:
        raise SystemExit("bench_train_data: no step log line in lerobot-train's output")
    _, updt, data = found[-1]
    return {"workers": workers, "updt_s": float(updt), "data_s": float(data), "step_s": float(updt) + float(data),
            "wall_s": wall}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--recipe", default="act_chunk", choices=list(train_backbones.RECIPES))
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--workers", default="0,1,2")
    ap.add_argument("--dataset", default=train_backbones.DATASET)
    args = ap.parse_args()
    if not (Path(args.dataset) / "meta" / "info.json").exists():
        raise SystemExit(f"bench_train_data: no dataset at {args.dataset}; run policies/record_dataset.py first")
    rows = []
    for w in [int(x) for x in args.workers.split(",")]:
        r = run(args.recipe, args.steps, w, args.dataset)
        rows.append(r)
        print(f"num_workers={w}: data {r['data_s'] * 1e3:.0f} ms + update {r['updt_s'] * 1e3:.0f} ms per step, "
              f"run {r['wall_s']:.0f} s", flush=True)
    base = rows[0]["step_s"]
    steps_total = train_backbones.RECIPES[args.recipe][1]
    lines = [
        "# A training step of a learned backbone on this CPU, with and without data-loader workers\n",
        f"Command: `.venv/bin/python eval/{Path(__file__).name} {' '.join(sys.argv[1:])}`  ",
        f"Ran on: {platform.machine()}, {os.cpu_count()} cores, no GPU; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; "
        f"recipe `{args.recipe}` ({steps_total} steps in full), {args.steps} steps per run, one torch thread, runs one "
        "after the other in this invocation. data = the time a step waited for its batch, update = forward + "
        "backward + optimizer, both from lerobot-train's own log at the last logged step.\n",
        "| --num_workers | data (ms/step) | update (ms/step) | step (ms) | speed-up vs 0 | the full recipe at this rate (min) | whole run (s) |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r['workers']} | {r['data_s'] * 1e3:.0f} | {r['updt_s'] * 1e3:.0f} | {r['step_s'] * 1e3:.0f} | "
                     f"{base / r['step_s']:.2f}x | {r['step_s'] * steps_total / 60:.0f} | {r['wall_s']:.0f} |")
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "README.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
