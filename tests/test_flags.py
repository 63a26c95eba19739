import pytest

from lerobot_physvla.flags import FlagError, build_config, split_argv


def test_split_argv_takes_our_flags_and_keeps_lerobots():
    argv = ["--policy.path=p", "--policy.postprocess=physvla", "--physvla.mode", "phys", "--physvla.cap=0.1",
            "--physvla.grasp_offset_m=[0,0,0.02]", "--env.type=libero"]
    post, overrides, rest = split_argv(argv)
    assert post == "physvla" and rest == ["--policy.path=p", "--env.type=libero"]
    assert overrides == {"mode": "phys", "cap": 0.1, "grasp_offset_m": (0.0, 0.0, 0.02)}
    cfg = build_config(overrides)
    assert cfg.cap == 0.1 and cfg.mode == "phys"


@pytest.mark.parametrize(
    "argv,message",
    [(["--policy.postprocess=x"], "unknown"), (["--physvla.nope=1"], "unknown"),
     (["--physvla.cap=abc"], "not a valid float"), (["--physvla.mode"], "needs a value")],
)
def test_bad_flags(argv, message):
    with pytest.raises(FlagError, match=message):
        split_argv(argv)


def test_bad_value_is_a_flag_error():
    with pytest.raises(FlagError, match="cap"):
        build_config({"cap": 2.0})


def test_which_configuration_the_flags_build():
    from lerobot_physvla.core.config import PRESETS, PhysVLAConfig

    assert build_config({}) == PRESETS["default"]  # --policy.postprocess=physvla alone
    # a mode flag changes the mode alone: the paper's main text is a preset
    assert build_config({"mode": "phys_el"}) == PRESETS["default"].replace(mode="phys_el") != PRESETS["paper"]
    assert build_config({"preset": "paper", "mode": "phys"}) == PhysVLAConfig.paper(mode="phys")
    assert build_config({"preset": "paper_alg1"}) == PRESETS["paper_alg1"]
    assert build_config({"preset": "default", "lowpass": "off"}) == PRESETS["default"].replace(lowpass="off")
    _, overrides, _ = split_argv(["--physvla.preset=paper", "--physvla.phase_caps=0,0,0,1"])
    assert build_config(overrides) == PhysVLAConfig.paper(mode="phys_el", phase_caps=(0.0, 0.0, 0.0, 1.0))
    with pytest.raises(FlagError, match="choose one of"):
        split_argv(["--physvla.preset=turbo"])


def test_help_lists_every_field_with_its_type_and_default_and_the_experimental_ones_apart(capsys):
    from lerobot_physvla.core.config import FIELDS, PhysVLAConfig

    with pytest.raises(SystemExit) as e:
        split_argv(["--policy.postprocess=physvla", "--physvla.help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    main, _, experimental = out.partition("EXPERIMENTAL")
    for f in FIELDS:
        line = next(ln for ln in out.splitlines() if ln.strip().startswith(f"--physvla.{f.name} "))
        assert f"default {getattr(PhysVLAConfig(), f.name)!r}" in line, line
        assert (f"--physvla.{f.name} " in experimental) == bool(f.experimental and not f.experimental_values), f.name
    assert "--physvla.mode  (baseline | temporal | phys | phys_el, default 'phys')" in main
    assert "--physvla.close_meets " in experimental and "--physvla.close_meets_onset " in main


def test_an_old_name_is_the_new_field_with_a_warning_and_both_at_once_is_an_error():
    from lerobot_physvla.core import config

    config._WARNED.discard("alias:redirect_tol_m")
    with pytest.warns(UserWarning, match="redirect_tol_m is now place_tol_m"):
        _, overrides, _ = split_argv(["--physvla.redirect_tol_m=0.01"])
    assert overrides == {"place_tol_m": 0.01} and build_config(overrides).place_tol_m == 0.01
    with pytest.raises(ValueError, match="one field"):
        config.PhysVLAConfig.from_dict({"redirect_tol_m": 0.01, "place_tol_m": 0.02})


def test_an_experimental_option_warns_once_and_still_acts(recwarn):
    from lerobot_physvla.core import config

    config._WARNED.difference_update({"experimental:close_meets=True", "experimental:lowpass_lag='compensate'"})
    a = config.PhysVLAConfig(close_meets=True)
    b = config.PhysVLAConfig(close_meets=True)
    said = [str(w.message) for w in recwarn if "experimental" in str(w.message)]
    assert a.close_meets and b.close_meets and len(said) == 1 and "28-close-meets.md" in said[0]
    config.PhysVLAConfig(lowpass="adaptive", lowpass_lag="compensate")
    config.PhysVLAConfig(lowpass_lag="trail")  # the kept value of a field with an experimental value: silent
    said = [str(w.message) for w in recwarn if "experimental" in str(w.message)]
    assert len(said) == 2 and "lowpass_lag='compensate'" in said[1]


def test_the_first_line_names_the_preset_and_what_differs():
    from lerobot_physvla.flags import describe

    _, o, _ = split_argv(["--physvla.preset=smooth", "--physvla.cap=0.1"])
    assert describe(build_config(o), o) == "lerobot-physvla: preset smooth; fields that differ from it: cap=0.1"
    assert describe(build_config({}), {}) == "lerobot-physvla: preset default; fields that differ from it: none"
    assert describe(build_config({}, default="arm"), {}, default="arm").startswith("lerobot-physvla: preset arm;")


@pytest.mark.slow
@pytest.mark.parametrize("script", ["lerobot-eval", "lerobot-rollout", "lerobot-physvla-replay"])
def test_the_console_scripts_print_the_fields_and_exit(script):
    import subprocess
    import sys
    from pathlib import Path

    run = subprocess.run([str(Path(sys.executable).parent / script), "--physvla.help"], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "--physvla.place_tol_m  (float, default 0.02)" in run.stdout and "EXPERIMENTAL" in run.stdout
    assert ("--physvla.object_xyz" in run.stdout) == (script == "lerobot-rollout")
