"""The centre guide (core/corrections/centre_guide.py): an open hand settled beside an object the hand can close
across is pulled onto its origin in x, y, in the approach and grasp phases, until the policy closes; never on a
rim-grasped bowl, never without a measured scene, never past the pose error the object's room tolerates."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from lerobot_physvla.core.config import BEFORE_PULL, LIBERO_OSC_POSE, METAWORLD, PRESETS, ActionLayout, PhysVLAConfig
from lerobot_physvla.core.corrections import params
from lerobot_physvla.core.corrections.centre_guide import CENTRE_SLACK_M
from lerobot_physvla.core.corrections.rim_guide import RIM_SETTLE_STEPS
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.geometry import scene_distances
from lerobot_physvla.core.phase import Phase
from lerobot_physvla.core.state import SCENE, PhysState, field_offsets

# measured on the scenes (sources/geometry.py): radius, half width, top of the object, the target's half width, the
# Panda's span and pads, m
BOWL = (0.05389, 0.05350, 0.05213, 0.06873, 0.08, 0.008, 0.008)  # LIBERO-Spatial's akita bowl on its plate
CREAM_CHEESE = (0.041, 0.021, 0.009, 0.06, 0.08, 0.008, 0.008)  # LIBERO-Goal task 6's box into a bowl
# the pull on every layout (the shipped default keeps it off MetaWorld's: centre_guide_trailing = False); the guide
# alone: the shipped default without the approach pull and the carry (BEFORE_PULL; their own tests hold them)
ON = PRESETS["default"].replace(**BEFORE_PULL, centre_guide=True, centre_guide_trailing=True)
OFF = PRESETS["default"].replace(**BEFORE_PULL, centre_guide=False)


def slack(scene, cfg=ON) -> float:
    n = 7
    row = np.zeros(field_offsets(n)["scene"] + len(SCENE))
    row[field_offsets(n)["scene"]:] = scene
    p = params(cfg, cfg.action_layout)
    pe, veto = np.empty_like(p), np.empty(2)
    scene_distances(row, field_offsets(n)["scene"], p, pe, np.array([cfg.veto_height_m, cfg.veto_reach_m]), veto)
    return float(pe[CENTRE_SLACK_M])


def _run(cfg, eef_xy, scene=CREAM_CHEESE, steps=12, close_at=None, height=0.05, lift=0.0, heights=None):
    """A hand hovering at eef_xy (m from the object's origin), `height` above it (or heights[t] at step t, for
    len(heights) steps), commanding a small move toward its own aim (+x); (actions out, policy action, phases). On a
    4-channel layout the action is [x, y, z, gripper]."""
    steps = steps if heights is None else len(heights)
    c = Corrector(cfg, batch_size=1)
    outs, phases = [], []
    a = np.array([[0.2, 0.1, -0.3, 0, 0, 0, -1.0]])  # open (robosuite: - = open)
    if cfg.action_layout.dim == 4:
        a = a[:, [0, 1, 2, 6]]
    for t in range(steps):
        s = PhysState.empty(1, 7)
        s.valid[:], s.dt[:], s.episode_step[:] = 1.0, 0.05, t
        s.obj_pos[:], s.target_pos[:], s.obj_rest_z[:] = (0.0, 0.0, 0.9 + lift), (0.3, 0.0, 0.9), 0.9
        s.eef_pos[:] = (eef_xy[0], eef_xy[1], 0.9 + lift + (height if heights is None else heights[t]))
        s.gripper[:] = 0.08
        s.M[:], s.J_pos[:, :, :3] = np.eye(7), np.eye(3)
        s.scene[:] = scene
        act = a.copy()
        if close_at is not None and t >= close_at:
            act[0, -1] = 1.0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            outs.append(c(act, s)[0])
        phases.append(int(c.last.phase[0]))
    return np.array(outs), a[0], phases


def test_on_a_layout_whose_target_the_hand_trails_the_pull_commands_the_layouts_step_gain_of_the_gap():
    """MetaWorld's action moves a mocap target the hand trails: a full-gap command every step wound it up past the
    puck (docs/decisions/25-centre-guide.md). There the pull commands step_gain (0.25) of the gap a step, as
    metaworld's own scripted policies do; LIBERO's OSC keeps the full gap (the test above)."""
    assert METAWORLD.step_gain == 0.25 and LIBERO_OSC_POSE.step_gain == 1.0
    xy = (0.004, -0.002)  # m: 0.4 / 0.2 action units of a full-gap command, 0.1 / 0.05 with the gain
    on = ON.replace(layout="metaworld", weighting="task_space")
    outs, a, phases = _run(on, xy)
    assert set(phases) == {Phase.GRASP}
    np.testing.assert_allclose(outs[-1][:2], -0.25 * np.asarray(xy) / METAWORLD.metres_per_unit)
    np.testing.assert_array_equal(outs[-1][2:], a[2:])
    with pytest.raises(ValueError, match="step_gain"):
        ActionLayout(dim=4, pos=(0, 1, 2), gripper=3, step_gain=1.5)


def test_with_centre_guide_trailing_off_a_trailing_target_layout_gets_no_pull_and_an_osc_one_keeps_it():
    """centre_guide_trailing = False leaves a layout whose step_gain is below 1 (MetaWorld's mocap) to the policy:
    every action as with the guide off, the two corrections inactive; LIBERO's OSC (step_gain 1) is pulled as
    before."""
    from lerobot_physvla.core.corrections import active

    xy = (0.004, -0.002)
    mw = dict(layout="metaworld", weighting="task_space")
    no_trail = ON.replace(centre_guide_trailing=False, **mw)
    assert not {"centre_guide", "centre_guide_approach"} & active(no_trail)
    assert {"centre_guide", "centre_guide_approach"} <= active(ON.replace(**mw))
    got, _, _ = _run(no_trail, xy)
    want, _, _ = _run(OFF.replace(**mw), xy)
    np.testing.assert_array_equal(got, want)
    pulled, _, _ = _run(ON.replace(**mw), xy)
    assert not np.array_equal(pulled, want)  # the same hand is pulled where trailing targets are allowed
    osc, _, _ = _run(ON.replace(centre_guide_trailing=False), (0.02, -0.015))
    osc_on, _, _ = _run(ON, (0.02, -0.015))
    np.testing.assert_array_equal(osc, osc_on)
    assert not np.array_equal(osc, _run(OFF, (0.02, -0.015))[0])


@pytest.mark.parametrize("xy, phase", [((0.02, -0.015), Phase.GRASP), ((0.05, 0.0), Phase.APPROACH)])
def test_a_settled_open_hand_beside_a_box_it_closes_across_is_pulled_onto_its_origin_in_x_y_only(xy, phase):
    """The traced failure: the jittery expert aims its grasp beside a box (2.5 cm off: within delta_grasp, the grasp
    phase; 5 cm: beyond it, the approach phase) and closes there, a finger on top of it. From the first settled step
    on, x, y point at the origin (clipped to 1 action unit); z, the rotation and the gripper stay the policy's."""
    outs, a, phases = _run(ON, xy)
    assert set(phases) == {phase}
    np.testing.assert_array_equal(outs[:RIM_SETTLE_STEPS], np.tile(a, (RIM_SETTLE_STEPS, 1)))  # not yet settled
    mpu = LIBERO_OSC_POSE.metres_per_unit
    want = np.clip(-np.asarray(xy) / mpu, -1, 1)
    for o in outs[RIM_SETTLE_STEPS:]:
        np.testing.assert_allclose(o[:2], want)
        np.testing.assert_array_equal(o[2:], a[2:])
    # without it the policy's action goes through
    outs, a, _ = _run(OFF, xy)
    np.testing.assert_array_equal(outs, np.tile(a, (len(outs), 1)))


def test_at_the_centre_the_pull_is_zero_and_holds_the_hand_against_a_policy_aiming_beside_it():
    outs, a, _ = _run(ON, (0.0, 0.0))
    assert (outs[RIM_SETTLE_STEPS:, :2] == 0.0).all() and (a[:2] != 0.0).all()


def test_no_pull_once_the_policy_closes_the_hand_is_high_or_the_object_is_lifted():
    outs, a, _ = _run(ON, (0.02, 0.0), close_at=8)
    assert (outs[RIM_SETTLE_STEPS:8, 0] < 0).all()  # pulled while open
    np.testing.assert_array_equal(outs[8:, :6], np.tile(a[:6], (len(outs) - 8, 1)))  # the close: the policy's
    for kw in ({"height": 0.2}, {"lift": 0.05}):  # above top + 9.8 cm; carried (the transport phase)
        outs, a, _ = _run(ON, (0.02, 0.0), **kw)
        np.testing.assert_array_equal(outs[:, :6], np.tile(a[:6], (len(outs), 1)))


def test_once_a_pull_has_ended_the_hand_that_comes_back_is_left_to_the_policy_until_the_object_is_lifted():
    """centre_guide_once: MetaWorld's bin-picking policy climbs out of the zone whenever it is held away from its own
    aim beside the cube, and comes back down to it (docs/decisions/25-centre-guide.md). Without the flag the guide
    pulls it away again on every return; with it, one pull per approach."""
    heights = [0.05] * 12 + [0.3] * 3 + [0.05] * 12  # settle, pulled; out of the zone; back, settled again
    again, a, _ = _run(ON, (0.02, 0.0), heights=heights)
    once, _, _ = _run(ON.replace(centre_guide_once=True), (0.02, 0.0), heights=heights)
    np.testing.assert_array_equal(once[:15], again[:15])  # the first pull is the same
    assert (once[RIM_SETTLE_STEPS:12, 0] < 0).all()
    assert (again[15 + RIM_SETTLE_STEPS:, 0] < 0).all()  # pulled again
    np.testing.assert_array_equal(once[15:], np.tile(a, (12, 1)))  # left to the policy
    with pytest.raises(ValueError, match="centre_guide_once shapes the centre guide"):
        PhysVLAConfig(centre_guide=False, centre_guide_once=True)


def test_a_pulled_hand_that_holds_its_height_is_let_go_until_the_object_is_lifted():
    """centre_guide_yield_steps: MetaWorld's bin-picking policy hovered over the cube against the pull, open, for
    75 steps, neither closing nor climbing out (docs/decisions/25-centre-guide.md). With n > 0 the pull lets go
    once the pulled hand has gone down under 5 mm for n steps; a hand that keeps descending stays pulled."""
    n = 4
    hover = [0.05] * 20  # settles at step 5, pulled from then on, never lower
    held, a, _ = _run(ON, (0.02, 0.0), heights=hover)
    let, _, _ = _run(ON.replace(centre_guide_yield_steps=n), (0.02, 0.0), heights=hover)
    assert (held[RIM_SETTLE_STEPS:, 0] < 0).all()
    # pulled on the first step and n more (its height counted from the first), then the policy's to the end
    np.testing.assert_array_equal(let[:RIM_SETTLE_STEPS + n + 1], held[:RIM_SETTLE_STEPS + n + 1])
    np.testing.assert_array_equal(let[RIM_SETTLE_STEPS + n + 1:], np.tile(a, (20 - RIM_SETTLE_STEPS - n - 1, 1)))
    descending = [0.09 - 0.006 * t for t in range(14)]  # 6 mm a step: never holds its height
    went, _, _ = _run(ON.replace(centre_guide_yield_steps=n), (0.02, 0.0), heights=descending)
    assert (went[RIM_SETTLE_STEPS:, 0] < 0).all()
    with pytest.raises(ValueError, match="centre_guide_yield_steps is a count"):
        PhysVLAConfig(centre_guide=True, centre_guide_yield_steps=-1)


def test_it_never_pulls_on_a_rim_grasped_bowl_nor_without_a_measured_scene_nor_with_the_fixed_distances():
    """LIBERO-Spatial's objects are all bowls wider than the hand opens: the centre guide changes no action there."""
    assert slack(BOWL) < 0 and slack(CREAM_CHEESE) == pytest.approx(0.04 - 0.021)
    for scene, cfg in ((BOWL, ON), (np.nan, ON), (CREAM_CHEESE, ON.replace(geometry="fixed"))):
        pulled, _, _ = _run(cfg, (0.02, -0.015), scene=scene)
        left, _, _ = _run(OFF.replace(geometry=cfg.geometry), (0.02, -0.015), scene=scene)
        np.testing.assert_array_equal(pulled, left)


def test_with_straddle_a_hand_within_the_room_beside_the_object_is_left_to_the_policy():
    """centre_guide_straddle: a camera ACT grasps LIBERO-Object's cream cheese 1.0-1.4 cm off its origin (room beside
    it: 4 - 2.1 = 1.9 cm) and lifts it; centred, it closed higher and lost it (docs/decisions/25-centre-guide.md).
    Within the room the guide begins no pull; farther out it pulls onto the origin as without the flag, and a pull
    that began outside goes on inside."""
    straddle = ON.replace(centre_guide_straddle=True)
    room = slack(CREAM_CHEESE, straddle)
    inside = (0.9 * room, 0.0)
    left, a, _ = _run(straddle, inside)
    np.testing.assert_array_equal(left, np.tile(a, (len(left), 1)))
    assert (_run(ON, inside)[0][RIM_SETTLE_STEPS:, 0] < 0).all()  # without the flag: pulled
    outside = (0.02, -0.015)  # 2.5 cm: beyond the room
    np.testing.assert_array_equal(_run(straddle, outside)[0], _run(ON, outside)[0])
    # a pull that began outside goes on: the hand (which this test holds still) stays pulled once it is inside
    c, s = Corrector(straddle, batch_size=1), None
    xs = [0.025] * 8 + [0.5 * room] * 6
    out = []
    for t, x in enumerate(xs):
        s = PhysState.empty(1, 7)
        s.valid[:], s.dt[:], s.episode_step[:] = 1.0, 0.05, t
        s.obj_pos[:], s.target_pos[:], s.obj_rest_z[:] = (0.0, 0.0, 0.9), (0.3, 0.0, 0.9), 0.9
        s.eef_pos[:] = (x, 0.0, 0.95)
        s.gripper[:], s.M[:], s.J_pos[:, :, :3], s.scene[:] = 0.08, np.eye(7), np.eye(3), CREAM_CHEESE
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out.append(c(a[None].copy(), s)[0])
    mpu = LIBERO_OSC_POSE.metres_per_unit
    np.testing.assert_allclose(out[-1][0], -0.5 * room / mpu)
    # with the guide off the flag changes nothing
    np.testing.assert_array_equal(_run(OFF.replace(centre_guide_straddle=True), inside)[0], _run(OFF, inside)[0])


# LIBERO-Object's objects the Panda closes across (sources/geometry.py, measured on the scenes): a can the open hand
# clears in every orientation (r 3.5 cm under span / 2 = 4 cm) and the cream cheese box it does not (r 4.06 cm)
CAN = (0.0349, 0.0313, 0.0378, 0.06, 0.08, 0.008, 0.008)
BOX = (0.0406, 0.0213, 0.0089, 0.06, 0.08, 0.008, 0.008)


def test_with_clears_a_box_longer_than_the_open_hand_is_left_to_the_policy_and_a_can_is_pulled_as_before():
    """centre_guide_clears: the state carries no yaw, so an object whose half-diagonal exceeds half the hand's opening
    may be closed along its length; centred, the camera ACT's pads landed on the cream cheese box's corners and the
    close missed (docs/decisions/38-centre-guide-clears.md). Such an object gets no pull; one the open hand clears in
    every orientation is pulled exactly as without the flag; with the guide off the flag changes nothing."""
    clears = ON.replace(centre_guide_clears=True)
    assert slack(BOX, clears) < 0 and slack(BOX) == pytest.approx(0.04 - 0.0213)
    assert slack(CAN, clears) == slack(CAN) == pytest.approx(0.04 - 0.0313)
    xy = (0.015, -0.01)  # 1.8 cm off: within delta_grasp of both, beyond the can's room
    left, a, _ = _run(clears, xy, scene=BOX)
    np.testing.assert_array_equal(left, np.tile(a, (len(left), 1)))
    assert (_run(ON, xy, scene=BOX)[0][RIM_SETTLE_STEPS:, 0] < 0).all()  # without the flag: pulled onto the box
    pulled, _, _ = _run(clears, xy, scene=CAN)
    assert (pulled[RIM_SETTLE_STEPS:, 0] < 0).all()
    np.testing.assert_array_equal(pulled, _run(ON, xy, scene=CAN)[0])
    np.testing.assert_array_equal(_run(OFF.replace(centre_guide_clears=True), xy, scene=BOX)[0],
                                  _run(OFF, xy, scene=BOX)[0])
    assert PhysVLAConfig.from_dict({"version": 9, "cap": 0.05}).centre_guide_clears is False


def test_the_pose_error_it_tolerates_is_the_room_beside_the_object():
    room = 0.04 - 0.021
    pulled, a, _ = _run(ON.replace(pose_error_m=room * 0.9), (0.02, 0.0))
    left, _, _ = _run(ON.replace(pose_error_m=room * 1.1), (0.02, 0.0))
    assert pulled[-1, 0] < 0
    np.testing.assert_array_equal(left[:, 0], np.full(len(left), a[0]))


def test_the_configuration_refuses_what_it_cannot_do_and_old_configurations_load_without_it():
    with pytest.raises(ValueError, match="grasp phase's authority"):
        PhysVLAConfig(centre_guide=True, phase_caps=(1.0, 0.0, 0.0, 1.0), approach_pull_m=0.0, carry_far_m=0.0)
    with pytest.raises(ValueError, match="approach phase's authority, which is 0 in chunk_phase_caps"):
        PhysVLAConfig(centre_guide=True, rim_guide_m=0.0, chunk_phase_caps=(0.0, 1.0, 0.0, 1.0), approach_pull_m=0.0,
                      carry_far_m=0.0)
    with pytest.raises(ValueError, match="centre_guide commands a delta layout"):
        PhysVLAConfig(centre_guide=True, layout=ActionLayout(dim=4, pos=(0, 1, 2), gripper=3, absolute=True),
                      rim_guide_m=0.0, lift_assist_u=0.0, approach_pull_m=0.0, carry_far_m=0.0)
    assert not PhysVLAConfig.paper().centre_guide and not PRESETS["arm"].centre_guide
    c = PhysVLAConfig()  # the shipped default since eval/studies/centre_guide_step_gain.toml: on, off MetaWorld's mocap
    assert c.centre_guide and not c.centre_guide_trailing and not c.centre_guide_once
    d = ON.to_dict()
    del d["centre_guide"], d["centre_guide_trailing"], d["version"]  # a file saved before versions (version 0)
    assert PhysVLAConfig.from_dict(d) == ON.replace(centre_guide=False)  # saved before they existed: as it acted then
