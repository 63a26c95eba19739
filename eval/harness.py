"""Evaluation harness: units of work over (backbone, mode, scene, seed block), run in parallel.

A unit runs its episodes in one process on a state-only scene (lerobot_physvla.sim.scenes: LIBERO,
MetaWorld, robosuite Lift, Fetch) with the core library alone (no LeRobot in the loop for scripted
backbones: the same corrector, state sources and metrics that `lerobot-eval
--policy.postprocess=physvla` uses) and writes one JSON of per-episode records. Units already in the
cache (outputs/eval/<study>/units, ignored by git) are skipped, so a killed sweep resumes where it
stopped; eval/run.py then moves their episodes into the study's data (eval/store.py).

Backends: a local process pool (default; `workers` = the CPU count; each worker keeps the scenes
and policies it built) or Ray (`backend="ray"`): it joins the cluster at $RAY_ADDRESS, or starts
a local one; the harness module travels by value and each unit's records come back to the
driver, which writes them, so workers need lerobot_physvla installed but no shared filesystem.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

sys.path.insert(0, str(Path(__file__).resolve().parent))
from backbones import ExpertBackbone, LeRobotBackbone  # noqa: E402

BACKENDS = ("process", "ray")


@dataclass(frozen=True)
class Unit:
    """One unit of work: `episodes` episodes of one (backbone, config, scene) from `first_seed`.

    Attributes:
        backbone: backbone name (a key of BACKBONES, or a learned backbone's name).
        config_name, config: the configuration's hash (eval/store.py) and the corrector config
            (PhysVLAConfig.to_dict()).
        task_id: LIBERO task id (the libero_* scenes) or MetaWorld task index (the "metaworld" scene:
            sim/metaworld_sim.py TASKS); ignored by other scenes.
        first_seed, episodes: the seed block.
        expert: ExpertConfig fields of the scripted backbone's failure modes.
        scene: a LIBERO suite (with task_id: libero_spatial, libero_object, ..., or a LIBERO-PRO one: libero_object_swap,
            libero_object_temp_x0.3, ..., sim/libero_pro.py), "metaworld" (with task_id: scene
            metaworld/<task_id>), "lift", "lift_plate", "fetch_pick_place", "so101_env" (lerobot-env-so101's
            pick-and-place env: sim/so101_env_sim.py) or "so101_pick_place" (lerobot's robot action processor on the
            simulated SO-101: so101_robot.py).
        policy: checkpoint directory of a learned backbone ("" = scripted expert).
    """

    backbone: str
    config_name: str
    config: dict = field(hash=False, compare=False)
    task_id: int = 0
    first_seed: int = 0
    episodes: int = 5
    expert: dict = field(default_factory=dict, hash=False, compare=False)
    scene: str = "libero_spatial"
    policy: str = ""

    @property
    def scene_name(self) -> str:
        return f"{self.scene}/{self.task_id}" if self._per_task else self.scene

    @property
    def _per_task(self) -> bool:
        """The scene has tasks (LIBERO suites, MetaWorld): task_id picks one."""
        return self.scene.startswith("libero_") or self.scene == "metaworld"

    @property
    def key(self) -> str:
        where = (f"t{self.task_id}" if self.scene == "libero_spatial" else
                 f"{self.scene}_t{self.task_id}" if self._per_task else self.scene)
        return f"{self.backbone}__{self.config_name}__{where}__s{self.first_seed}-{self.first_seed + self.episodes - 1}"


_POLICIES: dict[str, LeRobotBackbone] = {}  # per worker process: checkpoint -> backbone


def _scene(name: str):
    from lerobot_physvla.sim.scenes import cached_scene

    return cached_scene(name)


def _backbone(unit: Unit, scene):
    if not unit.policy:
        return ExpertBackbone(scene, unit.expert)
    if unit.policy not in _POLICIES:
        import torch

        torch.set_num_threads(1)  # one env per core; more threads only spin-wait here
        _POLICIES[unit.policy] = LeRobotBackbone(unit.policy)
    return _POLICIES[unit.policy]


CHANGE_TOL = 1e-6  # action units: a step whose executed action differs from the policy's by more was changed


def _finite_mean(vals: list[float]) -> float:
    vals = [v for v in vals if np.isfinite(v)]
    return float(np.mean(vals)) if vals else float("nan")


def run_episode(scene, corrector, backbone, seed: int, perception=None, on_step=None) -> dict:
    """One episode; returns its record (success, reward, metrics, firing rates, timings).

    Success: at the first successful step for scenes that stop on success (LIBERO, MetaWorld, lift_plate),
    else the scene's check at the last step (Lift, Fetch). perception: a sources.perception.Perception
    between the scene's state and the corrector (the backbone reads the scene's own state).

    How much the corrector did: `changed_fraction` (steps whose executed action differs from the policy's by more
    than CHANGE_TOL), `change_norm` (the mean over steps of |executed - policy|, action units) beside
    `action_norm` (the mean |policy action|).

    on_step(step, state, raw, out, diagnostics): called after each step's correction, before the scene steps
    (eval/trace_episode.py prints an episode from it); raw and out are (1, A) action units."""
    from lerobot_physvla import metrics

    scene.reset(seed)
    corrector.reset()
    backbone.reset(seed)
    if perception is not None:
        perception.reset(seed=seed)
    eef, d_obj, phases, t_a, t_b, t_tot, vetoes, el = [], [], [], [], [], [], 0, 0
    changed, change_norm, action_norm = 0, [], []  # steps the corrector changed; |out - raw|, |raw| (action units)
    grip = corrector.layout.gripper
    success, steps, reward, first_success = False, 0, 0.0, None
    for steps in range(1, scene.horizon + 1):
        st = scene.read()
        raw = np.asarray(backbone.act(scene, st), dtype=np.float64)[None]
        out = corrector(raw, st) if perception is None else corrector.correct_packed(raw, perception.apply(st.pack()))
        d = corrector.last
        if on_step is not None:
            on_step(steps, st, raw, out, d)
        success, r = scene.step(out[0])
        reward += r
        if success and first_success is None:
            first_success = steps
        eef.append(st.eef_pos[0].copy())
        d_obj.append(float(d.d_obj_xy[0]))
        phases.append(int(d.phase[0]))
        t_a.append(d.t_branch_a_s)
        t_b.append(d.t_branch_b_s)
        t_tot.append(d.t_total_s)
        vetoes += int(grip is not None and d.phase[0] == 0 and out[0, grip] != raw[0, grip])
        delta = float(np.linalg.norm(out[0] - raw[0])) if np.all(np.isfinite(raw)) else float("nan")
        changed += int(not delta <= CHANGE_TOL)  # a non-finite action the corrector replaced counts as changed
        change_norm.append(delta)
        action_norm.append(float(np.linalg.norm(raw[0])))
        el += int(d.weights[0].sum() > 0)
        if success and scene.stop_on_success:
            break
    eef_a = np.asarray(eef)
    ph = np.asarray(phases)
    dt = float(st.dt[0])
    return {
        "seed": seed, "success": bool(success), "steps": steps, "reward": reward,
        "first_success_step": first_success, "precision": metrics.precision(d_obj),
        "efficiency": metrics.efficiency(success, first_success or steps, scene.horizon),
        "stability": metrics.stability(eef_a, dt), "mean_jerk": metrics.mean_jerk(eef_a, dt),
        "sparc": metrics.sparc(eef_a, dt), "ldlj": metrics.ldlj(eef_a, dt),
        "phase_fraction": [float((ph == p).mean()) for p in range(4)],
        "veto_fire_rate": vetoes / max(int((ph == 0).sum()), 1), "el_fire_rate": el / steps,
        "passthrough": dict(corrector.passthrough_counts),
        "changed_fraction": changed / steps, "change_norm": _finite_mean(change_norm),
        "action_norm": _finite_mean(action_norm),
        "t_us_p50": {"a": float(np.median(t_a) * 1e6), "b": float(np.median(t_b) * 1e6), "total": float(np.median(t_tot) * 1e6)},
    }


def _marker_poses(scene, config: dict):
    """The poses from the scene's rendered markers (sim/marker_scene.py): the SO-101 pick-and-place's rig, positions
    whose bound exceeds the configuration's pose_error_m refused (pose_error_high), as the robot step does."""
    if scene.name != "so101_env":
        raise SystemExit(f"harness: pose_source markers renders lerobot-env-so101's scene (so101_env) only, not "
                         f"{scene.name!r}")
    import math

    from lerobot_physvla.arms.model import ARMS, resolve_mjcf
    from lerobot_physvla.sim.marker_scene import MarkerPoses, MarkerRig

    rig = MarkerRig(resolve_mjcf(ARMS["so101"].mjcf).parent / "pick_scene.xml")
    env = scene.env
    bound = float(config.get("pose_error_m", 0.0)) or math.inf
    return MarkerPoses(rig, lambda: rig.render(env._data.qpos, env.goal_pos), bound,
                       int(config.get("pose_max_age_steps", 5)))


def compute_unit(unit: Unit) -> dict:
    """Run one unit's episodes; returns {"unit", "seconds", "records"} (what run_unit writes)."""
    from lerobot_physvla.core.config import PhysVLAConfig
    from lerobot_physvla.core.corrector import Corrector

    if unit.scene == "so101_pick_place":  # lerobot's robot action processor on the simulated SO-101
        from so101_robot import compute_unit as so101_unit

        return so101_unit(unit)
    from lerobot_physvla.sources.perception import Perception, PerceptionConfig

    scene = _scene(unit.scene_name)
    backbone = _backbone(unit, scene)
    config = dict(unit.config)
    faults = PerceptionConfig.from_dict(config.pop("perception", {}))
    perception = None if faults.exact else Perception(faults)
    if config.pop("pose_source", None) == "markers":
        perception = _marker_poses(scene, config)
    # the configuration for this policy: chunk_phase_caps apply to policies that execute chunks
    corrector = Corrector(PhysVLAConfig.from_dict(config).for_policy(getattr(backbone, "actions_per_call", 1)))
    t0 = time.time()
    records = []
    for k in range(unit.episodes):
        rec = run_episode(scene, corrector, backbone, unit.first_seed + k, perception)
        rec.update(backbone=unit.backbone, config=unit.config_name, task_id=unit.task_id, scene=unit.scene)
        if hasattr(perception, "episode_summary"):  # the marker poses: their reasons and detection time
            rec.update(perception.episode_summary())
        records.append(rec)
    if hasattr(perception, "close"):
        perception.close()
    payload = {"unit": asdict(unit), "seconds": time.time() - t0, "records": records}
    if unit.policy:
        payload["policy_sha256"] = policy_fingerprint(unit.policy)
    return payload


def policy_fingerprint(path: str | Path) -> str:
    """sha256 of a checkpoint's weights (model.safetensors): which trained policy a unit ran.
    Hashed once per file version (a sweep checks every unit of a backbone against it)."""
    f = Path(path) / "model.safetensors"
    st = f.stat()
    key = (str(f.resolve()), st.st_size, st.st_mtime_ns)
    if key not in _SHA256:
        _SHA256[key] = hashlib.sha256(f.read_bytes()).hexdigest()
    return _SHA256[key]


# a plain dict, not functools.lru_cache: Ray ships this module to its workers by value, and an
# lru_cache wrapper is pickled by reference to a module (`harness`) the workers cannot import
_SHA256: dict[tuple[str, int, int], str] = {}


def _write(out_dir: str | Path, key: str, payload: dict) -> None:
    path = Path(out_dir) / "units" / f"{key}.json"
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(payload))
    tmp.replace(path)  # atomic: a killed sweep never leaves a half-written unit


def run_unit(unit: Unit, out_dir: str) -> str:
    """Run one unit and write `<out_dir>/units/<key>.json`; returns the key."""
    _write(out_dir, unit.key, compute_unit(unit))
    return unit.key


def _run_process(todo: list[Unit], out: Path, workers: int) -> None:
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(run_unit, u, str(out)) for u in todo]
        for f in tqdm(as_completed(futures), total=len(futures), desc="units", unit="unit"):
            f.result()


def _run_ray(todo: list[Unit], out: Path, workers: int) -> None:
    try:
        import ray
        import ray.cloudpickle
    except ImportError as e:
        raise SystemExit("harness: --backend ray needs ray: pip install 'lerobot_env_physvla[ray]'") from e
    if not ray.is_initialized():
        address = os.environ.get("RAY_ADDRESS")
        ray.init(address=address, num_cpus=None if address else workers, include_dashboard=False, log_to_driver=False)
    # the workers import lerobot_physvla; this module (eval/, not installed) travels by value
    for mod in (sys.modules[__name__], sys.modules["backbones"]):
        ray.cloudpickle.register_pickle_by_value(mod)
    remote = ray.remote(num_cpus=1)(compute_unit)
    pending = {remote.remote(u): u for u in todo}
    with tqdm(total=len(pending), desc="units (ray)", unit="unit") as bar:
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            unit = pending.pop(done[0])
            _write(out, unit.key, ray.get(done[0]))
            bar.update()


def run_units(units: list[Unit], out_dir: str | Path, workers: int | None = None,
              backend: str = "process") -> tuple[list[dict], float]:
    """Run the units not yet on disk (progress bar with ETA); return all records and the wall
    time this call spent."""
    if backend not in BACKENDS:
        raise ValueError(f"harness: unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    out = Path(out_dir)
    (out / "units").mkdir(parents=True, exist_ok=True)
    todo = [u for u in units if not (out / "units" / f"{u.key}.json").exists()]
    _check_stale([u for u in units if u not in todo], out)
    todo.sort(key=lambda u: (u.scene_name, u.policy))  # workers reuse the scenes they built
    t0 = time.time()
    if todo:
        workers = workers or os.cpu_count() or 1
        print(f"{len(units) - len(todo)} of {len(units)} units already done; running {len(todo)} on {workers} "
              f"{backend} workers")
        (_run_ray if backend == "ray" else _run_process)(todo, out, workers)
    records = []
    for u in units:
        records += json.loads((out / "units" / f"{u.key}.json").read_text())["records"]
    return records, time.time() - t0


def _check_stale(done: list[Unit], out: Path) -> None:
    """A unit on disk is keyed by backbone name and configuration hash: refuse to reuse one whose expert
    differs from what the name means now, or that ran other weights than the learned backbone's
    checkpoint holds now (it was retrained)."""
    for u in done:
        path = out / "units" / f"{u.key}.json"
        payload = json.loads(path.read_text())
        if payload["unit"].get("expert", {}) != u.expert:
            raise SystemExit(f"harness: {path} was run with another expert than {u.backbone!r} has now; "
                             "delete it to re-run that unit")
        if u.policy and payload.get("policy_sha256") != policy_fingerprint(u.policy):
            raise SystemExit(f"harness: {path} was run with other weights than {u.policy} holds now (retrained); "
                             "delete it to re-run that unit")


def seed_blocks(n_per_task: int, block: int) -> list[tuple[int, int]]:
    """(first_seed, episodes) blocks covering seeds 0 .. n_per_task - 1."""
    return [(s, min(block, n_per_task - s)) for s in range(0, n_per_task, block)]
