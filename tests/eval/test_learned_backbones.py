"""Learned backbones end to end: expert rollouts -> LeRobotDataset v3 -> lerobot-train -> a policy
the harness runs (backbones/record_dataset.py, backbones/train_backbones.py, eval/backbones.py)."""

import pytest
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "backbones"))
sys.path.insert(0, str(ROOT / "eval"))
import record_dataset  # noqa: E402
import train_backbones  # noqa: E402


def test_parse_range():
    assert record_dataset.parse_range("10-12,15") == [10, 11, 12, 15]


def test_every_recipe_is_state_only_seeded_and_cpu():
    for name in train_backbones.RECIPES:
        cmd = " ".join(train_backbones.command(name, "ds", "out"))
        assert "--policy.device=cpu" in cmd and f"--seed={train_backbones.SEED}" in cmd
        assert "--wandb.enable=false" in cmd and "--policy.push_to_hub=false" in cmd
        assert "image" not in cmd
        assert '"ENV": "' in cmd  # the object / target xyz are normalised (lerobot leaves type ENV raw)
        # where it runs is not part of the recipe: only the device and loader flags change
        gpu = train_backbones.command(name, "ds", "out", device="cuda", num_workers=3)
        changed = set(gpu) ^ set(train_backbones.command(name, "ds", "out"))
        assert changed == {"--policy.device=cpu", "--policy.device=cuda", "--num_workers=0", "--num_workers=3"}


def test_a_smaller_recipe_is_its_recipe_with_only_the_named_sizes_replaced():
    for small, (recipe, narrower, _) in train_backbones.SMALLER.items():
        mine, theirs = train_backbones.command(small, "ds", "out"), train_backbones.command(recipe, "ds", "out")
        keys = {a.split("=", 1)[0] for a in narrower}
        assert [a.split("=", 1)[0] for a in mine].count("--policy.dim_model") == 1  # no argument named twice
        assert set(narrower) <= set(mine) and not set(narrower) & set(theirs)
        named = {"--output_dir", "--job_name", *keys}
        rest = [{a for a in cmd if a.split("=", 1)[0] not in named} for cmd in (mine, theirs)]
        assert rest[0] == rest[1]


def test_a_fewer_data_recipe_is_its_recipe_on_the_first_episodes_of_each_task_and_noise_level(tmp_path):
    import pandas as pd

    # record_dataset.py's order: noise level, then task, then init state; T1 has no episode at level 1
    tasks = [["t0"]] * 3 + [["t1"]] * 2 + [["t2"]] * 4 + [["t0"]] * 1 + [["t2"]] * 2
    meta = tmp_path / "ds" / "meta" / "episodes" / "chunk-000"
    meta.mkdir(parents=True)
    pd.DataFrame({"episode_index": range(len(tasks)), "tasks": tasks, "length": [100] * len(tasks)}).to_parquet(
        meta / "file-000.parquet")
    assert train_backbones.first_episodes(str(tmp_path / "ds"), 2) == [0, 1, 3, 4, 5, 6, 9, 10, 11]
    assert train_backbones.first_episodes(str(tmp_path / "ds"), 1) == [0, 3, 5, 9, 10]
    for few, (recipe, k, _) in train_backbones.FEWER.items():
        mine = train_backbones.command(few, str(tmp_path / "ds"), "out")
        theirs = train_backbones.command(recipe, str(tmp_path / "ds"), "out")
        assert f"--dataset.episodes=[{','.join(map(str, train_backbones.first_episodes(str(tmp_path / 'ds'), k)))}]" in mine
        named = {"--output_dir", "--job_name", "--dataset.episodes"}
        rest = [{a for a in cmd if a.split("=", 1)[0] not in named} for cmd in (mine, theirs)]
        assert rest[0] == rest[1]


def test_weak_siblings_are_earlier_checkpoints_of_a_recipe():
    for weak, (recipe, step) in train_backbones.SIBLINGS.items():
        steps = train_backbones.RECIPES[recipe][1]
        assert 0 < step < steps and step % (steps // train_backbones.CHECKPOINTS_PER_RUN) == 0, weak
        assert train_backbones.checkpoint(weak).parts[-4:] == (recipe, "checkpoints", f"{step:06d}", "pretrained_model")


@pytest.mark.slow
def test_record_train_and_run_a_learned_backbone(tmp_path, monkeypatch):
    ds = tmp_path / "ds"
    rec = subprocess.run([sys.executable, str(ROOT / "backbones/record_dataset.py"), "--tasks", "0", "--seeds", "10",
                          "--dart-sigma", "0.1", "--workers", "1", "--out", str(ds)], capture_output=True, text=True, cwd=ROOT)
    assert rec.returncode == 0, rec.stderr[-2000:]
    info = json.loads((ds / "meta" / "info.json").read_text())
    assert info["total_episodes"] == 1 and info["features"]["observation.environment_state"]["shape"] == [6]
    assert 50 < info["total_frames"] < 280  # one successful expert episode

    train = subprocess.run([sys.executable, str(ROOT / "backbones/train_backbones.py"), "act_chunk", "--dataset", str(ds),
                            "--out", str(tmp_path / "train"), "--steps", "2"], capture_output=True, text=True, cwd=ROOT)
    assert train.returncode == 0, train.stdout[-2000:] + train.stderr[-2000:]
    ckpt = train_backbones.checkpoint("act_chunk", str(tmp_path / "train"))
    recipe = json.loads((ckpt / "recipe.json").read_text())
    assert recipe["recipe"] == "act_chunk" and recipe["steps"] == 2 and "CPU" in recipe["device"]
    assert "--num_workers=1" in recipe["command"]  # the CPU default: batches read beside the update
    # data-loader workers change how fast a recipe trains, not what it learns
    again = subprocess.run([sys.executable, str(ROOT / "backbones/train_backbones.py"), "act_chunk", "--dataset", str(ds),
                            "--out", str(tmp_path / "train0"), "--steps", "2", "--num-workers", "0"],
                           capture_output=True, text=True, cwd=ROOT)
    assert again.returncode == 0, again.stderr[-2000:]
    same = train_backbones.checkpoint("act_chunk", str(tmp_path / "train0")) / "model.safetensors"
    assert same.read_bytes() == (ckpt / "model.safetensors").read_bytes()

    # a `_mid` sibling continues a committed checkpoint: lerobot-train takes its config and weights
    # (--policy.path) with only the run's own settings named, and the recipe names what it continued
    mid = subprocess.run([sys.executable, str(ROOT / "backbones/train_backbones.py"), "act_chunk_mid", "--dataset",
                          str(ds), "--out", str(tmp_path / "train"), "--steps", "2"], capture_output=True, text=True,
                         cwd=ROOT)
    assert mid.returncode == 0, mid.stdout[-2000:] + mid.stderr[-2000:]
    mid_ckpt = tmp_path / "train" / "act_chunk_mid" / "checkpoints" / "last" / "pretrained_model"
    mid_recipe = json.loads((mid_ckpt / "recipe.json").read_text())
    base = train_backbones.COMMITTED / "act_chunk_weak"
    import hashlib

    assert mid_recipe["continues"]["model_sha256"] == hashlib.sha256((base / "model.safetensors").read_bytes()).hexdigest()
    mid_cfg, base_cfg = (json.loads((d / "config.json").read_text()) for d in (mid_ckpt, base))
    assert {k: mid_cfg[k] for k in ("chunk_size", "n_action_steps", "dim_model")} == \
        {k: base_cfg[k] for k in ("chunk_size", "n_action_steps", "dim_model")}
    assert (mid_ckpt / "model.safetensors").read_bytes() != (base / "model.safetensors").read_bytes()  # it trained

    # a `_mid` sibling may resume a whole CPU run from one of its checkpoints (RESUMED): lerobot-train
    # --resume into its own directory, saving finer; the recipe names the checkpoint it resumed
    (tmp_path / "train" / "cpu_full").mkdir()
    shutil.copytree(tmp_path / "train" / "act_chunk", tmp_path / "train" / "cpu_full" / "act_chunk")
    monkeypatch.setitem(train_backbones.RESUMED, "act_chunk_fine", ("act_chunk", 1, 2, 1))
    cmd = train_backbones.resumed_command("act_chunk_fine", str(tmp_path / "train"))
    assert "--resume=true" in cmd and "--save_freq=1" in cmd and "--steps=2" in cmd
    start = tmp_path / "train" / "cpu_full" / "act_chunk" / "checkpoints" / "000001" / "pretrained_model"
    monkeypatch.chdir(ROOT)
    train_backbones.train("act_chunk_fine", str(ds), str(tmp_path / "train"))
    fine = tmp_path / "train" / "cpu_full" / "act_chunk_fine" / "checkpoints" / "000002" / "pretrained_model"
    fine_recipe = json.loads((fine / "recipe.json").read_text())
    assert fine_recipe["resumes"]["model_sha256"] == hashlib.sha256((start / "model.safetensors").read_bytes()).hexdigest()
    assert (fine / "model.safetensors").read_bytes() != (start / "model.safetensors").read_bytes()  # it trained

    # Defect found in #9: lerobot's ACT / Diffusion configs normalise VISUAL, STATE and ACTION only,
    # so observation.environment_state (type ENV) reached the network raw. The saved preprocessor
    # must normalise it with the dataset's statistics, as lerobot-train and lerobot-eval apply it.
    import torch

    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import make_pre_post_processors

    stats = json.loads((ds / "meta" / "stats.json").read_text())["observation.environment_state"]
    pre, _ = make_pre_post_processors(PreTrainedConfig.from_pretrained(str(ckpt)), pretrained_path=str(ckpt))
    env = np.asarray(stats["mean"], np.float32) + np.asarray(stats["std"], np.float32)  # one std above the mean
    batch = {"observation.state": torch.zeros(1, 8), "observation.environment_state": torch.from_numpy(env)[None],
             "task": ["t"]}
    out = pre(batch)["observation.environment_state"][0].numpy()
    spread = np.asarray(stats["std"]) > 1e-6  # a coordinate constant over one episode (the plate) stays 0 / eps
    np.testing.assert_allclose(out[spread], 1.0, atol=1e-3)

    # A checkpoint trained on a GPU names cuda in its config and in its saved preprocessor's device
    # step; the harness (and lerobot-physvla-replay) run it on the CPU, as lerobot-eval does.
    pre_json = ckpt / "policy_preprocessor.json"
    pre = json.loads(pre_json.read_text())
    devices = [s for s in pre["steps"] if s.get("registry_name") == "device_processor"]
    assert devices, pre["steps"]
    for s in devices:
        s["config"]["device"] = "cuda"
    pre_json.write_text(json.dumps(pre))
    cfg = json.loads((ckpt / "config.json").read_text())
    (ckpt / "config.json").write_text(json.dumps({**cfg, "device": "cuda"}))

    from backbones import LeRobotBackbone

    from lerobot_physvla.sim.scenes import LiberoScene

    scene = LiberoScene("libero_spatial", 0)
    policy = LeRobotBackbone(str(ckpt))
    scene.reset(0)
    policy.reset(0)
    actions = []
    for _ in range(3):
        a = policy.act(scene, scene.read())
        assert a.shape == (7,) and np.isfinite(a).all()
        actions.append(a)
        scene.step(np.clip(a, -1, 1))
    assert policy.policy.config.n_action_steps == 10  # chunked: the 3 actions come from one chunk


def replays_to_success(data, cfg_env, vec, seed: int) -> bool:
    """Replay a recorded episode's actions in a one-env vector env through lerobot-eval's observation path
    (preprocess_observation + the env's preprocessor), asserting at every frame the state and environment_state
    the dataset holds; whether the replay ends in success."""
    from lerobot.envs.utils import preprocess_observation

    env_pre, _ = cfg_env.get_env_processors()
    try:
        obs, _ = vec.reset(seed=[seed])
        success = False
        for t in range(data.num_frames):
            seen = env_pre(preprocess_observation(obs))
            frame = data[t]
            for key in ("observation.state", "observation.environment_state"):
                np.testing.assert_allclose(seen[key][0].numpy(), frame[key].numpy(), atol=1e-4,
                                           err_msg=f"{key} at frame {t}")
            obs, _, _, _, info = vec.step(frame["action"].numpy()[None].astype(np.float64))
            success = bool(info["is_success"][0]) if "is_success" in info else success
        return success
    finally:
        vec.close()


@pytest.mark.slow
def test_recorded_observations_are_what_lerobot_eval_feeds_the_policy(tmp_path):
    """The training data and lerobot-eval agree on what the policy sees: a recorded expert episode
    (init state 0, no DART noise), replayed action by action in `--env.type=libero_physvla
    --env.cameras=false` through lerobot-eval's observation path (preprocess_observation + the
    env's preprocessor), gives at every frame the observation lerobot-train reads from the dataset."""
    ds = tmp_path / "ds"
    rec = subprocess.run([sys.executable, str(ROOT / "backbones/record_dataset.py"), "--tasks", "0", "--seeds", "0",
                          "--dart-sigma", "0", "--workers", "1", "--out", str(ds)], capture_output=True, text=True,
                         cwd=ROOT)
    assert rec.returncode == 0, rec.stderr[-2000:]

    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_physvla.envs.libero_physvla import LiberoPhysVLAEnvConfig

    data = LeRobotDataset("local/alignment", root=ds)
    assert data.num_episodes == 1
    cfg_env = LiberoPhysVLAEnvConfig(task="libero_spatial", task_ids=[0], cameras=False)
    vec = cfg_env.create_envs(n_envs=1)["libero_spatial"][0]  # its first sub-env starts at init state 0
    assert replays_to_success(data, cfg_env, vec, seed=0)  # the replayed episode ends where the recorded one did


def test_the_committed_checkpoints_are_the_weights_the_published_table_ran():
    """backbones/checkpoints holds the GPU-trained ACT backbones (and the `_mid` siblings trained from
    them or beside them on this CPU): each one's weights are the ones every
    episode of eval/results/learned recorded for it, and the harness runs it (on the CPU) with no
    training here. A retrained or replaced file would fail the first assertion."""
    import hashlib

    from backbones import LeRobotBackbone

    from lerobot_physvla.sim.scenes import LiberoScene

    from store import Store

    ran_with = Store(ROOT / "eval/results/learned").meta["backbones"]
    names = sorted(p.name for p in train_backbones.COMMITTED.iterdir() if (p / "model.safetensors").exists()
                   and p.name not in train_backbones.SUITE_CHOICE)  # the other suites' ACTs: the test below
    assert {"act_single", "act_single_weak", "act_chunk", "act_chunk_weak"} <= set(names)
    assert set(train_backbones.SUITE_CHOICE) <= {p.name for p in train_backbones.COMMITTED.iterdir()}
    for name in names:
        ckpt = train_backbones.trained_or_committed(name, "/nonexistent")
        assert ckpt == train_backbones.COMMITTED / name
        sha = hashlib.sha256((ckpt / "model.safetensors").read_bytes()).hexdigest()
        assert ran_with[name] == {"policy_sha256": sha}, name
        recipe = json.loads((ckpt / "recipe.json").read_text())
        if name in train_backbones.MID_CHOICE:  # trained here: the continued run, or the recipe's CPU draw
            drawn = (train_backbones.CPU_DRAW.get(name, ("",))[0], *train_backbones.SMALLER_OF.get(name, ()),
                     *train_backbones.FEWER_OF.get(name, ()))
            assert recipe["recipe"] in (name, *drawn) and "CPU" in recipe["device"]
            continue
        assert recipe["recipe"] == train_backbones.SIBLINGS.get(name, (name,))[0] and "cuda" in recipe["device"]
    scene = LiberoScene("libero_spatial", 0)
    policy = LeRobotBackbone(str(train_backbones.COMMITTED / "act_single"))
    scene.reset(0)
    policy.reset(0)
    a = policy.act(scene, scene.read())
    assert a.shape == (7,) and np.isfinite(a).all() and np.abs(a).max() <= 1.5


def test_the_mid_sibling_rule_keeps_the_checkpoint_closest_to_40_percent():
    rates = {"x_mid@001000": 0.22, "x_mid@002000": 0.36, "x_mid@003000": 0.46, "x_cpufull@020000": 0.52}
    assert train_backbones.choose_mid(rates) == "x_mid@002000"
    assert train_backbones.choose_mid({"x_mid@002400": 0.50, "x_mid@001200": 0.30}) == "x_mid@001200"  # tie: earlier
    assert train_backbones.choose_mid({"x_mid@003000": 0.0}) == "x_mid@003000"


def test_the_kept_mid_siblings_are_the_ones_the_rule_chose_on_the_recorded_runs():
    """MID_CHOICE (which checkpoint each `_mid` sibling is) must be what choose_mid gives on the
    uncorrected results the learned_mid study recorded (every candidate, n = 50 each), not a hand
    pick; and the committed copy holds the weights those episodes ran."""
    import hashlib

    from store import Store, config_hash

    from lerobot_physvla.core.config import PhysVLAConfig

    data = Store(ROOT / "eval/results/learned_mid")
    uncorrected = config_hash(PhysVLAConfig.paper(mode="baseline").to_dict())
    assert set(train_backbones.MID_CHOICE) <= set(train_backbones.MID_SIBLINGS)
    for name in train_backbones.MID_SIBLINGS:
        run, step = train_backbones.MID_CHOICE.get(name, (None, None))
        continued, drawn = train_backbones.CONTINUED.get(name), train_backbones.CPU_DRAW.get(name)
        resumed = train_backbones.RESUMED_OF.get(name, ())
        prefixes = (([f"{name}@"] if continued else []) + ([f"{drawn[0]}_cpufull@"] if drawn else [])
                    + [f"{run}@" for run in resumed]
                    + [f"{small}@" for small in train_backbones.SMALLER_OF.get(name, ())]
                    + [f"{few}@" for few in train_backbones.FEWER_OF.get(name, ())])
        rate, sha = {}, {}
        for r in data.rows:
            cand = r["backbone"]
            if r["config"] == uncorrected and any(cand.startswith(p) for p in prefixes):
                rate.setdefault(cand, []).append(r["success"])
                sha[cand] = data.meta["backbones"][cand]["policy_sha256"]
        steps = ((continued[1] // continued[2] if continued else 0) + (len(drawn[1]) if drawn else 0)
                 + sum((train_backbones.RESUMED[r][2] - train_backbones.RESUMED[r][1]) // train_backbones.RESUMED[r][3] - 1
                       for r in resumed)
                 + sum(len(train_backbones.SMALLER[s][2]) for s in train_backbones.SMALLER_OF.get(name, ()))
                 + sum(len(train_backbones.FEWER[f][2]) for f in train_backbones.FEWER_OF.get(name, ())))
        assert len(rate) == steps and all(len(v) == 50 for v in rate.values()), name
        kept = train_backbones.choose_mid({c: float(np.mean(v)) for c, v in rate.items()})
        if run is None:  # the rule's pick is outside the band: no backbone of that name
            assert not 0.30 <= np.mean(rate[kept]) <= 0.50, name
            continue
        assert kept.rsplit("@", 1)[1] == f"{step:06d}" and (run == name) == kept.startswith(f"{name}@"), name
        committed = train_backbones.COMMITTED / name / "model.safetensors"
        assert hashlib.sha256(committed.read_bytes()).hexdigest() == sha[kept], name


def test_the_suite_rule_keeps_the_latest_strong_checkpoint_and_the_weak_one_nearest_35_percent():
    choose = train_backbones.choose_suite
    # strong: the latest in 60-95 %; weak: another in 20-50 %, nearest 35 %
    assert choose({2400: 0.10, 4800: 0.30, 7200: 0.40, 9600: 0.70, 12000: 0.80}) == (12000, 4800)
    # the final checkpoint above the band: the latest in it is strong
    assert choose({2400: 0.36, 4800: 0.62, 7200: 0.98}) == (4800, 2400)
    # none in the strong band: the final one; none in the weak band: no sibling
    assert choose({2400: 0.0, 4800: 0.10, 7200: 1.0}) == (7200, None)
    # a tie in distance from 35 %: the earlier step
    assert choose({1000: 0.45, 2000: 0.25, 3000: 0.9}) == (3000, 1000)
    # a weak sibling is never the strong checkpoint itself
    assert choose({1000: 0.40}) == (1000, None)
    with pytest.raises(ValueError):
        choose({})


def test_the_suite_paths_and_repo_id_follow_the_suite():
    assert train_backbones.suite_paths("libero_object") == ("outputs/datasets/physvla_libero_object",
                                                            "outputs/train/libero_object")
    assert train_backbones.suite_paths("libero_spatial") == (train_backbones.DATASET, "outputs/train")
    assert train_backbones.suite_paths("metaworld") == ("outputs/datasets/physvla_metaworld", "outputs/train/metaworld")
    cmd = train_backbones.command("act_chunk", "outputs/datasets/physvla_libero_goal", "outputs/train/libero_goal")
    assert "--dataset.repo_id=local/physvla_libero_goal" in cmd and "--output_dir=outputs/train/libero_goal/act_chunk" in cmd
    assert "--dataset.repo_id=local/physvla_libero_spatial" in train_backbones.command("act_chunk", train_backbones.DATASET,
                                                                                      "outputs/train")
    with pytest.raises(SystemExit, match="unknown suite"):
        train_backbones.suite_paths("libero_90")


# each suite's selection study (its results directory) and the episodes it ran per checkpoint
SELECTION = {"libero_object": ("suites_learned_select", 50), "libero_goal": ("learned_goal_ten_select", 30),
             "libero_10": ("learned_goal_ten_select", 30), "metaworld": ("learned_metaworld_select", 60),
             "so101_env": ("learned_so101_select", 50)}


def test_the_kept_suite_acts_are_the_ones_the_rule_chose_on_their_selection_block():
    """SUITE_CHOICE (which checkpoints are each suite's ACT backbones) must be what choose_suite gives on the
    uncorrected episodes its selection study recorded (every checkpoint; LIBERO-Object eval/results/
    suites_learned_select, n = 50; LIBERO-Goal and -10 eval/results/learned_goal_ten_select, n = 30; MetaWorld
    eval/results/learned_metaworld_select, n = 60; the GPU's longer runs, DEVICE_SELECTION), not a hand pick; and
    each committed copy holds the weights those episodes ran."""
    import hashlib

    from store import Store
    from study import Study, find

    checked = 0
    assert set(SELECTION) == set(train_backbones.SUITE_SHORT)
    runs = [(suite, recipe, *SELECTION[suite], train_backbones.CHECKPOINTS_PER_RUN)
            for suite in train_backbones.SUITE_SHORT for recipe in train_backbones.SUITE_RECIPES]
    runs += [(suite, recipe, *sel) for (suite, recipe), sel in train_backbones.DEVICE_SELECTION.items()]
    for suite, recipe, study, n, n_checkpoints in runs:
        short = train_backbones.SUITE_SHORT[suite]
        selection = Study(find(study))  # its `baseline`, in each block's scene (MetaWorld's has its own layout)
        uncorrected = {selection.config_hash("baseline", bl.scene) for bl in selection.blocks.values()}
        data = Store(ROOT / "eval/results" / study)
        rate, sha = {}, {}
        for r in data.rows:
            name, _, step = r["backbone"].partition("@")
            if r["config"] in uncorrected and name == f"{short}_{recipe}":
                rate.setdefault(int(step), []).append(r["success"])
                sha[int(step)] = data.meta["backbones"][r["backbone"]]["policy_sha256"]
        if not rate:  # this suite's ACTs are not trained yet: no backbone of theirs may be named
            assert not any(k in (f"{short}_{recipe}", f"{short}_{recipe}_weak") for k in train_backbones.SUITE_CHOICE)
            continue
        assert len(rate) == n_checkpoints and all(len(v) == n for v in rate.values()), (suite, recipe)
        strong, weak = train_backbones.choose_suite({s: float(np.mean(v)) for s, v in rate.items()})
        kept = {f"{short}_{recipe}": strong} | ({f"{short}_{recipe}_weak": weak} if weak is not None else {})
        for name, step in kept.items():
            assert train_backbones.SUITE_CHOICE[name] == (f"{suite}/{recipe}", step), name
            committed = train_backbones.COMMITTED / name / "model.safetensors"
            assert hashlib.sha256(committed.read_bytes()).hexdigest() == sha[step], name
            checked += 1
        if weak is None:
            assert f"{short}_{recipe}_weak" not in train_backbones.SUITE_CHOICE
    assert checked >= 2  # LIBERO-Object's two recipes at least


@pytest.mark.slow
def test_recorded_metaworld_observations_are_what_lerobot_eval_feeds_the_policy(tmp_path):
    """The same agreement on MetaWorld (issue: MetaWorld and the SO-101, backbones from their own teachers): a
    recorded episode of pick-place's own scripted policy (seed 100, no DART noise), replayed in `--env.type=
    metaworld_physvla --env.cameras=false` through lerobot-eval's observation path, gives at every frame the
    recorded agent_pos and object / target xyz, and ends in success; the dataset is MetaWorld's 4-D layout at 80 fps.
    A --camera-size on MetaWorld is refused before anything runs."""
    ds = tmp_path / "ds"
    rec = subprocess.run([sys.executable, str(ROOT / "backbones/record_dataset.py"), "--suite", "metaworld", "--tasks",
                          "0", "--seeds", "100", "--dart-sigma", "0", "--workers", "1", "--out", str(ds)],
                         capture_output=True, text=True, cwd=ROOT)
    assert rec.returncode == 0, rec.stderr[-2000:]
    info = json.loads((ds / "meta" / "info.json").read_text())
    assert info["fps"] == 80 and info["robot_type"] == "sawyer" and info["total_episodes"] == 1
    assert info["features"]["observation.state"]["shape"] == [4] and info["features"]["action"]["shape"] == [4]

    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_physvla.envs.metaworld_physvla import MetaworldPhysVLAEnvConfig

    data = LeRobotDataset("local/alignment_mw", root=ds)
    cfg_env = MetaworldPhysVLAEnvConfig(task="pick-place-v3", cameras=False)
    vec = cfg_env.create_envs(n_envs=1)["pick-place-v3"][0]
    assert replays_to_success(data, cfg_env, vec, seed=100)
    refused = subprocess.run([sys.executable, str(ROOT / "backbones/record_dataset.py"), "--suite", "metaworld",
                              "--camera-size", "64", "--out", str(tmp_path / "no")], capture_output=True, text=True,
                             cwd=ROOT)
    assert refused.returncode != 0 and "state-only" in refused.stderr and not (tmp_path / "no").exists()

    # an ACT trained on it (2 steps) runs in the harness on the MetaWorld scene: 4-D actions from its observation
    train = subprocess.run([sys.executable, str(ROOT / "backbones/train_backbones.py"), "act_chunk", "--dataset", str(ds),
                            "--out", str(tmp_path / "train"), "--steps", "2"], capture_output=True, text=True, cwd=ROOT)
    assert train.returncode == 0, train.stdout[-2000:] + train.stderr[-2000:]
    from backbones import LeRobotBackbone

    from lerobot_physvla.sim.metaworld_sim import MetaworldScene

    scene, policy = MetaworldScene(0), LeRobotBackbone(str(train_backbones.checkpoint("act_chunk", str(tmp_path / "train"))))
    scene.reset(100)
    policy.reset(100)
    for _ in range(3):
        a = policy.act(scene, scene.read())
        assert a.shape == (4,) and np.isfinite(a).all()
        scene.step(np.clip(a, -1, 1))


@pytest.mark.slow
def test_recorded_so101_observations_are_what_lerobot_eval_feeds_the_policy(tmp_path):
    """The same agreement on the SO-101 (issue: MetaWorld and the SO-101, backbones from their own teachers): a
    recorded episode of lerobot-env-so101's pick-and-place controller (seed 100, no DART noise), replayed in
    `--env.type=so101_physvla --env.random_block_position=true --env.action_scale=0.025` through lerobot-eval's
    observation path, gives at every frame the recorded agent_pos and block / goal xyz, and ends in the env's
    success; the dataset is the so101 4-D layout at 10 fps. An ACT trained on it (2 steps) acts in the harness."""
    ds = tmp_path / "ds"
    rec = subprocess.run([sys.executable, str(ROOT / "backbones/record_dataset.py"), "--suite", "so101_env", "--tasks",
                          "0", "--seeds", "100", "--dart-sigma", "0", "--workers", "1", "--out", str(ds)],
                         capture_output=True, text=True, cwd=ROOT)
    assert rec.returncode == 0, rec.stderr[-2000:]
    info = json.loads((ds / "meta" / "info.json").read_text())
    assert info["fps"] == 10 and info["robot_type"] == "so101" and info["total_episodes"] == 1
    assert info["features"]["observation.state"]["shape"] == [14] and info["features"]["action"]["shape"] == [4]

    from lerobot.datasets.lerobot_dataset import LeRobotDataset
    from lerobot.envs.utils import preprocess_observation

    from lerobot_physvla.envs.so101_physvla import SO101PhysVLAEnvConfig

    data = LeRobotDataset("local/alignment_so101", root=ds)
    cfg_env = SO101PhysVLAEnvConfig(task="SO101PickPlace-v0", action_scale=0.025, random_block_position=True)
    vec = cfg_env.create_envs(n_envs=1)["SO101PickPlace-v0"][0]
    env_pre, _ = cfg_env.get_env_processors()
    try:
        obs, _ = vec.reset(seed=[100])
        for t in range(data.num_frames):
            seen, frame = env_pre(preprocess_observation(obs)), data[t]
            for key in ("observation.state", "observation.environment_state"):
                np.testing.assert_allclose(seen[key][0].numpy(), frame[key].numpy(), atol=1e-4, err_msg=f"{key} at {t}")
            obs, _, terminated, _, step_info = vec.step(frame["action"].numpy()[None].astype(np.float64))
        assert terminated[0] and step_info["final_info"]["is_success"][0]
    finally:
        vec.close()

    train = subprocess.run([sys.executable, str(ROOT / "backbones/train_backbones.py"), "act_chunk", "--dataset", str(ds),
                            "--out", str(tmp_path / "train"), "--steps", "2"], capture_output=True, text=True, cwd=ROOT)
    assert train.returncode == 0, train.stdout[-2000:] + train.stderr[-2000:]
    from backbones import LeRobotBackbone

    from lerobot_physvla.sim.so101_env_sim import SO101EnvScene

    scene, policy = SO101EnvScene(), LeRobotBackbone(str(train_backbones.checkpoint("act_chunk", str(tmp_path / "train"))))
    scene.reset(100)
    policy.reset(100)
    for _ in range(3):
        a = policy.act(scene, scene.read())
        assert a.shape == (4,) and np.isfinite(a).all()
        scene.step(np.clip(a, [-1, -1, -1, 0], 1))
