"""Tables and plots of a study, and its README, written from its episode rows alone.

Each `[[report]]` entry of a study file is one section (SECTIONS below: its `kind`); the README is the
header (the study's title, the command that regenerates it, the commands that ran its episodes, how
many episodes) and the sections in order. Nothing here depends on when or where it runs: the same
rows give the same README byte for byte (tests/eval/test_studies.py regenerates every one).
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

import compare as cmp
from study import ROOT, Study, shown

PAIRED_HEAD = ["| backbone / configuration | pairs | baseline | this | paired difference [95 % CI] | won / lost / both / "
               "neither | jerk / baseline's | tasks that lost |", "|---|---|---|---|---|---|---|---|"]
SUMMARY_HEAD = ["| backbone | configuration | n | success [95 % CI] | precision | efficiency | stability | jerk (m/s^3) | "
                "SPARC | veto fire | EL fire | corrector p50 (us) |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]


class Rows:
    """A study's episode rows, indexed for selection by configuration name, backbone and block."""

    def __init__(self, study: Study, rows: list[dict]):
        self.study = study
        self.by = defaultdict(list)
        for r in rows:
            self.by[(r["backbone"], r["config"], r["scene"])].append(r)
        self.n = len(rows)

    def get(self, config: str, backbone: str, block) -> list[dict]:
        """The episodes of `config` on `backbone` in `block`, sorted by (task, seed)."""
        h = self.study.config_hash(config, block.scene)
        tasks, seeds = set(block.tasks), set(block.seeds)
        rows = [r for r in self.by.get((backbone, h, block.scene), []) if r["task_id"] in tasks and r["seed"] in seeds]
        return sorted(rows, key=lambda r: (r["task_id"], r["seed"]))

    def over(self, config: str, backbone: str, blocks) -> list[dict]:
        return [r for b in blocks if backbone in b.backbones for r in self.get(config, backbone, b)]


def pct(x: float) -> str:
    return f"{x:.0%}"


def pp(p: dict, digits: int = 0) -> str:
    return f"{p['diff'] * 100:+.{digits}f} pp [{p['ci'][0] * 100:+.{digits}f}, {p['ci'][1] * 100:+.{digits}f}]"


def _task(t) -> str:
    """A task of compare.paired's task_losses: "T6", or "libero_goal T6" where the pairs span several scenes."""
    if isinstance(t, str):
        scene, task = t.rsplit("/", 1)
        return f"{scene} T{task}"
    return f"T{t}"


def paired_row(label: str, p: dict) -> str:
    tl = ", ".join(f"{_task(t)} -{k}" for t, k in sorted(p["task_losses"].items())) or "none"
    return (f"| {label} | {p['n']} | {pct(p['base_success'])} | {pct(p['success'])} | {pp(p)} | {p['won']} / {p['lost']} "
            f"/ {p['both']} / {p['neither']} | {p['jerk_ratio']:.2f} | {tl} |")


def summary_row(backbone: str, config: str, a: dict) -> str:
    return (f"| {backbone} | {config} | {a['n']} | {a['success']:.0%} [{a['ci'][0]:.0%}, {a['ci'][1]:.0%}] | "
            f"{a['precision']:.3f} | {a['efficiency']:.3f} | {a['stability']:.3f} | {a['mean_jerk']:.2f} | "
            f"{a['sparc']:.2f} | {a['veto_fire_rate']:.2f} | {a['el_fire_rate']:.2f} | {a['t_total_us']:.1f} |")


def _blocks(study: Study, sec: dict):
    names = sec.get("blocks", [sec["block"]] if "block" in sec else list(study.blocks))
    return [study.blocks[n] for n in names]


def _backbones(study: Study, sec: dict, blocks) -> list[str]:
    if "backbones" in sec:
        return study.expand(sec["backbones"])
    return list(dict.fromkeys(b for bl in blocks for b in bl.backbones))


def _block_label(bl) -> str:
    s = bl.seeds
    return f"{bl.name} ({bl.scene}, seeds {s[0]}-{s[-1]})" if len(s) > 1 else f"{bl.name} ({bl.scene}, seed {s[0]})"


# ---------------------------------------------------------------------------------------------------- sections

def section_text(study, rows, sec, out) -> list[str]:
    return [sec["text"].strip(), ""]


def section_summary(study, rows, sec, out) -> list[str]:
    """Success [95 % Wilson], the paper's metrics and the corrector's time per backbone x configuration;
    optionally per task (with regressions against `against`) and a success / jerk bar plot."""
    blocks = _blocks(study, sec)
    configs = sec["configs"]
    cells = []
    for b in _backbones(study, sec, blocks):
        for c in configs:
            rs = rows.over(c, b, blocks)
            if rs:
                cells.append((b, c, rs))
    lines = [*SUMMARY_HEAD, *(summary_row(b, c, cmp.aggregate(rs)) for b, c, rs in cells), ""]
    if sec.get("per_task"):
        base = sec.get("against", "baseline")
        tasks = sorted({r["task_id"] for _, _, rs in cells for r in rs})
        by = {(b, c): rs for b, c, rs in cells}
        lines += ["Per task: successes / episodes; (+) / (-) = more / fewer than " + base + " (same backbone and seeds)\n",
                  "| backbone | configuration | " + " | ".join(f"T{t}" for t in tasks) + " |",
                  "|---|---|" + "---|" * len(tasks)]
        flags = []
        for b, c, rs in cells:
            cols = []
            for t in tasks:
                a = [r for r in rs if r["task_id"] == t]
                ref = [r for r in by.get((b, base), []) if r["task_id"] == t]
                cell = f"{sum(r['success'] for r in a)}/{len(a)}" if a else "-"
                # (+) / (-) on the pairs both ran: a configuration may have run blocks `base` did not
                p = cmp.paired(a, ref)
                k, kr, n = p["won"] + p["both"], p["lost"] + p["both"], p["n"]
                if n and c != base and k < kr:
                    cell += " **(-)**"
                    flags.append(f"{b} / {c} / T{t}: {k}/{n} vs {base} {kr}/{n}")
                elif n and c != base and k > kr:
                    cell += " (+)"
                cols.append(cell)
            lines.append(f"| {b} | {c} | " + " | ".join(cols) + " |")
        lines += ["", f"Per-task regressions against {base}:\n", *([f"- {f}" for f in flags] or ["- none"]), ""]
    if sec.get("plot"):
        _plot_bars(cells, out / sec["plot"], sec.get("plot_title", study.title))
        lines += [f"![success and jerk]({sec['plot']})", ""]
    return lines


def section_paired(study, rows, sec, out) -> list[str]:
    """Each configuration against `against` on the same (task, seed) pairs, per backbone and block;
    `pool`: one more row per configuration pooling the backbones named."""
    blocks = _blocks(study, sec)
    against = sec.get("against", "baseline")
    lines = list(PAIRED_HEAD)
    several = len(blocks) > 1
    for bl in blocks:
        for c in sec["configs"]:
            found = []
            for b in _backbones(study, sec, [bl]):
                if b not in bl.backbones:
                    continue
                this, base = rows.get(c, b, bl), rows.get(against, b, bl)
                p = cmp.paired(this, base)
                if p["n"]:
                    found.append((b, p))
                    label = f"{b} / {c}" + (f" vs {against}" if against != "baseline" else "")
                    lines.append(paired_row(label + (f" ({bl.name})" if several else ""), p))
            if sec.get("pool") and found:
                pool_names = set(study.expand(sec["pool"]))
                pool = cmp.pooled([p for b, p in found if b in pool_names])
                if pool["n"]:
                    lines.append(f"| pooled ({sec['pool']}) / {c}" + (f" ({bl.name})" if several else "") +
                                 f" | {pool['n']} | | | {pp(pool, 1)} | {pool['won']} / {pool['lost']} / | | |")
    return lines + [""]


def section_paired_backbones(study, rows, sec, out) -> list[str]:
    """One configuration, two backbones paired on the same (task, seed): `pairs` = [[this, base, label], ...]."""
    blocks = _blocks(study, sec)
    c = sec.get("config", "baseline")
    lines = ["| pair | pairs | base | this | paired difference [95 % CI] | won / lost / both / neither | jerk / base's | "
             "tasks that lost |", "|---|---|---|---|---|---|---|---|"]
    for this, base, label in sec["pairs"]:
        p = cmp.paired(rows.over(c, this, blocks), rows.over(c, base, blocks))
        lines.append(paired_row(label, p))
    return lines + [""]


def section_sweep(study, rows, sec, out) -> list[str]:
    """A noise sweep (paper Table A1): per noise level (a backbone each) success, reward and jerk of each
    configuration; the jerk degradation from the first level to the last; a plot."""
    bl = study.blocks[sec["block"]]
    configs, levels = sec["configs"], list(bl.backbones)
    cell = {(b, c): rows.get(c, b, bl) for b in levels for c in configs}
    lines = ["| noise | " + " | ".join(f"success {c}" for c in configs) + " | " + " | ".join(f"reward {c}" for c in configs)
             + " | " + " | ".join(f"jerk {c}" for c in configs) + " |", "|---|" + "---|" * (3 * len(configs))]
    for b in levels:
        aggs = [cmp.aggregate(cell[(b, c)]) for c in configs]
        lines.append(f"| {b} | " + " | ".join(f"{a['successes']}/{a['n']}" for a in aggs) + " | "
                     + " | ".join(f"{a['reward']:.2f}" for a in aggs) + " | " + " | ".join(f"{a['mean_jerk']:.2f}" for a in aggs)
                     + " |")
    base = sec.get("against", "baseline")
    deg = {c: cmp.degradation(cell[(levels[0], c)], cell[(levels[-1], c)]) for c in configs}
    lines += ["", f"Jerk degradation from {levels[0]} to {levels[-1]}:\n",
              f"| configuration | jerk at {levels[0]} | jerk at {levels[-1]} | degradation | {base}'s degradation / this one's |",
              "|---|---|---|---|---|"]
    for c in configs:
        a0, a1 = cmp.aggregate(cell[(levels[0], c)]), cmp.aggregate(cell[(levels[-1], c)])
        lines.append(f"| {c} | {a0['mean_jerk']:.2f} | {a1['mean_jerk']:.2f} | {deg[c]:+.0%} | "
                     f"{cmp.degradation_ratio(deg[base], deg[c]):.2f} |")
    lines += ["", "Pooled over the noise levels:\n", *SUMMARY_HEAD,
              *(summary_row("all levels", c, cmp.aggregate([r for b in levels for r in cell[(b, c)]])) for c in configs), ""]
    if sec.get("plot"):
        _plot_sweep(cell, levels, configs, out / sec["plot"], sec.get("plot_title", study.title))
        lines += [f"![sweep]({sec['plot']})", ""]
    return lines


def section_noise_cells(study, rows, sec, out) -> list[str]:
    """Two noise cells (noise-free and noisy backbones) per block: successes, jerk, the degradation and
    baseline's degradation over each configuration's."""
    lines = ["| block | configuration | success (noise-free) | success (noisy) | jerk (noise-free) | jerk (noisy) | "
             "degradation | baseline's degradation / this one's |", "|---|---|---|---|---|---|---|---|"]
    for bl in _blocks(study, sec):
        zero, noisy = bl.backbones
        deg = {}
        for c in ["baseline", *[c for c in sec["configs"] if c != "baseline"]]:
            a, b = rows.get(c, zero, bl), rows.get(c, noisy, bl)
            if not a or not b:
                continue
            deg[c] = cmp.degradation(a, b)
            if "baseline" not in deg:
                break
            a0, a1 = cmp.aggregate(a), cmp.aggregate(b)
            lines.append(f"| {bl.name} ({zero} / {noisy}, seeds {bl.seeds[0]}-{bl.seeds[-1]}) | {c} | "
                         f"{a0['successes']}/{a0['n']} | {a1['successes']}/{a1['n']} | {a0['mean_jerk']:.2f} | "
                         f"{a1['mean_jerk']:.2f} | {deg[c]:+.0%} | {cmp.degradation_ratio(deg['baseline'], deg[c]):.2f} |")
    return lines + [""]


def section_compares(study, rows, sec, out) -> list[str]:
    """Every [[compare]] of the study (or those named): the candidate against baseline and its reference on
    each role's blocks, the rule's checks evaluated on them, and what was decided."""
    names = sec.get("names")
    lines = []
    for c in study.compares:
        if names and c.name not in names:
            continue
        lines += compare_lines(study, rows, c)
    return lines


def compare_lines(study, rows, c) -> list[str]:
    lines = [f"### {c.name}\n"]
    link = f" ([decision record]({_rel(study, c.decision)}))" if c.decision else ""
    lines.append(f"Candidate `{c.candidate}` against `{c.reference}`" + (f" and `{c.baseline}`" if c.reference != c.baseline
                                                                         else "") + (f". Outcome: **{c.outcome}**" if c.outcome else "") + f"{link}.\n")
    if c.about:
        lines += [c.about.strip(), ""]
    for role, names in c.blocks.items():
        if not names:
            continue
        blocks = [study.blocks[n] for n in names]
        lines += [f"{role.capitalize()} blocks: " + "; ".join(_block_label(b) for b in blocks) + ".\n",
                  PAIRED_HEAD[0].replace("| baseline |", "| the other |").replace("/ baseline's", "/ the other's"),
                  PAIRED_HEAD[1]]
        cells, order = rule_cells(study, rows, c, blocks)
        for b in order:
            for other in dict.fromkeys([c.baseline, c.reference]):
                key = "baseline" if other == c.baseline else "reference"
                p = cmp.paired(cells[b].get("candidate", []), cells[b].get(key, []))
                if p["n"]:
                    lines.append(paired_row(f"{b} / candidate vs {other}", p))
        lines.append("")
        if c.competent:
            lines += [f"Competent-policy check dropped: {c.competent}", ""]
        if c.checks:
            lines += ["| check | measured | holds |", "|---|---|---|"]
            results = []
            for chk in c.checks:
                ok, what = cmp.evaluate(chk, cells, order)
                results.append(ok)
                desc = chk.label or f"{chk.metric} vs {chk.against} {chk.bounds_text()}"
                lines.append(f"| {desc} | {what} | {'-' if ok is None else 'yes' if ok else 'no'} |")
            verdict = cmp.combine(results)
            recorded = c.verdicts.get(role)
            rec = "" if recorded is None else f" (recorded when decided: {'pass' if recorded else 'fail'})"
            unrun = [n for n, bl in zip(names, blocks)
                     if not any(rows.get(k, b, bl) for b in bl.backbones for k in (c.candidate, c.baseline))]
            gap = f" Not run: {', '.join(unrun)} (no episode); the verdict reads the blocks that ran." if unrun else ""
            lines += ["", f"Rule on the {role} blocks: **{'incomplete' if verdict is None else 'pass' if verdict else 'fail'}**"
                      f"{rec}.{gap}", ""]
    return lines


def rule_cells(study, rows, c, blocks) -> tuple[dict, list[str]]:
    """{backbone: {"candidate" | "reference" | "baseline": rows}} over the blocks, and the backbones in order."""
    cells, order = defaultdict(dict), []
    for bl in blocks:
        for b in bl.backbones:
            order.append(b)
            for key, name in (("candidate", c.candidate), ("reference", c.reference), ("baseline", c.baseline)):
                cells[b].setdefault(key, []).extend(rows.get(name, b, bl))
            cells[b]["n"] = cells[b].get("n", 0) + len(bl.tasks) * len(bl.seeds)
    return cells, list(dict.fromkeys(order))


def compare_verdict(study, rows, c, role: str) -> bool | None:
    """What a compare's rule gives on one role's blocks (None: a cell is missing)."""
    cells, order = rule_cells(study, rows, c, [study.blocks[n] for n in c.blocks[role]])
    return cmp.combine([cmp.evaluate(chk, cells, order)[0] for chk in c.checks])


def section_scatter(study, rows, sec, out) -> list[str]:
    """Success against mean jerk, one panel per backbone, one point per configuration with episodes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    blocks = _blocks(study, sec)
    panels = [(b, bl) for bl in blocks for b in bl.backbones]
    cols = min(6, len(panels))
    nrow = -(-len(panels) // cols)
    fig, axes = plt.subplots(nrow, cols, figsize=(3.1 * cols, 2.9 * nrow + 0.6), squeeze=False)
    for ax, (b, bl) in zip(axes.flat, panels):
        for j, c in enumerate(sec["configs"]):
            rs = rows.get(c, b, bl)
            if rs:
                ax.scatter(np.mean([r["mean_jerk"] for r in rs]), np.mean([r["success"] for r in rs]), s=40,
                           marker="os^v*DPX"[j % 8], color=f"C{j}", label=c)
        ax.set_title(b, fontsize=9)
        ax.set_ylim(-0.03, 1.03)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    axes.flat[0].set_ylabel("success rate", fontsize=8)
    axes.flat[0].set_xlabel("mean end-effector jerk (m/s^3)", fontsize=8)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=8, loc="lower center", ncol=min(len(labels), 4))
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    fig.savefig(out / sec["plot"], dpi=100)
    plt.close(fig)
    return [f"![success against jerk]({sec['plot']})", ""]


def section_provenance(study, rows, sec, out) -> list[str]:
    """The learned backbones' checkpoints: recipe, step, device, training time, data, commit (recipes/*.json
    beside the results, as each training run saved it)."""
    import json

    lines = ["| backbone | recipe | checkpoint (step) | trained on | minutes | data | commit |", "|---|---|---|---|---|---|---|"]
    for n in study.expand(sec["backbones"]):
        f = out / "recipes" / f"{n}.json"
        if not f.exists():
            continue
        r = json.loads(f.read_text())
        ds = r.get("dataset", {})
        cont = f" (continues {Path(r['continues']['checkpoint']).name})" if "continues" in r else ""
        lines.append(f"| {n} | {r['recipe']}{cont} | {r.get('checkpoint', 'last')} of {r.get('steps', '?')} | "
                     f"{r.get('device', 'CPU')} | {r['train_seconds'] / 60:.1f} | {ds.get('episodes', '?')} episodes, "
                     f"{ds.get('frames', '?')} frames | `{str(r.get('commit', '?'))[:7]}` |")
    return lines + [""]


def section_error_sweep(study, rows, sec, out) -> list[str]:
    """Success against perception error: per backbone, axis (bias, noise, ...) and level, the paired gain over
    baseline of the configuration told the error and of the one not told, beside the exact-state configuration's
    (`exact`); `kept` = the told gain over the exact one; a plot of the gains against the error per backbone."""
    bl = study.blocks[sec["block"]]
    base, exact = sec.get("against", "baseline"), sec["exact"]
    told_s, untold_s = sec.get("labels", ["told", "not told"])  # what the two columns of configurations are
    head = [f"| backbone | fault | level | {told_s}: gain [95 % CI] | won / lost | kept | {untold_s}: gain [95 % CI] | "
            f"won / lost | pass-throughs ({told_s}) |", "|---|---|---|---|---|---|---|---|---|"]
    lines, curves = [], {}
    for b in bl.backbones:
        ref = cmp.paired(rows.get(exact, b, bl), rows.get(base, b, bl))
        if not ref["n"]:
            continue
        lines += [f"**{b}**: baseline {pct(ref['base_success'])}, exact state {pct(ref['success'])}, gain "
                  f"{pp(ref)} ({ref['won']} / {ref['lost']}, n = {ref['n']}).", "", *head]
        for ax, spec in sec["axes"].items():
            pts = []
            for level, told, untold in zip(spec["levels"], spec["told"], spec["not_told"]):
                t = cmp.paired(rows.get(told, b, bl), rows.get(base, b, bl))
                u = cmp.paired(rows.get(untold, b, bl), rows.get(base, b, bl)) if untold else None
                kept = t["diff"] / ref["diff"] if t["n"] and ref["diff"] > 0 else float("nan")
                through = _passthroughs(rows.get(told, b, bl))
                t_gain, t_wl = (pp(t), f"{t['won']} / {t['lost']}") if t["n"] else ("-", "-")
                u_gain, u_wl = (pp(u), f"{u['won']} / {u['lost']}") if u and u["n"] else ("-", "-")
                kept_s = "-" if kept != kept else f"{kept:.2f}"
                lines.append(f"| {b} | {ax} | {level:g} | {t_gain} | {t_wl} | {kept_s} | {u_gain} | {u_wl} | {through} |")
                pts.append((level, t, u))
            curves[(b, ax)] = (ref, pts)
        lines.append("")
    if sec.get("plot") and curves:
        _plot_error_sweep(curves, [b for b in bl.backbones if any(k[0] == b for k in curves)], list(sec["axes"]),
                          out / sec["plot"], sec.get("plot_title", study.title), (told_s, untold_s))
        lines += [f"![{PLOT_ALT['error_sweep']}]({sec['plot']})", ""]
    return lines


def section_tasks(study, rows, sec, out) -> list[str]:
    """One row per task of the blocks: whether the corrector modelled it or passed every action through
    (unsupported_goal on every step of every episode), and each configuration's successes per backbone, with the
    pairs that changed against the first configuration; then how many tasks were modelled and passed through."""
    blocks = _blocks(study, sec)
    configs = sec["configs"]
    first, rest = configs[0], configs[1:]
    lines = ["| backbone | task | corrector | " + " | ".join(configs) + " | " +
             " | ".join(f"{c}: pairs changed" for c in rest) + " |",
             "|---|---|---|" + "---|" * (len(configs) + len(rest))]
    counts = defaultdict(set)
    for b in _backbones(study, sec, blocks):
        for bl in blocks:
            if b not in bl.backbones:
                continue
            for t in bl.tasks:
                got = {c: [r for r in rows.get(c, b, bl) if r["task_id"] == t] for c in configs}
                corrected = [r for c in rest for r in got[c]]
                if not corrected:
                    continue
                through = all(r.get("passthrough", {}).get("unsupported_goal", 0) >= r["steps"] for r in corrected)
                counts["passed through" if through else "modelled"].add((bl.scene, t))
                name = f"T{t}"
                if bl.scene == "metaworld":
                    from lerobot_physvla.sim.metaworld_sim import ALL_TASKS

                    name = f"{t} {ALL_TASKS[t]}"
                cells = [f"{sum(r['success'] for r in got[c])}/{len(got[c])}" if got[c] else "-" for c in configs]
                changed = []
                for c in rest:
                    p = cmp.paired(got[c], got[first]) if got[c] and got[first] else None
                    changed.append(f"{p['won']} won / {p['lost']} lost" if p and p["n"] else "-")
                lines.append(f"| {b} | {name} | {'passed through' if through else 'modelled'} | " + " | ".join(cells)
                             + " | " + " | ".join(changed) + " |")
    lines += ["", f"Tasks modelled: {len(counts['modelled'])}; passed through (unsupported_goal on every step): "
              f"{len(counts['passed through'])}.", ""]
    return lines


def section_intervention(study, rows, sec, out) -> list[str]:
    """Whether the policy or the corrector did the task: per cell (`cells`: label -> block names, pooled), backbone
    and configuration, success against `against` on the same pairs, then how much the corrector did over those
    episodes: the fraction of steps whose executed action differs from the policy's, and the mean norm of that
    change beside the mean norm of the policy's action (action units; harness.run_episode). A cell that ran no
    `against` episodes (a design block of candidate against reference) is paired against the first of `configs`
    that it ran, and its rows say so ("(against X)")."""
    against = sec.get("against", "baseline")
    lines = [f"| cell | backbone / configuration | pairs | {against} | this | paired difference [95 % CI] | "
             "won / lost | steps changed | mean change | mean action | change / action |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for label, names in sec["cells"].items():
        blocks = [study.blocks[n] for n in names]
        for b in _backbones(study, sec, blocks):
            ran = [c for c in sec["configs"] if rows.over(c, b, blocks)]
            ref = against if against in ran or not ran else ran[0]
            note = "" if ref == against else f" (against {ref})"
            for c in sec["configs"]:
                this, base = rows.over(c, b, blocks), rows.over(ref, b, blocks)
                p = cmp.paired(this, base)
                if not p["n"]:
                    continue
                a = cmp.aggregate(this)
                ratio = a["change_norm"] / a["action_norm"] if a["action_norm"] > 0 else float("nan")
                lines.append(f"| {label} | {b} / {c}{note} | {p['n']} | {pct(p['base_success'])} | {pct(p['success'])} | "
                             f"{pp(p)} | {p['won']} / {p['lost']} | {a['changed_fraction']:.1%} | "
                             f"{a['change_norm']:.3f} | {a['action_norm']:.3f} | {ratio:.2f} |")
    return lines + [""]


def _passthroughs(rs: list[dict]) -> str:
    """The corrector's pass-through reasons summed over episodes (`-` for none)."""
    total = defaultdict(int)
    for r in rs:
        for k, v in r.get("passthrough", {}).items():
            total[k] += v
    return ", ".join(f"{k} {v}" for k, v in sorted(total.items())) or "-"


SECTIONS = {"text": section_text, "summary": section_summary, "paired": section_paired,
            "paired_backbones": section_paired_backbones, "sweep": section_sweep, "noise_cells": section_noise_cells,
            "compares": section_compares, "scatter": section_scatter, "provenance": section_provenance,
            "error_sweep": section_error_sweep, "tasks": section_tasks, "intervention": section_intervention}


def _rel(study: Study, path: str) -> str:
    """A repository path as a link from the study's README."""
    import os

    return os.path.relpath(ROOT / path, study.results)


def readme(study: Study, rows: list[dict], write_plots: bool = True) -> str:
    """The study's README from its rows (plots written beside it when write_plots)."""
    out = study.results
    idx = Rows(study, rows)
    rel = shown(study.path)
    lines = [f"# {study.title}\n",
             f"Report: `.venv/bin/python eval/run.py {rel} --report-only` (written from `episodes.jsonl.gz` and "
             f"`configs.json` beside this file; {idx.n} episodes).  "]
    if study.made_by:
        lines.append("Episodes run by: " + "; ".join(f"`{m}`" for m in study.made_by) + ".  ")
    if study.about:
        lines.append(" ".join(study.about.split()))
    lines.append("")
    for sec in study.report:
        if sec.get("heading"):
            lines += [f"## {sec['heading']}\n"]
        if sec.get("note"):
            lines += [" ".join(sec["note"].split()), ""]
        kind = sec.get("kind", "text")
        if kind not in SECTIONS:
            raise SystemExit(f"study {study.name}: unknown report kind {kind!r}; choose one of {', '.join(SECTIONS)}")
        if not write_plots and kind == "scatter":
            lines += [f"![success against jerk]({sec['plot']})", ""]
            continue
        lines += _no_plot(SECTIONS[kind], write_plots)(study, idx, sec, out)
    return "\n".join(lines).rstrip() + "\n"


PLOT_ALT = {"sweep": "sweep", "error_sweep": "success gain against pose error"}  # each plot's alt text


def _no_plot(fn, write_plots: bool):
    if write_plots:
        return fn

    def wrapped(study, rows, sec, out):
        return fn(study, rows, {k: v for k, v in sec.items() if k != "plot"}, out) + (
            [f"![{PLOT_ALT.get(sec.get('kind'), 'success and jerk')}]({sec['plot']})", ""]
            if sec.get("plot") else [])

    return wrapped


# ---------------------------------------------------------------------------------------------------- plots

def _plot_bars(cells, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    aggs = [cmp.aggregate(rs) for _, _, rs in cells]
    x = np.arange(len(cells))
    s = np.array([a["success"] for a in aggs])
    lo, hi = np.array([a["ci"][0] for a in aggs]), np.array([a["ci"][1] for a in aggs])
    axes[0].bar(x, s, yerr=[s - lo, hi - s], capsize=3, color="tab:blue")
    axes[0].set_ylabel("success rate (95 % Wilson CI)")
    axes[1].bar(x, [a["mean_jerk"] for a in aggs], color="tab:orange")
    axes[1].set_ylabel("mean end-effector jerk (m/s^3)")
    for ax in axes:
        ax.set_xticks(x, [f"{b}\n{c}" for b, c, _ in cells], rotation=60, ha="right", fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_sweep(cell, levels, configs, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x = np.arange(len(levels))
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for c in configs:
        aggs = [cmp.aggregate(cell[(b, c)]) for b in levels]
        s = np.array([a["success"] for a in aggs])
        lo, hi = np.array([a["ci"][0] for a in aggs]), np.array([a["ci"][1] for a in aggs])
        axes[0].errorbar(x, s, yerr=[s - lo, hi - s], marker="o", capsize=3, label=c)
        axes[1].plot(x, [a["reward"] for a in aggs], marker="o", label=c)
        axes[2].plot(x, [a["mean_jerk"] for a in aggs], marker="o", label=c)
    for ax, lab in zip(axes, ("success (95 % CI)", "episode reward", "mean jerk (m/s^3)")):
        ax.set_xticks(x, levels, rotation=30, fontsize=7)
        ax.set_ylabel(lab)
        ax.legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_error_sweep(curves, backbones, axes_names, path: Path, title: str, labels=("told", "not told")) -> None:
    """One row per backbone, one panel per fault: the paired gain over baseline (95 % CI) against the level,
    of the two columns of configurations (`labels`: told and not told), with the exact-state gain as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(backbones), len(axes_names), figsize=(3.4 * len(axes_names), 3.0 * len(backbones)),
                             squeeze=False, sharey="row")
    for i, b in enumerate(backbones):
        for j, ax_name in enumerate(axes_names):
            ax = axes[i][j]
            ref, pts = curves[(b, ax_name)]
            ax.axhline(ref["diff"] * 100, color="grey", ls="--", lw=1, label="exact state")
            ax.axhline(0, color="black", lw=0.6)
            for k, (label, color) in enumerate(((labels[0], "tab:blue"), (labels[1], "tab:red"))):
                xs, ys, lo, hi = [], [], [], []
                for level, t, u in pts:
                    r = t if k == 0 else u
                    if r and r["n"]:
                        xs.append(level)
                        ys.append(r["diff"] * 100)
                        lo.append((r["diff"] - r["ci"][0]) * 100)
                        hi.append((r["ci"][1] - r["diff"]) * 100)
                if xs:
                    ax.errorbar(xs, ys, yerr=[lo, hi], marker="o", capsize=3, color=color, label=label)
            ax.set_title(f"{b}: {ax_name}", fontsize=8)
            ax.set_xlabel({"bias": "bias (m)", "noise": "noise sigma (m)", "lag": "lag (steps)",
                           "dropout": "dropout (fraction of steps)"}.get(ax_name, ax_name), fontsize=8)
            if j == 0:
                ax.set_ylabel("success gain over baseline (pp)", fontsize=8)
            ax.legend(fontsize=6)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
