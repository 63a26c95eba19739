import pytest

from lerobot_physvla.core.config import BEFORE_HOLD, BEFORE_PULL, FETCH_4D, LIBERO_OSC_POSE, ActionLayout, PhysVLAConfig

# what a configuration saved before these fields existed holds for them (the paper's values: how it acted then):
# fixed distances, the release assist within its tolerance alone, no centre guide
BEFORE = dict(geometry="fixed", release_assist_error_k=0.0, centre_guide=False, centre_guide_trailing=True)


def test_the_one_constructor_is_what_the_flag_applies():
    """PhysVLAConfig() is the shipped default: what --policy.postprocess=physvla applies (no other flag), what
    the corrector step holds unconfigured, and the `default` preset; the paper's main text is
    PhysVLAConfig.paper(), which departs from it in exactly PAPER's fields."""
    from lerobot_physvla.core.config import DEFAULT_PRESET, PAPER, PRESETS
    from lerobot_physvla.flags import build_config, split_argv
    from lerobot_physvla.processor.physvla_processor import PhysVLACorrectorStep

    _, overrides, _ = split_argv(["--policy.postprocess=physvla", "--env.type=libero"])
    assert PhysVLAConfig() == build_config(overrides) == PRESETS[DEFAULT_PRESET] == PhysVLACorrectorStep().cfg
    default, paper = PhysVLAConfig().to_dict(), PhysVLAConfig.paper().to_dict()
    assert {k for k in default if default[k] != paper[k]} == set(PAPER)


def test_configurations_saved_before_load_as_they_were():
    """Files saved by earlier versions: a 0.1 postprocessor (most fields unknown then: they take the
    paper's values, what they meant), the presets and an arm's robot processor as saved before the
    configuration's defaults became the shipped default (tests/fixtures/saved_before_0_2): each is the preset as it
    stood then, its distances fixed (geometry came later) and the release assist judging within its tolerance alone
    (release_assist_error_k came later), no centre guide, no approach pull or carry (they joined the default later)."""
    import json
    from pathlib import Path

    from lerobot_physvla.core.config import PRESETS

    fixtures = Path(__file__).resolve().parents[1] / "fixtures"
    old = json.loads((fixtures / "postprocessor_v0_1/policy_postprocessor.json").read_text())
    assert PhysVLAConfig.from_dict(old["steps"][0]["config"]["config"]) == PhysVLAConfig.paper()
    for name in ("default", "smooth", "paper"):
        saved = json.loads((fixtures / f"saved_before_0_2/preset_{name}/policy_postprocessor.json").read_text())
        then = PRESETS[name].replace(**BEFORE, **({**BEFORE_PULL, **BEFORE_HOLD} if name == "default" else {}))
        assert PhysVLAConfig.from_dict(saved["steps"][-1]["config"]["config"]) == then, name
    robot = json.loads((fixtures / "saved_before_0_2/robot_arm_so101/physvla_robot_processor.json").read_text())
    step = robot["steps"][-1]
    assert step["class"].endswith("PhysVLARobotActionStep") and step["config"]["arm"] == "so101"
    assert PhysVLAConfig.from_dict(step["config"]["config"]) == PRESETS["arm"].replace(**BEFORE)


def test_the_papers_values():
    c = PhysVLAConfig.paper()
    assert (c.cap, c.delta_grasp_m, c.beta, c.lift_bias_m, c.alpha_transport, c.d_thresh_m) == (
        0.05, 0.06, 0.5, 0.02, 0.92, 0.08
    )
    assert c.h_lift_m == 0.02 and c.eps_nm == 0.05 and c.alpha_temporal == 0.85
    assert c.action_layout is LIBERO_OSC_POSE


@pytest.mark.parametrize(
    "field,value",
    [("mode", "turbo"), ("el_mode", "hard"), ("weighting", "cartesian"), ("gripper_rule", "x"),
     ("chunk", "last"), ("layout", "ur5"), ("cap", 1.5), ("beta", -0.1), ("d_thresh_m", 0.0)],
)
def test_bad_values_are_rejected_with_the_choices(field, value):
    with pytest.raises(ValueError, match=field):
        PhysVLAConfig.paper(**{field: value})


def test_dict_round_trip_with_custom_layout():
    lay = ActionLayout(dim=5, pos=(1, 2, 3), gripper=0, metres_per_unit=0.1, gripper_open=1.0)
    c = PhysVLAConfig.paper(mode="phys", layout=lay, grasp_offset_m=(0.0, 0.01, 0.02))
    back = PhysVLAConfig.from_dict(c.to_dict())
    assert back == c and back.action_layout == lay
    with pytest.raises(ValueError, match="unknown config keys"):
        PhysVLAConfig.from_dict({"mdoe": "phys"})


def test_layout_validation():
    assert FETCH_4D.gripper == 3 and FETCH_4D.gripper_open == 1.0
    with pytest.raises(ValueError):
        ActionLayout(dim=3, pos=(0, 1, 3))
    with pytest.raises(ValueError):
        ActionLayout(dim=4, pos=(0, 1, 2), gripper=2)


def test_presets_follow_the_paper_and_the_default_is_built_from_the_options():
    from lerobot_physvla.core.config import DEFAULT_PRESET, PRESETS, preset

    assert PRESETS["paper"] == PhysVLAConfig.paper(mode="phys_el")  # main text: eq. 2, c = 0.05
    assert PRESETS["paper_alg1"].cap == 1.0 and PRESETS["paper_alg1"].mode == "phys_el"
    assert preset("paper", mode="phys") == PhysVLAConfig.paper(mode="phys")
    assert DEFAULT_PRESET in PRESETS
    # smooth: the default before the approach pull, the carry and the held close joined it, and the low-pass, nothing
    # else changed
    assert PRESETS["smooth"].replace(lowpass="off", lowpass_space="action", lowpass_alpha_max=0.6, lowpass_rough="ema",
                                     lowpass_phases=PhysVLAConfig.paper().lowpass_phases) == PRESETS["default"].replace(
                                         **BEFORE_PULL, **BEFORE_HOLD)
    # the default: the approach pull and the carry with the authority they need (docs/decisions/36-shift-shipped.md);
    # `shift` is its former name
    d = PRESETS["default"]
    assert (d.approach_pull_m, d.approach_pull_heading_u, d.carry_far_m, d.carry_clear_m) == (0.10, 0.3, 0.10, 0.05)
    assert (d.phase_caps, d.alpha_transport, d.lift_bias_m) == ((1.0, 1.0, 1.0, 1.0), 0.0, 0.0)
    assert PRESETS["shift"] == d and PhysVLAConfig() == d
    # and the held close (docs/decisions/39-hold-to-top.md): on in the default alone
    assert (d.veto_hold_to_top, d.lift_assist_needs_close) == (True, True)
    assert all(not (PRESETS[n].veto_hold_to_top or PRESETS[n].lift_assist_needs_close) for n in ("smooth", "arm", "paper"))
    assert PRESETS["smooth"].lowpass_mask == (True, True, False, True)  # none while an object is carried
    with pytest.raises(ValueError, match="unknown preset"):
        preset("turbo")


@pytest.mark.parametrize("bad", [{"phase_caps": (0.1, 0.2)}, {"phase_caps": (0, 0, 0, 2)},
                                 {"lowpass_phases": "approach,lunch"}, {"lowpass_alpha_max": 1.0},
                                 {"lowpass_rough_lo": 0.3, "lowpass_rough_hi": 0.2}, {"place_rule": "throw"},
                                 {"phase_ref": "elbow"}, {"veto_height_m": -0.1},
                                 {"veto_reach_m": -0.1}, {"chunk_phase_caps": (0, 0.05)},
                                 {"chunk_phase_caps": (0, -0.05, 0, 1)}, {"lowpass_rough": "mean"},
                                 {"lowpass_lag": "lead"}, {"lift_assist_u": -0.5},
                                 {"lift_assist_u": 2.0, "phase_caps": (0, 1, 0, 1)},
                                 {"rim_guide_m": -0.01, "phase_caps": (1, 1, 0, 1)},
                                 {"rim_guide_m": 0.06, "phase_caps": (1, 1, 0, 1)}])
def test_bad_options_are_rejected(bad):
    with pytest.raises(ValueError):
        PhysVLAConfig.paper(**bad)


def test_the_lift_assist_is_refused_where_it_could_not_act_and_says_what_to_set():
    """It raises a delta layout's z command with the grasp phase's authority: an absolute layout, or a
    grasp authority of 0 (the shipped default's phase_caps), would leave it silently inert."""
    from lerobot_physvla.core.config import ActionLayout

    with pytest.raises(ValueError, match="phase_caps"):
        PhysVLAConfig.paper(lift_assist_u=0.5, phase_caps=(0.0, 0.0, 0.0, 1.0))
    absolute = ActionLayout(dim=4, pos=(0, 1, 2), gripper=3, absolute=True)
    with pytest.raises(ValueError, match="absolute"):
        PhysVLAConfig.paper(lift_assist_u=0.5, phase_caps=(0.0, 1.0, 0.0, 1.0), layout=absolute)
    assert PhysVLAConfig.paper(lift_assist_u=0.5, phase_caps=(0.0, 1.0, 0.0, 1.0), beta=0.0).lift_assist_u == 0.5


def test_the_rim_guide_is_refused_where_it_could_not_act_and_says_what_to_set():
    """It commands a delta layout's x, y with the approach phase's authority, toward a point inside
    delta_grasp (where the approach phase ends)."""
    from lerobot_physvla.core.config import ActionLayout

    with pytest.raises(ValueError, match="phase_caps"):
        PhysVLAConfig.paper(rim_guide_m=0.047, phase_caps=(0.0, 1.0, 0.0, 1.0))
    absolute = ActionLayout(dim=4, pos=(0, 1, 2), gripper=3, absolute=True)
    with pytest.raises(ValueError, match="absolute"):
        PhysVLAConfig.paper(rim_guide_m=0.047, phase_caps=(1.0, 1.0, 0.0, 1.0), layout=absolute)
    with pytest.raises(ValueError, match="delta_grasp_m"):
        PhysVLAConfig.paper(rim_guide_m=0.06, phase_caps=(1.0, 1.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="chunk_phase_caps"):  # refused when built, not when a chunked policy comes
        PhysVLAConfig.paper(rim_guide_m=0.047, phase_caps=(1.0, 1.0, 0.0, 1.0), chunk_phase_caps=(0.0, 0.05, 0.0, 1.0))
    with pytest.raises(ValueError, match="chunk_phase_caps"):
        PhysVLAConfig.paper(lift_assist_u=0.5, phase_caps=(0.0, 1.0, 0.0, 1.0), chunk_phase_caps=(0.0, 0.0, 0.0, 1.0))
    assert PhysVLAConfig.paper(rim_guide_m=0.047, phase_caps=(1.0, 1.0, 0.0, 1.0)).rim_guide_m == 0.047
    with pytest.raises(ValueError, match="set rim_guide_m"):
        PhysVLAConfig.paper(rim_guide_into_grasp=True, phase_caps=(1.0, 1.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="grasp phase's authority, which is 0 in chunk_phase_caps"):
        PhysVLAConfig.paper(rim_guide_m=0.047, rim_guide_into_grasp=True, phase_caps=(1.0, 1.0, 0.0, 1.0),
                      chunk_phase_caps=(1.0, 0.0, 0.0, 1.0))
    assert PhysVLAConfig.paper(rim_guide_m=0.047, rim_guide_into_grasp=True, phase_caps=(1.0, 1.0, 0.0, 1.0)).rim_guide_into_grasp


def test_chunk_phase_caps_apply_only_to_a_policy_that_executes_chunks():
    c = PhysVLAConfig.paper(mode="phys", phase_caps=(0.0, 0.0, 0.0, 1.0), chunk_phase_caps=(0.0, 0.05, 0.0, 1.0))
    assert c.for_policy(1) is c and c.for_policy(1).caps == (0.0, 0.0, 0.0, 1.0)  # single-step: unchanged
    chunked = c.for_policy(10)
    assert chunked.caps == (0.0, 0.05, 0.0, 1.0) and chunked.chunk_phase_caps == ()
    assert chunked.replace(phase_caps=c.phase_caps, chunk_phase_caps=c.chunk_phase_caps) == c  # nothing else moves
    plain = PhysVLAConfig.paper(mode="phys", phase_caps=(0.0, 0.0, 0.0, 1.0))
    assert plain.for_policy(10) is plain  # no chunk caps: the same for every policy
    assert PhysVLAConfig.from_dict(c.to_dict()) == c


def test_the_class_is_a_plain_dataclass_that_agrees_with_the_declarations():
    """PhysVLAConfig's annotated fields are the declared ones (CORE_FIELDS, each correction's Correction.fields,
    LATE_FIELDS) in order, with their defaults; a choice field is a Literal of the values validate() accepts."""
    import dataclasses
    import typing

    from lerobot_physvla.core import config

    fields = dataclasses.fields(PhysVLAConfig)
    assert [f.name for f in fields] == [f.name for f in config.FIELDS]
    hints = typing.get_type_hints(PhysVLAConfig)
    for f, d in zip(fields, config.FIELDS, strict=True):
        assert f.default == d.default, f.name
        hint = hints[f.name]
        if typing.get_origin(hint) is typing.Literal:
            assert d.type is str and d.default in typing.get_args(hint), f.name
            with pytest.raises(ValueError, match="choose one of|unknown"):
                PhysVLAConfig(**{f.name: "no-such-choice"})
        else:
            assert hint == d.type, (f.name, hint, d.type)
    assert "dataclass" in repr(type(PhysVLAConfig.__dataclass_params__)).lower()
    assert PhysVLAConfig.__doc__.startswith("The corrector's configuration.")


# The fields of version 12 of the saved form (core/config.py CONFIG_VERSION; version 1 lacked approach_pull_m, 2 centre_guide_straddle, 3 carry_far_m, 4 approach_pull_stall_steps, 5 approach_pull_handback, 6 approach_pull_open_handback, 7 approach_pull_heading_u, 8 carry_clear_m, 9 centre_guide_clears, 10 veto_hold_to_top, 11 lift_assist_needs_close). A field added or renamed needs a new
# version: CONFIG_VERSION + 1, an UPGRADES entry (its value from before it), and this list for the new version.
FIELDS_V12 = ('alpha_temporal', 'alpha_transport', 'approach_pull_handback', 'approach_pull_heading_u', 'approach_pull_m', 'approach_pull_open_handback', 'approach_pull_stall_steps', 'assist_steps', 'assist_still', 'beta', 'cap', 'carry_clear_m', 'carry_far_m',
             'centre_guide', 'centre_guide_clears',
             'centre_guide_once', 'centre_guide_straddle', 'centre_guide_trailing', 'centre_guide_yield_steps', 'chunk', 'chunk_phase_caps',
             'close_meets', 'close_meets_onset', 'd_thresh_m', 'delta_grasp_m', 'dls_damping', 'el_mode', 'eps_nm',
             'geometry', 'grasp_offset_m', 'gripper_rule', 'h_lift_m', 'hold_steps', 'layout', 'lift_assist_at_rest', 'lift_assist_needs_close',
             'lift_assist_u', 'lift_bias_m', 'lowpass', 'lowpass_alpha_max', 'lowpass_lag', 'lowpass_phases',
             'lowpass_rough', 'lowpass_rough_hi', 'lowpass_rough_lo', 'lowpass_space', 'lowpass_speed_hi', 'mode',
             'phase_caps', 'phase_ref', 'place_gain', 'place_rule', 'place_tol_m', 'pose_error_m', 'pose_max_age_steps',
             'pose_noise_m', 'r0_nm', 'release_assist_error_k', 'release_assist_m', 'release_carry',
             'rim_guide_into_grasp', 'rim_guide_m', 'veto_close_lead_s', 'veto_height_m', 'veto_hold_to_top', 'veto_reach_m', 'veto_reopen',
             'weighting')


def test_the_saved_form_is_versioned_and_a_new_field_needs_a_new_version():
    from lerobot_physvla.core.config import CONFIG_VERSION, FIELDS, UPGRADES

    assert CONFIG_VERSION == 12 and set(UPGRADES) == set(range(CONFIG_VERSION))
    assert tuple(sorted(f.name for f in FIELDS)) == FIELDS_V12, "a field changed: bump CONFIG_VERSION, add an upgrade"
    assert PhysVLAConfig(cap=0.1).to_dict()["version"] == CONFIG_VERSION
    with pytest.raises(ValueError, match="upgrade lerobot-physvla"):
        PhysVLAConfig.from_dict({"version": CONFIG_VERSION + 1, "cap": 0.1})


def test_a_partial_configuration_fills_from_the_shipped_default_and_a_saved_file_from_before_acts_as_it_did():
    from lerobot_physvla.core.config import PRESETS, SAVED_V0

    assert PhysVLAConfig.from_dict({"mode": "phys_el"}) == PRESETS["default"].replace(mode="phys_el")
    # version 1 had no approach pull, carry or held close: they stay off, as then; every other field from the shipped
    # default
    assert PhysVLAConfig.from_dict({"version": 1, "cap": 0.2}) == PRESETS["default"].replace(
        cap=0.2, approach_pull_m=0.0, approach_pull_heading_u=0.0, carry_far_m=0.0, carry_clear_m=0.0, **BEFORE_HOLD)
    assert PhysVLAConfig.from_dict({"version": 11, "cap": 0.2}).lift_assist_needs_close is False  # version 11 lacked it
    paper = PhysVLAConfig.paper().to_dict()
    v0 = {k: paper[k] for k in SAVED_V0}  # what 0.1 saved: these fields only, no version
    v0["redirect_tol_m"] = 0.01  # saved under its old name: renamed by the upgrade
    assert PhysVLAConfig.from_dict(v0) == PhysVLAConfig.paper(place_tol_m=0.01)
    del v0["cap"]  # not a whole saved file: a partial configuration, the shipped default's other fields
    assert PhysVLAConfig.from_dict(v0).centre_guide
