"""Object and target positions from a camera: ArUco fiducial markers, their poses in the robot's base frame,
each with an error bound, and a named reason for every frame that gives none.

Per frame (H, W, 3) uint8 RGB, as lerobot's cameras give it:

1. detect the markers (cv2.aruco, dictionary DICT_4X4_50 unless configured);
2. refine each marker's 4 corners: the edge of its black border is found to a fraction of a pixel at ~one point
   per pixel along each side (the grey-level gradient's centroid across the edge), the points are undistorted
   with the calibration's lens model, a line is fitted to each side and the corners are the lines'
   intersections. (cv2's own SUBPIX refinement pulls an L-shaped corner ~0.2 px into the square, which makes a
   4 cm marker read ~0.4 % too small: 2-4 mm too far at 0.5 m, 10 mm at 0.8 m with a 600 px focal length.
   On 1500 synthetic frames, eval/bench/markers.py, the median error is 2.4 mm at 0.25-0.5 m and 7.7 mm at
   0.5-0.75 m with SUBPIX corners, 0.2 and 0.6 mm with the line fit);
3. the marker's pose in the camera frame: cv2.solvePnP, SOLVEPNP_IPPE_SQUARE on the 4 corners and the marker's
   printed side (m); its reprojection error (RMS over the corners, px), its side in pixels (mean of the 4
   sides), its viewing angle (between the marker's normal and the line of sight, deg);
4. the marker's centre in the base frame through the calibration's camera-to-base transform, plus a fixed
   base-frame offset per marker (e.g. [0, 0, -0.02] from a marker on top of a 4 cm block to the block's centre).

The error bound of a position (m), per frame:

    sigma = max(corner_noise_px, reprojection_px)                      the corners' noise, px
    bound = ERROR_K * sigma * Z * (1 / side_px + 1 / f)                 depth Z = f s / side_px moves by
            + scale_error * Z                                            Z sigma / side_px (= Z^2 sigma / (f s)
            + 2 * fit_rms_m                                              face-on); across the line of sight by
                                                                         Z sigma / f
Z the marker's distance (m), f the focal length (px), s its side (m); scale_error the relative uncertainty
of the focal length and of the printed side (a 1 % error in either is a 1 % error in Z; 0 by default: the
calibration is taken as exact), fit_rms_m the camera-to-base fit's residual (the calibration file's). ERROR_K
is calibrated against synthetic truth (eval/bench/markers.py: 1500 rendered frames, sources/marker_render.py,
3-6 cm markers 0.25-1.0 m away, tilted 0-70 deg, half through a distorting lens, blurred, noisy): 1.5 x the
99.5th percentile of |error| / (sigma Z (1 / side_px + 1 / f)), which covers 99.9 % of those frames' errors;
tests/sources/test_markers.py checks it covers the error on other draws.
It describes a static marker in a sharp frame: motion blur, rolling shutter and a wrong calibration are not in
it (the calibration's fit residual measures the last on the real camera).

Named reasons a frame gives no new position for a wanted marker (`REASONS`; the position held from an earlier
frame stays, and its age in control steps grows):

    missing_pose      no marker in view (or none yet seen)
    wrong_id          markers in view, none with the wanted id
    marker_lost       not found where it was seen in the last track_steps frames: covered, turned edge-on or
                      blurred beyond detection
    marker_occluded   found, but its corners are not a square's (reprojection error > max_reprojection_px):
                      partly covered
    marker_too_small  found, but its side is under min_side_px
    marker_edge_on    found, but seen at more than max_view_angle_deg from face-on
    pose_error_high   found, but its error bound exceeds max_error_m (the error the corrector is told)
    stale_pose        no new frame (None, or the same frame again: a stalled camera), or a frame older than
                      max_age_steps: the position is the one held, this old
    bad_frame         not an (H, W, 3) uint8 image of the calibration's size

Nothing here raises at run time: `MarkerSource.observe` always returns one `MarkerReading` per wanted marker.
A bad configuration (an unknown dictionary, a marker id outside it, a non-positive size) raises a ValueError
when the source is built.
"""

from __future__ import annotations

import hashlib
import math
import time
from collections import Counter
from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit

from lerobot_physvla.sources.calibration import Calibration

# The error model's constant (module doc), calibrated by eval/bench/markers.py on synthetic frames.
ERROR_K = 4.75
CORNER_NOISE_PX = 0.1  # corner noise floor, px (synthetic frames reproject to ~0.01-0.1 px; a real camera: more)
REASONS = ("missing_pose", "wrong_id", "marker_lost", "marker_occluded", "marker_too_small", "marker_edge_on",
           "pose_error_high", "stale_pose", "bad_frame")
EDGE_SPAN = (0.12, 0.88)  # the stretch of each side whose edge points are fitted (the corners' neighbourhoods left out)
EDGE_SAMPLES = 21  # grey levels read across a side's edge at each point along it (over 0.9 cell, at most 2.5 px, either way)


@dataclass(frozen=True)
class MarkerConfig:
    """How markers are read, and which frames are refused.

    Attributes:
        marker_size_m: the printed black square's side, m (measure it: its error is the depth's, in proportion).
        dictionary: a cv2.aruco predefined dictionary's name (DICT_4X4_50, DICT_5X5_100, DICT_APRILTAG_36h11, ...).
        min_side_px: a marker whose side is smaller (px) is refused (marker_too_small).
        max_reprojection_px: a marker whose corners' reprojection error is larger (RMS, px) is refused
            (marker_occluded).
        max_view_angle_deg: a marker seen further from face-on (deg) is refused (marker_edge_on).
        max_error_m: a position whose error bound is larger (m) is refused (pose_error_high); inf: none.
        max_age_steps: a position older than this (control steps) is reported stale (stale_pose).
        corner_noise_px: the corners' noise floor of the error model, px.
        scale_error: the relative uncertainty of the focal length and the printed size (error model), unitless.
        track_steps: frames over which a marker not found where it was seen is `marker_lost` (not missing_pose).
        threshold_window_px: the detector's adaptive-threshold window, px (odd, >= 3): one pass at this size
            (cv2's default, three passes at 3, 13 and 23 px, found 1 more marker in 800 synthetic frames at three
            times the time: eval/bench/markers.py).
    """

    marker_size_m: float
    dictionary: str = "DICT_4X4_50"
    min_side_px: float = 16.0
    max_reprojection_px: float = 0.5
    max_view_angle_deg: float = 75.0
    max_error_m: float = math.inf
    max_age_steps: int = 5
    corner_noise_px: float = CORNER_NOISE_PX
    scale_error: float = 0.0
    track_steps: int = 30
    threshold_window_px: int = 7

    def __post_init__(self):
        num = lambda v: isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool)  # noqa: E731
        if not (num(self.marker_size_m) and 0 < self.marker_size_m < math.inf):
            raise ValueError(f"markers: marker_size_m must be the printed black square's side in metres (> 0), got "
                             f"{self.marker_size_m!r}")
        if not hasattr(cv2.aruco, str(self.dictionary)) or not str(self.dictionary).startswith("DICT_"):
            known = ", ".join(n for n in dir(cv2.aruco) if n.startswith("DICT_"))
            raise ValueError(f"markers: unknown dictionary {self.dictionary!r}; choose one of {known}")
        for k in ("min_side_px", "max_reprojection_px", "max_view_angle_deg", "corner_noise_px"):
            v = getattr(self, k)
            if not (num(v) and 0 < v < math.inf):
                raise ValueError(f"markers: {k} must be a finite number > 0, got {v!r}")
        if not self.max_view_angle_deg < 90:
            raise ValueError(f"markers: max_view_angle_deg must be under 90 (deg), got {self.max_view_angle_deg}")
        if not (num(self.max_error_m) and self.max_error_m > 0):
            raise ValueError(f"markers: max_error_m must be a distance > 0 (m; inf: none), got {self.max_error_m!r}")
        if not (num(self.scale_error) and 0 <= self.scale_error < 1):
            raise ValueError(f"markers: scale_error is a relative uncertainty in [0, 1), got {self.scale_error!r}")
        for k in ("max_age_steps", "track_steps"):
            v = getattr(self, k)
            if not (int(v) == v >= 0):
                raise ValueError(f"markers: {k} must be an int >= 0 (control steps), got {v!r}")
        w = self.threshold_window_px
        if not (num(w) and int(w) == w >= 3 and int(w) % 2 == 1):
            raise ValueError(f"markers: threshold_window_px must be an odd number of pixels >= 3, got {w!r}")


@dataclass(frozen=True)
class MarkerDetection:
    """One marker found in a frame, in the camera frame.

    Attributes:
        marker_id: its id.
        corners_px: its 4 refined corners (4, 2), undistorted pixel coordinates (ArUco's order).
        position_m: its centre in the camera frame, m.
        rotation: its axes in the camera frame (3x3; z out of its face).
        distance_m: its centre's distance from the camera, m.
        side_px: its mean side, px.
        reprojection_px: RMS distance of its corners from the fitted square's, px.
        view_angle_deg: the angle between its normal and the line of sight, deg (0: face-on).
        error_bound_m: the error model's bound on its position in the camera frame, m (module doc).
        confidence: 0 .. 1, the smallest margin left to the refusal thresholds (1 - value / limit for the
            reprojection error, the viewing angle and the error bound; 1 - min_side / side); 0 where one is crossed.
        reason: why it is refused (marker_occluded, marker_too_small, marker_edge_on, pose_error_high), or None.
    """

    marker_id: int
    corners_px: np.ndarray
    position_m: np.ndarray
    rotation: np.ndarray
    distance_m: float
    side_px: float
    reprojection_px: float
    view_angle_deg: float
    error_bound_m: float
    confidence: float
    reason: str | None


@dataclass(frozen=True)
class MarkerReading:
    """What one frame says about one wanted marker, in the base frame.

    Attributes:
        name: the wanted marker's name (e.g. "object", "target").
        marker_id: its id.
        position_m: its position in the base frame (m, offset applied): this frame's, or the one held from an
            earlier frame (age_steps > 0), or None when none was ever measured.
        age_steps: control steps since position_m was measured (0: this frame's, taken now); nan when None.
        error_bound_m: the bound on |position_m - true| when it was measured, m (module doc); nan when None.
        reason: why this frame gives no current position (REASONS), or None.
        detail: the reason in words (the measured value and the limit it crossed).
        detection: this frame's detection of the marker (also when refused), or None.
    """

    name: str
    marker_id: int
    position_m: np.ndarray | None
    age_steps: float
    error_bound_m: float
    reason: str | None = None
    detail: str = ""
    detection: MarkerDetection | None = None


def object_corners(size_m: float) -> np.ndarray:
    """The marker's corners in its own frame (4, 3), m: the order SOLVEPNP_IPPE_SQUARE wants (ArUco's)."""
    h = 0.5 * size_m
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]], dtype=np.float64)


class MarkerDetector:
    """Markers' poses in the camera frame (steps 1-3 of the module doc), with their error bounds and refusals."""

    def __init__(self, calibration: Calibration, config: MarkerConfig):
        self.calibration, self.config = calibration, config
        self._dict = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, config.dictionary))
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        params.adaptiveThreshWinSizeMin = params.adaptiveThreshWinSizeMax = int(config.threshold_window_px)
        self._detector = cv2.aruco.ArucoDetector(self._dict, params)
        self._cells = int(self._dict.markerSize) + 2  # cells across a marker, its black border included
        self._k = calibration.intrinsics.matrix
        self._dist = calibration.intrinsics.dist
        self._obj = object_corners(config.marker_size_m)
        self._f = calibration.intrinsics.focal_px
        _compile_edge_fit()  # at start, not at the first tick (numba; loaded from its cache after the first run)

    @property
    def n_ids(self) -> int:
        """How many ids the dictionary holds."""
        return int(self._dict.bytesList.shape[0])

    def detect(self, gray: np.ndarray) -> list[MarkerDetection]:
        """Every marker found in a (H, W) uint8 grey frame (refused ones included, their `reason` set); one per id
        (of two with one id, the one with the smaller error bound)."""
        corners, ids, _ = self._detector.detectMarkers(gray)
        if ids is None:
            return []
        out: dict[int, MarkerDetection] = {}
        for c, i in zip(corners, ids.ravel()):
            d = self._pose(gray, c.reshape(4, 2).astype(np.float64), int(i))
            if d is not None and (int(i) not in out or d.error_bound_m < out[int(i)].error_bound_m):
                out[int(i)] = d
        return list(out.values())

    def _pose(self, gray: np.ndarray, raw: np.ndarray, marker_id: int) -> MarkerDetection | None:
        cfg = self.config
        corners = refine_corners(gray, raw, self._cells, self._k, self._dist)
        if corners is None:  # too small or degenerate to fit: the detector's corners, undistorted
            corners = raw if self._dist is None else cv2.undistortPoints(raw[:, None], self._k, self._dist,
                                                                         P=self._k).reshape(4, 2)
        ok, rvec, tvec = cv2.solvePnP(self._obj, corners, self._k, None, flags=cv2.SOLVEPNP_IPPE_SQUARE)
        if not ok:
            return None
        t = tvec.ravel()
        r, _ = cv2.Rodrigues(rvec)
        proj, _ = cv2.projectPoints(self._obj, rvec, tvec, self._k, None)
        reproj = float(np.sqrt(((proj.reshape(4, 2) - corners) ** 2).sum(1).mean()))
        side = float(np.linalg.norm(corners - np.roll(corners, 1, axis=0), axis=1).mean())
        dist = float(np.linalg.norm(t))
        cos = abs(float(r[:, 2] @ t)) / max(dist, 1e-12)
        angle = math.degrees(math.acos(min(1.0, cos)))
        sigma = max(cfg.corner_noise_px, reproj)
        bound = ERROR_K * sigma * t[2] * (1.0 / max(side, 1e-9) + 1.0 / self._f) + cfg.scale_error * t[2]
        bound += 2.0 * self.calibration.fit_rms_m
        reason = None
        if reproj > cfg.max_reprojection_px:
            reason = "marker_occluded"
        elif side < cfg.min_side_px:
            reason = "marker_too_small"
        elif angle > cfg.max_view_angle_deg:
            reason = "marker_edge_on"
        elif bound > cfg.max_error_m:
            reason = "pose_error_high"
        margins = [1.0 - reproj / cfg.max_reprojection_px, 1.0 - cfg.min_side_px / max(side, 1e-9),
                   1.0 - angle / cfg.max_view_angle_deg, 1.0 - bound / cfg.max_error_m]
        conf = 0.0 if reason else float(np.clip(min(margins), 0.0, 1.0))
        return MarkerDetection(marker_id, corners, t, r, dist, side, reproj, angle, float(bound), conf, reason)


def refine_corners(gray: np.ndarray, corners: np.ndarray, cells: int, k: np.ndarray, dist: np.ndarray | None,
                   samples: int = EDGE_SAMPLES) -> np.ndarray | None:
    """A marker's 4 corners (4, 2), undistorted pixels, from lines fitted to its black border's outer edges (module
    doc, step 2); None when a side is too short or too faint to fit. `corners`: the detector's, in the frame;
    cells: the marker's cells across (its black border included), which bounds the search across each edge;
    samples: grey levels read across the edge at each point (0.25 px apart on a marker over ~28 px a side)."""
    corners = np.ascontiguousarray(corners, dtype=np.float64)
    sides = np.sqrt(((np.roll(corners, -1, axis=0) - corners) ** 2).sum(1))
    if sides.min() < 6.0:
        return None
    edge, w, starts = _edge_points(np.ascontiguousarray(gray), corners, float(cells), int(samples))
    if dist is not None:
        edge = cv2.undistortPoints(edge[:, None], k, dist, P=k).reshape(-1, 2)
    out = _corners_from_edges(np.ascontiguousarray(edge), w, starts)
    if out is None:
        return None
    ref = corners if dist is None else cv2.undistortPoints(corners[:, None], k, dist, P=k).reshape(4, 2)
    if np.abs(out - ref).max() > 3.0:
        return None  # the fit moved a corner by more than the detector's error could be: keep the detector's
    return out


def _compile_edge_fit() -> None:
    """Compile (or load from numba's cache) the edge fit on a drawn 30-pixel square."""
    frame = np.full((48, 48), 220, np.uint8)
    frame[9:39, 9:39] = 20
    square = np.array([[9.0, 9.0], [39.0, 9.0], [39.0, 39.0], [9.0, 39.0]])
    refine_corners(frame, square - 0.5, 6, np.eye(3), None)


@njit(cache=True)
def _edge_points(gray, corners, cells, samples):  # pragma: no cover - compiled; tested through refine_corners
    """Each side's edge points (P, 2), px, their weights (the edge's contrast) and the sides' first indices (5,):
    along the side's middle EDGE_SPAN, one point per pixel (6-64 a side), the centroid of the rising grey-level
    gradient across the edge (bilinear reads, `samples` of them over 0.9 cell, at most 2.5 px, either way)."""
    h, wd = gray.shape
    cx, cy = corners[:, 0].mean(), corners[:, 1].mean()
    sides = np.empty(4)
    for i in range(4):
        j = (i + 1) % 4
        sides[i] = math.hypot(corners[j, 0] - corners[i, 0], corners[j, 1] - corners[i, 1])
    starts = np.zeros(5, np.int64)
    for i in range(4):
        starts[i + 1] = starts[i] + min(64, max(6, int(sides[i])))
    edge = np.empty((starts[4], 2))
    weight = np.empty(starts[4])
    prof = np.empty(samples)
    for i in range(4):
        j = (i + 1) % 4
        ax, ay, bx, by = corners[i, 0], corners[i, 1], corners[j, 0], corners[j, 1]
        tx, ty = (bx - ax) / sides[i], (by - ay) / sides[i]
        nx, ny = -ty, tx
        if nx * (0.5 * (ax + bx) - cx) + ny * (0.5 * (ay + by) - cy) < 0:
            nx, ny = -nx, -ny  # outward: dark (border) -> light (quiet zone)
        half = min(2.5, 0.9 * 0.5 * (sides[i - 1] + sides[j]) / cells)
        n = starts[i + 1] - starts[i]
        for q in range(n):
            u = EDGE_SPAN[0] + (EDGE_SPAN[1] - EDGE_SPAN[0]) * q / (n - 1)
            px, py = ax + u * (bx - ax), ay + u * (by - ay)
            for m in range(samples):
                o = half * (2.0 * m / (samples - 1) - 1.0)
                x = min(max(px + o * nx, 0.0), wd - 1.0)  # the frame's edge pixels repeated beyond it
                y = min(max(py + o * ny, 0.0), h - 1.0)
                x0, y0 = min(int(x), wd - 2), min(int(y), h - 2)
                fx, fy = x - x0, y - y0
                prof[m] = ((1 - fy) * ((1 - fx) * gray[y0, x0] + fx * gray[y0, x0 + 1])
                           + fy * ((1 - fx) * gray[y0 + 1, x0] + fx * gray[y0 + 1, x0 + 1]))
            sw, so = 0.0, 0.0
            for m in range(samples - 1):
                g = prof[m + 1] - prof[m]
                if g > 0:  # rising outward only: the border's outer edge
                    sw += g
                    so += g * half * ((2.0 * m + 1.0) / (samples - 1) - 1.0)
            shift = so / sw if sw > 0 else 0.0
            edge[starts[i] + q, 0] = px + shift * nx
            edge[starts[i] + q, 1] = py + shift * ny
            weight[starts[i] + q] = sw
    return edge, weight, starts


@njit(cache=True)
def _corners_from_edges(edge, weight, starts):  # pragma: no cover - compiled; tested through refine_corners
    """(4, 2) corners where the sides' fitted lines meet (corner i: side i-1 and side i), or None when a side has
    under 3 points of contrast (over a quarter of its median) or two sides are parallel. Each line: the total least
    squares fit (the principal axis) of its side's kept points."""
    lines = np.empty((4, 3))
    for i in range(4):
        ws = weight[starts[i]:starts[i + 1]]
        thr = 0.25 * np.median(ws) + 1e-6
        k, sx, sy = 0, 0.0, 0.0
        for q in range(starts[i], starts[i + 1]):
            if weight[q] > thr:
                k += 1
                sx += edge[q, 0]
                sy += edge[q, 1]
        if k < 3:
            return None
        mx, my = sx / k, sy / k
        sxx, syy, sxy = 0.0, 0.0, 0.0
        for q in range(starts[i], starts[i + 1]):
            if weight[q] > thr:
                dx, dy = edge[q, 0] - mx, edge[q, 1] - my
                sxx += dx * dx
                syy += dy * dy
                sxy += dx * dy
        theta = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
        lines[i, 0], lines[i, 1] = -math.sin(theta), math.cos(theta)
        lines[i, 2] = lines[i, 0] * mx + lines[i, 1] * my
    out = np.empty((4, 2))
    for i in range(4):
        a1, b1, c1 = lines[i - 1, 0], lines[i - 1, 1], lines[i - 1, 2]
        a2, b2, c2 = lines[i, 0], lines[i, 1], lines[i, 2]
        det = a1 * b2 - a2 * b1
        if abs(det) < 1e-3:
            return None
        out[i, 0], out[i, 1] = (c1 * b2 - c2 * b1) / det, (a1 * c2 - a2 * c1) / det
    return out


@dataclass
class _Track:
    position_m: np.ndarray | None = None  # the last position measured (base frame, offset applied)
    error_bound_m: float = math.nan
    age_steps: float = math.nan
    seen_quad: np.ndarray | None = None  # its corners in the last frame it was found in (px) ...
    seen_ago: int = 0  # ... that many frames ago


class MarkerSource:
    """The wanted markers' positions in the base frame, frame by frame (module doc).

        source = MarkerSource(load_calibration("camera.json"), {"object": 3, "target": 7},
                              MarkerConfig(marker_size_m=0.04), offsets={"object": (0, 0, -0.02)})
        readings = source.observe(frame)            # {"object": MarkerReading, "target": MarkerReading}

    Each call is one control step: a position held from an earlier frame ages by one. A name may have several
    markers (e.g. one on each face of a block, `{"object": (3, 4, 5)}`): the frame's position is the accepted one
    with the smallest error bound. `depths`: how far behind a marker's face the wanted point lies (m, along the
    marker's normal, away from the camera: a cube's half side for markers on its faces); `offsets`: a fixed
    base-frame offset after that (m).

    Attributes:
        markers: name -> its marker ids.
        counts: Counter of (name, reason) over the frames observed ((name, "ok") for a current position).
        seconds: time each observe() took, s (the last 1000).
    """

    def __init__(self, calibration: Calibration, markers: dict[str, int | tuple[int, ...]], config: MarkerConfig,
                 offsets: dict[str, tuple[float, float, float]] | None = None, detect_repeats: bool = True,
                 depths: dict[str, float] | None = None):
        if not markers:
            raise ValueError("markers: name at least one wanted marker (e.g. {'object': 3})")
        self.calibration, self.config = calibration, config
        self.detector = MarkerDetector(calibration, config)
        n = self.detector.n_ids
        self.markers: dict[str, tuple[int, ...]] = {}
        for name, ids in markers.items():
            ids = tuple(ids) if isinstance(ids, (tuple, list)) else (ids,)
            for i in ids:
                if not (int(i) == i and 0 <= i < n):
                    raise ValueError(f"markers: the {name} marker's id {i!r} is not in {config.dictionary} "
                                     f"(ids 0 .. {n - 1})")
            if not ids:
                raise ValueError(f"markers: the {name} has no marker id")
            self.markers[name] = tuple(int(i) for i in ids)
        every = [i for ids in self.markers.values() for i in ids]
        if len(set(every)) != len(every):
            raise ValueError(f"markers: two wanted markers share an id ({markers}); give each its own")
        depths = dict(depths or {})
        if set(depths) - set(markers):
            raise ValueError(f"markers: depths for {sorted(set(depths) - set(markers))}, which are not wanted markers "
                             f"({sorted(markers)})")
        self.depths = {}
        for name in self.markers:
            d = depths.get(name, 0.0)
            if not (isinstance(d, (int, float)) and math.isfinite(d)):
                raise ValueError(f"markers: the {name} marker's depth must be a finite distance (m), got {d!r}")
            self.depths[name] = float(d)
        offsets = dict(offsets or {})
        unknown = set(offsets) - set(markers)
        if unknown:
            raise ValueError(f"markers: offsets for {sorted(unknown)}, which are not wanted markers "
                             f"({sorted(markers)})")
        self.offsets = {}
        for name in self.markers:
            o = np.asarray(offsets.get(name, (0.0, 0.0, 0.0)), dtype=np.float64)
            if o.shape != (3,) or not np.isfinite(o).all():
                raise ValueError(f"markers: the {name} marker's offset must be 3 finite numbers (m, base frame), got "
                                 f"{offsets.get(name)!r}")
            self.offsets[name] = o
        self.detect_repeats = detect_repeats
        self.counts: Counter = Counter()
        self.seconds: list[float] = []
        self.reset()

    def reset(self) -> None:
        """An episode starts: the positions held, their tracks and the last frame are forgotten."""
        self._tracks = {name: _Track() for name in self.markers}
        self._last_fingerprint: bytes | None = None

    def observe(self, frame, frame_age_steps: float = 0.0) -> dict[str, MarkerReading]:
        """One control step: each wanted marker's reading from this frame (module doc). frame: (H, W, 3) uint8
        RGB (or (H, W) grey), or None when the camera gave none; frame_age_steps: how old it is, control steps.
        Never raises."""
        t0 = time.perf_counter()
        try:
            out = self._observe(frame, frame_age_steps)
        except Exception as e:  # noqa: BLE001 - do-no-harm: a frame that breaks detection is a bad frame
            out = self._no_frame("bad_frame", f"{type(e).__name__}: {e}")
        for r in out.values():
            self.counts[(r.name, r.reason or "ok")] += 1
        self.seconds = self.seconds[-999:] + [time.perf_counter() - t0]
        return out

    def _observe(self, frame, frame_age_steps: float) -> dict[str, MarkerReading]:
        for tr in self._tracks.values():  # one control step: what is held ages
            if tr.position_m is not None:
                tr.age_steps += 1
            tr.seen_ago += 1
        if frame is None:
            return self._no_frame("stale_pose", "no frame")
        gray, why = self._gray(frame)
        if gray is None:
            return self._no_frame("bad_frame", why)
        if self.detect_repeats:
            fp = hashlib.blake2b(np.ascontiguousarray(gray[::7, ::7]).tobytes(), digest_size=16).digest()
            repeated, self._last_fingerprint = fp == self._last_fingerprint, fp
            if repeated:
                return self._no_frame("stale_pose", "the same frame as the last step (the camera stalled)")
        age = float(frame_age_steps)
        if not (math.isfinite(age) and age >= 0):
            return self._no_frame("bad_frame", f"frame age {frame_age_steps!r} control steps")
        found = {d.marker_id: d for d in self.detector.detect(gray)}
        h, w = gray.shape
        out = {}
        for name, ids in self.markers.items():
            tr, d, i = self._tracks[name], _best([found[k] for k in ids if k in found]), ids[0]
            if d is None:
                quad = tr.seen_quad
                inside = quad is not None and (quad >= 0).all() and (quad[:, 0] <= w - 1).all() and (
                    quad[:, 1] <= h - 1).all()
                if inside and tr.seen_ago <= self.config.track_steps:
                    out[name] = self._held(name, "marker_lost", f"marker {_ids(ids)} not found where it was seen "
                                           f"{tr.seen_ago} frame(s) ago (covered, edge-on or blurred)")
                elif found:
                    out[name] = self._held(name, "wrong_id", f"markers {sorted(found)} in view, not {_ids(ids)}")
                else:
                    out[name] = self._held(name, "missing_pose", "no marker in view")
                continue
            tr.seen_quad, tr.seen_ago = d.corners_px, 0
            if d.reason is not None:
                out[name] = self._held(name, d.reason, _refusal(d, self.config), d)
                continue
            inward = d.rotation[:, 2] if d.rotation[:, 2] @ d.position_m > 0 else -d.rotation[:, 2]  # away from us
            pos = self.calibration.to_base(d.position_m + self.depths[name] * inward) + self.offsets[name]
            tr.position_m, tr.error_bound_m, tr.age_steps = pos, d.error_bound_m, age
            stale = age > self.config.max_age_steps
            out[name] = MarkerReading(name, d.marker_id, pos.copy(), age, d.error_bound_m, "stale_pose" if stale else None,
                                      f"the frame is {age:g} control steps old" if stale else "", d)
        return out

    def _gray(self, frame) -> tuple[np.ndarray | None, str]:
        if not isinstance(frame, np.ndarray):
            return None, f"a {type(frame).__name__}, not an image array"
        if frame.dtype != np.uint8:
            return None, f"dtype {frame.dtype}, not uint8"
        if frame.ndim not in (2, 3):
            return None, f"shape {frame.shape}, not (H, W, 3) RGB"
        w, h = self.calibration.intrinsics.image_size
        if frame.shape[:2] != (h, w):
            return None, f"{frame.shape[1]}x{frame.shape[0]} pixels, the calibration's camera gives {w}x{h}"
        if frame.ndim == 2:
            return frame, ""
        if frame.ndim == 3 and frame.shape[2] in (3, 4):
            return cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY if frame.shape[2] == 3 else cv2.COLOR_RGBA2GRAY), ""
        return None, f"shape {frame.shape}, not (H, W, 3) RGB"

    def _held(self, name: str, reason: str, detail: str, detection: MarkerDetection | None = None) -> MarkerReading:
        tr = self._tracks[name]
        pos = None if tr.position_m is None else tr.position_m.copy()
        if pos is None and reason == "stale_pose":
            reason, detail = "missing_pose", f"{detail}; no position measured yet"
        marker = detection.marker_id if detection is not None else self.markers[name][0]
        return MarkerReading(name, marker, pos, tr.age_steps, tr.error_bound_m, reason, detail, detection)

    def _no_frame(self, reason: str, detail: str) -> dict[str, MarkerReading]:
        return {name: self._held(name, reason, detail) for name in self.markers}


def _best(ds: list[MarkerDetection]) -> MarkerDetection | None:
    """Of one name's markers found in a frame: an accepted one with the smallest error bound, else the refused one
    with the smallest bound (its reason is the frame's), else None."""
    if not ds:
        return None
    return min(ds, key=lambda d: (d.reason is not None, d.error_bound_m))


def _ids(ids: tuple[int, ...]) -> str:
    return str(ids[0]) if len(ids) == 1 else "/".join(map(str, ids))


def _refusal(d: MarkerDetection, c: MarkerConfig) -> str:
    """A refused detection's reason in words: its value and the limit."""
    return {"marker_occluded": f"reprojection error {d.reprojection_px:.2f} px > {c.max_reprojection_px} px "
                               "(its corners are not a square's: partly covered?)",
            "marker_too_small": f"side {d.side_px:.1f} px < {c.min_side_px} px",
            "marker_edge_on": f"seen {d.view_angle_deg:.0f} deg from face-on > {c.max_view_angle_deg} deg",
            "pose_error_high": f"error bound {d.error_bound_m * 1000:.1f} mm > {c.max_error_m * 1000:.1f} mm"}[d.reason]
