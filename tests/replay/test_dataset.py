"""Opening datasets for replay: what comes out, and a one-line error for every bad input."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from lerobot_physvla.core.state import packed_size
from lerobot_physvla.replay import columns as C
from lerobot_physvla.replay.dataset import ReplayError, load

from replay_data import COLUMN_FEATURES, REPO_ID, column_episode, write_dataset


def test_load_keeps_float64_state_and_episode_identity(recorded):
    data = load(REPO_ID, recorded)
    assert data.total_episodes == 2 and [e.index for e in data.episodes] == [0, 1]
    ep = data.episodes[1]
    assert ep.states.dtype == np.float64 and ep.states.shape == (ep.frames, packed_size(7))
    assert list(ep.source) == [0, 0, 11] and ep.success is True
    assert ep.obs[C.STATE].shape == (ep.frames, 8) and "pick up" in ep.task
    # the packed state is stored whole in float64: the control period reads back exactly
    assert np.all(ep.states[:, 2] == 0.05)


def test_episode_selection(recorded):
    data = load(REPO_ID, recorded, [1])
    assert [e.index for e in data.episodes] == [1] and data.total_episodes == 2


@pytest.mark.parametrize("root, match", [(None, "--dataset.root is required"), ("missing", "does not exist")])
def test_missing_root(tmp_path, root, match):
    with pytest.raises(ReplayError, match=match):
        load(REPO_ID, None if root is None else tmp_path / root)


def test_directory_without_metadata(tmp_path):
    (tmp_path / "data").mkdir()
    with pytest.raises(ReplayError, match="has no meta/info.json"):
        load(REPO_ID, tmp_path)


def test_episodes_out_of_range(recorded):
    with pytest.raises(ReplayError, match=r"--episodes \[2, -1\] out of range: the dataset has 2 episodes \(0-1\)"):
        load(REPO_ID, recorded, [0, 2, -1])


def test_corrupt_parquet_is_one_line(recorded, tmp_path):
    bad = tmp_path / "bad"
    shutil.copytree(recorded, bad)
    for f in (bad / "data").rglob("*.parquet"):
        f.write_bytes(b"this is not parquet")
    with pytest.raises(ReplayError, match="could not read the dataset") as e:
        load(REPO_ID, bad)
    assert "\n" not in str(e.value)


def test_dataset_without_action(tmp_path):
    feats = {k: v for k, v in COLUMN_FEATURES.items() if k != "action"}
    ep = {k: v for k, v in column_episode(5).items() if k != "action"}
    root = write_dataset(tmp_path / "noact", feats, [ep])
    with pytest.raises(ReplayError, match="no 'action' column"):
        load("local/t", root)
