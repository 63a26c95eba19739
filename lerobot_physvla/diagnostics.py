"""Per-episode diagnostics of a corrected evaluation, written beside lerobot's eval_info.json.

`EpisodeRecorder` listens to `PhysVLACorrectorStep` (one call per control step, B envs) and
splits the stream into episodes per env with the state's own step counter. For each episode it
keeps the raw and corrected actions, the action the simulator actually executed (echoed back by
the env one step later), the phase timeline, residuals, pass-through reasons and timings, and
computes the metrics of `metrics.py`. `write(dir)` saves
    physvla_episodes.jsonl     one JSON record per episode (arrays included)
    physvla_diagnostics.json   aggregates: success, metrics, firing rates, overhead, pass-throughs
    physvla_states.npz         (only with save_states; PHYSVLA_SAVE_STATES=1 in lerobot-eval) the
                               packed states, raw and corrected actions of every step, float64
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import numpy as np

from lerobot_physvla import metrics
from lerobot_physvla.core.phase import PHASE_NAMES
from lerobot_physvla.core.state import REASONS


class _Episode:
    def __init__(self, env_index: int, task_id: int, number: int):
        self.env_index, self.task_id, self.number = env_index, task_id, number
        self.raw, self.corrected, self.executed = [], [], []
        self.phase, self.r_el, self.r_energy, self.status = [], [], [], []
        self.eef, self.d_obj, self.d_tgt, self.t_us = [], [], [], []
        self.states = []  # packed state rows, kept only when the recorder saves states
        self.el_weight = []  # sum of Branch B weights (0 where it did not run)
        self.success = False
        self.dt = 0.05

    def to_record(self, horizon: int | None) -> dict:
        steps = len(self.raw)
        eef = np.asarray(self.eef)
        phase = np.asarray(self.phase)
        corrected = np.asarray(self.corrected)
        dev = np.abs(corrected - np.asarray(self.raw)).max(axis=1) if steps else np.zeros(0)
        h = horizon or steps
        rec = {
            "env_index": self.env_index, "task_id": self.task_id, "episode": self.number, "steps": steps,
            "success": self.success,
            "precision": metrics.precision(self.d_obj) if steps else 0.0,
            "efficiency": metrics.efficiency(self.success, steps, h),
            "stability": metrics.stability(eef, self.dt) if steps > 3 else float("nan"),
            "mean_jerk": metrics.mean_jerk(eef, self.dt) if steps > 3 else float("nan"),
            "sparc": metrics.sparc(eef, self.dt),
            "ldlj": metrics.ldlj(eef, self.dt),
            "phase_timeline": _run_length(self.phase),
            "phase_fraction": {n: float((phase == i).mean()) if steps else 0.0 for i, n in enumerate(PHASE_NAMES)},
            "corrected_fraction": float((dev > 0).mean()) if steps else 0.0,
            "r_el_p50": _nanpct(self.r_el, 50), "r_el_p99": _nanpct(self.r_el, 99),
            "passthrough": dict(Counter(REASONS[s] for s in self.status if s != 0)),
            "overhead_us_p50": _nanpct(self.t_us, 50), "overhead_us_p99": _nanpct(self.t_us, 99),
            "raw_actions": np.asarray(self.raw).round(6).tolist(),
            "corrected_actions": corrected.round(6).tolist(),
            "executed_actions": [None if a is None else np.asarray(a).round(6).tolist() for a in self.executed],
            "phase": phase.tolist(),
            "r_el": [None if not np.isfinite(r) else round(float(r), 4) for r in self.r_el],
        }
        return rec


def _nanpct(x, q) -> float | None:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.percentile(x, q)) if x.size else None


def _run_length(phases) -> list[list]:
    out: list[list] = []
    for p in phases:
        name = PHASE_NAMES[p] if p >= 0 else "pass-through"
        if out and out[-1][0] == name:
            out[-1][1] += 1
        else:
            out.append([name, 1])
    return out


class EpisodeRecorder:
    """Collects per-step corrector output into per-env episodes (a PhysVLACorrectorStep listener).

    Attributes:
        horizon: episode length used for efficiency (the env's max steps), or None.
        gripper_index: the gripper's action entry (for the veto firing rate), or None.
        episodes: finished and running episodes, in start order.
    """

    def __init__(self, horizon: int | None = None, save_states: bool = False, gripper_index: int | None = 6):
        self.horizon = horizon
        self.gripper_index = gripper_index
        self.save_states = save_states
        self.episodes: list[_Episode] = []
        self._open: dict[int, _Episode] = {}
        self._last_step: dict[int, float] = {}
        self._closed: set[int] = set()

    def __call__(self, raw, out, state, extra, diag, t_total_s) -> None:
        b = raw.shape[0]
        raw0 = raw[:, 0] if raw.ndim == 3 else raw
        out0 = out[:, 0] if out.ndim == 3 else out
        steps = state.episode_step
        if (steps == 0).all():  # every env just reset: a new rollout batch
            self._open.clear()
            self._closed.clear()
        for i in range(b):
            if i in self._closed:  # finished: lerobot ignores this env until the next batch
                continue
            step = float(steps[i])
            ep = self._open.get(i)
            if ep is not None and step == self._last_step[i]:
                continue  # a frozen sub-env replaying its terminal observation
            if ep is None or step < self._last_step[i]:
                task = int(extra[i, 0]) if extra is not None else -1
                ep = self._open[i] = _Episode(i, task, len(self.episodes))
                self.episodes.append(ep)
            elif extra is not None and ep.executed:
                ep.executed[-1] = extra[i, 2 : 2 + raw0.shape[1]].copy()  # what the sim executed last step
            self._last_step[i] = step
            if extra is not None and extra[i, 1] > 0.5:  # the last action succeeded: episode over
                ep.success = True
                self._closed.add(i)
                continue
            ep.dt = float(state.dt[i]) or ep.dt
            ep.raw.append(raw0[i].copy())
            ep.corrected.append(out0[i].copy())
            ep.executed.append(None)
            ep.phase.append(int(diag.phase[i]))
            ep.r_el.append(float(diag.r_el[i]))
            ep.r_energy.append(float(diag.r_energy[i]))
            ep.status.append(int(diag.status[i]))
            ep.eef.append(state.eef_pos[i].copy())
            ep.d_obj.append(float(diag.d_obj_xy[i]))
            ep.d_tgt.append(float(diag.d_tgt_xy[i]))
            ep.t_us.append(t_total_s * 1e6 / b)
            ep.el_weight.append(float(diag.weights[i].sum()))
            if self.save_states:
                ep.states.append(state.pack()[i].copy())

    def apply_env_successes(self, per_task: dict[int, list[bool]]) -> None:
        """Take success from the env's own record (lerobot's eval_info.json), episode by episode.

        The postprocessor cannot see the outcome of an episode's last step when no further
        policy call follows it (the batch's last env to finish), so the env's word is final.
        Episodes of a task are matched in start order (batch by batch, env index within).
        """
        by_task: dict[int, list[_Episode]] = {}
        for ep in self.episodes:
            by_task.setdefault(ep.task_id, []).append(ep)
        for task, successes in per_task.items():
            eps = by_task.get(task, [])
            if len(eps) != len(successes):
                continue  # cannot be matched one to one: keep what was observed
            for ep, ok in zip(eps, successes):
                ep.success = bool(ok)

    def records(self) -> list[dict]:
        return [ep.to_record(self.horizon) for ep in self.episodes]

    def summary(self, records: list[dict] | None = None) -> dict:
        recs = self.records() if records is None else records
        n = len(recs)
        k = sum(r["success"] for r in recs)
        lo, hi = metrics.wilson_interval(k, n)
        mean = lambda key: float(np.nanmean([r[key] for r in recs])) if n else None  # noqa: E731
        phases = Counter()
        corrected_steps = total_steps = veto_steps = el_steps = approach_steps = 0
        g = self.gripper_index
        for ep in self.episodes:
            phases.update(PHASE_NAMES[p] if p >= 0 else "pass-through" for p in ep.phase)
            if not ep.raw:
                continue
            raw, cor, ph = np.asarray(ep.raw), np.asarray(ep.corrected), np.asarray(ep.phase)
            corrected_steps += int((np.abs(cor - raw).max(axis=1) > 0).sum())
            total_steps += len(raw)
            approach_steps += int((ph == 0).sum())
            if g is not None:
                veto_steps += int(((ph == 0) & (cor[:, g] != raw[:, g])).sum())
            el_steps += int((np.asarray(ep.el_weight) > 0).sum())
        pt = Counter()
        for r in recs:
            pt.update(r["passthrough"])
        t = np.concatenate([np.asarray(ep.t_us) for ep in self.episodes]) if self.episodes else np.zeros(0)
        return {
            "episodes": n, "success_rate": k / n if n else None, "success_ci95": [lo, hi],
            "precision": mean("precision"), "efficiency": mean("efficiency"), "stability": mean("stability"),
            "mean_jerk": mean("mean_jerk"), "sparc": mean("sparc"), "ldlj": mean("ldlj"),
            "steps": total_steps,
            "phase_fraction": {p: c / max(total_steps, 1) for p, c in phases.items()},
            "corrected_fraction": corrected_steps / max(total_steps, 1),
            # firing rates: the approach veto changed the gripper (share of approach steps);
            # Branch B blended something in (share of all steps)
            "veto_fire_rate": veto_steps / max(approach_steps, 1),
            "el_fire_rate": el_steps / max(total_steps, 1),
            "passthrough": dict(pt),
            "overhead_us_per_env_step": {"p50": _nanpct(t, 50), "p99": _nanpct(t, 99)},
        }

    def write(self, out_dir: str | Path, config: dict | None = None) -> Path:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        recs = self.records()
        with open(out / "physvla_episodes.jsonl", "w") as f:
            for r in recs:
                f.write(json.dumps(r) + "\n")
        summary = self.summary(recs)
        if config is not None:
            summary["physvla_config"] = config
        (out / "physvla_diagnostics.json").write_text(json.dumps(summary, indent=2))
        if self.save_states:  # exact replay material: states and actions in float64
            arrays = {}
            for k, ep in enumerate(self.episodes):
                arrays[f"ep{k}_states"] = np.asarray(ep.states)
                arrays[f"ep{k}_raw"] = np.asarray(ep.raw)
                arrays[f"ep{k}_corrected"] = np.asarray(ep.corrected)
            np.savez_compressed(out / "physvla_states.npz", **arrays)
        return out / "physvla_diagnostics.json"
