"""`lerobot-physvla-replay`: what it prints and writes, and one-line errors that write nothing."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "replay"))
from replay_data import COLUMN_FEATURES, REPO_ID, column_episode, write_dataset  # noqa: E402

from lerobot_physvla.scripts.lerobot_physvla_replay import main  # noqa: E402

pytestmark = pytest.mark.slow  # subprocess console scripts / re-simulation



@pytest.fixture(scope="module")
def recorded_ds(tmp_path_factory):
    from lerobot_physvla.replay.record import record

    root = tmp_path_factory.mktemp("cli") / "ds"
    record(root, ["libero_spatial/0"], [10], REPO_ID, progress=False)
    return root


def test_offline_run_prints_the_summary_and_writes_everything(recorded_ds, tmp_path, capsys):
    out = tmp_path / "run"
    main([f"--dataset.root={recorded_ds}", f"--dataset.repo_id={REPO_ID}", f"--output_dir={out}",
          "--write_dataset=true", "--physvla.preset=paper"])
    printed = capsys.readouterr().out
    assert "1 episodes," in printed and "success 1/1" in printed and "frames changed (recorded actions):" in printed
    for name in ("report.md", "replay_summary.json", "replay_episodes.jsonl", "plots/episode_000000.png",
                 "dataset/meta/info.json"):
        assert (out / name).is_file(), name
    summary = json.loads((out / "replay_summary.json").read_text())
    assert summary["physvla_config"]["mode"] == "phys_el" and summary["dataset"]["episodes"] == 1
    rec = json.loads((out / "replay_episodes.jsonl").read_text().splitlines()[0])
    assert rec["r_el_p50"] is not None  # the exported state carries the dynamics: Branch B ran
    assert "plots/episode_000000.png" in (out / "report.md").read_text()


def _error(argv, capsys) -> str:
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("lerobot-physvla-replay: error: ") and "\n" not in err
    return err


def test_bad_input_is_one_line_and_writes_nothing(recorded_ds, tmp_path, capsys):
    out = tmp_path / "never"
    base = [f"--dataset.root={recorded_ds}", f"--output_dir={out}"]
    assert "out of range" in _error([*base, "--episodes=[3]"], capsys)
    assert "--physvla.nope: unknown" in _error([*base, "--physvla.nope=1"], capsys)
    assert "needs --policy.path" in _error([*base, "--mode=policy"], capsys)
    assert "--mode=warp: unknown" in _error([*base, "--mode=warp"], capsys)
    assert "use them with --mode=resim" in _error([*base, "--pose_bias_m=0.02"], capsys)
    assert "perception: dropout" in _error([*base, "--mode=resim", "--pose_dropout=1.5"], capsys)
    assert "does not exist" in _error([f"--dataset.root={tmp_path / 'none'}", f"--output_dir={out}"], capsys)
    cols = write_dataset(tmp_path / "cols", COLUMN_FEATURES, [column_episode(5)])
    assert "physvla.episode" in _error([f"--dataset.root={cols}", f"--output_dir={out}", "--mode=resim"], capsys)
    so = write_dataset(tmp_path / "so", COLUMN_FEATURES, [column_episode(5)], robot_type="koch")
    assert "robot type 'koch'" in _error([f"--dataset.root={so}", f"--output_dir={out}"], capsys)
    assert not out.exists()
    out.mkdir()
    assert "exists; choose a new one" in _error(base, capsys)
    assert list(out.iterdir()) == []


def test_resim_mode_reports_recorded_raw_and_corrected(recorded_ds, tmp_path, capsys):
    out = tmp_path / "resim"
    main([f"--dataset.root={recorded_ds}", f"--output_dir={out}", "--mode=resim", "--plots=0"])
    printed = capsys.readouterr().out
    assert "yes/yes/" in printed and "re-simulated success: raw 1/1" in printed
    summary = json.loads((out / "replay_summary.json").read_text())
    assert summary["max_state_divergence_m"] == 0.0


def test_console_script_is_installed():
    exe = Path(sys.executable).parent / "lerobot-physvla-replay"
    r = subprocess.run([str(exe), "--help"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "--dataset.root" in r.stdout
