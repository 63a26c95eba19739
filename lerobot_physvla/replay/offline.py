"""Offline replay: each frame's recorded action and state through the corrector, no simulator.

Episodes are corrected in lockstep as a batch of B envs (one corrector call per frame index for
B episodes; the corrector keeps per-env memory), so a large dataset costs a few microseconds a
frame. Ended episodes are padded with invalid states (passed through, never reported).

State, per frame:
- `observation.physvla_state` where the dataset has it (recorded by this project in simulation:
  the full s_t, Branch B included);
- otherwise from the dataset's columns (`ColumnState`): the end-effector and gripper from
  observation.state, object and target from observation.environment_state or fixed poses given
  in configuration. That state has no joint dynamics, so Branch B is off (said in the report).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np

from lerobot_physvla import metrics
from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.phase import PHASE_NAMES
from lerobot_physvla.core.state import REASONS, field_offsets, n_joints_from_size, packed_size
from lerobot_physvla.core.tick import D_OBJ, D_PHASE, D_R_EL, D_STATUS, D_TGT, D_W_SUM
from lerobot_physvla.replay import columns as C
from lerobot_physvla.replay.dataset import Episode, ReplayData, ReplayError
from lerobot_physvla.report import corrections_by_phase, phase_timeline

# observation.state layouts the column state understands, by robot type: dim -> (eef xyz slice, finger indices)
STATE_MAPS: dict[str, dict[int, tuple[slice, tuple[int, ...]]]] = {
    # lerobot's LIBERO processor (eef xyz, eef axis-angle, two finger qpos); the recorder's other scenes
    # (eef xyz, gripper opening)
    "panda": {8: (slice(0, 3), (6, 7)), 4: (slice(0, 3), (3,))},
}
COLUMN_JOINTS = 7  # joint count of the packed rows a column state fills (joint fields stay 0)


@dataclass
class ColumnState:
    """How to build s_t from a dataset without observation.physvla_state.

    Attributes:
        object_xyz, target_xyz: fixed object / target positions in the robot's world frame, m;
            None reads them from observation.environment_state (object xyz, target xyz).
    """

    object_xyz: tuple[float, float, float] | None = None
    target_xyz: tuple[float, float, float] | None = None


def episode_states(data: ReplayData, ep: Episode, column_state: ColumnState | None = None) -> np.ndarray:
    """(T, L) packed states of one episode: the recorded ones, or built from its columns."""
    if ep.states is not None:
        return ep.states
    cs = column_state or ColumnState()
    maps = STATE_MAPS.get(str(data.robot_type))
    if maps is None:
        raise ReplayError(
            f"robot type {data.robot_type!r} has no state map and the dataset has no {C.PHYSVLA_STATE}; "
            f"supported robot types: {', '.join(STATE_MAPS)} (or record with python -m lerobot_physvla.replay.record)")
    s = ep.obs.get(C.STATE)
    if s is None or s.shape[1] not in maps:
        dims = sorted(maps)
        raise ReplayError(f"the dataset needs {C.STATE} of dim {dims} for a {data.robot_type} state "
                          f"(got {None if s is None else s.shape[1]})")
    eef_sl, fingers = maps[s.shape[1]]
    env = ep.obs.get(C.ENV_STATE)
    if (cs.object_xyz is None or cs.target_xyz is None) and (env is None or env.shape[1] < 6):
        raise ReplayError(f"object and target poses: the dataset has no {C.ENV_STATE} (object xyz, target xyz); "
                          f"give --object_xyz='[x,y,z]' and --target_xyz='[x,y,z]' (metres, world frame)")
    t = ep.frames
    f = field_offsets(COLUMN_JOINTS)
    out = np.zeros((t, packed_size(COLUMN_JOINTS)))
    out[:, f["valid"]] = 1.0
    out[:, f["episode_step"]] = np.arange(t)
    out[:, f["dt"]] = 1.0 / data.fps
    out[:, f["eef_pos"]:f["eef_pos"] + 3] = s[:, eef_sl]
    out[:, f["gripper"]] = np.abs(s[:, list(fingers)]).sum(axis=1)
    obj = np.broadcast_to(cs.object_xyz, (t, 3)) if cs.object_xyz is not None else env[:, 0:3]
    tgt = np.broadcast_to(cs.target_xyz, (t, 3)) if cs.target_xyz is not None else env[:, 3:6]
    out[:, f["obj_pos"]:f["obj_pos"] + 3] = obj
    out[:, f["obj_rest_z"]] = obj[0, 2]
    out[:, f["target_pos"]:f["target_pos"] + 3] = tgt
    m = f["M"]
    out[:, m:m + COLUMN_JOINTS**2] = np.eye(COLUMN_JOINTS).reshape(-1)
    return out


def effective_config(cfg: PhysVLAConfig, data: ReplayData) -> tuple[PhysVLAConfig, str | None]:
    """The config replay runs, and why it differs from the one asked for (None if it does not)."""
    if not data.has_physvla_state and cfg.mode == "phys_el" and cfg.el_mode != "off":
        return cfg.replace(el_mode="off"), (f"Branch B off: the dataset has no {C.PHYSVLA_STATE} "
                                            "(joint positions, velocities, M(q), bias); Branch A only")
    return cfg, None


def correct_shard(cfg_dict: dict, items: list[tuple[int, np.ndarray, np.ndarray]], batch: int = 64) -> list[dict]:
    """Correct episodes [(index, actions (T, A), states (T, L))] in lockstep batches of `batch`.
    Returns per episode: corrected actions, phase, status, residuals, distances, time per frame."""
    from lerobot_physvla.core.corrector import Corrector

    cfg = PhysVLAConfig.from_dict(cfg_dict)
    out = []
    for k in range(0, len(items), batch):
        group = items[k:k + batch]
        b = len(group)
        t_max = max(len(a) for _, a, _ in group)
        a_dim, width = group[0][1].shape[1], group[0][2].shape[1]
        acts = np.zeros((t_max, b, a_dim))
        states = np.zeros((t_max, b, width))  # valid = 0 past an episode's end
        for i, (_, a, s) in enumerate(group):
            acts[: len(a), i], states[: len(s), i] = a, s
        cor = Corrector(cfg, batch_size=b)
        cor.reset()
        corrected = np.empty_like(acts)
        diag = np.empty((t_max, b, cor.diag_buffer.shape[1]))
        t_call = np.empty(t_max)
        with warnings.catch_warnings():  # pass-throughs are counted per episode in the report
            warnings.simplefilter("ignore", RuntimeWarning)
            for t in range(t_max):
                t0 = time.perf_counter()
                corrected[t] = cor.correct_packed(acts[t], states[t])
                t_call[t] = time.perf_counter() - t0
                diag[t] = cor.diag_buffer
        live = np.array([[t < len(a) for _, a, _ in group] for t in range(t_max)]).sum(axis=1)
        us_per_frame = t_call * 1e6 / np.maximum(live, 1)
        for i, (index, a, _) in enumerate(group):
            n = len(a)
            d = diag[:n, i]
            out.append({
                "index": index, "corrected": corrected[:n, i].copy(), "phase": d[:, D_PHASE].astype(np.int8),
                "status": d[:, D_STATUS].astype(np.int8), "r_el": d[:, D_R_EL].copy(), "d_obj": d[:, D_OBJ].copy(),
                "d_tgt": d[:, D_TGT].copy(), "w_sum": d[:, D_W_SUM].copy(), "us_per_frame": us_per_frame[:n].copy(),
            })
    return out


def commanded_path(actions: np.ndarray, layout) -> np.ndarray:
    """(T, 3) end-effector path the position channels command, m: the running sum of deltas
    (delta layouts) or the targets themselves (absolute layouts)."""
    p = np.asarray(actions, float)[:, list(layout.pos)]
    return p if layout.absolute else np.cumsum(p, axis=0) * layout.metres_per_unit


def flagged_frames(raw: np.ndarray, states: np.ndarray, phase: np.ndarray, cfg: PhysVLAConfig) -> list[dict]:
    """Frames where the recorded action looks physically wrong, by the corrector's own geometry: a
    gripper close commanded out of the fingers' reach (horizontally beyond veto_reach_m from the
    object's origin, or delta_grasp_m when the reach is 0, or more than veto_height_m above it),
    and a release commanded in transport. One entry per onset (the frame the command switches)."""
    lay = cfg.action_layout
    g = lay.gripper
    if g is None or not len(raw):
        return []
    n = n_joints_from_size(states.shape[1])
    f = field_offsets(n)
    closing = lay.closes(raw[:, g])  # the command on the closed side of the open/closed midpoint
    onset_close = np.flatnonzero(closing & ~np.r_[False, closing[:-1]])
    onset_open = np.flatnonzero(~closing & np.r_[False, closing[:-1]])
    eef, obj = states[:, f["eef_pos"]:f["eef_pos"] + 3], states[:, f["obj_pos"]:f["obj_pos"] + 3]
    d_xy = np.linalg.norm(eef[:, :2] - obj[:, :2], axis=1)
    height = eef[:, 2] - obj[:, 2]
    out = []
    for t in onset_close:
        above = cfg.veto_height_m > 0 and height[t] > cfg.veto_height_m
        reach = cfg.veto_reach_m if cfg.veto_reach_m > 0 else cfg.delta_grasp_m
        if d_xy[t] > reach or above:
            out.append({"frame": int(t), "why": "gripper close far from the object",
                        "d_obj_xy_m": round(float(d_xy[t]), 4), "height_above_object_m": round(float(height[t]), 4)})
    for t in onset_open:
        if phase[t] == 2:
            out.append({"frame": int(t), "why": "release in transport", "d_tgt_xy_m": None})
    return sorted(out, key=lambda r: r["frame"])


def episode_report(ep: Episode, states: np.ndarray, res: dict, cfg: PhysVLAConfig, fps: float) -> dict:
    """The per-episode record of an offline replay (JSON-able; arrays kept under '_arrays')."""
    lay = cfg.action_layout
    raw, cor, ph = ep.actions, res["corrected"], res["phase"]
    dt = 1.0 / fps
    delta = np.abs(cor - raw)
    corrections = corrections_by_phase(raw, cor, ph, lay)
    corrections["branch B"] = {"frames_in_phase": int(len(ph)), "frames_changed": int((res["w_sum"] > 0).sum()),
                               "mean_abs_change": None}
    smooth = {}
    for which, acts in (("raw", raw), ("corrected", cor)):
        path = commanded_path(acts, lay)
        smooth[which] = {"mean_jerk": metrics.mean_jerk(path, dt) if len(path) > 3 else None,
                         "sparc": metrics.sparc(path, dt), "ldlj": metrics.ldlj(path, dt)}
    r = res["r_el"][np.isfinite(res["r_el"])]
    status = res["status"]
    return {
        "episode": ep.index, "task": ep.task, "frames": ep.frames, "success": ep.success,
        "source": None if ep.source is None else [int(v) for v in ep.source],
        "phase_timeline": phase_timeline(ph), "phase_fraction": {n: float((ph == i).mean()) for i, n in enumerate(PHASE_NAMES)},
        "frames_changed": int((delta.max(axis=1) > 0).sum()),
        "max_abs_change": float(delta.max()) if delta.size else 0.0,
        "corrections": corrections,
        "r_el_p50": float(np.median(r)) if r.size else None, "r_el_p99": float(np.percentile(r, 99)) if r.size else None,
        "smoothness": smooth,
        "passthrough": {REASONS[s]: int((status == s).sum()) for s in np.unique(status) if s != 0},
        "overhead_us_per_frame_p50": float(np.median(res["us_per_frame"])),
        "flagged": flagged_frames(raw, states, ph, cfg),
        "_arrays": {"raw": raw, "corrected": cor, "phase": ph, "r_el": res["r_el"]},
    }


def replay_offline(data: ReplayData, cfg: PhysVLAConfig, column_state: ColumnState | None = None,
                   workers: int = 1, backend: str = "process", batch: int = 64, progress: bool = True) -> tuple[list[dict], str | None]:
    """Per-episode offline records of every selected episode, and the note of effective_config."""
    from lerobot_physvla.replay.shards import map_shards

    cfg, note = effective_config(cfg, data)
    a_dim = cfg.action_layout.dim
    states = {}
    for ep in data.episodes:
        if ep.actions.shape[1] != a_dim:
            raise ReplayError(f"the dataset's actions have {ep.actions.shape[1]} channels; the layout "
                              f"{cfg.layout!r} has {a_dim}: set --physvla.layout")
        states[ep.index] = episode_states(data, ep, column_state)
    items = [(ep.index, ep.actions, states[ep.index]) for ep in data.episodes]
    results = {r["index"]: r for r in map_shards(correct_shard, cfg.to_dict(), items, workers=workers,
                                                 backend=backend, batch=batch, progress=progress, desc="offline replay")}
    return [episode_report(ep, states[ep.index], results[ep.index], cfg, data.fps) for ep in data.episodes], note
