"""Per-episode diagnostics of a corrected evaluation, written beside lerobot's eval_info.json.

`EpisodeRecorder` listens to `PhysVLACorrectorStep` (one call per control step, B envs) and
splits the stream into episodes per env with the state's own step counter. For each episode it
keeps the raw and corrected actions, the action the simulator actually executed (echoed back by
the env one step later), the phase timeline, residuals, pass-through reasons and timings, and
computes the metrics of `metrics.py`. Recording is one row per control step in a growable
arena, written by the corrector's compiled tick where the recorder is the step's one listener
(`slot` / `commit`), else copied in a few array assignments (`__call__`); no per-env Python work,
no unpacking. Episodes are split when read, and when
every env restarts together (lerobot-eval's next rollout batch) the finished batch is reduced
to its records and the rows are reused, so memory does not grow with the number of steps.
`write(dir)` saves
    physvla_episodes.jsonl     one JSON record per episode; per-step arrays (actions, phases,
                               r_EL) for the first 10 episodes, or all with keep_steps=None
                               (PHYSVLA_RECORD_STEPS=1 in lerobot-eval)
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
from lerobot_physvla.report import corrections_by_phase, phase_timeline
from lerobot_physvla.core.corrector import record_row
from lerobot_physvla.core.phase import PHASE_NAMES
from lerobot_physvla.core.state import REASONS
from lerobot_physvla.core.tick import D_OBJ, D_PHASE, D_R_EL, D_R_ENERGY, D_STATUS, D_TGT, D_W_SUM, REC_HEADER


class _Episode:
    """One env's episode: per-step arrays taken from the recording (`fill`)."""

    def __init__(self, env_index: int, task_id: int, number: int):
        self.env_index, self.task_id, self.number = env_index, task_id, number
        self.executed: list = []  # the action the sim executed at each step (None where not echoed)
        self.success = False
        self.dt = 0.05
        self.fill(None, np.zeros(0, np.intp), env_index)

    def fill(self, seg, ks: np.ndarray, i: int) -> None:
        """Per-step arrays of env i at the recording's rows ks of segment seg."""
        if seg is None:
            z = np.zeros(0)
            self.raw = self.corrected = np.zeros((0, 0))
            self.phase, self.status = np.zeros(0, int), np.zeros(0, int)
            self.r_el = self.r_energy = self.d_obj = self.d_tgt = self.t_us = self.el_weight = z
            self.eef, self.states = np.zeros((0, 3)), np.zeros((0, 0))
            return
        self.raw, self.corrected = seg.raw[ks, i], seg.out[ks, i]
        d = seg.diag[ks, i]
        self.phase, self.status = d[:, D_PHASE].astype(int), d[:, D_STATUS].astype(int)
        self.r_el, self.r_energy = d[:, D_R_EL], d[:, D_R_ENERGY]
        self.d_obj, self.d_tgt = d[:, D_OBJ], d[:, D_TGT]
        self.el_weight = d[:, D_W_SUM]  # sum of Branch B weights (0 where it did not run)
        self.eef = seg.header[ks, i, 3:6]
        self.t_us = seg.t_us[ks]
        dts = seg.header[ks, i, 2]
        if len(dts) and dts[-1] > 0:
            self.dt = float(dts[-1])
        self.states = seg.states[ks, i] if seg.states is not None else np.zeros((len(ks), 0))

    compact_record: dict | None = None  # set by `compact`: the record without per-step arrays

    def compact(self, layout, gripper_index: int | None, keep_steps: bool) -> dict:
        """Reduces a finished episode to its record and, unless keep_steps, drops its per-step
        arrays (memory stays flat over a long evaluation); returns its `stats`, which the
        recorder adds to its totals."""
        stats = self.stats(gripper_index)
        rec = self.to_record(None, layout, steps_too=keep_steps)
        if not keep_steps:
            self.fill(None, np.zeros(0, np.intp), self.env_index)
            self.executed = []
        self.compact_record = rec
        return stats

    def stats(self, gripper_index: int | None) -> dict:
        """The counts the run's summary adds up: phases, steps changed, veto and Branch B firings,
        the per-step call times as a log histogram."""
        raw, cor, ph = np.asarray(self.raw), np.asarray(self.corrected), np.asarray(self.phase)
        n = len(raw)
        changed = np.abs(cor - raw).max(axis=1) > 0 if n else np.zeros(0, bool)
        g = gripper_index
        return {
            "steps": n, "corrected": int(changed.sum()), "approach": int((ph == 0).sum()),
            "veto": int(((ph == 0) & (cor[:, g] != raw[:, g])).sum()) if g is not None and n else 0,
            "el": int((np.asarray(self.el_weight) > 0).sum()),
            "phases": Counter(PHASE_NAMES[p] if p >= 0 else "pass-through" for p in ph.tolist()),
            "t_hist": _time_histogram(self.t_us),
        }

    def to_record(self, horizon: int | None, layout=None, steps_too: bool = True) -> dict:
        """The episode's JSON record; per-step arrays (actions, phase, r_EL) only with steps_too,
        corrections per phase only given the action layout."""
        if self.compact_record is not None:
            rec = dict(self.compact_record)
            rec["success"] = self.success
            rec["efficiency"] = metrics.efficiency(self.success, rec["steps"], horizon or rec["steps"])
            return rec
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
            "phase_timeline": phase_timeline(self.phase),
            "phase_fraction": {n: float((phase == i).mean()) if steps else 0.0 for i, n in enumerate(PHASE_NAMES)},
            "corrected_fraction": float((dev > 0).mean()) if steps else 0.0,
            "r_el_p50": _nanpct(self.r_el, 50), "r_el_p99": _nanpct(self.r_el, 99),
            "passthrough": dict(Counter(REASONS[s] for s in self.status if s != 0)),
            "overhead_us_p50": _nanpct(self.t_us, 50), "overhead_us_p99": _nanpct(self.t_us, 99),
            "frames_changed": int((dev > 0).sum()),
        }
        if layout is not None:
            rec["corrections_by_phase"] = corrections_by_phase(self.raw, corrected, phase, layout)
        if steps_too:
            rec.update({
                "raw_actions": np.asarray(self.raw).round(6).tolist(),
                "corrected_actions": corrected.round(6).tolist(),
                "executed_actions": [None if a is None else np.asarray(a).round(6).tolist() for a in self.executed],
                "phase": phase.tolist(),
                "r_el": [None if not np.isfinite(r) else round(float(r), 4) for r in self.r_el],
            })
        return rec


# per-step call times, us: a log histogram (0.01 us .. 1 s, ~4.7 % per bin) keeps the run's
# percentiles with memory that does not grow with the number of steps
_T_EDGES = np.logspace(-2, 6, 401)


def _finite_mean(values) -> float | None:
    """The mean of the finite values (None where there are none: no episode measured it)."""
    v = np.asarray([np.nan if x is None else x for x in values], dtype=float)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else None


def _time_histogram(t_us) -> np.ndarray:
    t = np.asarray(t_us, dtype=float)
    t = t[np.isfinite(t)]
    return np.histogram(np.clip(t, _T_EDGES[0], _T_EDGES[-1]), _T_EDGES)[0]


def _no_stats() -> dict:
    return {"steps": 0, "corrected": 0, "approach": 0, "veto": 0, "el": 0, "phases": Counter(),
            "t_hist": np.zeros(len(_T_EDGES) - 1, np.int64)}


def _add_stats(total: dict, stats: dict) -> None:
    for key, value in stats.items():
        if key == "phases":
            total[key].update(value)
        else:
            total[key] += value


def _histogram_percentile(hist: np.ndarray, q: float) -> float | None:
    """The q-th percentile of the times a histogram holds (the geometric centre of its bin)."""
    total = int(hist.sum())
    if not total:
        return None
    k = int(np.searchsorted(np.cumsum(hist), q / 100.0 * total, side="left"))
    k = min(k, len(hist) - 1)
    return float(np.sqrt(_T_EDGES[k] * _T_EDGES[k + 1]))


def _nanpct(x, q) -> float | None:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.percentile(x, q)) if x.size else None


class _Segment:
    """Per-call rows of one batch size, in one growable arena (capacity doubles when full).

    The arena `rows` (capacity, B, width) holds, per call and env, the raw and corrected actions,
    the state header, the diagnostics and (with save_states) the packed state, in the order the
    corrector's stream tick writes a row (core/tick.py REC_HEADER: `EpisodeRecorder.slot`);
    raw, out, header, diag and states are views of it. Extras and call times are arrays of their own.
    """

    HEADER = REC_HEADER  # packed-state prefix kept per env: valid, episode_step, dt, eef_pos (state.py order)
    # first rows held: a LIBERO episode (at most 520 steps, libero_10) fits, so no rollout batch grows
    # the arrays inside a control tick (a doubling copies every row: ~40-100 us at B = 1)
    CAPACITY = 512

    def __init__(self, b: int, a_dim: int, n_diag: int, n_extra: int, n_state: int | None):
        self.b, self.a_dim, self.n_diag, self.n_extra, self.n_state = b, a_dim, n_diag, n_extra, n_state
        self.n = 0
        self.width = 2 * a_dim + self.HEADER + n_diag + (n_state or 0)
        self._views(np.zeros((self.CAPACITY, b, self.width)))
        self.extra = np.full((self.CAPACITY, b, n_extra), np.nan)
        self.t_us = np.zeros(self.CAPACITY)

    def _views(self, rows: np.ndarray) -> None:
        a, o_d = self.a_dim, 2 * self.a_dim + self.HEADER
        self.rows = rows
        self.raw, self.out, self.header = rows[:, :, :a], rows[:, :, a : 2 * a], rows[:, :, 2 * a : o_d]
        self.diag = rows[:, :, o_d : o_d + self.n_diag]
        self.states = rows[:, :, o_d + self.n_diag :] if self.n_state else None

    def clear(self) -> None:
        """Forget the rows (the arrays are kept and reused)."""
        self.n = 0
        self.extra[:] = np.nan

    def fits(self, b, a_dim, n_diag, n_extra, n_state) -> bool:
        return (b, a_dim, n_diag, n_extra, n_state) == (self.b, self.a_dim, self.n_diag, self.n_extra, self.n_state)

    def reserve(self) -> int:
        """The index of the next row, the arrays doubled first where they are full."""
        k = self.n
        if k == len(self.t_us):
            rows = np.zeros((2 * k, *self.rows.shape[1:]))
            rows[:k] = self.rows[:k]
            self._views(rows)
            extra = np.full((2 * k, *self.extra.shape[1:]), np.nan)
            extra[:k] = self.extra[:k]
            t_us = np.zeros(2 * k)
            t_us[:k] = self.t_us[:k]
            self.extra, self.t_us = extra, t_us
        return k

    def commit(self, extra, t_us: float) -> None:
        """The row reserved last is written (its extras (B, E) or None, the time per env-step, us)."""
        k = self.n
        if extra is not None:
            self.extra[k, :, : extra.shape[1]] = extra
        self.t_us[k] = t_us
        self.n = k + 1

    def append(self, raw, out, flat, diag, extra, t_us: float) -> None:
        """One call: raw and corrected actions (B, A) or (B, T, A) (step 0 is kept), packed states
        (B, L), diagnostics (B, D), extras (B, E) or None, the time per env-step (us)."""
        k = self.reserve()
        record_row(self.rows, k, raw, out, flat, diag)  # the row as the corrector's stream tick writes it
        self.commit(extra, t_us)


class EpisodeRecorder:
    """Collects per-step corrector output into per-env episodes (a PhysVLACorrectorStep listener).

    Memory stays flat over a long evaluation: when every env restarts together (lerobot-eval's
    next rollout batch) the finished batch is split into episodes, each reduced to its record and
    summary counts, and the recording's rows are reused. Per-step arrays (actions, phases, r_EL:
    the `*_actions`, `phase`, `r_el` fields of a record, the plots) are kept for the first
    `keep_steps` episodes only, or for all of them when asked (keep_steps None, or save_states).

    Attributes:
        horizon: episode length used for efficiency (the env's max steps), or None.
        gripper_index: the gripper's action entry (for the veto firing rate), or None.
        layout: the action layout (corrections per phase in each record), or None.
        save_states: keep every packed state row (for physvla_states.npz); implies keep_steps None.
        keep_steps: number of first episodes whose per-step arrays are kept; None: all.
        episodes: finished and running episodes, in start order (split from the recording when read).
    """

    def __init__(self, horizon: int | None = None, save_states: bool = False, gripper_index: int | None = 6,
                 layout=None, keep_steps: int | None = 10):
        self.horizon = horizon
        self.gripper_index = gripper_index
        self.layout = layout
        self.save_states = save_states
        self.keep_steps = None if save_states else keep_steps
        self._segments: list[_Segment] = []  # recorded rows not yet split into finished episodes
        self._seg: _Segment | None = None  # the segment being appended to
        self._done: list[_Episode] = []  # episodes of finished batches, compacted
        self._done_stats = _no_stats()  # their summary counts, added up
        self._episodes: list[_Episode] | None = None
        self._success: dict[int, bool] = {}  # episode number -> success from the env's own record

    def _keeps(self, number: int) -> bool:
        return self.keep_steps is None or number < self.keep_steps

    def __call__(self, raw, out, flat, extra, corrector, t_total_s) -> None:
        """One corrector call: raw and corrected actions (B, A) or (B, T, A), the packed states
        (B, L), the env extras (B, E) or None, the corrector (its diag_buffer) and the call time (s)."""
        diag = corrector.diag_buffer
        seg = self._segment(raw.shape[0], raw.shape[-1], diag.shape[1], extra, flat)
        seg.append(raw, out, flat, diag, extra, t_total_s * 1e6 / raw.shape[0])
        self._episodes = None

    def slot(self, b: int, a_dim: int, n_diag: int, extra, flat) -> tuple[np.ndarray, int]:
        """Before a corrector call that writes its own row (Corrector.correct_stream(..., rows, k),
        as PhysVLACorrectorStep calls it): the arena and the row index to write; then `commit`."""
        seg = self._segment(b, a_dim, n_diag, extra, flat)
        k = seg.reserve()  # first: a full arena is replaced by a larger one
        return seg.rows, k

    def commit(self, extra, t_us: float) -> None:
        """After the call that filled the row `slot` gave: its extras (B, E) or None and its time
        per env-step (us)."""
        self._seg.commit(extra, t_us)
        self._episodes = None

    def _segment(self, b: int, a_dim: int, n_diag: int, extra, flat) -> _Segment:
        """The segment this call's row goes to: a new one for rows of another shape; the current
        one emptied (its rows reduced to episodes) when every env is back at step 0."""
        n_extra = 0 if extra is None else extra.shape[1]
        n_state = flat.shape[1] if self.save_states else None
        seg = self._seg
        if seg is None or not seg.fits(b, a_dim, n_diag, max(n_extra, seg.n_extra), n_state):
            if self._segments:  # rows of another shape: that recording is over
                self._finish()
            seg = self._seg = _Segment(b, a_dim, n_diag, n_extra, n_state)
            self._segments.append(seg)
        elif flat[0, 1] == 0.0 and seg.n and not flat[:, 1].any() and seg.header[seg.n - 1, :, 1].any():
            # every env back at step 0 (from anywhere else): the last rollout batch is over
            self._finish()
            seg.clear()
            self._segments.append(seg)
        return seg

    def end_batch(self) -> None:
        """The rollout batch recorded so far is over: split it into episodes and compact them now.

        lerobot-eval's hook calls it before each rollout, outside any control tick (compacting costs
        ~1-2 ms per episode); without it the first call of the next batch does the same."""
        seg = self._seg
        if seg is None or not seg.n:
            return
        self._finish()
        seg.clear()
        self._segments.append(seg)

    def _finish(self) -> None:
        """Splits the recorded rows into episodes, compacts them and forgets the rows."""
        for ep in self._split(len(self._done)):
            _add_stats(self._done_stats, ep.compact(self.layout, self.gripper_index, self._keeps(ep.number)))
            self._done.append(ep)
        self._segments = []
        self._episodes = None

    @property
    def episodes(self) -> list[_Episode]:
        if self._episodes is None:
            self._episodes = self._done + self._split(len(self._done))
            for number, ok in self._success.items():
                self._episodes[number].success = ok
        return self._episodes

    def _split(self, first_number: int = 0) -> list[_Episode]:
        """Episodes from the recording, env by env, by the state's step counter and the env's extras:
        a step counter that goes back starts an episode; a repeated one is a frozen sub-env replaying
        its terminal observation; extras echo the executed action and mark success (the env is then
        ignored until every env restarts together: lerobot's next rollout batch)."""
        episodes: list[_Episode] = []
        for seg in self._segments:
            opened: dict[int, tuple[_Episode, list[int]]] = {}
            last: dict[int, float] = {}
            closed: set[int] = set()
            runs: list[tuple[_Episode, list[int], int]] = []
            for k in range(seg.n):
                steps = seg.header[k, :, 1]
                if (steps == 0).all():  # every env just reset: a new rollout batch
                    opened.clear()
                    closed.clear()
                for i in range(seg.b):
                    if i in closed:  # finished: lerobot ignores this env until the next batch
                        continue
                    step, ex = float(steps[i]), seg.extra[k, i]
                    cur = opened.get(i)
                    if cur is not None and step == last[i]:
                        continue
                    if cur is None or step < last[i]:
                        task = int(ex[0]) if ex.size and np.isfinite(ex[0]) else -1
                        cur = opened[i] = (_Episode(i, task, first_number + len(episodes)), [])
                        episodes.append(cur[0])
                        runs.append((cur[0], cur[1], i))
                    elif ex.size > 2 and cur[1] and np.isfinite(ex[2]):
                        cur[0].executed[-1] = ex[2 : 2 + seg.a_dim].copy()  # what the sim executed last step
                    last[i] = step
                    if ex.size > 1 and ex[1] > 0.5:  # the last action succeeded: episode over
                        cur[0].success = True
                        closed.add(i)
                        continue
                    cur[1].append(k)
                    cur[0].executed.append(None)
            for ep, ks, i in runs:
                ep.fill(seg, np.asarray(ks, dtype=np.intp), i)
        return episodes

    def apply_env_successes(self, per_task: dict[int, list[bool]]) -> None:
        """Take success from the env's own record (lerobot's eval_info.json), episode by episode.

        The postprocessor cannot see the outcome of an episode's last step when no further
        policy call follows it (the batch's last env to finish), so the env's word is final.
        Episodes of a task are matched in start order (batch by batch, env index within); where several task
        groups share an id (MetaWorld's: every task its own group, id 0), their successes come concatenated in
        lerobot's order, which is the order their episodes ran.
        """
        by_task: dict[int, list[_Episode]] = {}
        for ep in self.episodes:
            by_task.setdefault(ep.task_id, []).append(ep)
        for task, successes in per_task.items():
            eps = by_task.get(task, [])
            if len(eps) != len(successes):
                continue  # cannot be matched one to one: keep what was observed
            for ep, ok in zip(eps, successes):
                ep.success = self._success[ep.number] = bool(ok)

    def records(self) -> list[dict]:
        return [ep.to_record(self.horizon, self.layout, self._keeps(ep.number)) for ep in self.episodes]

    def summary(self, records: list[dict] | None = None) -> dict:
        recs = self.records() if records is None else records
        n = len(recs)
        k = sum(r["success"] for r in recs)
        lo, hi = metrics.wilson_interval(k, n)
        mean = lambda key: _finite_mean([r[key] for r in recs])  # noqa: E731
        tot = _no_stats()
        _add_stats(tot, self._done_stats)
        for ep in self.episodes:
            if ep.compact_record is None:  # running or not yet compacted
                _add_stats(tot, ep.stats(self.gripper_index))
        phases, total_steps, t_hist = tot["phases"], tot["steps"], tot["t_hist"]
        corrected_steps, approach_steps, veto_steps, el_steps = tot["corrected"], tot["approach"], tot["veto"], tot["el"]
        pt = Counter()
        for r in recs:
            pt.update(r["passthrough"])
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
            # from a log histogram of every step's time (bins ~4.7 % wide)
            "overhead_us_per_env_step": {"p50": _histogram_percentile(t_hist, 50),
                                         "p99": _histogram_percentile(t_hist, 99)},
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
