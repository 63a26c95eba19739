"""Re-simulation: an episode's recorded actions executed open loop from its recorded start,
without and with the corrector, in the simulator that recorded it.

The start comes from `physvla.episode` ([scene, task id, seed]: the scene is reset with that
seed, exactly as when it was recorded); the corrector reads the live simulator's state each
step. Without the corrector the episode is the recorded one again (deterministic simulators),
which the record checks: `state_divergence_m` is the largest end-effector distance between the
re-simulated and the recorded states.
"""

from __future__ import annotations

import numpy as np

from lerobot_physvla import metrics
from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.state import field_offsets, n_joints_from_size
from lerobot_physvla.replay import columns as C
from lerobot_physvla.replay.dataset import ReplayData, ReplayError



def _scene(name: str):
    from lerobot_physvla.sim.scenes import cached_scene

    return cached_scene(name)


def run(scene, actions: np.ndarray, seed: int, corrector=None, perception=None) -> dict:
    """Execute `actions` open loop from the scene's seeded start; the corrector (if any) corrects each,
    reading the state through `perception` (sources.perception.Perception) where one is given."""
    scene.reset(seed)
    if corrector is not None:
        corrector.reset()
    if perception is not None:
        perception.reset(seed=seed)
    eef, success, steps, changed = [], False, 0, 0
    for steps, a in enumerate(actions[: scene.horizon], start=1):
        st = scene.read()
        eef.append(st.eef_pos[0].copy())
        out = a[None]
        if corrector is not None:
            out = corrector(out, st) if perception is None else corrector.correct_packed(out, perception.apply(st.pack()))
            changed += int(np.abs(out - a[None]).max() > 0)
        success, _ = scene.step(out[0])
        if success and scene.stop_on_success:
            break
    eef = np.asarray(eef)
    dt = float(st.dt[0])
    return {"success": bool(success), "steps": steps, "eef": eef, "frames_changed": changed,
            "mean_jerk": metrics.mean_jerk(eef, dt) if len(eef) > 3 else None}


def resim_shard(cfg_dict: dict, items: list[tuple], batch: int = 64) -> list[dict]:
    """Re-simulate episodes [(index, scene name, seed, actions (T, A), recorded eef (T, 3) or None)];
    cfg_dict's "perception" (PerceptionConfig.to_dict()), where present, sits between the scene and the corrector."""
    import warnings

    from lerobot_physvla.core.corrector import Corrector
    from lerobot_physvla.sources.perception import Perception, PerceptionConfig

    cfg_dict = dict(cfg_dict)
    faults = PerceptionConfig.from_dict(cfg_dict.pop("perception", {}))
    cfg = PhysVLAConfig.from_dict(cfg_dict)
    out = []
    for index, name, seed, actions, rec_eef in items:
        scene = _scene(name)
        raw = run(scene, actions, seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            cor = run(scene, actions, seed, Corrector(cfg), None if faults.exact else Perception(faults))
        div = None
        if rec_eef is not None:
            n = min(len(rec_eef), len(raw["eef"]))
            div = float(np.linalg.norm(raw["eef"][:n] - rec_eef[:n], axis=1).max()) if n else 0.0
            div = div if len(rec_eef) == len(raw["eef"]) else float("inf")  # a different length is a divergence
        out.append({"index": index, "scene": name, "seed": seed,
                    "raw": {k: v for k, v in raw.items() if k != "eef"},
                    "corrected": {k: v for k, v in cor.items() if k != "eef"}, "state_divergence_m": div})
    return out


def check_resimulable(data: ReplayData) -> None:
    """ReplayError unless every selected episode names a scene re-simulation supports."""
    if C.EPISODE not in data.features:
        raise ReplayError(f"re-simulation needs the {C.EPISODE} column ([scene, task id, seed]) that "
                          f"python -m lerobot_physvla.replay.record writes; this dataset has none")
    for ep in data.episodes:
        name, _ = C.scene_of(ep.source)
        if name.partition("/")[0] not in C.RESIM_SCENES:
            raise ReplayError(f"episode {ep.index}: re-simulation supports {', '.join(C.RESIM_SCENES)}, not {name}")


def replay_resim(data: ReplayData, cfg: PhysVLAConfig, workers: int = 1, backend: str = "process",
                 progress: bool = True, perception=None) -> list[dict]:
    """Per-episode re-simulation records (recorded success beside raw and corrected); perception: a
    sources.perception.PerceptionConfig between the simulator and the corrector (None: exact poses)."""
    from lerobot_physvla.replay.shards import map_shards

    check_resimulable(data)
    items = []
    for ep in data.episodes:
        name, seed = C.scene_of(ep.source)
        rec_eef = None
        if ep.states is not None:
            f = field_offsets(n_joints_from_size(ep.states.shape[1]))
            rec_eef = ep.states[:, f["eef_pos"]:f["eef_pos"] + 3]
        items.append((ep.index, name, seed, ep.actions, rec_eef))
    cfg_dict = cfg.to_dict() | ({} if perception is None or perception.exact else {"perception": perception.to_dict()})
    res = {r["index"]: r for r in map_shards(resim_shard, cfg_dict, items, workers=workers, backend=backend,
                                             batch=1, progress=progress, desc="re-simulation")}
    return [{"episode": ep.index, "task": ep.task, "recorded_success": ep.success, **res[ep.index]}
            for ep in data.episodes]
