"""The robot step with pose_source=markers: the object's position from an ArUco marker in a (synthetic) camera frame
of the robot's observation, its age and the told error reach the corrector; every frame that gives no position is
a named reason, counted and warned once; a bad setting stops the rollout before the robot moves."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from lerobot.processor import RobotProcessorPipeline
from lerobot.processor.converters import robot_action_observation_to_transition, transition_to_robot_action

from lerobot_physvla.arms.model import ArmError, ArmModel
from lerobot_physvla.flags import split_argv
from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep
from lerobot_physvla.sources.calibration import Calibration, CameraIntrinsics
from lerobot_physvla.sources.marker_render import MarkerPlacement, render_markers

MOTORS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")
EEF_AT_ZERO = ArmModel("so101").eef_at(np.zeros(5))  # (0.391, 0, 0.227) m
CAM = Calibration(CameraIntrinsics(600.0, 600.0, 319.5, 239.5, image_size=(640, 480)),
                  np.array([[1.0, 0, 0, 0.25], [0, -1.0, 0, 0.0], [0, 0, -1.0, 0.6], [0, 0, 0, 1.0]]))  # 0.6 m up
FAR = (0.15, 0.2, 0.02)  # a 4 cm block's centre, 0.3 m from the gripper


def frame(block=FAR, seed=0):
    """The camera's view of the block with marker 3 on its top face (2 cm above its centre)."""
    top = (block[0], block[1], block[2] + 0.02)
    return render_markers(CAM, [MarkerPlacement(3, top)], seed=seed)


def obs(image, deg=(0, 0, 0, 0, 0), gripper=100.0):
    return {**{f"{m}.pos": float(v) for m, v in zip(MOTORS, deg)}, "gripper.pos": gripper, "front": image}


def act(gripper=0.0):
    return {**{f"{m}.pos": float(v) for m, v in zip(MOTORS, (2.0, -1.0, 1.5, 0.5, 0.0))}, "gripper.pos": gripper}


def pipeline(step):
    return RobotProcessorPipeline(steps=[step], to_transition=robot_action_observation_to_transition,
                                  to_output=transition_to_robot_action)


@pytest.fixture
def camera_file(tmp_path):
    return str(CAM.save(tmp_path / "camera.json"))


def step(camera_file, **kw):
    fields = dict(arm="so101", pose_source="markers", camera="front", object_marker=3, marker_size_m=0.04,
                  calibration=camera_file, object_marker_offset=[0.0, 0.0, -0.02], target_xyz=[0.3, -0.2, 0.0])
    return PhysVLARobotActionStep(**{**fields, **kw})


def test_the_marker_places_the_object_and_a_close_far_from_it_is_vetoed(camera_file):
    s = step(camera_file)
    out = pipeline(s)((act(gripper=0.0), obs(frame())))
    assert out["gripper.pos"] == 100.0  # held open: the object is 0.3 m away
    assert not s.pose_counts and not s.passed_through
    assert s.cfg.pose_error_m == 0.01  # the corrector is told marker_max_error_m
    r = s.markers.observe(frame(seed=1))["object"]
    np.testing.assert_allclose(r.position_m, FAR, atol=0.002)


def test_a_close_at_the_object_the_marker_shows_passes_untouched(camera_file):
    s = step(camera_file)
    under = tuple(EEF_AT_ZERO - np.array([0.0, 0.0, 0.02]))  # the block right under the gripper
    a = act(gripper=0.0)
    assert pipeline(s)((a, obs(frame(under)))) == a
    assert not s.pose_counts


def test_without_new_frames_the_position_is_held_and_ages_until_the_corrector_calls_it_stale(camera_file):
    s = step(camera_file)
    p = pipeline(s)
    p((act(), obs(frame())))
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        outs = [p((act(gripper=0.0), obs(None)))["gripper.pos"] for _ in range(7)]
    assert outs[:5] == [100.0] * 5  # ages 1 .. 5 <= pose_max_age_steps: the held position still vetoes
    assert outs[5:] == [0.0, 0.0]  # older: the corrector passes the policy's action through
    assert s.pose_counts == {"object stale_pose": 7} and s.passed_through["stale_pose"] == 2
    said = [str(x.message) for x in w if "stale_pose" in str(x.message)]
    assert len([m for m in said if "marker 3" in m]) == 1  # the marker's reason, said once
    assert "markers: no current position object stale_pose 7" in s.summary()


def test_a_marker_never_seen_is_missing_pose_and_the_action_passes(camera_file):
    s = step(camera_file)
    empty = render_markers(CAM, [])
    with pytest.warns(RuntimeWarning, match="missing_pose"):
        out = pipeline(s)((act(gripper=0.0), obs(empty)))
    assert out["gripper.pos"] == 0.0 and s.passed_through["missing_pose"] == 1
    assert s.pose_counts == {"object missing_pose": 1}


def test_a_bad_frame_never_raises(camera_file):
    s = step(camera_file)
    p = pipeline(s)
    p((act(), obs(frame())))
    with pytest.warns(RuntimeWarning, match="bad_frame"):
        out = p((act(gripper=0.0), obs(np.zeros((10, 10, 3), np.float64))))
    assert out["gripper.pos"] == 100.0 and s.pose_counts == {"object bad_frame": 1}  # the held position, age 1


def test_a_camera_missing_from_the_observation_stops_the_first_call(camera_file):
    o = obs(frame())
    del o["front"]
    with pytest.raises(ArmError, match="no camera 'front'"):
        pipeline(step(camera_file))((act(), o))


@pytest.mark.parametrize("kw, match", [
    ({"pose_source": None}, "need --physvla.pose_source=markers"),
    ({"pose_source": "lidar"}, "choose markers"),
    ({"calibration": None}, "needs --physvla.camera=.* --physvla.calibration="),
    ({"object_marker": None, "object_xyz": [0.1, 0.1, 0.0]}, "object_marker=<id> and/or"),
    ({"object_xyz": [0.1, 0.1, 0.0]}, "the object is given twice"),
    ({"pose_age_key": "age"}, "pose_age_key is a perception step's own"),
    ({"object_marker": 60}, "not in DICT_4X4_50"),
    ({"marker_dictionary": "DICT_2X2"}, "unknown dictionary"),
    ({"calibration": "/nonexistent/camera.json"}, "no file /nonexistent/camera.json"),
])
def test_a_bad_setting_is_one_arm_error_when_built(camera_file, kw, match):
    with pytest.raises(ArmError, match=match) as e:
        step(camera_file, **kw)
    assert "\n" not in str(e.value)


def test_a_malformed_calibration_file_names_its_field(camera_file, tmp_path):
    d = json.loads(open(camera_file).read())
    d["camera_to_base"][0][0] = 2.0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    with pytest.raises(ArmError, match="camera_to_base's rotation .* not orthonormal"):
        step(str(bad))


def test_the_flags_and_the_saved_configuration(camera_file):
    _, over, rest = split_argv(["--policy.postprocess=physvla", "--physvla.pose_source=markers",
                                "--physvla.camera=front", "--physvla.object_marker=3", "--physvla.marker_size_m=0.04",
                                f"--physvla.calibration={camera_file}", "--physvla.object_marker_offset=[0,0,-0.02]",
                                "--physvla.target_xyz=[0.3,-0.2,0]", "--fps=30"], robot=True)
    assert over["object_marker"] == 3 and over["marker_size_m"] == 0.04
    assert over["object_marker_offset"] == (0, 0, -0.02)
    assert rest == ["--fps=30"]
    s = step(camera_file)
    again = PhysVLARobotActionStep(**s.get_config())
    assert again.get_config() == s.get_config() and again.get_config()["object_marker"] == 3
    plain = PhysVLARobotActionStep(arm="so101", object_xyz=[0.1, 0.3, 0.0], target_xyz=[0.3, -0.2, 0.0])
    assert "pose_source" not in plain.get_config()  # a file saved without markers is written as before


@pytest.fixture
def restore_rollout():
    from lerobot.scripts import lerobot_rollout

    original = lerobot_rollout.build_rollout_context
    yield lerobot_rollout
    lerobot_rollout.build_rollout_context = original


def test_lerobot_rollout_s_flags_build_the_marker_step_and_a_bad_file_stops_it(camera_file, tmp_path, capsys,
                                                                              restore_rollout):
    from lerobot_physvla.scripts.lerobot_physvla_rollout import activate_rollout

    flags = ["--policy.postprocess=physvla", "--physvla.arm=so101", "--physvla.pose_source=markers",
             "--physvla.camera=front", "--physvla.object_marker=3", "--physvla.marker_size_m=0.04",
             "--physvla.object_marker_offset=[0,0,-0.02]", "--physvla.target_xyz=[0.3,-0.2,0]"]
    argv = ["lerobot-rollout", "--robot.type=so101_follower", "--fps=30", *flags,
            f"--physvla.calibration={camera_file}"]
    activate_rollout(argv)
    assert argv == ["lerobot-rollout", "--robot.type=so101_follower", "--fps=30"]
    s = restore_rollout.build_rollout_context.step
    assert s.markers.markers == {"object": (3,)} and s.object_marker_offset == [0.0, 0.0, -0.02]
    capsys.readouterr()
    (tmp_path / "bad.json").write_text(json.dumps({"intrinsics": {"fx": 600}, "camera_to_base": np.eye(4).tolist()}))
    with pytest.raises(SystemExit) as e:
        activate_rollout(["lerobot-rollout", *flags, f"--physvla.calibration={tmp_path / 'bad.json'}"])
    err = capsys.readouterr().err.strip()
    assert e.value.code == 2 and "intrinsics lacks fy, cx, cy, image_size" in err and "\n" not in err


def test_the_simulated_so101_s_rendered_camera_goes_through_the_step(tmp_path):
    """physvla_sim_so101 with marker_camera: the step reads the rendered frame (calibrated from the rig's own frames
    by the calibration helper), finds the block 0.3 m from the gripper and the goal, and vetoes the close."""
    from lerobot_physvla.robots.physvla_sim_so101 import SimSO101, SimSO101Config
    from lerobot_physvla.scripts.lerobot_physvla_calibrate_camera import main as calibrate
    from lerobot_physvla.sim.marker_scene import calibration_frames

    frames = calibration_frames(SimSO101.scene_xml(), tmp_path / "calib")
    calibrate(["--intrinsics", str(frames / "intrinsics.json"), "--points", str(frames / "points.json"),
               "--marker-id", "3", "--marker-size-m", "0.03", "--out", str(tmp_path / "camera.json")])
    block, goal = [0.2, 0.12, 0.02], [0.22, -0.12, 0.02]
    robot = SimSO101(SimSO101Config(fps=10, block_xyz=block, marker_camera=True, goal_xyz=goal))
    robot.connect()
    try:
        s = PhysVLARobotActionStep(arm="so101", pose_source="markers", camera="marker_cam", object_marker=3,
                                   target_marker=7, marker_size_m=0.03, calibration=str(tmp_path / "camera.json"),
                                   object_marker_offset=[0.0, 0.0, -0.021], target_marker_offset=[-0.05, 0.0, 0.019])
        o = robot.get_observation()
        assert o["marker_cam"].shape == (480, 640, 3)
        out = pipeline(s)((act(gripper=0.0), o))
        readings = s.markers.observe(robot.get_observation())
    finally:
        robot.disconnect()
    assert out["gripper.pos"] == 100.0 and not s.pose_counts  # both positions read; the far close held open
    np.testing.assert_allclose(readings["object"].position_m, block, atol=0.002)
    np.testing.assert_allclose(readings["target"].position_m, goal, atol=0.002)
    with pytest.raises(ValueError, match="goal_xyz"):
        SimSO101(SimSO101Config(marker_camera=True))
