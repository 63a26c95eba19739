"""A corrected copy of a dataset: a new LeRobotDataset whose `action` column is the corrector's
output (the recorded action kept as `physvla.raw_action`); the source is never touched.

State-only datasets (no image or video features) are copied frame by frame through lerobot's
own writer; the other columns are copied as stored.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lerobot_physvla.replay import columns as C
from lerobot_physvla.replay.dataset import ReplayData, ReplayError, arrow_table, column, quiet

RAW_ACTION = "physvla.raw_action"
_LEROBOT_OWN = ("timestamp", "frame_index", "episode_index", "index", "task_index")


def check_writable(data: ReplayData) -> None:
    media = [k for k, f in data.features.items() if f.get("dtype") in ("image", "video")]
    if media:
        raise ReplayError(f"--write_dataset copies state-only datasets; this one has image/video features {media}")


def write_corrected(data: ReplayData, records: list[dict], out_root: str | Path, repo_id: str | None = None) -> Path:
    """Write the selected episodes with their corrected actions (records of offline replay) to out_root."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    check_writable(data)
    out_root = Path(out_root)
    if out_root.exists():
        raise ReplayError(f"{out_root} exists; choose a new --output_dir")
    feats = {k: dict(f) for k, f in data.features.items() if k not in _LEROBOT_OWN}
    feats[RAW_ACTION] = dict(feats[C.ACTION])
    for f in feats.values():
        f["shape"] = tuple(f["shape"])
    table = arrow_table(data.dataset)
    cols = {k: column(table, k) for k in feats if k not in (C.ACTION, RAW_ACTION) and k in table.column_names}
    by_episode = {r["episode"]: r for r in records}
    ds = LeRobotDataset.create(repo_id or f"{data.repo_id}_physvla", fps=int(round(data.fps)), features=feats,
                               root=out_root, robot_type=data.robot_type, use_videos=False,
                               video_backend="pyav")
    try:
        for ep in data.episodes:
            corrected = by_episode[ep.index]["_arrays"]["corrected"]
            dtype = np.dtype(feats[C.ACTION]["dtype"])
            for t, row in enumerate(ep.rows):
                frame = {k: _cell(v[row], feats[k]) for k, v in cols.items()}
                frame[C.ACTION] = corrected[t].astype(dtype)
                frame[RAW_ACTION] = ep.actions[t].astype(dtype)
                frame["task"] = ep.task
                ds.add_frame(frame)
            quiet()  # lerobot's loaders switch datasets' bars back on
            ds.save_episode()
    finally:
        ds.finalize()
    return out_root


def _cell(value, feature: dict):
    arr = np.asarray(value, dtype=np.dtype(feature["dtype"]))
    return arr.reshape(feature["shape"])
