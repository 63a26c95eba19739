"""eval/experiments.py efficacy: the report shows every stage's units on disk, whichever stages ran.

A run of one stage once rewrote eval/results/efficacy/README.md with that stage's section alone
(f6127d5 committed such a report: sections 1-7 were gone)."""

import json
import sys
from argparse import Namespace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "eval"))
import efficacy as ef  # noqa: E402
import experiments  # noqa: E402


def _write_units(out: Path, stage: str, success) -> int:
    """Fake records for the units of one stage (expert_clean only): success(config, task, seed) -> bool."""
    units = experiments._efficacy_units([stage], ["expert_clean"])
    (out / "units").mkdir(parents=True, exist_ok=True)
    for u in units:
        rec = {"backbone": u.backbone, "config": u.config_name, "task_id": u.task_id, "seed": u.first_seed,
               "scene": u.scene, "success": bool(success(u.config_name, u.task_id, u.first_seed)),
               "mean_jerk": 2.0}
        (out / "units" / f"{u.key}.json").write_text(json.dumps({"unit": {}, "seconds": 1.0, "records": [rec]}))
    return len(units)


def _args(stages: str) -> Namespace:
    return Namespace(stages=stages, experts="expert_clean", learned="act_single", learned_on_disk=True,
                     checkpoints="nowhere", workers=1, backend="process")


def test_one_stage_run_keeps_every_stage_on_disk(tmp_path, monkeypatch):
    monkeypatch.setattr(experiments, "RESULTS", tmp_path)
    ran = []
    monkeypatch.setattr(experiments, "run_units", lambda units, out, w, b: (ran.extend(units), ([], 0.0))[1])
    # design block: default v2 wins task 0's five pairs; block 20-24: the default loses task 3's five
    n = _write_units(tmp_path / "efficacy", "design", lambda c, t, s: c != "baseline" and t == 0 or t in (1, 2))
    n += _write_units(tmp_path / "efficacy", "confirm4", lambda c, t, s: not (c != "baseline" and t == 3))
    experiments.efficacy(_args("confirm4"))
    assert {u.config_name for u in ran} == set(ef.CONFIRM4)  # only the stage asked for was run
    text = (tmp_path / "efficacy" / "README.md").read_text()
    assert "## 2. Design block" in text and "## 3d. Fourth confirmation block" in text
    rows = {line.split(" | ")[0].lstrip("| "): line for line in text.splitlines() if line.startswith("| expert_clean")}
    assert "| 50 | 20% | 30% | +10 pp" in rows["expert_clean / default v2"]
    v3 = rows[f"expert_clean / {ef.CANDIDATE_4}"]  # the configuration block 20-24 confirmed
    assert "| 50 | 100% | 90% | -10 pp" in v3 and "T3 -5" in v3
    assert len(json.loads((tmp_path / "efficacy" / "records.json").read_text())) == n


def test_a_cut_short_cell_is_left_out(tmp_path, monkeypatch):
    monkeypatch.setattr(experiments, "RESULTS", tmp_path)
    monkeypatch.setattr(experiments, "run_units", lambda units, out, w, b: ([], 0.0))
    _write_units(tmp_path / "efficacy", "confirm4", lambda c, t, s: True)
    cut = [f for f in (tmp_path / "efficacy" / "units").iterdir() if f"__{ef.CANDIDATE_4}__" in f.name][:7]
    for f in cut:
        f.unlink()
    experiments.efficacy(_args("confirm4"))
    text = (tmp_path / "efficacy" / "README.md").read_text()
    assert "## 3d." not in text and f"expert_clean / {ef.CANDIDATE_4} |" not in text  # 43 of 50 pairs: no row


def test_shipped_jerk_is_split_by_what_the_pair_did():
    """Section 8d: the shipped default's jerk ratio over all pairs and per outcome group, from the
    records: turned pairs (baseline fails, the default succeeds) are the ones whose motion changed."""
    recs = []
    for t in range(10):
        for s in ef.DESIGN_SEEDS:
            turned, both = t < 2, t >= 5  # tasks 0-1 turned (jerk x3), 5-9 both succeed (x1), 2-4 neither (x1)
            for config, ok, jerk in (("baseline", both, 1.0), (ef.SHIPPED, both or turned, 3.0 if turned else 1.0)):
                recs.append({"backbone": "expert_faulty", "config": config, "task_id": t, "seed": s,
                             "scene": "libero_spatial", "success": ok, "mean_jerk": jerk})
    lines = ef._shipped_jerk_lines(recs, [])
    row = next(line for line in lines if line.startswith("| expert_faulty | 0-4"))
    # all 50: (10 x 3 + 40 x 1) / 50 = 1.4; both 25 at x1; turned 10 at x3; neither 15 at x1; none lost
    assert row == "| expert_faulty | 0-4 | x1.40 (50) | x1.00 (25) | x3.00 (10) | x1.00 (15) | - (0) |"
    assert ef._shipped_jerk_lines(recs[:-2], []) == []  # 49 pairs: no complete cell, no section


def test_design19s_rule_asks_more_learned_pairs_won_than_lost_and_no_expert_down_two():
    """candidate_verdict with need_gain "learned" (DESIGN19): pooled over the learned ACTs strictly more
    pairs won than lost against the reference; any backbone 2 pairs net down fails it."""
    cand, ref = ef.CANDIDATE_19, ef.CANDIDATE_17

    def block(learned_won: int, learned_lost: int, expert_lost: int):
        recs, learned = [], []
        for t in range(10):
            for s in ef.DESIGN_SEEDS:
                k = t * 5 + s  # pair number, 0-49
                for config in ("baseline", ref, cand):
                    hurt = config == cand and k < expert_lost
                    recs.append({"backbone": "expert_clean", "config": config, "task_id": t, "seed": s,
                                 "scene": "libero_spatial", "success": not hurt, "mean_jerk": 1.0})
                    ok = (config == cand) if k < learned_won else (config != cand) if k < learned_won + learned_lost \
                        else False
                    learned.append({"backbone": "act_single", "config": config, "task_id": t, "seed": s,
                                    "scene": "libero_spatial", "success": ok, "mean_jerk": 1.0})
        for cell in ("lift sigma=0.00", "lift sigma=0.40", "fetch sigma=0.00", "fetch sigma=0.40"):
            for seed in range(ef.LIFT_DESIGN, ef.LIFT_DESIGN + 20):
                recs += [{"backbone": cell, "config": c, "task_id": 0, "seed": seed, "scene": "lift",
                          "success": True, "mean_jerk": 1.0} for c in ("baseline", ref, cand)]
        return ef.candidate_verdict(recs, learned, ef.DESIGN_SEEDS, ("expert_clean",), ef.LIFT_DESIGN, cand, ref,
                                    "candidate 19", "learned")[1]

    assert block(1, 0, 0)  # one learned pair won, none lost
    assert not block(0, 0, 0)  # no gain: not enough for this rule (DESIGN16's would pass it)
    assert not block(2, 2, 0)
    assert block(3, 1, 1)  # an expert 1 pair down is within the rule
    assert not block(3, 0, 2)  # 2 pairs down on an expert: fails (b), as candidate 19's jitter expert did
