"""A camera's calibration for measuring poses in the robot's base frame: the camera's intrinsics and where
the camera is (the camera-to-base transform), one JSON file, checked when it is loaded.

    {
      "intrinsics": {"fx": 600.0, "fy": 600.0, "cx": 319.5, "cy": 239.5,      pixels
                     "distortion": [k1, k2, p1, p2, k3],                        OpenCV's model (4, 5, 8, 12 or 14)
                     "image_size": [640, 480]},                                 width, height, pixels
      "camera_to_base": [[r, r, r, x], [r, r, r, y], [r, r, r, z], [0, 0, 0, 1]],   p_base = T @ [p_cam, 1], m
      "fit_rms_m": 0.0015                                                       optional: the camera-to-base fit's
    }                                                                           RMS residual, m (fit_camera_to_base)

Pixel coordinates are OpenCV's: the centre of the top-left pixel is (0, 0). The camera frame is OpenCV's:
x right, y down, z along the optical axis. `load_calibration` raises one ValueError naming the field that is
missing, of the wrong shape, not finite, or (the rotation) not orthonormal, so a bad file stops a run before
it starts.

The camera-to-base transform can be measured with a marker held at a few known base-frame positions (on the
gripper, read by forward kinematics; lerobot-physvla-calibrate-camera, scripts/lerobot_physvla_calibrate_camera.py):
the marker's positions seen in the camera frame and the known ones are related by one rotation and one
translation, found by least squares (`fit_camera_to_base`, the Kabsch / Umeyama fit without scale).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DISTORTION_LENGTHS = (4, 5, 8, 12, 14)  # the lengths OpenCV's distortion model accepts
ORTHONORMAL_TOL = 1e-4  # |R^T R - I| allowed in a file (numbers written with ~6 digits)


@dataclass(frozen=True)
class CameraIntrinsics:
    """A pinhole camera with OpenCV's lens distortion.

    Attributes:
        fx, fy: focal lengths, pixels.
        cx, cy: principal point, pixels (OpenCV's convention: the top-left pixel's centre is (0, 0)).
        distortion: OpenCV's distortion coefficients (k1, k2, p1, p2[, k3[, ...]]), unitless; all 0: none.
        image_size: (width, height) of the frames the intrinsics were measured at, pixels.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    image_size: tuple[int, int] = (640, 480)

    def __post_init__(self):
        _check_intrinsics(self)

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 camera matrix K, pixels."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def dist(self) -> np.ndarray | None:
        """The distortion coefficients as OpenCV takes them, or None when there is no distortion."""
        return np.asarray(self.distortion, dtype=np.float64) if any(self.distortion) else None

    @property
    def focal_px(self) -> float:
        """The mean focal length, pixels."""
        return 0.5 * (self.fx + self.fy)

    def to_dict(self) -> dict:
        return {"fx": self.fx, "fy": self.fy, "cx": self.cx, "cy": self.cy, "distortion": list(self.distortion),
                "image_size": list(self.image_size)}

    @classmethod
    def from_dict(cls, d: dict, where: str = "intrinsics") -> CameraIntrinsics:
        """From the file's "intrinsics" table; ValueError naming the field that is missing or wrong."""
        if not isinstance(d, dict):
            raise ValueError(f"calibration: {where} must be a table with fx, fy, cx, cy, distortion, image_size; "
                             f"got {type(d).__name__}")
        missing = [k for k in ("fx", "fy", "cx", "cy", "image_size") if k not in d]
        if missing:
            raise ValueError(f"calibration: {where} lacks {', '.join(missing)} (fx, fy, cx, cy in pixels, image_size "
                             "[width, height]; distortion optional)")
        unknown = set(d) - {"fx", "fy", "cx", "cy", "distortion", "image_size"}
        if unknown:
            raise ValueError(f"calibration: {where} has unknown field(s) {sorted(unknown)}; it holds fx, fy, cx, cy, "
                             "distortion, image_size")
        vals = {k: _number(d[k], f"{where}.{k}") for k in ("fx", "fy", "cx", "cy")}
        dist = _array(d.get("distortion", [0.0] * 5), f"{where}.distortion")
        if dist.ndim != 1 or len(dist) not in DISTORTION_LENGTHS:
            lengths = ", ".join(map(str, DISTORTION_LENGTHS))
            raise ValueError(f"calibration: {where}.distortion must be a list of {lengths}"
                             f" numbers (OpenCV's k1, k2, p1, p2, k3, ...), got shape {dist.shape}")
        size = _array(d["image_size"], f"{where}.image_size")
        if size.shape != (2,) or (size != np.round(size)).any():
            raise ValueError(f"calibration: {where}.image_size must be [width, height] in whole pixels, got "
                             f"{d['image_size']!r}")
        return cls(**vals, distortion=tuple(float(v) for v in dist), image_size=(int(size[0]), int(size[1])))


@dataclass(frozen=True)
class Calibration:
    """A camera's intrinsics and its pose in the robot's base frame.

    Attributes:
        intrinsics: the camera (CameraIntrinsics).
        camera_to_base: 4x4 rigid transform, p_base = T @ [p_cam, 1] (rotation unitless, translation m).
        fit_rms_m: the RMS residual of the fit that measured camera_to_base, m (0: not measured; a measured
            pose's error bound adds twice it: sources/markers.py).
    """

    intrinsics: CameraIntrinsics
    camera_to_base: np.ndarray
    fit_rms_m: float = 0.0

    def __post_init__(self):
        t = _array(self.camera_to_base, "camera_to_base")
        _check_transform(t, "camera_to_base")
        object.__setattr__(self, "camera_to_base", t.copy())
        if not (math.isfinite(self.fit_rms_m) and self.fit_rms_m >= 0):
            raise ValueError(f"calibration: fit_rms_m must be a finite distance >= 0 (m), got {self.fit_rms_m!r}")

    @property
    def rotation(self) -> np.ndarray:
        """The camera frame's axes in the base frame (3x3)."""
        return self.camera_to_base[:3, :3]

    @property
    def translation(self) -> np.ndarray:
        """The camera's optical centre in the base frame, m."""
        return self.camera_to_base[:3, 3]

    def to_base(self, p_cam: np.ndarray) -> np.ndarray:
        """Points (..., 3) in the camera frame -> the base frame, m."""
        return np.asarray(p_cam, dtype=np.float64) @ self.rotation.T + self.translation

    def to_camera(self, p_base: np.ndarray) -> np.ndarray:
        """Points (..., 3) in the base frame -> the camera frame, m."""
        return (np.asarray(p_base, dtype=np.float64) - self.translation) @ self.rotation

    def to_dict(self) -> dict:
        return {"intrinsics": self.intrinsics.to_dict(), "camera_to_base": self.camera_to_base.tolist(),
                "fit_rms_m": self.fit_rms_m}

    @classmethod
    def from_dict(cls, d: dict) -> Calibration:
        """From the file's table (module doc); ValueError naming the field that is missing or wrong."""
        if not isinstance(d, dict):
            raise ValueError(f"calibration: the file must hold a table with intrinsics and camera_to_base, got "
                             f"{type(d).__name__}")
        missing = [k for k in ("intrinsics", "camera_to_base") if k not in d]
        if missing:
            raise ValueError(f"calibration: the file lacks {', '.join(missing)} (intrinsics: fx, fy, cx, cy, "
                             "distortion, image_size; camera_to_base: a 4x4 transform, m)")
        unknown = set(d) - {"intrinsics", "camera_to_base", "fit_rms_m"}
        if unknown:
            raise ValueError(f"calibration: unknown field(s) {sorted(unknown)}; the file holds intrinsics, "
                             "camera_to_base and fit_rms_m")
        rms = _number(d.get("fit_rms_m", 0.0), "fit_rms_m")
        return cls(CameraIntrinsics.from_dict(d["intrinsics"]), _array(d["camera_to_base"], "camera_to_base"), rms)

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(self.to_dict(), indent=2) + "\n")
        return path


def load_calibration(path: str | Path) -> Calibration:
    """The calibration in a JSON file (module doc). ValueError, naming the file and the field, when it is missing,
    not JSON, or holds a field that is missing, of the wrong shape, not finite, or a rotation that is not one."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"calibration: no file {path}; write one with lerobot-physvla-calibrate-camera (or by hand: "
                         "lerobot_physvla/sources/calibration.py shows its fields)")
    try:
        d = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"calibration: {path} is not JSON ({e})") from None
    try:
        return Calibration.from_dict(d)
    except ValueError as e:
        raise ValueError(f"{e} (in {path})") from None


def fit_camera_to_base(p_cam, p_base) -> tuple[np.ndarray, float]:
    """The rigid transform T (4x4) that best maps points seen in the camera frame onto the same points' known
    base-frame positions, in the least-squares sense (Kabsch / Umeyama without scale): argmin sum |R p_cam + t -
    p_base|^2 over rotations R. Returns (T, the RMS residual, m). ValueError for fewer than 3 points, non-finite
    points, or points on one line (the rotation about that line is then unknown)."""
    a, b = np.asarray(p_cam, dtype=np.float64), np.asarray(p_base, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3 or a.shape != b.shape:
        raise ValueError(f"calibration: give the same N points (N, 3) in the camera and the base frame, got "
                         f"{a.shape} and {b.shape}")
    if len(a) < 3:
        raise ValueError(f"calibration: {len(a)} point(s); the camera's pose needs at least 3 not on one line "
                         "(5 or more spread over the workspace are better)")
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise ValueError("calibration: a point is not finite; drop the frames where the marker was not seen")
    ca, cb = a.mean(0), b.mean(0)
    sa = np.linalg.svd(a - ca, compute_uv=False)
    if sa[1] < 1e-3 * max(sa[0], 1e-12) or sa[1] < 1e-6:
        raise ValueError("calibration: the points lie on one line; place the marker at positions that span a "
                         "plane or a volume")
    u, _, vt = np.linalg.svd((b - cb).T @ (a - ca))
    s = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])  # a rotation, not a reflection
    r = u @ s @ vt
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = r, cb - r @ ca
    resid = a @ r.T + t[:3, 3] - b
    return t, float(np.sqrt((resid ** 2).sum(1).mean()))


def _number(v, where: str) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"calibration: {where} must be a number, got {v!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"calibration: {where} is not finite ({v!r})")
    return x


def _array(v, where: str) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"calibration: {where} must hold numbers (a ragged or non-numeric list: {v!r})") from None
    if not np.isfinite(a).all():
        raise ValueError(f"calibration: {where} holds a value that is not finite")
    return a


def _finite_float(v) -> float | None:
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _check_intrinsics(c: CameraIntrinsics) -> None:
    for k in ("fx", "fy"):
        v = _finite_float(getattr(c, k))
        if v is None or v <= 0:
            raise ValueError(f"calibration: intrinsics.{k} must be a focal length > 0 (pixels), got {getattr(c, k)!r}")
    size = tuple(c.image_size) if isinstance(c.image_size, (tuple, list)) else ()
    if len(size) != 2 or not all(isinstance(v, (int, np.integer)) and v > 0 for v in size):
        raise ValueError(f"calibration: intrinsics.image_size must be [width, height] > 0 pixels, got {c.image_size}")
    w, h = size
    for k, n in (("cx", w), ("cy", h)):
        v = _finite_float(getattr(c, k))
        if v is None or not -0.5 <= v <= n - 0.5:
            raise ValueError(f"calibration: intrinsics.{k} must lie inside the image (-0.5 .. {n - 0.5} pixels), "
                             f"got {getattr(c, k)!r}")
    if len(c.distortion) not in DISTORTION_LENGTHS or not all(_finite_float(x) is not None for x in c.distortion):
        raise ValueError(f"calibration: intrinsics.distortion must be {', '.join(map(str, DISTORTION_LENGTHS))} finite "
                         f"numbers, got {c.distortion!r}")


def _check_transform(t: np.ndarray, where: str) -> None:
    if t.shape != (4, 4):
        raise ValueError(f"calibration: {where} must be a 4x4 transform (rows of 4 numbers), got shape {t.shape}")
    if not np.allclose(t[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9):
        raise ValueError(f"calibration: {where}'s last row must be [0, 0, 0, 1], got {t[3].tolist()}")
    r = t[:3, :3]
    err = float(np.abs(r.T @ r - np.eye(3)).max())
    if err > ORTHONORMAL_TOL or np.linalg.det(r) < 0:
        raise ValueError(f"calibration: {where}'s rotation (its upper-left 3x3) is not orthonormal with det +1 "
                         f"(|R^T R - I| = {err:.2g}, det {np.linalg.det(r):.3g}); write it with more digits, or "
                         "re-fit it with lerobot-physvla-calibrate-camera")
