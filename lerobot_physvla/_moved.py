"""Import paths that moved, kept working: `lerobot_physvla.<old>` -> where it lives now.

A postprocessor saved before the layout moved names its step by class path
(`"class": "lerobot_physvla.lerobot_steps.PhysVLACorrectorStep"`); lerobot imports that path when
it loads the file. A meta-path finder answers for every old module name with a thin module that
forwards attribute lookups to the new module(s), and warns once per old path (FutureWarning,
naming the new path). The classes are the very same objects, so isinstance checks hold.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

P = "lerobot_physvla"
# old module -> new module(s); attributes are looked up in this order
MOVED: dict[str, tuple[str, ...]] = {
    f"{P}.config": (f"{P}.core.config",),
    f"{P}.state": (f"{P}.core.state",),
    f"{P}.phase": (f"{P}.core.phase", f"{P}.core.branch_a"),
    f"{P}.dynamics": (f"{P}.core.dynamics",),
    f"{P}.corrector": (f"{P}.core.corrector",),
    f"{P}.robosuite_source": (f"{P}.sources.robosuite",),
    f"{P}.libero_setup": (f"{P}.sim.libero_setup",),
    f"{P}.libero_sim": (f"{P}.sim.libero_sim",),
    f"{P}.lift_sim": (f"{P}.sim.lift_sim",),
    f"{P}.fetch_sim": (f"{P}.sim.fetch_sim",),
    f"{P}.experts": (f"{P}.sim.experts",),
    f"{P}.scenes": (f"{P}.sim.scenes",),
    f"{P}.lerobot_envs": (f"{P}.envs.libero_physvla",),
    f"{P}.lerobot_steps": (f"{P}.processor.physvla_processor",),
    f"{P}.lerobot_compat": (f"{P}.compat", f"{P}.envs.libero_physvla"),
    f"{P}.lerobot_plugin": (f"{P}.plugin", f"{P}.flags", f"{P}.scripts.lerobot_physvla_eval"),
    f"{P}.hub_config": (f"{P}.scripts.lerobot_physvla_config",),
    f"{P}.demo": (f"{P}.scripts.physvla_demo",),
    f"{P}.scripted_policy": (f"{P}.policies.physvla_scripted",),
    f"{P}.scripted_policy.configuration_physvla_scripted": (
        f"{P}.policies.physvla_scripted.configuration_physvla_scripted",),
    f"{P}.scripted_policy.modeling_physvla_scripted": (f"{P}.policies.physvla_scripted.modeling_physvla_scripted",),
    # names with one meaning (0.2): LeRobot robot types under robots/, arm models under arms/, state sources
    # under sources/, Branch B's noise guard beside Branch B
    f"{P}.robots.arms": (f"{P}.arms.model",),
    f"{P}.robots.joint_targets": (f"{P}.arms.joint_targets",),
    f"{P}.robots.joint_state": (f"{P}.sources.joint_state",),
    f"{P}.robots.noise_guard": (f"{P}.core.noise_guard",),
    f"{P}.sim.robosuite_source": (f"{P}.sources.robosuite",),
    f"{P}.robot_types": (f"{P}.robots",),
    f"{P}.robot_types.sim_arm": (f"{P}.robots.sim_arm",),
    **{f"{P}.robot_types.{arm}{sub}": (f"{P}.robots.{arm}{sub}",)
       for arm in ("physvla_sim_so101", "physvla_sim_panda")
       for sub in ("", f".{arm}", f".config_{arm}")},
}
_PACKAGES = {f"{P}.scripted_policy", f"{P}.robot_types", f"{P}.robot_types.physvla_sim_so101",
             f"{P}.robot_types.physvla_sim_panda"}


class _MovedLoader(importlib.abc.Loader):
    def __init__(self, targets: tuple[str, ...]):
        self.targets = targets

    def create_module(self, spec):
        return None  # a plain module, filled in by exec_module

    def exec_module(self, module) -> None:
        old, new = module.__name__, self.targets[0]
        targets = [importlib.import_module(t) for t in self.targets]
        warnings.warn(
            f"{old} is deprecated: it moved to {new}; import it from there (or re-save the "
            "postprocessor with lerobot-physvla-config to update its class path)",
            FutureWarning, stacklevel=2,
        )

        def __getattr__(name: str):
            for t in targets:
                if hasattr(t, name):
                    return getattr(t, name)
            raise AttributeError(f"module {old!r} (moved to {new}) has no attribute {name!r}")

        module.__getattr__ = __getattr__
        module.__dir__ = lambda: sorted(set().union(*(dir(t) for t in targets)))
        module.__moved_to__ = new
        if old in _PACKAGES:
            module.__path__ = []  # lets the old package's submodules be found by this finder


class _MovedFinder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        if fullname in MOVED:
            return importlib.util.spec_from_loader(fullname, _MovedLoader(MOVED[fullname]),
                                                   is_package=fullname in _PACKAGES)
        return None


def install() -> None:
    """Make the old paths importable (idempotent)."""
    if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
        sys.meta_path.append(_MovedFinder())
