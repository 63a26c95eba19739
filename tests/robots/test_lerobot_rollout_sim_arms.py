"""The real lerobot-rollout console script with the corrector on each simulated arm: a LeRobot ACT
policy (random weights: its gripper command hovers near 0, i.e. closed) for one second at 30 Hz,
the block 0.3-0.4 m from the gripper: with --policy.postprocess=physvla every gripper target the
servos receive is 'open' (the approach veto), and the arm's targets are the policy's own; without
the flag they close."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
ARMS = {  # arm: (robot type, block, target)
    "so101": ("physvla_sim_so101", "[0.1,0.3,0.02]", "[0.3,-0.2,0.0]"),
    "panda": ("physvla_sim_panda", "[0.3,0.4,0.02]", "[0.5,-0.2,0.0]"),
}

pytestmark = pytest.mark.slow  # subprocess console scripts / re-simulation


@pytest.mark.parametrize("arm", sorted(ARMS))
def test_lerobot_rollout_with_the_corrector_executes_the_corrected_targets(tmp_path, arm, random_policy):
    robot, block, target = ARMS[arm]
    policy = tmp_path / f"act_{arm}"
    random_policy(policy, inputs=arm)
    rollout = str(Path(sys.executable).parent / "lerobot-rollout")
    logs = {}
    for name, flags in (("corrected", ["--policy.postprocess=physvla", f"--physvla.arm={arm}",
                                       "--physvla.object_key=block", f"--physvla.target_xyz={target}"]), ("raw", [])):
        log = tmp_path / f"{name}.jsonl"
        r = subprocess.run([rollout, "--strategy.type=base", f"--robot.type={robot}", "--robot.blank_camera=true",
                            f"--robot.block_xyz={block}", f"--robot.action_log={log}",
                            f"--robot.calibration_dir={tmp_path}", f"--policy.path={policy}", "--duration=1", "--fps=30",
                            "--device=cpu", "--play_sounds=false", "--return_to_initial_position=false", *flags],
                           capture_output=True, text=True, timeout=300, cwd=tmp_path)
        assert r.returncode == 0, r.stderr[-3000:]
        logs[name] = [json.loads(line) for line in log.read_text().splitlines()]
        summary = [line for line in r.stderr.splitlines() if line.startswith("lerobot-physvla: ")]
        if name == "corrected":  # at exit, one line of what the corrector did
            n = len(logs[name])
            assert any(f"physvla: {n} ticks on arm '{arm}'" in line and f"gripper target changed on {n}," in line
                       for line in summary), r.stderr[-2000:]
        else:
            assert not summary
    assert len(logs["corrected"]) >= 10 and len(logs["raw"]) >= 10
    assert all(a["gripper.pos"] == 100.0 for a in logs["corrected"])
    assert max(a["gripper.pos"] for a in logs["raw"]) < 50.0  # the policy's own command: closing
