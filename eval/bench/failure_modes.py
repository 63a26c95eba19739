"""Why episodes fail: a study's cells run again with the scene's state traced, each episode sorted into an outcome.

    .venv/bin/python eval/bench/failure_modes.py learned_goal_ten --block goal \
        --backbone goal_act_chunk_weak --configs "baseline,shipped default" [--tasks 1,6,8] [--workers 2]

A study's report says how many failures a corrector turned into successes; this says what the failures were. Every
episode of the cells named (the block's tasks and seeds, so the pairs are the study's) runs again through
eval/harness.py's compute_unit, unchanged, on a scene whose reads are recorded, and is sorted by what the task's
movable object did (on a two-object goal, the object of the sub-goal the corrector followed last):

    success                  the task's own success
    never reached            not lifted, and the hand never came within REACH_M of the object's rim and top (its
                             extents from the scene's geometry, state.SCENE; a point where the scene has none)
    reached, not lifted      the hand came that close, but the object never rose LIFT_M above where it rested
    lifted, dropped          lifted, and at the end back down, farther than NEAR_M (xy) from its target
    lifted, held at the end  lifted and still LIFT_M above its rest at the horizon
    on target, no success    lifted, and at the end within NEAR_M (xy) of its target, but the goal is not met

It prints the outcomes per configuration and per task, the paired transitions (the first configuration against each
other), and how many replayed episodes agree with the study's stored success (a replay that disagrees means the run
is not the study's: other weights, code or seeds).
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from tqdm import tqdm

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "eval"))
import harness  # noqa: E402
from run import missing_units  # noqa: E402
from store import Store  # noqa: E402
from study import Study, find  # noqa: E402

from lerobot_physvla.core.state import SCENE  # noqa: E402
from lerobot_physvla.replay.record import parse_range  # noqa: E402

REACH_M = 0.03  # how close (m) the hand must come to the object's rim in the plane and to its top to have reached it
LIFT_M = 0.02  # rise above the object's rest height (m) that counts as lifted
NEAR_M = 0.05  # object-to-target distance in the plane (m) that counts as on target
SWITCH_M = 0.05  # a one-step jump of the tracked object's position (m): the corrector moved on to another object
OUTCOMES = ("success", "never reached", "reached, not lifted", "lifted, dropped", "lifted, held at the end",
            "on target, no success")


class TracedScene:
    """A scene whose reads are recorded: per episode, per step (hand xyz, object xyz, target xyz, the object's radius
    and its top above its origin), metres. Everything else is the wrapped scene's."""

    def __init__(self, scene):
        self._scene = scene
        self.episodes: list[list[np.ndarray]] = []

    def __getattr__(self, name):
        return getattr(self._scene, name)

    def reset(self, seed: int):
        self.episodes.append([])
        return self._scene.reset(seed)

    def read(self):
        st = self._scene.read()
        extents = st.scene[0, [SCENE.index("obj_radius"), SCENE.index("obj_top")]]
        row = np.concatenate([st.eef_pos[0], st.obj_pos[0], st.target_pos[0], extents])
        self.episodes[-1].append(row.astype(float))
        return st


def outcome(success: bool, trace: np.ndarray) -> str:
    """One episode's outcome (OUTCOMES) from its trace: rows (hand xyz, object xyz, target xyz[, the object's radius,
    its top above its origin]) per step, m; extents that are missing or NaN count as 0 (a point object)."""
    if success:
        return "success"
    jumps = np.flatnonzero(np.linalg.norm(np.diff(trace[:, 3:6], axis=0), axis=1) > SWITCH_M) + 1
    start = int(jumps[-1]) if len(jumps) else 0  # the last tracked object, from where it was first seen at rest
    trace = trace[start:]
    hand, obj, target = trace[:, 0:3], trace[:, 3:6], trace[:, 6:9]
    if len(obj) == 0 or not np.isfinite(obj).all():
        return "never reached"
    rise = obj[:, 2] - obj[0, 2]
    if rise.max() >= LIFT_M:
        if rise[-1] >= LIFT_M:
            return "lifted, held at the end"
        if np.linalg.norm(obj[-1, :2] - target[-1, :2]) <= NEAR_M:
            return "on target, no success"
        return "lifted, dropped"
    radius, top = (np.nan_to_num(trace[:, 9]), np.nan_to_num(trace[:, 10])) if trace.shape[1] > 10 else (0.0, 0.0)
    beside = np.linalg.norm(hand[:, :2] - obj[:, :2], axis=1) <= radius + REACH_M  # within reach of its rim
    low = hand[:, 2] - (obj[:, 2] + top) <= REACH_M  # down to its top
    return "reached, not lifted" if np.any(beside & low) else "never reached"


def end_gap_m(trace: np.ndarray) -> float:
    """The tracked object's distance to its target in the plane at the episode's last step, m."""
    return float(np.linalg.norm(trace[-1, 3:5] - trace[-1, 6:8]))


def trace_unit(unit: harness.Unit) -> list[tuple[dict, str, float]]:
    """Run one harness unit (in a worker) on traced scenes; (record, outcome, end_gap_m) per episode."""
    from lerobot_physvla.sim.scenes import cached_scene

    traced: dict[str, TracedScene] = {}

    def scene(name: str) -> TracedScene:
        if name not in traced:
            traced[name] = TracedScene(cached_scene(name))
        return traced[name]

    harness._scene = scene  # compute_unit builds its scene through this: the rest of it runs as in a study
    payload = harness.compute_unit(unit)
    episodes = traced[unit.scene_name].episodes[-unit.episodes:]
    return [(rec, outcome(rec["success"], np.asarray(tr)), end_gap_m(np.asarray(tr)))
            for rec, tr in zip(payload["records"], episodes)]


def table(rows: list[list[str]]) -> str:
    head, *body = rows
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    return "\n".join(lines + ["| " + " | ".join(r) + " |" for r in body])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("study", help="a study file, or a name under eval/studies/")
    ap.add_argument("--block", required=True, help="one of the study's blocks")
    ap.add_argument("--backbone", required=True, help="one backbone of that block")
    ap.add_argument("--configs", required=True, help="comma-separated configurations (semicolon-separated where a name holds a comma); the first "
                    "is the reference")
    ap.add_argument("--tasks", default=None, help="a subset of the block's tasks, e.g. 1,6,8")
    ap.add_argument("--seeds", default=None, help="a subset of the block's seeds, e.g. 5-7")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--checkpoints", default="outputs/train", help="where backbones/train_backbones.py wrote")
    ap.add_argument("--out", default=None, help="also write the report here (markdown, its command at the top)")
    args = ap.parse_args()

    study = Study(find(args.study))
    if args.block not in study.blocks:
        raise SystemExit(f"failure_modes: {study.name} has no block {args.block!r}; its blocks: "
                         f"{', '.join(study.blocks)}")
    block = study.blocks[args.block]
    if block.scene == "so101_pick_place":
        raise SystemExit("failure_modes: the SO-101 robot scene runs through lerobot's robot processor, not a traced "
                         "scene; pick a LIBERO or MetaWorld block")
    if args.backbone not in block.backbones:
        raise SystemExit(f"failure_modes: block {args.block} has no backbone {args.backbone!r}; its backbones: "
                         f"{', '.join(block.backbones)}")
    configs = [c.strip() for c in args.configs.split(";" if ";" in args.configs else ",") if c.strip()]
    unknown = [c for c in configs if c not in study.config_specs]
    if unknown:
        raise SystemExit(f"failure_modes: {study.name} has no configuration(s) {unknown}; its configurations: "
                         f"{', '.join(study.config_specs)}")
    tasks = [t for t in block.tasks if args.tasks is None or t in parse_range(args.tasks)]
    seeds = [s for s in block.seeds if args.seeds is None or s in parse_range(args.seeds)]
    if not tasks or not seeds:
        raise SystemExit(f"failure_modes: no task or seed left; the block's tasks {list(block.tasks)}, seeds "
                         f"{block.seeds[0]}-{block.seeds[-1]}")

    todo = {(args.backbone, c, block.scene, t): seeds for c in configs for t in tasks}
    units = missing_units(study, todo, 5, args.checkpoints)
    results: list[tuple[str, dict, str, float]] = []
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        futures = {pool.submit(trace_unit, u): u for u in units}
        for f in tqdm(futures, desc="units", unit="unit"):
            results += [(futures[f].config_name, rec, out, gap) for rec, out, gap in f.result()]

    names = {study.config_hash(c, block.scene): c for c in configs}
    stored = {(r["backbone"], r["config"], r["scene"], r["task_id"], r["seed"]): r["success"]
              for d in study.data for r in Store(d).rows}
    agree = [stored[k] == rec["success"] for h, rec, _, _ in results
             if (k := (args.backbone, h, block.scene, rec["task_id"], rec["seed"])) in stored]
    by = {(names[h], rec["task_id"], rec["seed"]): out for h, rec, out, _ in results}
    gaps = {(names[h], rec["task_id"], rec["seed"]): gap for h, rec, _, gap in results}

    def cell(c: str, o: str) -> str:
        """How many of configuration c's episodes ended in outcome o, and their object's median end gap to target."""
        g = [gaps[(c, t, s)] for t in tasks for s in seeds if by[(c, t, s)] == o]
        return f"{len(g)} ({np.median(g):.2f} m)" if g else "0"

    lines = [f"{study.name}, block {args.block} ({block.scene}, tasks {tasks}, seeds {seeds[0]}-{seeds[-1]}), "
             f"{args.backbone}: {len(results)} episodes",
             f"success as the study stored it: {sum(agree)} of {len(agree)} replayed episodes agree"
             + ("" if len(agree) else " (the study holds none of them)"), "",
             "episodes per outcome (the object's median distance to its target in the plane at the end, m):",
             table([["outcome", *configs]] + [[o, *(cell(c, o) for c in configs)] for o in OUTCOMES]), "",
             "per task, one digit a seed (" + ", ".join(f"{k} {o}" for k, o in enumerate(OUTCOMES)) + "):"]
    code = {o: str(k) for k, o in enumerate(OUTCOMES)}
    for c in configs:
        lines.append(f"  {c}: " + "  ".join(f"t{t} " + "".join(code[by[(c, t, s)]] for s in seeds) for t in tasks))
    ref = configs[0]
    for c in configs[1:]:
        moves = Counter((by[(ref, t, s)], by[(c, t, s)]) for t in tasks for s in seeds)
        changed = [[a, b, str(n)] for (a, b), n in sorted(moves.items()) if a != b]
        lines += ["", f"{ref} -> {c}, the pairs that changed:",
                  table([[ref, c, "pairs"]] + changed) if changed else "  none"]
    text = "\n".join(lines)
    print("\n" + text)
    if args.out:
        made_by = shlex.join([".venv/bin/python", "eval/bench/failure_modes.py", *sys.argv[1:]])
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(f"Made by: `{made_by}`\n\n```\n{text}\n```\n")
        print(f"wrote {args.out}")

if __name__ == "__main__":
    main()
