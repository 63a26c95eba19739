"""Per-episode metrics (plain numpy; the definitions docs/method.md reports with).

    precision   clip(1 - min_t d_obj_xy / 0.10 m, 0, 1)
    efficiency  1 - steps / horizon on success, 0 on failure
    mean_jerk   mean |d^3 p_eef / dt^3| over the episode, m/s^3 (finite differences)
    ldlj        log dimensionless jerk: -ln( T^3 / v_peak^2 * integral |jerk|^2 dt )
    sparc       spectral arc length of the speed profile (Balasubramanian et al. 2015)
    stability   1 / (1 + mean_jerk / J_REF): 1 is perfectly smooth; J_REF = 10 m/s^3 is the
                normaliser, fixed for every backbone, mode and task (a mean jerk of 10 m/s^3
                scores 0.5)
"""

from __future__ import annotations

import numpy as np

PRECISION_SCALE_M = 0.10
J_REF = 10.0  # m/s^3: the stability normaliser


def precision(d_obj_xy: np.ndarray) -> float:
    d = np.asarray(d_obj_xy, dtype=float)
    d = d[np.isfinite(d)]
    return float(np.clip(1.0 - d.min() / PRECISION_SCALE_M, 0.0, 1.0)) if d.size else 0.0


def efficiency(success: bool, steps: int, horizon: int) -> float:
    return float(1.0 - steps / horizon) if success else 0.0


def jerk(pos: np.ndarray, dt: float) -> np.ndarray:
    """(T-3, 3) third finite difference of (T, 3) positions, m/s^3."""
    return np.diff(np.asarray(pos, dtype=float), n=3, axis=0) / dt**3


def mean_jerk(pos: np.ndarray, dt: float) -> float:
    j = jerk(pos, dt)
    return float(np.linalg.norm(j, axis=1).mean()) if len(j) else float("nan")


def stability(pos: np.ndarray, dt: float) -> float:
    mj = mean_jerk(pos, dt)
    return float(1.0 / (1.0 + mj / J_REF)) if np.isfinite(mj) else float("nan")


def ldlj(pos: np.ndarray, dt: float) -> float:
    pos = np.asarray(pos, dtype=float)
    if len(pos) < 5:
        return float("nan")
    v = np.linalg.norm(np.diff(pos, axis=0) / dt, axis=1)
    vpeak = v.max()
    if vpeak <= 0:
        return float("nan")
    j = np.linalg.norm(jerk(pos, dt), axis=1)
    duration = dt * (len(pos) - 1)
    return float(-np.log(duration**3 / vpeak**2 * np.sum(j**2) * dt))


def sparc(pos: np.ndarray, dt: float, pad_level: int = 4, fc: float = 10.0, amp_th: float = 0.05) -> float:
    """Spectral arc length of the speed profile (closer to 0 is smoother)."""
    pos = np.asarray(pos, dtype=float)
    if len(pos) < 4:
        return float("nan")
    speed = np.linalg.norm(np.diff(pos, axis=0) / dt, axis=1)
    if speed.max() <= 0:
        return float("nan")
    nfft = int(2 ** (np.ceil(np.log2(len(speed))) + pad_level))
    freq = np.arange(nfft) / (nfft * dt)
    mag = np.abs(np.fft.fft(speed, nfft))
    mag = mag / mag.max()
    sel = freq <= fc
    freq, mag = freq[sel], mag[sel]
    above = np.flatnonzero(mag >= amp_th)
    freq, mag = freq[above[0] : above[-1] + 1], mag[above[0] : above[-1] + 1]
    df = np.diff(freq) / (freq[-1] - freq[0]) if freq[-1] > freq[0] else np.zeros(0)
    return float(-np.sum(np.sqrt(df**2 + np.diff(mag) ** 2)))


def wilson_interval(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a rate."""
    if n == 0:
        return (0.0, 1.0)
    p = successes / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (float(max(centre - half, 0.0)), float(min(centre + half, 1.0)))  # rounding leaves -1e-17 at p = 0
