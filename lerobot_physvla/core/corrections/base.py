"""What every Branch A correction shares: one signature, one parameter vector, one memory row, and the
declaration each correction file makes of itself.

Each correction is a numba function of one env that edits the candidate action in place:

    correction(a_raw, a_phys, idx, geo, p, mem, commit) -> None

    a_raw   (A,) float   the policy's action, action units (read only)
    a_phys  (A,) float   the candidate, action units: read, then written
    idx     (4,) int     action channels [x, y, z, gripper] (gripper = -1 if the layout has none)
    geo     (N_GEO,)     geometry of this env: eef xyz, object xyz, target xyz (m, world),
                         d_obj_xy, d_tgt_xy (m), lift = object height above its rest (m),
                         fingers = the gripper's opening (m)
    p       (N_PARAMS,)  parameters: the shared slots (slots.SHARED), then each correction's on-flag and
                         its own PARAMS (corrections/slots.py lays them out from the files)
    mem     (N_MEM,)     this env's memory, each correction's own MEMORY (then the pose filter's, slots.SHARED_MEMORY);
                         written only when commit is True
    commit  bool         True for the step about to execute (a chunk's first), False for
                         look-ahead steps of a chunk, which must leave memory untouched

A correction file declares itself: PARAMS and MEMORY (the names of its slots, literals), and
`CORRECTION = Correction(...)`: its phase, its place among that phase's corrections, its kernel, how each
of its parameters comes from the configuration, when the configuration turns it on, which correction it
replaces, and what it does to its memory on every committed step. `corrections/__init__.py` collects
them; `core/branch_a.py` assembles the dispatch from them. A new correction is its file, its tests and
the preset line that turns it on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from lerobot_physvla.core.corrections.slots import MEM_SLOTS, N_MEM, N_PARAMS, P_SLOTS  # noqa: F401

# idx
X, Y, Z, GRIPPER = range(4)
# geo
EEF, OBJ, TGT = 0, 3, 6  # xyz triples, m
D_OBJ_XY, D_TGT_XY, LIFT, FINGERS = 9, 10, 11, 12  # m
N_GEO = 13
# the shared parameter slots (slots.SHARED)
(METRES_PER_UNIT, GRIPPER_OPEN, LOW, HIGH, PHASE_REF_OBJECT, POSE_ERROR_M, POSE_MAX_AGE, GRIPPER_CLOSED,
 POSE_NOISE_M) = (P_SLOTS[n] for n in ("METRES_PER_UNIT", "GRIPPER_OPEN", "LOW", "HIGH", "PHASE_REF_OBJECT",
                                       "POSE_ERROR_M", "POSE_MAX_AGE", "GRIPPER_CLOSED", "POSE_NOISE_M"))
# A gripper command g closes where (g - c) (open - c) < 0, c = (open + closed) / 2 the midpoint of the layout's
# open and closed commands (p[GRIPPER_OPEN], p[GRIPPER_CLOSED]); c = 0 exactly for a command symmetric about 0,
# where this is the sign test g * open < 0. The kernels write it out (a helper here would be compiled into
# them from another file).


@dataclass(frozen=True)
class Field:
    """A configuration field a correction owns (a field of PhysVLAConfig and a `--physvla.<name>` flag).

    Attributes:
        name, type: the field.
        default: its value in the shipped default (PhysVLAConfig()).
        paper: its value in the paper's main text (PhysVLAConfig.paper()): off for a correction beyond it.
        doc: what it sets, with its unit.
        experimental: why the field is experimental (an option that failed its confirmation, in no preset, and
            its decision record), or "": it stays settable, is warned of once when set away from its default and is
            listed apart (PhysVLAConfig's `experimental` group, `--physvla.help`).
        experimental_values: values of a kept field that are experimental in the same way (with `experimental`
            saying why).
    """

    name: str
    type: object
    default: object
    paper: object
    doc: str
    experimental: str = ""
    experimental_values: tuple = ()


@dataclass(frozen=True)
class Correction:
    """A Branch A correction as its file declares it.

    Attributes:
        name: the file's name (its slots' owner).
        phase: the phase it acts in (core.phase APPROACH .. PLACE), or None: the temporal mode's EMA,
            which acts in every phase of that mode instead of Branch A.
        order: its place among its phase's corrections (lower runs first, on the candidate the
            earlier ones left).
        kernel: the numba function (the signature above).
        values: {its PARAMS slot name: f(cfg, layout) -> float}, how p gets each of its parameters.
        on: f(cfg) -> bool, whether the configuration turns it on.
        replaces: names of corrections of the same phase it runs instead of, where it is on.
        commit: a numba function (phase, geo, p, mem) run on every committed step while it is on, in
            every phase (its memory's upkeep: counters that start over outside its phase, a track of
            the hand), or None.
        fields: the configuration fields it owns (PhysVLAConfig is assembled from them).
        check: f(cfg) -> None, raising ValueError (one line, saying what to set) where the
            configuration asks it for something it cannot do; or None.
        pose: how its decisions answer to the pose error it is told (PhysVLAConfig.pose_error_m, p[POSE_ERROR_M]),
            in words; "" for one that reads p[POSE_ERROR_M] nowhere (it aims at no point of the pose and decides
            by no distance of the pose's order). A test holds each "" to that.
    """

    name: str
    phase: int | None
    order: int
    kernel: Callable
    values: dict = field(default_factory=dict)
    on: Callable = lambda cfg: True
    replaces: tuple[str, ...] = ()
    commit: Callable | None = None
    fields: tuple[Field, ...] = ()
    check: Callable | None = None
    pose: str = ""


def needs_authority(cfg, field: str, phases: tuple[int, ...], off: str) -> None:
    """ValueError where a correction the configuration turns on acts with the authority of a phase that phase_caps or
    chunk_phase_caps sets to 0 (it would be silently inert there); `off`: how to turn it off, in words."""
    from lerobot_physvla.core.phase import PHASE_NAMES

    for caps, name in ((cfg.caps, "phase_caps"), (tuple(cfg.chunk_phase_caps), "chunk_phase_caps")):
        for ph in phases:
            if caps and caps[ph] == 0.0:
                phase = PHASE_NAMES[ph]
                example = ", ".join("1" if k == ph else f"{v:g}" for k, v in enumerate(caps))
                raise ValueError(f"physvla: {field} acts with the {phase} phase's authority, which is 0 in {name}: set "
                                 f"{name} with {'an' if phase[0] in 'aeiou' else 'a'} {phase} entry above 0 (e.g. "
                                 f"({example})), or {off}")


def unit_interval(cfg, *names: str) -> None:
    """ValueError unless each named field lies in [0, 1]."""
    for name in names:
        v = getattr(cfg, name)
        if not 0.0 <= v <= 1.0:
            raise ValueError(f"physvla: {name} must lie in [0, 1], got {v}")


def __getattr__(name: str) -> int:
    """Every correction's slot by name (its index in p, or in the memory row), for tests and diagnostics."""
    if name in P_SLOTS:
        return P_SLOTS[name]
    if name in MEM_SLOTS:
        return MEM_SLOTS[name]
    raise AttributeError(f"module 'lerobot_physvla.core.corrections.base' has no attribute {name!r}")
