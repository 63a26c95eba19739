"""Shared fixtures: hand-built physical states and (session-scoped) real LIBERO scenes."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_physvla.core.state import PhysState


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
