"""What users saved before the layout moved keeps working (lerobot_physvla/_moved.py)."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from lerobot_physvla._moved import MOVED

ROOT = Path(__file__).resolve().parents[1]

# what a configuration saved before these fields existed holds for them (the paper's values: how it acted then):
# fixed distances, the release assist within its tolerance alone, no centre guide
BEFORE = dict(geometry="fixed", release_assist_error_k=0.0, centre_guide=False, centre_guide_trailing=True)
FIXTURE = ROOT / "tests/fixtures/postprocessor_v0_1"  # written by lerobot-physvla-config before the move


@pytest.mark.slow
def test_a_postprocessor_saved_before_the_move_loads_with_a_warning_naming_the_new_path():
    entry = json.loads((FIXTURE / "policy_postprocessor.json").read_text())["steps"][0]
    assert entry["class"] == "lerobot_physvla.lerobot_steps.PhysVLACorrectorStep"  # the old path
    probe = f"""
import sys, warnings
warnings.simplefilter("always")
from lerobot.processor import PolicyProcessorPipeline
from lerobot.processor.converters import policy_action_to_transition, transition_to_policy_action
assert not any(m.startswith("lerobot_physvla") for m in sys.modules)
with warnings.catch_warnings(record=True) as caught:
    p = PolicyProcessorPipeline.from_pretrained({str(FIXTURE)!r}, config_filename="policy_postprocessor.json",
        to_transition=policy_action_to_transition, to_output=transition_to_policy_action)
step = p.steps[-1]
from lerobot_physvla.processor.physvla_processor import PhysVLACorrectorStep
assert type(step) is PhysVLACorrectorStep
print(step.cfg.mode, step.cfg.cap)
print([str(w.message) for w in caught if issubclass(w.category, FutureWarning)])
"""
    r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300, cwd=FIXTURE)
    assert r.returncode == 0, r.stderr[-3000:]
    first, second = r.stdout.strip().splitlines()[-2:]
    assert first == "phys_el 0.05"
    assert "lerobot_physvla.lerobot_steps is deprecated" in second
    assert "lerobot_physvla.processor.physvla_processor" in second


@pytest.mark.parametrize("old", sorted(MOVED))
def test_every_old_module_path_forwards_to_its_new_home(old):
    sys.modules.pop(old, None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mod = importlib.import_module(old)
    new = importlib.import_module(MOVED[old][0])
    assert any(issubclass(w.category, FutureWarning) and MOVED[old][0] in str(w.message) for w in caught)
    public = [n for n in vars(new) if not n.startswith("_")]
    assert public, new
    assert all(getattr(mod, n) is getattr(new, n) for n in public)
    with pytest.raises(AttributeError, match="moved to"):
        getattr(mod, "no_such_name")


def test_old_names_that_moved_to_a_second_module_still_resolve():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from lerobot_physvla.lerobot_compat import as_physvla_env
        from lerobot_physvla.lerobot_plugin import activate, split_argv
        from lerobot_physvla.phase import phase_step
    from lerobot_physvla.core.branch_a import phase_step as new_phase_step
    from lerobot_physvla.envs.libero_physvla import as_physvla_env as new_env
    from lerobot_physvla.flags import split_argv as new_split
    from lerobot_physvla.plugin import activate as new_activate
    assert (as_physvla_env, activate, split_argv, phase_step) == (new_env, new_activate, new_split, new_phase_step)


def test_shipped_presets_name_the_new_class_path():
    for mode in ("baseline", "temporal", "phys", "phys_el"):
        steps = json.loads((ROOT / f"configs/{mode}/policy_postprocessor.json").read_text())["steps"]
        assert steps[-1]["class"] == "lerobot_physvla.processor.physvla_processor.PhysVLACorrectorStep"
        assert steps[-1]["config"]["config"]["mode"] == mode


def test_the_committed_preset_files_hold_the_presets_of_this_code():
    """configs/preset_<name> is what a user downloads to get a preset: it must be
    PRESETS[name] field for field (regenerate with lerobot-physvla-config --write-presets)."""
    from lerobot_physvla.core.config import PRESETS, PhysVLAConfig

    for name, preset in PRESETS.items():
        steps = json.loads((ROOT / f"configs/preset_{name}/policy_postprocessor.json").read_text())
        assert PhysVLAConfig.from_dict(steps["steps"][-1]["config"]["config"]) == preset, name


def test_pipelines_saved_before_the_defaults_changed_load_through_lerobot():
    """lerobot's own loaders rebuild the saved steps (tests/fixtures/saved_before_0_2) with the same
    configurations they were saved with (their distances fixed: geometry came later; the release assist within its
    tolerance alone: release_assist_error_k came later; no centre guide, approach pull or carry: they joined the
    default later)."""
    from lerobot.processor import PolicyProcessorPipeline, RobotProcessorPipeline
    from lerobot.processor.converters import (policy_action_to_transition, robot_action_observation_to_transition,
                                              transition_to_policy_action, transition_to_robot_action)

    from lerobot_physvla.core.config import BEFORE_HOLD, BEFORE_PULL, PRESETS, PhysVLAConfig

    saved = ROOT / "tests/fixtures/saved_before_0_2"
    for name in ("default", "smooth", "paper"):
        p = PolicyProcessorPipeline.from_pretrained(saved / f"preset_{name}", config_filename="policy_postprocessor.json",
                                                    to_transition=policy_action_to_transition,
                                                    to_output=transition_to_policy_action)
        then = PRESETS[name].replace(**BEFORE, **({**BEFORE_PULL, **BEFORE_HOLD} if name == "default" else {}))
        assert p.steps[-1].cfg == then, name
    r = RobotProcessorPipeline.from_pretrained(saved / "robot_arm_so101", config_filename="physvla_robot_processor.json",
                                               to_transition=robot_action_observation_to_transition,
                                               to_output=transition_to_robot_action)
    assert PhysVLAConfig.from_dict(r.steps[-1].config) == PRESETS["arm"].replace(**BEFORE)
    assert r.steps[-1].arm == "so101"
