"""What lerobot's plugin auto-import runs.

lerobot imports every installed distribution named `lerobot_env_*` at the start of its console
scripts; ours (`lerobot_env_physvla`) calls `activate()`, which
- registers the `libero_physvla`, `metaworld_physvla` and `so101_physvla` env types, the processor steps (env:
  capture, policy: corrector, robot: joint-target corrector), the `physvla_scripted` policy type and the
  `physvla_sim_so101` / `physvla_sim_panda` robot types (always);
- in `lerobot-eval` (and `lerobot-physvla-eval`) only: applies `--policy.postprocess` and
  `--physvla.*` (see `scripts/lerobot_physvla_eval.py`); in `lerobot-rollout`: the same flags plus
  the arm's (`scripts/lerobot_physvla_rollout.py`). No flag leaves lerobot untouched.
PHYSVLA_DISABLE=1 turns the plugin off entirely.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path


def _is_lerobot_eval(argv0: str) -> bool:
    return Path(argv0).name in ("lerobot-eval", "lerobot_eval.py", "lerobot-physvla-eval")


def activate(argv: list[str] | None = None) -> None:
    """Entry point of the plugin import (see module docstring)."""
    if os.environ.get("PHYSVLA_DISABLE") == "1":
        return
    # registers the env type, the processor steps and the policy type
    from lerobot_physvla.envs import libero_physvla  # noqa: F401
    from lerobot_physvla.envs import metaworld_physvla  # noqa: F401
    from lerobot_physvla.envs import so101_physvla  # noqa: F401
    from lerobot_physvla.policies import physvla_metaworld_scripted, physvla_scripted  # noqa: F401
    from lerobot_physvla.processor import physvla_processor, physvla_robot_step  # noqa: F401
    from lerobot_physvla.robots import physvla_sim_panda, physvla_sim_so101  # noqa: F401  (robot types)

    argv = sys.argv if argv is None else argv
    if argv and Path(argv[0]).name in ("lerobot-rollout", "lerobot_rollout.py"):
        from lerobot_physvla.scripts.lerobot_physvla_rollout import activate_rollout

        activate_rollout(argv)
    if argv and _is_lerobot_eval(argv[0]):
        from lerobot_physvla.scripts.lerobot_physvla_eval import activate_eval

        activate_eval(argv)
