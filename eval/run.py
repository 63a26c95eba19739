"""Run a study file: the episodes it needs that its data does not hold yet, then its README from the data.

    .venv/bin/python eval/run.py eval/studies/table2.toml             # or just: table2
    .venv/bin/python eval/run.py efficacy --compare "rim guide" --role confirm
    .venv/bin/python eval/run.py my_study.toml --workers 2 --backend ray
    .venv/bin/python eval/run.py efficacy --report-only                 # the README from the data alone
    .venv/bin/python eval/run.py --check                                # every study's README against its data

What a study needs: every undecided [[compare]]'s configurations (baseline, reference, candidate, `also`)
on every backbone of its blocks (`--role` / `--compare` narrow it; `--compare` also reaches a decided one,
whose `outcome` is recorded), and every [[run]] entry's configurations on its blocks. An episode is (backbone, configuration hash, scene, task, seed); those already in
eval/results/<study>/episodes.jsonl.gz are not run again. New episodes run in the harness (process pool
or Ray, a progress bar with the ETA; a killed run resumes from its cache under outputs/eval/) and are
added to the data, then the README and plots are written.
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import harness  # noqa: E402
import report  # noqa: E402
from store import Store  # noqa: E402
from study import ROLES, ROOT, STUDIES, Study, find, shown  # noqa: E402

CACHE = ROOT / "outputs" / "eval"


def needed(study: Study, roles=ROLES, only: str | None = None) -> list[tuple]:
    """The cells a study needs: (block, backbone, configuration name). A comparison whose outcome is recorded
    was decided on the episodes it had: its cells run only when `only` names it."""
    cells = []
    for c in study.compares:
        if only and only.lower() not in c.name.lower():
            continue
        if c.outcome and not only:
            continue
        for role in roles:
            for bn in c.blocks.get(role, []):
                bl = study.blocks[bn]
                cells += [(bl, b, name) for b in bl.backbones for name in study.all_configs_of(c)]
    if not only:
        for r in study.raw.get("run", []):
            for bn in r["blocks"]:
                bl = study.blocks[bn]
                names = study.expand(r["backbones"]) if "backbones" in r else bl.backbones
                cells += [(bl, b, name) for b in names for name in r["configs"]]
    return list(dict.fromkeys(cells))


def only_blocks(study: Study, cells: list[tuple], blocks: str | None) -> list[tuple]:
    """The cells of the blocks named (comma-separated), or all of them; an unknown name is an error."""
    if not blocks:
        return cells
    names = [b.strip() for b in blocks.split(",") if b.strip()]
    unknown = [b for b in names if b not in study.blocks]
    if unknown:
        raise SystemExit(f"eval: study {study.name} has no block(s) {unknown}; its blocks: {', '.join(study.blocks)}")
    return [c for c in cells if c[0].name in names]


def missing(study: Study, store: Store, cells) -> dict[tuple, list[int]]:
    """The episodes of `cells` the store does not hold: {(backbone, configuration, scene, task): [seeds]}."""
    todo = defaultdict(list)
    for bl, b, name in cells:
        h = study.config_hash(name, bl.scene)
        for t in bl.tasks:
            for s in bl.seeds:
                if not store.has((b, h, bl.scene, t, s)):
                    todo[(b, name, bl.scene, t)].append(s)
    return todo


def missing_units(study: Study, todo: dict[tuple, list[int]], per_unit: int, checkpoints: str) -> list[harness.Unit]:
    """Harness units for the missing episodes: runs of consecutive seeds of one (backbone, configuration,
    scene, task), at most `per_unit` episodes each."""
    policies = {}
    units = []
    for (b, name, scene, t), seeds in todo.items():
        spec = study.backbone_spec(b)
        policy = ""
        if "policy" in spec:
            if b not in policies:
                path = study.policy_path(b, checkpoints)
                if not (path / "model.safetensors").exists():
                    raise SystemExit(f"eval: no checkpoint for {b} at {path}; run backbones/record_dataset.py then "
                                     f"backbones/train_backbones.py {spec['policy']} (or --checkpoints DIR)")
                policies[b] = str(path.resolve())
            policy = policies[b]
        seeds = sorted(set(seeds))
        runs, start = [], 0
        for k in range(1, len(seeds) + 1):  # split into consecutive runs of at most per_unit seeds
            if k == len(seeds) or seeds[k] != seeds[k - 1] + 1 or k - start == per_unit:
                runs.append((seeds[start], k - start))
                start = k
        cfg = study.config(name, scene)
        h = study.config_hash(name, scene)
        units += [harness.Unit(b, h, cfg, t, first, n, dict(spec.get("expert", {})), scene, policy)
                  for first, n in runs]
    return units


def run(study: Study, roles=ROLES, only=None, workers=None, backend="process", per_unit=5,
        checkpoints="outputs/train", dry_run=False, blocks: str | None = None) -> int:
    """Run what the study lacks (of the blocks named, if any); returns the number of new episodes."""
    store = Store(study.data[0])
    for other in study.data[1:]:  # episodes another study's data already holds are not run again
        store.add(Store(other).rows)
        store.meta["backbones"].update(Store(other).meta["backbones"])
    todo = missing(study, store, only_blocks(study, needed(study, roles, only), blocks))
    n = sum(len(v) for v in todo.values())
    if dry_run:
        print(f"{study.name}: {len(store.rows)} episodes on disk; {n} to run")
        cells = defaultdict(int)
        for (b, name, scene, _), seeds in todo.items():
            cells[(name, b, scene)] += len(seeds)
        for (name, b, scene), k in sorted(cells.items()):
            print(f"  {k:5d}  {name} / {b} ({scene})")
        return 0
    units = missing_units(study, todo, per_unit, checkpoints)
    print(f"{study.name}: {len(store.rows)} episodes on disk; {n} to run in {len(units)} units")
    if not units:
        return 0
    new = Store(study.data[0])  # the new episodes, their configurations and backbones go here
    for u in units:  # a learned backbone's weights must be the ones its episodes on disk ran with
        what = {"policy_sha256": harness.policy_fingerprint(u.policy)} if u.policy else {"expert": u.expert}
        if store.meta["backbones"].get(u.backbone, what) != what:
            raise SystemExit(f"eval: {u.backbone}'s episodes on disk ran with {store.meta['backbones'][u.backbone]}, "
                             f"now {what}: name the new one differently, or remove its rows")
        new.add_backbone(u.backbone, what)
        new.add_config(u.config)
    records, secs = harness.run_units(units, CACHE / study.results.name, workers, backend)
    new.add(records)
    new.write()
    print(f"{study.name}: {n} episodes in {secs / 60:.1f} min added to {shown(study.data[0])}")
    return n


def rows_of(study: Study) -> list[dict]:
    """Every episode of the study's data directories (one row per episode key)."""
    rows = {}
    for d in study.data:
        rows.update({tuple(r[k] for k in ("backbone", "config", "scene", "task_id", "seed")): r for r in Store(d).rows})
    return list(rows.values())


def write_report(study: Study) -> Path:
    rows = rows_of(study)
    study.results.mkdir(parents=True, exist_ok=True)
    path = study.results / "README.md"
    path.write_text(report.readme(study, rows))
    return path


def check_all() -> list[str]:
    """Studies whose README differs from what their data gives now (plots are not redrawn)."""
    bad = []
    for f in sorted(STUDIES.glob("*.toml")):
        study = Study(f)
        if not (study.results / "README.md").exists():
            continue
        want = report.readme(study, rows_of(study), write_plots=False)
        if (study.results / "README.md").read_text() != want:
            bad.append(study.name)
    return bad


def spans(seeds) -> str:
    """15, 16, 17, 20 -> '15-17, 20'."""
    out, run_ = [], []
    for s in sorted(set(seeds)):
        if run_ and s != run_[-1] + 1:
            out.append(f"{run_[0]}-{run_[-1]}" if len(run_) > 1 else str(run_[0]))
            run_ = []
        run_.append(s)
    if run_:
        out.append(f"{run_[0]}-{run_[-1]}" if len(run_) > 1 else str(run_[0]))
    return ", ".join(out)


def seeds_used(scene: str) -> list[str]:
    """Every study's blocks on a scene (a LIBERO suite, metaworld, lift_plate, ...), by first seed: the study, the
    block, its role, its seeds and tasks. Demonstrations and selection blocks outside study files are not here
    (backbones/README.md says which init states the recorded datasets hold)."""
    rows = []
    for f in sorted(STUDIES.glob("*.toml")):
        study = Study(f)
        for b, role in study.seed_roles():
            if b.scene == scene:
                rows.append((min(b.seeds), f"{spans(b.seeds):<10} {study.name:<24} {b.name:<18} {role:<15} "
                                           f"{spans(b.tasks)}"))
    head = f"{'seeds':<10} {'study':<24} {'block':<18} {'role':<15} tasks"
    return [head] + [r for _, r in sorted(rows)] if rows else [f"no study runs a block on {scene!r}"]


def listing() -> list[str]:
    """Every study file: its name, the episodes its data holds, its title."""
    out = []
    for f in sorted(STUDIES.glob("*.toml")):
        study = Study(f)
        out.append(f"{study.name:<24} {len(rows_of(study)):>6}  {study.title}")
    return [f"{'study':<24} {'episodes':>6}  title"] + out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("study", nargs="?", help="a study file, or a name under eval/studies/")
    ap.add_argument("--role", choices=(*ROLES, "all"), default="all", help="which blocks of the comparisons to run")
    ap.add_argument("--compare", default=None, help="only the comparisons whose name contains this")
    ap.add_argument("--blocks", default=None,
                    help="only these blocks (comma-separated), e.g. the suite whose backbones have trained")
    ap.add_argument("--workers", type=int, default=None, help="local processes (default: every core)")
    ap.add_argument("--backend", choices=harness.BACKENDS, default="process",
                    help="process pool, or ray (joins $RAY_ADDRESS or starts a local Ray)")
    ap.add_argument("--per-unit", type=int, default=5, help="episodes per unit of work")
    ap.add_argument("--checkpoints", default="outputs/train", help="where backbones/train_backbones.py wrote")
    ap.add_argument("--dry-run", action="store_true", help="say how many episodes would run, run none")
    ap.add_argument("--report-only", action="store_true", help="run nothing; write the README from the data")
    ap.add_argument("--check", action="store_true", help="compare every study's README with its data; exit 1 if any differ")
    ap.add_argument("--seeds-used", metavar="SCENE", default=None,
                    help="list every study's blocks on a scene (libero_goal, metaworld, ...): which seeds are taken")
    ap.add_argument("--list", action="store_true", help="list every study: its episodes on disk and its title")
    args = ap.parse_args()
    if args.list:
        print("\n".join(listing()))
        return
    if args.seeds_used:
        print("\n".join(seeds_used(args.seeds_used)))
        return
    if args.check:
        bad = check_all()
        print("every study's README matches its data" if not bad else f"out of date: {', '.join(bad)}")
        raise SystemExit(1 if bad else 0)
    if not args.study:
        ap.error("name a study (eval/studies/*.toml)")
    study = Study(find(args.study))
    if not args.report_only:
        roles = ROLES if args.role == "all" else (args.role,)
        run(study, roles, args.compare, args.workers, args.backend, args.per_unit, args.checkpoints, args.dry_run,
            args.blocks)
    if not args.dry_run:
        path = write_report(study)
        print(path.read_text())
        print(f"wrote {shown(path)} and its plots")


if __name__ == "__main__":
    main()
