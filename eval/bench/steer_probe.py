"""Probe: would a pull toward the object's true position, from farther than the centre guide reaches, rescue a camera
policy under LIBERO-PRO's position perturbations? A design probe for a correction not yet in the corrector.

    .venv/bin/python eval/bench/steer_probe.py --suite libero_object_swap --tasks 0-9 --init 10 \\
        --policy backbones/checkpoints/camera/object_act_camera [--json out.json]

Under LIBERO-PRO's swap the camera ACTs (eval/studies/camera_libero_pro.toml) descend where the object was in their
demonstrations, 15-20 cm from where it is, and close there: the shipped default holds those closes open (the approach
veto) and the centre guide, whose zone ends at the rim zone (delta_grasp + span, ~12 cm), does not pull. This probe
runs each episode twice, as the harness does (eval/harness.py run_episode, the agentview at 64 px): under the shipped
default, and under the shipped default followed by a pull written here (not in lerobot_physvla):

    in the approach and grasp phases, the object not lifted (under 2 cm), the hand under HOVER_M above the object's
    origin and within REACH_M of it horizontally, settled (moved under 1 cm in 5 steps; once pulling, on until a
    condition fails): x, y <- clip((p_obj - p_eef)_xy / metres_per_unit, -1, 1), z and the gripper as the default
    left them; a policy's close within CLOSE_M of the object ends the pull (farther, the approach veto holds it open).

Init states 40-49 are refused; the camera_libero_pro study's blocks (init states 5-9 of the LIBERO-PRO suites, 30-34
of LIBERO-Object) are refused too, so that a probe never looks at the blocks a later confirmation runs on.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "eval"))
sys.path.insert(0, str(ROOT / "eval" / "bench"))
from shape_expert_probe import parse_range  # noqa: E402

REACH_M = 0.40  # the pull's zone: the hand within this of the object horizontally, metres
HOVER_M = 0.12  # ... and under this above the object's origin, metres
CLOSE_M = 0.03  # a close within this of the object ends the pull, metres
SETTLE_M, SETTLE_STEPS = 0.01, 5  # settled: moved under SETTLE_M (x, y) in SETTLE_STEPS control steps
LIFTED_M = 0.02  # the object counts as lifted above this, metres
REFUSED = {"libero_object": range(30, 35)}  # camera_libero_pro's blocks (every other suite, LIBERO-PRO's: 5-9)
HELD_OUT = range(40, 50)


class SteeredCorrector:
    """The shipped default's corrector, then the probe's pull (module doc) on its output; the harness's interface."""

    def __init__(self, inner):
        self.inner = inner
        self.layout = inner.layout
        self.track: list[np.ndarray] = []
        self.on = False
        self.pulled = 0

    def reset(self):
        self.inner.reset()
        self.track, self.on, self.pulled = [], False, 0

    @property
    def last(self):
        return self.inner.last

    @property
    def passthrough_counts(self):
        return self.inner.passthrough_counts

    def __call__(self, raw, st):
        out = self.inner(raw, st)
        d = self.inner.last
        lay = self.layout
        eef, obj = st.eef_pos[0], st.obj_pos[0]
        self.track.append(eef[:2].copy())
        rho = float(np.hypot(*(eef[:2] - obj[:2])))
        closing = lay.gripper is not None and bool(lay.closes(raw[0, lay.gripper]))
        settled = len(self.track) > SETTLE_STEPS and np.linalg.norm(self.track[-1] - self.track[-1 - SETTLE_STEPS]) < SETTLE_M
        on = (int(d.phase[0]) in (0, 1) and d.lift[0] < LIFTED_M and eef[2] - obj[2] < HOVER_M and rho < REACH_M
              and (settled or self.on) and not (closing and rho < CLOSE_M) and np.all(np.isfinite(out)))
        self.on = bool(on)
        if on:
            out = out.copy()
            for k, c in ((lay.pos[0], 0), (lay.pos[1], 1)):
                out[0, k] = np.clip((obj[c] - eef[c]) / lay.metres_per_unit, lay.low, lay.high)
            self.pulled += 1
        return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--suite", default="libero_object_swap")
    ap.add_argument("--tasks", default="0-9")
    ap.add_argument("--init", default="10", help="init states, e.g. 10-11")
    ap.add_argument("--policy", default="backbones/checkpoints/camera/object_act_camera")
    ap.add_argument("--size", type=int, default=64, help="the agentview's pixels (the policy's input)")
    ap.add_argument("--json", default="")
    args = ap.parse_args(argv)
    inits = parse_range(args.init)
    study_block = REFUSED.get(args.suite, range(5, 10))  # a LIBERO-PRO suite: its init states 5-9
    refused = [i for i in inits if i in HELD_OUT or i in study_block]
    if refused:
        raise SystemExit(f"steer_probe: init states {refused} are held out or confirmation blocks; not run")

    import torch

    torch.set_num_threads(1)
    from backbones import LeRobotBackbone
    from harness import _scene, run_episode

    from lerobot_physvla.core.config import PhysVLAConfig
    from lerobot_physvla.core.corrector import Corrector

    policy = LeRobotBackbone(str(ROOT / args.policy))
    cfg = PhysVLAConfig().for_policy(getattr(policy, "actions_per_call", 1))
    rows = []
    t0 = time.time()
    for task in parse_range(args.tasks):
        scene = _scene(f"{args.suite}+agentview{args.size}/{task}")
        for init in inits:
            row = {"suite": args.suite, "task": task, "init": init}
            for name in ("shipped default", "default + pull"):
                corr = Corrector(cfg)
                corr = SteeredCorrector(corr) if name == "default + pull" else corr
                rec = run_episode(scene, corr, policy, init)
                row[name] = bool(rec["success"])
                if name == "default + pull":
                    row["pulled_steps"] = corr.pulled
            rows.append(row)
            print(f"task {task} init {init}: shipped default {'yes' if row['shipped default'] else 'no'}, "
                  f"default + pull {'yes' if row['default + pull'] else 'no'} ({row['pulled_steps']} steps pulled)",
                  flush=True)
    a = sum(r["shipped default"] for r in rows)
    b = sum(r["default + pull"] for r in rows)
    won = sum(r["default + pull"] and not r["shipped default"] for r in rows)
    lost = sum(r["shipped default"] and not r["default + pull"] for r in rows)
    print(f"{args.suite}, {Path(args.policy).name}, {len(rows)} pairs: shipped default {a}/{len(rows)}, "
          f"default + pull {b}/{len(rows)} (won {won}, lost {lost}); {time.time() - t0:.0f} s")
    if args.json:
        Path(args.json).write_text(json.dumps({"argv": sys.argv, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)  # robosuite's EGL context fails its own teardown at exit (eval/trace_episode.py)
