"""A small dataset the tests record themselves: the scripted expert, saved as a LeRobot
checkpoint, on LIBERO-Spatial task 0, init states 10 and 11, through the project's recorder."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
from replay_data import REPO_ID


@pytest.fixture(scope="session")
def scripted_policy(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("policy") / "scripted"
    r = subprocess.run([sys.executable, str(ROOT / "policies/make_scripted_policy.py"), str(out)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return out


@pytest.fixture(scope="session")
def recorded(tmp_path_factory, scripted_policy) -> Path:
    """Dataset root: 2 episodes recorded from the scripted policy checkpoint (both succeed)."""
    from lerobot_physvla.replay.record import record

    root = tmp_path_factory.mktemp("datasets") / "replay_test"
    out = record(root, ["libero_spatial/0"], [10, 11], REPO_ID, policy_path=str(scripted_policy), progress=False)
    assert out["episodes"] == 2 and out["successes"] == 2
    return root
