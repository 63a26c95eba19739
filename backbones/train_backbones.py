"""Training recipes for the learned backbones: LeRobot ACT and Diffusion on the expert dataset.

    .venv/bin/python backbones/record_dataset.py                 # once: the dataset
    .venv/bin/python backbones/train_backbones.py act_chunk      # one recipe (or: all)
    .venv/bin/python backbones/train_backbones.py --list         # each recipe's lerobot-train command
    python3 backbones/train_backbones.py all --device cuda --num-workers 3 --parallel 3   # on a GPU

Each recipe is one `lerobot-train` command (printed before it runs, and saved beside the
checkpoint as recipe.json with the device it ran on and how long it took) on the local dataset,
state inputs only (observation.state + observation.environment_state), fixed seed, no hub, no
wandb, no env (so no evaluation during training). `--device` and `--num-workers` say where a
recipe runs, not what it learns: the recipe (policy, sizes, steps, seed, data) is the same on the
CPU and on a GPU. On the CPU a run is deterministic and the loader workers do not change its
weights (tested); a GPU follows other numerics, so its run of a recipe is another draw: act_single
trained on the H100 succeeds 68 % on init states 5-9, trained here 46 %
(eval/results/learned_checkpoints). On this CPU a recipe trains in 29-42 min with the default one
loader worker (eval/results/bench_training), one recipe at a time. The checkpoints land in
outputs/train/<recipe>/checkpoints/<step>/pretrained_model (every fifth of the steps; `last` is
the final one), which eval/run.py learned uses (or
`lerobot-eval --policy.path=... --env.type=libero_physvla --env.cameras=false`).

    act_single        ACT, chunk 1 (a single-step policy)
    act_chunk         ACT, chunk 20, executes 10 before re-planning
    diffusion_single  Diffusion (DDIM, 10 denoising steps), re-plans every step
    diffusion_chunk   Diffusion, executes 8 of its 16-step horizon before re-planning

Weak siblings (`SIBLINGS`) are earlier checkpoints of the same runs: the same recipe stopped
early, so the corrector is judged on a weak and a strong policy of one family. Those landed below
the 30-50 % band #9 asks for; the `_mid` siblings (`CONTINUED`, `CPU_DRAW`, `MID_CHOICE`) are in it:

    .venv/bin/python backbones/train_backbones.py act_chunk_mid      # continues act_chunk_weak here
    .venv/bin/python backbones/train_backbones.py act_single_mid     # continues act_single_weak here
    .venv/bin/python backbones/train_backbones.py act_single --out outputs/train/cpu_full
    .venv/bin/python backbones/train_backbones.py act_chunk --out outputs/train/cpu_full   # act_chunk_mid2
    .venv/bin/python backbones/train_backbones.py act_chunk_fine   # resumes that run from 7200 (RESUMED)
    .venv/bin/python backbones/train_backbones.py act_chunk_small --out outputs/train/cpu_full  # SMALLER
    .venv/bin/python backbones/train_backbones.py act_chunk_tiny --out outputs/train/cpu_full
    .venv/bin/python backbones/train_backbones.py act_chunk_w96 --out outputs/train/cpu_full   # fifth round
    .venv/bin/python backbones/train_backbones.py act_chunk_w112 --out outputs/train/cpu_full
    .venv/bin/python backbones/train_backbones.py act_chunk_w112_fine   # seventh round: resumes it from 4800
    .venv/bin/python backbones/train_backbones.py act_chunk_few5 --out outputs/train/cpu_full   # eighth: FEWER
    .venv/bin/python backbones/train_backbones.py act_chunk_few10 --out outputs/train/cpu_full
    .venv/bin/python eval/run.py learned_mid

Normalisation: lerobot 0.6.1's ACT and Diffusion configs normalise only the VISUAL, STATE and
ACTION feature types; `observation.environment_state` (type ENV: object and target xyz, metres)
falls through to IDENTITY and reaches the network raw, where the object's position across init
states spans a few centimetres of a ~1 m value. Every recipe names ENV in
`--policy.normalization_mapping` (tests/policies/test_train_backbones.py checks that the saved
preprocessor normalises it).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

DATASET = "outputs/datasets/physvla_libero_spatial"
SEED = 1000
CHECKPOINTS_PER_RUN = 5  # a checkpoint every fifth of the steps: the weak siblings come from them

_COMMON = ["--policy.push_to_hub=false", "--wandb.enable=false", "--log_freq=200", f"--seed={SEED}"]
_ACT = ["--policy.type=act", "--policy.dim_model=128", "--policy.n_heads=4", "--policy.dim_feedforward=512",
        "--policy.n_encoder_layers=2", "--policy.n_decoder_layers=1", "--policy.latent_dim=16",
        "--policy.optimizer_lr=3e-4", "--batch_size=32",
        '--policy.normalization_mapping={"VISUAL": "MEAN_STD", "STATE": "MEAN_STD", "ENV": "MEAN_STD", '
        '"ACTION": "MEAN_STD"}']
_DIFFUSION = ["--policy.type=diffusion", "--policy.n_obs_steps=2", "--policy.horizon=16",
              "--policy.down_dims=[64,128,256]", "--policy.diffusion_step_embed_dim=64",
              "--policy.noise_scheduler_type=DDIM", "--policy.num_inference_steps=10", "--policy.optimizer_lr=3e-4",
              "--batch_size=32",
              '--policy.normalization_mapping={"VISUAL": "MEAN_STD", "STATE": "MIN_MAX", "ENV": "MIN_MAX", '
              '"ACTION": "MIN_MAX"}']

# name -> (lerobot-train arguments, steps). Steps are sized to train within about an hour on this
# 2-core CPU, two recipes side by side (recipe.json records the time each run took).
RECIPES: dict[str, tuple[list[str], int]] = {
    "act_single": (_ACT + ["--policy.chunk_size=1", "--policy.n_action_steps=1", "--policy.use_vae=false"], 20000),
    "act_chunk": (_ACT + ["--policy.chunk_size=20", "--policy.n_action_steps=10"], 12000),
    "diffusion_single": (_DIFFUSION + ["--policy.n_action_steps=1"], 10000),
    "diffusion_chunk": (_DIFFUSION + ["--policy.n_action_steps=8"], 10000),
}

# weak sibling -> (recipe, training step of the earlier checkpoint it is): the first checkpoint of
# each run (a fifth of its steps), fixed before any of them was evaluated. Diffusion's first
# checkpoint (step 2000) succeeded 0 / 50 and is no sibling: no corrector can be judged on it.
SIBLINGS: dict[str, tuple[str, int]] = {
    "act_single_weak": ("act_single", 4000),
    "act_chunk_weak": ("act_chunk", 2400),
}


# Weak siblings in the 30-50 % band (#9). The GPU runs' first checkpoints landed below it (act_single
# @4000: 28 %, act_chunk @2400: 22 % on init states 0-4) and their later intermediate checkpoints
# were not kept. The candidates for each `_mid` sibling, fixed before any of them was evaluated:
# - CONTINUED: the committed first checkpoint trained further on this CPU, `lerobot-train
#   --policy.path=<checkpoint>` (its weights, config and normalisation, a fresh AdamW at the recipe's
#   constant learning rate, batch 32, seed 1000) for `steps` more steps, saving every `every`;
# - CPU_DRAW: the recipe run whole on this CPU (`train_backbones.py <recipe> --out
#   outputs/train/cpu_full`): the same recipe, data and seed, another draw (the GPU's numerics are
#   not this CPU's; eval/results/learned_checkpoints), its final checkpoint.
# The one kept is the candidate whose uncorrected success on init states 5-9 (the study
# eval/studies/learned_mid.toml) lies closest to 40 %, ties to the earlier; the learned table reports it on 0-4.
# name -> (committed checkpoint it continues, steps, save every)
CONTINUED: dict[str, tuple[str, int, int]] = {
    "act_single_mid": ("act_single_weak", 4000, 1000),
    "act_chunk_mid": ("act_chunk_weak", 3600, 1200),
}
# Second round for the chunked sibling: act_chunk_mid (step 1200 of its continued run, 42 % on init
# states 5-9) landed at 16 % on 0-4, below the band. Its candidates, fixed before any ran: every
# checkpoint of act_chunk run whole on this CPU (2400 .. 12000); the same rule keeps one.
# name -> (recipe run whole on this CPU, the steps of that run that are candidates)
CPU_DRAW: dict[str, tuple[str, tuple[int, ...]]] = {
    "act_single_mid": ("act_single", (20000,)),
    "act_chunk_mid2": ("act_chunk", (2400, 4800, 7200, 9600, 12000)),
}
# Third round for act_chunk_mid2: the whole CPU run went from 8 % (step 7200) to 68 % (9600) on init
# states 5-9, and the rule tied 2400 (12 %) with 9600 (68 %) at 28 points from 40 % (ties to the
# earlier: 2400): no candidate in the band. Finer candidates inside that jump, fixed before any ran:
# the same run resumed from its 7200 checkpoint (`lerobot-train --resume`: its weights, optimizer,
# scheduler and data order) to 9600, saving every 400 steps; its 9600 is not a candidate (the whole
# run's is), only a check that resuming retraces the run. The same rule keeps one of all candidates.
# Seventh round (below the sixth): the 112-wide run resumed the same way.
# resumed run (its directory under <CPU_DRAW_DIR>) -> (the whole CPU run it resumes, from step, to step,
# save every); its candidates are the steps strictly between from and to
RESUMED: dict[str, tuple[str, int, int, int]] = {"act_chunk_fine": ("act_chunk", 7200, 9600, 400),
                                                 "act_chunk_w112_fine": ("act_chunk_w112", 4800, 7200, 400)}
RESUMED_OF: dict[str, tuple[str, ...]] = {"act_chunk_mid2": ("act_chunk_fine", "act_chunk_w112_fine")}
# Fourth round for act_chunk_mid2: the resumed run's checkpoints went 18, 2, 4, 4, 62 % (7600 .. 9200):
# at act_chunk's size the policy learns to let go of the bowl within ~400 updates, in most tasks at
# once, so no checkpoint of such a run sits in the band. A smaller model instead (#9 allows "an
# earlier checkpoint or a smaller model"): act_chunk's recipe (same data, seed, chunk, steps) with a
# narrower transformer, run whole on this CPU (`train_backbones.py <name> --out outputs/train/cpu_full`);
# every checkpoint is a candidate. Fixed before any of them was trained; the same rule keeps one of
# all candidates of every round.
# Fifth round: the two smaller models' checkpoints all landed at 0-22 % on init states 5-9 (none in the
# band): at dim_model 64 the chunked ACT stays weak throughout, at 128 it reaches 68-70 %. Between
# them, fixed before any trained: widths 96 and 112 (feedforward 4x, 4 heads), their final checkpoint
# only (a converged model of limited capacity, not a checkpoint caught inside the jump). The same rule
# keeps one of all candidates of every round. Sixth round, after 96 landed at 6 % and 112 at 68 %: the
# 112-wide run's earlier checkpoints (2400 .. 9600, saved by the same run) join the candidates.
# Seventh round, after those went 14, 0, 56, 66 % (the pick, 7200 at 56 %, outside the band): the
# 112-wide run resumed from its 4800 checkpoint (0 %) to 7200, saving every 400 steps (RESUMED
# act_chunk_w112_fine: candidates 5200 .. 6800, inside the jump from 0 to 56 %; its 7200 is not one).
# Fixed before it trained; the same rule keeps one of all candidates of every round.
# smaller recipe -> (the recipe it shrinks, the lerobot-train arguments that replace the recipe's,
# the steps of its run that are candidates)
SMALLER: dict[str, tuple[str, tuple[str, ...], tuple[int, ...]]] = {
    "act_chunk_small": ("act_chunk", ("--policy.dim_model=64", "--policy.dim_feedforward=256"),
                        (2400, 4800, 7200, 9600, 12000)),
    "act_chunk_tiny": ("act_chunk", ("--policy.dim_model=32", "--policy.n_heads=2", "--policy.dim_feedforward=128"),
                       (2400, 4800, 7200, 9600, 12000)),
    "act_chunk_w96": ("act_chunk", ("--policy.dim_model=96", "--policy.dim_feedforward=384"), (12000,)),
    "act_chunk_w112": ("act_chunk", ("--policy.dim_model=112", "--policy.dim_feedforward=448"),
                       (2400, 4800, 7200, 9600, 12000)),
}
SMALLER_OF: dict[str, tuple[str, ...]] = {"act_chunk_mid2": ("act_chunk_small", "act_chunk_tiny", "act_chunk_w96",
                                                             "act_chunk_w112")}
# Eighth round, after seven rounds of checkpoints and widths put no chunked candidate in the band (each
# either below 22 % or above 55 % on init states 5-9: the bowl's release switches on in most tasks
# at once): act_chunk's recipe (same model, seed, steps) on fewer demonstrations, lerobot-train
# `--dataset.episodes`: per task and DART noise level only its first k recorded episodes (the lowest
# init states that succeeded; the dataset's normalisation statistics stay the whole dataset's),
# k = 5 and 10 (81 and 161 of the 431 episodes: T4 and T6 have few). Every demonstration still ends
# in a release, so the skill is learned; what data lacks is coverage of the starts, which should
# lower success by the init states a policy cannot reach rather than by a skill it lacks. Every checkpoint of both
# runs is a candidate, fixed before either trained; the same rule keeps one of all candidates of
# every round. fewer-data run -> (the recipe it trains, episodes kept per task and noise level,
# the steps of its run that are candidates)
FEWER: dict[str, tuple[str, int, tuple[int, ...]]] = {
    "act_chunk_few5": ("act_chunk", 5, (2400, 4800, 7200, 9600, 12000)),
    "act_chunk_few10": ("act_chunk", 10, (2400, 4800, 7200, 9600, 12000)),
}
FEWER_OF: dict[str, tuple[str, ...]] = {"act_chunk_mid2": ("act_chunk_few5", "act_chunk_few10")}
MID_SIBLINGS = tuple(dict.fromkeys([*CONTINUED, *CPU_DRAW, *RESUMED_OF, *SMALLER_OF, *FEWER_OF]))  # every `_mid` sibling
CPU_DRAW_DIR = "cpu_full"  # where, under the training root, the whole CPU runs are
# name -> the kept candidate: (its run's directory under the training root, step), as
# eval/results/learned_mid chose it (a test recomputes the choice from that file's units). A sibling
# whose pick lies outside 30-50 % on init states 5-9 is no backbone and is not named here.
# act_chunk_mid2's pick over its eight rounds is act_chunk_few5@002400, 32 % [21, 46] (the eighth's
# candidates: few5 at 2400 .. 12000: 32, 16, 6, 66, 66 %; few10: 4, 16, 6, 64, 68 %); over seven
# rounds it had been act_chunk_w112@007200, 56 % [42, 69], outside the band.
MID_CHOICE: dict[str, tuple[str, int]] = {"act_single_mid": (f"{CPU_DRAW_DIR}/act_single", 20000),
                                          "act_chunk_mid": ("act_chunk_mid", 1200),
                                          "act_chunk_mid2": (f"{CPU_DRAW_DIR}/act_chunk_few5", 2400)}


# Per-suite ACTs (issue 41 item 3): the two ACT recipes unchanged, trained on one suite's demonstrations
# from the shape-planning expert (`record_dataset.py --suite S --seeds 20-39`: init states 20-39, DART
# 0.1 and 0.3, successful episodes only) into outputs/train/<suite>/<recipe>:
#     .venv/bin/python backbones/train_backbones.py act_single --suite libero_object
# LIBERO-Goal and LIBERO-10 (whose init states 5-19 earlier studies hold) record 20-34 instead and select on
# 35-39, act_chunk only so far (eval/studies/learned_goal_ten_select.toml). MetaWorld's ACTs (`mw_`) learn from
# its own scripted policies (`record_dataset.py --suite metaworld --tasks 0-5 --seeds 100-139`) and select on
# seeds 140-149 (eval/studies/learned_metaworld_select.toml), act_chunk only.
# Which checkpoints become backbones, written before any of them trained: every checkpoint of a run
# (steps 1/5 .. 5/5) runs uncorrected on the suite's selection block (LIBERO-Object init states 10-14,
# eval/studies/suites_learned_select.toml; Goal and 10 35-39), then (`choose_suite`)
#  - strong, `<short>_<recipe>`: the latest checkpoint whose success lies in STRONG_BAND; if none does,
#    the final one, reported as outside the band;
#  - weaker sibling, `<short>_<recipe>_weak`: of the other checkpoints, the one in WEAK_BAND closest to
#    WEAK_TARGET, ties to the earlier step; if none lies in the band the run has no weaker sibling
#    (reported, not searched further).
SUITE_SHORT = {"libero_object": "object", "libero_goal": "goal", "libero_10": "ten", "metaworld": "mw",
               "so101_env": "so101"}
SUITE_RECIPES = ("act_single", "act_chunk")
STRONG_BAND, WEAK_BAND, WEAK_TARGET = (0.60, 0.95), (0.20, 0.50), 0.35
# "<short>_<recipe>[_weak]" -> (its run's directory under the training root, step), as the selection
# study's units chose it (a test recomputes the choice from them)
SUITE_CHOICE: dict[str, tuple[str, int]] = {
    # LIBERO-Object (eval/results/suites_learned_select): act_single's checkpoints 0, 6, 6, 4, 0 % (none in either
    # band: its final one is kept, outside the band, and it has no weaker sibling); act_chunk's 38, 74, 30, 80, 58 %
    "object_act_single": ("libero_object/act_single", 20000),
    "object_act_chunk": ("libero_object/act_chunk", 9600),
    "object_act_chunk_weak": ("libero_object/act_chunk", 2400),
    # LIBERO-Goal (eval/results/learned_goal_ten_select, init states 35-39, n = 30): act_chunk's checkpoints 17, 30, 0,
    # 27, 10 % (none in the strong band: the final one is kept, outside the band)
    "goal_act_chunk": ("libero_goal/act_chunk", 12000),
    "goal_act_chunk_weak": ("libero_goal/act_chunk", 4800),
    # LIBERO-10 (the same study and block): act_chunk's 7, 33, 23, 27, 17 % (none in the strong band: the final one)
    "ten_act_chunk": ("libero_10/act_chunk", 12000),
    "ten_act_chunk_weak": ("libero_10/act_chunk", 4800),
    # MetaWorld (eval/results/learned_metaworld_select, seeds 140-149, n = 60): act_chunk's 30, 47, 52, 30, 70 % (the
    # final one in the strong band; of the two at 30 %, equally near 35 %, the earlier)
    "mw_act_chunk": ("metaworld/act_chunk", 12000),
    "mw_act_chunk_weak": ("metaworld/act_chunk", 2400),
    # act_single (the same block, seeds 140-149, n = 60; trained here): 58, 65, 53, 68, 75 % (the final one in the strong
    # band; none in the weak band, so no weaker sibling)
    "mw_act_single": ("metaworld/act_single", 20000),
    # SO-101 (eval/results/learned_so101_select, seeds 300-349, n = 50): every checkpoint of both recipes 0 % (none in
    # either band: each run's final one is kept, outside the band, and neither has a weaker sibling)
    "so101_act_single": ("so101_env/act_single", 20000),
    "so101_act_chunk": ("so101_env/act_chunk", 12000),
    # The GPU's longer runs (backbones/device_train.py act_chunk_long, stopped by the lent time at two checkpoints
    # each; eval/results/learned_goal_ten_long_select, init states 35-39, n = 30). LIBERO-Goal 80, 80 % (the later one;
    # neither in the weak band); LIBERO-10 73, 97 % (97 % lies above the strong band, so step 8,000; no weak sibling)
    "goal_act_chunk_long": ("libero_goal/act_chunk_long", 15415),
    "ten_act_chunk_long": ("libero_10/act_chunk_long", 8000),
    # The SO-101's act_chunk_b128 (device_train.py's recipe run on this CPU, no device drawn; stopped by its 110-min
    # bound at 8,789 steps; eval/results/learned_so101_b128_select, seeds 300-349, n = 50): 0, 12, 58, 24, 36 % (none in
    # the strong band: the final one is kept, outside it; the weaker sibling step 8,000, the other one in the weak band)
    "so101_act_chunk_b128": ("so101_env/act_chunk_b128", 8789),
    "so101_act_chunk_b128_weak": ("so101_env/act_chunk_b128", 8000),
}
# The selection study of each device_train.py run (suite, recipe; on a lent GPU, or on this CPU where none was
# drawn) -> (study, episodes per checkpoint, checkpoints it saved)
DEVICE_SELECTION: dict[tuple[str, str], tuple[str, int, int]] = {
    ("libero_goal", "act_chunk_long"): ("learned_goal_ten_long_select", 30, 2),
    ("libero_10", "act_chunk_long"): ("learned_goal_ten_long_select", 30, 2),
    ("so101_env", "act_chunk_b128"): ("learned_so101_b128_select", 50, 5),
}


def choose_suite(success: dict[int, float]) -> tuple[int, int | None]:
    """The rule above for one run: (strong step, weaker sibling's step or None) from each checkpoint's
    uncorrected success on the selection block ({step: fraction})."""
    if not success:
        raise ValueError("choose_suite: no checkpoint evaluated")
    steps = sorted(success)
    in_strong = [s for s in steps if STRONG_BAND[0] <= success[s] <= STRONG_BAND[1]]
    strong = in_strong[-1] if in_strong else steps[-1]
    weak = [s for s in steps if s != strong and WEAK_BAND[0] <= success[s] <= WEAK_BAND[1]]
    if not weak:
        return strong, None
    return strong, min(weak, key=lambda s: (round(abs(success[s] - WEAK_TARGET), 9), s))


def suite_paths(suite: str) -> tuple[str, str]:
    """(dataset root, training root) of a suite's ACTs (MetaWorld's: `record_dataset.py --suite metaworld`)."""
    if suite not in SUITE_SHORT and suite != "libero_spatial":
        raise SystemExit(f"train_backbones: unknown suite {suite!r}; one of libero_spatial, {', '.join(SUITE_SHORT)}")
    if suite == "libero_spatial":
        return DATASET, "outputs/train"
    return f"outputs/datasets/physvla_{suite}", f"outputs/train/{suite}"


def mid_candidates(name: str, out_root: str = "outputs/train") -> dict[str, Path]:
    """A `_mid` sibling's candidate checkpoints on disk: `<name>@<step>` for its continued run,
    `<recipe>_cpufull@<step>` for the named checkpoints of its recipe's whole run on this CPU."""
    found = {}
    if name in CONTINUED:
        for p in sorted((Path(out_root) / name / "checkpoints").glob("[0-9]*/pretrained_model")):
            found[f"{name}@{p.parent.name}"] = p
    if name in CPU_DRAW:
        recipe, steps = CPU_DRAW[name]
        for step in steps:
            p = Path(out_root) / CPU_DRAW_DIR / recipe / "checkpoints" / f"{step:06d}" / "pretrained_model"
            found[f"{recipe}_cpufull@{p.parent.name}"] = p
    for resumed in RESUMED_OF.get(name, ()):
        _, start, stop, every = RESUMED[resumed]
        run = Path(out_root) / CPU_DRAW_DIR / resumed
        for step in range(start + every, stop, every):
            found[f"{resumed}@{step:06d}"] = run / "checkpoints" / f"{step:06d}" / "pretrained_model"
    for run_name, steps in [(s, SMALLER[s][2]) for s in SMALLER_OF.get(name, ())] + \
                           [(f, FEWER[f][2]) for f in FEWER_OF.get(name, ())]:
        run = Path(out_root) / CPU_DRAW_DIR / run_name / "checkpoints"
        for step in steps:
            found[f"{run_name}@{step:06d}"] = run / f"{step:06d}" / "pretrained_model"
    return {k: p for k, p in found.items() if (p / "model.safetensors").exists()}


def choose_mid(success: dict[str, float], target: float = 0.40) -> str:
    """The rule that keeps a `_mid` sibling: of the candidates (`<run>@<step>` -> success, a fraction),
    the one closest to `target`; ties to the earlier step, then to the continued run (listed first)."""
    if not success:
        raise ValueError("choose_mid: no checkpoint evaluated")
    order = {k: i for i, k in enumerate(success)}
    return min(success, key=lambda k: (round(abs(success[k] - target), 9), int(k.rsplit("@", 1)[1]), order[k]))


def _episodes_meta(dataset: str, columns: list[str]):
    """Columns of the dataset's per-episode metadata (meta/episodes/*/*.parquet), in episode order."""
    import pandas as pd

    files = sorted((Path(dataset) / "meta" / "episodes").glob("chunk-*/file-*.parquet"))
    if not files:
        raise SystemExit(f"train_backbones: no episode metadata under {dataset}/meta/episodes; run "
                         "backbones/record_dataset.py first")
    # one thread: pyarrow's reader pool otherwise aborts some interpreters at exit ("terminate called")
    return pd.concat([pd.read_parquet(f, columns=columns, use_threads=False) for f in files])


def first_episodes(dataset: str, k: int) -> list[int]:
    """The dataset's episode indices that FEWER keeps: the first k of each run of consecutive episodes
    of one task (record_dataset.py writes them per noise level, then per task, by init state)."""
    meta = _episodes_meta(dataset, ["episode_index", "tasks"])
    kept, prev, run = [], None, 0
    for idx, tasks in zip(meta["episode_index"], meta["tasks"]):
        task = tuple(tasks)
        run = run + 1 if task == prev else 1
        prev = task
        if run <= k:
            kept.append(int(idx))
    return kept


RAW_ENV = "_rawenv"  # suffix of the ablation that reproduces the normalisation defect (ENV left raw)


def command(name: str, dataset: str, out_root: str, steps: int | None = None, device: str = "cpu",
            num_workers: int = 0, raw_env: bool = False) -> list[str]:
    """The lerobot-train argv of a recipe (optionally with fewer steps, for smoke tests).

    raw_env: the recipe as it was before the normalisation fix (no ENV entry: lerobot's default
    leaves observation.environment_state raw), written to <recipe>_rawenv; measures the fix."""
    if name in SMALLER:  # the recipe it shrinks, with the named arguments replaced
        recipe, narrower, _ = SMALLER[name]
        args, n = RECIPES[recipe]
        keys = {a.split("=", 1)[0] for a in narrower}
        args = [a for a in args if a.split("=", 1)[0] not in keys] + list(narrower)
    elif name in FEWER:  # the recipe it trains, on the first episodes of each task and noise level
        recipe, k, _ = FEWER[name]
        args, n = RECIPES[recipe]
        args = [*args, f"--dataset.episodes=[{','.join(map(str, first_episodes(dataset, k)))}]"]
    else:
        args, n = RECIPES[name]
    n = n if steps is None else steps
    if raw_env:
        args = [a.replace('"ENV": "MEAN_STD", ', "").replace('"ENV": "MIN_MAX", ', "") for a in args]
        name = name + RAW_ENV
    head = _lerobot_train()
    return [*head, f"--dataset.repo_id={repo_id(dataset)}", f"--dataset.root={dataset}", f"--policy.device={device}",
            f"--num_workers={num_workers}", *_COMMON, *args, f"--steps={n}",
            f"--save_freq={max(1, n // CHECKPOINTS_PER_RUN)}", f"--output_dir={out_root}/{name}",
            f"--job_name=physvla_{name}"]


def repo_id(dataset: str) -> str:
    """The local repo id of a dataset root (record_dataset.py names them local/<directory>)."""
    return f"local/{Path(dataset).name}"


def _lerobot_train() -> list[str]:
    """The lerobot-train entry point of this interpreter's environment."""
    exe = Path(sys.executable).with_name("lerobot-train")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "lerobot.scripts.lerobot_train"]


def continued_command(name: str, dataset: str, out_root: str, steps: int | None = None, device: str = "cpu",
                      num_workers: int = 0) -> list[str]:
    """The lerobot-train argv that continues a committed checkpoint (CONTINUED): its policy config,
    weights and normalisation come from --policy.path; only the run's own settings are named."""
    base, n, every = CONTINUED[name]
    n = n if steps is None else steps
    head = _lerobot_train()
    return [*head, f"--policy.path={COMMITTED / base}", f"--dataset.repo_id={repo_id(dataset)}", f"--dataset.root={dataset}",
            f"--policy.device={device}", f"--num_workers={num_workers}", *_COMMON, "--batch_size=32", f"--steps={n}",
            f"--save_freq={min(every, n)}", f"--output_dir={out_root}/{name}", f"--job_name=physvla_{name}"]


def resumed_command(name: str, out_root: str, device: str = "cpu", num_workers: int = 0) -> list[str]:
    """The lerobot-train argv of a resumed run (RESUMED): a whole CPU run resumed from a checkpoint into
    the resumed run's own directory; the run's config, weights, optimizer, scheduler and data order
    come from the checkpoint."""
    recipe, start, stop, every = RESUMED[name]
    ckpt = Path(out_root) / CPU_DRAW_DIR / recipe / "checkpoints" / f"{start:06d}" / "pretrained_model"
    return [*_lerobot_train(), "--resume=true", f"--config_path={ckpt / 'train_config.json'}",
            f"--policy.device={device}", f"--num_workers={num_workers}", f"--steps={stop}", f"--save_freq={every}",
            f"--output_dir={Path(out_root) / CPU_DRAW_DIR / name}"]


def checkpoint(name: str, out_root: str = "outputs/train") -> Path:
    """The pretrained_model directory of a recipe's final checkpoint, or of a weak sibling's."""
    if name in SIBLINGS:
        recipe, step = SIBLINGS[name]
        return Path(out_root) / recipe / "checkpoints" / f"{step:06d}" / "pretrained_model"
    if name in MID_CHOICE or name in SUITE_CHOICE:
        run, step = MID_CHOICE.get(name) or SUITE_CHOICE[name]
        return Path(out_root) / run / "checkpoints" / f"{step:06d}" / "pretrained_model"
    if name in CONTINUED:  # not chosen yet: the continued run's last checkpoint
        return Path(out_root) / name / "checkpoints" / "last" / "pretrained_model"
    return Path(out_root) / name / "checkpoints" / "last" / "pretrained_model"


# The GPU-trained ACT checkpoints the published tables ran (eval/results/learned), committed because
# they are small (2.6-5.7 MB) and a CPU run of the same recipe is another policy. The H100 re-runs
# them bit for bit: the same recipe, data and seed gave the same model.safetensors in two sessions.
# Diffusion's checkpoint (17 MB) is not committed and did not re-run bit for bit on the H100.
COMMITTED = Path(__file__).resolve().parent / "checkpoints"


def trained_or_committed(name: str, out_root: str = "outputs/train") -> Path:
    """The checkpoint train_backbones.py wrote under out_root, else the committed copy of it."""
    trained, committed = checkpoint(name, out_root), COMMITTED / name
    if not (trained / "model.safetensors").exists() and (committed / "model.safetensors").exists():
        return committed
    return trained


def _device_name(device: str) -> str:
    if device.startswith("cuda"):
        import torch

        return f"{torch.cuda.get_device_name(0)} (cuda), {os.cpu_count()} CPU cores"
    return f"{platform.machine()} CPU, {os.cpu_count()} cores, 1 torch thread"


def _commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True,
                              cwd=Path(__file__).resolve().parent).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def train(name: str, dataset: str, out_root: str, steps: int | None = None, device: str = "cpu",
          num_workers: int = 0, raw_env: bool = False) -> Path:
    if not (Path(dataset) / "meta" / "info.json").exists():
        raise SystemExit(f"train_backbones: no dataset at {dataset}; run backbones/record_dataset.py first")
    if name in CONTINUED:
        cmd = continued_command(name, dataset, out_root, steps, device, num_workers)
    elif name in RESUMED:
        cmd = resumed_command(name, out_root, device, num_workers)
    else:
        cmd = command(name, dataset, out_root, steps, device, num_workers, raw_env)
    name = name + RAW_ENV if raw_env else name
    out = Path(next(a for a in cmd if a.startswith("--output_dir=")).split("=", 1)[1])
    if out.exists():  # lerobot-train refuses an existing output dir without --resume
        shutil.rmtree(out)
    print("+ " + shlex.join(cmd), flush=True)
    t0 = time.time()
    # One torch thread: on a busy 2-core machine, 2 OpenMP threads spin-wait and a step takes ~25x
    # longer (measured: 1.7 s vs 66 ms for act_chunk's forward + backward at batch 64).
    env = {**os.environ, "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS", "1")}
    if subprocess.run(cmd, env=env).returncode != 0:
        raise SystemExit(f"train_backbones: lerobot-train failed for {name} (its error is above)")
    secs = time.time() - t0
    info = json.loads((Path(dataset) / "meta" / "info.json").read_text())
    recipe = {"recipe": name, "command": cmd, "train_seconds": secs, "device": _device_name(device),
              "steps": int(next(a for a in cmd if a.startswith("--steps=")).split("=")[1]), "seed": SEED,
              "commit": _commit(), "dataset": {"root": dataset, "episodes": info.get("total_episodes"),
                                               "frames": info.get("total_frames")}}
    subset = next((a for a in cmd if a.startswith("--dataset.episodes=")), None)
    if subset is not None:  # FEWER: the episodes it trained on, of the whole dataset's
        kept = set(json.loads(subset.split("=", 1)[1]))
        meta = _episodes_meta(dataset, ["episode_index", "length"])
        recipe["dataset"] |= {"episodes": len(kept), "frames": int(meta["length"][meta["episode_index"].isin(kept)].sum()),
                              "of_episodes": info.get("total_episodes"), "of_frames": info.get("total_frames")}
    if name in CONTINUED or name in RESUMED:  # the run it continues, by the weights it started from
        import hashlib

        if name in CONTINUED:
            base, key = COMMITTED / CONTINUED[name][0], "continues"
            where = str(base.relative_to(COMMITTED.parent.parent))
        else:
            base = Path(next(a for a in cmd if a.startswith("--config_path=")).split("=", 1)[1]).parent
            key, where = "resumes", str(base)
        recipe[key] = {"checkpoint": where,
                       "model_sha256": hashlib.sha256((base / "model.safetensors").read_bytes()).hexdigest()}
    for ckpt in sorted((out / "checkpoints").glob("*/pretrained_model")):  # every checkpoint knows its recipe
        (ckpt / "recipe.json").write_text(json.dumps({**recipe, "checkpoint": ckpt.parent.name}, indent=1))
    print(f"{name}: trained in {secs / 60:.1f} min on {recipe['device']} -> {out / 'checkpoints'}")
    return checkpoint(name, out_root)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("recipe", nargs="?", choices=[*RECIPES, *SMALLER, *FEWER, *CONTINUED, *RESUMED, "all"], default="all",
                    help="a recipe, a `_mid` sibling that continues a committed checkpoint, a resumed CPU run, "
                         "or all recipes")
    ap.add_argument("--suite", default="libero_spatial",
                    help="whose demonstrations (a LIBERO suite, or metaworld): sets --dataset and --out to "
                         "outputs/{datasets/physvla_,train/}<suite>")
    ap.add_argument("--dataset", default=None, help=f"dataset root (default: the suite's; {DATASET})")
    ap.add_argument("--out", default=None, help="training root (default: the suite's; outputs/train)")
    ap.add_argument("--steps", type=int, default=None, help="override the recipe's step count (smoke tests)")
    ap.add_argument("--list", action="store_true", help="print each recipe's command and exit")
    ap.add_argument("--parallel", type=int, default=1, help="recipes trained side by side")
    ap.add_argument("--device", default="cpu", help="where lerobot-train runs (cpu, cuda): not part of the recipe")
    # one loader process reads the next batch while the update runs: 1.6-1.8x faster chunked
    # recipes on this 2-core CPU (eval/results/bench_training); the weights are the same
    ap.add_argument("--num-workers", type=int, default=1,
                    help="lerobot-train's data-loader processes per recipe (0: read in the training process)")
    ap.add_argument("--raw-env", action="store_true",
                    help="ablation: leave observation.environment_state raw, as before the fix (-> <recipe>_rawenv)")
    args = ap.parse_args()
    dataset, out = suite_paths(args.suite)
    args.dataset, args.out = args.dataset or dataset, args.out or out
    names = list(RECIPES) if args.recipe == "all" else [args.recipe]
    if args.list:
        for n in names:
            cmd = (continued_command(n, args.dataset, args.out, None, args.device, args.num_workers)
                   if n in CONTINUED else resumed_command(n, args.out, args.device, args.num_workers)
                   if n in RESUMED else command(n, args.dataset, args.out, None, args.device, args.num_workers,
                                                args.raw_env))
            print(n + ":\n  " + shlex.join(cmd))
        return
    with ThreadPoolExecutor(max_workers=max(1, args.parallel)) as pool:  # each recipe is its own process
        for f in [pool.submit(train, n, args.dataset, args.out, args.steps, args.device, args.num_workers,
                              args.raw_env) for n in names]:
            f.result()


if __name__ == "__main__":
    main()
