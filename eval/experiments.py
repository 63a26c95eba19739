"""The paper's experiments on LIBERO-Spatial, re-measured with scripted backbones.

    .venv/bin/python eval/experiments.py table2     [--per-task 5] [--workers 2]
    .venv/bin/python eval/experiments.py ablation   [--per-task 5]
    .venv/bin/python eval/experiments.py place_bias [--pairs 20]

Each writes `eval/results/<experiment>/`: README.md (the table, with this command, how long it
took and on what), records.json (one record per episode) and plots. Sweeps are resumable:
re-running the same command skips the units already written under `units/`.

- table2: backbones x modes (baseline, temporal, phys, phys_el) x the 10 tasks; success with
  95 % Wilson intervals, precision, efficiency, stability, jerk, SPARC; per-task regressions
  against baseline flagged (paper Table 2 / A2 analogue).
- ablation: phys_el with both EL weightings x both gripper rules (+ phys for reference).
- place_bias: matched seeds (same init state, same drawn bias) with and without correction,
  for an expert with a persistent place bias (paper's real-world sim verification).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import BACKBONES, Unit, run_units, seed_blocks  # noqa: E402

from lerobot_physvla import metrics  # noqa: E402
from lerobot_physvla.config import PhysVLAConfig  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
MODES = ("baseline", "temporal", "phys", "phys_el")


def _mean(recs, key):
    vals = [r[key] for r in recs if r[key] is not None and np.isfinite(r[key])]
    return float(np.mean(vals)) if vals else float("nan")


def aggregate(records, keys=("backbone", "config")) -> dict:
    groups = defaultdict(list)
    for r in records:
        groups[tuple(r[k] for k in keys)].append(r)
    out = {}
    for g, recs in groups.items():
        k = sum(r["success"] for r in recs)
        lo, hi = metrics.wilson_interval(k, len(recs))
        out[g] = {
            "n": len(recs), "successes": k, "success": k / len(recs), "ci": (lo, hi),
            **{m: _mean(recs, m) for m in ("precision", "efficiency", "stability", "mean_jerk", "sparc", "ldlj",
                                           "veto_fire_rate", "el_fire_rate")},
            "t_total_us": float(np.median([r["t_us_p50"]["total"] for r in recs])),
        }
    return out


def header(title: str, seconds: float, n_units: int) -> list[str]:
    return [
        f"# {title}\n",
        f"Command: `.venv/bin/python {' '.join(sys.argv)}`  ",
        f"Ran on: {platform.machine()}, {os.cpu_count()} cores, no GPU; LIBERO state-only (no cameras); "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; this invocation took {seconds / 60:.1f} min "
        f"for {n_units} units (units already on disk are not re-run).  ",
        "Backbones are the scripted expert with injected failure modes (eval/harness.py: BACKBONES); "
        "seeds = LIBERO init-state index and expert noise seed, matched across modes. Success is LIBERO's "
        "own check; rates with 95 % Wilson intervals.\n",
    ]


def summary_table(agg: dict, rows: list[tuple]) -> list[str]:
    lines = ["| backbone | mode | n | success [95 % CI] | precision | efficiency | stability | jerk (m/s^3) | SPARC | veto fire | EL fire | corrector p50 (us) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for key in rows:
        a = agg[key]
        lines.append(
            f"| {key[0]} | {key[1]} | {a['n']} | {a['success']:.0%} [{a['ci'][0]:.0%}, {a['ci'][1]:.0%}] | "
            f"{a['precision']:.3f} | {a['efficiency']:.3f} | {a['stability']:.3f} | {a['mean_jerk']:.2f} | "
            f"{a['sparc']:.2f} | {a['veto_fire_rate']:.2f} | {a['el_fire_rate']:.2f} | {a['t_total_us']:.1f} |"
        )
    return lines


def per_task_table(records, backbones, configs, base="baseline") -> tuple[list[str], list[str]]:
    agg = aggregate(records, keys=("backbone", "config", "task_id"))
    tasks = sorted({r["task_id"] for r in records})
    lines = ["| backbone | mode | " + " | ".join(f"T{t}" for t in tasks) + " |", "|---|---|" + "---|" * len(tasks)]
    flags = []
    for b in backbones:
        for c in configs:
            cells = []
            for t in tasks:
                a = agg.get((b, c, t))
                ref = agg.get((b, base, t))
                cell = f"{a['successes']}/{a['n']}" if a else "-"
                if a and ref and c != base and a["successes"] < ref["successes"]:
                    cell += " **(-)**"
                    flags.append(f"{b} / {c} / T{t}: {a['successes']}/{a['n']} vs {base} {ref['successes']}/{ref['n']}")
                elif a and ref and c != base and a["successes"] > ref["successes"]:
                    cell += " (+)"
                cells.append(cell)
            lines.append(f"| {b} | {c} | " + " | ".join(cells) + " |")
    return lines, flags


def plot_success(agg: dict, rows: list[tuple], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    labels = [f"{b}\n{c}" for b, c in rows]
    x = np.arange(len(rows))
    s = np.array([agg[r]["success"] for r in rows])
    lo = np.array([agg[r]["ci"][0] for r in rows])
    hi = np.array([agg[r]["ci"][1] for r in rows])
    axes[0].bar(x, s, yerr=[s - lo, hi - s], capsize=3, color="tab:blue")
    axes[0].set_ylabel("success rate (95 % Wilson CI)")
    axes[1].bar(x, [agg[r]["mean_jerk"] for r in rows], color="tab:orange")
    axes[1].set_ylabel("mean end-effector jerk (m/s^3)")
    for ax in axes:
        ax.set_xticks(x, labels, rotation=60, ha="right", fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write(out: Path, lines: list[str], records: list[dict]) -> None:
    (out / "README.md").write_text("\n".join(lines) + "\n")
    (out / "records.json").write_text(json.dumps(records))
    print("\n".join(lines))
    print(f"\nwrote {out}/README.md, records.json and plots")


def table2(args) -> None:
    out = RESULTS / "table2"
    units = [
        Unit(b, m, PhysVLAConfig(mode=m).to_dict(), t, s, n, BACKBONES[b])
        for b in BACKBONES for m in MODES for t in range(10) for s, n in seed_blocks(args.per_task, args.block)
    ]
    records, secs = run_units(units, out, args.workers)
    agg = aggregate(records)
    rows = [(b, m) for b in BACKBONES for m in MODES]
    pt, flags = per_task_table(records, BACKBONES, MODES)
    plot_success(agg, rows, out / "success_jerk.png", "LIBERO-Spatial, scripted backbones x modes")
    lines = header("Table 2 analogue: backbones x modes on LIBERO-Spatial", secs, len(units))
    lines += ["## Aggregate over the 10 tasks\n", *summary_table(agg, rows), "",
              "## Per task (successes / episodes; (+)/(-) = more / fewer than baseline, same backbone and seeds)\n",
              *pt, "", "## Per-task regressions against baseline\n",
              *([f"- {f}" for f in flags] or ["- none"]), "", "![success and jerk](success_jerk.png)"]
    write(out, lines, records)


ABLATION = {
    "phys (blend)": PhysVLAConfig(mode="phys"),
    "phys (veto)": PhysVLAConfig(mode="phys", gripper_rule="veto"),
    "phys_el joint_diag blend": PhysVLAConfig(mode="phys_el"),
    "phys_el joint_diag veto": PhysVLAConfig(mode="phys_el", gripper_rule="veto"),
    "phys_el task_space blend": PhysVLAConfig(mode="phys_el", weighting="task_space"),
    "phys_el task_space veto": PhysVLAConfig(mode="phys_el", weighting="task_space", gripper_rule="veto"),
    "baseline": PhysVLAConfig(mode="baseline"),
}


def ablation(args) -> None:
    out = RESULTS / "ablation"
    backbones = args.backbones.split(",")
    units = [
        Unit(b, name, cfg.to_dict(), t, s, n, BACKBONES[b])
        for b in backbones for name, cfg in ABLATION.items() for t in range(10)
        for s, n in seed_blocks(args.per_task, args.block)
    ]
    records, secs = run_units(units, out, args.workers)
    agg = aggregate(records)
    rows = [(b, c) for b in backbones for c in ABLATION]
    plot_success(agg, rows, out / "success_jerk.png", "EL weighting x gripper rule")
    pt, flags = per_task_table(records, backbones, list(ABLATION))
    lines = header("Ablation: EL weighting (joint_diag, task_space) x gripper rule (blend, veto)", secs, len(units))
    lines += [*summary_table(agg, rows), "", "## Per task\n", *pt, "", "## Per-task regressions against baseline\n",
              *([f"- {f}" for f in flags] or ["- none"]), "", "![success and jerk](success_jerk.png)"]
    write(out, lines, records)


def place_bias(args) -> None:
    out = RESULTS / "place_bias"
    expert = {"place_bias_m": args.bias_m}
    configs = {"baseline": PhysVLAConfig(mode="baseline"), "phys": PhysVLAConfig(mode="phys"),
               "phys_el": PhysVLAConfig(mode="phys_el")}
    # seed pairs spread over the 10 tasks: pair k runs task k % 10 with seed k
    units = [Unit("expert_place_bias", name, cfg.to_dict(), k % 10, k, 1, expert)
             for name, cfg in configs.items() for k in range(args.pairs)]
    records, secs = run_units(units, out, args.workers)
    by = {(r["config"], r["task_id"], r["seed"]): r for r in records}
    agg = aggregate(records)
    rows = [("expert_place_bias", c) for c in configs]
    lines = header(f"Matched-seed place-bias study (bias direction ~ U(0, 2 pi), size ~ U(0, {args.bias_m} m))",
                   secs, len(units))
    lines += summary_table(agg, rows) + ["", "## Paired outcomes against baseline (same task, init state, drawn bias)\n",
                                         "| mode | both succeed | only corrected | only baseline | both fail | mean jerk change (m/s^3) |",
                                         "|---|---|---|---|---|---|"]
    for c in ("phys", "phys_el"):
        cnt = defaultdict(int)
        dj = []
        for k in range(args.pairs):
            a, b = by[(c, k % 10, k)], by[("baseline", k % 10, k)]
            cnt[(a["success"], b["success"])] += 1
            dj.append(a["mean_jerk"] - b["mean_jerk"])
        lines.append(f"| {c} | {cnt[(True, True)]} | {cnt[(True, False)]} | {cnt[(False, True)]} | "
                     f"{cnt[(False, False)]} | {np.mean(dj):+.3f} |")
    plot_success(agg, rows, out / "success_jerk.png", "place-bias study")
    lines += ["", "![success and jerk](success_jerk.png)"]
    write(out, lines, records)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("experiment", choices=("table2", "ablation", "place_bias"))
    ap.add_argument("--per-task", type=int, default=5, help="episodes per task and cell (seeds 0..N-1)")
    ap.add_argument("--block", type=int, default=5, help="episodes per unit of work")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--backbones", default="expert_jitter,expert_faulty", help="ablation: which backbones")
    ap.add_argument("--pairs", type=int, default=20, help="place_bias: matched seed pairs")
    ap.add_argument("--bias-m", type=float, default=0.05, help="place_bias: maximum bias, m")
    args = ap.parse_args()
    {"table2": table2, "ablation": ablation, "place_bias": place_bias}[args.experiment](args)


if __name__ == "__main__":
    main()
