"""The evaluation harness: a unit writes its records atomically and a re-run skips it (resume)."""

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "eval"))
from harness import Unit, run_units, seed_blocks  # noqa: E402

from lerobot_physvla import metrics  # noqa: E402
from lerobot_physvla.config import PhysVLAConfig  # noqa: E402


def test_seed_blocks_cover_every_seed_once():
    assert seed_blocks(7, 3) == [(0, 3), (3, 3), (6, 1)]


def test_units_run_once_and_resume(tmp_path):
    unit = Unit("expert_clean", "phys_el", PhysVLAConfig(mode="phys_el").to_dict(), task_id=0, first_seed=0, episodes=1)
    records, _ = run_units([unit], tmp_path, workers=1)
    path = tmp_path / "units" / f"{unit.key}.json"
    stamp = path.stat().st_mtime_ns
    (rec,) = records
    assert rec["success"] and rec["steps"] < 280  # the clean expert solves task 0, init state 0
    assert 0 < rec["precision"] <= 1 and rec["el_fire_rate"] == 1.0 and rec["t_us_p50"]["total"] > 0
    again, _ = run_units([unit], tmp_path, workers=1)
    assert again == records and path.stat().st_mtime_ns == stamp  # resumed: not re-run
    assert json.loads(path.read_text())["unit"]["backbone"] == "expert_clean"
    assert metrics.wilson_interval(1, 1)[1] == 1.0
