"""One episode of a study's cell, step by step: what the policy commanded, what was executed, and where.

    .venv/bin/python eval/trace_episode.py camera_libero_pro --block original --backbone object_act_camera \\
        --config "shipped default" --task 1 --seed 30 [--every 3] [--set centre_guide=false]

The episode runs as eval/harness.py runs the study's unit (the block's scene, the backbone's policy, the
configuration as the study resolves it on that scene). Printed every `--every` control steps, and at every step
where the corrector changed the policy's action beyond clipping it, or the phase changed:

    step  phase  d_xy  h  lift  tgt   the corrector's phase; the hand's horizontal distance from the object and its
                                      height above the object's origin, the object's lift, and the object's
                                      horizontal distance from the target (cm)
    policy xyz g / executed xyz g  the action's first three channels and the gripper (action units)
    why                          what moved it: "clip" (the action space alone), "gripper held open", "xyz", or
                                 a pass-through's reason

The last lines give the episode's record (success, steps, steps changed) and, when the study holds that episode,
its stored record beside it: the trace is the study's episode. `--set FIELD=VALUE` (repeatable) changes a
PhysVLAConfig field for a what-if; its record is then not the study's. The seed must be one of the block's (a block
never holds LIBERO's untouched init states 40-49).
"""

from __future__ import annotations

import argparse
import ast
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import harness  # noqa: E402
from store import Store, config_hash  # noqa: E402
from study import Study, find  # noqa: E402

CM = 100.0


def _value(text: str):
    """A --set value: a Python literal (0.02, false, [1, 2]) or the text itself."""
    low = {"true": "True", "false": "False"}.get(text.lower(), text)
    try:
        return ast.literal_eval(low)
    except (ValueError, SyntaxError):
        return text


def overrides(pairs: list[str]) -> dict:
    out = {}
    for p in pairs:
        if "=" not in p:
            raise SystemExit(f"trace: --set takes FIELD=VALUE, not {p!r}")
        k, v = p.split("=", 1)
        out[k.strip()] = _value(v.strip())
    return out


def unit_of(study: Study, block: str, backbone: str, config: str, task: int, seed: int, changes: dict) -> harness.Unit:
    """The harness unit of one episode, the configuration changed by `changes` (PhysVLAConfig fields)."""
    if block not in study.blocks:
        raise SystemExit(f"trace: study {study.name} has no block {block!r}; its blocks: {', '.join(study.blocks)}")
    bl = study.blocks[block]
    if backbone not in bl.backbones:
        raise SystemExit(f"trace: block {block!r} runs {', '.join(bl.backbones)}, not {backbone!r}")
    if task not in bl.tasks or seed not in bl.seeds:
        raise SystemExit(f"trace: block {block!r} holds tasks {bl.tasks[0]}-{bl.tasks[-1]} and seeds "
                         f"{bl.seeds[0]}-{bl.seeds[-1]}; task {task} seed {seed} is not one of its episodes")
    cfg = dict(study.config(config, bl.scene))
    if changes:
        from lerobot_physvla.core.config import PhysVLAConfig

        unknown = sorted(set(changes) - set(PhysVLAConfig().to_dict()))
        if unknown:
            raise SystemExit(f"trace: --set {unknown}: not PhysVLAConfig fields (docs/method.md lists them)")
        cfg.update(changes)
    spec = study.backbone_spec(backbone)
    policy = str(study.policy_path(backbone).resolve()) if "policy" in spec else ""
    return harness.Unit(backbone, config_hash(cfg), cfg, task, seed, 1, dict(spec.get("expert", {})), bl.scene, policy)


class Printer:
    """Prints the steps worth reading (module doc) as they come; counts the steps the corrector changed."""

    def __init__(self, grip: int | None, every: int, low: float, high: float, gripper_open: float):
        self.grip, self.every, self.low, self.high, self.open = grip, every, low, high, gripper_open
        self.last_phase = None
        print(f"{'step':>4} {'phase':>5} {'d_xy':>5} {'h':>5} {'lift':>5} {'tgt':>5}   {'policy xyz':<20} {'g':>5}   "
              f"{'executed xyz':<20} {'g':>5}   why")

    def why(self, raw: np.ndarray, out: np.ndarray, status: int) -> str:
        if status != 0:
            from lerobot_physvla.core.corrector import REASONS

            return f"passed through: {REASONS[status]}"
        clipped = np.clip(raw, self.low, self.high)
        if np.allclose(out, clipped, atol=harness.CHANGE_TOL):
            return "clip" if not np.allclose(out, raw, atol=harness.CHANGE_TOL) else ""
        parts = []
        if self.grip is not None and abs(out[self.grip] - clipped[self.grip]) > harness.CHANGE_TOL:
            parts.append("gripper held open" if abs(out[self.grip] - self.open) < 1e-9 else "gripper")
        if not np.allclose(out[:3], clipped[:3], atol=harness.CHANGE_TOL):
            parts.append("xyz")
        return ", ".join(parts) or "other channels"

    def __call__(self, step, st, raw, out, d):
        phase = int(d.phase[0])
        raw, out = raw[0], out[0]
        why = self.why(raw, out, int(d.status[0]))
        if step % self.every and phase == self.last_phase and why in ("", "clip"):
            return
        self.last_phase = phase
        h = (st.eef_pos[0, 2] - st.obj_pos[0, 2]) * CM
        tgt = float(np.hypot(*(st.obj_pos[0, :2] - st.target_pos[0, :2]))) * CM
        g = "" if self.grip is None else f"{raw[self.grip]:+5.2f}"
        go = "" if self.grip is None else f"{out[self.grip]:+5.2f}"
        print(f"{step:4d} {phase:5d} {d.d_obj_xy[0] * CM:5.1f} {h:5.1f} {d.lift[0] * CM:5.1f} {tgt:5.1f}   "
              f"{np.array2string(raw[:3], precision=2, suppress_small=True):<20} {g:>5}   "
              f"{np.array2string(out[:3], precision=2, suppress_small=True):<20} {go:>5}   {why}")


def trace(study: Study, unit: harness.Unit, every: int) -> dict:
    """Run the unit's one episode, printing it; returns its record."""
    from lerobot_physvla.core.config import PhysVLAConfig
    from lerobot_physvla.core.corrector import Corrector

    scene = harness._scene(unit.scene_name)
    backbone = harness._backbone(unit, scene)
    config = dict(unit.config)
    if config.pop("perception", None) or config.pop("pose_source", None):
        raise SystemExit("trace: configurations with perception faults or marker poses are not traced (exact poses "
                         "only); run the study's unit instead")
    corrector = Corrector(PhysVLAConfig.from_dict(config).for_policy(getattr(backbone, "actions_per_call", 1)))
    lay = corrector.layout
    printer = Printer(lay.gripper, every, lay.low, lay.high, lay.gripper_open)
    return harness.run_episode(scene, corrector, backbone, unit.first_seed, on_step=printer)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("study")
    ap.add_argument("--block", required=True)
    ap.add_argument("--backbone", required=True)
    ap.add_argument("--config", required=True, help="a configuration of the study ([configs])")
    ap.add_argument("--task", type=int, default=0)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--every", type=int, default=5, help="print every n-th step (and every step that matters)")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", help="change a configuration field")
    args = ap.parse_args(argv)
    study = Study(find(args.study))
    changes = overrides(args.set)
    unit = unit_of(study, args.block, args.backbone, args.config, args.task, args.seed, changes)
    rec = trace(study, unit, max(args.every, 1))
    print(f"episode: success {rec['success']}, {rec['steps']} steps, steps changed {rec['changed_fraction']:.0%}, "
          f"mean change {rec['change_norm']:.3f} action units (policy's mean {rec['action_norm']:.3f})")
    stored = None if changes else Store(study.data[0])._load().get(
        (unit.backbone, unit.config_name, unit.scene, unit.task_id, unit.first_seed))
    if stored is not None:
        same = stored["success"] == rec["success"] and stored["steps"] == rec["steps"]
        print(f"the study's record: success {stored['success']}, {stored['steps']} steps "
              f"({'the same episode' if same else 'DIFFERENT from this run'})")
    elif changes:
        print(f"changed: {', '.join(f'{k}={v!r}' for k, v in changes.items())} (a what-if, not the study's episode)")
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    # robosuite's EGL render context (camera scenes) fails its own teardown at interpreter exit and prints a
    # traceback that says nothing about the episode; the episode is done and printed, so leave without it
    os._exit(code)
