"""Does the corrector do good? Per-correction ablation, candidates, and the shipped default vs
the paper's two readings and `temporal`, on a design and a confirmation seed block (issue #10).

    .venv/bin/python eval/experiments.py efficacy [--stages ablation,design,confirm,lift] [--workers 2]

Stages (each resumable; units on disk are skipped):
- ablation: each Branch A correction alone (the paper's four at full authority, and the options
  beyond the paper) on the clean expert (harm) and on the backbone whose failure it targets,
  LIBERO init states 0-1 of the design block (n = 20 per cell: a screen).
- design: baseline, the candidate default and the paper's readings on init states 0-4 (n = 50).
- confirm: the same configurations on init states 5-9 (n = 50), a block no decision looked at.
- lift: robosuite Lift (and Fetch) grasp-phase noise at sigma 0 and 0.40, seeds 7-26 (design)
  and 100-119 (confirmation): the jerk-degradation ratio with success unchanged.

Outcomes are paired against baseline on the same (task, init state, expert seed): won / lost /
both / neither and the paired difference in success with a 95 % interval (normal approximation
of the mean of per-pair differences in {-1, 0, 1}).
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from lerobot_physvla.core.config import PRESETS, PhysVLAConfig

# Backbones: the scripted expert with one failure mode each (ExpertConfig fields), and the clean one.
BACKBONES = {
    "expert_clean": {},
    "expert_jitter": {"action_noise": 0.3, "aim_noise_m": 0.015},
    "expert_faulty": {"premature_close": 0.3, "place_bias_m": 0.04, "no_decel": True},
    "expert_place_bias": {"place_bias_m": 0.05},
}
OFF = (0.0, 0.0, 0.0, 0.0)

# Each correction alone (the others' authority 0), phys mode.
ALONE = {
    "approach veto (paper, c=1)": PhysVLAConfig(mode="phys", phase_caps=(1.0, 0.0, 0.0, 0.0)),
    "grasp guidance (paper, c=1)": PhysVLAConfig(mode="phys", phase_caps=(0.0, 1.0, 0.0, 0.0)),
    "transport EMA + lift (paper, c=1)": PhysVLAConfig(mode="phys", phase_caps=(0.0, 0.0, 1.0, 0.0)),
    "place deceleration (paper, c=1)": PhysVLAConfig(mode="phys", phase_caps=(0.0, 0.0, 0.0, 1.0)),
    "full veto + height": PhysVLAConfig(mode="phys", phase_caps=OFF, gripper_rule="veto", veto_height_m=0.06),
    "place redirect": PhysVLAConfig(mode="phys", phase_caps=(0.0, 0.0, 0.0, 1.0), place_rule="redirect",
                                    phase_ref="object"),
    "adaptive low-pass": PhysVLAConfig(mode="phys", phase_caps=OFF, lowpass="adaptive"),
}
# which backbones each correction is screened on: the clean expert always (harm), plus its target
TARGETS = {
    "approach veto (paper, c=1)": ("expert_faulty",),
    "grasp guidance (paper, c=1)": ("expert_jitter",),
    "transport EMA + lift (paper, c=1)": ("expert_jitter", "expert_faulty"),
    "place deceleration (paper, c=1)": ("expert_faulty", "expert_place_bias"),
    "full veto + height": ("expert_faulty",),
    "place redirect": ("expert_faulty", "expert_place_bias"),
    "adaptive low-pass": ("expert_jitter",),
}

# The configurations compared on the design and confirmation blocks.
COMPARED = {
    "baseline": PhysVLAConfig(mode="baseline"),
    "default": PRESETS["default"],
    "temporal": PhysVLAConfig(mode="temporal"),
    "paper (eq. 2, c=0.05)": PRESETS["paper"],
    "paper Alg. 1 (c=1)": PRESETS["paper_alg1"],
}
DESIGN_SEEDS, CONFIRM_SEEDS, SCREEN_SEEDS = range(0, 5), range(5, 10), range(0, 2)
LIFT_DESIGN, LIFT_CONFIRM = 7, 100  # first seeds of the Lift / Fetch blocks (20 trials each)


def paired(records, config: str, backbone: str, base: str = "baseline") -> dict:
    """Paired outcomes of `config` against `base` over the (task, seed) pairs both ran."""
    by = {(r["config"], r["task_id"], r["seed"]): r for r in records if r["backbone"] == backbone}
    keys = sorted({(t, s) for c, t, s in by if c == config} & {(t, s) for c, t, s in by if c == base})
    won = lost = both = neither = 0
    d, dj = [], []
    per_task = defaultdict(lambda: [0, 0])
    for t, s in keys:
        a, b = by[(config, t, s)], by[(base, t, s)]
        won += a["success"] and not b["success"]
        lost += b["success"] and not a["success"]
        both += a["success"] and b["success"]
        neither += not (a["success"] or b["success"])
        d.append(int(a["success"]) - int(b["success"]))
        dj.append(a["mean_jerk"] / b["mean_jerk"] if b["mean_jerk"] > 0 else np.nan)
        per_task[t][0] += int(a["success"])
        per_task[t][1] += int(b["success"])
    n = len(d)
    mean = float(np.mean(d)) if n else float("nan")
    half = 1.96 * float(np.std(d, ddof=1)) / np.sqrt(n) if n > 1 else float("nan")
    return {"n": n, "won": won, "lost": lost, "both": both, "neither": neither, "diff": mean,
            "ci": (mean - half, mean + half), "jerk_ratio": float(np.nanmean(dj)) if dj else float("nan"),
            "success": (won + both) / n if n else float("nan"), "base_success": (lost + both) / n if n else float("nan"),
            "task_losses": {t: v[1] - v[0] for t, v in per_task.items() if v[0] < v[1]}}


def paired_row(label: str, p: dict) -> str:
    tl = ", ".join(f"T{t} -{k}" for t, k in sorted(p["task_losses"].items())) or "none"
    return (f"| {label} | {p['n']} | {p['base_success']:.0%} | {p['success']:.0%} | {p['diff'] * 100:+.0f} pp "
            f"[{p['ci'][0] * 100:+.0f}, {p['ci'][1] * 100:+.0f}] | {p['won']} / {p['lost']} / {p['both']} / "
            f"{p['neither']} | {p['jerk_ratio']:.2f} | {tl} |")


PAIRED_HEAD = ["| backbone / configuration | pairs | baseline | this | paired difference [95 % CI] | won / lost / both / "
               "neither | jerk / baseline's | tasks that lost |", "|---|---|---|---|---|---|---|---|"]


def report(out, records, secs, n_units, header, write) -> None:
    """Placeholder until the report is written: prints the paired tables of what ran."""
    lines = header("Efficacy", secs, n_units)
    for b in BACKBONES:
        lines += ["", f"### {b}", *PAIRED_HEAD]
        for c in sorted({r["config"] for r in records if r["backbone"] == b} - {"baseline"}):
            p = paired(records, c, b)
            if p["n"]:
                lines.append(paired_row(c, p))
    write(out, lines, records)
