"""lerobot-eval's flags (scripts/lerobot_physvla_eval.py activate_eval), in process: bad ones stop before anything is
built, with one line. tests/scripts/test_lerobot_eval.py runs one of them through the real console script."""

from __future__ import annotations

import pytest

from lerobot_physvla.scripts.lerobot_physvla_eval import activate_eval

COMMON = ["--env.type=libero", "--env.task=libero_spatial", "--env.task_ids=[0]", "--policy.device=cpu"]


@pytest.mark.parametrize(
    "flags,message",
    [
        (["--policy.postprocess=physvla", "--physvla.mode=turbo"], "unknown mode 'turbo'"),
        (["--policy.postprocess=fizz"], "--policy.postprocess=fizz: unknown"),
        (["--policy.postprocess=physvla", "--physvla.capp=0.1"], "--physvla.capp: unknown"),
        (["--physvla.mode=phys"], "need --policy.postprocess=physvla"),
    ],
)
def test_bad_flags_fail_with_one_line(flags, message, capsys):
    argv = ["lerobot-eval", *COMMON, *flags]
    with pytest.raises(SystemExit) as e:
        activate_eval(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("lerobot-physvla: error:") and message in err and "\n" not in err
    assert argv == ["lerobot-eval", *COMMON, *flags]  # nothing stripped, nothing installed


def test_no_flag_leaves_the_arguments_as_they_are(capsys):
    argv = ["lerobot-eval", *COMMON]
    activate_eval(argv)
    assert argv == ["lerobot-eval", *COMMON] and capsys.readouterr().err == ""
