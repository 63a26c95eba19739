"""Evaluation harness: units of work over (backbone, mode, task, seed block), run in parallel.

A unit runs its episodes in one process on a state-only LIBERO scene (the core library, no
LeRobot in the loop: the same corrector, state source and metrics that `lerobot-eval
--policy.postprocess=physvla` uses) and writes one JSON of per-episode records. Units already on
disk are skipped, so a killed sweep resumes where it stopped. Units run on a local process pool
(`--workers`, default: the CPU count); each worker keeps the LIBERO scenes it built.
"""

from __future__ import annotations

import json
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

HORIZON = 280  # lerobot's LIBERO-Spatial episode length

# Backbones: the scripted expert with the paper's failure modes injected (experts.ExpertConfig).
BACKBONES: dict[str, dict] = {
    "expert_clean": {},
    # per-step lateral jitter and a grasp-aim error: a memoryless policy's imprecision
    "expert_jitter": {"action_noise": 0.3, "aim_noise_m": 0.015},
    # premature closes, a persistent place bias, no deceleration near the target
    "expert_faulty": {"premature_close": 0.3, "place_bias_m": 0.04, "no_decel": True},
}


@dataclass(frozen=True)
class Unit:
    """One unit of work: `episodes` episodes of one (backbone, config, task) from `first_seed`."""

    backbone: str
    config_name: str
    config: dict = field(hash=False, compare=False)
    task_id: int = 0
    first_seed: int = 0
    episodes: int = 5
    expert: dict = field(default_factory=dict, hash=False, compare=False)

    @property
    def key(self) -> str:
        return f"{self.backbone}__{self.config_name}__t{self.task_id}__s{self.first_seed}-{self.first_seed + self.episodes - 1}"


_SCENES: dict[int, tuple] = {}  # per worker process: task id -> (task, env)


def _scene(task_id: int):
    from lerobot_physvla import libero_sim

    if task_id not in _SCENES:
        task = libero_sim.load_task("libero_spatial", task_id)
        _SCENES[task_id] = (task, libero_sim.make_libero_env(task))
    return _SCENES[task_id]


def run_episode(task, env, corrector, expert, seed: int) -> dict:
    """One episode; returns its record (success, metrics, firing rates, timings)."""
    from lerobot_physvla import libero_sim, metrics
    from lerobot_physvla.robosuite_source import RobosuiteStateSource

    libero_sim.reset_to_init_state(env, task, seed)
    src = RobosuiteStateSource(env.env)
    src.reset()
    corrector.reset()
    expert.reset(seed=seed)
    eef, d_obj, phases, t_a, t_b, t_tot, vetoes, el = [], [], [], [], [], [], 0, 0
    grip = corrector.layout.gripper
    success, steps = False, 0
    for steps in range(1, HORIZON + 1):
        st = src.read()
        raw = expert.act(st.eef_pos[0], st.obj_pos[0], st.target_pos[0])[None]
        out = corrector(raw, st)
        d = corrector.last
        env.step(out[0])
        src.step()
        eef.append(st.eef_pos[0].copy())
        d_obj.append(float(d.d_obj_xy[0]))
        phases.append(int(d.phase[0]))
        t_a.append(d.t_branch_a_s)
        t_b.append(d.t_branch_b_s)
        t_tot.append(d.t_total_s)
        vetoes += int(d.phase[0] == 0 and out[0, grip] != raw[0, grip])
        el += int(d.weights[0].sum() > 0)
        if env.check_success():
            success = True
            break
    eef_a = np.asarray(eef)
    ph = np.asarray(phases)
    dt = float(st.dt[0])
    return {
        "seed": seed, "success": success, "steps": steps,
        "precision": metrics.precision(d_obj), "efficiency": metrics.efficiency(success, steps, HORIZON),
        "stability": metrics.stability(eef_a, dt), "mean_jerk": metrics.mean_jerk(eef_a, dt),
        "sparc": metrics.sparc(eef_a, dt), "ldlj": metrics.ldlj(eef_a, dt),
        "phase_fraction": [float((ph == p).mean()) for p in range(4)],
        "veto_fire_rate": vetoes / max(int((ph == 0).sum()), 1), "el_fire_rate": el / steps,
        "passthrough": dict(corrector.passthrough_counts),
        "t_us_p50": {"a": float(np.median(t_a) * 1e6), "b": float(np.median(t_b) * 1e6), "total": float(np.median(t_tot) * 1e6)},
    }


def run_unit(unit: Unit, out_dir: str) -> str:
    """Run one unit and write `<out_dir>/units/<key>.json`; returns the key."""
    from lerobot_physvla.config import PhysVLAConfig
    from lerobot_physvla.corrector import Corrector
    from lerobot_physvla.experts import ExpertConfig, PickPlaceExpert

    task, env = _scene(unit.task_id)
    corrector = Corrector(PhysVLAConfig.from_dict(unit.config))
    expert = PickPlaceExpert(cfg=ExpertConfig(**unit.expert))
    t0 = time.time()
    records = []
    for k in range(unit.episodes):
        rec = run_episode(task, env, corrector, expert, unit.first_seed + k)
        rec.update(backbone=unit.backbone, config=unit.config_name, task_id=unit.task_id)
        records.append(rec)
    path = Path(out_dir) / "units" / f"{unit.key}.json"
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps({"unit": asdict(unit), "seconds": time.time() - t0, "records": records}))
    tmp.replace(path)  # atomic: a killed sweep never leaves a half-written unit
    return unit.key


def run_units(units: list[Unit], out_dir: str | Path, workers: int | None = None) -> tuple[list[dict], float]:
    """Run the units not yet on disk (process pool, progress bar with ETA); return all records
    and the wall time this call spent."""
    out = Path(out_dir)
    (out / "units").mkdir(parents=True, exist_ok=True)
    todo = [u for u in units if not (out / "units" / f"{u.key}.json").exists()]
    todo.sort(key=lambda u: u.task_id)  # workers reuse the scene they built
    t0 = time.time()
    if todo:
        workers = workers or os.cpu_count() or 1
        print(f"{len(units) - len(todo)} of {len(units)} units already done; running {len(todo)} on {workers} workers")
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = [pool.submit(run_unit, u, str(out)) for u in todo]
            for f in tqdm(as_completed(futures), total=len(futures), desc="units", unit="unit"):
                f.result()
    records = []
    for u in units:
        records += json.loads((out / "units" / f"{u.key}.json").read_text())["records"]
    return records, time.time() - t0


def seed_blocks(n_per_task: int, block: int) -> list[tuple[int, int]]:
    """(first_seed, episodes) blocks covering seeds 0 .. n_per_task - 1."""
    return [(s, min(block, n_per_task - s)) for s in range(0, n_per_task, block)]
