"""Per control tick on the simulated SO-101: the corrector's added latency against the tick period.

    .venv/bin/python eval/bench_robot_step.py [--ticks 3000] [--fps 30] [--out eval/results/bench_robot_step]

The loop lerobot-rollout runs (robot observation -> policy action -> robot action processor ->
send_action) on the `physvla_sim_so101` robot, with a scripted policy that moves the arm and
closes the gripper part of the time, through lerobot's own RobotProcessorPipeline: once with its
default robot action processor (an identity step: what a rollout without the corrector pays) and
once with PhysVLARobotActionStep after it, the two interleaved tick by tick. The added latency is
the difference of the two processors' times at the same tick. Prints the table and, last,
`robot step p50 <x> us, p99 <y> us, tick period <z> us`.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from lerobot.processor import RobotProcessorPipeline
from lerobot.processor.converters import robot_action_observation_to_transition, transition_to_robot_action
from lerobot.processor.factory import make_default_robot_action_processor

from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep
from lerobot_physvla.robot_types.physvla_sim_so101 import SimSO101, SimSO101Config

ARM = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")


def policy(t: int) -> dict:
    """A slow sweep of every joint, the gripper closing for a third of each 90-tick cycle."""
    phase = 2 * np.pi * t / 90.0
    a = {f"{m}.pos": float(20.0 * np.sin(phase + k)) for k, m in enumerate(ARM)}
    a["gripper.pos"] = 0.0 if (t % 90) < 30 else 100.0
    return a


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ticks", type=int, default=3000)
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--out", default="eval/results/bench_robot_step")
    args = ap.parse_args()
    robot = SimSO101(SimSO101Config(fps=int(args.fps), block_xyz=[0.25, 0.1, 0.02],
                                    calibration_dir=Path(tempfile.mkdtemp())))
    robot.connect()
    base = make_default_robot_action_processor()
    step = PhysVLARobotActionStep(arm="so101", fps=args.fps, object_key="block", target_xyz=[0.2, -0.15, 0.02])
    corrected = RobotProcessorPipeline(steps=[*make_default_robot_action_processor().steps, step],
                                       to_transition=robot_action_observation_to_transition,
                                       to_output=transition_to_robot_action)
    clock = time.perf_counter
    t_base, t_corr, changed = [], [], 0
    for t in range(args.ticks + 1):
        obs = robot.get_observation()
        a = policy(t)
        order = (base, corrected) if t % 2 else (corrected, base)
        outs = {}
        for proc in order:
            t0 = clock()
            outs[id(proc)] = proc((dict(a), obs))
            (t_base if proc is base else t_corr).append(clock() - t0)
        out = outs[id(corrected)]
        changed += out != a
        robot.send_action(out)
    first_us = t_corr[0] * 1e6
    base_us, corr_us = np.array(t_base[1:]) * 1e6, np.array(t_corr[1:]) * 1e6
    added = corr_us - base_us
    period_us = 1e6 / args.fps
    rows = {
        "lerobot's default processor": base_us, "with PhysVLARobotActionStep": corr_us, "added by the corrector": added,
    }
    lines = [
        "# The corrector per control tick on the simulated SO-101\n",
        f"Command: `{' '.join(['.venv/bin/python', *sys.argv])}`  ",
        f"Machine: {platform.processor() or platform.machine()}, {platform.python_version()}, "
        f"{len(os.sched_getaffinity(0))} cores; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}  ",
        f"{args.ticks} ticks at {args.fps:g} Hz (period {period_us:.0f} us) of robot observation -> scripted joint "
        "targets -> robot action processor -> send_action on `physvla_sim_so101`; the two processors timed at "
        f"every tick, interleaved. The corrector changed the action at {changed} of {args.ticks + 1} ticks. First "
        f"corrected tick: {first_us:.0f} us.\n",
        "| robot action processor | p50 (us) | p99 (us) | max (us) | p50 / tick period |", "|---|---|---|---|---|",
    ]
    for name, v in rows.items():
        p50, p99 = np.percentile(v, [50, 99])
        lines.append(f"| {name} | {p50:.1f} | {p99:.1f} | {v.max():.0f} | {p50 / period_us:.4f} |")
    last = (f"robot step p50 {np.percentile(added, 50):.1f} us, p99 {np.percentile(added, 99):.1f} us, "
            f"tick period {period_us:.0f} us")
    lines.append(f"\n{last}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "README.md").write_text("\n".join(lines) + "\n")
    (out / "results.json").write_text(json.dumps({k: {"p50_us": float(np.median(v)), "p99_us": float(np.percentile(
        v, 99))} for k, v in rows.items()} | {"changed_ticks": int(changed), "first_us": first_us}, indent=1))
    print("\n".join(lines[4:]))


if __name__ == "__main__":
    main()
