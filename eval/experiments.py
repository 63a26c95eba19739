"""The paper's experiments, re-measured with the project's own backbones (state-only, no cameras).

    .venv/bin/python eval/experiments.py table2      [--per-task 5] [--workers 2] [--backend ray]
    .venv/bin/python eval/experiments.py ablation    [--per-task 5]
    .venv/bin/python eval/experiments.py place_bias  [--pairs 20]
    .venv/bin/python eval/experiments.py lift_sweep  [--trials 20]
    .venv/bin/python eval/experiments.py lift_plate  [--pairs 20]
    .venv/bin/python eval/experiments.py fetch_sweep [--trials 20]
    .venv/bin/python eval/experiments.py learned     [--per-task 5] [--checkpoints outputs/train]
    .venv/bin/python eval/experiments.py learned_fixes [--fixes act_chunk,diffusion_chunk]
    .venv/bin/python eval/experiments.py efficacy    [--stages ablation,diagnosis,design,confirm,confirm2,confirm3,confirm3_others,confirm_default,confirm_others,lift,lowpass]

Each writes `eval/results/<experiment>/`: README.md (the table, with this command, how long it
took and on what), records.json (one record per episode) and plots. Sweeps are resumable:
re-running the same command skips the units already written under `units/`.

- table2: backbones x modes (baseline, temporal, phys, phys_el) x the 10 tasks; success with
  95 % Wilson intervals, precision, efficiency, stability, jerk, SPARC; per-task regressions
  against baseline flagged (paper Table 2 / A2 analogue).
- ablation: phys_el with both EL weightings x both gripper rules (+ phys for reference).
- place_bias: matched seeds (same init state, same drawn bias) with and without correction,
  for an expert with a persistent place bias, on LIBERO-Spatial.
- lift_sweep: robosuite Lift, Gaussian x, y action noise of sigma (action units) during the
  grasp phase, sigma in {0 .. 0.40}, seeds 7 + trial; success, reward, jerk and the
  jerk-degradation ratio (paper Table A1).
- lift_plate: Lift + place-on-plate, persistent place-phase x, y action bias of size
  ~ U(0, 1.7) action units, matched seeds 7 + i (paper's real-world sim verification).
- fetch_sweep: the lift_sweep protocol on gymnasium-robotics FetchPickAndPlace (4-D action
  layout, another arm, task_space EL weighting): the corrector is not tied to one simulator.
- learned: the LeRobot ACT / Diffusion backbones trained by policies/train_backbones.py x modes
  x the 10 tasks (Table 2 layout).
- learned_fixes: each defect found in the learned backbones, measured alone: a recipe trained as
  shipped and with the defect put back (`train_backbones.py NAME --raw-env`), uncorrected, paired.
- efficacy: does the corrector do good (eval/efficacy.py): per-correction ablation, the shipped
  default vs baseline vs temporal vs the paper's two readings on a design and a confirmation
  seed block, paired outcomes; Lift / Fetch noise at sigma 0 and 0.40.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import harness  # noqa: E402
from backbones import BACKBONES  # noqa: E402
from harness import BACKENDS, Unit, seed_blocks  # noqa: E402

from lerobot_physvla import metrics  # noqa: E402
from lerobot_physvla.core.config import DEFAULT_PRESET, PRESETS, PhysVLAConfig  # noqa: E402

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


COMPUTE_S = [0.0]  # summed "seconds" of the units of the last run_units call (what header() reports)


def run_units(units, out, workers, backend):
    """harness.run_units, plus the units' summed compute time for the table header."""
    records, secs = harness.run_units(units, out, workers, backend)
    COMPUTE_S[0] = sum(json.loads((Path(out) / "units" / f"{u.key}.json").read_text())["seconds"] for u in units)
    return records, secs


def header(title: str, seconds: float, n_units: int, sim: str = "LIBERO", about: str | None = None) -> list[str]:
    about = about or ("Backbones are the scripted expert with injected failure modes (eval/backbones.py: BACKBONES); "
                      "seeds = LIBERO init-state index and expert noise seed, matched across modes. Success is "
                      "LIBERO's own check; rates with 95 % Wilson intervals.")
    return [
        f"# {title}\n",
        f"Command: `.venv/bin/python {shlex.join(sys.argv)}`  ",
        f"Ran on: {platform.machine()}, {os.cpu_count()} cores, no GPU; {sim} state-only (no cameras); "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; this invocation took {seconds / 60:.1f} min "
        f"for {n_units} units (units already on disk are not re-run); the units' own compute time, summed over "
        f"workers and invocations: {COMPUTE_S[0] / 60:.1f} min.  ",
        about + "\n",
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
            if not any((b, c, t) in agg for t in tasks):  # a mode not run for this backbone
                continue
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


def paired_table(records, pairs: list[tuple[int, int]], modes=("phys", "phys_el")) -> list[str]:
    """Outcomes of each corrected mode against baseline over matched (task_id, seed) pairs."""
    by = {(r["config"], r["task_id"], r["seed"]): r for r in records}
    lines = ["| mode | both succeed | only corrected | only baseline | both fail | mean jerk change (m/s^3) |",
             "|---|---|---|---|---|---|"]
    for c in modes:
        cnt = defaultdict(int)
        dj = []
        for t, k in pairs:
            a, b = by[(c, t, k)], by[("baseline", t, k)]
            cnt[(a["success"], b["success"])] += 1
            dj.append(a["mean_jerk"] - b["mean_jerk"])
        lines.append(f"| {c} | {cnt[(True, True)]} | {cnt[(True, False)]} | {cnt[(False, True)]} | "
                     f"{cnt[(False, False)]} | {np.mean(dj):+.3f} |")
    return lines


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
    records, secs = run_units(units, out, args.workers, args.backend)
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
    records, secs = run_units(units, out, args.workers, args.backend)
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
    records, secs = run_units(units, out, args.workers, args.backend)
    agg = aggregate(records)
    rows = [("expert_place_bias", c) for c in configs]
    lines = header(f"Matched-seed place-bias study (bias direction ~ U(0, 2 pi), size ~ U(0, {args.bias_m} m))",
                   secs, len(units))
    lines += summary_table(agg, rows) + ["", "## Paired outcomes against baseline (same task, init state, drawn bias)\n",
                                         *paired_table(records, [(k % 10, k) for k in range(args.pairs)])]
    plot_success(agg, rows, out / "success_jerk.png", "place-bias study")
    lines += ["", "![success and jerk](success_jerk.png)"]
    write(out, lines, records)


SIGMAS = (0.0, 0.05, 0.10, 0.15, 0.20, 0.30, 0.40)


def noise_sweep(args, scene: str, out: Path, configs: dict, title: str, sim: str) -> None:
    """Grasp-phase x, y action noise sweep (paper Table A1 protocol) on one scene."""
    units = [Unit(f"sigma={sg:.2f}", name, cfg.to_dict(), 0, 7, args.trials,
                  {"action_noise": sg, "noise_stage": "grasp"}, scene=scene)
             for sg in SIGMAS for name, cfg in configs.items()]
    records, secs = run_units(units, out, args.workers, args.backend)
    agg = aggregate(records)
    base = "baseline"
    lines = header(title, secs, len(units), sim, about=(
        f"Backbone: the scripted expert with Gaussian x, y noise of sigma (action units) added to its action while "
        f"within 6 cm of the grasp point before lifting (ExpertConfig noise_stage='grasp'); {args.trials} trials per "
        f"cell, seed = 7 + trial (same scene draw and noise stream in every mode). Success is the env's own check "
        f"at the last step; reward is the env's reward summed over the episode; jerk is the mean end-effector "
        f"jerk (m/s^3, metrics.mean_jerk); success rates with 95 % Wilson intervals."))
    head = "| sigma | " + " | ".join(f"success {c}" for c in configs) + " | " + \
        " | ".join(f"reward {c}" for c in configs) + " | " + " | ".join(f"jerk {c}" for c in configs) + " |"
    lines += ["## Per noise level\n", head, "|---|" + "---|" * (3 * len(configs))]
    for sg in SIGMAS:
        b = f"sigma={sg:.2f}"
        row = [f"{agg[(b, c)]['successes']}/{agg[(b, c)]['n']}" for c in configs]
        row += [f"{_mean(_sel(records, b, c), 'reward'):.2f}" for c in configs]
        row += [f"{agg[(b, c)]['mean_jerk']:.2f}" for c in configs]
        lines.append(f"| {sg:.2f} | " + " | ".join(row) + " |")
    lines += ["", "## Jerk degradation from sigma = 0 to sigma = 0.40\n",
              "| mode | jerk at 0 | jerk at 0.40 | degradation | baseline degradation / this mode's |", "|---|---|---|---|---|"]
    deg = {}
    for c in configs:
        j0, j1 = agg[("sigma=0.00", c)]["mean_jerk"], agg[("sigma=0.40", c)]["mean_jerk"]
        deg[c] = (j1 - j0) / j0
    for c in configs:
        ratio = deg[base] / deg[c] if deg[c] > 0 else float("inf")
        lines.append(f"| {c} | {agg[('sigma=0.00', c)]['mean_jerk']:.2f} | {agg[('sigma=0.40', c)]['mean_jerk']:.2f} | "
                     f"{deg[c]:+.0%} | {ratio:.2f} |")
    pooled = aggregate([dict(r, backbone="all sigmas") for r in records])
    lines += ["", "## Pooled over the noise levels (n = 7 x trials per mode)\n",
              *summary_table(pooled, [("all sigmas", c) for c in configs]), "",
              "Paper (Table A1, n = 10 per cell): jerk +175 % (baseline) vs +17 % (PhysVLA), ratio ~10x; success "
              "100 % everywhere.", "", "![sweep](sweep.png)"]
    _plot_sweep(agg, records, configs, out / "sweep.png", title)
    write(out, lines, records)


def _sel(records, backbone, config):
    return [r for r in records if r["backbone"] == backbone and r["config"] == config]


def _plot_sweep(agg, records, configs, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for c in configs:
        keys = [(f"sigma={sg:.2f}", c) for sg in SIGMAS]
        s = np.array([agg[k]["success"] for k in keys])
        lo = np.array([agg[k]["ci"][0] for k in keys])
        hi = np.array([agg[k]["ci"][1] for k in keys])
        axes[0].errorbar(SIGMAS, s, yerr=[s - lo, hi - s], marker="o", capsize=3, label=c)
        axes[1].plot(SIGMAS, [_mean(_sel(records, *k), "reward") for k in keys], marker="o", label=c)
        axes[2].plot(SIGMAS, [agg[k]["mean_jerk"] for k in keys], marker="o", label=c)
    for ax, lab in zip(axes, ("success (95 % CI)", "episode reward", "mean jerk (m/s^3)")):
        ax.set_xlabel("grasp-phase noise sigma (action units)")
        ax.set_ylabel(lab)
        ax.legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def lift_sweep(args) -> None:
    configs = {"baseline": PhysVLAConfig(mode="baseline"), "phys": PhysVLAConfig(mode="phys"),
               "phys_el": PhysVLAConfig(mode="phys_el")}
    noise_sweep(args, "lift", RESULTS / "lift_sweep", configs, "Robosuite Lift noise sweep (paper Table A1)",
                "robosuite 1.4 Lift (Panda, OSC_POSE, 20 Hz, 250 steps)")


def fetch_sweep(args) -> None:
    # joint_diag needs one joint weight per action entry (7 = 7 on the Panda); Fetch has 7 arm joints
    # and a 4-D action, so the EL blend is weighted in task space.
    configs = {"baseline": PhysVLAConfig(mode="baseline", layout="fetch_4d"),
               "phys": PhysVLAConfig(mode="phys", layout="fetch_4d"),
               "phys_el": PhysVLAConfig(mode="phys_el", layout="fetch_4d", weighting="task_space")}
    noise_sweep(args, "fetch_pick_place", RESULTS / "fetch_sweep", configs,
                "Cross-simulator: FetchPickAndPlace noise sweep (4-D actions, Fetch arm)",
                "gymnasium-robotics FetchPickAndPlace-v4 (mocap-driven Fetch, 25 Hz)")


def lift_plate(args) -> None:
    out = RESULTS / "lift_plate"
    expert = {"place_bias_units": args.bias_units}
    configs = {"baseline": PhysVLAConfig(mode="baseline"), "phys": PhysVLAConfig(mode="phys"),
               "phys_el": PhysVLAConfig(mode="phys_el")}
    units = [Unit("expert_place_bias", name, cfg.to_dict(), 0, 7, args.pairs, expert, scene="lift_plate")
             for name, cfg in configs.items()]
    records, secs = run_units(units, out, args.workers, args.backend)
    agg = aggregate(records)
    rows = [("expert_place_bias", c) for c in configs]
    lines = header(f"Lift + place-on-plate, matched seeds, persistent place bias ~ U(0, {args.bias_units}) action units",
                   secs, len(units), "robosuite 1.4 Lift + plate check (lerobot_physvla/sim/lift_sim.py)", about=(
                       "Backbone: the scripted expert with a persistent x, y action bias during place (direction ~ "
                       f"U(0, 2 pi), size ~ U(0, {args.bias_units}) action units, drawn per seed, identical across modes); seeds "
                       "7 .. 7 + pairs - 1. Success: cube at rest on the 4.5 cm plate disk, gripper open, 5 steps."))
    lines += summary_table(agg, rows) + ["", "## Paired outcomes against baseline (same seed: same cube, same bias)\n",
                                         *paired_table(records, [(0, k) for k in range(7, 7 + args.pairs)])]
    lines += ["", "Paper (n = 20 pairs): baseline 35 %, PhysVLA 95 %.", "", "![success and jerk](success_jerk.png)"]
    plot_success(agg, rows, out / "success_jerk.png", "Lift + place-on-plate, place bias")
    write(out, lines, records)


def _train_backbones():
    """policies/train_backbones.py (the recipes, their checkpoints and weak siblings)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "policies"))
    import train_backbones

    return train_backbones


def _checkpoints(names: list[str], root: str, fix: str) -> dict[str, Path]:
    """Each learned backbone's checkpoint directory; one clear error naming the missing ones."""
    ckpts = {n: _train_backbones().trained_or_committed(n, root) for n in names}
    missing = [n for n, c in ckpts.items() if not (c / "model.safetensors").exists()]
    if missing:
        raise SystemExit(f"experiments: no checkpoint for {missing} under {root}; {fix}")
    return ckpts


def learned(args) -> None:
    train_backbones = _train_backbones()
    out = RESULTS / "learned"
    names = [n for n in args.learned.split(",")]
    ckpts = {n: train_backbones.trained_or_committed(n, args.checkpoints) for n in names}
    absent = [n for n in names if not (ckpts[n] / "model.safetensors").exists()]
    if absent and not args.learned_on_disk:
        raise SystemExit(f"experiments: no checkpoint for {absent} under {args.checkpoints}; run "
                         "policies/record_dataset.py then policies/train_backbones.py, or pass --learned-on-disk to "
                         "report their units on disk as they are")
    modes = [m for m in MODES if m in args.modes.split(",")]
    weak_modes = [m for m in modes if m in (args.weak_modes or args.modes).split(",")]
    presets = [p for p in args.presets.split(",") if p]  # the shipped default beside the paper's modes
    unknown = [p for p in presets if p not in PRESETS]
    if unknown:
        raise SystemExit(f"experiments: unknown preset(s) {unknown}; choose from {', '.join(PRESETS)}")
    import efficacy as ef

    # a preset's units carry the name the efficacy stages give its configuration (the shipped default
    # is one of the candidates there), so a preset whose configuration changed never reuses the units
    # its former self ran, and the learned table and the efficacy report share them
    named = [next((k for k, c in ef.COMPARED.items() if k != "baseline" and c == PRESETS[p]), p) for p in presets]
    configs = {**{m: PhysVLAConfig(mode=m) for m in modes}, **{k: PRESETS[p] for k, p in zip(named, presets)}}
    weak = {*train_backbones.SIBLINGS, *train_backbones.CONTINUED}
    modes_of = {n: [*(weak_modes if n in weak else modes), *named] for n in names}
    units = [
        Unit(n, m, configs[m].to_dict(), t, s, k, policy=str(ckpts[n].resolve()))
        for n in names for m in modes_of[n] for t in range(10) for s, k in seed_blocks(args.per_task, args.block)
    ]
    records, secs = run_units([u for u in units if u.backbone not in absent], out, args.workers, args.backend)
    # a backbone whose checkpoint is not here (--learned-on-disk): its units on disk, as they are
    records += _present([u for u in units if u.backbone in absent], out)[0]
    (out / "recipes").mkdir(exist_ok=True)
    provenance = []
    for n in names:  # the lerobot-train command, seed, device and training time of each checkpoint
        recipe = ckpts[n] / "recipe.json"
        if not recipe.exists():
            recipe = out / "recipes" / f"{n}.json"  # as the run that trained it saved it
        elif recipe != out / "recipes" / f"{n}.json":
            (out / "recipes" / f"{n}.json").write_text(recipe.read_text())
        if recipe.exists():
            r = json.loads(recipe.read_text())
            ds = r.get("dataset", {})
            cont = f" (continues {Path(r['continues']['checkpoint']).name})" if "continues" in r else ""
            provenance.append(f"| {n} | {r['recipe']}{cont} | {r.get('checkpoint', 'last')} of {r.get('steps', '?')} | "
                              f"{r.get('device', 'CPU')} | {r['train_seconds'] / 60:.1f} | "
                              f"{ds.get('episodes', '?')} episodes, {ds.get('frames', '?')} frames | "
                              f"`{str(r.get('commit', '?'))[:7]}` |")
    agg = aggregate(records)
    rows = [(n, m) for n in names for m in modes_of[n] if (n, m) in agg]  # a cell with no units is left out
    pt, flags = per_task_table(records, names, list(configs))
    plot_success(agg, rows, out / "success_jerk.png", "LIBERO-Spatial, learned backbones x modes")
    lines = header("Learned backbones (LeRobot ACT / Diffusion, state inputs) x modes on LIBERO-Spatial", secs,
                   len(units), about=(
                       "Backbones: LeRobot policies trained with lerobot-train by policies/train_backbones.py (each "
                       "one's command, seed, device and training time: recipes/<name>.json; `_weak` = an earlier "
                       "checkpoint of the same run; `_mid` = the weak sibling in the 30-50 % band, trained on this CPU "
                       "(a `_weak` checkpoint trained further, the recipe run whole, or for act_chunk_mid2 the recipe run "
                       "whole on 81 of the 431 demonstrations, its step-2400 checkpoint), chosen on init states 5-9 in "
                       "eval/results/learned_mid) on "
                       "scripted-expert demonstrations (clean expert labels, DART "
                       "noise 0.1 and 0.3 on the executed x, y actions, successful episodes only) from init states "
                       "10-39 (policies/record_dataset.py); evaluated on init states 0 .. per-task - 1, which no "
                       "training or checkpoint choice used. Success is LIBERO's own check; rates with 95 % Wilson "
                       "intervals." + "".join(f" Preset `{p}` runs as `{k}` (its name in eval/efficacy.py)." for p, k in
                                              zip(presets, named) if k != p)))
    if provenance:
        lines += ["## Checkpoints\n", "| backbone | recipe | checkpoint (step) | trained on | minutes | data | commit |",
                  "|---|---|---|---|---|---|---|", *provenance, ""]

    paired = [ef.paired_row(f"{n} / {m}", ef.paired(records, m, n)) for n, m in rows if m != "baseline"]
    left_out = [f"{n} / {m}" for n in names for m in modes_of[n] if (n, m) not in agg]
    if left_out:
        lines += [f"Not run, no checkpoint here (--learned-on-disk) and no units on disk: {', '.join(left_out)}.\n"]
    lines += ["## Aggregate over the 10 tasks\n", *summary_table(agg, rows), "",
              "## Paired outcomes against baseline (same backbone, same init state)\n", *ef.PAIRED_HEAD, *paired, "",
              "## Per task (successes / episodes; (+)/(-) = more / fewer than baseline, same backbone and seeds)\n",
              *pt, "", "## Per-task regressions against baseline\n",
              *([f"- {f}" for f in flags] or ["- none"]), "", "![success and jerk](success_jerk.png)"]
    write(out, lines, records)


def learned_fixes(args) -> None:
    """Each defect of the learned backbones measured alone: the same recipe, data, steps and seed
    trained with the defect and without it; uncorrected success on the same init states, paired."""
    import efficacy as ef

    out = RESULTS / "learned_fixes"
    out.mkdir(parents=True, exist_ok=True)
    fixed = args.fixes.split(",")
    defects = {n: n + _train_backbones().RAW_ENV for n in fixed}  # observation.environment_state left raw
    names = [*fixed, *defects.values()]
    ckpts = _checkpoints(names, args.checkpoints,
                         "train them with policies/train_backbones.py NAME (and --raw-env for the defect)")
    units = [Unit(n, "baseline", PhysVLAConfig(mode="baseline").to_dict(), t, s, k, policy=str(ckpts[n].resolve()))
             for n in names for t in range(10) for s, k in seed_blocks(args.per_task, args.block)]
    # the units are the learned experiment's (same key, same weights): shared, run once
    records, secs = run_units(units, RESULTS / "learned", args.workers, args.backend)
    rows = []
    for n, d in defects.items():
        recs = ([dict(r, config="fixed") for r in records if r["backbone"] == n]
                + [dict(r, backbone=n, config="defect") for r in records if r["backbone"] == d])
        rows.append(ef.paired_row(f"{n}: environment_state normalised / left raw", ef.paired(recs, "fixed", n,
                                                                                             base="defect")))
    lines = header("Defects of the learned backbones, each measured alone (uncorrected success)", secs, len(units),
                   about=("Each row: one recipe of policies/train_backbones.py trained twice on the same dataset, "
                          "steps and seed, once as shipped and once with the defect put back "
                          "(`train_backbones.py NAME --raw-env`: no ENV entry in --policy.normalization_mapping, so "
                          "lerobot 0.6.1 leaves observation.environment_state -- object and target xyz, metres -- "
                          "un-normalised); both evaluated uncorrected on the same LIBERO-Spatial init states 0 .. "
                          "per-task - 1 of the 10 tasks. `baseline` = with the defect, `this` = without."))
    lines += ["| recipe | pairs | baseline | this | paired difference [95 % CI] | won / lost / both / neither | "
              "jerk / baseline's | tasks that lost |", "|---|---|---|---|---|---|---|---|", *rows]
    write(out, lines, records)


# the recipes' runs on this CPU: <recipe><suffix>@<step> names a checkpoint under <checkpoints>/<dir>
CPU_RUNS = {"_cpu": "cpu",  # train_backbones.py act_single --steps 8000 (act_chunk: 6000) --out outputs/train/cpu
            "_cpufull": "cpu_full"}  # train_backbones.py act_single --out outputs/train/cpu_full (all 20000 steps)


def learned_checkpoints(args) -> None:
    """Uncorrected success of chosen checkpoints on one block of init states (default 5-9, which the
    learned table does not use): how a recipe's success grows with its steps, and whether a run of
    the same recipe on this CPU matches the GPU run the learned table uses. `--ckpts` entries are
    `<run>@<step>`: `<run>` a recipe's directory under --checkpoints, or a run of it on this CPU
    (CPU_RUNS)."""
    cands: dict[str, Path] = {}
    for entry in args.ckpts.split(","):
        run, _, step = entry.partition("@")
        if not step.isdigit():
            raise SystemExit(f"experiments: --ckpts entry {entry!r} is not <run>@<step>")
        here = next((sub for suffix, sub in CPU_RUNS.items() if run.endswith(suffix)), None)
        d = Path(args.checkpoints) / (f"{here}/{run.rsplit('_', 1)[0]}" if here else run)
        c = d / "checkpoints" / f"{int(step):06d}" / "pretrained_model"
        if not (c / "model.safetensors").exists():
            raise SystemExit(f"experiments: no checkpoint {c}; train it with policies/train_backbones.py")
        cands[f"{run}@{int(step):06d}"] = c
    first = args.first_seed
    units = [Unit(n, "baseline", PhysVLAConfig(mode="baseline").to_dict(), t, first, args.per_task,
                  policy=str(c.resolve())) for n, c in cands.items() for t in range(10)]
    out = RESULTS / "learned_checkpoints"
    records, secs = run_units(units, out, args.workers, args.backend)
    agg = aggregate(records)
    rows = []
    for n, c in cands.items():
        a = agg[(n, "baseline")]
        r = json.loads((c / "recipe.json").read_text()) if (c / "recipe.json").exists() else {}
        where = "GPU" if "cuda" in r.get("device", "") else "CPU"
        recipe = r.get("recipe", n.split("@")[0]).removesuffix("_weak")
        rows.append(f"| {recipe} | {where}: {r.get('device', '?')} | {r.get('steps', '?')} | {int(n.split('@')[1])} | {a['successes']} / {a['n']} | {100 * a['success']:.0f}% "
                    f"[{100 * a['ci'][0]:.0f}, {100 * a['ci'][1]:.0f}] | {a['mean_jerk']:.1f} |")
    lines = header(f"Learned checkpoints, uncorrected, on init states {first}-{first + args.per_task - 1}", secs,
                   len(units), about=(
                       "Each row: one checkpoint of a policies/train_backbones.py recipe (lerobot-train command, seed "
                       "and device in its recipe.json), evaluated uncorrected on LIBERO-Spatial init states "
                       f"{first}-{first + args.per_task - 1} of the 10 tasks (n = {10 * args.per_task}). The GPU runs are "
                       "the ones eval/results/learned uses (their step-4000 / 2400 checkpoints are the weak siblings); "
                       "the CPU runs are the same recipes, data and seed run on this machine (`--policy.device=cpu`): "
                       "act_single for 8000 and for all 20000 steps, act_chunk for 6000. On the CPU a run is "
                       "deterministic (see below); the GPU run of the same recipe and seed follows other numerics."))
    lines += ["| recipe | trained on | steps of the run | checkpoint (step) | successes | success [95 % Wilson] | "
              "mean jerk (m/s^3) |", "|---|---|---|---|---|---|---|", *rows, ""]
    # the same step of two runs of one recipe: equal weights = the run (and an early stop) is reproducible
    runs_of = defaultdict(list)  # (recipe, step) -> the CPU runs (<checkpoints>/<dir>/<recipe>) that saved it
    for w in sorted(Path(args.checkpoints).glob("*/*/checkpoints/[0-9]*/pretrained_model/model.safetensors")):
        runs_of[(w.parts[-5], int(w.parts[-3]))].append(w.parent)
    same = [f"- {recipe} step {step}: the `{a.parts[-5]}` and `{b.parts[-5]}` runs (same recipe, data, seed; CPU) hold "
            f"{'identical' if harness.policy_fingerprint(a) == harness.policy_fingerprint(b) else 'different'} "
            "weights (sha256)" for (recipe, step), (a, *rest) in runs_of.items() for b in rest]
    lines += ["Reproducibility of the CPU runs:", "", *(same or ["- no two CPU runs share a checkpoint step"])]
    write(out, lines, records)


def learned_mid(args) -> None:
    """The `_mid` weak siblings (policies/train_backbones.py CONTINUED, CPU_DRAW): every candidate
    checkpoint, uncorrected, on init states 5-9 (which the learned table does not use), and the one
    the rule written before this ran keeps: success closest to 40 %, ties to the earlier step; then each
    kept sibling in the 30-50 % band under the shipped default on the same init states, paired."""
    tb = _train_backbones()
    first, out = args.first_seed, RESULTS / "learned_mid"
    cands: dict[str, tuple[str, Path]] = {}
    for name in args.learned.split(","):
        if name not in tb.MID_SIBLINGS:
            raise SystemExit(f"experiments: {name!r} is no `_mid` sibling; choose from {', '.join(tb.MID_SIBLINGS)}")
        found = tb.mid_candidates(name, args.checkpoints)
        if not found:
            raise SystemExit(f"experiments: no candidate checkpoint of {name} under {args.checkpoints}; run "
                             f"policies/train_backbones.py {name}")
        cands |= {k: (name, p) for k, p in found.items()}
    units = [Unit(n, "baseline", PhysVLAConfig(mode="baseline").to_dict(), t, first, args.per_task,
                  policy=str(c.resolve())) for n, (_, c) in cands.items() for t in range(10)]
    records, secs = run_units(units, out, args.workers, args.backend)
    agg = aggregate(records)
    rows, chosen = [], {}
    for name in dict.fromkeys(v[0] for v in cands.values()):
        mine = {n: c for n, (m, c) in cands.items() if m == name}
        chosen[name] = tb.choose_mid({n: agg[(n, "baseline")]["success"] for n in mine})
        for n, c in mine.items():
            a = agg[(n, "baseline")]
            r = json.loads((c / "recipe.json").read_text()) if (c / "recipe.json").exists() else {}
            how = (f"continues {Path(r['continues']['checkpoint']).name} (GPU)" if "continues" in r
                   else f"the whole run resumed from {Path(r['resumes']['checkpoint']).parent.name}" if "resumes" in r
                   else f"{r.get('recipe', '?')} run whole" + (
                       f" on {r['dataset']['episodes']} of {r['dataset']['of_episodes']} episodes"
                       if "of_episodes" in r.get("dataset", {}) else ""))
            rows.append(f"| {name} | `{n}` | {how} | {int(n.rsplit('@', 1)[1])} of {r.get('steps', '?')} | "
                        f"{a['successes']} / {a['n']} | {100 * a['success']:.0f}% [{100 * a['ci'][0]:.0f}, "
                        f"{100 * a['ci'][1]:.0f}] | {a['mean_jerk']:.1f} | {r.get('device', '?')}, "
                        f"{r.get('train_seconds', 0) / 60:.1f} min | `{harness.policy_fingerprint(c)[:8]}` | "
                        f"{'kept' if n == chosen[name] else ''} |")
    lines = header(f"Weak siblings in the 30-50 % band: candidate checkpoints, uncorrected, on init states {first}-"
                   f"{first + args.per_task - 1}", secs, len(units), about=(
                       "Candidates of each `_mid` sibling (policies/train_backbones.py CONTINUED, CPU_DRAW): its "
                       "committed GPU first checkpoint trained further on this CPU (lerobot-train --policy.path=<it>, "
                       "a fresh AdamW at the recipe's learning rate, batch 32, seed 1000), every saved step; for "
                       "act_single, the recipe run whole on this CPU (another draw of the same recipe, data and seed), its "
                       "final checkpoint; for act_chunk_mid2 (a second round, after act_chunk_mid's kept checkpoint "
                       "landed at 16 % on init states 0-4), every checkpoint of act_chunk run whole on this CPU and, a third "
                       "round after those tied at 12 % and 68 % (none in the band), that run resumed from its step 7200 "
                       "(lerobot-train --resume) saving every 400 steps, and, a fourth round after those went 18, 2, 4, 4, 62 % "
                       "(the release skill switches on within 400 updates), every checkpoint of two smaller chunked ACTs "
                       "(act_chunk's recipe with dim_model 64 / feedforward 256, and 32 / 128 with 2 heads: "
                       "train_backbones.py SMALLER) run whole on this CPU, and, a fifth round after those landed at 0-22 %, the "
                       "final checkpoints of two more widths between them and act_chunk's 128 (96 and 112), and, a sixth round after "
                       "those landed at 6 % and 68 %, the 112-wide run's earlier checkpoints, and, a seventh round after "
                       "those went 14, 0, 56, 66 %, the 112-wide run resumed from its step 4800 saving every 400 steps "
                       "(train_backbones.py RESUMED), and, an eighth round after those went 4, 8, 0, 0, 6 %, every "
                       "checkpoint of act_chunk's recipe trained on fewer demonstrations (the first 5 or 10 recorded "
                       "episodes of each task and noise level, 81 and 161 of 431: train_backbones.py FEWER). "
                       f"Each ran uncorrected on init states {first}-{first + args.per_task - 1} of the 10 tasks (n = "
                       f"{10 * args.per_task}); the learned table reports the kept one on init states 0-4. Rule, "
                       "written before any of them ran: keep the candidate whose success here lies closest to 40 %, "
                       "ties to the earlier step."))
    lines += ["| sibling | candidate | how | step of its run | successes | success [95 % Wilson] | mean jerk (m/s^3) | "
              "trained on, minutes (whole run) | weights (sha256) | |", "|---|---|---|---|---|---|---|---|---|---|",
              *rows, "", "Kept (policies/train_backbones.py MID_CHOICE names those in the 30-50 % band): " +
              ", ".join(f"{n}: `{c}`" + ("" if 0.30 <= agg[(c, "baseline")]["success"] <= 0.50 else
                                          f" ({100 * agg[(c, 'baseline')]['success']:.0f} %: outside the band, no sibling)")
                        for n, c in chosen.items())]
    # the kept siblings in the band under the shipped default, on the same init states, paired
    import efficacy as ef

    kept = {n: c for n, c in chosen.items() if 0.30 <= agg[(c, "baseline")]["success"] <= 0.50}
    shipped = PRESETS[DEFAULT_PRESET]
    named = next((k for k, c in ef.COMPARED.items() if k != "baseline" and c == shipped), DEFAULT_PRESET)
    more = [Unit(c, named, shipped.to_dict(), t, first, args.per_task, policy=str(cands[c][1].resolve()))
            for c in kept.values() for t in range(10)]
    if more:
        extra, secs2 = run_units(more, out, args.workers, args.backend)
        records = records + extra
        lines += ["", f"## The kept siblings under the shipped default (`{DEFAULT_PRESET}`, `{named}`), same init states",
                  "", "Paired against the same checkpoint uncorrected on the same (task, init state); this block "
                  "chose the checkpoint by its uncorrected success, not the default.", "", *ef.PAIRED_HEAD,
                  *(ef.paired_row(f"{n} (`{c}`) / {named}", ef.paired(records, named, c)) for n, c in kept.items()),
                  "", f"{len(more)} units; their own compute time: {COMPUTE_S[0] / 60:.1f} min (this invocation: "
                  f"{secs2 / 60:.1f} min)."]
    write(out, lines, records)


EFFICACY_STAGES = ("ablation,diagnosis,design,confirm,confirm2,confirm3,confirm3_others,confirm_default,confirm_others,"
                   "lift,lowpass,design3,confirm4,design5,confirm5,design6,confirm6,design7,confirm7,learned,learned_confirm,"
                   "learned_phys,learned_phys_confirm,design9,learned9,learned9_confirm,confirm9,design10,learned10,"
                   "learned10_confirm,confirm10,learned11,learned11_confirm,design12,learned12,confirm12,"
                   "learned12_confirm,design13,learned13,confirm13,learned13_confirm,design14,learned14,confirm14,"
                   "learned14_confirm,design15,learned15,confirm15,learned15_confirm,design16,learned16,confirm16,learned16_confirm,"
                   "design17,learned17,confirm17,learned17_confirm,confirm18,learned18_confirm,learned18_baseline,"
                   "design19,learned19,confirm19,learned19_confirm,confirm20,learned20_confirm,learned20_baseline,smooth,learned_smooth,paper_modes,"
                   "learned_paper_modes")
EXPERTS = "expert_clean,expert_jitter,expert_faulty,expert_place_bias"
# the efficacy stages whose units run learned backbones (_learned_units)
LEARNED_STAGES = {"learned", "learned_confirm", "learned_phys", "learned_phys_confirm", "learned9", "learned9_confirm",
                  "learned10", "learned10_confirm", "learned11", "learned11_confirm", "learned12",
                  "learned12_confirm", "learned13", "learned13_confirm", "learned14", "learned14_confirm",
                  "learned15", "learned15_confirm", "learned16", "learned16_confirm", "learned17", "learned17_confirm",
                  "learned18_confirm", "learned18_baseline", "learned19", "learned19_confirm",
                  "learned20_confirm", "learned20_baseline", "learned_smooth",
                  "learned_paper_modes"}
LEARNED = ("act_single,act_single_weak,act_single_mid,act_chunk,act_chunk_weak,act_chunk_mid,act_chunk_mid2,"
           "diffusion_chunk")


def _lowpass_choice(n: int) -> str | None:
    """What DESIGN13's rule chooses from the design units on disk of low-pass candidate n (13: among
    its two variants; 14: its one), or None (none meets the rule, or a cell is missing)."""
    import efficacy as ef

    records, _, _ = _present(_efficacy_units([f"design{n}"], EXPERTS.split(",")), RESULTS / "efficacy")
    names = LEARNED.split(",")
    learned, _, _ = _present(_learned_units([f"learned{n}"], names, {b: Path("policies/checkpoints") / b for b in names}),
                             RESULTS / "learned")
    return ef.lowpass_choice(records, learned, ef.LOWPASS_CANDIDATES[n][0])


def _assist_passed(n: int) -> bool:
    """Whether assist candidate n (eval/efficacy.py ASSIST_CANDIDATES) passes its rule on the design units
    on disk (False: fails, or a cell is missing)."""
    import efficacy as ef

    cand, ref, _, need_gain = ef.ASSIST_CANDIDATES[n]
    records, _, _ = _present(_efficacy_units([f"design{n}"], EXPERTS.split(",")), RESULTS / "efficacy")
    names = LEARNED.split(",")
    learned, _, _ = _present(_learned_units([f"learned{n}"], names, {b: Path("policies/checkpoints") / b for b in names}),
                             RESULTS / "learned")
    _, ok = ef.candidate_verdict(records, learned, ef.DESIGN_SEEDS, tuple(ef.BACKBONES), ef.LIFT_DESIGN, cand, ref,
                                 f"candidate {n}", need_gain)
    return ok is not None and bool(ok)  # a numpy bool where every cell is there


def _lowpass_confirm_configs(n: int) -> dict:
    """Baseline, candidate 12 and what the design seeds chose of low-pass candidate n (none before they
    chose: then the confirmation stages hold the references only, and `efficacy` refuses to run them)."""
    import efficacy as ef

    chosen = _lowpass_choice(n)
    return {name: ef.COMPARED[name] for name in ("baseline", ef.CANDIDATE_12, *([chosen] if chosen else []))}


def _efficacy_units(stages: list[str], experts: list[str]) -> list:
    """The scripted backbones' units (LIBERO, Lift, Fetch) of the efficacy stages named."""
    import efficacy as ef

    units = []
    if "ablation" in stages:
        units += [Unit(b, name, ef.ALONE[name].to_dict(), t, s, 1, ef.BACKBONES[b])
                  for name in ef.ALONE for b in ("expert_clean", *ef.TARGETS[name])
                  for t in range(10) for s in ef.SCREEN_SEEDS]
        units += [Unit(b, "baseline", ef.COMPARED["baseline"].to_dict(), t, s, 1, ef.BACKBONES[b])
                  for b in ef.BACKBONES for t in range(10) for s in ef.SCREEN_SEEDS]
    if "diagnosis" in stages:
        units += [Unit("expert_jitter", name, cfg.to_dict(), t, s, 1, ef.BACKBONES["expert_jitter"])
                  for name, cfg in [(n, ef.ALONE[n]) for n in ef.DIAGNOSIS] + [("baseline", ef.COMPARED["baseline"])]
                  for t in range(10) for s in ef.DESIGN_SEEDS]
    shipped = {k: ef.COMPARED[k] for k in ("baseline", ef.DEFAULT_V2)}  # ran on 5-9 while v2 shipped
    others = {k: v for k, v in ef.COMPARED.items() if k in ("temporal", "paper (eq. 2, c=0.05)", "paper Alg. 1 (c=1)")}
    for stage, seeds, configs in (("design", ef.DESIGN_SEEDS, ef.DESIGN), ("confirm", ef.CONFIRM_SEEDS, ef.CONFIRM),
                                  ("confirm2", ef.CONFIRM2_SEEDS, ef.CONFIRM2),
                                  ("confirm3", ef.CONFIRM3_SEEDS, ef.CONFIRM3),
                                  ("confirm_default", ef.CONFIRM_SEEDS, shipped),
                                  ("confirm_others", ef.CONFIRM_SEEDS, others),
                                  ("confirm3_others", ef.CONFIRM3_SEEDS, others),
                                  ("design3", ef.DESIGN_SEEDS, ef.DESIGN3),
                                  ("confirm4", ef.CONFIRM4_SEEDS, ef.CONFIRM4),
                                  ("design5", ef.DESIGN_SEEDS, ef.DESIGN5),
                                  ("confirm5", ef.CONFIRM5_SEEDS, ef.CONFIRM5),
                                  ("design6", ef.DESIGN_SEEDS, ef.DESIGN6),
                                  ("confirm6", ef.CONFIRM6_SEEDS, ef.CONFIRM6),
                                  ("design7", ef.DESIGN_SEEDS, ef.DESIGN7),
                                  ("design9", ef.DESIGN_SEEDS, ef.DESIGN9),
                                  ("design10", ef.DESIGN_SEEDS, ef.DESIGN10),
                                  ("design12", ef.DESIGN_SEEDS, ef.DESIGN12),
                                  ("design13", ef.DESIGN_SEEDS, ef.DESIGN13),
                                  ("design14", ef.DESIGN_SEEDS, ef.DESIGN14),
                                  *((f"design{n}", ef.DESIGN_SEEDS, configs)  # the assist candidates
                                    for n, (_, _, configs, _) in ef.ASSIST_CANDIDATES.items()),
                                  ("confirm7", ef.CONFIRM7_SEEDS, ef.CONFIRM7)):
        if stage in stages:
            units += [Unit(b, name, cfg.to_dict(), t, s, 1, ef.BACKBONES[b]) for name, cfg in configs.items()
                      for b in experts for t in range(10) for s in seeds]
    for stage, configs in (("confirm9", ef.CONFIRM9), ("confirm10", ef.DESIGN10)):
        if stage in stages:  # init states 35-39, fresh failure draws (ef.CONFIRM9_BACKBONES)
            units += [Unit(b, name, cfg.to_dict(), t, s, 1, ef.CONFIRM9_BACKBONES[b]) for name, cfg in configs.items()
                      for b in ef.CONFIRM9_BACKBONES for t in range(10) for s in ef.CONFIRM9_SEEDS]
    if "confirm12" in stages:  # init states 35-39, fresh failure draws seed + 2000 (ef.CONFIRM12_BACKBONES)
        units += [Unit(b, name, cfg.to_dict(), t, s, 1, ef.CONFIRM12_BACKBONES[b]) for name, cfg in ef.DESIGN12.items()
                  for b in ef.CONFIRM12_BACKBONES for t in range(10) for s in ef.CONFIRM9_SEEDS]
    for n, (_, fresh) in ef.LOWPASS_CANDIDATES.items():  # what candidate n's design seeds chose, init states
        if f"confirm{n}" in stages:  # 35-39 with fresh failure draws (13: seed + 3000, 14: seed + 4000)
            units += [Unit(b, name, cfg.to_dict(), t, s, 1, fresh[b]) for name, cfg in _lowpass_confirm_configs(n).items()
                      for b in fresh for t in range(10) for s in ef.CONFIRM9_SEEDS]
    for n, (_, _, configs, _) in ef.ASSIST_CANDIDATES.items():
        fresh = ef.ASSIST_CONFIRM[n][0]  # init states 35-39, fresh failure draws (15-17: seed + 4000, 19: + 6000)
        if f"confirm{n}" in stages:
            units += [Unit(b, name, cfg.to_dict(), t, s, 1, fresh[b]) for name, cfg in configs.items()
                      for b in fresh for t in range(10) for s in ef.CONFIRM9_SEEDS]
    for n, (configs, _) in ef.FRESH_STAGES.items():  # init states 35-39, fresh draws (18: seed + 5000, 20: + 6000)
        fresh = ef.FRESH_BLOCKS[n][3]
        if f"confirm{n}" in stages:
            units += [Unit(b, name, cfg.to_dict(), t, s, 1, fresh[b]) for name, cfg in configs.items()
                      for b in fresh for t in range(10) for s in ef.CONFIRM9_SEEDS]
    for stage, configs in (("smooth", ef.SMOOTH_STAGE), ("paper_modes", ef.PAPER_MODES)):
        if stage in stages:  # init states 35-39, seed + 6000 draws (ef.SMOOTH_BACKBONES)
            units += [Unit(b, name, cfg.to_dict(), t, s, 1, ef.SMOOTH_BACKBONES[b]) for name, cfg in configs.items()
                      for b in ef.SMOOTH_BACKBONES for t in range(10) for s in ef.CONFIRM9_SEEDS]
    lift_stages = {"lift": ((ef.LIFT_DESIGN, ef.LIFT_CONFIRM), {k: ef.COMPARED[k] for k in ef.LIFT_CONFIGS}),
                   "design7": ((ef.LIFT_DESIGN,), ef.DESIGN7), "confirm7": ((ef.LIFT_CONFIRM,), ef.CONFIRM7),
                   "design9": ((ef.LIFT_DESIGN,), ef.DESIGN9), "design10": ((ef.LIFT_DESIGN,), ef.DESIGN10),
                   "confirm10": ((ef.LIFT_CONFIRM,), ef.DESIGN10), "design12": ((ef.LIFT_DESIGN,), ef.DESIGN12),
                   "confirm12": ((ef.LIFT_CONFIRM,), ef.DESIGN12), "design13": ((ef.LIFT_DESIGN,), ef.DESIGN13),
                   "design14": ((ef.LIFT_DESIGN,), ef.DESIGN14), "smooth": ((ef.SMOOTH_LIFT,), ef.SMOOTH_STAGE),
                   "paper_modes": ((ef.SMOOTH_LIFT,), ef.PAPER_MODES),
                   **{f"confirm{n}": ((ef.FRESH_BLOCKS[n][6],), configs) for n, (configs, _) in ef.FRESH_STAGES.items()},
                   **{f"{stage}{n}": ((first,), configs) for n, (_, _, configs, _) in ef.ASSIST_CANDIDATES.items()
                      for stage, first in (("design", ef.LIFT_DESIGN), ("confirm", ef.ASSIST_CONFIRM[n][2]))}}
    for n in ef.LOWPASS_CANDIDATES:
        if f"confirm{n}" in stages:
            lift_stages[f"confirm{n}"] = ((ef.LIFT_CONFIRM,), _lowpass_confirm_configs(n))
    for stage, (blocks, lift_cfgs) in lift_stages.items():
        if stage not in stages:
            continue
        for first in blocks:
            for sg in (0.0, 0.40):
                expert = {"action_noise": sg, "noise_stage": "grasp"}
                units += [Unit(f"lift sigma={sg:.2f}", name, cfg.to_dict(), 0, first, 20, expert, scene="lift")
                          for name, cfg in lift_cfgs.items()]
                units += [Unit(f"fetch sigma={sg:.2f}", name, cfg.replace(layout="fetch_4d", weighting="task_space")
                               .to_dict(), 0, first, 20, expert, scene="fetch_pick_place")
                          for name, cfg in lift_cfgs.items()]
            units += [Unit("lift_plate bias<=1.7", name, cfg.to_dict(), 0, first, 20, {"place_bias_units": 1.7},
                           scene="lift_plate") for name, cfg in lift_cfgs.items()]
    if "lowpass" in stages:  # the low-pass's strength on the design seeds (Fetch: every alpha; Lift: 0.8)
        for sg in (0.0, 0.40):
            expert = {"action_noise": sg, "noise_stage": "grasp"}
            for am in ef.LOWPASS_ALPHAS:
                cfg = ef.COMPARED[ef.CANDIDATE_1].replace(lowpass_alpha_max=am)
                units.append(Unit(f"fetch sigma={sg:.2f}", f"default, alpha_max={am}", cfg.replace(
                    layout="fetch_4d", weighting="task_space").to_dict(), 0, ef.LIFT_DESIGN, 20, expert,
                    scene="fetch_pick_place"))
                if am == 0.8:
                    units.append(Unit(f"lift sigma={sg:.2f}", f"default, alpha_max={am}", cfg.to_dict(), 0,
                                      ef.LIFT_DESIGN, 20, expert, scene="lift"))
    return list(dict.fromkeys(units))  # the screen's baselines are also design units


def _learned_units(stages: list[str], names: list[str], ckpts: dict[str, Path]) -> list:
    """The learned backbones' units of the efficacy stages in LEARNED_STAGES."""
    import efficacy as ef

    blocks = []
    if "learned" in stages:  # the default, the candidates (and, on LEARNED_SCREENED, the default's
        # rules one by one), design block 0-4
        blocks.append((ef.DESIGN_SEEDS, names, {"baseline": PhysVLAConfig(mode="baseline"),
                                                ef.DEFAULT_V2: ef.COMPARED[ef.DEFAULT_V2],
                                                **{k: ef.COMPARED[k] for k in ef.LEARNED_CANDIDATES}}))
        blocks.append((ef.DESIGN_SEEDS, [n for n in names if n in ef.LEARNED_SCREENED],
                       {k: ef.ALONE[k] for k in ef.LEARNED_ALONE}))
    if "learned_phys" in stages:  # the paper's capped blend one phase at a time, chunked ACTs, block 0-4
        blocks.append((ef.DESIGN_SEEDS, [n for n in names if n in ef.LEARNED_PHYS_SCREENED], ef.PHYS_PHASES))
    if "learned_phys_confirm" in stages:  # its grasp phase alone on init states 5-9
        blocks.append((ef.CONFIRM_SEEDS, [n for n in names if n in ef.LEARNED_PHYS_SCREENED], ef.LEARNED_PHYS_CONFIRM))
    if "learned9" in stages:  # candidate 9 on every learned backbone, design block 0-4
        blocks.append((ef.DESIGN_SEEDS, names, ef.DESIGN9))
    if "learned9_confirm" in stages:  # and on init states 5-9
        blocks.append((ef.CONFIRM_SEEDS, names, ef.DESIGN9))
    if "learned10" in stages:  # candidate 10 (and the shipped default, its reference), block 0-4
        blocks.append((ef.DESIGN_SEEDS, names, ef.DESIGN10))
    if "learned10_confirm" in stages:  # and on init states 5-9
        blocks.append((ef.CONFIRM_SEEDS, names, ef.DESIGN10))
    if "learned11" in stages:  # candidate 11 (and candidate 10, its reference) on the chunked ACTs, 0-4
        blocks.append((ef.DESIGN_SEEDS, [n for n in names if n in ef.LEARNED_CHUNKED], ef.DESIGN11))
    if "learned11_confirm" in stages:  # and on init states 10-14
        blocks.append((ef.CONFIRM11_SEEDS, [n for n in names if n in ef.LEARNED_CHUNKED], ef.DESIGN11))
    if "learned12" in stages:  # candidate 12 (and candidate 10, its reference), every learned ACT, 0-4
        blocks.append((ef.DESIGN_SEEDS, names, ef.DESIGN12))
    if "learned12_confirm" in stages:  # and on init states 10-14
        blocks.append((ef.CONFIRM11_SEEDS, names, ef.DESIGN12))
    for n, design in ((13, ef.DESIGN13), (14, ef.DESIGN14)):  # the low-pass candidates (and candidate 12,
        if f"learned{n}" in stages:  # their reference), every learned ACT, 0-4
            blocks.append((ef.DESIGN_SEEDS, names, design))
        if f"learned{n}_confirm" in stages:  # what the design seeds chose, on init states 10-14
            blocks.append((ef.CONFIRM11_SEEDS, names, _lowpass_confirm_configs(n)))
    for n, (_, _, configs, _) in ef.ASSIST_CANDIDATES.items():  # the assist candidates (and their references)
        if f"learned{n}" in stages:  # every learned ACT, 0-4
            blocks.append((ef.DESIGN_SEEDS, names, configs))
        if f"learned{n}_confirm" in stages:  # and on their confirmation block (15-17: 10-14, 19: 20-24)
            blocks.append((ef.ASSIST_CONFIRM[n][1], names, configs))
    for n, (_, configs) in ef.FRESH_STAGES.items():  # candidates 18 and 20 and their references on fresh init
        seeds = ef.FRESH_BLOCKS[n][5]  # states (18: 15-19, 20: 20-24); their baseline there after the verdict
        if f"learned{n}_confirm" in stages:
            blocks.append((seeds, names, configs))
        if f"learned{n}_baseline" in stages:
            blocks.append((seeds, names, ef.LEARNED18_BASELINE))
    for stage, configs in (("learned_smooth", ef.SMOOTH_STAGE), ("learned_paper_modes", ef.PAPER_MODES)):
        if stage in stages:  # the smooth preset, then the paper's modes, on the learned ACTs, init states 20-24
            blocks.append((ef.SMOOTH_SEEDS, names, configs))
    if "learned_confirm" in stages:  # candidates on init states 5-9 (on the backbones LEARNED_CONFIRM names)
        for name, only in ef.LEARNED_CONFIRM.items():
            blocks.append((ef.CONFIRM_SEEDS, [n for n in names if only is None or n in only],
                           {name: ef.COMPARED[name]}))
    return [Unit(n, name, cfg.to_dict(), t, seeds.start, len(seeds), policy=str(ckpts[n].resolve()))
            for seeds, bbs, configs in blocks for n in bbs for name, cfg in configs.items() for t in range(10)]


def _present(units: list, out: Path) -> tuple[list[dict], float, int]:
    """Records and summed compute seconds of the units on disk (missing ones are left out), and how many."""
    payloads = [json.loads(f.read_text()) for u in units if (f := out / "units" / f"{u.key}.json").exists()]
    return [r for p in payloads for r in p["records"]], sum(p["seconds"] for p in payloads), len(payloads)


def efficacy(args) -> None:
    """Runs the units of the stages named (units on disk are skipped), then writes the report from
    every stage's units on disk, whichever invocation ran them: running one stage never drops the
    others' sections from eval/results/efficacy/README.md."""
    import efficacy as ef

    out = RESULTS / "efficacy"
    stages, every = args.stages.split(","), EFFICACY_STAGES.split(",")
    unknown = [s for s in stages if s not in every]
    if unknown:
        raise SystemExit(f"experiments: unknown efficacy stage(s) {unknown}; choose from {EFFICACY_STAGES}")
    experts = args.experts.split(",")
    unknown = [b for b in experts if b not in ef.BACKBONES]
    if unknown:
        raise SystemExit(f"experiments: unknown expert backbone(s) {unknown}; choose from {', '.join(ef.BACKBONES)}")
    for n in ef.LOWPASS_CANDIDATES:
        if {f"confirm{n}", f"learned{n}_confirm"} & set(stages) and _lowpass_choice(n) is None:
            raise SystemExit(f"experiments: candidate {n} did not meet its rule on the design seeds (or a design{n} / "
                             f"learned{n} cell is missing): its confirmation is not run (eval/efficacy.py DESIGN{n})")
    for n in ef.ASSIST_CANDIDATES:
        if {f"confirm{n}", f"learned{n}_confirm"} & set(stages) and not _assist_passed(n):
            raise SystemExit(f"experiments: candidate {n} did not pass its rule on the design seeds (or a design{n} / "
                             f"learned{n} cell is missing): its confirmation is not run (eval/efficacy.py DESIGN{n})")
    _, secs = run_units(_efficacy_units(stages, experts), out, args.workers, args.backend)
    learned_secs = 0.0
    names = args.learned.split(",")
    if LEARNED_STAGES & set(stages) and not args.learned_on_disk:
        ckpts = _checkpoints(names, args.checkpoints, "run policies/record_dataset.py then policies/train_backbones.py")
        _, learned_secs = run_units(_learned_units(stages, names, ckpts), RESULTS / "learned", args.workers,
                                    args.backend)
    # the report: every stage's units on disk (each unit records the weights' sha256 it ran with)
    shown = list(dict.fromkeys([*LEARNED.split(","), *names]))
    records, compute, n = _present(_efficacy_units(every, list(dict.fromkeys([*EXPERTS.split(","), *experts]))), out)
    lunits = _learned_units(every, shown, {b: Path(args.checkpoints) / b for b in shown})
    learned_records, learned_compute, n_learned = _present(lunits, RESULTS / "learned")
    COMPUTE_S[0] = compute + learned_compute
    ef.report(out, records, secs + learned_secs, n + n_learned, header, write, learned=learned_records)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("experiment", choices=tuple(EXPERIMENTS))
    ap.add_argument("--per-task", type=int, default=5, help="episodes per task and cell (seeds 0..N-1)")
    ap.add_argument("--block", type=int, default=5, help="episodes per unit of work")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--backbones", default="expert_jitter,expert_faulty", help="ablation: which backbones")
    ap.add_argument("--pairs", type=int, default=20, help="place_bias: matched seed pairs")
    ap.add_argument("--bias-m", type=float, default=0.05, help="place_bias: maximum bias, m")
    ap.add_argument("--bias-units", type=float, default=1.7, help="lift_plate: maximum bias, action units")
    ap.add_argument("--trials", type=int, default=20, help="lift_sweep / fetch_sweep: trials per (sigma, mode)")
    ap.add_argument("--checkpoints", default="outputs/train", help="learned: where train_backbones.py wrote")
    ap.add_argument("--fixes", default="act_chunk,diffusion_chunk",
                    help="learned_fixes: recipes trained as shipped and with --raw-env")
    # diffusion_single is left out by default: 10 denoising passes per control step make it ~10x
    # slower to evaluate on this CPU than the others
    ap.add_argument("--learned", default=LEARNED,
                    help="learned: which trained recipes (of policies/train_backbones.py)")
    ap.add_argument("--modes", default=",".join(MODES), help="learned: which of the four modes")
    ap.add_argument("--learned-on-disk", action="store_true",
                    help="efficacy: run no learned unit (no checkpoints needed); the report shows the learned units "
                         "on disk as they are. learned: a backbone whose checkpoint is not here is reported from its "
                         "units on disk")
    ap.add_argument("--ckpts", default="act_single@4000,act_single_cpu@4800,act_single_cpu@6400,act_single_cpu@8000,"
                                       "act_chunk@2400,act_chunk_cpu@2400,act_chunk_cpu@3600,act_chunk_cpu@4800,"
                                       "act_chunk_cpu@6000,act_single@20000,act_single_cpufull@20000",
                    help="learned_checkpoints: <run>@<step> entries (<recipe>_cpu / _cpufull: its runs on this CPU, CPU_RUNS)")
    ap.add_argument("--first-seed", type=int, default=5,
                    help="learned_checkpoints, learned_mid: first init state of the block")
    ap.add_argument("--weak-modes", default=None, help="learned: modes for the weak siblings (default: --modes)")
    ap.add_argument("--presets", default="default",
                    help="learned: presets run beside the modes (core.config.PRESETS; '' for none)")
    ap.add_argument("--stages", default=EFFICACY_STAGES,
                    help="efficacy: which stages to run (the report shows every stage's units on disk)")
    ap.add_argument("--experts", default=EXPERTS,
                    help="efficacy: the scripted backbones (eval/efficacy.py BACKBONES) of the LIBERO stages")
    ap.add_argument("--backend", choices=BACKENDS, default="process",
                    help="process pool (default) or ray (joins $RAY_ADDRESS or starts a local Ray)")
    args = ap.parse_args()
    EXPERIMENTS[args.experiment](args)


EXPERIMENTS = {"table2": table2, "ablation": ablation, "place_bias": place_bias, "lift_sweep": lift_sweep,
               "lift_plate": lift_plate, "fetch_sweep": fetch_sweep, "learned": learned,
               "learned_fixes": learned_fixes, "learned_checkpoints": learned_checkpoints, "learned_mid": learned_mid, "efficacy": efficacy}

if __name__ == "__main__":
    main()
