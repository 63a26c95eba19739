"""The corrector's distances from the scene's geometry (PhysVLAConfig.geometry = "scene", core/geometry.py): on
LIBERO-Spatial's bowl each lands near the constant it replaces, a small object gets its own, a state with no
measured scene keeps the constants, and geometry = "fixed" ignores a scene."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrections import params
from lerobot_physvla.core.corrections.base import P_SLOTS
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.geometry import measured, scene_distances
from lerobot_physvla.core.state import SCENE, PhysState, field_offsets

# measured on LIBERO-Spatial task 0 (sources/geometry.py; tests/sources/test_robosuite.py reads them live): the
# akita bowl's radius, half width and top, the plate's half width, the Panda's span and pads, m
BOWL = (0.05389, 0.05350, 0.05213, 0.06873, 0.08, 0.008, 0.008)
CAN = (0.0315, 0.031, 0.038, 0.0611, 0.08, 0.008, 0.008)  # LIBERO-Object's alphabet soup into the basket


def derived(scene, **cfg):
    """(delta_grasp, veto [height, reach], {slot: value}) of one env with this scene under the configuration."""
    c = PhysVLAConfig.from_dict(cfg)
    n = 7
    row = np.zeros(field_offsets(n)["scene"] + len(SCENE))
    row[field_offsets(n)["scene"]:] = scene
    p = params(c, c.action_layout)
    pe, veto = np.empty_like(p), np.empty(2)
    dg = scene_distances(row, field_offsets(n)["scene"], p, pe, np.array([c.veto_height_m, c.veto_reach_m]), veto)
    names = ("RIM_GUIDE_M", "RIM_SLACK_M", "RIM_REACH_M", "RIM_HEIGHT_M", "PLACE_TOL_M", "CARRY_REACH_M")
    return dg, veto, {k: pe[P_SLOTS[k]] for k in names}


def test_on_the_spatial_bowl_every_distance_lands_within_3_mm_of_the_constant_it_replaces():
    c = PhysVLAConfig()
    dg, veto, s = derived(BOWL)
    got = {"delta_grasp_m": dg, "veto_height_m": veto[0], "veto_reach_m": veto[1], "rim_guide_m": s["RIM_GUIDE_M"],
           "place_tol_m": s["PLACE_TOL_M"], "rim reach": s["RIM_REACH_M"], "rim height": s["RIM_HEIGHT_M"],
           "carry reach": s["CARRY_REACH_M"]}
    want = {"delta_grasp_m": c.delta_grasp_m, "veto_height_m": c.veto_height_m, "veto_reach_m": c.veto_reach_m,
            "rim_guide_m": c.rim_guide_m, "place_tol_m": c.place_tol_m, "rim reach": 0.14, "rim height": 0.15,
            "carry reach": 0.10}
    assert {k: round(abs(got[k] - want[k]), 4) for k in want} == pytest.approx({k: 0.0 for k in want}, abs=0.003)
    assert s["RIM_SLACK_M"] > 0  # the bowl is wider than the hand opens: the rim guide pulls


def test_a_can_the_hand_closes_around_gets_no_rim_pull_and_its_own_smaller_envelope():
    dg, veto, s = derived(CAN)
    assert s["RIM_SLACK_M"] < 0  # no pose error is below it: the rim guide never pulls
    assert dg == pytest.approx(0.0395) and veto[1] == pytest.approx(0.0315 + 0.04 + 0.008)
    assert s["PLACE_TOL_M"] == pytest.approx(0.0611 - 0.0315 + 0.008)  # the basket is wider than the bowl's plate


def test_the_pose_error_widens_the_derived_veto_as_the_fixed_one_and_what_is_off_stays_off():
    _, veto0, _ = derived(BOWL)
    _, veto1, _ = derived(BOWL, pose_error_m=0.01)
    np.testing.assert_allclose(veto1 - veto0, 0.01)
    dg, veto, s = derived(BOWL, **PhysVLAConfig.paper().to_dict() | {"geometry": "scene"})
    assert veto[0] == 0.0 and veto[1] == 0.0  # the paper's veto: the whole approach phase, no height test
    assert s["PLACE_TOL_M"] == 0.0  # the paper has no release tolerance


def test_a_scene_is_measured_only_where_every_value_is_finite_and_sizes_are_positive():
    row = np.zeros(20)
    row[10:17] = BOWL
    assert measured(row, 10) and not measured(row, -1)
    row[13] = np.nan
    assert not measured(row, 10)
    row[10:17] = BOWL
    row[10] = 0.0
    assert not measured(row, 10)


def _episode(cfg: PhysVLAConfig, scene, d=0.05, steps=30, seed=0):
    """A corrector over a hand hovering d (m) off an object's origin, 3 cm above it, closing from step 11;
    (actions out, phases)."""
    rng = np.random.default_rng(seed)
    c = Corrector(cfg, batch_size=1)
    outs, phases = [], []
    for t in range(steps):
        s = PhysState.empty(1, 7)
        s.valid[:], s.dt[:], s.episode_step[:] = 1.0, 0.05, t
        s.obj_pos[:], s.target_pos[:], s.obj_rest_z[:] = (0.0, 0.0, 0.9), (0.3, 0.0, 0.9), 0.9
        s.eef_pos[:] = (d + rng.normal(0, 0.002), 0.0, 0.93)
        s.gripper[:] = 0.08
        s.M[:], s.J_pos[:, :, :3] = np.eye(7), np.eye(3)
        s.scene[:] = scene
        a = np.array([[rng.normal(0, 0.2), rng.normal(0, 0.2), -0.1, 0, 0, 0, 1.0 if t > 10 else -1.0]])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            outs.append(c(a, s))
        phases.append(int(c.last.phase[0]))
    return np.concatenate(outs), phases


def test_a_state_without_a_scene_keeps_the_fixed_distances_bit_for_bit():
    for cfg in (PhysVLAConfig(geometry="fixed"), PhysVLAConfig.paper()):
        fixed, _ = _episode(cfg, np.nan)
        scene, _ = _episode(cfg.replace(geometry="scene"), np.nan)
        np.testing.assert_array_equal(scene, fixed)


def test_fixed_ignores_a_measured_scene_and_scene_follows_it():
    fixed_nan, ph_fixed = _episode(PhysVLAConfig(geometry="fixed"), np.nan)
    fixed_can, _ = _episode(PhysVLAConfig(geometry="fixed"), CAN)
    np.testing.assert_array_equal(fixed_can, fixed_nan)
    _, ph_scene = _episode(PhysVLAConfig(geometry="scene"), CAN)
    assert set(ph_fixed) == {1}  # 5 cm from the origin: inside the fixed 6 cm envelope, the grasp phase
    assert set(ph_scene) == {0}  # beyond the can's 3.95 cm: the approach phase
    # a close 9 cm from the can's origin: within the fixed veto reach (10 cm), let through; beyond the can's own
    # (its edge, 3.15 cm, plus an open hand's half span and pad, 4.8 cm), where no finger can touch it: vetoed
    fixed, _ = _episode(PhysVLAConfig(geometry="fixed"), CAN, d=0.09)
    scene, _ = _episode(PhysVLAConfig(geometry="scene"), CAN, d=0.09)
    assert (fixed[11:, 6] == 1.0).all() and (scene[11:, 6] == -1.0).all()


def test_geometry_is_a_checked_field_and_a_configuration_saved_before_it_reads_as_fixed():
    assert PhysVLAConfig().geometry == "scene" and PhysVLAConfig.paper().geometry == "fixed"
    with pytest.raises(ValueError, match="geometry"):
        PhysVLAConfig(geometry="bowl")
    d = PhysVLAConfig().to_dict()
    del d["geometry"], d["version"]  # a file saved before the field (and before versions)
    assert PhysVLAConfig.from_dict(d).geometry == "fixed"
