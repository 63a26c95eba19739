"""Comparisons of configurations on the same episodes: paired and pooled differences, won / lost / both /
neither, Wilson and paired intervals, per-task regressions, jerk and degradation ratios, and a decision
rule evaluated from its declarative spec (a list of checks in a study file).

Every function takes episode rows (eval/store.py) already selected for one configuration; rows pair
on (scene, task_id, seed): the same init state and the same drawn faults (a row from before rows named their
scene pairs on its task and seed alone).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from lerobot_physvla import metrics

Z95 = 1.96


def _finite_mean(vals) -> float:
    vals = [v for v in vals if v is not None and np.isfinite(v)]
    return float(np.mean(vals)) if vals else float("nan")


def aggregate(rows: list[dict]) -> dict:
    """Success with its 95 % Wilson interval and the mean of each metric over some episodes."""
    k, n = sum(r["success"] for r in rows), len(rows)
    lo, hi = metrics.wilson_interval(k, n)
    out = {"n": n, "successes": k, "success": k / n if n else float("nan"), "ci": (lo, hi)}
    for m in ("precision", "efficiency", "stability", "mean_jerk", "sparc", "ldlj", "veto_fire_rate", "el_fire_rate",
              "reward", "changed_fraction", "change_norm", "action_norm"):
        out[m] = _finite_mean(r.get(m) for r in rows)
    out["t_total_us"] = float(np.median([r["t_us_p50"]["total"] for r in rows])) if rows and "t_us_p50" in rows[0] \
        else float("nan")
    return out


def _pair_key(r: dict) -> tuple[str, int, int]:
    return r.get("scene", ""), r["task_id"], r["seed"]


def paired(this: list[dict], base: list[dict]) -> dict:
    """Paired outcomes of `this` against `base` over the (scene, task, seed) pairs both ran: won / lost / both /
    neither, the mean per-pair success difference with its 95 % interval (normal approximation of the mean
    of differences in {-1, 0, 1}), the mean per-pair jerk ratio, and the tasks where `this` lost net (by task id,
    or "<scene>/<task id>" where the rows span several scenes)."""
    a_by = {_pair_key(r): r for r in this}
    b_by = {_pair_key(r): r for r in base}
    keys = sorted(set(a_by) & set(b_by))
    several = len({k[0] for k in keys}) > 1
    won = lost = both = neither = 0
    d, dj = [], []
    per_task = defaultdict(lambda: [0, 0])
    for key in keys:
        a, b = a_by[key], b_by[key]
        won += a["success"] and not b["success"]
        lost += b["success"] and not a["success"]
        both += a["success"] and b["success"]
        neither += not (a["success"] or b["success"])
        d.append(int(a["success"]) - int(b["success"]))
        dj.append(a["mean_jerk"] / b["mean_jerk"] if b["mean_jerk"] > 0 else np.nan)
        task = f"{key[0]}/{key[1]}" if several else key[1]
        per_task[task][0] += int(a["success"])
        per_task[task][1] += int(b["success"])
    n = len(d)
    mean = float(np.mean(d)) if n else float("nan")
    half = Z95 * float(np.std(d, ddof=1)) / np.sqrt(n) if n > 1 else float("nan")
    return {"n": n, "won": int(won), "lost": int(lost), "both": int(both), "neither": int(neither), "diff": mean,
            "ci": (mean - half, mean + half), "jerk_ratio": float(np.nanmean(dj)) if dj else float("nan"),
            "success": (won + both) / n if n else float("nan"), "base_success": (lost + both) / n if n else float("nan"),
            "task_losses": {t: v[1] - v[0] for t, v in per_task.items() if v[0] < v[1]},
            "differences": d}


def pooled(results: list[dict]) -> dict:
    """Several paired results pooled: the mean of every per-pair difference with its 95 % interval."""
    d = [x for p in results for x in p["differences"]]
    n = len(d)
    mean = float(np.mean(d)) if n else float("nan")
    half = Z95 * float(np.std(d, ddof=1)) / np.sqrt(n) if n > 1 else float("nan")
    return {"n": n, "diff": mean, "ci": (mean - half, mean + half), "won": sum(x > 0 for x in d),
            "lost": sum(x < 0 for x in d)}


def degradation(at_zero: list[dict], at_noise: list[dict]) -> float:
    """Relative growth of the mean jerk from the noise-free cell to the noisy one (paper Table A1)."""
    j0, j1 = _finite_mean(r["mean_jerk"] for r in at_zero), _finite_mean(r["mean_jerk"] for r in at_noise)
    return (j1 - j0) / j0


def degradation_ratio(base: float, this: float) -> float:
    """Baseline's jerk degradation over this configuration's (paper Table A1: ~10x)."""
    return base / this if this > 0 else float("inf")


# ---------------------------------------------------------------------------------------------- decision rules

METRICS = ("net", "won_minus_lost_pooled", "pooled_diff", "pooled_lower", "jerk_ratio", "cell_successes",
           "degradation_ratio", "kept", "competent", "changed")
COMPETENT_RATE = 0.8  # a backbone this successful uncorrected (its comparison's baseline) is a competent policy


@dataclass(frozen=True)
class Check:
    """One check of a decision rule, as a study file declares it.

    Attributes:
        metric: what is measured on the role's blocks, candidate against `against`:
            - "net": pairs won minus pairs lost, for each backbone;
            - "won_minus_lost_pooled": the same pooled over the backbones named;
            - "pooled_diff": the pooled paired difference in success (0-1) over the backbones named;
            - "pooled_lower": the lower end of the pooled paired difference's 95 % interval (success, 0-1);
            - "jerk_ratio": the mean per-pair jerk ratio, for each backbone;
            - "cell_successes": successes minus the other configuration's, for each backbone (noise cells);
            - "degradation_ratio": baseline's jerk degradation over the candidate's between two noise cells
              (`cells` = [noise-free backbone, noisy backbone]);
            - "kept": the candidate's gain over baseline (successes, same pairs) as a fraction of the reference's,
              for each backbone (`against` names nothing here: it reads all three; a reference that gains nothing
              gives inf where the candidate gains as much, else -inf).
            - "competent": "net" against baseline for each backbone whose baseline succeeds in COMPETENT_RATE or
              more of its pairs (the competent-policy check, COMPETENT: every comparison has it unless its study
              drops it, saying why);
            - "changed": pairs whose outcome differs (won plus lost), for each backbone: 0 = identical outcomes.
        against: "baseline" or "reference".
        backbones: the backbones it reads ([] = every backbone of the role's blocks); a name may be a group.
        exclude: backbones left out.
        min, max: the bounds the value must meet (inclusive); above: a strict lower bound.
        cells: for degradation_ratio, the noise-free and the noisy backbone names.
        label: what the check stands for, in words (shown in the report).
    """

    metric: str
    against: str = "reference"
    backbones: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()
    min: float | None = None
    max: float | None = None
    above: float | None = None
    cells: tuple[str, ...] = ()
    label: str = ""

    @classmethod
    def from_dict(cls, d: dict) -> Check:
        d = dict(d)
        if d.get("metric") not in METRICS:
            raise ValueError(f"rule: unknown metric {d.get('metric')!r}; choose one of {', '.join(METRICS)}")
        if d.get("against", "reference") not in ("baseline", "reference"):
            raise ValueError(f"rule: against must be 'baseline' or 'reference', not {d['against']!r}")
        for k in ("backbones", "exclude", "cells"):
            if k in d:
                d[k] = tuple([d[k]] if isinstance(d[k], str) else d[k])
        return cls(**d)

    def bounds_ok(self, v: float) -> bool:
        if not np.isfinite(v) and not (v == float("inf") and self.min is not None):
            return False
        return bool((self.min is None or v >= self.min) and (self.max is None or v <= self.max)
                    and (self.above is None or v > self.above))

    def bounds_text(self) -> str:
        parts = [f">= {self.min:g}" if self.min is not None else "", f"<= {self.max:g}" if self.max is not None else "",
                 f"> {self.above:g}" if self.above is not None else ""]
        return " and ".join(p for p in parts if p)


def kept(candidate: list[dict], reference: list[dict], baseline: list[dict]) -> float:
    """The candidate's gain in successes over baseline as a fraction of the reference's (rows paired on the same
    episodes: each list holds one row per pair); a reference that gains nothing: inf where the candidate gains
    as much or more, else -inf."""
    base = sum(r["success"] for r in baseline)
    gain, ref = sum(r["success"] for r in candidate) - base, sum(r["success"] for r in reference) - base
    if ref <= 0:
        return float("inf") if gain >= ref else float("-inf")
    return gain / ref


def evaluate(check: Check, cells: dict[str, dict[str, list[dict]]], backbones: list[str]) -> tuple[bool | None, str]:
    """One check on one role's cells ({backbone: {"candidate" | "reference" | "baseline": rows, "n": pairs the
    blocks hold}}): whether it holds and the values it read, in words. A check fails as soon as a complete
    cell fails it; it is undecided (None) when no cell fails and one it reads is incomplete."""
    other = check.against

    def complete(b: str, *configs: str) -> bool:
        c = cells.get(b, {})
        return all(len(c.get(k, [])) == c.get("n", -1) for k in configs)

    if check.metric == "degradation_ratio":
        zero, noisy = check.cells
        if not all(complete(b, "candidate", "baseline") for b in (zero, noisy)):
            return None, "a cell is incomplete"
        ratio = degradation_ratio(degradation(cells[zero]["baseline"], cells[noisy]["baseline"]),
                                  degradation(cells[zero]["candidate"], cells[noisy]["candidate"]))
        return check.bounds_ok(ratio), f"{ratio:.2f}"
    # the backbones of this role's blocks the check names; one where neither configuration ran is not part
    # of the comparison (a backbone added to the project later)
    names = [b for b in (check.backbones or backbones) if b not in check.exclude and b in backbones
             and (cells.get(b, {}).get("candidate") or cells.get(b, {}).get(other))]
    if not names:
        return None, "no backbone of these blocks ran"
    whole = [b for b in names if complete(b, "candidate", other)]
    partial = [b for b in names if b not in whole]
    if check.metric in ("won_minus_lost_pooled", "pooled_diff", "pooled_lower"):
        if partial:
            return None, "incomplete: " + ", ".join(partial)
        pool = pooled([paired(cells[b]["candidate"], cells[b][other]) for b in whole])
        if check.metric == "won_minus_lost_pooled":
            v = pool["won"] - pool["lost"]
            return check.bounds_ok(v), f"{pool['won']} won / {pool['lost']} lost over {pool['n']} pairs"
        if check.metric == "pooled_diff":
            return check.bounds_ok(pool["diff"]), f"{pool['diff'] * 100:+.1f} pp over {pool['n']} pairs"
        return check.bounds_ok(pool["ci"][0]), (f"{pool['diff'] * 100:+.1f} pp [{pool['ci'][0] * 100:+.1f}, "
                                               f"{pool['ci'][1] * 100:+.1f}] over {pool['n']} pairs")
    if check.metric == "competent":
        whole = [b for b in names if complete(b, "candidate", "baseline")]
        partial = [b for b in names if b not in whole]
        rates = {b: sum(r["success"] for r in cells[b]["baseline"]) / max(len(cells[b]["baseline"]), 1) for b in whole}
        whole = [b for b in whole if rates[b] >= COMPETENT_RATE]
        if not whole and not partial:
            return True, f"no backbone at {COMPETENT_RATE:.0%} or more uncorrected"
    if check.metric == "kept":
        whole = [b for b in names if complete(b, "candidate", "reference", "baseline")]
        partial = [b for b in names if b not in whole]
        vals = {b: kept(cells[b]["candidate"], cells[b]["reference"], cells[b]["baseline"]) for b in whole}
    elif check.metric == "cell_successes":
        vals = {b: sum(r["success"] for r in cells[b]["candidate"]) - sum(r["success"] for r in cells[b][other])
                for b in whole}
    else:
        ps = {b: paired(cells[b]["candidate"], cells[b][other]) for b in whole}
        vals = {b: p["won"] - p["lost"] if check.metric in ("net", "competent") else p["won"] + p["lost"]
                if check.metric == "changed" else p["jerk_ratio"] for b, p in ps.items()}
    fmt = "{:.2f}" if check.metric in ("jerk_ratio", "kept") else "{:d}" if check.metric == "changed" else "{:+d}"
    what = ", ".join(f"{b} {fmt.format(v)}" for b, v in vals.items()) + ("; incomplete: " + ", ".join(partial)
                                                                         if partial else "")
    if not all(check.bounds_ok(v) for v in vals.values()):
        return False, what
    return (None if partial else True), what


COMPETENT = Check("competent", against="baseline", min=-1, label=f"competent policy: no backbone at {COMPETENT_RATE:.0%} "
                  "or more uncorrected more than 1 pair net down against baseline (every comparison, unless dropped)")


def combine(results: list[bool | None]) -> bool | None:
    """A rule's verdict from its checks': it fails if any check fails, is undecided if any is, else holds."""
    if any(r is False for r in results):
        return False
    return None if any(r is None for r in results) else True
