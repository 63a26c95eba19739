"""`physvla-demo`: one LIBERO-Spatial episode, scripted policy -> corrector -> simulator.

Prints the phase timeline, what the corrector changed, Branch B's residuals and the per-step
overhead. Runs state-only (no cameras) unless --cameras is given.
"""

from __future__ import annotations

import argparse
import itertools
import time

import numpy as np

from lerobot_physvla.core.config import MODES, PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.phase import PHASE_NAMES


def run_length(phases: list[int]) -> str:
    parts = []
    for ph, grp in itertools.groupby(phases):
        name = PHASE_NAMES[ph] if ph >= 0 else "pass-through"
        parts.append(f"{name} x{len(list(grp))}")
    return " -> ".join(parts)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="physvla-demo", description=__doc__.split("\n\n")[0])
    ap.add_argument("--task", type=int, default=0, help="LIBERO-Spatial task id (0-9)")
    ap.add_argument("--init-state", type=int, default=0)
    ap.add_argument("--mode", default="phys_el", choices=MODES)
    ap.add_argument("--steps", type=int, default=150, help="at most this many control steps (20 Hz)")
    ap.add_argument("--cameras", action="store_true", help="render LIBERO's cameras too (~0.6 s a step here)")
    args = ap.parse_args(argv)

    from lerobot_physvla.sim import libero_sim
    from lerobot_physvla.sim.experts import PickPlaceExpert
    from lerobot_physvla.sources.robosuite import RobosuiteStateSource

    task = libero_sim.load_task("libero_spatial", args.task)
    print(f"LIBERO-Spatial task {args.task}: {task.language!r}  (mode={args.mode}, cameras={'on' if args.cameras else 'off'})")
    env = libero_sim.make_libero_env(task, cameras=args.cameras)
    libero_sim.reset_to_init_state(env, task, args.init_state)
    src = RobosuiteStateSource(env.env)
    src.reset()
    print(f"object {src.obj_name!r} -> target {src.target_name!r} (from the task's BDDL goal)")

    corr = Corrector(PhysVLAConfig.paper(mode=args.mode))
    expert = PickPlaceExpert()
    phases, devs, r_el, t_a, t_b, t_tot, t_env = [], [], [], [], [], [], []
    success = False
    for step in range(args.steps):
        st = src.read()
        raw = expert.act(st.eef_pos[0], st.obj_pos[0], st.target_pos[0])[None]
        out = corr(raw, st)
        d = corr.last
        t0 = time.perf_counter()
        env.step(out[0])
        t_env.append(time.perf_counter() - t0)
        src.step()
        phases.append(int(d.phase[0]))
        devs.append(float(d.deviation[0]))
        r_el.append(float(d.r_el[0]))
        t_a.append(d.t_branch_a_s)
        t_b.append(d.t_branch_b_s)
        t_tot.append(d.t_total_s)
        if env.check_success():
            success = True
            break
    env.close()

    us = lambda x, q: np.percentile(np.asarray(x) * 1e6, q)  # noqa: E731
    print(f"\nsteps: {len(phases)}   success: {success}")
    print(f"phase timeline: {run_length(phases)}")
    devs_a = np.asarray(devs)
    print(f"corrected steps: {(devs_a > 0).mean():.0%}   max |a - a_raw|: {devs_a.max():.3f} action units")
    if np.isfinite(r_el).any():
        r = np.asarray(r_el)
        print(f"|r_EL| (N m): p50 {np.nanmedian(r):.2f}  p99 {np.nanpercentile(r, 99):.2f}")
    print(
        f"corrector time per step (us): total p50 {us(t_tot, 50):.1f} p99 {us(t_tot, 99):.1f} | "
        f"branch A p50 {us(t_a, 50):.1f} | branch B + blend p50 {us(t_b, 50):.1f}"
    )
    print(f"env step (us): p50 {us(t_env, 50):.0f}  -> corrector / env step = {np.median(t_tot) / np.median(t_env):.4f}")
    if corr.passthrough_counts:
        print(f"passed through unchanged: {dict(corr.passthrough_counts)}")


if __name__ == "__main__":
    main()
