"""Do-no-harm of the LeRobot steps for every input, as lerobot hands it over (torch tensors).

The capture step publishes whatever state the observation carries (any field extreme, zero,
negative or non-finite, the wrong batch, none at all); the corrector step gets actions of any
value, dtype, shape ((B, A), (B, T, A), a wrong last dimension) and batch. Whatever happens: no
exception, same shape / dtype / device out, every entry finite and inside the layout's bounds, a
non-finite policy entry never in the output, and every action it could not correct counted.
"""

from __future__ import annotations

import itertools

import numpy as np
import torch
from hypothesis import given, settings
from hypothesis import strategies as st_

from lerobot.lerobot_types import TransitionKey

from lerobot_physvla.core.config import LAYOUTS, MODES, PhysVLAConfig
from lerobot_physvla.core.state import _FIELDS
from lerobot_physvla.processor.physvla_processor import (
    EXTRA_KEY, ROBOT_STATE, STATE_KEY, PhysVLACorrectorStep, PhysVLAStateCaptureStep,
)

from conftest import make_state

FIELD_NAMES = [name for name, _ in _FIELDS]
EXTREME = [0.0, -1.0, -1e-300, 1e300, -1e300, np.nan, np.inf, -np.inf]
_BUS = itertools.count()


def _counted(step: PhysVLACorrectorStep) -> int:
    """Actions the step or its corrector did not correct or had to guard, all reasons."""
    c = step.corrector
    return sum(step.passthrough_counts.values()) + sum(c.passthrough_counts.values()) + sum(c.guard_counts.values())


@settings(max_examples=250, deadline=None)
@given(
    field=st_.sampled_from(FIELD_NAMES),
    value=st_.sampled_from(EXTREME),
    where=st_.integers(0, 10_000),
    mode=st_.sampled_from(MODES),
    preset=st_.sampled_from([None, "default", "paper_alg1", "smooth"]),
    layout=st_.sampled_from(sorted(LAYOUTS)),
    horizon=st_.sampled_from([None, 1, 5]),
    dtype=st_.sampled_from([torch.float32, torch.float64, torch.bfloat16]),
    bad_action=st_.sampled_from([None, np.nan, np.inf, -np.inf]),
    scale=st_.sampled_from([0.5, 3.0, 1e30]),
    state_batch=st_.sampled_from(["same", "other", "none", "flat"]),
    wrong_dim=st_.booleans(),
    seed=st_.integers(0, 50),
)
def test_the_step_never_raises_and_emits_finite_in_bounds_actions(
    field, value, where, mode, preset, layout, horizon, dtype, bad_action, scale, state_batch, wrong_dim, seed
):
    from lerobot_physvla.core.config import PRESETS

    lay = LAYOUTS[layout]
    cfg = PRESETS[preset] if preset else PhysVLAConfig.paper(mode=mode)
    weighting = "joint_diag" if lay.dim == 7 and seed % 2 else "task_space"
    cfg = cfg.replace(layout=layout, weighting=weighting)
    bus = f"dnh-{next(_BUS)}"
    cap, step = PhysVLAStateCaptureStep(bus=bus), PhysVLACorrectorStep(config=cfg.to_dict(), bus=bus)
    b = 2
    rng = np.random.default_rng(seed)
    a_dim = lay.dim + (1 if wrong_dim else 0)
    shape = (b, a_dim) if horizon is None else (b, horizon, a_dim)
    for t in range(3):  # memory and the episode counter carry over
        st = make_state(b, 7, eef=(0.01, 0.0, 1.0), obj=(0.0, 0.0, 0.9), lift=0.05 * (seed % 3 == 0), seed=seed)
        st.episode_step[:] = t
        arr = getattr(st, field).reshape(b, -1)
        arr[where % b, where % arr.shape[1]] = value
        rows = st.pack()
        if state_batch == "other":
            rows = np.concatenate([rows, rows])
        if state_batch != "none":
            obs = ({ROBOT_STATE: {STATE_KEY: torch.from_numpy(rows), EXTRA_KEY: torch.zeros(len(rows), 9,
                                                                                             dtype=torch.float64)}}
                   if state_batch != "flat" else {"observation.physvla_state": torch.from_numpy(rows)})
            out_obs = cap({TransitionKey.OBSERVATION: obs})[TransitionKey.OBSERVATION]
            assert not any("physvla" in k for k in out_obs)  # the policy never sees the state
        a = rng.uniform(-scale, scale, shape)
        if bad_action is not None:
            a.reshape(b, -1)[where % b, where % a.reshape(b, -1).shape[1]] = bad_action
        action = torch.from_numpy(a).to(dtype)
        before = _counted(step)
        out = step({TransitionKey.ACTION: action})[TransitionKey.ACTION]  # never raises
        assert out.shape == action.shape and out.dtype == action.dtype
        o = out.double().numpy()
        assert np.isfinite(o).all()
        assert (o >= lay.low).all() and (o <= lay.high).all()
        a_in = action.double().numpy()
        bad = ~np.isfinite(a_in)
        if bad.any():  # never in the output: held (0 on delta channels) or set to 0 (unknown layout)
            first_in, first_out = (a_in, o) if horizon is None else (a_in[:, 0], o[:, 0])
            for i in np.flatnonzero(~np.isfinite(first_in).all(axis=1)):
                delta = ~lay.absolute_mask if not wrong_dim else np.ones(a_dim, bool)
                if wrong_dim:
                    assert (first_out[i][~np.isfinite(first_in[i])] == 0.0).all()
                else:
                    assert (first_out[i, delta[: lay.dim]] == 0.0).all()
        uncorrectable = wrong_dim or state_batch in ("other", "none") or bad.any()
        if uncorrectable:
            assert _counted(step) > before, (step.passthrough_counts, step.corrector.passthrough_counts)
