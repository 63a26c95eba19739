"""The summary table and per-episode plots shared by replay and lerobot-eval."""

from __future__ import annotations

import numpy as np

from lerobot_physvla import report
from lerobot_physvla.core.config import LIBERO_OSC_POSE


def test_corrections_are_attributed_to_their_phase():
    raw = np.zeros((8, 7))
    raw[:, 6] = 1.0  # closing throughout
    cor = raw.copy()
    cor[0:2, 6] = -1.0  # approach: the veto opened the gripper twice
    cor[6, 0] = 0.3  # place: a position change of 0.3
    phase = np.array([0, 0, 0, 1, 2, 2, 3, 3])
    c = report.corrections_by_phase(raw, cor, phase, LIBERO_OSC_POSE)
    assert c["approach veto"] == {"frames_in_phase": 3, "frames_changed": 2, "mean_abs_change": 2.0}
    assert c["place guidance"] == {"frames_in_phase": 2, "frames_changed": 1, "mean_abs_change": 0.3}
    assert c["grasp guidance"]["frames_changed"] == c["transport EMA + lift"]["frames_changed"] == 0
    assert c["approach guides"]["frames_changed"] == 0  # the approach's changes were the gripper's
    cor[2, 1] = -0.4  # approach: the rim guide moved y
    c = report.corrections_by_phase(raw, cor, phase, LIBERO_OSC_POSE)
    assert c["approach guides"] == {"frames_in_phase": 3, "frames_changed": 1, "mean_abs_change": 0.4}
    assert c["approach veto"]["frames_changed"] == 2


def test_summary_table_rows_and_total():
    rows = [report.episode_row(i, "pick up the bowl", 10, ok, np.zeros(10, int), {"approach veto": {"frames_changed": i}},
                               i, 2.5, {"invalid_state": 1} if i else {}) for i, ok in enumerate([True, False, None])]
    text = report.summary_table(rows, {"corrector": "preset default"}, max_rows=2)
    lines = text.splitlines()
    assert lines[2].split()[:2] == ["0", "pick"] and "none" in lines[2]
    assert "veto 1" in lines[3] and "invalid_state 1" in lines[3]
    assert "... 1 more episodes" in text
    assert "3 episodes, 30 frames, success 1/2" in text and lines[-1] == "corrector: preset default"
    resim = [dict(rows[0], success="yes/no/yes")]
    assert "recorded success 1/1" in report.summary_table(resim)


def test_plot_and_report_files(tmp_path):
    t = 30
    raw = np.zeros((t, 7))
    cor = raw.copy()
    cor[20:, 0] = 0.2
    phase = np.repeat([0, 1, 2], 10)
    png = report.plot_episode(tmp_path / "plots" / "ep.png", raw, cor, phase, np.full(t, 0.1), 0.05, LIBERO_OSC_POSE, "ep")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = report.write_report(tmp_path, "title", "| table |", [("episode 0", png)], ["a note"], name="physvla_report.md")
    assert md == tmp_path / "physvla_report.md"
    text = md.read_text()
    assert "![episode 0](plots/ep.png)" in text and "- a note" in text
