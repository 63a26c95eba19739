"""Open a local LeRobotDataset (v3) as per-episode numpy arrays, with one-line errors.

Read through lerobot's `LeRobotDataset` (its metadata and its Arrow table); columns are
converted whole, in their stored dtype (the packed physical state stays float64), never frame
by frame. Nothing is downloaded: the dataset must be on disk at `root`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lerobot_physvla.core.state import upgrade
from lerobot_physvla.replay import columns as C


class ReplayError(ValueError):
    """Bad input to the replay: the message says what is missing or what to do."""


@dataclass
class Episode:
    """One recorded episode.

    Attributes:
        index: the dataset's episode_index.
        task: the task's text.
        actions: (T, A) recorded actions, float64.
        states: (T, L) packed physical states (observation.physvla_state), or None.
        obs: {feature: (T, d)} every other numeric column (observation.*), as stored.
        success: whether the episode succeeded (next.success at any frame), or None if not recorded.
        source: physvla.episode [scene code, task id, seed] of the first frame, or None.
        rows: (T,) the frames' row numbers in the dataset's table.
    """

    index: int
    task: str
    actions: np.ndarray
    states: np.ndarray | None
    obs: dict[str, np.ndarray] = field(default_factory=dict)
    success: bool | None = None
    source: np.ndarray | None = None
    rows: np.ndarray | None = None

    @property
    def frames(self) -> int:
        return len(self.actions)


@dataclass
class ReplayData:
    """A dataset opened for replay.

    Attributes:
        repo_id, root: as given.
        fps: frames per second (the control period is 1 / fps).
        robot_type: the dataset's robot_type (meta/info.json).
        features: LeRobot's feature dict of the dataset.
        total_episodes: episodes in the dataset (selected or not).
        episodes: the selected episodes, in index order.
        dataset: the LeRobotDataset itself (for writing a corrected copy).
    """

    repo_id: str
    root: Path
    fps: float
    robot_type: str | None
    features: dict
    total_episodes: int
    episodes: list[Episode]
    dataset: object = None

    @property
    def frames(self) -> int:
        return sum(e.frames for e in self.episodes)

    @property
    def has_physvla_state(self) -> bool:
        return C.PHYSVLA_STATE in self.features


def column(table, name: str) -> np.ndarray:
    """One Arrow column as a numpy array: (N,) scalars or (N, d) fixed-size lists, stored dtype."""
    import pyarrow as pa

    col = table.column(name).combine_chunks()
    if pa.types.is_fixed_size_list(col.type) or pa.types.is_list(col.type):
        flat = col.flatten().to_numpy(zero_copy_only=False)
        return flat.reshape(len(col), -1)
    return col.to_numpy(zero_copy_only=False)


def quiet() -> None:
    """No per-episode "Map" progress bars from datasets (lerobot's writer would print one per episode)."""
    from datasets.utils.logging import disable_progress_bar

    disable_progress_bar()


def arrow_table(ds):
    """The Arrow table behind a LeRobotDataset (its rows, in stored order and dtype)."""
    hf = ds.hf_dataset
    if getattr(hf, "_indices", None) is None:
        return hf.data.table
    return hf.with_format("arrow")[:]


def load(repo_id: str, root: str | Path | None, episodes: list[int] | None = None) -> ReplayData:
    """Open the dataset at `root` and read the selected episodes (all if None)."""
    if root is None:
        raise ReplayError("--dataset.root is required: replay reads a LeRobotDataset on disk (nothing is downloaded)")
    root = Path(root)
    if not (root / "meta" / "info.json").is_file():
        what = "does not exist" if not root.exists() else "has no meta/info.json"
        raise ReplayError(f"--dataset.root={root} {what}: point it at a LeRobotDataset v3 directory")
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    quiet()
    try:
        ds = LeRobotDataset(repo_id, root=root, video_backend="pyav")  # state columns: no video decoder to probe
        table = arrow_table(ds)
    except Exception as e:  # noqa: BLE001 - any reading failure becomes one line naming the dataset
        first = str(e).strip().splitlines()[0] if str(e).strip() else ""
        raise ReplayError(f"could not read the dataset at {root} ({type(e).__name__}: {first[:200]}); "
                          f"check or re-record its data/ and meta/ files") from None
    feats = dict(ds.features)
    if C.ACTION not in feats:
        raise ReplayError(f"the dataset at {root} has no 'action' column; its features: {sorted(feats)}")
    total = int(ds.meta.total_episodes)
    chosen = list(range(total)) if episodes is None else [int(e) for e in episodes]
    bad = [e for e in chosen if not 0 <= e < total]
    if bad:
        raise ReplayError(f"--episodes {bad} out of range: the dataset has {total} episodes (0-{total - 1})")

    ep_index = column(table, "episode_index")
    actions = column(table, C.ACTION).astype(np.float64)
    states = column(table, C.PHYSVLA_STATE).astype(np.float64) if C.PHYSVLA_STATE in table.column_names else None
    if states is not None:
        states = upgrade(states)  # recorded before pose_age existed: age 0
    success = column(table, C.SUCCESS).reshape(-1).astype(bool) if C.SUCCESS in table.column_names else None
    source = column(table, C.EPISODE) if C.EPISODE in table.column_names else None
    numeric = [k for k, f in feats.items() if k.startswith("observation.") and k != C.PHYSVLA_STATE
               and f.get("dtype") not in ("image", "video", "string") and k in table.column_names]
    obs_cols = {k: column(table, k) for k in numeric}
    task_index = column(table, "task_index")
    tasks = _task_names(ds)
    order = np.argsort(ep_index, kind="stable")
    sorted_ep = ep_index[order]
    out = []
    for e in sorted(set(chosen)):
        lo, hi = np.searchsorted(sorted_ep, e), np.searchsorted(sorted_ep, e, side="right")
        rows = order[lo:hi]
        if len(rows) == 0:
            raise ReplayError(f"episode {e} has no frames in {root}/data; the dataset is incomplete, re-record it")
        out.append(Episode(
            index=e, task=tasks.get(int(task_index[rows[0]]), ""), actions=actions[rows],
            states=None if states is None else states[rows], obs={k: v[rows] for k, v in obs_cols.items()},
            success=None if success is None else bool(success[rows].any()),
            source=None if source is None else source[rows[0]], rows=rows,
        ))
    return ReplayData(repo_id, root, float(ds.fps), ds.meta.robot_type, feats, total, out, ds)


def _task_names(ds) -> dict[int, str]:
    tasks = ds.meta.tasks
    try:  # v3: a DataFrame indexed by the task text, with a task_index column
        return {int(i): str(t) for t, i in zip(tasks.index, tasks["task_index"])}
    except Exception:  # noqa: BLE001 - an unexpected table shape only loses the task text
        return {}
