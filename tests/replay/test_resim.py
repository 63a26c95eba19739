"""Re-simulation: the recorded actions, executed again from the recorded start, reproduce the
recorded episode; with the corrector they are corrected live."""

from __future__ import annotations

import pytest

from lerobot_physvla.core.config import preset
from lerobot_physvla.replay.dataset import ReplayError, load
from lerobot_physvla.replay.resim import replay_resim

from replay_data import COLUMN_FEATURES, REPO_ID, column_episode, write_dataset

pytestmark = pytest.mark.slow  # subprocess console scripts / re-simulation


def test_resim_reproduces_the_recorded_episode(recorded):
    data = load(REPO_ID, recorded, [0])
    # the paper's blend (c = 0.05) moves every frame; the shipped default leaves a clean expert's
    # episode untouched, so it would not show the live correction
    (rec,) = replay_resim(data, preset("paper"), progress=False)
    assert rec["recorded_success"] is True and rec["raw"]["success"] is True
    assert rec["state_divergence_m"] == 0.0  # bit-for-bit the recorded trajectory
    assert rec["raw"]["steps"] == data.episodes[0].frames and rec["raw"]["frames_changed"] == 0
    assert rec["corrected"]["frames_changed"] > 0


def test_resim_needs_the_episode_identity(tmp_path):
    data = load("local/t", write_dataset(tmp_path / "cols", COLUMN_FEATURES, [column_episode(5)]))
    with pytest.raises(ReplayError, match="physvla.episode"):
        replay_resim(data, preset(), progress=False)


def test_resim_on_robosuite_lift_plate(tmp_path):
    """A recorded Lift place-on-plate failure (persistent place bias, seed 100): re-run raw it fails
    again along the same trajectory; with the place redirection (default v2) it succeeds. (The
    shipped default's release veto does not rescue this episode: docs/method.md.)"""
    from lerobot_physvla.replay.record import record

    root = tmp_path / "lift"
    out = record(root, ["lift_plate"], [100], expert={"place_bias_units": 1.7}, progress=False)
    assert out["successes"] == 0
    (rec,) = replay_resim(load("local/physvla_replay", root), preset(place_rule="redirect", place_tol_m=0.0),
                          progress=False)
    assert rec["scene"] == "lift_plate" and rec["recorded_success"] is False
    assert rec["raw"]["success"] is False and rec["state_divergence_m"] == 0.0
    assert rec["corrected"]["success"] is True and rec["corrected"]["frames_changed"] > 0


def test_resim_reads_the_state_through_the_perception_model(tmp_path):
    """The recorded Lift failure above, re-simulated with the poses 3 steps late and the corrector told to act
    on none older than 1: every step passes through (stale_pose), so the corrected run is the raw one."""
    from lerobot_physvla.replay.record import record
    from lerobot_physvla.sources.perception import PerceptionConfig

    root = tmp_path / "lift"
    record(root, ["lift_plate"], [100], expert={"place_bias_units": 1.7}, progress=False)
    data = load("local/physvla_replay", root)
    cfg = preset(place_rule="redirect", place_tol_m=0.0, pose_max_age_steps=1)
    (late,) = replay_resim(data, cfg, progress=False, perception=PerceptionConfig.both(lag_steps=3))
    assert late["corrected"]["frames_changed"] == 0 and late["corrected"]["success"] is False
    (fresh,) = replay_resim(data, cfg, progress=False, perception=PerceptionConfig.both(lag_steps=1))
    assert fresh["corrected"]["frames_changed"] > 0
