"""Save the scripted expert as a LeRobot policy checkpoint (`--policy.path` loads it).

    .venv/bin/python backbones/make_scripted_policy.py OUT_DIR [--action_noise 0.1] [--aim_noise_m 0.01]
        [--place_bias_m 0.03] [--premature_close 0.2] [--no_decel] [--noise_stage grasp]
        [--place_bias_units 1.7] [--seed 0] [--scene libero_spatial|lift|lift_plate|fetch_pick_place]
    .venv/bin/python backbones/make_scripted_policy.py OUT_DIR --scene metaworld [--task shelf-place-v3]

--scene takes the action layout and waypoint geometry of that scene (lerobot_physvla.sim.scenes);
LeRobot env types exist for LIBERO only, so the lift / fetch policies run in the project's own
harness or any env that feeds the same observation.

--scene metaworld saves MetaWorld's own scripted policies instead (`physvla_metaworld_scripted`: each env runs its
task's policy from `metaworld.policies`; --task fixes one, else the env's own); no failure mode applies to them.

The checkpoint has no learned weights: config.json, an empty model file and lerobot's default
processors (identity normalisation). Evaluate it state-only:
    lerobot-eval --policy.path=OUT_DIR --env.type=libero_physvla --env.cameras=false --env.task=libero_spatial
    lerobot-eval --policy.path=OUT_DIR --env.type=metaworld_physvla --env.cameras=false --env.raw_obs=true \
        --env.task=shelf-place-v3,door-open-v3                                    # --scene metaworld
"""

from __future__ import annotations

import argparse

from lerobot.processor.factory import make_default_pre_post_processors

from lerobot_physvla.policies.physvla_scripted.configuration_physvla_scripted import PhysVLAScriptedConfig
from lerobot_physvla.policies.physvla_scripted.modeling_physvla_scripted import PhysVLAScriptedPolicy


SCENES = ("libero_spatial", "lift", "lift_plate", "fetch_pick_place", "metaworld")


def scene_fit(scene: str) -> dict:
    """layout + expert geometry of a scene (its class attributes; no sim is built)."""
    if scene == "libero_spatial":
        return {}
    if scene == "fetch_pick_place":
        from lerobot_physvla.sim.fetch_sim import FetchScene

        return {"layout": "fetch_4d", "expert": dict(FetchScene.expert)}
    from lerobot_physvla.sim.lift_sim import lift_expert

    return {"expert": lift_expert(plate=scene == "lift_plate")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--action_noise", type=float, default=0.0)
    ap.add_argument("--aim_noise_m", type=float, default=0.0)
    ap.add_argument("--place_bias_m", type=float, default=0.0)
    ap.add_argument("--premature_close", type=float, default=0.0)
    ap.add_argument("--no_decel", action="store_true")
    ap.add_argument("--noise_stage", choices=("all", "grasp"), default="all")
    ap.add_argument("--place_bias_units", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--scene", choices=SCENES, default="libero_spatial")
    ap.add_argument("--task", default="", help="--scene metaworld: the MetaWorld task (default: each env's own)")
    args = vars(ap.parse_args())
    out, scene, task = args.pop("out"), args.pop("scene"), args.pop("task")
    if scene == "metaworld":
        from lerobot_physvla.policies.physvla_metaworld_scripted.configuration_physvla_metaworld_scripted import (
            PhysVLAMetaworldScriptedConfig)
        from lerobot_physvla.policies.physvla_metaworld_scripted.modeling_physvla_metaworld_scripted import (
            PhysVLAMetaworldScriptedPolicy)

        if any(args[k] != ap.get_default(k) for k in args):
            ap.error("--scene metaworld runs MetaWorld's own policies: no failure mode applies")
        cfg = PhysVLAMetaworldScriptedConfig(device="cpu", task=task)
        policy = PhysVLAMetaworldScriptedPolicy(cfg)
    else:
        cfg = PhysVLAScriptedConfig(device="cpu", **args, **scene_fit(scene))
        policy = PhysVLAScriptedPolicy(cfg)
    pre, post = make_default_pre_post_processors(cfg, None, normalizer_device="cpu")
    policy.save_pretrained(out)
    pre.save_pretrained(out)
    post.save_pretrained(out)
    print(f"saved the scripted expert policy to {out}")


if __name__ == "__main__":
    main()
