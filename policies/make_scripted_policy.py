"""Save the scripted expert as a LeRobot policy checkpoint (`--policy.path` loads it).

    .venv/bin/python policies/make_scripted_policy.py OUT_DIR [--action_noise 0.1] [--aim_noise_m 0.01]
        [--place_bias_m 0.03] [--premature_close 0.2] [--no_decel] [--seed 0]

The checkpoint has no learned weights: config.json, an empty model file and lerobot's default
processors (identity normalisation). Evaluate it state-only:
    lerobot-eval --policy.path=OUT_DIR --env.type=libero_physvla --env.cameras=false --env.task=libero_spatial
"""

from __future__ import annotations

import argparse

from lerobot.processor.factory import make_default_pre_post_processors

from lerobot_physvla.scripted_policy.configuration_physvla_scripted import PhysVLAScriptedConfig
from lerobot_physvla.scripted_policy.modeling_physvla_scripted import PhysVLAScriptedPolicy


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--action_noise", type=float, default=0.0)
    ap.add_argument("--aim_noise_m", type=float, default=0.0)
    ap.add_argument("--place_bias_m", type=float, default=0.0)
    ap.add_argument("--premature_close", type=float, default=0.0)
    ap.add_argument("--no_decel", action="store_true")
    ap.add_argument("--seed", type=int, default=0)
    args = vars(ap.parse_args())
    out = args.pop("out")
    cfg = PhysVLAScriptedConfig(device="cpu", **args)
    policy = PhysVLAScriptedPolicy(cfg)
    pre, post = make_default_pre_post_processors(cfg, None, normalizer_device="cpu")
    policy.save_pretrained(out)
    pre.save_pretrained(out)
    post.save_pretrained(out)
    print(f"saved the scripted expert policy to {out}")


if __name__ == "__main__":
    main()
