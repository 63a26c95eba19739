"""The real `lerobot-eval` console script, in subprocesses, with policies made by lerobot's factory."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.state import PhysState

BIN = Path(sys.executable).parent
ROOT = Path(__file__).resolve().parents[2]
COMMON = ["--env.task=libero_spatial", "--env.task_ids=[0]", "--policy.device=cpu"]

pytestmark = pytest.mark.slow  # subprocess console scripts / re-simulation


def run(args: list[str], env_extra: dict | None = None, timeout: int = 600) -> subprocess.CompletedProcess:
    env = {**os.environ, **(env_extra or {})}
    return subprocess.run(args, capture_output=True, text=True, timeout=timeout, env=env, stdin=subprocess.DEVNULL)


@pytest.fixture(scope="module")
def policies(tmp_path_factory, random_policy):
    d = tmp_path_factory.mktemp("policies")
    out = {}
    for inputs in ("state", "image"):
        random_policy(d / inputs, inputs=inputs)  # in process: lerobot's factory, as the script does
        out[inputs] = d / inputs
    return out


def _eval(policy, out_dir, extra, env_extra=None, exe="lerobot-eval"):
    r = run([str(BIN / exe), f"--policy.path={policy}", f"--output_dir={out_dir}", *COMMON, *extra], env_extra)
    assert r.returncode == 0, r.stderr[-4000:]
    return r


def test_corrected_state_only_run_executes_exactly_what_the_corrector_says(policies, tmp_path):
    out = tmp_path / "corrected"
    # two rollout batches: the recorder compacts the first between the rollouts (the eval hook's end_batch)
    state_only = ["--env.type=libero_physvla", "--env.cameras=false", "--eval.n_episodes=4",
                  "--eval.batch_size=2", "--env.episode_length=12"]
    r = _eval(policies["state"], out, [*state_only, "--policy.postprocess=physvla", "--physvla.preset=paper",
                                       "--physvla.gripper_rule=veto", "--physvla.chunk_phase_caps=0,0.05,0,1"],
              {"PHYSVLA_SAVE_STATES": "1"})
    # the summary table is printed and the report links a plot per episode
    assert "4 episodes, 48 frames, success 0/4" in r.stdout and "corrector overhead per env-step" in r.stdout
    report = (out / "physvla_report.md").read_text()
    for k in range(4):
        assert f"physvla_plots/episode_{k:04d}.png" in report and (out / f"physvla_plots/episode_{k:04d}.png").is_file()
    info = json.loads((out / "eval_info.json").read_text())
    assert info["overall"]["n_episodes"] == 4
    diag = json.loads((out / "physvla_diagnostics.json").read_text())
    assert diag["episodes"] == 4 and diag["physvla_config"]["gripper_rule"] == "veto"
    # the random ACT executes its chunks (n_action_steps 10): the chunk caps are the caps it was corrected with
    assert diag["physvla_config"]["phase_caps"] == [0, 0.05, 0, 1] and diag["physvla_config"]["chunk_phase_caps"] == []
    assert diag["passthrough"] == {} and diag["steps"] == 48
    episodes = [json.loads(line) for line in (out / "physvla_episodes.jsonl").read_text().splitlines()]
    npz = np.load(out / "physvla_states.npz")
    cfg = PhysVLAConfig.from_dict(diag["physvla_config"])
    for k, ep in enumerate(episodes):
        states, raw, corrected = npz[f"ep{k}_states"], npz[f"ep{k}_raw"], npz[f"ep{k}_corrected"]
        # replay this env's episode through a fresh single-env corrector: same output, step by step
        c = Corrector(cfg)
        offline = np.stack([c(raw[t : t + 1], PhysState.unpack(states[t]))[0] for t in range(len(raw))])
        np.testing.assert_allclose(corrected, offline, rtol=0, atol=1e-12)
        assert np.abs(corrected - raw).max() > 0  # the corrector did act
        # what the simulator executed (echoed by the env one step later) is the corrected action
        executed = [(t, a) for t, a in enumerate(ep["executed_actions"]) if a is not None]
        assert len(executed) == len(raw) - 1
        for t, a in executed:
            np.testing.assert_allclose(a, corrected[t], atol=1e-6)


def test_pose_faults_on_the_state_export_reach_the_corrector_through_the_real_console_script(policies, tmp_path):
    out = tmp_path / "late"
    r = _eval(policies["state"], out, ["--env.type=libero_physvla", "--env.cameras=false", "--eval.n_episodes=2",
                                       "--eval.batch_size=2", "--env.episode_length=12", "--env.pose_lag_steps=2",
                                       "--env.pose_bias_m=0.02", "--env.pose_noise_m=0.01", "--policy.postprocess=physvla",
                                       "--physvla.pose_error_m=0.02", "--physvla.pose_noise_m=0.01"],
              {"PHYSVLA_SAVE_STATES": "1"})
    diag = json.loads((out / "physvla_diagnostics.json").read_text())
    # lag 2: no pose has arrived in each episode's first 2 steps; every later one is 2 steps old, within the bound
    assert diag["passthrough"] == {"missing_pose": 4} and diag["steps"] == 24
    assert diag["physvla_config"]["pose_error_m"] == 0.02 and diag["physvla_config"]["pose_noise_m"] == 0.01
    assert "missing_pose" in r.stdout + r.stderr
    # the corrector filtered the noisy poses it was given (core/pose_filter.py): a fresh one replays the run, and its
    # object distance differs from the unfiltered poses' on every step after the first with a pose
    npz = np.load(out / "physvla_states.npz")
    cfg = PhysVLAConfig.from_dict(diag["physvla_config"])
    for k in range(2):
        states, raw, corrected = npz[f"ep{k}_states"], npz[f"ep{k}_raw"], npz[f"ep{k}_corrected"]
        filtered, plain = Corrector(cfg), Corrector(cfg.replace(pose_noise_m=0.0))
        d_f, d_p, outs = [], [], []
        for t in range(len(raw)):
            st = PhysState.unpack(states[t])
            outs.append(filtered(raw[t : t + 1], st)[0])
            plain(raw[t : t + 1], st)
            d_f.append(filtered.last.d_obj_xy[0])
            d_p.append(plain.last.d_obj_xy[0])
        np.testing.assert_allclose(corrected, np.stack(outs), rtol=0, atol=1e-12)
        assert np.isnan(d_f[:2]).all() and np.all(np.abs(np.subtract(d_f[3:], d_p[3:])) > 1e-9)


def test_a_goal_outside_the_model_is_one_row_per_episode_with_its_task_and_its_reason(policies, tmp_path):
    """LIBERO-Goal tasks 0 ("open the middle drawer") and 7 ("turn on the stove") have no On / In predicate. Run
    through the project's own console script, lerobot-physvla-eval, which takes lerobot-eval's arguments."""
    out = tmp_path / "goal"
    r = _eval(policies["state"], out, ["--env.type=libero_physvla", "--env.cameras=false", "--env.task=libero_goal",
                                       "--env.task_ids=[0,7]", "--eval.n_episodes=1", "--eval.batch_size=1",
                                       "--env.episode_length=12", "--policy.postprocess=physvla",
                                       "--physvla.mode=phys"], exe="lerobot-physvla-eval")
    episodes = [json.loads(line) for line in (out / "physvla_episodes.jsonl").read_text().splitlines()]
    assert [(e["task_id"], e["steps"], e["passthrough"]) for e in episodes] == [
        (0, 12, {"unsupported_goal": 12}), (7, 12, {"unsupported_goal": 12})]
    diag = json.loads((out / "physvla_diagnostics.json").read_text())
    assert diag["episodes"] == 2 and diag["passthrough"] == {"unsupported_goal": 24}
    assert diag["physvla_config"]["mode"] == "phys"  # lerobot-eval's arguments and the --physvla flags, as given
    assert "pass-throughs: unsupported_goal 24" in r.stdout  # the table's line
    assert "(pass-throughs: unsupported_goal 24)" in r.stderr  # and the log's, the same count
    assert "open(wooden_cabinet_1_middle_region) has no On / In(object, target) predicate" in r.stderr


def test_flag_absent_or_none_is_plain_lerobot_and_physvla_changes_the_rollout(policies, tmp_path):
    cam = ["--env.type=libero", "--eval.n_episodes=1", "--eval.batch_size=1", "--env.episode_length=6"]
    _eval(policies["image"], tmp_path / "plain", cam, {"PHYSVLA_DISABLE": "1"})
    _eval(policies["image"], tmp_path / "none", [*cam, "--policy.postprocess=none"])
    # temporal mode: a correction large enough to show in 6 rendered frames (phys_el changes <1 mm here)
    r = _eval(policies["image"], tmp_path / "phys", [*cam, "--policy.postprocess=physvla", "--physvla.mode=temporal"])
    video = "videos/libero_spatial_0/eval_episode_0.mp4"
    plain = (tmp_path / "plain" / video).read_bytes()
    assert (tmp_path / "none" / video).read_bytes() == plain  # bit-identical rollout
    assert (tmp_path / "phys" / video).read_bytes() != plain  # the same check sees a corrected rollout
    assert not (tmp_path / "none" / "physvla_diagnostics.json").exists()
    assert (tmp_path / "phys" / "physvla_diagnostics.json").exists()
    assert "physvla: diagnostics in" in r.stdout


def test_a_bad_flag_stops_the_real_console_script_with_one_line(tmp_path):
    """The plugin reads the flags at lerobot's plugin import; each message: tests/scripts/test_lerobot_physvla_eval.py."""
    r = run([str(BIN / "lerobot-eval"), "--env.type=libero", *COMMON, "--policy.postprocess=physvla",
             "--physvla.mode=turbo"])
    assert r.returncode == 2
    errors = [line for line in r.stderr.splitlines() if line.startswith("lerobot-physvla: error:")]
    assert len(errors) == 1 and "unknown mode 'turbo'" in errors[0], r.stderr[-2000:]


def test_a_libero_pro_suite_runs_under_plain_libero_and_its_unmodelled_goal_passes_through(policies, tmp_path):
    """`--env.type=libero` (cameras on) with --policy.postprocess=physvla becomes libero_physvla, which builds
    LIBERO-PRO's libero_goal_swap (sim/libero_pro.py); its task 0 keeps the base's "open the middle drawer": counted
    as unsupported_goal, every step."""
    out = tmp_path / "pro"
    r = _eval(policies["image"], out, ["--env.type=libero", "--env.task=libero_goal_swap", "--env.task_ids=[0]",
                                       "--eval.n_episodes=1", "--eval.batch_size=1", "--env.episode_length=6",
                                       "--policy.postprocess=physvla"])
    assert "suite=libero_goal_swap | task_id=0" in r.stdout
    info = json.loads((out / "eval_info.json").read_text())
    assert info["per_group"]["libero_goal_swap"]["n_episodes"] == 1
    diag = json.loads((out / "physvla_diagnostics.json").read_text())
    assert diag["passthrough"] == {"unsupported_goal": 6}
    assert "open(wooden_cabinet_1_middle_region) has no On / In(object, target) predicate" in r.stderr
