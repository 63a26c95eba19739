#!/usr/bin/env bash
# The main job: a short corrected lerobot-eval on LIBERO-Spatial (state-only, no hub access).
# The policy is the project's scripted expert saved as a LeRobot checkpoint; any --policy.path works.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
out="${1:-outputs/eval/physvla_demo}"
.venv/bin/python backbones/make_scripted_policy.py outputs/policies/scripted --aim_noise_m 0.01
rm -rf "$out"
set -x
.venv/bin/lerobot-eval --policy.path=outputs/policies/scripted --env.type=libero_physvla --env.cameras=false \
  --env.task=libero_spatial --env.task_ids='[0,1]' --eval.n_episodes=2 --eval.batch_size=2 \
  --policy.postprocess=physvla --output_dir="$out"
