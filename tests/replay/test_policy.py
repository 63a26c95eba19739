"""Policy mode: a policy replayed on observations it recorded itself gives back its actions."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_physvla.core.config import preset
from lerobot_physvla.replay.dataset import load
from lerobot_physvla.replay.policy import LeRobotPolicy, replay_policy

from replay_data import REPO_ID


def test_the_recording_policy_reproduces_its_actions(recorded, scripted_policy):
    data = load(REPO_ID, recorded)
    recs = replay_policy(data, str(scripted_policy), preset("paper"), progress=False)  # moves every frame
    for rec in recs:
        assert rec["mse_raw_mean"] < 1e-8, rec["mse_raw"]  # float32 observations: ~0, not exactly 0
        assert rec["mse_corrected_mean"] > rec["mse_raw_mean"]  # the corrector moves the actions it corrects
        np.testing.assert_allclose(rec["_arrays"]["raw"], rec["_arrays"]["recorded"], atol=1e-3)


def test_a_directory_without_checkpoint(tmp_path):
    with pytest.raises(ValueError, match="holds no LeRobot checkpoint"):
        LeRobotPolicy(tmp_path)
