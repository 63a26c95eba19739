"""Record scripted-expert rollouts on a LIBERO suite or on MetaWorld into a local LeRobotDataset (v3), state only.

    .venv/bin/python backbones/record_dataset.py [--suite libero_spatial] [--out outputs/datasets/physvla_<suite>]
        [--seeds 10-39] [--tasks 0-9] [--dart-sigma 0.1,0.3] [--workers 2] [--camera-size 0]

The teacher: LIBERO-Spatial's bowl expert (sim/experts.py) on libero_spatial, the shape-planning expert
(sim/shape_expert.py) on the other suites (`--teacher` to choose), and on `--suite metaworld` each task's own
scripted policy from metaworld.policies (sim/metaworld_expert.py; `--tasks` are the modelled tasks' indices,
sim/metaworld_sim.py TASKS). Each suite's horizon is lerobot's (sim/scenes.py HORIZONS); MetaWorld's is 500.

Each frame holds what a state-based policy sees in `lerobot-eval --env.type=libero_physvla
--env.cameras=false` (scenes.LiberoScene.policy_observation):
    observation.state              eef xyz, eef axis-angle, finger qpos       (8, float32)
    observation.environment_state  object xyz, target xyz (from the BDDL goal) (6, float32)
    action                         the clean expert's action, LIBERO OSC_POSE  (7, float32)
    task                           the task's language instruction
On MetaWorld, what `--env.type=metaworld_physvla --env.cameras=false` gives (sim/metaworld_sim.py
MetaworldScene.policy_observation), at its 80 fps:
    observation.state              hand xyz, finger opening (MetaWorld's agent_pos)  (4, float32)
    observation.environment_state  object xyz, target xyz (the task's own)            (6, float32)
    action                         the clean policy's action, [dx, dy, dz, grab]      (4, float32)
On `--suite so101_env` (lerobot-env-so101's SO101PickPlace-v0, sim/so101_env_sim.py; the teacher its pick-and-place
controller, sim/so101_env_expert.py), what `--env.type=so101_physvla --env.random_block_position=true
--env.action_scale=0.025` gives, at its 10 fps (`--tasks 0`; seeds draw the block and the goal):
    observation.state              agent_pos: 5 joint positions, 5 joint velocities, gripper command, site xyz (14)
    observation.environment_state  block xyz, goal xyz                                            (6, float32)
    action                         the clean controller's action, [dx, dy, dz, grasp]             (4, float32)
With --camera-size N the frames hold what an image-input policy sees in `lerobot-eval --env.type=libero
--env.observation_height=N --env.observation_width=N` instead (no object or target position):
    observation.state              as above                                   (8, float32)
    observation.images.image       the agentview frame, turned as lerobot's LiberoProcessorStep turns it
                                   (N, N, 3, uint8; sim/scenes.py LiberoScene.frame)
    action, task                   as above
rendered on this CPU at ~0.13 s a step (default root outputs/datasets/physvla_<suite>_agentview<N>).
Only successful episodes are kept. With --dart-sigma > 0 the *executed* action gets Gaussian
x, y noise (action units) while the *recorded* label stays the expert's clean action (DART), so
the demonstrations cover the states a slightly-off learned policy will visit. Several noise
levels (`--dart-sigma 0.1,0.3`) record each init state once per level, each with its own noise
draw: more varied recoveries from the same starts.

Init states: LIBERO has 50 per task; evaluation (eval/run.py, eval/studies/) uses seeds 0..N-1, so the
default training seeds 10-39 never overlap the evaluation's first 10.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from tqdm import tqdm

from lerobot_physvla.replay.record import parse_range  # noqa: F401 - also this script's API

FPS = 20  # LIBERO's control frequency
STATE_NAMES = ["eef_x", "eef_y", "eef_z", "eef_ax", "eef_ay", "eef_az", "finger_l", "finger_r"]
ENV_NAMES = ["obj_x", "obj_y", "obj_z", "tgt_x", "tgt_y", "tgt_z"]
ACTION_NAMES = ["dx", "dy", "dz", "drx", "dry", "drz", "gripper"]
FEATURES = {
    "observation.state": {"dtype": "float32", "shape": (8,), "names": STATE_NAMES},
    "observation.environment_state": {"dtype": "float32", "shape": (6,), "names": ENV_NAMES},
    "action": {"dtype": "float32", "shape": (7,), "names": ACTION_NAMES},
}
IMAGE = "observation.images.image"
METAWORLD = "metaworld"
METAWORLD_FPS = 80  # lerobot's MetaworldEnvConfig.fps (the env's 12.5 ms control step)
SO101 = "so101_env"  # lerobot-env-so101's SO101PickPlace-v0 (sim/so101_env_sim.py)
SO101_FPS = 10  # its control_dt of 0.1 s
SO101_FEATURES = {
    "observation.state": {"dtype": "float32", "shape": (14,),
                          "names": [*(f"{j}.pos" for j in ("pan", "lift", "elbow", "wrist_flex", "wrist_roll")),
                                    *(f"{j}.vel" for j in ("pan", "lift", "elbow", "wrist_flex", "wrist_roll")),
                                    "gripper_cmd", "site_x", "site_y", "site_z"]},
    "observation.environment_state": {"dtype": "float32", "shape": (6,),
                                      "names": ["block_x", "block_y", "block_z", "goal_x", "goal_y", "goal_z"]},
    "action": {"dtype": "float32", "shape": (4,), "names": ["dx", "dy", "dz", "grasp"]},
}
METAWORLD_FEATURES = {
    "observation.state": {"dtype": "float32", "shape": (4,), "names": ["hand_x", "hand_y", "hand_z", "fingers"]},
    "observation.environment_state": FEATURES["observation.environment_state"],
    "action": {"dtype": "float32", "shape": (4,), "names": ["dx", "dy", "dz", "grab"]},
}


def features(camera_size: int = 0, suite: str = "libero_spatial") -> dict:
    """The dataset's features: state-only, or (camera_size > 0, LIBERO only) state and the agentview frame, no
    object state."""
    if suite in (METAWORLD, SO101):
        if camera_size:
            raise SystemExit(f"record_dataset: {suite} is recorded state-only; leave --camera-size out")
        return METAWORLD_FEATURES if suite == METAWORLD else SO101_FEATURES
    if not camera_size:
        return FEATURES
    return {"observation.state": FEATURES["observation.state"],
            IMAGE: {"dtype": "image", "shape": (camera_size, camera_size, 3), "names": ["height", "width", "channels"]},
            "action": FEATURES["action"]}


def scene_and_teacher(suite: str, task_id: int, teacher: str, camera_size: int = 0):
    """(scene, reset(seed), act(state) -> clean action) of one task's teacher."""
    if suite == METAWORLD:
        from lerobot_physvla.sim.metaworld_expert import MetaworldExpert, MetaworldExpertConfig
        from lerobot_physvla.sim.metaworld_sim import MetaworldScene

        scene = MetaworldScene(task_id)
        mw = MetaworldExpert(scene.task.name, MetaworldExpertConfig())
        return scene, (lambda seed: mw.reset(seed=seed)), (lambda st: mw.act(scene.raw_obs))
    if suite == SO101:
        from lerobot_physvla.sim.so101_env_expert import SO101EnvExpert
        from lerobot_physvla.sim.so101_env_sim import SO101EnvScene

        scene, so = SO101EnvScene(), SO101EnvExpert()
        return scene, (lambda seed: so.reset(seed=seed)), (lambda st: so.act(scene))
    from lerobot_physvla.sim.experts import PickPlaceExpert
    from lerobot_physvla.sim.scenes import LiberoScene
    from lerobot_physvla.sim.shape_expert import ShapeExpert

    scene = LiberoScene(suite, task_id, camera_size=camera_size, every_step=True)  # lerobot-eval's pixels
    expert = ShapeExpert() if teacher == "shape" else PickPlaceExpert()
    if teacher == "shape":
        return scene, (lambda seed: expert.reset(seed=seed)), (lambda st: expert.act_source(scene.source))
    return scene, (lambda seed: expert.reset(seed=seed)), (
        lambda st: expert.act(st.eef_pos[0], st.obj_pos[0], st.target_pos[0]))


def rollout(task_id: int, seeds: list[int], dart_sigma: float, level: int = 0, suite: str = "libero_spatial",
            teacher: str = "bowl", camera_size: int = 0) -> list[dict]:
    """Expert episodes of one task; returns the successful ones as arrays (runs in a worker)."""
    scene, reset, act = scene_and_teacher(suite, task_id, teacher, camera_size)
    episodes = []
    for seed in seeds:
        scene.reset(seed)
        reset(seed)
        rng = np.random.default_rng(10_000 + seed + 1_000_000 * level)  # level 0: the original draws
        obs_s, obs_e, frames, acts, success = [], [], [], [], False
        for _ in range(scene.horizon):
            st = scene.read()
            # the frame is rendered once, below
            state_only = suite in (METAWORLD, SO101)
            o = scene.policy_observation(st) if state_only else scene.policy_observation(st, frame=False)
            a = np.asarray(act(st), dtype=np.float64)
            obs_s.append(o["observation.state"])
            obs_e.append(o["observation.environment_state"])
            if camera_size:
                frames.append(scene.frame())
            acts.append(a.astype(np.float32))
            executed = a.copy()
            if dart_sigma > 0:
                executed[:2] = np.clip(executed[:2] + rng.normal(0.0, dart_sigma, 2), -1.0, 1.0)
            success, _ = scene.step(executed)
            if success:
                break
        if success:
            episodes.append({"task_id": task_id, "seed": seed, "dart_sigma": dart_sigma, "task": scene.task.language,
                             "state": np.asarray(obs_s), "env": np.asarray(obs_e), "action": np.asarray(acts),
                             "image": np.asarray(frames) if camera_size else None})
    return episodes


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--suite", default="libero_spatial",
                    help=f"libero_spatial, libero_object, libero_goal, libero_10, {METAWORLD} or {SO101}")
    ap.add_argument("--teacher", choices=("bowl", "shape", METAWORLD, "so101"), default=None,
                    help="bowl (sim/experts.py) or shape (sim/shape_expert.py); default: bowl on libero_spatial, "
                         "MetaWorld's own on metaworld, lerobot-env-so101's controller on so101_env, else shape")
    ap.add_argument("--out", default=None, help="dataset root (replaced); default outputs/datasets/physvla_<suite>")
    ap.add_argument("--repo-id", default=None, help="default local/physvla_<suite>")
    ap.add_argument("--tasks", default="0-9")
    ap.add_argument("--seeds", default="10-39", help="LIBERO init-state indices (MetaWorld: seeds) to record")
    ap.add_argument("--dart-sigma", default="0.1,0.3",
                    help="executed-action x, y noise (action units); a comma list records each init state once per level")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--camera-size", type=int, default=0,
                    help="N > 0: record the agentview frame (N x N) instead of the object and target positions")
    args = ap.parse_args()

    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    teacher = args.teacher or ("bowl" if args.suite == "libero_spatial" else METAWORLD if args.suite == METAWORLD
                               else "so101" if args.suite == SO101 else "shape")
    if (teacher == METAWORLD) != (args.suite == METAWORLD):
        sys.exit("record_dataset: MetaWorld's teacher runs on --suite metaworld only, and only it runs there")
    if (teacher == "so101") != (args.suite == SO101):
        sys.exit(f"record_dataset: the so101 teacher runs on --suite {SO101} only, and only it runs there")
    feats = features(args.camera_size, args.suite)
    name = f"physvla_{args.suite}" + (f"_agentview{args.camera_size}" if args.camera_size else "")
    args.out = args.out or f"outputs/datasets/{name}"
    args.repo_id = args.repo_id or f"local/{name}"
    tasks, seeds = parse_range(args.tasks), parse_range(args.seeds)
    if any(40 <= s <= 49 for s in seeds):
        sys.exit("record_dataset: init states 40-49 are kept for the final evaluation; record others")
    sigmas = [float(x) for x in str(args.dart_sigma).split(",") if x.strip()]
    t0 = time.time()
    episodes = []
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        futures = [pool.submit(rollout, t, seeds, sig, lvl, args.suite, teacher, args.camera_size)
                   for lvl, sig in enumerate(sigmas) for t in tasks]
        for f in tqdm(futures, desc="tasks", unit="task"):
            episodes += f.result()
    out = Path(args.out)
    if out.exists():
        shutil.rmtree(out)
    fps, robot = {METAWORLD: (METAWORLD_FPS, "sawyer"), SO101: (SO101_FPS, "so101")}.get(args.suite, (FPS, "panda"))
    ds = LeRobotDataset.create(args.repo_id, fps=fps, features=feats, root=out, robot_type=robot, use_videos=False)
    for ep in tqdm(episodes, desc="writing", unit="episode"):
        for t, (s, e, a) in enumerate(zip(ep["state"], ep["env"], ep["action"])):
            frame = {"observation.state": s, "action": a, "task": ep["task"]}
            if args.camera_size:
                frame[IMAGE] = ep["image"][t]
            else:
                frame["observation.environment_state"] = e
            ds.add_frame(frame)
        ds.save_episode()
    ds.finalize()
    kept = {t: sum(e["task_id"] == t for e in episodes) for t in tasks}
    n_runs = len(seeds) * len(sigmas)
    frames = sum(len(e["action"]) for e in episodes)
    print(f"recorded {len(episodes)} of {len(tasks) * n_runs} episodes (successful only), {frames} frames, "
          f"in {time.time() - t0:.0f} s -> {out}")
    print("kept per task: " + ", ".join(f"T{t}: {k}/{n_runs}" for t, k in kept.items()))
    if not episodes:
        sys.exit("record_dataset: no successful episode; nothing to train on")


if __name__ == "__main__":
    main()
