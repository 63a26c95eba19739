"""The real lerobot-rollout console script with real-time chunking (`--inference.type=rtc`) on the simulated
SO-101, with the corrector as its robot action step: the chunks come from a background thread, and what the
servos receive is still what the corrector made of each action.

lerobot 0.6.1 refuses RTC for ACT (the first test shows its message, unchanged by the plugin); the policies it
accepts all need hub weights, so the chunks come from a test-only RTC policy type
(tests/fixtures/rtc_chunk_policy: each chunk holds the arm still with the gripper closed)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "fixtures"
BLOCK, TARGET = "[0.1,0.3,0.02]", "[0.3,-0.2,0.0]"

pytestmark = pytest.mark.slow  # subprocess console scripts


def _rollout(tmp_path: Path, policy: Path, log: Path, *flags: str) -> subprocess.CompletedProcess:
    rollout = str(Path(sys.executable).parent / "lerobot-rollout")
    # tests/fixtures/rtc_site/sitecustomize.py registers the fixture's policy type at interpreter start
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(FIXTURES / "rtc_site"), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([rollout, "--strategy.type=base", "--robot.type=physvla_sim_so101", "--robot.blank_camera=true",
                           f"--robot.block_xyz={BLOCK}", f"--robot.action_log={log}", f"--robot.calibration_dir={tmp_path}",
                           f"--policy.path={policy}", "--duration=1.5", "--fps=30", "--device=cpu", "--play_sounds=false",
                           "--return_to_initial_position=false", *flags],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path, env=env)


CORRECTED = ("--policy.postprocess=physvla", "--physvla.arm=so101", "--physvla.object_key=block",
             f"--physvla.target_xyz={TARGET}")


def test_rtc_with_an_act_stops_with_lerobots_own_message(tmp_path, random_policy):
    policy = tmp_path / "act"
    random_policy(policy, inputs="so101")
    r = _rollout(tmp_path, policy, tmp_path / "log.jsonl", "--inference.type=rtc", *CORRECTED)
    assert "RTC inference is not supported by policy type 'act'" in r.stderr
    assert not (tmp_path / "log.jsonl").exists() or not (tmp_path / "log.jsonl").read_text().strip()  # nothing sent


def test_rtc_chunks_reach_the_servos_corrected(tmp_path):
    import torch  # noqa: F401 - the fixture's policy

    sys.path.insert(0, str(FIXTURES))
    from rtc_chunk_policy import RTCChunkStubConfig, RTCChunkStubPolicy

    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.processor.factory import make_default_pre_post_processors

    policy = tmp_path / "rtc_policy"
    cfg = RTCChunkStubConfig(device="cpu", input_features={"observation.state": PolicyFeature(FeatureType.STATE, (6,))},
                             output_features={"action": PolicyFeature(FeatureType.ACTION, (6,))})
    RTCChunkStubPolicy(cfg).save_pretrained(policy)
    for p in make_default_pre_post_processors(cfg, None, normalizer_device="cpu"):
        p.save_pretrained(policy)
    logs = {}
    for name, flags in (("corrected", CORRECTED), ("raw", ())):
        log = tmp_path / f"{name}.jsonl"
        r = _rollout(tmp_path, policy, log, "--inference.type=rtc", *flags)
        assert r.returncode == 0, r.stderr[-3000:]
        logs[name] = [json.loads(line) for line in log.read_text().splitlines()]
        summary = [line for line in r.stderr.splitlines() if line.startswith("lerobot-physvla: ")]
        if name == "corrected":  # at exit, one line of what the corrector did, counting every executed action
            n = len(logs[name])
            assert any(f"physvla: {n} ticks on arm 'so101'" in line and f"gripper target changed on {n}," in line
                       for line in summary), r.stderr[-2000:]
        else:
            assert not summary
    assert len(logs["corrected"]) >= 10 and len(logs["raw"]) >= 10  # chunks arrived from the engine's thread
    assert all(a["gripper.pos"] == 100.0 for a in logs["corrected"])  # the approach veto: open
    assert max(a["gripper.pos"] for a in logs["raw"]) < 50.0  # the policy's own command: closed
