"""A close held from its onset, held to the object's top (corrections/approach_veto.py, `veto_hold_to_top`): the
height veto keeps holding a close it held when the policy began it until the pads' centres are level with the
object's top, not their lower edges; a close begun lower, and a scene that is not measured, are judged as before."""

import numpy as np

from lerobot_physvla.core.config import PhysVLAConfig, preset
from lerobot_physvla.core.corrector import Corrector

from conftest import make_state

TOP, PAD_H = 0.0089, 0.008  # LIBERO's cream cheese box: its top over its origin; the Panda's pad half height (m)
VETO_H = TOP + PAD_H  # core/geometry.py: the veto height of a measured scene
CLOSE, OPEN = np.array([[0.0, 0.0, -0.1, 0.0, 0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, -0.1, 0.0, 0.0, 0.0, -1.0]])


def _state(height, scene=True):
    """Grasp phase over the box, the hand `height` above its origin and at rest (no close is timed)."""
    st = make_state(eef=(0.003, 0.0, 0.9 + height), obj=(0.0, 0.0, 0.9))
    st.J_pos[:], st.qdot[:] = 0.0, 0.0
    st.gripper[:] = 0.08
    st.scene[0] = (0.0406, 0.0213, TOP, 0.061, 0.08, 0.008, PAD_H) if scene else np.nan  # SCENE's order
    st.close_time[:] = 0.29 if scene else np.nan
    return st


def _corrector(on):
    return Corrector(PhysVLAConfig.from_dict({**preset("default").to_dict(), "veto_hold_to_top": on}))  # on by default


def _gripper(c, h, raw=CLOSE, scene=True):
    return c(raw, _state(h, scene))[0, -1]


def test_a_close_held_at_its_onset_stays_held_until_the_pads_centres_are_at_the_top():
    between = 0.5 * (TOP + VETO_H)  # the pads' lower edges under the top, their centres above it
    for on in (True, False):
        c = _corrector(on)
        assert _gripper(c, 0.022) == -1.0  # begun 2.2 cm up, above the veto height: held (both)
        assert _gripper(c, VETO_H + 0.001) == -1.0  # still above it: held (both)
        assert _gripper(c, between) == (-1.0 if on else 1.0)  # the option holds it on; without, let go
        assert _gripper(c, TOP - 0.001) == 1.0  # the pads' centres at the top: let go (both)


def test_a_close_begun_below_the_veto_height_is_left_alone():
    between = 0.5 * (TOP + VETO_H)
    c = _corrector(True)
    assert _gripper(c, between) == 1.0  # begun there: never held at its onset, so not held now
    c = _corrector(True)
    assert _gripper(c, 0.022) == -1.0
    _gripper(c, 0.022, raw=OPEN)  # the policy opens: its next close is judged afresh
    assert _gripper(c, between) == 1.0


def test_without_a_measured_scene_the_height_veto_is_as_configured():
    c = _corrector(True)
    assert _gripper(c, 0.07, scene=False) == -1.0  # above the fixed 6 cm: held
    assert _gripper(c, 0.05, scene=False) == 1.0  # below it: let go, the option has no top to hold to


def test_on_in_the_default_alone_and_off_in_a_configuration_saved_before():
    for name in ("default", "shift"):
        assert preset(name).veto_hold_to_top and preset(name).lift_assist_needs_close
    for name in ("smooth", "arm", "paper"):
        assert not (preset(name).veto_hold_to_top or preset(name).lift_assist_needs_close)
    old = PhysVLAConfig.from_dict({"version": 10, "cap": 0.1})
    assert not (old.veto_hold_to_top or old.lift_assist_needs_close)


def _hold(fingers, on, scene=True, steps=15):
    """A still hand 1.2 cm over the box with the close commanded (held open by the veto or not), its z commands."""
    c = Corrector(PhysVLAConfig.from_dict({**preset("default").to_dict(), "veto_hold_to_top": True,
                                           "lift_assist_needs_close": on}))
    st = _state(0.012, scene)
    st.gripper[:] = fingers
    return [c(np.array([[0.0, 0.0, -0.02, 0.0, 0.0, 0.0, 1.0]]), st)[0, 2] for _ in range(steps)]


def test_the_lift_assist_lifts_no_hand_held_wide_open_with_lift_assist_needs_close():
    """lift_assist_needs_close (corrections/lift_assist.py): fingers at the hand's span, held open while the policy
    commands its close, are not a hold; fingers stopped on the box are; without a measured scene, as before."""
    steps = preset("default").assist_steps
    wide, on_box = 0.0799, 0.0426  # m: the Panda's span less 0.1 mm; the box's narrower width
    assert _hold(wide, on=False)[steps - 1:] == [0.5] * (16 - steps)  # as shipped: a wide-open hand is lifted
    assert _hold(wide, on=True) == [-0.02] * 15  # held open: no hold, no lift
    assert _hold(on_box, on=True)[steps - 1:] == [0.5] * (16 - steps)  # fingers on the box: lifted
    assert _hold(wide, on=True, scene=False)[steps - 1:] == [0.5] * (16 - steps)  # no span known: as before
