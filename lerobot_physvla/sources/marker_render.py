"""A synthetic camera frame of ArUco markers at known poses: the ground truth the marker pose source
(sources/markers.py) is tested and its error model calibrated against, with no camera.

Each marker (cv2.aruco.generateImageMarker, with a white quiet zone `quiet` x its side wide around it) is
projected through the calibration's camera (cv2.projectPoints of its corners) and warped onto a
grey background (cv2.getPerspectiveTransform + warpPerspective), drawn `supersample` times larger and averaged
down (a camera's pixels integrate light over their area), blurred (the lens: a Gaussian of `blur_px`), with the
lens' distortion applied (the calibration's distortion coefficients), and Gaussian pixel noise of `noise` grey
levels. Markers are drawn in the order given (a later one covers an earlier one); `occluders` are grey
rectangles drawn over everything, in pixels.

    frame = render_markers(calibration, [MarkerPlacement(7, centre_m=(0.3, 0.0, 0.04))], seed=0)   # (H, W, 3) RGB
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import cv2
import numpy as np

from lerobot_physvla.sources.calibration import Calibration, CameraIntrinsics

MARKER_PX = 240  # the marker image's side before warping, pixels (a multiple of 6 and 8: 4x4 and 6x6 codes)


def _axis_rotation(axis: str, deg: float) -> np.ndarray:
    a = np.deg2rad(deg)
    c, s = np.cos(a), np.sin(a)
    i = "xyz".index(axis)
    j, k = (i + 1) % 3, (i + 2) % 3
    r = np.eye(3)
    r[j, j], r[j, k], r[k, j], r[k, k] = c, -s, s, c
    return r


@dataclass(frozen=True)
class MarkerPlacement:
    """One marker in the scene.

    Attributes:
        marker_id: its id in the dictionary.
        centre_m: its centre in the base frame, m.
        rotation: its axes in the base frame (3x3; columns x right, y up on the printed marker, z out of its face);
            default: lying flat, face up, its x along the base's x.
        size_m: the printed black square's side, m.
    """

    marker_id: int
    centre_m: tuple[float, float, float]
    rotation: np.ndarray = field(default_factory=lambda: np.diag([1.0, 1.0, 1.0]))
    size_m: float = 0.04

    @staticmethod
    def tilted(deg: float, axis: str = "x") -> np.ndarray:
        """A rotation: flat and face up, then turned by deg about the base's axis."""
        return _axis_rotation(axis, deg)


def marker_corners(p: MarkerPlacement, scale: float = 1.0) -> np.ndarray:
    """The marker's 4 corners in the base frame (4, 3), m, in ArUco's order: top-left, top-right, bottom-right,
    bottom-left of the printed marker; `scale` > 1 gives the quiet zone's corners."""
    h = 0.5 * p.size_m * scale
    local = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
    return np.asarray(p.centre_m, dtype=np.float64) + local @ np.asarray(p.rotation, dtype=np.float64).T


@functools.lru_cache(maxsize=32)
def _marker_image(dictionary: str, marker_id: int, quiet: float) -> np.ndarray:
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    m = cv2.aruco.generateImageMarker(d, marker_id, MARKER_PX)
    q = int(round(quiet * MARKER_PX))
    img = np.full((MARKER_PX + 2 * q, MARKER_PX + 2 * q), 255, np.uint8)
    img[q : q + MARKER_PX, q : q + MARKER_PX] = m
    return img


@functools.lru_cache(maxsize=8)
def _distortion_map(intr: CameraIntrinsics) -> tuple[np.ndarray, np.ndarray]:
    """For every pixel of the distorted frame, where it lies in the undistorted (pinhole) one."""
    w, h = intr.image_size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    pts = np.stack([u.ravel(), v.ravel()], 1)[:, None, :]
    k = intr.matrix
    und = cv2.undistortPoints(pts, k, intr.dist, P=k).reshape(h, w, 2).astype(np.float32)
    return und[..., 0], und[..., 1]


def render_markers(calibration: Calibration, markers: list[MarkerPlacement], dictionary: str = "DICT_4X4_50",
                   background: int = 128, noise: float = 2.0, blur_px: float = 0.7, supersample: int = 4,
                   quiet: float = 0.25, occluders: list[tuple[int, int, int, int, int]] = (),
                   seed: int | None = 0) -> np.ndarray:
    """An (H, W, 3) uint8 RGB frame of the markers as the calibration's camera sees them (module doc).

    Args:
        quiet: the white margin around each marker, a fraction of its side.
        noise: Gaussian pixel noise, grey levels (std).
        occluders: (x0, y0, x1, y1, grey) rectangles drawn last, pixels.
        seed: the noise's seed (None: fresh).
    """
    intr = calibration.intrinsics
    w, h = intr.image_size
    ss = int(supersample)
    k = intr.matrix
    big = np.full((h * ss, w * ss), background, np.uint8)
    for p in markers:
        img = _marker_image(dictionary, int(p.marker_id), quiet)
        corners_cam = calibration.to_camera(marker_corners(p, 1.0 + 2.0 * quiet))
        if (corners_cam[:, 2] <= 1e-3).any():
            continue  # behind the camera
        ip, _ = cv2.projectPoints(corners_cam, np.zeros(3), np.zeros(3), k, None)
        ip = (ip.reshape(4, 2) + 0.5) * ss - 0.5  # pixel centres of the large image
        n = img.shape[0]
        src = np.array([[-0.5, -0.5], [n - 0.5, -0.5], [n - 0.5, n - 0.5], [-0.5, n - 0.5]], np.float32)
        hm = cv2.getPerspectiveTransform(src, ip.astype(np.float32))
        warped = cv2.warpPerspective(img, hm, (w * ss, h * ss), flags=cv2.INTER_LINEAR, borderValue=0)
        mask = cv2.warpPerspective(np.full(img.shape, 255, np.uint8), hm, (w * ss, h * ss), flags=cv2.INTER_LINEAR,
                                   borderValue=0)
        a = mask.astype(np.float32) / 255.0
        big = (big * (1.0 - a) + warped * a).astype(np.uint8) if a.any() else big
    out = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32) if ss > 1 else big.astype(np.float32)
    if intr.dist is not None:
        mx, my = _distortion_map(intr)
        out = cv2.remap(out, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=float(background))
    if blur_px > 0:
        out = cv2.GaussianBlur(out, (0, 0), blur_px)
    for x0, y0, x1, y1, grey in occluders:
        out[max(0, y0) : max(0, y1), max(0, x0) : max(0, x1)] = grey
    if noise > 0:
        out += np.random.default_rng(seed).normal(0.0, noise, out.shape).astype(np.float32)
    g = np.clip(np.rint(out), 0, 255).astype(np.uint8)
    return np.repeat(g[:, :, None], 3, axis=2)
