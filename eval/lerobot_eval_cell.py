"""One study cell again through lerobot's own evaluation: `lerobot-eval --policy.postprocess=physvla` with cameras on
the cell's backbone, scene, tasks and init states, episode by episode against the harness's stored episodes.

    .venv/bin/python eval/lerobot_eval_cell.py camera_libero_pro --block original \
        --backbone object_act_camera_weak --configs "baseline,shipped default" --out eval/results/lerobot_eval_cell
    .venv/bin/python eval/lerobot_eval_cell.py --report-only eval/results/lerobot_eval_cell   # the README again

Each configuration runs beside the others, one lerobot-eval process per task (one torch thread; a killed run
resumes at the first task without output), its flags the study's own spelling of the configuration (`preset = "paper", mode = "baseline"` -> `--physvla.preset=paper
--physvla.mode=baseline`); the configuration lerobot-eval reports it ran (physvla_diagnostics.json) must hash as the
study's. Task t's episode k starts from init state first + k (`--env.first_init_state`), as the harness's seed.
Writes `records.json` (every pair) and a README from it into --out; lerobot-eval's own output stays under outputs/.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from store import Store, config_hash  # noqa: E402
from study import ROOT, Study, find  # noqa: E402

LEROBOT_EVAL = Path(".venv/bin/lerobot-eval")  # run from ROOT, as the README's commands
RUNS = Path("outputs") / "eval" / "lerobot_eval_cell"  # lerobot-eval's own output, under ROOT


def flag_value(v) -> str:
    """A study's TOML value as a --physvla flag spells it."""
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, (list, tuple)):
        return "[" + ",".join(str(x) for x in v) + "]"
    return str(v)


def scene_args(scene: str) -> list[str]:
    """`libero_object_swap+agentview64` -> the env flags that render that suite's agentview at 64 x 64."""
    suite, _, camera = scene.partition("+")
    if not camera.startswith("agentview"):
        raise SystemExit(f"lerobot_eval_cell: {scene!r} is not a camera scene (<suite>+agentview<size>)")
    size = camera.removeprefix("agentview") or "128"
    return [f"--env.task={suite}", f"--env.observation_height={size}", f"--env.observation_width={size}",
            "--env.camera_name=agentview_image"]


def command(study: Study, block: str, backbone: str, config: str, out: Path, tasks=None, episodes=None) -> list[str]:
    """The lerobot-eval command that runs `config` on `backbone` over the block's tasks and init states (or the
    first `episodes` init states of `tasks`)."""
    b = study.blocks[block]
    if backbone not in b.backbones:
        raise SystemExit(f"lerobot_eval_cell: block {block!r} runs {list(b.backbones)}, not {backbone!r}")
    seeds, tasks = list(b.seeds)[:episodes], list(tasks if tasks is not None else b.tasks)
    if not set(tasks) <= set(b.tasks):
        raise SystemExit(f"lerobot_eval_cell: block {block!r} runs tasks {list(b.tasks)}, not {tasks}")
    if seeds != list(range(seeds[0], seeds[0] + len(seeds))):
        raise SystemExit(f"lerobot_eval_cell: block {block!r}'s init states {seeds} are not consecutive")
    spec = study.spec(config)
    policy = study.policy_path(backbone).resolve().relative_to(ROOT)
    return [str(LEROBOT_EVAL), f"--policy.path={policy}", "--env.type=libero_physvla", *scene_args(b.scene),
            f"--env.task_ids=[{','.join(str(t) for t in tasks)}]", f"--env.first_init_state={seeds[0]}",
            f"--eval.n_episodes={len(seeds)}", "--eval.batch_size=1", "--policy.device=cpu",
            "--policy.postprocess=physvla", *[f"--physvla.{k}={flag_value(v)}" for k, v in spec.items()],
            f"--output_dir={out}"]


def pairs(study: Study, block: str, backbone: str, config: str, out: Path) -> list[dict]:
    """lerobot-eval's episodes in `out` beside the harness's stored episode of the same task and init state."""
    b = study.blocks[block]
    out = ROOT / out
    ran = json.loads((out / "physvla_diagnostics.json").read_text())["physvla_config"]
    want = study.config_hash(config, b.scene)
    if config_hash(ran) != want:
        raise SystemExit(f"lerobot_eval_cell: lerobot-eval ran configuration {config_hash(ran)} for {config!r}, "
                         f"the study's is {want}")
    stored = {(r["task_id"], r["seed"]): r for d in study.data for r in Store(d).rows
              if r["backbone"] == backbone and r["config"] == want and r["scene"] == b.scene}
    rows = []
    for line in (out / "physvla_episodes.jsonl").read_text().splitlines():
        e = json.loads(line)
        seed = b.seeds[0] + e["episode"]
        h = stored.get((e["task_id"], seed))
        rows.append({"config": config, "task_id": e["task_id"], "seed": seed,
                     "lerobot_eval": {"success": bool(e["success"]), "steps": e["steps"],
                                      "changed": e["corrected_fraction"]},
                     "harness": None if h is None else {"success": bool(h["success"]), "steps": h["steps"],
                                                        "changed": h["changed_fraction"]}})
    return rows


def report(records: dict) -> str:
    rows = records["pairs"]
    lines = [f"<!-- made by: {records['command']} -->",
             f"# {records['backbone']} through lerobot-eval against the harness ({records['study']}, {records['block']})",
             "",
             f"The cell {records['scene']}, tasks {records['tasks']}, init states {records['seeds']} of "
             f"eval/studies/{records['study']}.toml, run again by `lerobot-eval --policy.postprocess=physvla` with "
             "cameras (the configurations side by side, one lerobot-eval per task, this CPU) and paired, episode by episode, with the episode the "
             "study's harness stored. Generated by eval/lerobot_eval_cell.py from records.json.",
             "",
             "| configuration | episodes | harness successes | lerobot-eval successes | difference | same outcome | "
             "both succeed: steps equal | mean steps changed, harness / lerobot-eval | lerobot-eval time, this call (min) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for config in records["configs"]:
        mine = [r for r in rows if r["config"] == config and r["harness"]]
        h = sum(r["harness"]["success"] for r in mine)
        e = sum(r["lerobot_eval"]["success"] for r in mine)
        same = sum(r["harness"]["success"] == r["lerobot_eval"]["success"] for r in mine)
        both = [r for r in mine if r["harness"]["success"] and r["lerobot_eval"]["success"]]
        equal = sum(r["harness"]["steps"] == r["lerobot_eval"]["steps"] for r in both)
        ch = sum(r["harness"]["changed"] for r in mine) / max(len(mine), 1)
        ce = sum(r["lerobot_eval"]["changed"] for r in mine) / max(len(mine), 1)
        lines.append(f"| {config} | {len(mine)} | {h} | {e} | {e - h:+d} | {same} / {len(mine)} | "
                     f"{equal} / {len(both)} | {ch:.1%} / {ce:.1%} | {records['wall_s'][config] / 60:.1f} |")
    for config, cmd in records.get("lerobot_eval_first_task", {}).items():
        lines += ["", f"{config}, one lerobot-eval per task (the first):", "", "```", cmd, "```"]
    missing = [r for r in rows if not r["harness"]]
    if missing:
        lines += ["", f"{len(missing)} lerobot-eval episodes have no stored harness episode (not counted above)."]
    if len(records["configs"]) == 2:
        a, c = records["configs"]
        lines += ["", f"Paired {c} against {a} on the same init states, each path on its own:", "",
                  "| path | won / lost | net |", "|---|---|---|"]
        for path in ("harness", "lerobot_eval"):
            by = {(r["task_id"], r["seed"], r["config"]): r[path]["success"] for r in rows if r[path]}
            keys = {(t, s) for t, s, _ in by}
            won = sum(by.get((t, s, c), False) and not by.get((t, s, a), True) for t, s in keys)
            lost = sum(by.get((t, s, a), False) and not by.get((t, s, c), True) for t, s in keys)
            lines.append(f"| {path.replace('_', '-')} | {won} / {lost} | {won - lost:+d} |")
    differ = [r for r in rows if r["harness"] and r["harness"]["success"] != r["lerobot_eval"]["success"]]
    if differ:
        lines += ["", "Episodes whose outcome differs between the paths:", "",
                  "| configuration | task | init state | harness (steps) | lerobot-eval (steps) |", "|---|---|---|---|---|"]
        for r in differ:
            fmt = lambda x: f"{'success' if x['success'] else 'failure'} ({x['steps']})"  # noqa: E731
            lines.append(f"| {r['config']} | {r['task_id']} | {r['seed']} | {fmt(r['harness'])} | "
                         f"{fmt(r['lerobot_eval'])} |")
    return "\n".join(lines) + "\n"


def run_dir(study: Study, block: str, backbone: str, config: str) -> Path:
    return RUNS / study.name / f"{block}_{backbone}_{config.replace(' ', '_')}"


def run_config(study: Study, block: str, backbone: str, config: str, tasks: list[int],
               episodes: int | None) -> tuple[list[dict], float]:
    """One lerobot-eval process per task, one after another (a killed run resumes at the first task without
    output); (the pairs, seconds lerobot-eval ran now)."""
    base, secs = run_dir(study, block, backbone, config), 0.0
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONWARNINGS": "ignore"}
    rows = []
    for t in tasks:
        out = base / f"task{t}"
        if not (ROOT / out / "physvla_episodes.jsonl").exists():
            shutil.rmtree(ROOT / out, ignore_errors=True)  # lerobot-eval writes into a fresh folder
            (ROOT / base).mkdir(parents=True, exist_ok=True)
            cmd = command(study, block, backbone, config, out, [t], episodes)
            print("+ " + shlex.join(cmd), flush=True)
            t0 = time.time()
            with open(ROOT / base / f"task{t}.log", "w") as log:
                if subprocess.run(cmd, cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT).returncode != 0:
                    raise SystemExit(f"lerobot_eval_cell: lerobot-eval failed for {config!r}, task {t}; its output: "
                                     f"{log.name}")
            secs += time.time() - t0
        rows += pairs(study, block, backbone, config, out)
    return rows, secs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("study", nargs="?", help="a study name or file (its blocks, backbones, configurations, episodes)")
    ap.add_argument("--block", help="the block whose cell runs")
    ap.add_argument("--backbone", help="one backbone of that block")
    ap.add_argument("--configs", default="baseline", help="comma-separated configuration names, run side by side")
    ap.add_argument("--tasks", default=None, help="a subset of the block's tasks, comma-separated (a quick look)")
    ap.add_argument("--episodes", type=int, default=None, help="the block's first N init states only (a quick look)")
    ap.add_argument("--out", default="eval/results/lerobot_eval_cell", help="records.json and README.md")
    ap.add_argument("--report-only", metavar="DIR", help="write DIR/README.md from DIR/records.json and stop")
    args = ap.parse_args()
    if args.report_only:
        d = Path(args.report_only)
        (d / "README.md").write_text(report(json.loads((d / "records.json").read_text())))
        print(f"wrote {d / 'README.md'}")
        return
    if not (args.study and args.block and args.backbone):
        ap.error("give a study, --block and --backbone (or --report-only DIR)")
    study = Study(find(args.study))
    if args.block not in study.blocks:
        raise SystemExit(f"lerobot_eval_cell: {study.name} has no block {args.block!r}; one of {', '.join(study.blocks)}")
    tasks = [int(t) for t in args.tasks.split(",")] if args.tasks else None
    configs = [c.strip() for c in args.configs.split(",") if c.strip()]
    unknown = [c for c in configs if c not in study.config_specs]
    if unknown:
        raise SystemExit(f"lerobot_eval_cell: {study.name} has no configuration {unknown}; "
                         f"one of {', '.join(study.config_specs)}")
    b = study.blocks[args.block]
    tasks = tasks or list(b.tasks)
    for c in configs:  # resolved once, before the threads
        study.config_hash(c, b.scene)
    with ThreadPoolExecutor(len(configs)) as pool:  # the configurations side by side, each task after task
        done = dict(zip(configs, pool.map(lambda c: run_config(study, args.block, args.backbone, c, tasks,
                                                               args.episodes), configs)))
    rows = [r for c in configs for r in done[c][0]]
    records = {"command": shlex.join([".venv/bin/python", "eval/lerobot_eval_cell.py", *sys.argv[1:]]),
               "study": study.name, "block": args.block, "backbone": args.backbone, "scene": b.scene,
               "tasks": ",".join(str(t) for t in tasks),
               "seeds": f"{b.seeds[0]}-{list(b.seeds)[:args.episodes][-1]}", "configs": configs,
               "wall_s": {c: done[c][1] for c in configs},
               "lerobot_eval_first_task": {c: shlex.join(command(study, args.block, args.backbone, c, run_dir(
                   study, args.block, args.backbone, c) / f"task{tasks[0]}", tasks[:1], args.episodes)) for c in configs},
               "pairs": rows}
    dest = Path(args.out)
    dest.mkdir(parents=True, exist_ok=True)
    (dest / "records.json").write_text(json.dumps(records, indent=1))
    (dest / "README.md").write_text(report(records))
    print(report(records))


if __name__ == "__main__":
    main()
