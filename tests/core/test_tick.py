"""The fused tick (one compiled call) against the same stages called one by one."""

import numpy as np
import pytest

from lerobot_physvla.core.config import PRESETS, PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector

from conftest import make_state

CONFIGS = [
    PhysVLAConfig.paper(mode="baseline"),
    PhysVLAConfig.paper(mode="temporal"),
    PhysVLAConfig.paper(mode="phys", cap=0.3),
    PhysVLAConfig.paper(mode="phys_el"),
    PhysVLAConfig.paper(mode="phys_el", weighting="task_space", el_mode="gated", cap=1.0),
    PhysVLAConfig.paper(mode="phys_el", chunk="first"),
    PRESETS["default"],
    PRESETS["default"].replace(veto_reopen=True),  # default v3: the veto may open a closed gripper
    PRESETS["default"].replace(release_carry=False),  # default v4: the release veto in the place phase only
    PRESETS["default"].replace(place_rule="redirect", place_tol_m=0.015),
    PRESETS["default"].replace(mode="phys_el", phase_caps=(0.2, 0.5, 1.0, 1.0), lowpass="adaptive",
                               lowpass_phases="grasp,place"),
    PRESETS["default"].replace(lowpass="adaptive", lowpass_space="target", lowpass_rough="median",
                               lowpass_lag="compensate"),
]


def _episode(seed: int, b: int = 4, steps: int = 40):
    """States that walk every env through approach, grasp, transport and place, with a few
    invalid rows, non-finite actions and out-of-bounds actions mixed in."""
    rng = np.random.default_rng(seed)
    out = []
    for t in range(steps):
        st = make_state(batch_size=b, seed=t, eef=(0.3 * t / steps, 0.0, 1.0 - 0.1 * (t > 15)),
                        obj=(0.02, 0.01, 0.9 + 0.08 * (t > 20)), lift=0.08 * (t > 20))
        st.episode_step[:] = t
        a = rng.uniform(-1.3, 1.3, size=(b, 3, 7))
        if t % 7 == 3:
            st.valid[t % b] = 0.0
            a[(t + 1) % b, 0, 2] = np.nan
        out.append((st, a))
    return out


@pytest.mark.parametrize("cfg", CONFIGS, ids=lambda c: f"{c.mode}-{c.weighting}-{c.chunk}-{c.lowpass}-{c.place_rule}")
@pytest.mark.parametrize("chunked", [False, True])
def test_fused_tick_equals_the_staged_kernels(cfg, chunked):
    fused, staged = Corrector(cfg, 4), Corrector(cfg, 4, profile=True)
    for st, a in _episode(1):
        a = a if chunked else a[:, 0]
        out_f, out_s = fused(a, st), staged(a, st)
        np.testing.assert_array_equal(out_f, out_s)
        df, ds = fused.last, staged.last
        for name in ("phase", "d_obj_xy", "d_tgt_xy", "lift", "r_el", "r_energy", "weights", "deviation", "status"):
            np.testing.assert_array_equal(getattr(df, name), getattr(ds, name), err_msg=name)
        assert np.isnan(df.t_branch_a_s) and ds.t_branch_a_s > 0
    assert fused.passthrough_counts == staged.passthrough_counts
    assert bool(fused.passthrough_counts) == (cfg.mode != "baseline")  # baseline passes everything as is
    assert fused.guard_counts == staged.guard_counts and fused.guard_counts["held_nonfinite_action"] > 0


def test_last_is_a_snapshot_of_its_call():
    c = Corrector(PhysVLAConfig.paper(mode="phys_el"), 1)
    c(np.zeros((1, 7)), make_state(eef=(0, 0, 1.0), obj=(0.3, 0, 0.9)))
    first = c.last
    phase = first.phase.copy()
    c(np.zeros((1, 7)), make_state(eef=(0, 0, 1.0), obj=(0.01, 0, 0.95)))
    np.testing.assert_array_equal(first.phase, phase)  # the buffers moved on, the snapshot did not
    assert c.last is not first and c.last.phase[0] != phase[0]
