"""eval/trace_episode.py: one study episode step by step, the same episode the harness records."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "eval"))
import harness  # noqa: E402
import trace_episode as trace_tool  # noqa: E402
from study import Study  # noqa: E402

STUDY = """
[backbones]
premature = {expert = {premature_close = 1.0}}
[configs]
baseline = {mode = "baseline"}
default = {preset = "default"}
[blocks]
b = {scene = "libero_spatial", tasks = [0, 0], seeds = [3, 4], backbones = ["premature"]}
"""


@pytest.fixture
def study(tmp_path):
    f = tmp_path / "t.toml"
    f.write_text(STUDY)
    return Study(f)


def test_set_values_are_literals_and_a_pair_without_equals_is_refused():
    assert trace_tool.overrides(["centre_guide=false", "veto_height_m=0.02", "preset=smooth"]) == {
        "centre_guide": False, "veto_height_m": 0.02, "preset": "smooth"}
    with pytest.raises(SystemExit, match="FIELD=VALUE"):
        trace_tool.overrides(["centre_guide"])


def test_only_the_blocks_episodes_and_real_fields_are_traced(study):
    unit = trace_tool.unit_of(study, "b", "premature", "default", 0, 4, {})
    assert (unit.first_seed, unit.episodes, unit.scene) == (4, 1, "libero_spatial")
    assert unit.config_name == study.config_hash("default", "libero_spatial")  # the study's own episode
    changed = trace_tool.unit_of(study, "b", "premature", "default", 0, 4, {"centre_guide": False})
    assert changed.config["centre_guide"] is False and changed.config_name != unit.config_name
    with pytest.raises(SystemExit, match="not one of its episodes"):
        trace_tool.unit_of(study, "b", "premature", "default", 0, 45, {})  # never a held-out init state
    with pytest.raises(SystemExit, match="not PhysVLAConfig fields"):
        trace_tool.unit_of(study, "b", "premature", "default", 0, 3, {"veto_hieght_m": 0.0})
    with pytest.raises(SystemExit, match="no block"):
        trace_tool.unit_of(study, "nope", "premature", "default", 0, 3, {})


def test_why_tells_clipping_from_the_correctors_own_change():
    p = trace_tool.Printer(grip=6, every=5, low=-1.0, high=1.0, gripper_open=-1.0)
    raw = np.array([1.3, 0.0, -0.2, 0, 0, 0, 1.0])
    assert p.why(raw, np.clip(raw, -1, 1), 0) == "clip"
    assert p.why(np.clip(raw, -1, 1), np.clip(raw, -1, 1), 0) == ""
    held = np.clip(raw, -1, 1)
    held[6] = -1.0
    assert p.why(raw, held, 0) == "gripper held open"
    moved = np.clip(raw, -1, 1)
    moved[1] = 0.4
    assert p.why(raw, moved, 0) == "xyz"
    assert p.why(raw, np.clip(raw, -1, 1), 3).startswith("passed through: ")


@pytest.mark.slow
def test_the_trace_is_the_harness_episode_and_prints_the_veto(study, capsys):
    """The scripted expert that closes during its approach: under the default the trace shows the close held open,
    and its record is the one the harness's unit gives for that episode."""
    unit = trace_tool.unit_of(study, "b", "premature", "default", 0, 3, {})
    rec = trace_tool.trace(study, unit, every=50)
    out = capsys.readouterr().out
    assert "gripper held open" in out
    assert any(line.split()[:2] == ["step", "phase"] for line in out.splitlines())  # the table's header
    ref = harness.compute_unit(unit)["records"][0]
    for k in ("success", "steps", "changed_fraction", "change_norm", "veto_fire_rate"):
        assert rec[k] == ref[k], k


def test_a_printed_step_gives_the_objects_distance_from_the_target(capsys):
    """The `tgt` column: the object's horizontal distance from the target, cm (a bowl set down off its plate)."""
    from types import SimpleNamespace

    p = trace_tool.Printer(grip=6, every=1, low=-1.0, high=1.0, gripper_open=-1.0)
    st = SimpleNamespace(eef_pos=np.array([[0.1, 0.0, 0.95]]), obj_pos=np.array([[0.1, 0.0, 0.9]]),
                         target_pos=np.array([[0.13, 0.04, 0.9]]))
    d = SimpleNamespace(phase=np.array([2]), status=np.array([0]), d_obj_xy=np.array([0.0]), lift=np.array([0.02]))
    a = np.zeros((1, 7))
    p(10, st, a, a, d)
    head, row = capsys.readouterr().out.splitlines()
    assert head.split()[:6] == ["step", "phase", "d_xy", "h", "lift", "tgt"]
    assert row.split()[:6] == ["10", "2", "0.0", "5.0", "2.0", "5.0"]  # 3-4-5 cm from the plate
