"""eval/so101_robot.py (the SO-101 engine of the harness): the block / goal draws."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "eval"))

import so101_robot as sr  # noqa: E402


def test_draws_are_seeded_inside_the_box_and_apart():
    for seed in range(200):
        block, goal = sr.draw(seed)
        assert np.all(block[:2] >= sr.BOX[0]) and np.all(block[:2] <= sr.BOX[1]) and block[2] == 0.02
        assert np.linalg.norm(goal[:2] - block[:2]) >= 0.08
    np.testing.assert_array_equal(sr.draw(7)[1], sr.draw(7)[1])
