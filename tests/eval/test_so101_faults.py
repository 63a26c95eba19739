"""eval/so101_faults.py's pieces: the block / goal draws and the paired statistics."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "eval"))

import so101_faults as sf  # noqa: E402


def test_draws_are_seeded_inside_the_box_and_apart():
    for seed in range(200):
        block, goal = sf.draw(seed)
        assert np.all(block[:2] >= sf.BOX[0]) and np.all(block[:2] <= sf.BOX[1]) and block[2] == 0.02
        assert np.linalg.norm(goal[:2] - block[:2]) >= 0.08
    np.testing.assert_array_equal(sf.draw(7)[1], sf.draw(7)[1])


def test_paired_counts_and_interval():
    rec = lambda s, c, ok: {"seed": s, "mode": "clean", "corrected": c, "success": ok, "mean_jerk": 2.0}  # noqa: E731
    base = [True, False, False, True, False]
    corr = [True, True, False, False, True]
    records = [rec(s, None, b) for s, b in enumerate(base)] + [rec(s, "arm", c) for s, c in enumerate(corr)]
    p = sf.paired(records, "clean", range(5), "arm")
    assert (p["n"], p["won"], p["lost"], p["both"], p["neither"]) == (5, 2, 1, 1, 1)
    assert p["diff"] == pytest.approx(0.2) and p["base"] == pytest.approx(0.4) and p["this"] == pytest.approx(0.6)
    d = np.array([0, 1, 0, -1, 1])
    half = 1.96 * d.std(ddof=1) / np.sqrt(5)
    assert p["ci"] == pytest.approx((0.2 - half, 0.2 + half)) and p["jerk"] == pytest.approx(1.0)
