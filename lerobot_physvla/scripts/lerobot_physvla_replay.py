"""`lerobot-physvla-replay`: what the corrector would have done to a recorded LeRobotDataset.

    lerobot-physvla-replay --dataset.repo_id=local/demo --dataset.root=DIR [--mode=offline|resim|policy]
        [--episodes='[0,1]'] [--policy.path=CKPT] [--physvla.preset=...] [--physvla.<field>=...]
        [--output_dir=DIR] [--write_dataset=true] [--workers=2] [--backend=process|ray]

Modes (lerobot_physvla.replay): offline (each recorded action and state through the corrector),
resim (the recorded actions re-executed in the recording simulator, without and with the
corrector), policy (a LeRobot policy on the recorded observations, against the recorded
actions). Every mode prints a summary table and writes to --output_dir: replay_summary.json,
replay_episodes.jsonl, plots/ (one PNG per episode, the first --plots), report.md, and with
--write_dataset a corrected copy of the dataset in dataset/. Bad input ends with a one-line error
and exit code 2, before anything is written.
"""

from __future__ import annotations

import datetime as _dt
import json
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lerobot_physvla.flags import FlagError, build_config, split_argv

MODES = ("offline", "resim", "policy")


@dataclass
class DatasetArgs:
    """repo_id: the dataset's name; root: its directory on disk (required; nothing is downloaded)."""

    repo_id: str = "local/dataset"
    root: str | None = None


@dataclass
class PolicyArgs:
    """path: a LeRobot checkpoint directory (policy mode)."""

    path: str | None = None


@dataclass
class ReplayArgs:
    """Arguments of lerobot-physvla-replay (module docstring); --physvla.* are taken out first.

    Attributes:
        object_xyz, target_xyz: fixed object / target poses (m, world frame) for datasets with
            neither observation.physvla_state nor observation.environment_state.
        plots: per-episode plots to draw (the first N episodes; 0 = none).
        batch: episodes corrected in lockstep per corrector call (offline).
        pose_bias_m, pose_noise_m, pose_lag_steps, pose_dropout: resim only: the perception model's faults
            on the object's and the target's poses the corrector reads (sources/perception.py PoseFaults:
            a bias of this length per episode (m), noise sigma per axis (m), lag (control steps), the
            fraction of steps missing); all 0: exact.
    """

    dataset: DatasetArgs = field(default_factory=DatasetArgs)
    policy: PolicyArgs = field(default_factory=PolicyArgs)
    mode: str = "offline"
    episodes: list[int] | None = None
    output_dir: str | None = None
    write_dataset: bool = False
    workers: int = 1
    backend: str = "process"
    plots: int = 10
    batch: int = 64
    object_xyz: list[float] | None = None
    target_xyz: list[float] | None = None
    pose_bias_m: float = 0.0
    pose_noise_m: float = 0.0
    pose_lag_steps: int = 0
    pose_dropout: float = 0.0

    @property
    def perception(self):
        from lerobot_physvla.sources.perception import PerceptionConfig

        return PerceptionConfig.from_flags(self)


def parse(argv: list[str]) -> tuple[ReplayArgs, object]:
    """(arguments, PhysVLAConfig); FlagError on any bad flag."""
    import draccus

    post, overrides, rest = split_argv(argv)
    if post == "none":
        raise FlagError("--policy.postprocess=none: replay always runs the corrector; drop the flag")
    cfg = build_config(overrides)
    try:
        args = draccus.parse(config_class=ReplayArgs, args=rest)
    except SystemExit as e:
        raise FlagError(f"bad arguments {rest} (see lerobot-physvla-replay --help)") from e
    if args.mode not in MODES:
        raise FlagError(f"--mode={args.mode}: unknown; choose one of {', '.join(MODES)}")
    if args.mode == "policy" and not args.policy.path:
        raise FlagError("--mode=policy needs --policy.path=<a LeRobot checkpoint directory>")
    try:
        faults = args.perception
    except ValueError as e:
        raise FlagError(f"--pose_*: {e}") from e
    if not faults.exact and args.mode != "resim":
        raise FlagError("--pose_bias_m / --pose_noise_m / --pose_lag_steps / --pose_dropout act on a live "
                        "simulator's state: use them with --mode=resim")
    for name in ("object_xyz", "target_xyz"):
        v = getattr(args, name)
        if v is not None and (len(v) != 3 or not np.isfinite(v).all()):
            raise FlagError(f"--{name} needs three finite numbers (metres), got {v}")
    return args, cfg


def run(args: ReplayArgs, cfg) -> dict:
    """Validate, replay, write; returns the summary. ReplayError before anything is written."""
    from lerobot_physvla import report
    from lerobot_physvla.replay import dataset, offline, write
    from lerobot_physvla.replay.dataset import ReplayError

    out = Path(args.output_dir or f"outputs/replay/{_dt.datetime.now():%Y-%m-%d_%H-%M-%S}_{args.mode}")
    if out.exists():
        raise ReplayError(f"--output_dir={out} exists; choose a new one (replay never overwrites)")
    data = dataset.load(args.dataset.repo_id, args.dataset.root, args.episodes)
    if args.write_dataset:
        write.check_writable(data)
    if args.mode == "resim":
        from lerobot_physvla.replay.resim import check_resimulable

        check_resimulable(data)
    column_state = offline.ColumnState(
        tuple(args.object_xyz) if args.object_xyz else None, tuple(args.target_xyz) if args.target_xyz else None)
    for ep in data.episodes[:1]:  # state and layout problems surface here, before any output
        offline.episode_states(data, ep, column_state)
    t0 = time.perf_counter()
    records, note = offline.replay_offline(data, cfg, column_state, workers=args.workers, backend=args.backend,
                                           batch=args.batch)
    t_offline = time.perf_counter() - t0
    extra_records = None
    if args.mode == "resim":
        from lerobot_physvla.replay.resim import replay_resim

        extra_records = replay_resim(data, cfg, workers=args.workers, backend=args.backend,
                                     perception=args.perception)
    elif args.mode == "policy":
        from lerobot_physvla.replay.policy import replay_policy

        extra_records = replay_policy(data, args.policy.path, cfg, column_state)

    # ---- write (only now: every check has passed)
    out.mkdir(parents=True)
    eff_cfg, _ = offline.effective_config(cfg, data)
    lay = eff_cfg.action_layout
    rows, plots = [], []
    by_ep = {r["episode"]: r for r in (extra_records or [])}
    for k, r in enumerate(records):
        x = by_ep.get(r["episode"])
        success = r["success"]
        if args.mode == "resim" and x is not None:
            yn = lambda v: "-" if v is None else ("yes" if v else "no")  # noqa: E731
            success = f"{yn(x['recorded_success'])}/{yn(x['raw']['success'])}/{yn(x['corrected']['success'])}"
        phase, corrections, changed = r["_arrays"]["phase"], r["corrections"], r["frames_changed"]
        if args.mode == "policy" and x is not None:  # the table describes the policy's actions, corrected
            pa = x["_arrays"]
            phase, changed = pa["phase"], int((np.abs(pa["corrected"] - pa["raw"]).max(axis=1) > 0).sum())
            corrections = report.corrections_by_phase(pa["raw"], pa["corrected"], phase, lay)
        row = report.episode_row(r["episode"], r["task"], r["frames"], success, phase, corrections, changed,
                                 r["overhead_us_per_frame_p50"], r["passthrough"])
        if isinstance(success, str):
            row["success"] = success
        rows.append(row)
        if k < args.plots:
            arrays = x["_arrays"] if args.mode == "policy" and x is not None else r["_arrays"]
            what = "policy actions" if args.mode == "policy" else "recorded actions"
            title = f"episode {r['episode']}: {r['task'][:70]} ({what}, {cfg.mode})"
            plots.append((f"episode {r['episode']}", report.plot_episode(
                out / "plots" / f"episode_{r['episode']:06d}.png", arrays["raw"], arrays["corrected"], arrays["phase"],
                arrays["r_el"], eff_cfg.eps_nm if eff_cfg.mode == "phys_el" and eff_cfg.el_mode != "off" else None,
                lay, title)))
    summary = _summary(args, cfg, data, records, extra_records, note, t_offline)
    extra_lines = {k: v for k, v in summary["lines"].items()}
    table = report.summary_table(rows, extra_lines)
    with open(out / "replay_episodes.jsonl", "w") as f:
        for r in records:
            x = by_ep.get(r["episode"])
            rec = {k: v for k, v in r.items() if k != "_arrays"}
            if x is not None:
                rec[args.mode] = {k: v for k, v in x.items() if k not in ("_arrays", "episode", "task")}
            f.write(json.dumps(rec) + "\n")
    (out / "replay_summary.json").write_text(json.dumps(summary, indent=2))
    notes = [f"command: `{' '.join(['lerobot-physvla-replay', *sys.argv[1:]])}`"] + ([note] if note else [])
    report.write_report(out, f"lerobot-physvla-replay --mode={args.mode}: {data.repo_id}",
                        report.summary_table(rows, extra_lines, markdown=True), plots, notes)
    if args.write_dataset:
        try:
            write.write_corrected(data, records, out / "dataset", f"{data.repo_id}_physvla")
        except BaseException:
            shutil.rmtree(out / "dataset", ignore_errors=True)
            raise
    print(table)
    if note:
        print(f"note: {note}")
    print(f"physvla replay: {out} (report.md, replay_summary.json, replay_episodes.jsonl, plots/"
          + (", dataset/" if args.write_dataset else "") + ")")
    return summary


def _summary(args, cfg, data, records, extra, note, t_offline) -> dict:
    frames = sum(r["frames"] for r in records)
    changed = sum(r["frames_changed"] for r in records)
    flagged = sum(len(r["flagged"]) for r in records)
    from lerobot_physvla.core.config import PRESETS, differing

    name = min(PRESETS, key=lambda k: (len(differing(cfg, k)), k != "default"))  # the preset it departs least from
    diff = ", ".join(f"{k}={v!r}" for k, v in differing(cfg, name).items())
    lines = {
        "corrector": f"preset {name}" + (f"; fields that differ from it: {diff}" if diff else ""),
        "frames changed (recorded actions)": f"{changed}/{frames} ({changed / max(frames, 1) * 100:.1f} %)",
        "flagged frames": f"{flagged} (gripper close far from the object, release in transport; see replay_episodes.jsonl)",
        "offline replay": f"{frames} frames in {t_offline:.2f} s (kernels loaded once per process included)",
    }
    out = {"mode": args.mode, "dataset": {"repo_id": data.repo_id, "root": str(data.root), "episodes": len(records),
                                         "total_episodes": data.total_episodes, "frames": frames},
           "physvla_config": cfg.to_dict(), "note": note, "frames_changed": changed, "flagged": flagged,
           "offline_frames_per_s": frames / max(t_offline, 1e-9)}
    if args.mode == "resim" and extra:
        n = len(extra)
        raw = sum(x["raw"]["success"] for x in extra)
        cor = sum(x["corrected"]["success"] for x in extra)
        div = [x["state_divergence_m"] for x in extra if x["state_divergence_m"] is not None]
        lines["re-simulated success"] = f"raw {raw}/{n}, corrected {cor}/{n} (success column: recorded/raw/corrected)"
        if div:
            lines["raw re-simulation vs recorded"] = f"largest end-effector divergence {max(div):.2e} m"
        out.update(resim_success_raw=raw, resim_success_corrected=cor, episodes=n,
                   max_state_divergence_m=max(div) if div else None)
    if args.mode == "policy" and extra:
        raw = np.mean([x["mse_raw"] for x in extra], axis=0)
        cor = np.mean([x["mse_corrected"] for x in extra], axis=0)
        fmt = lambda v: "[" + ", ".join(f"{x:.2e}" for x in v) + "]"  # noqa: E731
        lines["policy vs recorded, per-channel MSE"] = f"raw {fmt(raw)}; corrected {fmt(cor)}"
        out.update(mse_raw=raw.tolist(), mse_corrected=cor.tolist())
    out["lines"] = lines
    return out


def main(argv: list[str] | None = None) -> None:
    import datasets as hf_datasets

    from lerobot_physvla.replay.dataset import ReplayError

    argv = sys.argv[1:] if argv is None else argv
    if any(a in ("-h", "--help") for a in argv):
        print(__doc__)
        return
    hf_datasets.disable_progress_bars()
    try:
        args, cfg = parse(argv)
        run(args, cfg)
    except (FlagError, ReplayError, FileExistsError) as e:
        print(f"lerobot-physvla-replay: error: {e}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
