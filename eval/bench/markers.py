"""The marker pose source (lerobot_physvla/sources/markers.py) against synthetic truth: its position error, the
error model's constant (ERROR_K), and its time per frame on one core.

    .venv/bin/python eval/bench/markers.py [--draws 1500] [--holdout 500] [--out eval/results/bench_markers]

Frames: sources/marker_render.py draws a 4 cm DICT_4X4_50 marker (also 3 and 6 cm) at a random pose before a
640x480 camera (f = 600 px, with and without lens distortion k1 = -0.12, k2 = 0.05): distance 0.25-1.0 m,
anywhere in the image, turned 0-70 deg from face-on about a random axis, spun in-plane; 4x supersampled, lens
blur 0.4-1.2 px, pixel noise 1-6 grey levels. Per detected marker: |position - truth| (m) and the model's
prediction g = sigma * Z * (1 / side_px + 1 / f) with sigma = max(corner noise floor, reprojection error); the
constant is the 99.5th percentile of |error| / g, times 1.5 (the bound's margin), rounded up to a quarter; its
coverage is then checked on other frames (--holdout, another seed). Also
cv2's own SUBPIX corners on the same frames, for the bias the edge fit removes, and the time of one
MarkerSource.observe on a 640x480 frame holding two markers (cv2.setNumThreads(1): one core).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from lerobot_physvla.sources.calibration import Calibration, CameraIntrinsics
from lerobot_physvla.sources.marker_render import MarkerPlacement, render_markers
from lerobot_physvla.sources.markers import ERROR_K, MarkerConfig, MarkerDetector, MarkerSource, object_corners

INTR = CameraIntrinsics(600.0, 600.0, 319.5, 239.5, image_size=(640, 480))
INTR_DIST = CameraIntrinsics(600.0, 600.0, 319.5, 239.5, distortion=(-0.12, 0.05, 0.0, 0.0, 0.0), image_size=(640, 480))
FACING = np.diag([1.0, -1.0, -1.0])  # a marker facing a camera whose frame is the base frame
MARGIN = 1.5


def _rotation(axis: np.ndarray, deg: float) -> np.ndarray:
    r, _ = cv2.Rodrigues(np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis) * math.radians(deg))
    return r


def draw(rng: np.random.Generator) -> dict:
    """One random scene: the marker's placement (camera frame = base frame) and the frame's degradations."""
    z = rng.uniform(0.25, 1.0)
    intr = INTR_DIST if rng.random() < 0.5 else INTR
    u, v = rng.uniform(80, 560), rng.uniform(70, 410)  # where its centre falls in the image, px
    centre = np.array([(u - intr.cx) / intr.fx * z, (v - intr.cy) / intr.fy * z, z])
    tilt = rng.uniform(0.0, 70.0)
    axis = np.append(rng.normal(size=2), 0.0)
    rot = _rotation(axis, tilt) @ FACING @ _rotation([0, 0, 1], rng.uniform(0, 360))
    size = float(rng.choice([0.03, 0.04, 0.04, 0.06]))
    return {"intr": intr, "placement": MarkerPlacement(int(rng.integers(0, 50)), tuple(centre), rot, size),
            "blur": rng.uniform(0.4, 1.2), "noise": rng.uniform(1.0, 6.0), "seed": int(rng.integers(2**31)),
            "tilt": tilt}


def measure(draws: int, seed: int = 0) -> list[dict]:
    rng = np.random.default_rng(seed)
    rows = []
    subpix = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50), _subpix_params())
    for _ in range(draws):
        s = draw(rng)
        cal = Calibration(s["intr"], np.eye(4))
        p: MarkerPlacement = s["placement"]
        frame = render_markers(cal, [p], noise=s["noise"], blur_px=s["blur"], seed=s["seed"])
        gray = cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY)
        det = MarkerDetector(cal, MarkerConfig(p.size_m))
        found = [d for d in det.detect(gray) if d.marker_id == p.marker_id]
        t0 = time.perf_counter()
        theirs = subpix.detectMarkers(gray)  # cv2's default detector (three threshold windows)
        t1 = time.perf_counter()
        det._detector.detectMarkers(gray)  # ours (one window), on the same frame
        t2 = time.perf_counter()
        row = {"z": p.centre_m[2], "tilt": s["tilt"], "size": p.size_m, "distorted": s["intr"].dist is not None,
               "detected": bool(found), "default_detected": theirs[1] is not None and p.marker_id in theirs[1].ravel(),
               "t_default_s": t1 - t0, "t_ours_s": t2 - t1}
        if found:
            d = found[0]
            err = float(np.linalg.norm(d.position_m - np.asarray(p.centre_m)))
            sigma = max(det.config.corner_noise_px, d.reprojection_px)
            g = sigma * d.position_m[2] * (1.0 / d.side_px + 1.0 / det._f)
            row.update(err=err, g=g, side=d.side_px, reproj=d.reprojection_px, angle=d.view_angle_deg,
                       bound=d.error_bound_m, reason=d.reason, subpix_err=_subpix_error(theirs, p, cal))
        rows.append(row)
    return rows


def _subpix_params():
    q = cv2.aruco.DetectorParameters()
    q.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    return q


def _subpix_error(detected, p: MarkerPlacement, cal: Calibration) -> float:
    """|position - truth| with cv2's SUBPIX corners alone (no edge fit), m; nan when not found."""
    corners, ids, _ = detected
    if ids is None or p.marker_id not in ids.ravel():
        return math.nan
    c = corners[list(ids.ravel()).index(p.marker_id)].reshape(4, 2).astype(np.float64)
    k, dist = cal.intrinsics.matrix, cal.intrinsics.dist
    ok, _, t = cv2.solvePnP(object_corners(p.size_m), c, k, dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    return float(np.linalg.norm(t.ravel() - np.asarray(p.centre_m))) if ok else math.nan


def time_observe(frames: int = 200) -> dict:
    """One MarkerSource.observe per 640x480 frame holding two 4 cm markers 0.5 m away, one core."""
    cv2.setNumThreads(1)
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = np.diag([1.0, -1.0, -1.0]), [0.3, 0.0, 0.5]
    cal = Calibration(INTR, t)
    src = MarkerSource(cal, {"object": 3, "target": 7}, MarkerConfig(0.04), detect_repeats=False)
    shots = [render_markers(cal, [MarkerPlacement(3, (0.3 + 0.01 * (i % 5), 0.02, 0.0)),
                                  MarkerPlacement(7, (0.4, -0.08, 0.0))], seed=i) for i in range(10)]
    empty = render_markers(cal, [], seed=0)
    for f in shots:
        src.observe(f)
    src.seconds = []
    for i in range(frames):
        src.observe(shots[i % len(shots)])
    two = np.array(src.seconds) * 1e3
    src.seconds = []
    for i in range(frames // 2):
        src.observe(empty)
    none = np.array(src.seconds) * 1e3
    return {"two_markers_ms_p50": float(np.median(two)), "two_markers_ms_p99": float(np.percentile(two, 99)),
            "no_marker_ms_p50": float(np.median(none))}


def summarize(rows: list[dict]) -> dict:
    ok = [r for r in rows if r["detected"]]
    used = [r for r in ok if r["reason"] is None]
    ratio = np.array([r["err"] / r["g"] for r in ok])
    k = math.ceil(float(np.percentile(ratio, 99.5)) * MARGIN * 4) / 4
    err = np.array([r["err"] for r in used]) * 1e3
    sp = np.array([r["subpix_err"] for r in used]) * 1e3
    near = [r for r in used if 0.4 <= r["z"] <= 0.6 and r["size"] == 0.04]
    bins = {}
    for lo, hi in ((0.25, 0.5), (0.5, 0.75), (0.75, 1.0)):
        b = [r for r in used if lo <= r["z"] < hi]
        if b:
            e = np.array([r["err"] for r in b]) * 1e3
            bins[f"{lo}-{hi} m"] = {"n": len(b), "err_p50_mm": float(np.median(e)),
                                    "err_p95_mm": float(np.percentile(e, 95)),
                                    "bound_p50_mm": float(np.median([r["bound"] for r in b]) * 1e3),
                                    "subpix_err_p50_mm": float(np.nanmedian([r["subpix_err"] for r in b]) * 1e3)}
    t_ours, t_default = (np.array([r[k] for r in rows]) for k in ("t_ours_s", "t_default_s"))
    return {"draws": len(rows), "detected": len(ok), "used": len(used),
            "default_detected": sum(r["default_detected"] for r in rows),
            "detect_ms_p50": float(np.median(t_ours) * 1e3), "default_detect_ms_p50": float(np.median(t_default) * 1e3),
            "detect_time_ratio_p50": float(np.median(t_ours / t_default)),
            "refused": {k_: sum(r["reason"] == k_ for r in ok) for k_ in {r["reason"] for r in ok} if k_},
            "ratio_p50": float(np.median(ratio)), "ratio_p99_5": float(np.percentile(ratio, 99.5)),
            "ratio_max": float(ratio.max()), "error_k_suggested": k, "error_k_in_use": ERROR_K,
            "covered_by_bound": float(np.mean([r["err"] <= r["bound"] for r in used])),
            "err_p50_mm": float(np.median(err)), "err_p95_mm": float(np.percentile(err, 95)),
            "err_max_mm": float(err.max()),
            "subpix_err_p50_mm": float(np.nanmedian(sp)), "subpix_err_p95_mm": float(np.nanpercentile(sp, 95)),
            "4cm_0.4-0.6m": {"n": len(near), "err_p50_mm": float(np.median([r["err"] for r in near]) * 1e3),
                             "err_max_mm": float(max(r["err"] for r in near) * 1e3),
                             "bound_p50_mm": float(np.median([r["bound"] for r in near]) * 1e3)},
            "by_distance": bins}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=1500, help="frames the constant is calibrated on (seed 0)")
    ap.add_argument("--holdout", type=int, default=500, help="other frames its coverage is checked on (seed 1)")
    ap.add_argument("--out", default="eval/results/bench_markers")
    a = ap.parse_args(argv)
    t0 = time.time()
    cv2.setNumThreads(1)
    res = summarize(measure(a.draws))
    held = [r for r in measure(a.holdout, seed=1) if r["detected"] and r["reason"] is None]
    res["holdout"] = {"used": len(held), "covered_by_bound": float(np.mean([r["err"] <= r["bound"] for r in held])),
                      "err_p50_mm": float(np.median([r["err"] for r in held]) * 1e3)}
    res["time"] = time_observe()
    res["machine"] = f"{platform.machine()}, {platform.python_version()}, OpenCV {cv2.__version__}"
    res["wall_s"] = time.time() - t0
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(res, indent=1) + "\n")
    (out / "README.md").write_text(readme(res, a))
    print(json.dumps(res, indent=1))


def readme(r: dict, a) -> str:
    """The results as a page: the command, the error against truth, the model's constant, the time."""
    rows = "\n".join(f"| {k} | {b['n']} | {b['err_p50_mm']:.2f} | {b['err_p95_mm']:.2f} | {b['bound_p50_mm']:.1f} | "
                     f"{b['subpix_err_p50_mm']:.2f} |" for k, b in r["by_distance"].items())
    n, t = r["4cm_0.4-0.6m"], r["time"]
    return f"""# The marker pose source against synthetic truth

Command: `.venv/bin/python eval/bench/markers.py --draws {a.draws} --holdout {a.holdout}`  
Machine: {r['machine']}; one OpenCV thread; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}

{r['draws']} random frames (module doc of eval/bench/markers.py: 3-6 cm markers 0.25-1.0 m from a 640x480, f = 600 px
camera, half with lens distortion, tilted 0-70 deg, blurred, noisy): {r['detected']} detected, {r['used']} used
(refused: {', '.join(f'{k} {v}' for k, v in sorted(r['refused'].items())) or 'none'}).
cv2's default detector (three threshold windows, 3-23 px) on the same frames: {r['default_detected']} detected; its
detectMarkers p50 {r['default_detect_ms_p50']:.2f} ms against the one-window detector's {r['detect_ms_p50']:.2f} ms (ratio,
frame by frame, p50 {r['detect_time_ratio_p50']:.2f}).

| distance | frames used | error p50 (mm) | error p95 (mm) | bound p50 (mm) | cv2 SUBPIX corners alone, error p50 (mm) |
|---|---|---|---|---|---|
{rows}

All used: error p50 {r['err_p50_mm']:.2f} mm, p95 {r['err_p95_mm']:.2f} mm, max {r['err_max_mm']:.1f} mm
(cv2's SUBPIX corners alone: p50 {r['subpix_err_p50_mm']:.2f} mm, p95 {r['subpix_err_p95_mm']:.2f} mm).
A 4 cm marker 0.4-0.6 m away ({n['n']} frames): error p50 {n['err_p50_mm']:.2f} mm, max {n['err_max_mm']:.1f} mm;
its bound p50 {n['bound_p50_mm']:.1f} mm.

Error model (sources/markers.py): |error| / (sigma Z (1 / side_px + 1 / f)) has p50 {r['ratio_p50']:.2f}, p99.5
{r['ratio_p99_5']:.2f}, max {r['ratio_max']:.2f}; ERROR_K = p99.5 x {MARGIN} rounded up to a quarter =
{r['error_k_suggested']} (in use: {r['error_k_in_use']}); the bound covers the error of
{100 * r['covered_by_bound']:.1f} % of the frames used; on {r['holdout']['used']} other frames used (seed 1), of
{100 * r['holdout']['covered_by_bound']:.1f} % (their error p50 {r['holdout']['err_p50_mm']:.2f} mm).

Time of one MarkerSource.observe on a 640x480 frame, one core: two markers p50 {t['two_markers_ms_p50']:.1f} ms, p99
{t['two_markers_ms_p99']:.1f} ms; no marker p50 {t['no_marker_ms_p50']:.1f} ms.
"""


if __name__ == "__main__":
    sys.exit(main())
