"""Phase detection at and around every threshold, and each Branch A correction in action units."""

import numpy as np
import pytest

from lerobot_physvla.core.config import ActionLayout, PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.phase import Phase, detect_phase, xy_distance

from conftest import make_state

D, H = 0.06, 0.02  # delta_grasp_m, h_lift_m


def phase_of(d_obj, d_tgt, lift):
    return Phase(detect_phase(np.array([d_obj]), np.array([d_tgt]), np.array([lift]), D, H)[0])


@pytest.mark.parametrize(
    "d_obj,d_tgt,lift,expected",
    [
        (0.06, 1.0, 0.0, Phase.APPROACH),  # at the envelope: approach (>=)
        (0.0599, 1.0, 0.0, Phase.GRASP),
        (0.0599, 1.0, 0.02, Phase.GRASP),  # at h_lift: not lifted (>)
        (0.0599, 1.0, 0.0201, Phase.TRANSPORT),
        (0.0599, 0.06, 0.0201, Phase.TRANSPORT),  # at the target envelope: transport (>=)
        (0.0599, 0.0599, 0.0201, Phase.PLACE),
        (0.06, 0.0, 0.5, Phase.PLACE),  # lifted wins over approach: never veto a carried object
        (0.2, 1.0, 0.0201, Phase.TRANSPORT),
        (0.0, 0.0, -0.01, Phase.GRASP),  # object pushed below its resting height
    ],
)
def test_detect_phase_thresholds(d_obj, d_tgt, lift, expected):
    assert phase_of(d_obj, d_tgt, lift) == expected


def test_xy_distance_ignores_height():
    a = np.array([[0.0, 0.0, 5.0]])
    b = np.array([[0.03, 0.04, -2.0]])
    assert xy_distance(a, b)[0] == pytest.approx(0.05)


def run(phase, a_raw, eef=(0, 0, 1.0), obj=(0, 0, 0.9), d_tgt=1.0, cfg=None, corr=None):
    """Branch A's candidate a_phys alone: a `phys` corrector with the cap at 1 returns it as is.

    The state is built so that `phase` is detected: approach puts the object 0.5 m away, transport
    and place lift it 5 cm, and the target sits d_tgt metres from the end-effector along y."""
    cfg = (cfg or PhysVLAConfig.paper()).replace(mode="phys", cap=1.0)
    corr = corr or Corrector(cfg)
    eef = np.asarray(eef, float)
    obj = np.asarray(obj, float)
    lift = 0.0
    if phase == Phase.APPROACH:
        obj = eef + [0.5, 0.0, -0.1]
    elif phase in (Phase.TRANSPORT, Phase.PLACE):
        lift = 0.05
    st = make_state(eef=eef, obj=obj, target=eef + [0.0, d_tgt, -0.1], lift=lift)
    out = corr(np.array([a_raw], float), st)
    assert corr.last.phase[0] == phase
    return out[0], corr


RAW = [0.4, -0.2, 0.1, 0.3, 0.0, -0.3, 1.0]


def test_approach_vetoes_the_gripper_only():
    out, _ = run(Phase.APPROACH, RAW)
    np.testing.assert_allclose(out[:6], RAW[:6])
    assert out[6] == -1.0


def test_grasp_pulls_toward_the_waypoint_in_action_units():
    # p* - p_eef = (+0.01, -0.02, -0.05) m = (0.2, -0.4, -1.0) units at 0.05 m/unit
    out, _ = run(Phase.GRASP, RAW, eef=(0.0, 0.0, 1.0), obj=(0.01, -0.02, 0.95))
    expected_pos = 0.5 * np.array([0.2, -0.4, -1.0]) + 0.5 * np.array(RAW[:3])
    np.testing.assert_allclose(out[:3], expected_pos)
    np.testing.assert_allclose(out[3:], RAW[3:])


def test_grasp_metre_to_unit_conversion_follows_the_layout():
    lay = ActionLayout(dim=7, pos=(0, 1, 2), rot=(3, 4, 5), gripper=6, metres_per_unit=0.1)
    cfg = PhysVLAConfig.paper(layout=lay, grasp_offset_m=(0.0, 0.0, 0.02))
    out, _ = run(Phase.GRASP, [0] * 7, eef=(0, 0, 1.0), obj=(0.01, 0.0, 0.98), cfg=cfg)
    np.testing.assert_allclose(out[:3], 0.5 * np.array([0.1, 0.0, 0.0]))  # 1 cm = 0.1 units; z offset cancels


def test_grasp_waypoint_is_clipped_to_bounds():
    out, _ = run(Phase.GRASP, [1.0, 0, 0, 0, 0, 0, 0], eef=(0, 0, 1.0), obj=(0.059, 0, 1.0))  # 0.5*1.18 + 0.5*1
    assert out[0] == 1.0


def test_transport_lift_bias_and_ema():
    cfg = PhysVLAConfig.paper()
    out1, corr = run(Phase.TRANSPORT, RAW, cfg=cfg)
    lift_units = 0.02 / 0.05
    x1 = np.array(RAW[:3]) + [0, 0, lift_units]
    np.testing.assert_allclose(out1[:3], x1)  # first transport step: EMA starts at its input
    raw2 = [0.0, 0.0, 0.0, 0.3, 0.0, -0.3, 1.0]
    out2, corr = run(Phase.TRANSPORT, raw2, cfg=cfg, corr=corr)
    x2 = np.array([0, 0, lift_units])
    np.testing.assert_allclose(out2[:3], 0.92 * x1 + 0.08 * x2)
    np.testing.assert_allclose(out2[3:], raw2[3:])  # rotation and gripper unsmoothed
    # leaving transport and coming back restarts the EMA
    run(Phase.PLACE, RAW, d_tgt=0.03, cfg=cfg, corr=corr)
    out3, _ = run(Phase.TRANSPORT, raw2, cfg=cfg, corr=corr)
    np.testing.assert_allclose(out3[:3], x2)


# place needs d_tgt < delta_grasp (6 cm) < d_thresh (8 cm): inside the phase the ramp never reaches 1
@pytest.mark.parametrize("d_tgt,ramp", [(0.04, 0.5), (0.0, 0.0), (0.059, 0.059 / 0.08)])
def test_place_deceleration_ramp(d_tgt, ramp):
    out, _ = run(Phase.PLACE, RAW, d_tgt=d_tgt)
    np.testing.assert_allclose(out[:3], ramp * np.array(RAW[:3]))
    np.testing.assert_allclose(out[3:], RAW[3:])


def test_transport_memory_is_per_env_and_resettable():
    cfg = PhysVLAConfig.paper(mode="phys", cap=1.0)
    corr = Corrector(cfg, 2)
    st = make_state(batch_size=2, obj=(0, 0, 0.95), lift=0.05)
    corr(np.array([RAW, RAW]), st)
    corr.reset([1])
    out = corr(np.zeros((2, 7)), st)
    lift_units = 0.4
    np.testing.assert_allclose(out[0, :3], 0.92 * (np.array(RAW[:3]) + [0, 0, lift_units]) + 0.08 * np.array([0, 0, lift_units]))
    np.testing.assert_allclose(out[1, :3], [0, 0, lift_units])  # env 1 restarted from its input
