"""The scene's geometry read from a MuJoCo model: boxes of bodies (their subtree's collision geoms) and sites, in
world axes about the origin, and a gripper's span and pads."""

import mujoco
import numpy as np
import pytest

from lerobot_physvla.sources.geometry import body_extent, hand, site_extent

XML = """
<mujoco>
  <worldbody>
    <body name="box" pos="0.3 0.1 0.02" euler="0 0 90">
      <geom type="box" size="0.04 0.02 0.02" pos="0 0 0.01"/>
      <geom type="sphere" size="0.5" contype="0" conaffinity="0"/>
      <body name="cap" pos="0 0 0.04"><geom type="cylinder" size="0.01 0.01"/></body>
      <site name="region" type="box" size="0.06 0.03 0.01" pos="0 0 0.2"/>
    </body>
    <body name="ghost" pos="1 1 1"><geom type="sphere" size="0.01" contype="0" conaffinity="0"/></body>
    <body name="hand" pos="0 0 1">
      <body name="left"><joint name="l" type="slide" axis="0 1 0" range="0 0.04"/>
        <geom name="lpad" type="box" size="0.008 0.004 0.009"/></body>
      <body name="right"><joint name="r" type="slide" axis="0 1 0" range="-0.04 0"/>
        <geom name="rpad" type="box" size="0.008 0.004 0.009"/></body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def scene():
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return m, d


def test_a_body_is_measured_by_its_collision_geoms_and_its_subtree_in_world_axes(scene):
    m, d = scene
    e = body_extent(m, d, m.body("box").id)
    # turned 90 degrees about z: the 8 cm side lies along y; the visual-only sphere is left out; the cap adds height
    np.testing.assert_allclose(e.lo, (-0.02, -0.04, -0.01), atol=1e-9)
    np.testing.assert_allclose(e.hi, (0.02, 0.04, 0.05), atol=1e-9)
    assert e.radius_m == pytest.approx(0.04) and e.half_width_m == pytest.approx(0.02)
    assert e.top_m == pytest.approx(0.05) and e.bottom_m == pytest.approx(-0.01)


def test_a_body_without_collision_geoms_is_a_clear_error(scene):
    m, d = scene
    with pytest.raises(ValueError, match="no collision geom"):
        body_extent(m, d, m.body("ghost").id)


def test_a_region_site_is_its_box_in_world_axes(scene):
    m, d = scene
    e = site_extent(m, d, m.site("region").id)
    np.testing.assert_allclose(e.hi, (0.03, 0.06, 0.01), atol=1e-9)  # turned with its body
    assert e.half_width_m == pytest.approx(0.03)


def test_a_hand_is_its_fingers_ranges_and_its_pads(scene):
    m, _ = scene
    h = hand(m, [m.joint("l").id, m.joint("r").id], [m.geom("lpad").id, m.geom("rpad").id])
    assert h.span_m == pytest.approx(0.08) and h.pad_half_width_m == pytest.approx(0.008)
    assert h.pad_half_height_m == pytest.approx(0.009)
    assert hand(m, [m.joint("l").id]).pad_half_width_m == 0.0
    with pytest.raises(ValueError, match="finger joints"):
        hand(m, [])
