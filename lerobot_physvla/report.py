"""What the corrector did, for people: a one-screen summary table and per-episode plots.

Shared by `lerobot-physvla-replay` and `lerobot-eval --policy.postprocess=physvla`. Each episode
is summarised as a row (`episode_row`); `summary_table` prints them with a total line, and
`write_report` saves one PNG per episode (phase timeline over the action channels, raw vs
corrected actions, |r_EL| against eps) and a `report.md` indexing them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lerobot_physvla.core.phase import PHASE_NAMES

# the Branch A correction each phase applies (docs/method.md)
CORRECTIONS = ("approach veto", "grasp guidance", "transport EMA + lift", "place guidance")
PHASE_INDEX = {**{name: i for i, name in enumerate(PHASE_NAMES)}, "pass-through": -1}  # phase_timeline's names
PHASE_COLOURS = ("#dbe9f6", "#fde2c8", "#d9f0d3", "#eadcf0")
SHORT = {"approach veto": "veto", "grasp guidance": "grasp", "transport EMA + lift": "transport",
         "place guidance": "place", "branch B": "B", "approach guides": "guide"}


def corrections_by_phase(raw: np.ndarray, corrected: np.ndarray, phase: np.ndarray, layout) -> dict[str, dict]:
    """How often and how much each correction changed the action: per phase, the frames spent in
    it, the frames whose action it changed (the gripper for the approach veto, the position
    channels otherwise) and the mean largest change on those frames, action units; and the approach
    guides (the rim guide, the centre guide and the approach pull: the position channels in the approach
    phase). Attribution is by phase and channel: a low-pass acting in a phase (lowpass=adaptive, the smooth
    preset) counts there too."""
    raw, corrected, phase = np.asarray(raw, float), np.asarray(corrected, float), np.asarray(phase)
    delta = np.abs(corrected - raw) if raw.size else np.zeros((0, layout.dim))
    pos, g = list(layout.pos), layout.gripper
    out = {}
    for p, name in enumerate(CORRECTIONS):
        sel = phase == p
        ch = [g] if p == 0 and g is not None else pos
        out[name] = _changed(delta, sel, ch)
    out["approach guides"] = _changed(delta, phase == 0, pos)
    return out


def _changed(delta: np.ndarray, sel: np.ndarray, ch: list) -> dict:
    """Frames in `sel`, those whose channels `ch` changed, and the mean largest change there."""
    changed = sel & (delta[:, ch].max(axis=1) > 0) if len(delta) else sel
    return {"frames_in_phase": int(sel.sum()), "frames_changed": int(changed.sum()),
            "mean_abs_change": float(delta[changed][:, ch].max(axis=1).mean()) if changed.any() else 0.0}


def phase_timeline(phases) -> list[list]:
    """Run-length phase timeline: [[phase name, frames], ...] ("pass-through" for -1)."""
    out: list[list] = []
    for p in np.asarray(phases):
        name = PHASE_NAMES[p] if p >= 0 else "pass-through"
        if out and out[-1][0] == name:
            out[-1][1] += 1
        else:
            out.append([name, 1])
    return out


def episode_row(episode, task: str, frames: int, success, phase, corrections: dict, frames_changed: int,
                overhead_us, passthrough: dict) -> dict:
    """One line of the summary table (JSON-able)."""
    phase = np.asarray(phase)
    return {
        "episode": episode, "task": task, "frames": int(frames),
        "success": "-" if success is None else ("yes" if success else "no"),
        "phases": "/".join(f"{(phase == i).mean() * 100:.0f}" if len(phase) else "0" for i in range(len(PHASE_NAMES))),
        "changed": f"{frames_changed / max(frames, 1) * 100:.0f}%",
        "fired": ", ".join(f"{SHORT.get(k, k)} {v['frames_changed']}" for k, v in corrections.items()
                           if v["frames_changed"]) or "none",
        "overhead_us": "-" if overhead_us is None else f"{overhead_us:.1f}",
        "passthrough": ", ".join(f"{k} {v}" for k, v in passthrough.items() if v) or "none",
    }


COLUMNS = (("episode", "ep"), ("task", "task"), ("frames", "frames"), ("success", "success"),
           ("phases", "phases % A/G/T/P"), ("changed", "changed"), ("fired", "corrections fired (frames)"),
           ("overhead_us", "us/frame p50"), ("passthrough", "pass-throughs"))


def summary_table(rows: list[dict], extra: dict[str, str] | None = None, max_rows: int = 20, markdown: bool = False) -> str:
    """The one-screen table: one row per episode (the first max_rows), then a total line and
    `extra` lines (label: value)."""
    shown = rows[:max_rows]
    cells = [[str(r[k])[:48] if k == "task" else str(r[k]) for k, _ in COLUMNS] for r in shown]
    heads = [h for _, h in COLUMNS]
    if markdown:
        lines = ["| " + " | ".join(heads) + " |", "|" + "---|" * len(heads)]
        lines += ["| " + " | ".join(c) + " |" for c in cells]
    else:
        w = [max([len(h)] + [len(c[i]) for c in cells]) for i, h in enumerate(heads)]
        lines = ["  ".join(h.ljust(w[i]) for i, h in enumerate(heads)), "  ".join("-" * x for x in w)]
        lines += ["  ".join(c[i].ljust(w[i]) for i in range(len(heads))) for c in cells]
    if len(rows) > max_rows:
        lines.append(f"... {len(rows) - max_rows} more episodes (all of them in the JSON records)")
    known = [r for r in rows if r["success"] != "-"]
    total = f"{len(rows)} episodes, {sum(r['frames'] for r in rows)} frames"
    if known:  # "recorded/raw/corrected" rows (re-simulation) count the recorded outcome here
        ok = sum(str(r["success"]).split("/")[0] == "yes" for r in known)
        total += f", {'recorded ' if '/' in str(known[0]['success']) else ''}success {ok}/{len(known)}"
    lines.append(("\n" if markdown else "") + total)
    for k, v in (extra or {}).items():
        lines.append(f"{k}: {v}" + ("  " if markdown else ""))
    return "\n".join(lines)


def plot_episode(path: str | Path, raw: np.ndarray, corrected: np.ndarray, phase: np.ndarray, r_el: np.ndarray | None,
                 eps_nm: float | None, layout, title: str) -> Path:
    """One PNG: (1) the corrected action channels over the phase timeline, (2) raw vs corrected
    on every channel the corrector changed, (3) |r_EL| with eps (or why there is none)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    raw, corrected, phase = np.asarray(raw, float), np.asarray(corrected, float), np.asarray(phase)
    t = np.arange(len(raw))
    names = _channel_names(layout)
    fig, axes = plt.subplots(3, 1, figsize=(10, 7.5), sharex=True, gridspec_kw={"height_ratios": [2, 2, 1]})
    for ax in axes[:2]:
        _phase_bands(ax, phase)
    for i in range(raw.shape[1]):
        axes[0].plot(t, corrected[:, i], lw=1, label=names[i])
    axes[0].set_ylabel("corrected action")
    axes[0].legend(ncol=min(raw.shape[1], 7), fontsize=7, loc="upper right")
    changed = [i for i in range(raw.shape[1]) if np.abs(corrected[:, i] - raw[:, i]).max() > 0] if len(raw) else []
    for i in changed:
        line, = axes[1].plot(t, raw[:, i], lw=1, ls="--", label=f"{names[i]} raw")
        axes[1].plot(t, corrected[:, i], lw=1.2, color=line.get_color(), label=f"{names[i]} corrected")
    axes[1].set_ylabel("raw (--) vs corrected")
    if changed:
        axes[1].legend(ncol=4, fontsize=7, loc="upper right")
    else:
        axes[1].text(0.5, 0.5, "the corrector changed no channel", transform=axes[1].transAxes, ha="center")
    r = None if r_el is None else np.asarray(r_el, float)
    if r is not None and np.isfinite(r).any():
        axes[2].semilogy(t, np.abs(r), lw=1, color="k", label="|r_EL|")
        if eps_nm:
            axes[2].axhline(eps_nm, color="r", lw=1, ls=":", label=f"eps = {eps_nm} N m")
        axes[2].legend(fontsize=7, loc="upper right")
    else:
        axes[2].text(0.5, 0.5, "Branch B did not run (no |r_EL|)", transform=axes[2].transAxes, ha="center")
    axes[2].set_ylabel("|r_EL| (N m)")
    axes[2].set_xlabel("frame")
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in PHASE_COLOURS]
    fig.suptitle(title, fontsize=10, y=0.995)
    fig.legend(handles, PHASE_NAMES, loc="upper center", bbox_to_anchor=(0.5, 0.965), ncol=4, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def _channel_names(layout) -> list[str]:
    names = [f"a{i}" for i in range(layout.dim)]
    for i, n in zip(layout.pos, ("x", "y", "z")):
        names[i] = n
    for k, i in enumerate(layout.rot):
        names[i] = f"r{k}"
    if layout.gripper is not None:
        names[layout.gripper] = "gripper"
    return names


def _phase_bands(ax, phase: np.ndarray) -> None:
    start = 0
    for t in range(1, len(phase) + 1):
        if t == len(phase) or phase[t] != phase[start]:
            p = phase[start]
            if p >= 0:
                ax.axvspan(start - 0.5, t - 0.5, color=PHASE_COLOURS[p % 4], lw=0)
            start = t


def write_report(out_dir: str | Path, title: str, table_md: str, plots: list[tuple[str, Path]], notes: list[str] = (),
                 name: str = "report.md") -> Path:
    """`name` (report.md) in out_dir: the summary table, notes, and links to the per-episode plots."""
    out = Path(out_dir)
    lines = [f"# {title}", "", table_md, ""]
    lines += [f"- {n}" for n in notes]
    if plots:
        lines += ["", "## Episodes", ""]
        for label, p in plots:
            rel = Path(p).relative_to(out) if Path(p).is_relative_to(out) else Path(p)
            lines += [f"### {label}", "", f"![{label}]({rel.as_posix()})", ""]
    path = out / name
    path.write_text("\n".join(lines) + "\n")
    return path
