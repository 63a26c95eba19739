"""`lerobot-physvla-calibrate-camera`: where the camera is, from a marker held at known base-frame positions.

    lerobot-physvla-calibrate-camera --intrinsics intrinsics.json --points points.json --marker-id 0 \\
        --marker-size-m 0.04 --out camera.json

intrinsics.json: the camera's intrinsics (fx, fy, cx, cy, distortion, image_size: pixels; from OpenCV's
calibrateCamera or the camera's data sheet), alone or as the "intrinsics" table of a calibration file.
points.json: [{"image": "frame_0.png", "base_xyz": [x, y, z]}, ...]: frames of one marker, each with the base-frame
position of the marker's centre (m) when it was taken (e.g. a marker on the gripper, its position from the arm's
forward kinematics); image paths relative to points.json. Five or more positions spread over the workspace, not on
one line, in the camera's view.

Each frame's marker is measured in the camera frame (sources/markers.py); the camera-to-base transform is the
rigid fit of those positions onto the known ones (sources/calibration.py fit_camera_to_base); the file written
holds the intrinsics, the transform and the fit's RMS residual (fit_rms_m: every position measured with the file
then has twice it added to its error bound). A frame whose marker is not found or is refused is left out and said;
fewer than 3 left is an error. Prints one line per frame (its residual, mm) and the fit's RMS.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

from lerobot_physvla.sources.calibration import Calibration, CameraIntrinsics, fit_camera_to_base
from lerobot_physvla.sources.markers import MarkerConfig, MarkerDetector


def calibrate_from_frames(intrinsics: CameraIntrinsics, frames: list[np.ndarray], base_xyz, marker_id: int,
                          marker_size_m: float, dictionary: str = "DICT_4X4_50") -> tuple[Calibration, list[dict]]:
    """(the calibration, one row per frame: {"frame", "used", "why", "residual_m"}) from frames (H, W, 3) uint8 RGB
    of the marker at the known base-frame positions base_xyz (N, 3), m. ValueError when fewer than 3 frames give
    the marker, or the positions lie on one line."""
    base = np.asarray(base_xyz, dtype=np.float64)
    if base.ndim != 2 or base.shape != (len(frames), 3):
        raise ValueError(f"calibration: give one base-frame position (x, y, z, m) per frame: {len(frames)} frames, "
                         f"positions of shape {base.shape}")
    cfg = MarkerConfig(marker_size_m, dictionary)
    detector = MarkerDetector(Calibration(intrinsics, np.eye(4)), cfg)
    rows, cam, known = [], [], []
    for i, frame in enumerate(frames):
        row = {"frame": i, "used": False, "why": "", "residual_m": float("nan")}
        rows.append(row)
        if not (isinstance(frame, np.ndarray) and frame.dtype == np.uint8 and frame.ndim == 3):
            row["why"] = "not an (H, W, 3) uint8 image"
            continue
        if frame.shape[1::-1] != tuple(intrinsics.image_size):
            row["why"] = f"{frame.shape[1]}x{frame.shape[0]} pixels, the intrinsics are for {intrinsics.image_size}"
            continue
        found = [d for d in detector.detect(cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY)) if d.marker_id == marker_id]
        if not found:
            row["why"] = f"marker {marker_id} not found"
            continue
        if found[0].reason:
            row["why"] = f"marker {marker_id} refused ({found[0].reason})"
            continue
        row["used"] = True
        cam.append(found[0].position_m)
        known.append(base[i])
    if len(cam) < 3:
        left = "; ".join(f"frame {r['frame']}: {r['why']}" for r in rows if not r["used"])
        raise ValueError(f"calibration: the marker was measured in {len(cam)} frame(s) of {len(frames)}; at least 3 "
                         f"are needed ({left})")
    t, rms = fit_camera_to_base(np.array(cam), np.array(known))
    cal = Calibration(intrinsics, t, rms)
    used = [r for r in rows if r["used"]]
    for r, pc, pb in zip(used, cam, known):
        r["residual_m"] = float(np.linalg.norm(cal.to_base(pc) - pb))
    return cal, rows


def _intrinsics(path: Path) -> CameraIntrinsics:
    try:
        d = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ValueError(f"calibration: cannot read the intrinsics {path} ({e})") from None
    return CameraIntrinsics.from_dict(d.get("intrinsics", d) if isinstance(d, dict) else d)


def _points(path: Path) -> tuple[list[np.ndarray | None], np.ndarray]:
    try:
        pts = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ValueError(f"calibration: cannot read the points {path} ({e})") from None
    if not isinstance(pts, list) or not all(isinstance(p, dict) and {"image", "base_xyz"} <= set(p) for p in pts):
        raise ValueError(f"calibration: {path} must hold a list of {{\"image\": <file>, \"base_xyz\": [x, y, z]}}")
    frames = []
    for p in pts:
        img = cv2.imread(str(path.parent / p["image"]), cv2.IMREAD_COLOR)
        frames.append(None if img is None else cv2.cvtColor(img, cv2.COLOR_BGR2RGB))
    return frames, np.array([p["base_xyz"] for p in pts], dtype=np.float64)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="lerobot-physvla-calibrate-camera", description=__doc__.splitlines()[0])
    ap.add_argument("--intrinsics", required=True, type=Path, help="JSON: fx, fy, cx, cy, distortion, image_size")
    ap.add_argument("--points", required=True, type=Path, help='JSON: [{"image": ..., "base_xyz": [x, y, z]}, ...]')
    ap.add_argument("--marker-id", required=True, type=int)
    ap.add_argument("--marker-size-m", required=True, type=float, help="the printed black square's side, m")
    ap.add_argument("--dictionary", default="DICT_4X4_50")
    ap.add_argument("--out", required=True, type=Path, help="the calibration file to write")
    a = ap.parse_args(argv)
    try:
        frames, base = _points(a.points)
        missing = [i for i, f in enumerate(frames) if f is None]
        frames = [np.zeros((1, 1, 3), np.uint8) if f is None else f for f in frames]
        cal, rows = calibrate_from_frames(_intrinsics(a.intrinsics), frames, base, a.marker_id, a.marker_size_m,
                                          a.dictionary)
    except ValueError as e:
        print(f"lerobot-physvla-calibrate-camera: error: {e}", file=sys.stderr)
        return 2
    for r in rows:
        why = "image not readable" if r["frame"] in missing else r["why"]
        said = f"residual {r['residual_m'] * 1000:.1f} mm" if r["used"] else f"left out ({why})"
        print(f"frame {r['frame']}: {said}")
    cal.save(a.out)
    print(f"wrote {a.out}: {sum(r['used'] for r in rows)} frames, fit RMS {cal.fit_rms_m * 1000:.1f} mm")
    return 0


if __name__ == "__main__":
    sys.exit(main())
