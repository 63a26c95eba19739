"""Do-no-harm for every input: any field of the state, any action, any mode, layout and shape.

No exception leaves the corrector, every emitted action is finite and inside the bounds, a
non-finite policy action becomes the layout's hold action, and every pass-through is counted.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st_

from lerobot_physvla.core.config import LAYOUTS, MODES, PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.state import _FIELDS

from conftest import make_state

FIELD_NAMES = [name for name, _ in _FIELDS]
EXTREME = [0.0, -0.0, -1.0, -1e-300, 1e-300, 1e300, -1e300, 1e30, np.nan, np.inf, -np.inf]


@settings(max_examples=400, deadline=None)
@given(
    field=st_.sampled_from(FIELD_NAMES),
    value=st_.sampled_from(EXTREME),
    where=st_.integers(0, 10_000),
    whole_field=st_.booleans(),
    mode=st_.sampled_from(MODES),
    layout=st_.sampled_from(sorted(LAYOUTS)),
    weighting=st_.sampled_from(["joint_diag", "task_space"]),
    el=st_.sampled_from(["soft", "gated"]),
    grip=st_.sampled_from(["blend", "veto"]),
    chunk=st_.sampled_from([None, "all", "first"]),
    scale=st_.sampled_from([0.5, 3.0, 1e6]),
    bad_action=st_.sampled_from([None, np.nan, np.inf, -np.inf]),
    seed=st_.integers(0, 100),
    beyond=st_.booleans(),
)
def test_any_state_field_and_action_gives_a_finite_in_bounds_action(
    field, value, where, whole_field, mode, layout, weighting, el, grip, chunk, scale, bad_action, seed, beyond
):
    lay = LAYOUTS[layout]
    n = lay.dim if weighting == "joint_diag" else 7  # joint_diag needs one joint per action entry
    cfg = PhysVLAConfig.paper(mode=mode, layout=layout, weighting=weighting, el_mode=el, gripper_rule=grip,
                        chunk=chunk or "all", cap=1.0 if seed % 2 else 0.05)
    if beyond:  # the options beyond the paper (those of the default preset, and per-phase authority)
        cfg = cfg.replace(phase_caps=(0.5 * (seed % 5 > 1), 0.5, 1.0, 1.0), veto_height_m=0.06, veto_reach_m=0.10,
                          place_rule=("redirect", "release_veto")[seed % 2], place_tol_m=0.02 * (seed % 3 > 0),
                          phase_ref="object", lowpass="adaptive", release_carry=seed % 2 == 1,
                          lowpass_space=("action", "target")[seed % 3 > 0], lowpass_rough=("ema", "median")[seed % 2],
                          lowpass_lag=("trail", "compensate")[seed % 4 > 1],
                          release_assist_m=0.04 * (seed % 2), assist_still=("action", "hand")[seed % 4 > 1],
                          lift_assist_u=0.5 * (seed % 3 != 1), assist_steps=1 + seed % 3,
                          lift_assist_at_rest=seed % 4 == 0, rim_guide_m=0.047 * (seed % 5 > 1),
                          rim_guide_into_grasp=seed % 5 > 2,
                          chunk_phase_caps=(0.5 * (seed % 5 > 1), 0.05, 0.0, 1.0))
    b = 3
    c = Corrector(cfg, b)
    rng = np.random.default_rng(seed)
    shape = (b, lay.dim) if chunk is None else (b, 4, lay.dim)
    for step in range(3):  # memory (EMAs, last action) carries over
        state = make_state(b, n, eef=(0.01, 0.0, 1.0), obj=(0.0, 0.0, 0.9), lift=0.05 * (seed % 3 == 0), seed=seed)
        arr = getattr(state, field)
        flat_view = arr.reshape(b, -1)
        if whole_field:
            flat_view[:] = value
        else:
            flat_view[where % b, where % flat_view.shape[1]] = value
        a = rng.uniform(-scale, scale, shape)
        if bad_action is not None:
            a.reshape(b, -1)[0, where % a.reshape(b, -1).shape[1]] = bad_action
        out = c(a, state)  # never raises
        assert out.shape == a.shape
        assert np.isfinite(out).all()
        assert (out >= lay.low).all() and (out <= lay.high).all()
        first = a if chunk is None else a[:, 0]
        first_out = out if chunk is None else out[:, 0]
        bad_rows = ~np.isfinite(first).all(axis=1)
        for i in np.flatnonzero(bad_rows):  # the hold action: 0 on delta channels
            delta = ~lay.absolute_mask
            assert (first_out[i, delta] == 0.0).all()
        if bad_rows.any():
            assert c.guard_counts["held_nonfinite_action"] >= bad_rows.sum() * (step + 1)
            if mode != "baseline":
                assert sum(c.passthrough_counts.values()) >= bad_rows.sum() * (step + 1)


@pytest.mark.parametrize("mode", MODES)
def test_zero_dt_is_a_counted_pass_through_not_an_exception(mode):
    st = make_state(2, obj=(0.5, 0.0, 0.9))
    st.dt[1] = 0.0
    c = Corrector(PhysVLAConfig.paper(mode=mode), 2)
    a = np.full((2, 7), 0.3)
    with pytest.warns(RuntimeWarning) if mode == "phys_el" else _nothing():
        out = c(a, st)
    assert np.isfinite(out).all()
    if mode == "phys_el":
        assert c.passthrough_counts == {"invalid_dt": 1}
        np.testing.assert_array_equal(out[1], a[1])


def test_out_of_bounds_pass_through_is_clipped_and_counted():
    st = make_state(1)
    st.valid[0] = 0.0  # no usable state: pass-through
    c = Corrector(PhysVLAConfig.paper(mode="phys"), 1)
    with pytest.warns(RuntimeWarning, match="invalid_state"):
        out = c(np.array([[2.0, -3.0, 0.5, 0, 0, 0, 1.0]]), st)
    np.testing.assert_array_equal(out, [[1.0, -1.0, 0.5, 0, 0, 0, 1.0]])
    assert c.guard_counts == {"clipped_to_bounds": 1} and c.passthrough_counts == {"invalid_state": 1}


def test_hold_of_an_absolute_layout_repeats_the_last_action():
    from lerobot_physvla.core.config import ActionLayout

    lay = ActionLayout(dim=7, pos=(0, 1, 2), gripper=6, absolute=True)
    c = Corrector(PhysVLAConfig.paper(mode="baseline", layout=lay), 1)
    st = make_state(1)
    first = c(np.array([[0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]]), st)
    with pytest.warns(RuntimeWarning, match="non-finite"):
        out = c(np.full((1, 7), np.nan), st)
    np.testing.assert_array_equal(out, first)
    c.reset()
    with pytest.warns(RuntimeWarning) if False else _nothing():
        out = c(np.full((1, 7), np.nan), st)  # no history after a reset: 0, gripper open
    np.testing.assert_array_equal(out, [[0, 0, 0, 0, 0, 0, -1]])


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False
