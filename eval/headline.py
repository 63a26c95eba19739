"""The results the README and docs/results.md show, computed from the studies' data
(eval/results/<study>/episodes.jsonl.gz).

    .venv/bin/python eval/headline.py           # print both blocks
    .venv/bin/python eval/headline.py --write   # replace them in README.md and docs/results.md (between the markers)
    .venv/bin/python eval/headline.py --check   # exit 1 if either differs from the data

README.md holds one table, a row per policy family (FAMILIES): the shipped default against the same policies
uncorrected, pooled over the family's backbones on blocks its study holds out for confirmation; docs/results.md every
table, per backbone and per mode (the paper's readings beside the default), the other suites' included.

Nothing here is typed by hand: every number comes from a study's episode rows, selected by the
study file's blocks and configuration names.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import compare as cmp  # noqa: E402
from report import PAIRED_HEAD, Rows, paired_row, pp  # noqa: E402
from run import rows_of  # noqa: E402
from study import ROOT, Study, find  # noqa: E402

START, END = "<!-- headline:start -->", "<!-- headline:end -->"
# eval/studies/efficacy.toml's name for the default as it shipped from decision 18 until the centre guide joined it,
# with its distances fixed (today's default measures them on the scene and adds the centre guide): not "the shipped
# default" of this code, and never called that unqualified in what this file writes
SHIPPED = "default + rim guide"
SHIPPED_WAS = ("`default + rim guide`: the default as it shipped before the centre guide joined it, with the distances "
               "fitted on this bowl (`geometry=fixed`)")
SMOOTH = "smooth (default + rim guide + low-pass off the carry)"
PAPER = ("temporal", "paper (eq. 2, c=0.05)", "paper Alg. 1 (c=1)")
NEWEST = ("baseline", *PAPER, SHIPPED, SMOOTH)


def _load(name: str) -> tuple[Study, Rows]:
    study = Study(find(name))
    return study, Rows(study, rows_of(study))


def _rate(rows: list[dict]) -> str:
    a = cmp.aggregate(rows)
    return f"{a['success']:.0%} [{a['ci'][0] * 100:.0f}, {a['ci'][1] * 100:.0f}] (n={a['n']})"


def _cell(p: dict) -> str:
    return (f"{p['success']:.0%} ({p['diff'] * 100:+.0f} pp [{p['ci'][0] * 100:+.0f}, {p['ci'][1] * 100:+.0f}]; "
            f"jerk x{p['jerk_ratio']:.2f})")


def newest_table() -> list[str]:
    """Every mode against baseline on the newest blocks (the experts on 35-39 with seed + 6000 draws, the
    learned ACTs on init states 20-24), paired."""
    study, rows = _load("efficacy")
    lines = ["**LIBERO-Spatial, every mode on the newest held-out blocks: the experts on init states 35-39 with fresh "
             "failure draws (seed + 6000), the learned ACTs on init states 20-24 (10 tasks, n = 50 pairs per cell)** "
             "([eval/results/efficacy](eval/results/efficacy/README.md)): success; paired difference against baseline "
             "[95 % CI]; jerk relative to baseline's. `temporal`: the paper's smoothing foil; `paper (eq. 2, c=0.05)`: "
             "its main text (`--physvla.preset=paper`); `paper Alg. 1 (c=1)`: its supplement (`paper_alg1`); "
             f"{SHIPPED_WAS} (today's default measures them on the scene, which gave the same result: "
             "[eval/results/geometry_scene](eval/results/geometry_scene/README.md), and adds the centre guide, which "
             "pulls on no LIBERO-Spatial bowl); `smooth`: `--physvla.preset=smooth` of that time\n",
             "| backbone | " + " | ".join(NEWEST) + " |", "|---|" + "---|" * len(NEWEST)]
    for bn in ("fresh6000", "acts_20_24"):
        bl = study.blocks[bn]
        for b in bl.backbones:
            base = rows.get("baseline", b, bl)
            ps = [cmp.paired(rows.get(c, b, bl), base) for c in NEWEST[1:]]
            lines.append(f"| {b} | {ps[0]['base_success']:.0%} | " + " | ".join(_cell(p) for p in ps) + " |")
    return lines + [""]


def lift_tables() -> list[str]:
    """Lift / Fetch sigma 0 / 0.40 on the confirmation blocks, and Lift place-on-plate, paired."""
    study, rows = _load("efficacy")
    configs = ("baseline", SHIPPED, SMOOTH, "default + robust low-pass off the carry", *PAPER)
    lines = ["**Lift and Fetch, grasp-phase noise sigma 0 / 0.40, the confirmation blocks (seeds 100-159)** (paper "
             "Table A1: jerk-degradation ratio ~10x; baseline, `default + rim guide` (the default before the centre "
             "guide, fixed distances), the `smooth` preset, its low-pass alone on the default of the time and the "
             "paper's modes, where they ran)\n",
             "| sim | block | configuration | success sigma 0 | success sigma 0.40 | jerk sigma 0 | jerk sigma 0.40 | "
             "degradation | baseline's degradation / this one's |", "|---|---|---|---|---|---|---|---|---|"]
    for first in (100, 120, 140):
        for sim in ("lift", "fetch"):
            bl = study.blocks[f"{sim}_{first}"]
            zero, noisy = bl.backbones
            deg = {}
            for c in configs:
                a, b = rows.get(c, zero, bl), rows.get(c, noisy, bl)
                if not a or not b:
                    continue
                deg[c] = cmp.degradation(a, b)
                a0, a1 = cmp.aggregate(a), cmp.aggregate(b)
                lines.append(f"| {sim} | seeds {first}-{first + 19} | {c} | {a0['successes']}/{a0['n']} | "
                             f"{a1['successes']}/{a1['n']} | {a0['mean_jerk']:.2f} | {a1['mean_jerk']:.2f} | {deg[c]:+.0%} | "
                             f"{cmp.degradation_ratio(deg['baseline'], deg[c]):.2f} |")
    lines += ["", "**Lift + place-on-plate with a persistent place bias, the confirmation blocks** (paper: 35 % -> 95 %; "
              "the default's release veto, not eq. 5, does it; the paper's modes where they ran)\n", *PAIRED_HEAD]
    for first in (100, 120, 140):
        bl = study.blocks[f"plate_{first}"]
        (b,) = bl.backbones
        for c in (*PAPER, SHIPPED, SMOOTH):
            p = cmp.paired(rows.get(c, b, bl), rows.get("baseline", b, bl))
            if p["n"]:
                lines.append(paired_row(f"seeds {first}-{first + 19} / {c}", p))
    return lines + [""]


def robot_table() -> list[str]:
    study, rows = _load("so101_faults")
    early = study.backbone_spec("so101_premature_close")["expert"]["premature_close"]
    half = Study(find("learned_so101")).backbone_spec("so101_expert_premature")["expert"]["premature_close"]
    lines = ["**Simulated SO-101 through lerobot's robot action processor (eval/so101_robot.py, the `lerobot-rollout` "
             "path): a scripted pick-and-place controller** "
             "([eval/results/so101_faults](eval/results/so101_faults/README.md)): success uncorrected -> corrected, "
             f"paired difference [95 % CI], n = 50 draws per block; `so101_premature_close` closes early in "
             f"{early:.0%} of its episodes (the second table's `so101_expert_premature`, lerobot-env-so101 through "
             f"`lerobot-eval`, in {half:.0%}). `arm`: the arm preset; `default (2026-11-24)`: the LIBERO default of "
             "that date, not today's\n",
             "| expert | preset | design block (seeds 0-49) | confirmation block (seeds 1000-1049) |", "|---|---|---|---|"]
    for b in study.blocks["design"].backbones:
        for c in ("arm", "default (2026-11-24)"):
            cells = []
            for bn in ("design", "confirmation"):
                bl = study.blocks[bn]
                p = cmp.paired(rows.get(c, b, bl), rows.get("baseline", b, bl))
                cells.append(f"{p['base_success']:.0%} -> {p['success']:.0%} ({p['diff'] * 100:+.0f} pp "
                             f"[{p['ci'][0] * 100:+.0f}, {p['ci'][1] * 100:+.0f}])")
            lines.append(f"| {b} | {c} | " + " | ".join(cells) + " |")
    return lines + [""]


def success_table(name: str, title: str, configs: tuple[str, ...]) -> list[str]:
    study, rows = _load(name)
    (bl,) = study.blocks.values()
    lines = [f"**{title}** ([eval/results/{name}](eval/results/{name}/README.md)): success [95 % Wilson CI], "
             "mean end-effector jerk (m/s^3)\n", "| backbone | " + " | ".join(configs) + " |",
             "|---|" + "---|" * len(configs)]
    for b in bl.backbones:
        cells = []
        for c in configs:
            rs = rows.get(c, b, bl)
            cells.append(f"{_rate(rs)}; {cmp.aggregate(rs)['mean_jerk']:.1f}" if rs else "not run")
        lines.append(f"| {b} | " + " | ".join(cells) + " |")
    return lines + [""]


def sweep_table(name: str, title: str) -> list[str]:
    study, rows = _load(name)
    bl = study.blocks["sweep"]
    zero, noisy = bl.backbones[0], bl.backbones[-1]
    lines = [f"**{title}** ([eval/results/{name}](eval/results/{name}/README.md)): success pooled over the "
             f"{len(bl.backbones)} noise levels; mean jerk (m/s^3) at sigma 0 and 0.40 and its degradation\n",
             "| mode | success (all sigmas) | jerk sigma=0 | jerk sigma=0.40 | degradation |", "|---|---|---|---|---|"]
    for c in ("baseline", "phys", "phys_el"):
        j0, j1 = (cmp.aggregate(rows.get(c, b, bl))["mean_jerk"] for b in (zero, noisy))
        every = [r for b in bl.backbones for r in rows.get(c, b, bl)]
        lines.append(f"| {c} | {_rate(every)} | {j0:.2f} | {j1:.2f} | {(j1 - j0) / j0:+.0%} |")
    return lines + [""]


def paired_table(name: str, title: str) -> list[str]:
    study, rows = _load(name)
    bl = study.blocks["pairs"]
    (b,) = bl.backbones
    base = rows.get("baseline", b, bl)
    lines = [f"**{title}** ([eval/results/{name}](eval/results/{name}/README.md))\n",
             "| mode | success | pairs won vs baseline | pairs lost |", "|---|---|---|---|"]
    for c in ("baseline", "phys", "phys_el"):
        p = cmp.paired(rows.get(c, b, bl), base)
        lines.append(f"| {c} | {_rate(rows.get(c, b, bl))} | {p['won']} | {p['lost']} |")
    return lines + [""]


# The README's table: one row per policy family, the shipped default against the same policies uncorrected, the
# pairs of the family's backbones pooled (compare.pooled, as the studies' reports pool). Each part: (study,
# configuration, blocks, backbones; () = every backbone of the blocks). A block must be a confirmation block of one
# of the study's comparisons and of none's design, and hold every pair; the configuration is the shipped default of
# this code wherever a study ran it (`is_shipped`), else the row says which default it is (`note`, required then).
SPATIAL_WEAKER = ("act_single_weak", "act_single_mid", "act_chunk_weak", "act_chunk_mid", "act_chunk_mid2")
SPATIAL_STRONG = ("act_single", "act_chunk")
BEFORE_HOLD_NOTE = ("the default before the held close ([39](docs/decisions/39-hold-to-top.md)); not run with it: "
                    "~50 s an episode on this CPU")
FAMILIES: tuple[tuple[str, tuple, str], ...] = (
    ("Scripted expert, clean and with injected faults (LIBERO-Spatial)",
     (("libero_rows_hold", "shipped default", ("experts",), ()),), ""),
    ("Learned ACTs, weaker checkpoints (LIBERO-Spatial)",
     (("libero_rows_hold", "shipped default", ("spatial_acts",), SPATIAL_WEAKER),), ""),
    ("Learned ACTs, strong checkpoints (LIBERO-Spatial)",
     (("libero_rows_hold", "shipped default", ("spatial_acts",), SPATIAL_STRONG),), ""),
    ("Learned ACTs, strong and weaker, LIBERO-Object, -Goal and -10",
     (("libero_rows_hold", "shipped default", ("object_weak", "goal", "ten"), ()),), ""),
    ("MetaWorld's scripted policies, clean and with injected faults (6 tasks modelled)",
     (("state_rows_hold", "shipped default on MetaWorld", ("mw_fresh", "mw50_modelled"), ()),), ""),
    ("MetaWorld's scripted policy, 44 tasks not modelled (passed through)",
     (("state_rows_hold", "shipped default on MetaWorld", ("mw50_passed",), ()),), ""),
    ("Learned ACTs, strong and weaker, MetaWorld",
     (("state_rows_hold", "shipped default on MetaWorld", ("mw_learned",), ()),), ""),
    ("Learned ACTs, none strong, simulated SO-101 (lerobot-env-so101)",
     (("state_rows_hold", "shipped default", ("so101",), ()),), ""),
    ("Camera ACTs (64 px, no object poses), LIBERO-Object, -Spatial",
     (("camera_originals_hold", "shipped default", ("object", "object_original"), ()),
      ("camera_rows_hold", "shipped default", ("spatial",), ())), ""),
    ("Camera Diffusion Policy (64 px), LIBERO-Spatial",
     (("camera_diffusion_spatial", "shipped default", ("original",), ()),), BEFORE_HOLD_NOTE),
    ("Camera ACTs, LIBERO-PRO position shift (Spatial swap, Object x-shift)",
     (("camera_rows_hold", "shipped default", ("spatial_swap", "object_temp_x"), ()),), ""),
    ("Camera ACTs, LIBERO-PRO mug, new objects",
     (("camera_rows_hold", "shipped default",
       ("object_with_mug", "spatial_with_mug", "object_replaced", "spatial_replaced"), ()),), ""),
)
MARKS = "†‡§¶"


def env_options(scene: str) -> dict:
    """The options confirmed on one env alone that its env type adds under the shipped presets (`physvla_options`,
    scripts/lerobot_physvla_eval.py for_env): MetaWorld's close_meets_onset; {} for scenes without an env type."""
    if scene.startswith("metaworld"):
        from lerobot_physvla.envs.metaworld_physvla import MetaworldPhysVLAEnvConfig as env
    elif scene.startswith("so101_env"):
        from lerobot_physvla.envs.so101_physvla import SO101PhysVLAEnvConfig as env
    elif scene.startswith("libero_"):
        from lerobot_physvla.envs.libero_physvla import LiberoPhysVLAEnvConfig as env
    else:
        return {}
    return dict(getattr(env, "physvla_options", None) or {})


def shipped(study: Study, scene: str) -> dict:
    """The shipped default of this code on `scene`, as `--policy.postprocess=physvla` with no other flag builds it:
    PhysVLAConfig() with the fields the env sets (the study's scene_overrides: layout, weighting; never its
    [pinned], which freezes an older default) and the env's own options."""
    from lerobot_physvla.core.config import ActionLayout, PhysVLAConfig

    spec = {k: tuple(v) if isinstance(v, list) else v for k, v in study.scene_overrides.get(scene, {}).items()}
    if isinstance(spec.get("layout"), dict):
        spec["layout"] = ActionLayout(**{k: tuple(v) if isinstance(v, list) else v for k, v in spec["layout"].items()})
    return PhysVLAConfig(**spec, **env_options(scene)).to_dict()


def is_shipped(study: Study, name: str, scene: str) -> bool:
    from store import config_hash

    return study.config_hash(name, scene) == config_hash(shipped(study, scene))


def departures(study: Study, name: str, scene: str) -> str:
    """Where the study's configuration differs from the shipped default as they act (store.effective), as flags."""
    from store import NEUTRAL, effective

    from lerobot_physvla.core.config import BEFORE_HOLD, BEFORE_PULL

    now, ran = effective(shipped(study, scene)), effective(study.config(name, scene))
    keys = sorted(k for k in set(now) | set(ran) if now.get(k, NEUTRAL.get(k)) != ran.get(k, NEUTRAL.get(k)))
    value = {k: ran.get(k, NEUTRAL.get(k)) for k in keys}
    said, told = [], set()
    for alias, fields in (("BEFORE_PULL", BEFORE_PULL), ("BEFORE_HOLD", BEFORE_HOLD)):  # core/config.py's names
        before = [k for k in keys if k in fields and value[k] == (list(v) if isinstance(v := fields[k], tuple) else v)]
        if len(before) == len(fields):
            said.append(f"`{alias}`")
            told |= set(before)
    return ", ".join(said + [f"`{k}={str(value[k]).lower()}`" for k in keys if k not in told])


def family(parts: tuple, each: list | None = None) -> tuple[dict, list[dict], list[tuple[Study, str, str]]]:
    """A family's pooled paired result, its per-backbone paired results, and the (study, configuration, scene) each
    part ran; `each`, if given, gets (study, block, backbone, paired result) for every backbone."""
    results, ran = [], []
    for name, config, blocks, backbones in parts:
        study, rows = _load(name)
        roles = {b.name: role for b, role in study.seed_roles()}
        for bn in blocks:
            if roles[bn] != "confirm":
                raise SystemExit(f"headline: {name} block {bn!r} is {roles[bn]!r}; the README shows confirmation "
                                 "blocks only")
            bl = study.blocks[bn]
            ran.append((study, config, bl.scene))
            for b in backbones or bl.backbones:
                if b not in bl.backbones:
                    raise SystemExit(f"headline: {name} block {bn!r} has no backbone {b!r}")
                p = cmp.paired(rows.get(config, b, bl), rows.get("baseline", b, bl))
                if p["n"] != len(bl.tasks) * len(bl.seeds):
                    raise SystemExit(f"headline: {name} {bn} {b}: {p['n']} of {len(bl.tasks) * len(bl.seeds)} pairs")
                results.append(p)
                if each is not None:
                    each.append((study, bl, b, p))
    return cmp.pooled(results), results, ran


def _rates(results: list[dict]) -> tuple[float, float]:
    """Success uncorrected and corrected over every pair of some paired results."""
    n = sum(p["n"] for p in results)
    return sum(p["lost"] + p["both"] for p in results) / n, sum(p["won"] + p["both"] for p in results) / n


def families_table() -> list[str]:
    """The README's table per backbone: each family's pairs, backbone by backbone, and the pooled row it shows."""
    lines = ["**The README's table, backbone by backbone: the shipped default against the same policy uncorrected on "
             "each study's confirmation blocks**: the study's configuration and how it differs from today's shipped "
             "default where it does, success, the paired difference [95 % CI], pairs won / lost, and the pooled row "
             "the README shows\n",
             "| policy family | study / block | configuration as run | backbone | pairs | baseline | corrected | "
             "paired difference [95 % CI] | won / lost |", "|---|---|---|---|---|---|---|---|---|"]
    for label, parts, _ in FAMILIES:
        each: list = []
        pool, results, _ = family(parts, each)
        for study, bl, b, p in each:
            config = next(c for name, c, blocks, _ in parts if name == study.name and bl.name in blocks)
            what = (f"`{config}`: today's shipped default" if is_shipped(study, config, bl.scene) else
                    f"`{config}`: today's shipped default with {departures(study, config, bl.scene)}")
            lines.append(f"| {label} | [{study.name}](eval/results/{study.results.name}/README.md) / {bl.name} "
                         f"({bl.scene}, {bl.seeds[0]}-{bl.seeds[-1]}) | {what} | {b} | {p['n']} | "
                         f"{p['base_success']:.0%} | {p['success']:.0%} | {pp(p)} | {p['won']} / {p['lost']} |")
        base, this = _rates(results)
        lines.append(f"| {label} | pooled | | | {pool['n']} | {base:.0%} | {this:.0%} | {pp(pool, 1)} | "
                     f"{pool['won']} / {pool['lost']} |")
    return lines + [""]


def readme_table() -> list[str]:
    """One row per policy family (FAMILIES): pairs, success uncorrected and under the shipped default, and the pooled
    paired difference in points [95 % CI]; a row whose study ran an older default is marked and footnoted."""
    lines = ["| policy family | pairs (n) | baseline success | shipped default success | paired difference, points "
             "[95 % CI] | source |", "|---|---|---|---|---|---|"]
    notes: dict[str, str] = {}
    for label, parts, note in FAMILIES:
        pool, results, ran = family(parts)
        base, this = _rates(results)
        older = sorted({departures(st, c, sc) for st, c, sc in ran if not is_shipped(st, c, sc)})
        mark = ""
        if older:
            if not note:
                raise SystemExit(f"headline: {label!r} ran {', '.join(older)} against the shipped default; say which "
                                 "default it is (FAMILIES note)")
            text = f"ran with {'; '.join(older)}: {note}"
            mark = next((m for m, t in notes.items() if t == text), MARKS[len(notes)])
            notes[mark] = text
        names = dict.fromkeys(st.results.name for st, _, _ in ran)
        src = ", ".join(f"[{s}](eval/results/{s}/README.md)" for s in names)
        lines.append(f"| {label}{' ' + mark if mark else ''} | {pool['n']} | {base:.0%} | {this:.0%} | "
                     f"{pool['diff'] * 100:+.1f} [{pool['ci'][0] * 100:+.1f}, {pool['ci'][1] * 100:+.1f}] | {src} |")
    return lines + ([""] + [f"{m} {t[0].upper()}{t[1:]}." for m, t in notes.items()] if notes else [])


SUITES = {"object": "LIBERO-Object", "goal": "LIBERO-Goal", "ten": "LIBERO-10",
          "image": "LIBERO-Spatial, agentview camera", "metaworld": "MetaWorld",
          "so101": "SO-101, lerobot-env-so101 pick-and-place"}


# the scripted teacher's study, the ACTs distilled from it, the image-input ACT (eval/studies/image_act.toml), the
# centre guide's confirmation blocks (eval/studies/centre_guide.toml: the option `centre_guide` beside the shipped
# default, docs/decisions/25-centre-guide.md), the ACTs distilled from MetaWorld's own scripted policies, and
# lerobot-env-so101's pick-and-place controller with the ACTs distilled from it; the ACTs trained longer on a lent GPU
# and the single-step MetaWorld ACT (each row joins once its block has run)
SUITE_STUDIES = ("suites", "suites_learned", "learned_goal_ten", "learned_goal_ten_long", "image_act", "centre_guide",
                 "learned_metaworld", "learned_metaworld_single", "learned_so101", "learned_so101_b128")
# the shipped default as the studies froze it (before the centre guide joined it), and the centre guide's first form
# (what the shipped default adds since eval/studies/centre_guide_step_gain.toml, wherever the layout lets it act)
BEFORE, NOW = "shipped default", "default + centre guide"


def _default_now(study: Study, scene: str) -> str | None:
    """Which of the study's configurations the shipped default of this code is on `scene` (`shipped`: the env's own
    options included, MetaWorld's close_meets_onset); None where none is."""
    return next((name for name in (BEFORE, NOW, *study.config_specs)
                 if name in study.config_specs and is_shipped(study, name, scene)), None)


def _vs_baseline(rows: list[dict], base: list[dict]) -> str:
    if not rows or not base:
        return "-"
    p = cmp.paired(rows, base)
    return f"{p['success']:.0%} ({p['diff'] * 100:+.0f} [{p['ci'][0] * 100:+.0f}, {p['ci'][1] * 100:+.0f}])"


def suites_table() -> list[str]:
    """Baseline, the shipped default before the centre guide joined it (as frozen at 519c8932 for the pre-registered
    test) and the shipped default of this code (with the centre guide wherever the layout lets it act) on the other
    LIBERO suites, MetaWorld and the SO-101 (eval/studies/suites.toml,
    suites_learned.toml, learned_goal_ten.toml, learned_goal_ten_long.toml, image_act.toml, centre_guide.toml,
    learned_metaworld.toml, learned_metaworld_single.toml, learned_so101.toml, learned_so101_b128.toml): success,
    and the paired difference against baseline [95 % CI]; "-" where a configuration did not run on a block."""
    lines = ["| suite (tasks, init states) | policy | baseline | the default as its study froze it (before the centre "
             "guide and MetaWorld's close_meets_onset) | today's shipped default |", "|---|---|---|---|---|"]
    loaded = [_load(name) for name in SUITE_STUDIES]
    for bn, title in SUITES.items():
        for study, rows in loaded:
            for name, bl in study.blocks.items():
                if name != bn and name != f"{bn}_weak":
                    continue
                where = (f"{title} ({len(bl.tasks)} tasks, {bl.seeds[0]}-{bl.seeds[-1]})" if len(bl.tasks) > 1 else
                         f"{title} (seeds {bl.seeds[0]}-{bl.seeds[-1]})")
                for b in bl.backbones:
                    n = len(bl.tasks) * len(bl.seeds)
                    base, before = rows.get("baseline", b, bl), rows.get(BEFORE, b, bl)
                    shipped = _default_now(study, bl.scene)
                    now = rows.get(shipped, b, bl) if shipped else []
                    if len(base) < n or len(before) < n:
                        if study.name == "suites":  # the learned rows join once they have run
                            lines.append(f"| {where} | {b} | not run yet | not run yet | - |")
                        continue
                    lines.append(f"| {where} | {b} | {sum(r['success'] for r in base) / len(base):.0%} | "
                                 f"{_vs_baseline(before, base)} | {_vs_baseline(now, base)} |")
    return lines


def readme_block() -> str:
    """The README's one table (the suites' table is docs/results.md's, with every other)."""
    return "\n".join([START, "", *readme_table(), "", END])


def block() -> str:
    lines = [START, ""]
    lines += newest_table()
    lines += ["**The other LIBERO suites, MetaWorld and the SO-101, pre-registered "
              "([eval/results/suites](eval/results/suites/README.md) and the studies each row's policies come from): "
              "the shape-planning scripted expert clean, jittered and "
              "faulty, the ACTs distilled from it, an image-input ACT, the ACTs distilled from MetaWorld's own "
              "scripted policies, and lerobot-env-so101's pick-and-place controller with the ACTs distilled from it; "
              "success and the paired difference against baseline [95 % CI]**\n", *suites_table(), ""]
    lines += families_table()
    lines += lift_tables()
    lines += robot_table()
    lines += success_table("table2", "LIBERO-Spatial, scripted backbones x modes (10 tasks x 5 seeds)",
                           ("baseline", "temporal", "phys", "phys_el"))
    lines += success_table("learned", "LIBERO-Spatial, learned backbones (LeRobot ACT / Diffusion, state inputs) x modes",
                           ("baseline", "temporal", "phys", "phys_el", "default"))
    lines += sweep_table("lift_sweep", "robosuite Lift, grasp-phase noise sweep (20 trials per cell)")
    lines += sweep_table("fetch_sweep", "FetchPickAndPlace (4-D actions, another arm), same sweep")
    lines += paired_table("lift_plate", "Lift + place-on-plate, persistent place bias, 20 matched pairs")
    lines += paired_table("place_bias", "LIBERO-Spatial, persistent place bias, 20 matched pairs")
    lines.append(END)
    return "\n".join(lines)


RESULTS_MD = ROOT / "docs" / "results.md"


def current(path: Path = ROOT / "README.md") -> str:
    m = re.search(re.escape(START) + ".*?" + re.escape(END), path.read_text(), flags=re.S)
    if not m:
        raise SystemExit(f"headline: {path.relative_to(ROOT)} has no {START} ... {END} block")
    return m.group(0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--write", action="store_true", help="replace the block in README.md")
    ap.add_argument("--check", action="store_true", help="exit 1 if README.md's block differs from the data")
    args = ap.parse_args()
    blocks = {ROOT / "README.md": readme_block(), RESULTS_MD: block().replace("](eval/results/", "](../eval/results/")}
    if args.check:
        stale = [p.name for p, text in blocks.items() if current(p) != text]
        print("headline: README.md and docs/results.md match the data" if not stale else
              f"headline: {', '.join(stale)} differ from the data")
        raise SystemExit(1 if stale else 0)
    if not args.write:
        print("\n\n".join(blocks.values()))
        return
    for path, text in blocks.items():
        path.write_text(path.read_text().replace(current(path), text))
    print("headline: README.md and docs/results.md updated")


if __name__ == "__main__":
    main()
