"""Offline LIBERO wiring: idempotent set-up, no prompt, clear errors naming the fix."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from lerobot_physvla.sim import libero_setup


def test_setup_is_idempotent_and_libero_imports_without_a_prompt():
    exe = Path(sys.executable).with_name("physvla-libero-setup")
    for _ in range(2):
        r = subprocess.run([str(exe)], stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        assert "assets at" in r.stdout
    # a fresh interpreter of this venv finds the config by itself (the .pth file), stdin closed
    env = {k: v for k, v in os.environ.items() if k != "LIBERO_CONFIG_PATH"}
    probe = "import os; from libero.libero import get_libero_path; print(os.environ['LIBERO_CONFIG_PATH'], get_libero_path('assets'))"
    r = subprocess.run([sys.executable, "-c", probe], stdin=subprocess.DEVNULL, capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    cfg_dir, assets = r.stdout.split()
    assert Path(cfg_dir, "config.yaml").is_file() and Path(assets, "scenes").is_dir()


def test_check_names_the_fix_when_the_config_is_missing(tmp_path, monkeypatch):
    monkeypatch.setenv("LIBERO_CONFIG_PATH", str(tmp_path))
    with pytest.raises(libero_setup.LiberoSetupError, match="tools/setup.sh"):
        libero_setup.check()


def test_asset_tree_is_complete():
    tree = libero_setup.asset_tree()
    for d in ("scenes", "stable_scanned_objects", "textures"):
        assert (tree / d).is_dir()


def test_private_macros_are_copied_once_and_kept(tmp_path):
    from lerobot_physvla.sim.libero_setup import private_macros

    (tmp_path / "macros.py").write_text("SIMULATION_TIMESTEP = 0.002\n")
    path = private_macros(tmp_path)
    assert path.read_text() == "SIMULATION_TIMESTEP = 0.002\n"
    path.write_text("SIMULATION_TIMESTEP = 0.001  # the user's own\n")
    private_macros(tmp_path)
    assert path.read_text() == "SIMULATION_TIMESTEP = 0.001  # the user's own\n"


def test_robosuite_imports_without_the_macro_warning():
    r = subprocess.run([sys.executable, "-c", "import robosuite"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "macro" not in (r.stdout + r.stderr).lower(), r.stderr[-1000:]
