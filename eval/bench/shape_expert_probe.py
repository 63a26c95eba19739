"""Success of the clean shape-aware scripted expert (lerobot_physvla.sim.shape_expert) on LIBERO suites, state-only.

Each episode as the harness runs a LIBERO scene (eval/harness.py, sim/scenes.py `LiberoScene`): the env seeded
with the init state's index, reset to that init state, 10 no-op settle steps, then the expert's action each
control step until the task succeeds (LIBERO's `check_success`) or the suite's episode length runs out
(LIBERO's own lengths: spatial 220, object 280, goal 300, libero_10 520). No failure mode is injected.

    python eval/bench/shape_expert_probe.py --suite libero_object --tasks 0-9 --init 0-4
    python eval/bench/shape_expert_probe.py --suite libero_goal --tasks covered --init 0-4 -v

--tasks covered: the suite's pick-place tasks (shape_expert's module doc). Init states 40-49 are refused
(held out).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings

import numpy as np

HORIZON = {"libero_spatial": 220, "libero_object": 280, "libero_goal": 300, "libero_10": 520}
COVERED = {"libero_spatial": list(range(10)), "libero_object": list(range(10)),
           "libero_goal": [1, 2, 4, 6, 8, 9], "libero_10": [0, 1, 4, 5, 6, 7]}
HELD_OUT = range(40, 50)


def parse_range(text: str) -> list[int]:
    """'0-4' / '1,2,4' / '0-2,7' -> a list of ints."""
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


def run_episode(env, task, source, expert, init: int, horizon: int, verbose: bool = False) -> dict:
    from lerobot_physvla.sim import libero_sim

    libero_sim.reset_to_init_state(env, task, init)
    source.reset()
    expert.reset(seed=init)
    success, steps, stages = False, 0, []
    for steps in range(1, horizon + 1):
        a = expert.act_source(source)
        env.step(a)
        source.step()
        stages.append(expert.STAGES[expert.stage])
        if env.check_success():
            success = True
            break
    reached = list(dict.fromkeys(stages))
    out = {"init": init, "success": success, "steps": steps, "last_stage": stages[-1], "subgoal": source.subgoal}
    if verbose:
        out["stages"] = reached
        out["grasp"] = expert.plan.grasp.kind
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--suite", default="libero_object", choices=sorted(HORIZON))
    ap.add_argument("--tasks", default="covered", help="'covered' or e.g. 0-9, 1,2,4")
    ap.add_argument("--init", default="0-4", help="init state indices, e.g. 0-4 (40-49 are refused)")
    ap.add_argument("--horizon", type=int, default=None, help="control steps per episode (default: LIBERO's)")
    ap.add_argument("--json", default="", help="also write the per-episode records here")
    ap.add_argument("-v", "--verbose", action="store_true")
    args = ap.parse_args(argv)
    warnings.filterwarnings("ignore")
    inits = parse_range(args.init)
    if any(i in HELD_OUT for i in inits):
        raise SystemExit("shape_expert_probe: init states 40-49 are held out; not run")
    tasks = COVERED[args.suite] if args.tasks == "covered" else parse_range(args.tasks)
    horizon = args.horizon or HORIZON[args.suite]

    from lerobot_physvla.sim import libero_sim
    from lerobot_physvla.sim.shape_expert import ShapeExpert
    from lerobot_physvla.sources.robosuite import RobosuiteStateSource

    records, t0 = [], time.time()
    for t in tasks:
        task = libero_sim.load_task(args.suite, t)
        env = libero_sim.make_libero_env(task)
        source, expert = None, ShapeExpert()
        ok = 0
        for i in inits:
            if source is None:
                libero_sim.reset_to_init_state(env, task, i)
                source = RobosuiteStateSource(env.env)
            rec = run_episode(env, task, source, expert, i, horizon, args.verbose)
            rec["task"] = t
            records.append(rec)
            ok += rec["success"]
            print(f"{args.suite}/{t} init {i}: {'OK  ' if rec['success'] else 'FAIL'} steps {rec['steps']:3d} "
                  f"stage {rec['last_stage']}" + (f" {rec.get('stages')} {rec.get('grasp')}" if args.verbose else ""),
                  flush=True)
        print(f"== {args.suite}/{t} ({task.language}): {ok}/{len(inits)}", flush=True)
        env.close()
    n_ok = sum(r["success"] for r in records)
    print(f"TOTAL {args.suite} tasks {tasks} init {inits}: {n_ok}/{len(records)} = "
          f"{n_ok / max(len(records), 1):.0%} ({time.time() - t0:.0f} s)")
    for t in tasks:
        rs = [r for r in records if r["task"] == t]
        print(f"  task {t}: {sum(r['success'] for r in rs)}/{len(rs)}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"suite": args.suite, "horizon": horizon, "records": records}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
