"""Per-step overhead of the corrector, side by side with a no-op corrector and the env step.

    .venv/bin/python eval/bench/overhead.py [--steps 200] [--repeats 20] [--episodes 2] [--out eval/results/bench_overhead]

1. Kernel: records a real LIBERO-Spatial task-0 episode (state-only, no cameras) -- the scripted
   expert's raw actions and the packed physical state at every step -- then replays those inputs
   through `Corrector` for B = 1 and B = 8 envs (env i starts i*17 steps into the episode, so the
   batch mixes phases), for a no-op corrector and each mode, the configs interleaved repeat by
   repeat so that machine noise falls on all of them alike. Branch A / Branch B columns come from
   a profiling twin of each corrector (its stages called one by one); the total is the default,
   fused call.
2. Whole path, live in the env loop (what `lerobot-eval --policy.postprocess=physvla` pays per
   env-step): the state read (`RobosuiteStateSource.read_packed`), the capture step and the
   corrector step (phys_el, with the EpisodeRecorder that lerobot-eval attaches: diagnostics
   included) on torch tensors as lerobot hands them over, timed right after each real env step
   (caches cold, as in a rollout) and again three times back to back on the same inputs (warm).
   B = 8 reads the env 8 times (each env reads its own state) and counts (capture + step) / 8.
   A no-op path (the same tensor conversions, no correction) is timed beside it.
3. Whole path inside lerobot-eval: `lerobot-eval --policy.postprocess=physvla` itself (its
   eval_main in a fresh process, the scripted policy checkpoint, B = 1 and B = 8 on a sync vector
   env), the reads, the capture step and the corrector step each timed where lerobot calls them,
   between lerobot's own work: what a user pays, with lerobot's and the policy's cache traffic.
4. First call: a fresh process builds the env, the source and the steps, then times the very
   first whole-path call (and the first no-op call).
5. Memory: RSS growth of the corrector step over 10^5 steps (B = 1), without and with the recorder.

Prints every row and, last, `whole path p50 <x> us, p99 <y> us, first call <z> us (B=1)` (inside
lerobot-eval, item 3).
Writes a markdown table and a JSON next to it.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch
from numba import njit
from lerobot.lerobot_types import TransitionKey

from lerobot_physvla.sim import libero_sim
from lerobot_physvla.core.config import DEFAULT_PRESET, PRESETS, PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.direct_call import direct_entry
from lerobot_physvla.core.tick import stream_tick
from lerobot_physvla.sim.experts import PickPlaceExpert
from lerobot_physvla.sources.robosuite import RobosuiteStateSource
from lerobot_physvla.core.state import PhysState
from lerobot_physvla.diagnostics import EpisodeRecorder
from lerobot_physvla.processor.physvla_processor import (
    EXTRA_KEY, ROBOT_STATE, STATE_KEY, PhysVLACorrectorStep, PhysVLAStateCaptureStep,
)

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = {
    "no-op (identity function)": None,
    "baseline mode (phases only)": PhysVLAConfig.paper(mode="baseline"),
    "temporal": PhysVLAConfig.paper(mode="temporal"),
    "phys": PhysVLAConfig.paper(mode="phys"),
    "phys_el joint_diag": PhysVLAConfig.paper(mode="phys_el"),
    "phys_el task_space": PhysVLAConfig.paper(mode="phys_el", weighting="task_space"),
    "phys_el gated": PhysVLAConfig.paper(mode="phys_el", el_mode="gated"),
    "shipped default": PRESETS[DEFAULT_PRESET],
    "shipped default + pose filter": PRESETS[DEFAULT_PRESET].replace(pose_noise_m=0.01),
    "smooth preset": PRESETS["smooth"],
}


def record(steps: int):
    task = libero_sim.load_task("libero_spatial", 0)
    env = libero_sim.make_libero_env(task)
    libero_sim.reset_to_init_state(env, task, 0)
    src = RobosuiteStateSource(env.env)
    src.reset()
    expert = PickPlaceExpert()
    rows, actions, t_step, t_read = [], [], [], []
    for _ in range(steps):
        t0 = time.perf_counter()
        row = src.read_packed()
        t1 = time.perf_counter()
        a = expert.act(row[3:6], row[7:10], row[11:14])
        t2 = time.perf_counter()
        env.step(a)
        t3 = time.perf_counter()
        src.step()
        rows.append(row.copy())
        actions.append(a)
        t_read.append(t1 - t0)
        t_step.append(t3 - t2)
    env.close()
    return np.array(rows), np.array(actions), np.array(t_step), np.array(t_read)


def bench(configs: dict, rows, actions, batch: int, repeats: int) -> dict:
    """Time every config on the same inputs, interleaved (repeat r runs all configs in turn),
    so machine noise falls on all of them alike."""
    n = len(rows)
    idx = (np.arange(n)[:, None] + 17 * np.arange(batch)[None]) % n  # (steps, B)
    states = [PhysState.unpack(rows[i]) for i in idx]
    acts = [np.ascontiguousarray(actions[i]) for i in idx]
    correctors = {name: (Corrector(cfg, batch) if cfg is not None else None) for name, cfg in configs.items()}
    twins = {name: (Corrector(cfg, batch, profile=True) if cfg is not None else None) for name, cfg in configs.items()}
    res = {name: {"total": [], "a": [], "b": []} for name in configs}
    for _ in range(repeats + 1):  # the first round warms up (numba compiles on first use)
        for name, c in correctors.items():
            call = c if c is not None else (lambda a, s: a.copy())  # the no-op corrector
            twin = twins[name]
            if c is not None:
                c.reset()
                twin.reset()
            r = res[name]
            for s, a in zip(states, acts):
                t0 = time.perf_counter()
                call(a, s)
                r["total"].append(time.perf_counter() - t0)
                if twin is not None:
                    twin(a, s)
                r["a"].append(twin.last.t_branch_a_s if twin else 0.0)
                r["b"].append(twin.last.t_branch_b_s if twin else 0.0)
    out = {}
    for name, r in res.items():
        c = correctors[name]
        out[name] = {k: np.asarray(v[n:]) * 1e6 / batch for k, v in r.items()}  # drop warm-up; us / env-step
        out[name]["passthrough"] = dict(c.passthrough_counts) if c else {}
    return out


def _obs(rows: np.ndarray, extra: np.ndarray) -> dict:
    """The env observation as lerobot's preprocess_observation hands it to the env preprocessor."""
    return {ROBOT_STATE: {STATE_KEY: torch.from_numpy(rows), EXTRA_KEY: torch.from_numpy(extra)}}


def _noop_capture(tr: dict) -> np.ndarray:
    return tr[TransitionKey.OBSERVATION][ROBOT_STATE][STATE_KEY].numpy()


def _noop_step(tr: dict) -> torch.Tensor:
    a = tr[TransitionKey.ACTION]
    return torch.from_numpy(a.numpy().astype(np.float64).astype(np.float32))


# the path as it was before the recorder's row was written inside the compiled tick: the same step and
# recorder, the row copied array by array in Python after the call (what any second listener causes)
COPIED = "B=1, row copied in Python"


def _no_listener(*args) -> None:
    return None


def whole_path(episodes: int, steps: int, warm_repeats: int = 3) -> dict:
    """Whole-path timings per env-step, live in the env loop (see the module doc). Right after
    each env step one path runs first (cold), in turn: B = 1, B = 8, the no-op, B = 1 with the row
    copied in Python; then every path
    runs warm_repeats times back to back."""
    task = libero_sim.load_task("libero_spatial", 0)
    env = libero_sim.make_libero_env(task)
    cfg = PhysVLAConfig.paper(mode="phys_el").to_dict()
    steps_of = {}
    for path in ("B=1", "B=8", COPIED):
        bus = f"bench-{path}"
        cap, cor = PhysVLAStateCaptureStep(bus=bus), PhysVLACorrectorStep(config=cfg, bus=bus)
        cor.listeners.append(EpisodeRecorder())  # diagnostics included, as in lerobot-eval
        if path == COPIED:  # a second listener: the step copies the recorder's row in Python after the call
            cor.listeners.append(_no_listener)
        steps_of[path] = (cap, cor)
    paths = ("B=1", "B=8", "no-op B=1", COPIED)
    res = {(kind, p): {"read": [], "capture": [], "step": []} for kind in ("live", "warm") for p in paths}
    expert = PickPlaceExpert()
    clock = time.perf_counter

    def run(path: str, src, extra) -> np.ndarray:
        b = 8 if path == "B=8" else 1
        t0 = clock()
        rows = [src.read_packed() for _ in range(b)]
        t1 = clock()
        if path.startswith("no-op"):  # without the corrector nothing reads the physical state
            t1 = t0
        tr = {TransitionKey.OBSERVATION: _obs(np.stack(rows), np.repeat(extra, b, 0))}  # lerobot's own work
        raw = expert.act(rows[0][3:6], rows[0][7:10], rows[0][11:14])
        act = torch.from_numpy(np.repeat(raw[None], b, 0).astype(np.float32))
        if path.startswith("no-op"):
            t2 = clock()
            _noop_capture(tr)
            t3 = clock()
            out = _noop_step({TransitionKey.ACTION: act})
            t4 = clock()
        else:
            cap, cor = steps_of[path]
            t2 = clock()
            cap(tr)
            t3 = clock()
            out = cor({TransitionKey.ACTION: act})[TransitionKey.ACTION]
            t4 = clock()
        return out[0].numpy().astype(np.float64), ((t1 - t0) / b, (t3 - t2) / b, (t4 - t3) / b)

    k = 0
    for ep in range(episodes):
        for _, cor in steps_of.values():  # as lerobot-eval's hook before each rollout: compact outside the ticks
            cor.listeners[0].end_batch()
        libero_sim.reset_to_init_state(env, task, ep)
        src = RobosuiteStateSource(env.env)
        src.reset()
        extra = np.zeros((1, 9))
        for _ in range(steps):
            first = paths[k % len(paths)]
            k += 1
            order = [first] + [p for p in paths if p != first]
            a_exec = None
            for rep in range(1 + warm_repeats):
                for path in order:
                    if rep == 0 and path != first:
                        continue
                    a, times = run(path, src, extra)
                    if path == "B=1" or a_exec is None:
                        a_exec = a
                    r = res[("live" if rep == 0 else "warm", path)]
                    for key, t in zip(("read", "capture", "step"), times):
                        r[key].append(t)
            env.step(a_exec)
            src.step()
            extra[0, 2:] = a_exec
    env.close()
    out = {}
    for (kind, path), r in res.items():
        r = {key: np.asarray(v) * 1e6 for key, v in r.items()}
        out[f"{kind} {path}"] = {"total": r["read"] + r["capture"] + r["step"], **r}
    return out


_FIRST_CALL = r"""
import json, time, numpy as np, torch
t_start = time.perf_counter()
from lerobot.lerobot_types import TransitionKey
from lerobot_physvla.sim import libero_sim
from lerobot_physvla.sources.robosuite import RobosuiteStateSource
from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.diagnostics import EpisodeRecorder
from lerobot_physvla.processor.physvla_processor import PhysVLAStateCaptureStep, PhysVLACorrectorStep
import overhead as bo
task = libero_sim.load_task("libero_spatial", 0)
env = libero_sim.make_libero_env(task)
libero_sim.reset_to_init_state(env, task, 0)
t0 = time.perf_counter()
src = RobosuiteStateSource(env.env); src.reset()
cap, cor = PhysVLAStateCaptureStep(bus="first"), PhysVLACorrectorStep(config=PhysVLAConfig.paper(mode="phys_el").to_dict(), bus="first")
cor.listeners.append(EpisodeRecorder())
t_build = time.perf_counter() - t0
act = torch.zeros(1, 7)
c = time.perf_counter
t0 = c(); row = src.read_packed(); t1 = c()
tr = {TransitionKey.OBSERVATION: bo._obs(row[None], np.zeros((1, 9)))}
t2 = c(); cap(tr); t3 = c(); cor({TransitionKey.ACTION: act}); t4 = c()
bo._noop_capture(tr); bo._noop_step({TransitionKey.ACTION: act}); t5 = c()
print(json.dumps({"first_call_us": (t1 - t0 + t4 - t2) * 1e6, "read_us": (t1 - t0) * 1e6, "capture_us": (t3 - t2) * 1e6,
                  "step_us": (t4 - t3) * 1e6, "noop_first_call_us": (t5 - t4) * 1e6, "build_s": t_build}))
"""


def first_call() -> dict:
    """The first whole-path call of a fresh process (after building env, source and steps)."""
    r = subprocess.run([sys.executable, "-c", _FIRST_CALL], capture_output=True, text=True,
                       cwd=Path(__file__).resolve().parent, env={**os.environ, "PYTHONWARNINGS": "ignore"})
    if r.returncode != 0:
        raise RuntimeError(r.stderr[-2000:])
    return json.loads(r.stdout.strip().splitlines()[-1])


_IN_EVAL = r"""
import json, sys, time, warnings
warnings.simplefilter("ignore")
policy, batch, episodes, out_dir, flags = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], sys.argv[5:]
from lerobot_physvla.envs.libero_physvla import PhysVLAStateExport
from lerobot_physvla.sources.robosuite import RobosuiteStateSource
from lerobot_physvla.processor.physvla_processor import PhysVLAStateCaptureStep, PhysVLACorrectorStep
clock = time.perf_counter
events = []  # (what, seconds) in call order
def timed(cls, name, what):
    orig = getattr(cls, name)
    def call(self, *args, **kwargs):
        t0 = clock(); r = orig(self, *args, **kwargs); events.append((what, clock() - t0)); return r
    setattr(cls, name, call)
if "--bench-floor" in flags:  # the floor: the same three places, each doing the least it could
    flags = [f for f in flags if f != "--bench-floor"]
    import numpy as np, torch
    from numba import njit
    from lerobot.processor import TransitionKey
    @njit(cache=False)
    def _trivial(a):  # one compiled call that reads one float of one array
        return a.ravel()[0]
    real_read = RobosuiteStateSource.read_packed
    def floor_read(self):  # the packed row of the build-time read, handed back through one compiled call
        row = getattr(self, "_floor_row", None)
        if row is None:
            row = self._floor_row = real_read(self)
        _trivial(row)
        return row
    RobosuiteStateSource.read_packed = floor_read
    def floor_step(self, transition):  # the action to numpy, one compiled call, back to a float32 tensor
        a = transition[TransitionKey.ACTION].numpy()
        _trivial(a)
        new = dict(transition)
        new[TransitionKey.ACTION] = torch.from_numpy(a.astype(np.float32))
        return new
    PhysVLACorrectorStep.__call__ = floor_step
    _trivial(np.zeros((1, 7), np.float32))  # compiled for the action here, for the row at the build-time read
read = RobosuiteStateSource.read_packed
def read_in_ticks(self):  # the read the source makes when it is built is no control tick's
    if not getattr(self, "_built", False):
        self._built = True
        return read(self)
    t0 = clock(); r = read(self); events.append(("read", clock() - t0)); return r
RobosuiteStateSource.read_packed = read_in_ticks
timed(PhysVLAStateCaptureStep, "__call__", "capture")
timed(PhysVLACorrectorStep, "__call__", "step")
timed(PhysVLAStateExport, "step", "env_step")
from lerobot_physvla.scripts.lerobot_physvla_eval import activate_eval
argv = ["lerobot-eval", f"--policy.path={policy}", "--env.type=libero_physvla", "--env.cameras=false",
        "--env.task=libero_spatial", "--env.task_ids=[0]", f"--eval.n_episodes={episodes}", f"--eval.batch_size={batch}",
        "--eval.use_async_envs=false", "--env.episode_length=200", "--policy.postprocess=physvla",
        f"--output_dir={out_dir}", *flags]
activate_eval(argv)
sys.argv = argv
from lerobot.scripts import lerobot_eval
from lerobot.utils.import_utils import register_third_party_plugins
register_third_party_plugins()
lerobot_eval.eval_main()
print("EVENTS" + json.dumps(events))
"""


FLOOR = "floor (no correction)"


def in_eval(batch: int, episodes: int, policy: Path, out: Path, flags: tuple = ()) -> dict:
    """The whole path inside lerobot-eval's own loop (a fresh process running its eval_main with
    --policy.postprocess=physvla, phys_el, the scripted policy checkpoint, a sync vector env): the
    state reads, the capture step and the corrector step (its EpisodeRecorder included), each
    timed by a wrapper around it, grouped per policy call. Per env-step: (reads + capture + step) / B."""
    r = subprocess.run([sys.executable, "-c", _IN_EVAL, str(policy), str(batch), str(episodes), str(out), *flags],
                       capture_output=True, text=True, cwd=Path(__file__).resolve().parent,
                       env={**os.environ, "PYTHONWARNINGS": "ignore"})
    line = [x for x in r.stdout.splitlines() if x.startswith("EVENTS")]
    if r.returncode != 0 or not line:
        raise RuntimeError(r.stderr[-3000:])
    groups, reads, env_steps, capture = [], [], [], None
    for what, sec in json.loads(line[-1][len("EVENTS"):]):
        us = sec * 1e6
        if what == "read":
            reads.append(us)
        elif what == "env_step":
            env_steps.append(us)
        elif what == "capture":
            capture = us
        elif what == "step" and capture is not None:  # one policy call: the reads since the last one
            groups.append({"read": sum(reads) / batch, "capture": capture / batch, "step": us / batch,
                           "reads": len(reads)})
            reads, capture = [], None
    tot = np.array([g["read"] + g["capture"] + g["step"] for g in groups])
    later = tot[1:]
    return {"batch": batch, "calls": len(groups), "first_us": float(tot[0]), "p50_us": float(np.median(later)),
            "p99_us": float(np.percentile(later, 99)), "max_us": float(later.max()),
            **{f"p50_{k}_us": float(np.median([g[k] for g in groups[1:]])) for k in ("read", "capture", "step")},
            **{f"p99_{k}_us": float(np.percentile([g[k] for g in groups[1:]], 99)) for k in ("read", "capture", "step")},
            "env_step_us_p50": float(np.median(env_steps)) / 1.0}


@njit(cache=False)
def _trivial(a):  # the least a compiled call can do: read one float of one array
    return a[0]


@njit(cache=False)
def _trivial8(a0, a1, a2, a3, a4, a5, a6, a7):  # the same with 8 array arguments
    return a0[0]


@njit(cache=False)
def _trivial21(a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, a12, a13, a14, a15, a16, a17, a18, a19, a20):
    return a0[0]  # 21 array arguments, as the tick and the read had before they took arenas


def cold_floor(rows: np.ndarray, actions: np.ndarray, repeats: int = 300) -> dict:
    """p50 per call, warm (back to back) and cold (after a 64 MB sweep through the caches, as a
    control tick finds them after the physics step and the policy's forward pass), of the pieces
    the whole path is made of: a trivial compiled call (with 1, 8 and 21 array arguments), a torch
    tensor's .numpy(), the action's way back (float32 cast + torch.from_numpy), and the corrector's
    compiled tick (shipped default, B = 1) as correct_packed and as the LeRobot step's correct_stream."""
    c = Corrector(PRESETS[DEFAULT_PRESET], 1)
    flat, a = np.ascontiguousarray(rows[:1]), np.ascontiguousarray(actions[:1], dtype=np.float64)
    t = torch.from_numpy(a.astype(np.float32))
    junk = np.ones(8_000_000)
    arrays = [np.zeros((2, 3)) for _ in range(21)]
    a32 = a.astype(np.float32)
    none = np.zeros((0, 0, 0))  # no recording arena
    direct = direct_entry(stream_tick, a32, flat, c._fws, c._iws, c._bws, none, 0)
    pieces = {"trivial compiled call": lambda: _trivial(a),
              "trivial compiled call, 8 array arguments": lambda: _trivial8(a, *arrays[:7]),
              "trivial compiled call, 21 array arguments": lambda: _trivial21(a, *arrays[:20]),
              "torch tensor .numpy()": lambda: t.numpy(),
              "float32 cast + torch.from_numpy": lambda: torch.from_numpy(a.astype(np.float32)),
              "corrector tick (correct_packed)": lambda: c.correct_packed(a, flat),
              "corrector stream tick (correct_stream, float32 in and out)": lambda: c.correct_stream(a32, flat),
              "stream_tick through numba's dispatch": lambda: stream_tick(a32, flat, c._fws, c._iws, c._bws, none, 0),
              "stream_tick's compiled overload called directly (what correct_stream calls)":
                  lambda: direct(a32, flat, c._fws, c._iws, c._bws, none, 0)}
    out = {}
    for name, fn in pieces.items():
        fn()
        res = {}
        for cold in (False, True):
            ts = []
            for _ in range(repeats):
                if cold:
                    junk.sum()
                t0 = time.perf_counter()
                fn()
                ts.append(time.perf_counter() - t0)
            res["cold" if cold else "warm"] = float(np.median(ts)) * 1e6
        out[name] = res
    return out


def _rss_bytes() -> int:
    return int(Path("/proc/self/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def memory(rows: np.ndarray, actions: np.ndarray, steps: int = 100_000) -> dict:
    """RSS growth of the corrector step (B = 1) between step steps/10 and step steps."""
    out = {}
    for name, listen in (("step", False), ("step + recorder", True)):
        cap = PhysVLAStateCaptureStep(bus="mem")
        cor = PhysVLACorrectorStep(config=PhysVLAConfig.paper(mode="phys_el").to_dict(), bus="mem")
        if listen:
            cor.listeners.append(EpisodeRecorder())
        obs = [_obs(r[None].copy(), np.zeros((1, 9))) for r in rows]
        acts = [torch.from_numpy(a[None].astype(np.float32)) for a in actions]
        gc.collect()
        mark = None
        for k in range(steps):
            if k == steps // 10:
                gc.collect()
                mark = _rss_bytes()
            i = k % len(rows)
            cap({TransitionKey.OBSERVATION: obs[i]})
            cor({TransitionKey.ACTION: acts[i]})
        gc.collect()
        grown = _rss_bytes() - mark
        out[name] = {"rss_growth_bytes": grown, "bytes_per_step": grown / (steps - steps // 10)}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--episodes", type=int, default=2, help="live episodes of the whole-path rows")
    ap.add_argument("--memory-steps", type=int, default=100_000)
    ap.add_argument("--eval-episodes", type=int, default=4, help="lerobot-eval episodes per env (in-eval rows)")
    ap.add_argument("--eval-repeats", type=int, default=3, help="runs of each in-eval row, interleaved")
    ap.add_argument("--out", default="eval/results/bench_overhead")
    args = ap.parse_args()

    print(f"recording {args.steps} steps of LIBERO-Spatial task 0 (state-only) ...", flush=True)
    rows, actions, t_step, t_read = record(args.steps)
    step_us = np.median(t_step) * 1e6
    read_us = np.median(t_read) * 1e6
    lines = [
        "# Corrector overhead\n",
        f"Command: `{' '.join(['.venv/bin/python', *sys.argv])}`  ",
        f"Machine: {platform.processor() or platform.machine()}, {platform.python_version()}, "
        f"{len(os.sched_getaffinity(0))} cores; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}  ",
        f"Kernel inputs: {args.steps} recorded steps x {args.repeats} repeats per row; times are per env-step "
        "(call time / B).\n",
        f"LIBERO env step (no cameras): p50 {step_us:.0f} us; state read (RobosuiteStateSource.read_packed, one "
        f"compiled copy from the live MjData): p50 {read_us:.1f} us.\n",
        "## The corrector alone\n",
        "Total: the default call (one compiled tick). Branch A / Branch B: a profiling twin (stages called one by one).\n",
        "| config | B | p50 total (us) | p99 total (us) | p50 Branch A (us) | p50 Branch B + blend (us) | total / no-op | total / env step |",
        "|---|---|---|---|---|---|---|---|",
    ]
    results = {"env_step_us_p50": step_us, "state_read_us_p50": read_us, "rows": []}
    for batch in (1, 8):
        noop = None
        timings = bench(CONFIGS, rows, actions, batch, args.repeats)
        for name in CONFIGS:
            r = timings[name]
            p50, p99 = np.percentile(r["total"], [50, 99])
            noop = p50 if noop is None else noop
            row = {
                "config": name, "batch": batch, "p50_us": p50, "p99_us": p99, "p50_a_us": float(np.median(r["a"])),
                "p50_b_us": float(np.median(r["b"])), "ratio_noop": p50 / noop, "ratio_env_step": p50 / step_us,
                "passthrough": r["passthrough"],
            }
            results["rows"].append(row)
            line = (f"| {name} | {batch} | {p50:.1f} | {p99:.1f} | {row['p50_a_us']:.1f} | {row['p50_b_us']:.1f} | "
                    f"{row['ratio_noop']:.2f} | {row['ratio_env_step']:.4f} |")
            lines.append(line)
            print(line, flush=True)

    print(f"whole path, live in {args.episodes} episodes of {args.steps} steps ...", flush=True)
    wp = whole_path(args.episodes, args.steps)
    lines += [
        "\n## The whole path per env-step (phys_el, diagnostics included)\n",
        "State read + capture step + corrector step with lerobot-eval's EpisodeRecorder, on torch tensors as lerobot "
        "hands them over. *live*: right after each real env step (caches cold, as in a rollout); *warm*: three more "
        "times back to back on the same inputs. B = 8: eight reads + (capture + step) / 8 per env. No-op: the same "
        "tensor conversions (state tensor to numpy, action tensor to numpy and back), no state read, no correction. "
        f"*{COPIED}*: B = 1 with the recorder's row copied array by array in Python after the corrector's call (as "
        "before the compiled tick wrote it; what any second listener on the step still causes). Right after each env "
        "step one path runs first, in turn (B = 1, B = 8, no-op, row copied): each live row holds a quarter of the "
        "steps. p99 excludes each run's first call (next section).\n",
        "| path | p50 total (us) | p99 total (us) | p50 read (us) | p50 capture (us) | p50 corrector step (us) | "
        "total / no-op | total / env step |",
        "|---|---|---|---|---|---|---|---|",
    ]
    results["whole_path"] = {}
    for name, r in wp.items():
        tot = r["total"][1:]
        p50, p99 = np.percentile(tot, [50, 99])
        noop = float(np.median(wp[f"{name.split()[0]} no-op B=1"]["total"][1:]))
        row = {"p50_us": p50, "p99_us": p99, "samples": len(tot),
               **{f"p50_{k}_us": float(np.median(r[k][1:])) for k in ("read", "capture", "step")},
               "ratio_noop": p50 / noop, "ratio_env_step": p50 / step_us}
        results["whole_path"][name] = row
        line = (f"| {name} | {p50:.1f} | {p99:.1f} | {row['p50_read_us']:.1f} | {row['p50_capture_us']:.1f} | "
                f"{row['p50_step_us']:.1f} | {row['ratio_noop']:.1f} | {row['ratio_env_step']:.4f} |")
        lines.append(line)
        print(line, flush=True)

    print("whole path inside lerobot-eval (B = 1, 8) ...", flush=True)
    tmp = Path(tempfile.mkdtemp(prefix="physvla_bench_"))
    policy = tmp / "scripted"
    subprocess.run([sys.executable, str(ROOT / "backbones/make_scripted_policy.py"), str(policy)], check=True,
                   capture_output=True)
    runs = (("phys_el", 1, ("--physvla.mode=phys_el",)), ("phys_el", 8, ("--physvla.mode=phys_el",)),
            ("shipped default", 1, ()), ("smooth preset", 1, ("--physvla.preset=smooth",)),
            (FLOOR, 1, ("--bench-floor",)), (FLOOR, 8, ("--bench-floor",)))
    tries: dict[str, list[dict]] = {f"{name} B={b}": [] for name, b, _ in runs}
    for rep in range(args.eval_repeats):  # interleaved: this VM's speed drifts over minutes
        for k, (name, b, flags) in enumerate(runs):
            tries[f"{name} B={b}"].append(in_eval(b, b * args.eval_episodes, policy, tmp / f"eval{rep}_{k}", flags))
    ev = {}
    for key, rs in tries.items():  # the run with the median p50, and the spread of p50 over the runs
        rs = sorted(rs, key=lambda r: r["p50_us"])
        ev[key] = {**rs[len(rs) // 2], "p50_us_runs": [r["p50_us"] for r in rs]}
    shutil.rmtree(tmp, ignore_errors=True)
    results["in_eval"] = ev
    lines += [
        "\n## The whole path inside lerobot-eval (diagnostics included)\n",
        "`lerobot-eval --policy.postprocess=physvla [--physvla.mode=phys_el]` itself (its `eval_main`, in a fresh "
        "process; the scripted policy checkpoint; LIBERO-Spatial task 0, state-only, 200-step episodes; a sync vector "
        "env so that every read runs in this process): the state reads (inside the env's step), the capture step "
        "(env preprocessor) and the corrector step with its EpisodeRecorder (policy postprocessor), each timed by a "
        "wrapper around it where lerobot calls it, between lerobot's own work (the physics step, the policy, "
        "lerobot's tensor conversions). Per env-step: (the B reads + capture + step) / B, per policy call; p50 / "
        f"p99 / max over the calls after the first. Episodes: {args.eval_episodes} at B = 1, "
        f"{8 * args.eval_episodes} at B = 8; each row ran {args.eval_repeats} times, interleaved with the others, "
        "and shows the run with the median p50 (the p50 of every run in the last column). The max is the first tick of a rollout batch, right after lerobot-eval "
        "reset the envs: the recorder then reduces the finished batch's episodes to their records (docs/lerobot_eval.md). "
        f"*{FLOOR}*: the same three places doing the least they could: the read hands back the build-time packed "
        "row through one trivial compiled call, the capture step is the shipped one (it only takes the state out of "
        "the observation), and the corrector step converts the action to numpy, makes one trivial compiled call and "
        "returns a float32 tensor: what any corrector built this way pays at these places, before it corrects.\n",
        "| corrector | B | calls | p50 total (us) | p99 total (us) | max (us) | first call (us) | p50 read (us) | p50 capture (us) | "
        "p50 corrector step (us) | p99 corrector step (us) | total / env step | p50 of each run (us) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for key, r in ev.items():
        name, b = key.rsplit(" B=", 1)
        lines.append(f"| {name} | {b} | {r['calls']} | {r['p50_us']:.1f} | {r['p99_us']:.1f} | {r['max_us']:.0f} | "
                     f"{r['first_us']:.0f} | {r['p50_read_us']:.1f} | {r['p50_capture_us']:.1f} | "
                     f"{r['p50_step_us']:.1f} | {r['p99_step_us']:.1f} | {r['p50_us'] / r['env_step_us_p50']:.4f} | "
                     f"{', '.join(f'{x:.0f}' for x in r['p50_us_runs'])} |")
        print(lines[-1], flush=True)

    fc = first_call()
    results["first_call"] = fc
    lines += [
        "\n## First call of a fresh process (B = 1)\n",
        f"Building the env's state source and the two steps (numba kernels loaded and run once, at build time): "
        f"{fc['build_s'] * 1e3:.0f} ms. The first control tick then costs: whole path {fc['first_call_us']:.0f} us "
        f"(read {fc['read_us']:.0f}, capture {fc['capture_us']:.0f}, corrector step {fc['step_us']:.0f}); "
        f"the first no-op call {fc['noop_first_call_us']:.0f} us.\n",
    ]
    print(lines[-1].strip(), flush=True)

    floor = cold_floor(rows, actions)
    results["cold_floor"] = floor
    lines += ["\n## The cold-cache floor (why the in-lerobot-eval rows cost more than the warm ones)\n",
              "p50 per call, warm (back to back) and cold (after a 64 MB sweep through the caches, as a control tick "
              "finds them after the physics step and the policy's forward pass). A cold compiled call costs more the "
              "more array arguments it unboxes, so the state read (`pack_live_buf`: the row, one view of the MjData "
              "buffer, an int arena, the header constants) and the LeRobot step's tick (`correct_stream`: the action, "
              "the state, three arenas) each take all they need in "
              "one call with few arguments, and both call the compiled code directly, without numba's per-call type "
              "dispatch (the last two rows; core/direct_call.py); what remains is the tensor conversions at the "
              "step's two ends and lerobot's own Python around them (docs/method.md \"Speed\").\n",
              "| piece | warm p50 (us) | cold p50 (us) | cold / warm |", "|---|---|---|---|"]
    for name, r in floor.items():
        lines.append(f"| {name} | {r['warm']:.1f} | {r['cold']:.1f} | {r['cold'] / r['warm']:.1f} |")
    print("\n".join(lines[-len(floor) - 2:]), flush=True)

    mem = memory(rows, actions, args.memory_steps)
    results["memory"] = mem
    lines += [f"\n## Memory over {args.memory_steps} steps (B = 1)\n",
              "| path | RSS growth from step 10^4 to the end (KiB) | bytes / step |", "|---|---|---|"]
    for name, m in mem.items():
        lines.append(f"| {name} | {m['rss_growth_bytes'] / 1024:.0f} | {m['bytes_per_step']:.1f} |")
        print(lines[-1], flush=True)
    lines.append("\nThe step allocates nothing that outlives a call. The recorder keeps per-step rows for the "
                 "running rollout batch only: when every env restarts (here: each time the recorded episode wraps "
                 "around) the finished episodes are reduced to their records and the rows are reused.")

    live = results["in_eval"]["phys_el B=1"]
    last = (f"whole path p50 {live['p50_us']:.1f} us, p99 {live['p99_us']:.1f} us, first call "
            f"{live['first_us']:.0f} us (B=1)")
    lines.append("\nThe last line is the phys_el B = 1 row of the whole path inside lerobot-eval.")
    lines.append(f"\n{last}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "README.md").write_text("\n".join(lines) + "\n")
    (out / "results.json").write_text(json.dumps(results, indent=1, default=float))
    print(f"\nwrote {out}/README.md and results.json")
    print(last)


if __name__ == "__main__":
    main()
