"""Small datasets written through lerobot's own writer, for the replay tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

REPO_ID = "local/replay_test"


def write_dataset(root: Path, features: dict, episodes: list[dict], robot_type: str = "panda", fps: int = 20) -> Path:
    """A LeRobotDataset from per-episode {feature: (T, ...) array}, through lerobot's writer."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_physvla.replay.dataset import quiet

    ds = LeRobotDataset.create("local/t", fps=fps, features=features, root=root, robot_type=robot_type,
                               use_videos=False, video_backend="pyav")
    for ep in episodes:
        n = len(next(iter(ep.values())))
        for t in range(n):
            ds.add_frame({**{k: np.asarray(v[t]) for k, v in ep.items()}, "task": "synthetic"})
        quiet()
        ds.save_episode()
    ds.finalize()
    return root


COLUMN_FEATURES = {  # what backbones/record_dataset.py (the training recorder) writes: no physical state
    "observation.state": {"dtype": "float32", "shape": (8,), "names": None},
    "observation.environment_state": {"dtype": "float32", "shape": (6,), "names": None},
    "action": {"dtype": "float32", "shape": (7,), "names": None},
}


def column_episode(t: int = 40, close_at: int | None = None, far: bool = False) -> dict:
    """An approach toward an object at (0.1, 0, 0.9): eef moving in, gripper open unless close_at."""
    s = np.zeros((t, 8), np.float32)
    s[:, 0] = np.linspace(0.4 if far else 0.3, 0.1, t)
    s[:, 2] = 1.0
    s[:, 6], s[:, 7] = 0.04, -0.04
    env = np.tile(np.array([0.1, 0.0, 0.9, -0.2, 0.1, 0.9], np.float32), (t, 1))
    a = np.zeros((t, 7), np.float32)
    a[:, 0] = -0.5
    a[:, 6] = -1.0
    if close_at is not None:
        a[close_at:, 6] = 1.0
    return {"observation.state": s, "observation.environment_state": env, "action": a}
