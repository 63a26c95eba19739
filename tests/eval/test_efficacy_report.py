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


def _lift_cells(first: int, jerk: dict, success: dict | None = None) -> list[dict]:
    """Lift / Fetch records of one block: jerk[(config, sigma)] per cell, every trial a success unless
    success[(config, cell)] says how many of the 20 succeed."""
    recs = []
    for (config, sg), j in jerk.items():
        for sim in ("lift", "fetch"):
            cell = f"{sim} sigma={sg}"
            k = (success or {}).get((config, cell), 20)
            recs += [{"backbone": cell, "config": config, "task_id": 0, "seed": first + i, "success": i < k,
                      "scene": "lift" if sim == "lift" else "fetch_pick_place", "mean_jerk": j} for i in range(20)]
    return recs


def test_lift_ratio_is_baselines_degradation_over_this_ones():
    recs = _lift_cells(100, {("baseline", "0.00"): 2.0, ("baseline", "0.40"): 8.0,  # +300 %
                             (ef.SHIPPED, "0.00"): 2.0, (ef.SHIPPED, "0.40"): 4.0})  # +100 %
    assert ef.lift_ratio(recs, 100, "lift", ef.SHIPPED) == 3.0
    assert ef.lift_ratio(recs, 100, "fetch", "baseline") == 1.0
    assert str(ef.lift_ratio(recs, 120, "lift", ef.SHIPPED)) == "nan"  # no such block
    assert str(ef.lift_ratio(recs, 100, "lift", ef.SMOOTH)) == "nan"  # not run there


def _smooth_block(jitter_jerk: float, lost: dict, lift_jerk: float, lift_lost: int = 0):
    """The smooth preset's blocks: every pair succeeds under baseline and the shipped default; under
    smooth `lost[backbone]` pairs fail; the jitter expert's jerk under smooth is jitter_jerk x baseline's;
    Lift / Fetch at sigma 0.40 degrade +300 % uncorrected and under the default, lift_jerk under smooth."""
    recs, learned = [], []
    names = [*ef.SMOOTH_BACKBONES, "act_single"]
    for b in names:
        for t in range(10):
            for i, s in enumerate(ef.CONFIRM9_SEEDS if b != "act_single" else ef.SMOOTH_SEEDS):
                for config in ("baseline", ef.SHIPPED, ef.SMOOTH):
                    smooth = config == ef.SMOOTH
                    jerk = jitter_jerk if smooth and b.startswith("expert_jitter") else 1.0
                    (learned if b == "act_single" else recs).append(
                        {"backbone": b, "config": config, "task_id": t, "seed": s, "scene": "libero_spatial",
                         "success": not (smooth and t * 5 + i < lost.get(b, 0)), "mean_jerk": jerk})
    recs += _lift_cells(ef.SMOOTH_LIFT, {(c, "0.00"): 1.0 for c in ("baseline", ef.SHIPPED, ef.SMOOTH)}
                        | {("baseline", "0.40"): 4.0, (ef.SHIPPED, "0.40"): 4.0, (ef.SMOOTH, "0.40"): lift_jerk},
                        {(ef.SMOOTH, "lift sigma=0.40"): 20 - lift_lost})
    return ef.smooth_verdict(recs, learned)[1]


def test_the_smooth_presets_rule():
    """SMOOTH_STAGE's rule: (a) the jitter expert's jerk <= 0.5 x baseline's, (b) Lift / Fetch ratio >= 3
    with every cell within 1 of 20 of the shipped default, (c) no backbone but the jitter expert more
    than 1 pair net down against the shipped default; the jitter expert's own losses are the trade."""
    jitter = next(b for b in ef.SMOOTH_BACKBONES if b.startswith("expert_jitter"))
    assert _smooth_block(0.45, {jitter: 5}, 2.0) == {"a": True, "b": True, "c": True}  # ratio 3 / 1 = 3
    assert _smooth_block(0.55, {}, 2.0)["a"] is False
    assert _smooth_block(0.45, {}, 2.5)["b"] is False  # ratio 3 / 1.5 = 2
    assert _smooth_block(0.45, {}, 2.0, lift_lost=2)["b"] is False  # Lift sigma 0.40: 18 vs 20
    assert _smooth_block(0.45, {"act_single": 2}, 2.0)["c"] is False
    assert _smooth_block(0.45, {"expert_clean": 1}, 2.0)["c"] is True


def test_goal_section_says_met_out_of_reach_or_what_was_turned():
    """Section 9: per backbone and confirmation block, the shipped default's paired gain against
    baseline, whether +10 pp with the interval above 0 holds, and if not, section 8c's measurement:
    out of reach (fewer reachable failures than +10 pp needs) or how many of them it turned."""
    recs = []
    draws = f"+{ef.FRESH_DRAWS_18}"
    for t in range(10):
        for i, s in enumerate(ef.CONFIRM7_SEEDS):
            k = t * 5 + i
            # the clean expert fails pairs 0-9 (so they are out of a corrector's reach for the others)
            recs += [{"backbone": "expert_clean", "config": c, "task_id": t, "seed": s, "scene": "libero_spatial",
                      "success": k >= 10, "mean_jerk": 1.0} for c in ("baseline", ef.SHIPPED)]
            # place-bias: baseline fails 0-19, the default turns 10-19 (all reachable): +20 pp, met
            # faulty: baseline fails 0-13, the default turns 10-13: 4 reachable, +10 pp needs 5: out of reach
            # jitter: baseline fails 0-19, the default turns 10-11: 2 of 10 reachable turned
            for b, fails, turned in (("expert_place_bias", 20, range(10, 20)), ("expert_faulty", 14, range(10, 14)),
                                     ("expert_jitter", 20, range(10, 12))):
                recs += [{"backbone": b + draws, "config": "baseline", "task_id": t, "seed": s,
                          "scene": "libero_spatial", "success": k >= fails, "mean_jerk": 2.0},
                         {"backbone": b + draws, "config": ef.SHIPPED, "task_id": t, "seed": s,
                          "scene": "libero_spatial", "success": k >= fails or k in turned, "mean_jerk": 1.0}]
    lines = ef._goal_lines(recs, [])
    rows = {line.split(" | ")[0].lstrip("| "): line for line in lines if line.startswith("| expert_") and "35-39" in line}
    assert "+20 pp [+9, +31] | met |" in rows["expert_place_bias"]
    assert "not met | out of reach: +10 pp needs 5 pairs turned, the block has 4 reachable failures" in rows["expert_faulty"]
    assert "not met | turned 2 of 10 reachable failures, +10 pp needs 5" in rows["expert_jitter"]
    assert any("The clean expert on init states 35-39: +0 pp" in line and ": met." in line for line in lines)
    assert any("x0.50" in line for line in lines if "seed + 5000 draws" in line)  # goal 3: jitter jerk, that block


def test_the_presets_are_the_configurations_that_were_measured():
    """The shipped default and the smooth preset are, field for field, the configurations whose units
    eval/results/efficacy reports under their names (SHIPPED, SMOOTH)."""
    from lerobot_physvla.core.config import PRESETS

    assert PRESETS["default"] == ef.COMPARED[ef.SHIPPED]
    assert PRESETS["smooth"] == ef.COMPARED[ef.SMOOTH]
