"""The close that meets (corrections/approach_veto.py, `close_meets`): the height veto leaves alone a close whose
fingers, closing at the speed the state's close_time gives them, reach the object's width while the descending
hand is at the veto height, and holds the closes that cannot meet it, on each layout's own gripper physics."""

import numpy as np
import pytest

from lerobot_physvla.core.config import PhysVLAConfig, preset
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.state import SCENE, field_offsets

from conftest import make_state

SO101 = {"dim": 4, "pos": [0, 1, 2], "gripper": 3, "metres_per_unit": 0.025, "gripper_open": 1.0,
         "gripper_closed": 0.0}
# (layout, control period s, close command, the source's measured close time s, hand span m, object width m,
# object top m, pad half height m): the numbers each source measures on its own model (tests/sources/test_close_time.py)
LAYOUTS = {
    "libero_object": ("libero_osc_pose", 0.05, 1.0, 0.182, 0.080, 0.062, 0.038, 0.008),
    "lift": ("libero_osc_pose", 0.05, 1.0, 0.258, 0.080, 0.048, 0.021, 0.008),
    "metaworld": ("metaworld", 0.0125, 1.0, 0.1025, 0.070, 0.040, 0.020, 0.045),
    "so101": (SO101, 0.1, 0.0, 0.284, 0.091, 0.040, 0.020, 0.007),
    "fetch": ("fetch_4d", 0.04, -1.0, 0.150, 0.100, 0.050, 0.025, 0.010),
}


def _state(spec, height, v_z, fingers=None, close_time=None):
    """Grasp phase: the hand `height` above the object's origin, moving vertically at v_z (m/s: J_pos[2] . qdot),
    the fingers `fingers` apart (default: wide open), the scene and close time of `spec`."""
    _, dt, _, t_close, span, width, top, pad_h = spec
    st = make_state(eef=(0.01, 0.0, 0.9 + height), obj=(0.0, 0.0, 0.9), dt=dt)
    st.J_pos[:], st.qdot[:] = 0.0, 0.0
    st.J_pos[0, 2, 0], st.qdot[0, 0] = 1.0, v_z
    st.gripper[:] = span if fingers is None else fingers
    st.scene[0] = (width / 2, width / 2, top, 0.05, span, 0.008, pad_h)  # SCENE's order
    st.close_time[:] = t_close if close_time is None else close_time
    return st


def _gripper(spec, st, meets=True):
    layout = spec[0]
    raw = np.zeros((1, 4 if layout != "libero_osc_pose" else 7))
    raw[0, -1] = spec[2]
    c = Corrector(PhysVLAConfig.from_dict({**preset("default").to_dict(), "layout": layout, "close_meets": meets}))
    return c(raw, st)[0, -1]


@pytest.mark.parametrize("name", list(LAYOUTS))
def test_a_close_that_meets_the_object_is_left_alone_and_one_that_cannot_is_held(name):
    spec = LAYOUTS[name]
    close, t_close, span, width, top, pad_h = spec[2], spec[3], spec[4], spec[5], spec[6], spec[7]
    veto_h = top + pad_h  # core/geometry.py: the veto height of a measured scene
    v = -0.8  # m/s, coming down
    reach = -v * t_close  # how far the hand comes down while the fingers close from wide open to the width
    meets = veto_h + 0.8 * reach  # the pads on the object by the time the fingers reach its width
    short = veto_h + 1.25 * reach  # the fingers reach its width with the pads still above it
    assert _gripper(spec, _state(spec, meets, v)) == close  # left alone
    assert _gripper(spec, _state(spec, meets, 0.0)) != close  # hovering there: cannot meet it, held
    assert _gripper(spec, _state(spec, meets, 0.4)) != close  # rising: held
    assert _gripper(spec, _state(spec, short, v)) != close  # too high for the fingers' speed: held
    assert _gripper(spec, _state(spec, meets, v), meets=False) != close  # the option off: the height veto
    assert _gripper(spec, _state(spec, meets, v, close_time=np.nan)) != close  # no close time: the height veto
    half = width + 0.5 * (span - width)  # half closed already: half the time left, half the descent
    assert _gripper(spec, _state(spec, veto_h + 0.4 * reach, v, fingers=half)) == close
    assert _gripper(spec, _state(spec, veto_h + 0.6 * reach, v, fingers=half)) != close
    assert _gripper(spec, _state(spec, veto_h - 0.005, 0.0)) == close  # below the veto height: as ever


def test_the_state_keeps_the_close_time_after_the_scene():
    f = field_offsets(7)
    assert f["close_time"] == f["scene"] + len(SCENE)  # core/branch_a.py reads it there


def test_judged_at_onset_a_close_begun_where_it_could_not_meet_stays_held():
    """close_meets_onset: the judgement is made at the step the policy begins its close and kept while it lasts. A
    close begun hovering (a premature close) stays held when the hand then comes down fast; one begun on the way down
    where it meets the object is left alone, also if the hand then stops above the veto height."""
    spec = LAYOUTS["metaworld"]
    close, veto_h, reach = spec[2], spec[6] + spec[7], 0.8 * spec[3]
    meets = veto_h + 0.8 * reach
    raw, opened = np.array([[0.0, 0.0, -1.0, close]]), np.array([[0.0, 0.0, -1.0, -close]])

    def corrector(**kw):
        return Corrector(PhysVLAConfig.from_dict({**preset("default").to_dict(), "layout": "metaworld", **kw}))

    onset, each = corrector(close_meets_onset=True), corrector(close_meets=True)
    for c in (onset, each):
        assert c(raw, _state(spec, meets, 0.0))[0, -1] != close  # begun hovering: held
    assert onset(raw, _state(spec, meets, -0.8))[0, -1] != close  # the same close, now coming down: still held
    assert each(raw, _state(spec, meets, -0.8))[0, -1] == close  # judged step by step: let go
    onset(opened, _state(spec, meets, -0.8))  # the policy opens: its next close is judged afresh
    assert onset(raw, _state(spec, meets, -0.8))[0, -1] == close  # begun coming down, meeting it: left alone
    assert onset(raw, _state(spec, meets, 0.0))[0, -1] == close  # and kept while it lasts
