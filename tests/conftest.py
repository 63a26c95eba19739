"""Shared fixtures: hand-built physical states, (session-scoped) real LIBERO scenes, and a small
recorded dataset for the replay tests (the scripted expert saved as a LeRobot checkpoint, on
LIBERO-Spatial task 0, init states 10 and 11, through the project's recorder)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lerobot_physvla.core.state import PhysState


# Files that run console scripts, train or compile in subprocesses, longest first (minutes each on 2 cores). CI runs
# `-n auto --dist loadfile` with xdist's reorder by test count off (pyproject.toml): whole files go to the workers in
# collection order, so these start first and the many short files fill in behind them, and the workers end together.
# A file missing here only runs later; the order never changes what a test checks.
FIRST = (
    "tests/scripts/test_lerobot_eval.py",
    "tests/eval/test_learned_backbones.py",
    "tests/test_readme.py",
    "tests/policies/test_camera_policies.py",
    "tests/core/test_corrections.py",
    "tests/robots/test_lerobot_rollout_sim_arms.py",
    "tests/test_moved.py",
    "tests/robots/test_lerobot_rollout_rtc.py",
    "tests/scripts/test_lerobot_eval_metaworld.py",
)


def pytest_collection_modifyitems(config, items):
    rank = {path: k for k, path in enumerate(FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(FIRST)))  # stable: the rest keep their order


def make_state(
    batch_size: int = 1,
    n: int = 7,
    eef=(0.0, 0.0, 1.0),
    obj=(0.0, 0.0, 0.9),
    target=(0.3, 0.0, 0.9),
    lift: float = 0.0,
    dt: float = 0.05,
    seed: int = 0,
) -> PhysState:
    """A valid state with a well-conditioned random arm (M SPD, full-rank J)."""
    rng = np.random.default_rng(seed)
    st = PhysState.empty(batch_size, n)
    st.valid[:] = True
    st.dt[:] = dt
    st.eef_pos[:] = eef
    st.obj_pos[:] = obj
    st.obj_rest_z[:] = np.asarray(obj, dtype=float)[2] - lift
    st.obj_pos[:, 2] = np.asarray(obj, dtype=float)[2]
    st.target_pos[:] = target
    a = rng.normal(size=(batch_size, n, n))
    st.M[:] = a @ a.transpose(0, 2, 1) / n + np.eye(n)
    st.J_pos[:] = rng.normal(size=(batch_size, 3, n)) * 0.3
    st.q[:] = rng.normal(size=(batch_size, n))
    st.qdot[:] = rng.normal(size=(batch_size, n)) * 0.1
    st.bias[:] = rng.normal(size=(batch_size, n))
    st.tau[:] = st.bias + rng.normal(size=(batch_size, n)) * 0.1
    return st


@pytest.fixture(scope="session")
def libero_task0():
    """LIBERO-Spatial task 0 built offline with no renderer, reset to init state 0."""
    from lerobot_physvla.sim import libero_sim

    task = libero_sim.load_task("libero_spatial", 0)
    env = libero_sim.make_libero_env(task)
    libero_sim.reset_to_init_state(env, task, 0)
    yield task, env
    env.close()


ROOT = Path(__file__).resolve().parents[1]
REPLAY_REPO_ID = "local/replay_test"  # tests/replay/replay_data.REPO_ID


@pytest.fixture(scope="session")
def random_policy():
    """backbones/make_random_policy.py's make(out, type="act", inputs="state", seed=0), in process, loaded by its
    path (the module the tests import as `backbones` is eval/backbones.py)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_random_policy", ROOT / "backbones/make_random_policy.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.make


@pytest.fixture(scope="session")
def scripted_policy(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("policy") / "scripted"
    r = subprocess.run([sys.executable, str(ROOT / "backbones/make_scripted_policy.py"), str(out)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return out


@pytest.fixture(scope="session")
def recorded(tmp_path_factory, scripted_policy) -> Path:
    """Dataset root: 2 episodes recorded from the scripted policy checkpoint (both succeed)."""
    from lerobot_physvla.replay.record import record

    root = tmp_path_factory.mktemp("datasets") / "replay_test"
    out = record(root, ["libero_spatial/0"], [10, 11], REPLAY_REPO_ID, policy_path=str(scripted_policy), progress=False)
    assert out["episodes"] == 2 and out["successes"] == 2
    return root
