"""Offline replay speed on a 10^5-frame dataset, side by side with plain LeRobotDataset reads.

    .venv/bin/python eval/bench/replay.py [--frames 100000] [--item-sample 2000] [--out eval/results/bench_replay]

1. Dataset: the project's recorder writes LIBERO-Spatial episodes of the jitter expert (tasks
   0-1, init states 10-11, packed physical state included); they are tiled, through lerobot's own
   writer, into a dataset of --frames frames (kept under outputs/bench_replay/ and reused).
2. In one process, timed side by side on that dataset:
   - plain iteration: `LeRobotDataset[i]` frame by frame (what a DataLoader does; timed on the
     first --item-sample frames, reported per frame);
   - plain columnar read: every numeric column of LeRobotDataset's Arrow table to numpy;
   - replay: `lerobot_physvla.replay.dataset.load` (open + columns to per-episode arrays), then
     offline correction of every frame (default preset, episodes in lockstep, B = 64), in this
     process and with 2 worker processes.
Prints a table of frames/s and the ratios, and last
`offline replay <x> frames/s (<y>x plain iteration, <z>x the columnar read)`; writes README.md
and results.json to --out.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
REPO = "local/bench_replay"


def build(frames: int, cache: Path) -> Path:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_physvla.replay import dataset as D
    from lerobot_physvla.replay.record import record

    base, big = cache / "base", cache / f"tiled_{frames}"
    if (big / "meta" / "info.json").is_file():
        return big
    if not (base / "meta" / "info.json").is_file():
        shutil.rmtree(base, ignore_errors=True)
        record(base, ["libero_spatial/0", "libero_spatial/1"], [10, 11], REPO, expert={"action_noise": 0.3,
                                                                                          "aim_noise_m": 0.015})
    src = D.load(REPO, base)
    shutil.rmtree(big, ignore_errors=True)
    feats = {k: {**f, "shape": tuple(f["shape"])} for k, f in src.features.items()
             if k not in ("timestamp", "frame_index", "episode_index", "index", "task_index")}
    ds = LeRobotDataset.create(REPO, fps=int(src.fps), features=feats, root=big, robot_type=src.robot_type,
                               use_videos=False, video_backend="pyav")
    table = D.arrow_table(src.dataset)
    cols = {k: D.column(table, k) for k in feats}
    n, k = 0, 0
    t0 = time.time()
    while n < frames:
        ep = src.episodes[k % len(src.episodes)]
        rows = ep.rows[: frames - n]
        for r in rows:
            ds.add_frame({**{c: np.asarray(v[r], dtype=feats[c]["dtype"]).reshape(feats[c]["shape"])
                             for c, v in cols.items()}, "task": ep.task})
        D.quiet()
        ds.save_episode()
        n, k = n + len(rows), k + 1
        print(f"\rtiling: {n}/{frames} frames ({time.time() - t0:.0f} s)", end="", file=sys.stderr)
    ds.finalize()
    print(file=sys.stderr)
    return big


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=100_000)
    ap.add_argument("--item-sample", type=int, default=2000)
    ap.add_argument("--out", default=str(ROOT / "eval/results/bench_replay"))
    ap.add_argument("--cache", default=str(ROOT / "outputs/bench_replay"))
    args = ap.parse_args()

    import torch

    torch.set_num_threads(1)
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_physvla.core.config import preset
    from lerobot_physvla.replay import dataset as D
    from lerobot_physvla.replay.offline import replay_offline

    root = build(args.frames, Path(args.cache))
    rows = {}

    t0 = time.perf_counter()
    ds = LeRobotDataset(REPO, root=root, video_backend="pyav")
    n_items = min(args.item_sample, ds.num_frames)
    for i in range(n_items):
        ds[i]
    t_item = (time.perf_counter() - t0) / n_items
    rows["plain iteration, LeRobotDataset[i]"] = 1.0 / t_item

    t0 = time.perf_counter()
    ds = LeRobotDataset(REPO, root=root, video_backend="pyav")
    table = D.arrow_table(ds)
    for name in ds.features:
        if ds.features[name]["dtype"] not in ("string", "image", "video") and name in table.column_names:
            D.column(table, name)
    t_cols = time.perf_counter() - t0
    rows["plain columnar read, all numeric columns"] = ds.num_frames / t_cols

    t0 = time.perf_counter()
    data = D.load(REPO, root)
    t_load = time.perf_counter() - t0
    frames = data.frames
    rows["replay: load (open + per-episode arrays)"] = frames / t_load
    timings = {}
    for workers in (1, 2):
        replay_offline(data, preset(), workers=workers, progress=False)  # warm: compiled kernels, pool start
        t0 = time.perf_counter()
        recs, _ = replay_offline(data, preset(), workers=workers, progress=False)
        timings[workers] = time.perf_counter() - t0
        rows[f"replay: correction + per-episode report, {workers} process{'es' if workers > 1 else ''}"] = frames / timings[workers]
    best = min(timings.values())
    whole = frames / (t_load + best)
    rows["replay: whole (load + correction + report)"] = whole
    changed = sum(r["frames_changed"] for r in recs)

    plain = rows["plain iteration, LeRobotDataset[i]"]
    cols = rows["plain columnar read, all numeric columns"]
    lines = [
        f"# Offline replay speed ({frames} frames, {len(data.episodes)} episodes)",
        "",
        f"Command: `.venv/bin/python eval/bench/replay.py --frames {args.frames} --item-sample {args.item_sample}`",
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; one run, every row timed in it.",
        "",
        "| path | frames / s | / plain iteration | / columnar read |",
        "|---|---|---|---|",
    ]
    for k, v in rows.items():
        lines.append(f"| {k} | {v:,.0f} | {v / plain:.1f} | {v / cols:.2f} |")
    lines += ["", f"Frames the default corrector changed: {changed} of {frames}.",
              f"Plain iteration timed on the first {n_items} frames."]
    last = f"offline replay {whole:,.0f} frames/s ({whole / plain:.1f}x plain iteration, {whole / cols:.2f}x the columnar read)"
    lines += ["", last]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "README.md").write_text("\n".join(lines) + "\n")
    (out / "results.json").write_text(json.dumps({"frames": frames, "frames_per_s": rows, "changed": changed}, indent=2))
    print("\n".join(lines[5:-2]))
    print(last)


if __name__ == "__main__":
    main()
