"""Offline replay: deterministic, equal to the corrector run frame by frame, and honest about
what it changed; datasets without the exported state replay from their columns."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_physvla.core.config import preset
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.replay import offline
from lerobot_physvla.replay.dataset import ReplayError, load
from lerobot_physvla.replay.write import RAW_ACTION, write_corrected

from replay_data import COLUMN_FEATURES, REPO_ID, column_episode, write_dataset


@pytest.fixture(scope="module")
def data(recorded):
    return load(REPO_ID, recorded)


def test_offline_replay_is_deterministic(data):
    a, _ = offline.replay_offline(data, preset(), progress=False)
    b, _ = offline.replay_offline(data, preset(), progress=False)
    for ra, rb in zip(a, b):
        assert np.array_equal(ra["_arrays"]["corrected"], rb["_arrays"]["corrected"])
        assert ra["phase_timeline"] == rb["phase_timeline"] and ra["corrections"] == rb["corrections"]


@pytest.mark.parametrize("name", ["default", "paper"])
def test_lockstep_batch_equals_the_corrector_frame_by_frame(data, name):
    """The batched replay gives each episode exactly what a B = 1 corrector gives it."""
    cfg = preset(name)
    recs, _ = offline.replay_offline(data, cfg, progress=False)
    for ep, rec in zip(data.episodes, recs):
        cor = Corrector(cfg)
        ref = np.stack([cor.correct_packed(ep.actions[t][None], ep.states[t][None])[0] for t in range(ep.frames)])
        assert np.array_equal(rec["_arrays"]["corrected"], ref)


def test_the_report_counts_exactly_what_changed(data):
    # default v2 (place redirection) changes a clean expert's place frames; the shipped default's
    # release veto leaves a clean expert alone, so it would not exercise the count
    recs, note = offline.replay_offline(data, preset(place_rule="redirect", place_tol_m=0.0), progress=False)
    assert note is None
    for ep, rec in zip(data.episodes, recs):
        cor = rec["_arrays"]["corrected"]
        changed = np.abs(cor - ep.actions).max(axis=1) > 0
        assert rec["frames_changed"] == int(changed.sum()) > 0
        per_phase = sum(v["frames_changed"] for k, v in rec["corrections"].items() if k != "branch B")
        assert per_phase == rec["frames_changed"]  # every change is attributed to one correction
        assert sum(n for _, n in rec["phase_timeline"]) == ep.frames
        assert rec["smoothness"]["raw"]["mean_jerk"] > 0


def test_workers_give_the_same_result(data):
    one, _ = offline.replay_offline(data, preset(), workers=1, batch=1, progress=False)
    two, _ = offline.replay_offline(data, preset(), workers=2, batch=1, progress=False)
    for a, b in zip(one, two):
        assert np.array_equal(a["_arrays"]["corrected"], b["_arrays"]["corrected"])


def test_corrected_copy_holds_the_corrected_actions_and_leaves_the_source(data, recorded, tmp_path):
    before = sorted((p, p.stat().st_mtime_ns) for p in recorded.rglob("*") if p.is_file())
    recs, _ = offline.replay_offline(data, preset(), progress=False)
    write_corrected(data, recs, tmp_path / "copy")
    copy = load("local/copy", tmp_path / "copy")
    for ep, rec, src in zip(copy.episodes, recs, data.episodes):
        np.testing.assert_allclose(ep.actions, rec["_arrays"]["corrected"], atol=1e-6)  # float32 column
        np.testing.assert_array_equal(ep.states, src.states)
        raw = copy.dataset.hf_dataset.with_format("numpy")[RAW_ACTION]
    assert np.asarray(raw).shape[1] == 7
    assert sorted((p, p.stat().st_mtime_ns) for p in recorded.rglob("*") if p.is_file()) == before
    with pytest.raises(ReplayError, match="exists"):
        write_corrected(data, recs, tmp_path / "copy")


def test_column_state_replays_a_training_dataset(tmp_path):
    """No exported state: eef and gripper from observation.state, object and target from
    observation.environment_state; phys_el runs with Branch B off and says so."""
    root = write_dataset(tmp_path / "cols", COLUMN_FEATURES, [column_episode(40, close_at=5, far=True)])
    data = load("local/t", root)
    recs, note = offline.replay_offline(data, preset(), progress=False)
    rec = recs[0]
    assert note is None and rec["corrections"]["approach veto"]["frames_changed"] > 0  # closed 0.3 m away: vetoed
    assert [f["why"] for f in rec["flagged"]] == ["gripper close far from the object"] and rec["flagged"][0]["frame"] == 5
    _, note = offline.replay_offline(data, preset("paper"), progress=False)
    assert "Branch B off" in note


def test_column_state_with_fixed_poses(tmp_path):
    feats = {k: v for k, v in COLUMN_FEATURES.items() if k != "observation.environment_state"}
    ep = {k: v for k, v in column_episode(20).items() if k != "observation.environment_state"}
    data = load("local/t", write_dataset(tmp_path / "fixed", feats, [ep]))
    with pytest.raises(ReplayError, match="--object_xyz"):
        offline.replay_offline(data, preset(), progress=False)
    cs = offline.ColumnState(object_xyz=(0.1, 0.0, 0.9), target_xyz=(-0.2, 0.1, 0.9))
    recs, _ = offline.replay_offline(data, preset(), cs, progress=False)
    assert recs[0]["frames"] == 20 and recs[0]["passthrough"] == {}


def test_unknown_robot_type_without_state(tmp_path):
    data = load("local/t", write_dataset(tmp_path / "so", COLUMN_FEATURES, [column_episode(5)], robot_type="so101_follower"))
    with pytest.raises(ReplayError, match="robot type 'so101_follower' has no state map"):
        offline.replay_offline(data, preset(), progress=False)


def test_release_in_transport_is_flagged():
    cfg = preset()
    raw = np.zeros((6, 7))
    raw[:, 6] = [1, 1, 1, -1, -1, -1]  # closed, then opened at frame 3
    st = np.zeros((6, 112))
    phase = np.array([1, 2, 2, 2, 2, 2])
    assert offline.flagged_frames(raw, st, phase, cfg) == [{"frame": 3, "why": "release in transport", "d_tgt_xy_m": None}]
    phase[3] = 3  # opened over the target: nothing wrong
    assert offline.flagged_frames(raw, st, phase, cfg) == []


@pytest.mark.slow
def test_ray_backend_gives_the_same_result(data):
    import ray

    local, _ = offline.replay_offline(data, preset(), batch=1, progress=False)
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        remote, _ = offline.replay_offline(data, preset(), workers=2, backend="ray", batch=1, progress=False)
    finally:
        ray.shutdown()
    for a, b in zip(local, remote):
        assert np.array_equal(a["_arrays"]["corrected"], b["_arrays"]["corrected"])
