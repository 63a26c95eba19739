"""The camera's calibration file (checked when loaded, each bad field named) and the camera-to-base fit (from
points, and from frames of a marker held at known positions, through lerobot-physvla-calibrate-camera)."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from lerobot_physvla.scripts.lerobot_physvla_calibrate_camera import calibrate_from_frames, main
from lerobot_physvla.sources.calibration import Calibration, CameraIntrinsics, fit_camera_to_base, load_calibration
from lerobot_physvla.sources.marker_render import MarkerPlacement, render_markers

INTR = CameraIntrinsics(600.0, 600.0, 319.5, 239.5, image_size=(640, 480))


def true_transform() -> np.ndarray:
    """A camera 0.6 m up and 0.1 m behind the base, looking down and forward (turned 35 deg from straight down)."""
    t = np.eye(4)
    t[:3, :3] = MarkerPlacement.tilted(-35, "x") @ np.diag([1.0, -1.0, -1.0])
    t[:3, :3] = MarkerPlacement.tilted(90, "z") @ t[:3, :3]
    t[:3, 3] = [-0.1, 0.0, 0.6]
    return t


def workspace_error_m(cal: Calibration) -> float:
    """The largest error, m, of the fitted camera-to-base transform over the workspace: a point seen in the true
    camera frame, mapped to the base frame by cal (what a measured position goes through)."""
    axes = np.linspace(0.15, 0.35, 3), np.linspace(-0.15, 0.15, 3), [0.0, 0.15]
    grid = np.stack(np.meshgrid(*axes), -1).reshape(-1, 3)
    true = Calibration(INTR, true_transform())
    return float(np.linalg.norm(cal.to_base(true.to_camera(grid)) - grid, axis=1).max())


def good() -> dict:
    return Calibration(INTR, true_transform(), 0.0015).to_dict()


def write(tmp_path, d) -> str:
    p = tmp_path / "camera.json"
    p.write_text(d if isinstance(d, str) else json.dumps(d))
    return p


def test_a_calibration_file_round_trips(tmp_path):
    cal = load_calibration(Calibration.from_dict(good()).save(tmp_path / "c.json"))
    np.testing.assert_allclose(cal.camera_to_base, true_transform())
    assert cal.intrinsics == INTR and cal.fit_rms_m == 0.0015
    p = np.array([0.3, 0.05, 0.02])
    np.testing.assert_allclose(cal.to_base(cal.to_camera(p)), p)


def _set(d: dict, path: str, value):
    keys = path.split(".")
    for k in keys[:-1]:
        d = d[k]
    if value is KeyError:
        del d[keys[-1]]
    else:
        d[keys[-1]] = value


@pytest.mark.parametrize("field, value, match", [
    ("intrinsics", KeyError, "lacks intrinsics"),
    ("camera_to_base", KeyError, "lacks camera_to_base"),
    ("intrinsics.fx", KeyError, "intrinsics lacks fx"),
    ("intrinsics.fx", -600.0, "intrinsics.fx must be a focal length > 0"),
    ("intrinsics.fy", "six hundred", "intrinsics.fy must be a number"),
    ("intrinsics.cx", float("nan"), "intrinsics.cx is not finite"),
    ("intrinsics.cy", 900.0, "intrinsics.cy must lie inside the image"),
    ("intrinsics.distortion", [0.1, 0.0, 0.0], "intrinsics.distortion must be a list of 4, 5, 8, 12, 14"),
    ("intrinsics.image_size", [640], r"intrinsics.image_size must be \[width, height\]"),
    ("intrinsics.focal", 600, "unknown field"),
    ("camera_to_base", np.eye(4)[:3].tolist(), r"camera_to_base must be a 4x4 transform .* shape \(3, 4\)"),
    ("camera_to_base", [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0]], "camera_to_base must hold numbers"),
    ("camera_to_base", (np.eye(4) * [[2], [1], [1], [1]]).tolist(), "rotation .* is not orthonormal"),
    ("camera_to_base", np.diag([1.0, 1.0, -1.0, 1.0]).tolist(), r"not orthonormal with det \+1"),
    ("camera_to_base", [[1, 0, 0, float("inf")], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], "not finite"),
    ("camera_to_base", [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]], "last row must be"),
    ("fit_rms_m", -1.0, "fit_rms_m must be a finite distance"),
    ("extrinsics", [], "unknown field"),
])
def test_a_malformed_file_is_one_value_error_naming_the_field(tmp_path, field, value, match):
    d = good()
    _set(d, field, value)
    with pytest.raises(ValueError, match=match) as e:
        load_calibration(write(tmp_path, json.dumps(d, allow_nan=True)))
    assert "camera.json" in str(e.value) and "\n" not in str(e.value)


def test_a_missing_or_unreadable_file_says_how_to_write_one(tmp_path):
    with pytest.raises(ValueError, match="no file .* lerobot-physvla-calibrate-camera"):
        load_calibration(tmp_path / "nope.json")
    with pytest.raises(ValueError, match="is not JSON"):
        load_calibration(write(tmp_path, "{intrinsics:"))


def test_the_rigid_fit_recovers_a_known_transform_from_noisy_points():
    rng = np.random.default_rng(0)
    t = true_transform()
    base = rng.uniform([0.1, -0.2, 0.0], [0.4, 0.2, 0.2], size=(12, 3))  # the workspace, m
    cam = (base - t[:3, 3]) @ t[:3, :3]
    cam_noisy = cam + rng.normal(0.0, 0.001, cam.shape)  # 1 mm per axis
    fit, rms = fit_camera_to_base(cam_noisy, base)
    assert np.linalg.norm(fit[:3, 3] - t[:3, 3]) < 0.003
    angle = np.degrees(np.arccos(np.clip((np.trace(fit[:3, :3].T @ t[:3, :3]) - 1) / 2, -1, 1)))
    assert angle < 0.5
    assert 0.001 < rms < 0.003  # about sqrt(3) mm x sqrt((N - 6) / N)
    exact, rms0 = fit_camera_to_base(cam, base)
    np.testing.assert_allclose(exact, t, atol=1e-9)
    assert rms0 < 1e-9
    Calibration(INTR, fit)  # a proper rotation: it passes the file's checks


def test_the_rigid_fit_refuses_too_few_points_and_points_on_a_line():
    with pytest.raises(ValueError, match="at least 3"):
        fit_camera_to_base(np.zeros((2, 3)), np.zeros((2, 3)))
    line = np.outer(np.linspace(0, 1, 5), [1.0, 2.0, 0.5])
    with pytest.raises(ValueError, match="one line"):
        fit_camera_to_base(line, line + 1)
    with pytest.raises(ValueError, match="not finite"):
        fit_camera_to_base(np.full((4, 3), np.nan), np.zeros((4, 3)))


def _calibration_frames(n=8, seed=0):
    """A 4 cm marker at n known base positions, seen by the camera at true_transform()."""
    rng = np.random.default_rng(seed)
    cal = Calibration(INTR, true_transform())
    base = rng.uniform([0.15, -0.15, 0.0], [0.35, 0.15, 0.15], size=(n, 3))
    facing = MarkerPlacement.tilted(90, "z") @ MarkerPlacement.tilted(-35, "x")  # roughly towards the camera
    frames = [render_markers(cal, [MarkerPlacement(0, tuple(p), facing)], seed=i) for i, p in enumerate(base)]
    return frames, base


def test_the_camera_pose_from_frames_of_a_marker_at_known_positions():
    frames, base = _calibration_frames()
    frames.append(render_markers(Calibration(INTR, true_transform()), []))  # a frame without the marker: left out
    base = np.vstack([base, [0.2, 0.0, 0.0]])
    cal, rows = calibrate_from_frames(INTR, frames, base, marker_id=0, marker_size_m=0.04)
    assert [r["used"] for r in rows] == [True] * 8 + [False] and rows[-1]["why"] == "marker 0 not found"
    assert workspace_error_m(cal) < 0.002  # measured ~1.1 mm; the camera itself is placed ~3 mm off (a lever arm)
    assert cal.fit_rms_m < 0.002 and max(r["residual_m"] for r in rows[:8]) < 0.003


def test_the_console_script_writes_the_file_from_images(tmp_path, capsys):
    frames, base = _calibration_frames(6, seed=1)
    points = []
    for i, f in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"f{i}.png"), cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
        points.append({"image": f"f{i}.png", "base_xyz": base[i].tolist()})
    (tmp_path / "points.json").write_text(json.dumps(points))
    (tmp_path / "intrinsics.json").write_text(json.dumps(INTR.to_dict()))
    out = tmp_path / "camera.json"
    rc = main(["--intrinsics", str(tmp_path / "intrinsics.json"), "--points", str(tmp_path / "points.json"),
               "--marker-id", "0", "--marker-size-m", "0.04", "--out", str(out)])
    assert rc == 0 and "fit RMS" in capsys.readouterr().out
    assert workspace_error_m(load_calibration(out)) < 0.002
    rc = main(["--intrinsics", str(tmp_path / "intrinsics.json"), "--points", str(tmp_path / "points.json"),
               "--marker-id", "5", "--marker-size-m", "0.04", "--out", str(out)])
    assert rc == 2 and "measured in 0 frame(s) of 6" in capsys.readouterr().err
