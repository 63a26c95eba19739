"""Record episodes of a scripted expert or a LeRobot policy in a simulator into a LeRobotDataset.

    .venv/bin/python -m lerobot_physvla.replay.record --root outputs/datasets/replay_demo \
        --scene libero_spatial --tasks 0-1 --seeds 10-11 [--policy.path DIR | --expert '{"action_noise": 0.3}']
        [--physvla]   (the default corrector in the loop; its corrected action is what is executed)

Every frame holds the policy's observation, the executed action, the corrector's packed physical
state and the episode's [scene, task, seed] (columns.py), so the dataset can be replayed offline,
re-simulated and fed to a policy. Failed episodes are kept (`next.success` says which). The
executed action is the recorded float32 one, so re-simulating it reproduces the episode.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np
from tqdm import tqdm

from lerobot_physvla.core.state import packed_size
from lerobot_physvla.replay import columns as C
from lerobot_physvla.replay.dataset import quiet

FPS = 20  # LIBERO's and robosuite's control frequency here


def observation_of(scene, state) -> dict[str, np.ndarray]:
    """The policy observation of a scene (LIBERO: lerobot-eval's state-only observation; other
    scenes: eef xyz + gripper opening, and object + target xyz), float32."""
    if hasattr(scene, "policy_observation"):
        return scene.policy_observation(state)
    return {
        C.STATE: np.concatenate([state.eef_pos[0], state.gripper]).astype(np.float32),
        C.ENV_STATE: np.concatenate([state.obj_pos[0], state.target_pos[0]]).astype(np.float32),
    }


def features(scene, n_joints: int, obs: dict[str, np.ndarray]) -> dict:
    a = scene.layout.dim
    return {
        C.STATE: {"dtype": "float32", "shape": obs[C.STATE].shape, "names": None},
        C.ENV_STATE: {"dtype": "float32", "shape": (6,), "names": ["obj_x", "obj_y", "obj_z", "tgt_x", "tgt_y", "tgt_z"]},
        C.PHYSVLA_STATE: {"dtype": "float64", "shape": (packed_size(n_joints),), "names": None},
        C.EPISODE: {"dtype": "int64", "shape": (3,), "names": ["scene", "task_id", "seed"]},
        C.SUCCESS: {"dtype": "bool", "shape": (1,), "names": None},
        C.ACTION: {"dtype": "float32", "shape": (a,), "names": None},
    }


def run_episode(scene, act, seed: int, corrector=None) -> dict:
    """One episode: per-frame arrays of observation, state, executed action, success."""
    scene.reset(seed)
    if corrector is not None:
        corrector.reset()
    frames = {C.STATE: [], C.ENV_STATE: [], C.PHYSVLA_STATE: [], C.ACTION: [], C.SUCCESS: []}
    for _ in range(scene.horizon):
        st = scene.read()
        obs = observation_of(scene, st)
        a = np.asarray(act(obs, st), dtype=np.float64)[None]
        if corrector is not None:
            a = corrector(a, st)
        a32 = a[0].astype(np.float32)
        success, _ = scene.step(a32.astype(np.float64))  # the recorded value is what runs
        for k, v in ((C.STATE, obs[C.STATE]), (C.ENV_STATE, obs[C.ENV_STATE]), (C.PHYSVLA_STATE, st.pack()[0]),
                     (C.ACTION, a32), (C.SUCCESS, np.array([success]))):
            frames[k].append(np.array(v, copy=True))
        if success and scene.stop_on_success:
            break
    return {k: np.stack(v) for k, v in frames.items()}


def record(root: str | Path, scene_names: list[str], seeds: list[int], repo_id: str = "local/physvla_replay",
           policy_path: str | None = None, expert: dict | None = None, corrector_cfg=None,
           progress: bool = True) -> dict:
    """Record every (scene, seed) into a new LeRobotDataset at `root` (must not exist).
    Returns {"episodes", "frames", "successes"}."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_physvla.core.corrector import Corrector
    from lerobot_physvla.sim.scenes import make_scene

    root = Path(root)
    if root.exists():
        raise FileExistsError(f"physvla: {root} exists; record into a new directory")
    ds, n_frames, successes = None, 0, 0
    bar = tqdm(total=len(scene_names) * len(seeds), desc="recording", unit="episode", disable=not progress)
    try:
        for name in scene_names:
            scene = make_scene(name)
            if policy_path:
                from lerobot_physvla.replay.policy import LeRobotPolicy

                pol = LeRobotPolicy(policy_path)
                task = getattr(getattr(scene, "task", None), "language", name)
                reset, act = pol.reset, (lambda obs, st, _p=pol, _t=task: _p.act(obs, _t))
            else:
                from lerobot_physvla.sim.experts import ExpertConfig, PickPlaceExpert

                exp = PickPlaceExpert(layout=scene.layout, cfg=ExpertConfig(**{**scene.expert, **(expert or {})}))
                reset = lambda seed, _e=exp: _e.reset(seed=seed)  # noqa: E731
                act = lambda obs, st, _e=exp: _e.act(st.eef_pos[0], st.obj_pos[0], st.target_pos[0])  # noqa: E731
            cor = Corrector(corrector_cfg.replace(layout=_layout_name(scene.layout))) if corrector_cfg else None
            task_text = getattr(getattr(scene, "task", None), "language", name)
            for seed in seeds:
                reset(seed)
                ep = run_episode(scene, act, seed, cor)
                if ds is None:
                    n = (ep[C.PHYSVLA_STATE].shape[1])
                    from lerobot_physvla.core.state import n_joints_from_size

                    feats = features(scene, n_joints_from_size(n), {C.STATE: ep[C.STATE][0]})
                    ds = LeRobotDataset.create(repo_id, fps=FPS, features=feats, root=root, robot_type="panda", video_backend="pyav",
                                               use_videos=False)
                code = C.episode_code(name, seed)
                for t in range(len(ep[C.ACTION])):
                    ds.add_frame({**{k: v[t] for k, v in ep.items()}, C.EPISODE: code, "task": task_text})
                quiet()  # lerobot's loaders switch datasets' bars back on
                ds.save_episode()
                n_frames += len(ep[C.ACTION])
                successes += bool(ep[C.SUCCESS].any())
                bar.update(1)
    except BaseException:
        if ds is not None:
            ds.finalize()
        shutil.rmtree(root, ignore_errors=True)  # nothing half-written stays behind
        raise
    finally:
        bar.close()
    if ds is not None:
        ds.finalize()
    return {"episodes": len(scene_names) * len(seeds), "frames": n_frames, "successes": successes}


def _layout_name(layout) -> str:
    from lerobot_physvla.core.config import LAYOUTS

    return next(k for k, v in LAYOUTS.items() if v == layout)


def parse_range(text: str) -> list[int]:
    """'10-29' -> [10, ..., 29]; '0,3,5' -> [0, 3, 5]."""
    out = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out += list(range(int(lo), int(hi or lo) + 1))
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m lerobot_physvla.replay.record", description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", required=True, help="new dataset directory (must not exist)")
    ap.add_argument("--repo_id", default="local/physvla_replay")
    ap.add_argument("--scene", default="libero_spatial", choices=C.SCENES)
    ap.add_argument("--tasks", default="0", help="LIBERO task ids, e.g. 0-9 (LIBERO scenes only)")
    ap.add_argument("--seeds", default="10-11", help="init states / seeds, e.g. 10-39")
    ap.add_argument("--policy.path", dest="policy_path", default=None, help="a LeRobot checkpoint (else the scripted expert)")
    ap.add_argument("--expert", default="{}", help="ExpertConfig failure fields as JSON, e.g. '{\"action_noise\": 0.3}'")
    ap.add_argument("--physvla", action="store_true", help="run the default corrector in the loop")
    args = ap.parse_args(argv)
    scenes = [f"{args.scene}/{t}" for t in parse_range(args.tasks)] if args.scene.startswith("libero_") else [args.scene]
    cfg = None
    if args.physvla:
        from lerobot_physvla.core.config import preset

        cfg = preset()
    out = record(args.root, scenes, parse_range(args.seeds), args.repo_id, args.policy_path, json.loads(args.expert), cfg)
    print(f"recorded {out['episodes']} episodes ({out['successes']} successful), {out['frames']} frames -> {args.root}")


if __name__ == "__main__":
    main()
