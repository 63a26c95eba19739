"""eval/lerobot_eval_cell.py: a study cell again through lerobot-eval, paired with the harness's episodes."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "eval"))
import lerobot_eval_cell as cell  # noqa: E402
from store import Store, config_hash  # noqa: E402
from study import Study, find  # noqa: E402

from lerobot_physvla.flags import build_config, split_argv  # noqa: E402


@pytest.fixture(scope="module")
def study():
    return Study(find("camera_libero_pro"))


@pytest.mark.parametrize("config", ["baseline", "shipped default"])
def test_the_command_s_flags_give_the_study_s_configuration(study, config):
    argv = cell.command(study, "original", "object_act_camera_weak", config, Path("outputs/x"))
    post, overrides, rest = split_argv(argv[1:])
    assert post == "physvla"
    assert config_hash(build_config(overrides).to_dict()) == study.config_hash(config, "libero_object+agentview64")
    assert "--env.task=libero_object" in rest and "--env.observation_height=64" in rest
    assert "--env.first_init_state=30" in rest and "--eval.n_episodes=5" in rest
    assert "--env.task_ids=[0,1,2,3,4,5,6,7,8,9]" in rest


def test_a_state_scene_or_a_task_outside_the_block_is_refused(study):
    with pytest.raises(SystemExit, match="not a camera scene"):
        cell.scene_args("libero_object")
    with pytest.raises(SystemExit, match="not \\[12\\]"):
        cell.command(study, "original", "object_act_camera_weak", "baseline", Path("x"), tasks=[12])


def _fake_run(out: Path, config: dict, episodes: list[dict]) -> None:
    out.mkdir(parents=True)
    (out / "physvla_diagnostics.json").write_text(json.dumps({"physvla_config": config}))
    (out / "physvla_episodes.jsonl").write_text("\n".join(json.dumps(e) for e in episodes))


def test_episode_k_is_paired_with_the_stored_episode_of_init_state_first_plus_k(study, tmp_path, monkeypatch):
    monkeypatch.setattr(cell, "ROOT", tmp_path)
    scene = "libero_object+agentview64"
    stored = {(r["task_id"], r["seed"]): r for r in Store(study.data[0]).rows
              if r["backbone"] == "object_act_camera_weak" and r["scene"] == scene
              and r["config"] == study.config_hash("shipped default", scene)}
    episodes = [{"task_id": 3, "episode": k, "steps": 100 + k, "success": k % 2 == 0, "corrected_fraction": 0.5}
                for k in range(2)]
    _fake_run(tmp_path / "run", study.config("shipped default", scene), episodes)
    rows = cell.pairs(study, "original", "object_act_camera_weak", "shipped default", Path("run"))
    assert [(r["task_id"], r["seed"]) for r in rows] == [(3, 30), (3, 31)]
    for r in rows:
        h = stored[(3, r["seed"])]
        assert r["harness"] == {"success": h["success"], "steps": h["steps"], "changed": h["changed_fraction"]}
    assert [r["lerobot_eval"]["steps"] for r in rows] == [100, 101]

    # lerobot-eval ran another configuration than the study's: refused, not paired
    _fake_run(tmp_path / "other", study.config("baseline", scene), episodes)
    with pytest.raises(SystemExit, match="the study's is"):
        cell.pairs(study, "original", "object_act_camera_weak", "shipped default", Path("other"))


def test_the_committed_cell_is_its_records_report_and_every_episode_has_its_harness_pair(study):
    """eval/results/lerobot_eval_cell: the README is report(records.json); the records hold the whole cell (every
    configuration x task x init state once), each lerobot-eval episode beside the harness episode the study stored."""
    d = ROOT / "eval" / "results" / "lerobot_eval_cell"
    records = json.loads((d / "records.json").read_text())
    assert (d / "README.md").read_text() == cell.report(records)
    assert records["study"] == study.name
    b = study.blocks[records["block"]]
    rows = records["pairs"]
    want = {(c, t, s) for c in records["configs"] for t in b.tasks for s in b.seeds}
    assert len(rows) == len(want) == 2 * 50 and {(r["config"], r["task_id"], r["seed"]) for r in rows} == want
    for config in records["configs"]:
        h = study.config_hash(config, b.scene)
        stored = {(r["task_id"], r["seed"]): r for r in Store(study.data[0]).rows
                  if r["backbone"] == records["backbone"] and r["scene"] == b.scene and r["config"] == h}
        for r in rows:
            if r["config"] == config:
                s = stored[(r["task_id"], r["seed"])]
                assert r["harness"] == {"success": s["success"], "steps": s["steps"], "changed": s["changed_fraction"]}
