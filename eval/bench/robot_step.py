"""Per control tick on the simulated arms: the corrector's added latency against the tick period.

    .venv/bin/python eval/bench/robot_step.py [--ticks 3000] [--fps 30] [--out eval/results/bench_robot_step]

The loop lerobot-rollout runs (robot observation -> policy action -> robot action processor ->
send_action) on `physvla_sim_so101` and `physvla_sim_panda` (0.024 deg of reading noise), with a
scripted policy that moves the arm and closes the gripper part of the time, with the shipped
default and with phys_el (Branch B and its noise guard), through lerobot's own
RobotProcessorPipeline: once with its
default robot action processor (an identity step: what a rollout without the corrector pays) and
once with PhysVLARobotActionStep after it, the two interleaved tick by tick. The added latency is
the difference of the two processors' times at the same tick. Prints the table and, last, for the
SO-101 with the shipped default: `robot step p50 <x> us, p99 <y> us, tick period <z> us`.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from lerobot.processor import RobotProcessorPipeline
from lerobot.processor.converters import robot_action_observation_to_transition, transition_to_robot_action
from lerobot.processor.factory import make_default_robot_action_processor

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep
from lerobot_physvla.robots.physvla_sim_panda import SimPanda, SimPandaConfig
from lerobot_physvla.robots.physvla_sim_so101 import SimSO101, SimSO101Config

def policy(robot, t: int) -> dict:
    """A slow sweep of every joint around the arm's start (20 deg on the SO-101, 5 on the Panda), the
    gripper closing for a third of each 90-tick cycle."""
    spec = robot.spec
    q0 = np.asarray(getattr(robot.config, "start_q", np.zeros(len(spec.joints))))
    amp = 20.0 if spec.name == "so101" else 5.0
    q = q0 + np.deg2rad(amp) * np.sin(2 * np.pi * t / 90.0 + np.arange(len(q0))) / spec.to_radians
    a = {f"{m}.pos": float(v) for m, v in zip(spec.motors, q)}
    a["gripper.pos"] = 0.0 if (t % 90) < 30 else 100.0
    return a


CASES = {  # name: (robot class, config class, block, target, corrector mode or None for the shipped default)
    "SO-101, shipped default": (SimSO101, SimSO101Config, [0.25, 0.1, 0.02], [0.2, -0.15, 0.02], None),
    "SO-101, phys_el + noise guard": (SimSO101, SimSO101Config, [0.25, 0.1, 0.02], [0.2, -0.15, 0.02], "phys_el"),
    "Panda, shipped default": (SimPanda, SimPandaConfig, [0.55, 0.1, 0.02], [0.5, -0.2, 0.02], None),
    "Panda, phys_el + noise guard": (SimPanda, SimPandaConfig, [0.55, 0.1, 0.02], [0.5, -0.2, 0.02], "phys_el"),
}


def bench(case: str, ticks: int, fps: float) -> dict:
    """Times lerobot's default robot action processor and the corrected one, interleaved per tick."""
    robot_cls, cfg_cls, block, target, mode = CASES[case]
    robot = robot_cls(cfg_cls(fps=int(fps), block_xyz=block, joint_noise_deg=0.024,
                              calibration_dir=Path(tempfile.mkdtemp())))
    robot.connect()
    base = make_default_robot_action_processor()
    kw = {} if mode is None else {"config": PhysVLAConfig.paper(mode=mode).to_dict()}
    step = PhysVLARobotActionStep(arm=robot.spec.name, fps=fps, object_key="block", target_xyz=target, **kw)
    corrected = RobotProcessorPipeline(steps=[*make_default_robot_action_processor().steps, step],
                                       to_transition=robot_action_observation_to_transition,
                                       to_output=transition_to_robot_action)
    clock = time.perf_counter
    t_base, t_corr, changed = [], [], 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the noise guard's one warning
        for t in range(ticks + 1):
            obs = robot.get_observation()
            a = policy(robot, t)
            order = (base, corrected) if t % 2 else (corrected, base)
            outs = {}
            for proc in order:
                t0 = clock()
                outs[id(proc)] = proc((dict(a), obs))
                (t_base if proc is base else t_corr).append(clock() - t0)
            out = outs[id(corrected)]
            changed += out != a
            robot.send_action(out)
    base_us, corr_us = np.array(t_base[1:]) * 1e6, np.array(t_corr[1:]) * 1e6
    return {"base": base_us, "corrected": corr_us, "added": corr_us - base_us, "first_us": t_corr[0] * 1e6,
            "changed": int(changed), "branch_b_off": dict(step.branch_b_off)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ticks", type=int, default=3000)
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--out", default="eval/results/bench_robot_step")
    args = ap.parse_args()
    period_us = 1e6 / args.fps
    res = {case: bench(case, args.ticks, args.fps) for case in CASES}
    lines = [
        "# The corrector per control tick on the simulated arms\n",
        f"Command: `{' '.join(['.venv/bin/python', *sys.argv])}`  ",
        f"Machine: {platform.processor() or platform.machine()}, {platform.python_version()}, "
        f"{len(os.sched_getaffinity(0))} cores; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}  ",
        f"{args.ticks} ticks at {args.fps:g} Hz (period {period_us:.0f} us) per case of robot observation (0.024 deg "
        "of reading noise) -> scripted joint targets -> robot action processor -> send_action; lerobot's default "
        "robot action processor and the one with PhysVLARobotActionStep after it, timed at every tick, "
        "interleaved; `added` is their difference at the same tick.\n",
        "| case | default processor p50 (us) | added p50 (us) | added p99 (us) | added max (us) | added p50 / period "
        "| first corrected tick (us) | ticks changed | Branch B off (ticks) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for case, r in res.items():
        p50, p99 = np.percentile(r["added"], [50, 99])
        off = sum(r["branch_b_off"].values()) if "phys_el" in case else "-"
        lines.append(f"| {case} | {np.median(r['base']):.1f} | {p50:.1f} | {p99:.1f} | {r['added'].max():.0f} | "
                     f"{p50 / period_us:.4f} | {r['first_us']:.0f} | {r['changed']} of {args.ticks + 1} | {off} |")
    so = res["SO-101, shipped default"]["added"]
    last = (f"robot step p50 {np.percentile(so, 50):.1f} us, p99 {np.percentile(so, 99):.1f} us, "
            f"tick period {period_us:.0f} us")
    lines.append(f"\n{last}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "README.md").write_text("\n".join(lines) + "\n")
    (out / "results.json").write_text(json.dumps({case: {
        "added_p50_us": float(np.median(r["added"])), "added_p99_us": float(np.percentile(r["added"], 99)),
        "default_p50_us": float(np.median(r["base"])), "first_us": r["first_us"], "changed_ticks": r["changed"],
        "branch_b_off": r["branch_b_off"]} for case, r in res.items()}, indent=1))
    print("\n".join(lines[4:]))


if __name__ == "__main__":
    main()
