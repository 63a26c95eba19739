"""A/B of the whole path inside lerobot-eval: this checkout against another git revision.

    .venv/bin/python eval/bench/ab_in_eval.py REV [--batch 1] [--alternations 4] [--mode phys_el]

This machine's speed drifts ~2x over minutes, so two bench runs made at different times cannot
be compared; this runs `eval/bench/overhead.py`'s in-lerobot-eval measurement (a fresh process
running lerobot-eval's eval_main, the reads, the capture step and the corrector step timed where
lerobot calls them) for REV (checked out into a temporary git worktree, imported through
PYTHONPATH) and for this checkout, alternating (A B, B A, A B, ...), and prints each run's p50 and
p99 per env-step (calls after the first) and the median of each over the runs.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "eval" / "bench"))
import overhead as bench_overhead  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rev", help="the git revision to compare this checkout with")
    ap.add_argument("--batch", type=int, default=1)
    ap.add_argument("--alternations", type=int, default=4)
    ap.add_argument("--episodes", type=int, default=4, help="lerobot-eval episodes per env")
    ap.add_argument("--mode", default="phys_el")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="physvla_ab_"))
    other = tmp / "other"
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(other), args.rev], check=True,
                   capture_output=True)
    policy = tmp / "scripted"
    subprocess.run([sys.executable, str(ROOT / "backbones/make_scripted_policy.py"), str(policy)], check=True,
                   capture_output=True)
    trees = {args.rev: other, "this checkout": ROOT}
    results: dict[str, list[tuple[float, float]]] = {name: [] for name in trees}
    try:
        for k in range(args.alternations):
            order = list(trees) if k % 2 == 0 else list(trees)[::-1]
            for name in order:
                os.environ["PYTHONPATH"] = str(trees[name])  # in_eval's subprocess imports this tree
                r = bench_overhead.in_eval(args.batch, args.batch * args.episodes, policy, tmp / f"out{k}{len(name)}",
                                           (f"--physvla.mode={args.mode}",))
                results[name].append((r["p50_us"], r["p99_us"]))
                print(f"{name}: p50 {r['p50_us']:.1f} us, p99 {r['p99_us']:.1f} us (B={args.batch})", flush=True)
    finally:
        os.environ.pop("PYTHONPATH", None)
        subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(other)], capture_output=True)
    for name, runs in results.items():
        p50, p99 = np.median(np.array(runs), axis=0)
        print(f"{name}: median over {len(runs)} runs: p50 {p50:.1f} us, p99 {p99:.1f} us")


if __name__ == "__main__":
    main()
