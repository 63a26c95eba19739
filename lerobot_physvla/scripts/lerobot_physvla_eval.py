"""`lerobot-eval --policy.postprocess=physvla` and `lerobot-physvla-eval`: the corrected evaluation.

`activate_eval(argv)` strips our flags from argv (lerobot's parser would reject them) and, for
`--policy.postprocess=physvla`, installs the eval hook of `compat`: a `libero` env becomes
`libero_physvla`, a `metaworld` env `metaworld_physvla` and an `so101` env `so101_physvla`, the corrector step is
appended to the policy postprocessor (with the env's own fields, `physvla_defaults`: metaworld's layout, the so101
layout at the env's action_scale, where no flag sets them), and
per-episode diagnostics are written beside eval_info.json. Bad flags end the program with a one-line error
and exit code 2.

    lerobot-physvla-eval ARGS   is   lerobot-eval ARGS   (the plugin applies the flags either way)
"""

from __future__ import annotations

import json
import logging
import os
import sys
from pathlib import Path

from lerobot_physvla import compat
from lerobot_physvla.diagnostics import EpisodeRecorder
from lerobot_physvla.envs.libero_physvla import as_physvla_env
from lerobot_physvla.envs.metaworld_physvla import as_metaworld_physvla_env
from lerobot_physvla.envs.so101_physvla import as_so101_physvla_env
from lerobot_physvla.flags import FlagError, build_config, describe, split_argv
from lerobot_physvla.processor.physvla_processor import PhysVLACorrectorStep


def _write_diagnostics(cfg, step) -> None:
    recorder = getattr(step, "_physvla_recorder", None)
    if recorder is None or cfg.output_dir is None:
        return
    recorder.horizon = getattr(cfg.env, "horizon", None) or getattr(cfg.env, "episode_length", None)
    if recorder.horizon is None:
        from lerobot.envs.libero import TASK_SUITE_MAX_STEPS

        recorder.horizon = TASK_SUITE_MAX_STEPS.get(str(getattr(cfg.env, "task", "")).split(",")[0])
    info = Path(cfg.output_dir) / "eval_info.json"
    if info.is_file():
        per_task = json.loads(info.read_text()).get("per_task", [])
        successes: dict[int, list[bool]] = {}  # task groups (MetaWorld's: one per task, each id 0) in lerobot's order
        for t in per_task:
            successes.setdefault(int(t["task_id"]), []).extend(t["metrics"]["successes"])
        recorder.apply_env_successes(successes)
    path = recorder.write(cfg.output_dir, config=step.config)
    counts = ", ".join(f"{k} {v}" for k, v in recorder.summary()["passthrough"].items()) or "none"  # as the table
    logging.info("physvla: diagnostics written to %s (pass-throughs: %s)", path, counts)
    try:
        _write_report(Path(cfg.output_dir), recorder, step.cfg)
    except Exception as e:  # noqa: BLE001 - a plot must never fail an evaluation
        logging.warning("physvla: the summary report could not be drawn (%r); the JSON diagnostics are complete", e)
    print(f"physvla: diagnostics in {Path(path).parent} (physvla_diagnostics.json, physvla_episodes.jsonl, "
          "physvla_report.md, physvla_plots/)")


def _write_report(out: Path, recorder, pcfg, plots: int = 10) -> None:
    """The summary table (printed) and physvla_report.md with one plot per episode (the first `plots`)."""
    import numpy as np

    from lerobot_physvla import report

    lay = pcfg.action_layout
    records = recorder.records()
    summary = recorder.summary(records)
    rows, drawn = [], []
    eps = pcfg.eps_nm if pcfg.mode == "phys_el" and pcfg.el_mode != "off" else None
    for k, r in enumerate(records):
        phase = np.repeat([report.PHASE_INDEX[name] for name, _ in r["phase_timeline"]],
                          [frames for _, frames in r["phase_timeline"]]).astype(int)
        rows.append(report.episode_row(r["episode"], f"task {r['task_id']}", r["steps"], r["success"], phase,
                                       r.get("corrections_by_phase", {}), r["frames_changed"], r["overhead_us_p50"],
                                       r["passthrough"]))
        if k < plots and r.get("raw_actions"):  # per-step arrays: the first episodes (EpisodeRecorder.keep_steps)
            raw, cor = np.asarray(r["raw_actions"], float), np.asarray(r["corrected_actions"], float)
            r_el = np.array([np.nan if v is None else v for v in r["r_el"]], float)
            drawn.append((f"episode {r['episode']} (task {r['task_id']})", report.plot_episode(
                out / "physvla_plots" / f"episode_{r['episode']:04d}.png", raw, cor, phase, r_el, eps, lay,
                f"episode {r['episode']}, task {r['task_id']}: {pcfg.mode}")))
    lo, hi = summary["success_ci95"]
    t = summary["overhead_us_per_env_step"]
    fmt = lambda v: "-" if v is None else f"{v:.1f}"  # noqa: E731
    extra = {
        "success": f"{(summary['success_rate'] or 0) * 100:.0f} % [95 % CI {max(lo, 0.0) * 100:.0f}, "
                   f"{hi * 100:.0f}]",
        "approach veto fired": f"{summary['veto_fire_rate'] * 100:.1f} % of approach steps",
        "corrector overhead per env-step": f"p50 {fmt(t['p50'])} us, p99 {fmt(t['p99'])} us",
        "pass-throughs": ", ".join(f"{k} {v}" for k, v in summary["passthrough"].items()) or "none",
    }
    print(report.summary_table(rows, extra))
    md = report.write_report(out, "lerobot-eval --policy.postprocess=physvla", report.summary_table(rows, extra, markdown=True),
                             drawn, [f"corrector: {pcfg.mode}; JSON: physvla_diagnostics.json, physvla_episodes.jsonl"],
                             name="physvla_report.md")
    logging.info("physvla: report in %s", md)


SHIPPED_PRESETS = ("default", "smooth", "shift", "arm")  # the presets an env's own options join (never the paper's readings)


def preset_of(overrides) -> str:
    """The preset the flags resolve to (flags.build_config): --physvla.preset, else the shipped default."""
    return str(overrides.get("preset") or "default")


def for_env(cfg, env_cfg, given=(), preset_name: str = "default"):
    """The corrector's configuration for the evaluated env: the fields the env needs (its `physvla_defaults`, e.g.
    metaworld_physvla's layout "metaworld" and weighting "task_space", so101_physvla's ActionLayout at its
    action_scale) and, under a shipped preset (SHIPPED_PRESETS), the options confirmed on that env alone (its
    `physvla_options`: metaworld_physvla's close_meets_onset), where the flags did not set them (`given`: the
    --physvla.<field> names); `cfg` itself for an env that needs none."""
    fields = dict(getattr(env_cfg, "physvla_defaults", None) or {})
    if preset_name in SHIPPED_PRESETS:
        fields.update(getattr(env_cfg, "physvla_options", None) or {})
    changes = {k: v for k, v in fields.items() if k not in set(given)}
    return cfg.replace(**changes) if changes else cfg


def activate_eval(argv: list[str]) -> None:
    """Strip our flags from argv in place and install the eval hook if asked. Exits 2 on bad flags."""
    try:
        post, overrides, rest = split_argv(argv[1:])
        if overrides and post != "physvla":
            raise FlagError("--physvla.* flags need --policy.postprocess=physvla")
        cfg = build_config(overrides) if post == "physvla" else None
        if cfg is not None:
            compat.check_lerobot_version()
            print(describe(cfg, overrides), file=sys.stderr)
    except (FlagError, compat.UnsupportedLerobot) as e:
        print(f"lerobot-physvla: error: {e}", file=sys.stderr)
        raise SystemExit(2) from None
    argv[1:] = rest
    if cfg is None:
        return

    def attach(step):  # record every step of the evaluation (also a checkpoint's own corrector)
        if getattr(step, "_physvla_recorder", None) is None:
            lay = step.cfg.action_layout
            step._physvla_recorder = EpisodeRecorder(
                save_states=os.environ.get("PHYSVLA_SAVE_STATES") == "1", gripper_index=lay.gripper, layout=lay,
                keep_steps=None if os.environ.get("PHYSVLA_RECORD_STEPS") == "1" else 10,
            )
            step.listeners.append(step._physvla_recorder)
        return step

    env_flags = {a.partition("=")[0].removeprefix("--env.") for a in rest if a.startswith("--env.")}
    evaluated: dict[str, object] = {}

    def adapt_env(env_cfg):  # libero -> libero_physvla, metaworld -> metaworld_physvla, so101 -> so101_physvla
        adapted = as_metaworld_physvla_env(as_physvla_env(env_cfg), given=env_flags)
        evaluated["env"] = as_so101_physvla_env(adapted, given=env_flags)
        return evaluated["env"]

    def make_step(actions_per_call: int = 1):  # the configuration for this policy (chunk_phase_caps) and env
        c = for_env(cfg, evaluated.get("env"), given=overrides, preset_name=preset_of(overrides))
        return attach(PhysVLACorrectorStep(config=c.for_policy(actions_per_call).to_dict()))

    def before_rollout(step):  # compact the finished rollout batch here, not in the next batch's first tick
        recorder = getattr(step, "_physvla_recorder", None)
        if recorder is not None:
            recorder.end_batch()

    compat.install_eval_hook(PhysVLACorrectorStep, make_step, _write_diagnostics, attach, adapt_env, before_rollout)


def eval_main() -> None:
    """`lerobot-physvla-eval`: lerobot-eval with the same arguments (the flags work the same).

    lerobot's plugin import (`lerobot_env_physvla`) applies the flags, as in `lerobot-eval`.
    """
    from lerobot.scripts import lerobot_eval
    from lerobot.utils.import_utils import register_third_party_plugins
    from lerobot.utils.utils import init_logging

    init_logging()
    register_third_party_plugins()
    lerobot_eval.eval_main()
