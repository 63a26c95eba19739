"""Configuration of the corrector: the action layout and every hyperparameter.

`PhysVLAConfig` is a plain dataclass whose annotated fields are, in order, the fields that belong to no one correction
(CORE_FIELDS, LATE_FIELDS: mode and layout, the blender, the phase machine, the gripper veto, the place rule, Branch
B, the low-pass) and the fields each correction declares in its own file (core/corrections/*.py, `Correction.fields`:
their meaning, unit, default and paper value). A test holds the class to those declarations (names, order, types,
defaults), so a new correction is its file plus its lines in the class. Its defaults are the shipped default; the
paper's values (App. A's hyperparameter table, and the ones this project fixes where the paper is silent: h_lift,
the layout, the gripper rule, the EL weighting and mode, eps, r0) are `PhysVLAConfig.paper()`. Nothing here
imports LeRobot; the LeRobot glue turns `--physvla.*` flags into a `PhysVLAConfig`.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from lerobot_physvla.core.corrections import CORRECTIONS
from lerobot_physvla.core.corrections.base import Field
from lerobot_physvla.core.pose_filter import residual_m

# The choices of the configuration's choice fields: Literal types (what PhysVLAConfig's annotations say, what IDEs
# and type checkers see) and their values as tuples (what validate() and the flags check against).
Mode = Literal["baseline", "temporal", "phys", "phys_el"]
ElMode = Literal["soft", "gated", "off"]
Weighting = Literal["joint_diag", "task_space"]
GripperRule = Literal["blend", "veto"]
ChunkMode = Literal["all", "first"]
PlaceRule = Literal["decelerate", "redirect", "release_veto"]
PhaseRef = Literal["eef", "object"]
Geometry = Literal["fixed", "scene"]  # the distances as configured, or from the scene (core/geometry.py)
LowpassRule = Literal["off", "adaptive"]
LowpassSpace = Literal["action", "target"]
LowpassRough = Literal["ema", "median"]  # the low-pass's roughness estimate (core/lowpass.py)
LowpassLag = Literal["trail", "compensate"]  # a filtered target's lag behind a steady move
AssistStill = Literal["action", "hand"]  # what makes a hold still for the release assist
MODES: tuple[str, ...] = get_args(Mode)
EL_MODES: tuple[str, ...] = get_args(ElMode)
WEIGHTINGS: tuple[str, ...] = get_args(Weighting)
GRIPPER_RULES: tuple[str, ...] = get_args(GripperRule)
CHUNK_MODES: tuple[str, ...] = get_args(ChunkMode)
PLACE_RULES: tuple[str, ...] = get_args(PlaceRule)
PHASE_REFS: tuple[str, ...] = get_args(PhaseRef)
GEOMETRIES: tuple[str, ...] = get_args(Geometry)
LOWPASS_RULES: tuple[str, ...] = get_args(LowpassRule)
LOWPASS_SPACES: tuple[str, ...] = get_args(LowpassSpace)
LOWPASS_ROUGH: tuple[str, ...] = get_args(LowpassRough)
LOWPASS_LAGS: tuple[str, ...] = get_args(LowpassLag)
PHASE_NAMES: tuple[str, ...] = ("approach", "grasp", "transport", "place")


@dataclass(frozen=True)
class ActionLayout:
    """Where each quantity sits in the env's action vector, and its units.

    Attributes:
        dim: action dimension A.
        pos: indices of the Cartesian position deltas (x, y, z), in action units.
        rot: indices of the rotation deltas (may be empty).
        gripper: index of the gripper command, or None if the env has none.
        metres_per_unit: metres of end-effector travel per action unit on the position
            channels (0.05 m for LIBERO / robosuite OSC_POSE).
        gripper_open: the gripper command value that means "open" (-1 in robosuite).
        gripper_closed: the gripper command value that means "closed"; None: -gripper_open (a command
            symmetric about 0, as robosuite's, MetaWorld's and Fetch's). A command on the closed side of the
            midpoint of the two is a close (`closes`): lerobot-env-so101's absolute grasp in [0, 1] has
            gripper_open 1, gripper_closed 0, a close below 0.5.
        low, high: the action space bounds (scalars, broadcast to every channel).
        absolute: False for delta layouts (the position/rotation channels are increments, so
            holding still is 0); True for absolute targets (holding still is the last target).
            The gripper channel is always treated as absolute. Used by the safe hold action that
            replaces a non-finite policy action.
        step_gain: the fraction of a position gap (m) the centre guide commands in one step, as a ratio:
            1 where the action sets the step's goal from where the hand is (OSC_POSE, Fetch); below 1 where it
            moves a target the hand trails and integrates, so a full-gap command every step would wind the
            target up past the goal (MetaWorld's mocap: 0.25, its own scripted policies' gain of 25 times the
            action scale).
    """

    dim: int
    pos: tuple[int, int, int]
    rot: tuple[int, ...] = ()
    gripper: int | None = None
    metres_per_unit: float = 0.05
    gripper_open: float = -1.0
    low: float = -1.0
    high: float = 1.0
    absolute: bool = False
    gripper_closed: float | None = None
    step_gain: float = 1.0

    def __post_init__(self) -> None:
        used = list(self.pos) + list(self.rot) + ([self.gripper] if self.gripper is not None else [])
        if len(self.pos) != 3:
            raise ValueError(f"ActionLayout.pos needs 3 indices (x, y, z), got {self.pos}")
        if any(not 0 <= i < self.dim for i in used) or len(set(used)) != len(used):
            raise ValueError(f"ActionLayout indices {used} must be distinct and in [0, {self.dim})")
        if not self.metres_per_unit > 0:
            raise ValueError(f"metres_per_unit must be > 0, got {self.metres_per_unit}")
        if not 0 < self.step_gain <= 1:
            raise ValueError(f"step_gain must be in (0, 1], got {self.step_gain}")
        if not (np.isfinite(self.low) and np.isfinite(self.high)):
            raise ValueError(f"ActionLayout bounds must be finite, got [{self.low}, {self.high}]")
        if not self.low < self.high or not self.low <= self.gripper_open <= self.high:
            raise ValueError("need low < high and gripper_open within [low, high]")
        if self.gripper_closed is not None and not (self.low <= self.gripper_closed <= self.high
                                                    and self.gripper_closed != self.gripper_open):
            raise ValueError(f"need gripper_closed within [low, high] and not gripper_open, got {self.gripper_closed}")

    @property
    def gripper_shut(self) -> float:
        """The gripper command that means "closed" (gripper_closed, or -gripper_open where it is None)."""
        return -self.gripper_open if self.gripper_closed is None else float(self.gripper_closed)

    @property
    def gripper_centre(self) -> float:
        """The midpoint of the open and the closed command: a command beyond it, away from open, closes (0 for a
        command symmetric about 0)."""
        return 0.5 * (self.gripper_open + self.gripper_shut)

    def closes(self, g):
        """Whether gripper command(s) g close: on the closed side of `gripper_centre` (elementwise)."""
        c = self.gripper_centre
        return (np.asarray(g) - c) * (self.gripper_open - c) < 0

    @property
    def gripper_hold_tol(self) -> float:
        """How far from open the last command may lie and still count as open for the veto's "never open a
        gripper that holds" (core/blend.py): half the open-to-closed span where gripper_closed is set; half the
        bounds' span where it is not (the layouts from before gripper_closed, whose commands span the bounds)."""
        if self.gripper_closed is None:
            return 0.5 * (self.high - self.low)
        return 0.5 * abs(self.gripper_open - self.gripper_closed)

    @property
    def pos_index(self) -> np.ndarray:
        return np.asarray(self.pos, dtype=np.intp)

    def hold(self, last: np.ndarray | None = None) -> np.ndarray:
        """The safe hold action (A,): what an env executes in place of a non-finite policy action.

        Delta channels hold still with 0; absolute channels (the gripper always; every channel of
        an absolute layout) repeat `last`, the action this env executed last, or without one
        (an episode's first step) the gripper opens and other absolute channels take 0 clipped
        to the bounds.
        """
        out = np.zeros(self.dim)
        absolute = self.absolute_mask
        if last is not None and np.isfinite(last).all():
            out[absolute] = np.clip(np.asarray(last, dtype=np.float64)[absolute], self.low, self.high)
        else:
            out[absolute] = min(max(0.0, self.low), self.high)
            if self.gripper is not None:
                out[self.gripper] = self.gripper_open
        return out

    @property
    def absolute_mask(self) -> np.ndarray:
        """(A,) True on the channels that hold by repeating (see `hold`)."""
        m = np.full(self.dim, bool(self.absolute))
        if self.gripper is not None:
            m[self.gripper] = True
        return m


# robosuite / LIBERO OSC_POSE: [dx, dy, dz, drx, dry, drz, g], 0.05 m per unit, -1 = open.
LIBERO_OSC_POSE = ActionLayout(dim=7, pos=(0, 1, 2), rot=(3, 4, 5), gripper=6, metres_per_unit=0.05)
# gymnasium-robotics Fetch: [dx, dy, dz, g], 0.05 m per unit (pos_ctrl *= 0.05), +1 = open.
FETCH_4D = ActionLayout(dim=4, pos=(0, 1, 2), gripper=3, metres_per_unit=0.05, gripper_open=1.0)

# MetaWorld (Sawyer, mocap): [dx, dy, dz, g]; the mocap target moves action * 0.01 m a step (SawyerXYZEnv.action_scale;
# the tool centre follows at that speed once moving, measured), g: +1 closes, -1 opens (the finger servos get [g, -g]).
# The target integrates the actions and the hand trails it: a pull commands a quarter of the gap a step, as
# metaworld's own scripted policies do (policies/policy.py move(..., p=25) times action_scale 0.01).
METAWORLD = ActionLayout(dim=4, pos=(0, 1, 2), gripper=3, metres_per_unit=0.01, gripper_open=-1.0, step_gain=0.25)

LAYOUTS: dict[str, ActionLayout] = {"libero_osc_pose": LIBERO_OSC_POSE, "fetch_4d": FETCH_4D, "metaworld": METAWORLD}


def so101_layout(action_scale: float = 1.0) -> ActionLayout:
    """lerobot-env-so101 (SO-101, position IK): [dx, dy, dz, grasp]. The IK target of the point the action moves
    steps action * action_scale m a control step (the env config's `action_scale`, 1.0 by default; the package's
    scripted controller and BC policy use 0.025), so metres_per_unit follows the env; the grasp point follows its
    target at 0.8-1.0 of that speed (measured mid-workspace at 4 mm a step: x 0.90, y 1.00, z 0.81; the IK's
    top-down constraint and the servos' lag). grasp: an absolute target in [0, 1], 1 open, 0 closed (a close below
    0.5). Not in LAYOUTS: the env type so101_physvla passes the one of its config (sources/so101.py)."""
    return ActionLayout(dim=4, pos=(0, 1, 2), gripper=3, metres_per_unit=float(action_scale), gripper_open=1.0,
                        gripper_closed=0.0)


# The fields that belong to no one correction, by concept: (heading, fields). Each correction's own fields
# are declared in its file (core/corrections/*.py, `Correction.fields`); PhysVLAConfig is assembled from both.
CORE_FIELDS: tuple = (
    ("what runs, on which action vector", (
        Field("mode", str, "phys", "phys_el", "baseline (identity) | temporal (uniform EMA) | phys (Branch A) | "
              "phys_el (A + B)"),
        Field("layout", str | ActionLayout, "libero_osc_pose", "libero_osc_pose", "a name in LAYOUTS or an ActionLayout"),
    )),
    ("the blender (eq. 2)", (
        Field("cap", float, 0.05, 0.05, "the authority c of the corrected action"),
        Field("phase_caps", tuple[float, ...], (1.0, 1.0, 1.0, 1.0), (), "the authority per phase (approach, grasp, "
              "transport, place), in place of cap; () = cap in every phase"),
        Field("chunk_phase_caps", tuple[float, ...], (), (), "phase_caps for a policy that executes open-loop chunks "
              "(for_policy); () = phase_caps"),
        Field("chunk", str, "all", "all", "all | first: which steps of a (B, T, A) chunk are corrected"),
        Field("gripper_rule", str, "veto", "blend", "blend (the gripper goes through the blender) | veto (opened in "
              "full where no grasp can close on the object)"),
    )),
    ("the phase machine (eq. 3)", (
        Field("geometry", str, "scene", "fixed", "scene | fixed: the distances below (delta_grasp_m, the veto's, the "
              "rim guide's, the release tolerance) measured on the scene the state carries (core/geometry.py; a state "
              "without one keeps them as set), or as set"),
        Field("delta_grasp_m", float, 0.06, 0.06, "the grasp envelope, m"),
        Field("h_lift_m", float, 0.02, 0.02, "the lift above its rest that counts as lifted, m"),
        Field("phase_ref", str, "object", "eef", "eef | object: what the place distance measures from once the "
              "object is lifted"),
    )),
    ("the gripper veto (gripper_rule=veto)", (
        Field("veto_height_m", float, 0.06, 0.0, "a close in the grasp phase with the hand more than this above the "
              "object's origin is vetoed too, m; 0 = approach phase only"),
        Field("veto_reach_m", float, 0.10, 0.0, "in approach, the veto applies from this far from the object "
              "horizontally (or above veto_height_m), m; 0 = everywhere in approach"),
        Field("veto_reopen", bool, False, True, "the veto may open a gripper whose last command was closed"),
    )),
    ("the place phase's correction", (
        Field("place_rule", str, "release_veto", "decelerate", "decelerate (eq. 5) | redirect | release_veto"),
        Field("place_tol_m", float, 0.02, 0.0, "on target: the held object's centre within this of the target's (the "
              "release veto holds back a release beyond it, the redirect steers only beyond it, the release assist "
              "lets go within it), m; was redirect_tol_m"),
        Field("place_gain", float, 0.5, 0.5, "how hard the redirect and the release veto steer the held object toward "
              "the target: action units per action unit of error beyond place_tol_m; was redirect_gain"),
    )),
    ("the pose the corrections read (the object's and the target's)", (
        Field("pose_error_m", float, 0.0, 0.0, "how far the poses may be off, a bound on |perceived - true| (e.g. "
              "bias + 2 x noise sigma), m: each distance a correction decides by answers to it (docs/method.md, "
              "'Pose error'); 0 = exact, as a simulator's state is"),
        Field("pose_max_age_steps", int, 5, 5, "the oldest pose a correction acts on (the state's pose_age), control "
              "steps; an older one passes the action through (stale_pose)"),
        Field("pose_noise_m", float, 0.0, 0.0, "the poses' per-step noise, a standard deviation on each axis, m: the "
              "corrector filters each pose over the steps its motion is known (core/pose_filter.py) and the "
              "corrections answer to pose_error_m + 2 x what the filter leaves; 0 = no filter"),
    )),
)
LATE_FIELDS: tuple = (  # after the corrections' own
    ("Branch B (eq. 4-6)", (
        Field("el_mode", str, "soft", "soft", "soft | gated | off"),
        Field("weighting", str, "joint_diag", "joint_diag", "joint_diag | task_space"),
        Field("eps_nm", float, 0.05, 0.05, "the gate's threshold, N m"),
        Field("r0_nm", float, 1.5, 1.5, "the residual at which the gated weight saturates, N m"),
        Field("dls_damping", float, 1e-2, 1e-2, "the damped least-squares pseudo-inverse's damping, m"),
    )),
    ("the adaptive low-pass (core/lowpass.py)", (
        Field("lowpass", str, "off", "off", "off | adaptive"),
        Field("lowpass_phases", str, "approach,grasp,transport,place", "approach,grasp,transport,place",
              "the phases where it acts (comma-separated)"),
        Field("lowpass_space", str, "action", "action", "action | target: the increments, or the position they command"),
        Field("lowpass_speed_hi", float, 0.0, 0.0, "it fades out as the policy's speed reaches this, action units per "
              "step; 0 = off",
              experimental="failed its confirmation, in no preset: docs/decisions/07-target-lowpass.md"),
        Field("lowpass_alpha_max", float, 0.6, 0.6, "its strongest smoothing factor, in [0, 1)"),
        Field("lowpass_rough_lo", float, 0.05, 0.05, "the roughness where it starts acting, action units"),
        Field("lowpass_rough_hi", float, 0.2, 0.2, "the roughness where it reaches alpha_max, action units"),
        Field("lowpass_rough", str, "ema", "ema", "ema | median: the roughness estimate"),
        Field("lowpass_lag", str, "trail", "trail", "trail | compensate: a filtered target's lag behind a steady move",
              experimental="compensate failed its confirmation, in no preset: docs/decisions/13-robust-lowpass.md",
              experimental_values=("compensate",)),
    )),
)
_DECLARED: tuple = (*CORE_FIELDS, *((f"{c.name} (core/corrections/{c.name}.py)", c.fields) for c in CORRECTIONS
                                    if c.fields), *LATE_FIELDS)
EXPERIMENTAL_GROUP = "experimental: failed their confirmation, in no preset; warned of once when set"
# The fields by concept, in the class's order: each group's kept fields, then the experimental fields (a Field whose
# `experimental` says why and which has no experimental_values: the whole field is experimental) in one group.
GROUPS: tuple = (*((h, kept) for h, fs in _DECLARED
                   if (kept := tuple(f for f in fs if not (f.experimental and not f.experimental_values)))),
                 (EXPERIMENTAL_GROUP, tuple(f for _, fs in _DECLARED for f in fs
                                            if f.experimental and not f.experimental_values)))
FIELDS: tuple = tuple(f for _, fs in GROUPS for f in fs)
# What the paper's main text sets where the shipped default departs from it.
PAPER: dict = {f.name: f.paper for f in FIELDS if f.paper != f.default}

# The saved form (to_dict, a policy_postprocessor.json) carries CONFIG_VERSION. A dict without a version that holds
# every field of the first saved form (SAVED_V0, lerobot-physvla 0.1) is a file saved before versions: version 0.
# from_dict brings a saved dict up one version at a time (UPGRADES[v]: its renamed fields, then the fields it lacks
# at the value that keeps it acting as it did), then fills what is still unnamed from the shipped default. Adding a
# field means a new version: CONFIG_VERSION + 1 and an UPGRADES entry giving the field's value from before it.
CONFIG_VERSION = 12
SAVED_V0 = frozenset({"alpha_temporal", "alpha_transport", "beta", "cap", "chunk", "d_thresh_m", "delta_grasp_m",
                      "dls_damping", "el_mode", "eps_nm", "grasp_offset_m", "gripper_rule", "h_lift_m", "layout",
                      "lift_bias_m", "mode", "r0_nm", "weighting"})
# Renamed fields: {old name: new name}; the old names are accepted with a warning (once) wherever names are given.
ALIASES: dict[str, str] = {"redirect_tol_m": "place_tol_m", "redirect_gain": "place_gain"}
# {version: ({old name: new name}, {field: value for a dict of that version without it})}. Version 0 -> 1: the
# renames, and every field added after the paper's main text at its paper value (the option off) as before it existed.
# Version 1 -> 2: approach_pull_m, at 0 (off) as before it existed; 2 -> 3: centre_guide_straddle, off; 3 -> 4:
# carry_far_m, at 0 (off); 4 -> 5: approach_pull_stall_steps, at 0 (off); 5 -> 6: approach_pull_handback, off; 6 -> 7:
# approach_pull_open_handback, off; 7 -> 8: approach_pull_heading_u, at 0 (off);
# 8 -> 9: carry_clear_m, at 0 (off); 9 -> 10: centre_guide_clears, off; 10 -> 11: veto_hold_to_top, off;
# 11 -> 12: lift_assist_needs_close, off.
UPGRADES: dict[int, tuple[dict, dict]] = {0: (ALIASES, PAPER), 1: ({}, {"approach_pull_m": 0.0}),
                                          2: ({}, {"centre_guide_straddle": False}), 3: ({}, {"carry_far_m": 0.0}),
                                          4: ({}, {"approach_pull_stall_steps": 0}),
                                          5: ({}, {"approach_pull_handback": False}),
                                          6: ({}, {"approach_pull_open_handback": False}),
                                          7: ({}, {"approach_pull_heading_u": 0.0}),
                                          8: ({}, {"carry_clear_m": 0.0}),
                                          9: ({}, {"centre_guide_clears": False}),
                                          10: ({}, {"veto_hold_to_top": False}),
                                          11: ({}, {"lift_assist_needs_close": False})}
_WARNED: set = set()


def _warn_once(key: str, message: str) -> None:
    if key not in _WARNED:
        _WARNED.add(key)
        warnings.warn(message, UserWarning, stacklevel=4)


def renamed(changes: dict) -> dict:
    """`changes` with old field names (ALIASES) replaced by their new ones, each warned of once."""
    out = dict(changes)
    for old, new in ALIASES.items():
        if old in out:
            _warn_once(f"alias:{old}", f"physvla: {old} is now {new}; the old name will go in a later version")
            if new in out:
                raise ValueError(f"physvla: {old} and {new} are one field ({new}); give it once")
            out[new] = out.pop(old)
    return out


def upgraded(d: dict) -> dict:
    """A saved or partial configuration dict as the current version names it (module note above CONFIG_VERSION):
    a saved dict's missing fields at what they were before they existed; a partial one's left unnamed."""
    d = dict(d)
    version = d.pop("version", None)
    if version is None:
        version = 0 if SAVED_V0 <= d.keys() else CONFIG_VERSION
    if not (isinstance(version, int) and 0 <= version <= CONFIG_VERSION):
        raise ValueError(f"physvla: configuration version {version!r} is not one this lerobot-physvla reads "
                         f"(0 .. {CONFIG_VERSION}); a newer one saved it: upgrade lerobot-physvla")
    for v in range(version, CONFIG_VERSION):
        names, before = UPGRADES[v]
        d = {names.get(k, k): x for k, x in d.items()}
        d = {**before, **d}
    return renamed(d)


def experimental_set(c) -> list[str]:
    """The experimental options (Field.experimental) configuration `c` sets, as `name=value`."""
    out = []
    for f in FIELDS_BY_NAME.values():
        v = getattr(c, f.name)
        if f.experimental and (v in f.experimental_values if f.experimental_values else v != f.default):
            out.append(f"{f.name}={v!r}")
    return out


def _doc() -> str:
    lines = ["The corrector's configuration. `PhysVLAConfig()` is the shipped default, what",
             "`--policy.postprocess=physvla` applies; `PhysVLAConfig.paper(**changes)` is the paper's main text",
             "with every option beyond it off; `preset(name, **changes)` any named preset (PRESETS). Every field",
             "is a `--physvla.<field>` flag; docs/method.md gives its equation, unit and evidence. The fields, by",
             "concept (a correction's own fields are declared in its file, core/corrections/):", ""]
    for heading, fields in GROUPS:
        lines.append(heading.capitalize())
        lines += [f"    {f.name}: {f.doc}." for f in fields]
    return "\n".join(lines)


@dataclass
class PhysVLAConfig:
    # (the docstring is written from the fields' declarations below the class: _doc())
    # what runs, on which action vector
    mode: Mode = "phys"
    layout: str | ActionLayout = "libero_osc_pose"
    # the blender (eq. 2)
    cap: float = 0.05
    phase_caps: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0)
    chunk_phase_caps: tuple[float, ...] = ()
    chunk: ChunkMode = "all"
    gripper_rule: GripperRule = "veto"
    # the phase machine (eq. 3)
    geometry: Geometry = "scene"
    delta_grasp_m: float = 0.06
    h_lift_m: float = 0.02
    phase_ref: PhaseRef = "object"
    # the gripper veto (gripper_rule=veto)
    veto_height_m: float = 0.06
    veto_reach_m: float = 0.1
    veto_reopen: bool = False
    # the place phase's correction
    place_rule: PlaceRule = "release_veto"
    place_tol_m: float = 0.02
    place_gain: float = 0.5
    # the pose the corrections read (the object's and the target's)
    pose_error_m: float = 0.0
    pose_max_age_steps: int = 5
    pose_noise_m: float = 0.0
    # approach_pull (core/corrections/approach_pull.py)
    approach_pull_m: float = 0.10
    approach_pull_heading_u: float = 0.3
    # approach_veto (core/corrections/approach_veto.py)
    close_meets_onset: bool = False
    veto_hold_to_top: bool = True
    # carry_to_target (core/corrections/carry_to_target.py)
    carry_far_m: float = 0.10
    carry_clear_m: float = 0.05
    # centre_guide (core/corrections/centre_guide.py)
    centre_guide: bool = True
    centre_guide_trailing: bool = False
    # grasp_guidance (core/corrections/grasp_guidance.py)
    beta: float = 0.0
    grasp_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    # lift_assist (core/corrections/lift_assist.py)
    lift_assist_u: float = 0.5
    lift_assist_at_rest: bool = True
    lift_assist_needs_close: bool = True
    # place_deceleration (core/corrections/place_deceleration.py)
    d_thresh_m: float = 0.08
    # release_assist (core/corrections/release_assist.py)
    release_assist_m: float = 0.04
    assist_steps: int = 10
    assist_still: AssistStill = "hand"
    release_assist_error_k: float = 1.0
    # release_veto (core/corrections/release_veto.py)
    hold_steps: int = 40
    release_carry: bool = True
    # rim_guide (core/corrections/rim_guide.py)
    rim_guide_m: float = 0.047
    # temporal_ema (core/corrections/temporal_ema.py)
    alpha_temporal: float = 0.85
    # transport_smoothing (core/corrections/transport_smoothing.py)
    lift_bias_m: float = 0.0
    alpha_transport: float = 0.0
    # Branch B (eq. 4-6)
    el_mode: ElMode = "soft"
    weighting: Weighting = "joint_diag"
    eps_nm: float = 0.05
    r0_nm: float = 1.5
    dls_damping: float = 0.01
    # the adaptive low-pass (core/lowpass.py)
    lowpass: LowpassRule = "off"
    lowpass_phases: str = "approach,grasp,transport,place"
    lowpass_space: LowpassSpace = "action"
    lowpass_alpha_max: float = 0.6
    lowpass_rough_lo: float = 0.05
    lowpass_rough_hi: float = 0.2
    lowpass_rough: LowpassRough = "ema"
    lowpass_lag: LowpassLag = "trail"
    # experimental: options that failed their confirmation and sit in no preset (each field's `experimental` says
    # why); settable, warned of once when set, listed apart in --physvla.help
    approach_pull_stall_steps: int = 0
    approach_pull_handback: bool = False
    approach_pull_open_handback: bool = False
    veto_close_lead_s: float = 0.0
    close_meets: bool = False
    centre_guide_once: bool = False
    centre_guide_yield_steps: int = 0
    centre_guide_straddle: bool = False
    centre_guide_clears: bool = False
    rim_guide_into_grasp: bool = False
    lowpass_speed_hi: float = 0.0

    @classmethod
    def paper(cls, **changes) -> PhysVLAConfig:
        """The paper's main text (eq. 2 with c = 0.05, Phys + Dyn: phys_el), every option beyond it off."""
        return cls(**{**PAPER, **renamed(changes)})

    def __post_init__(self) -> None:
        self.validate()
        for name in experimental_set(self):
            f = FIELDS_BY_NAME[name.partition("=")[0]]
            _warn_once(f"experimental:{name}", f"physvla: {name} is experimental ({f.experimental})")

    def validate(self) -> None:
        """ValueError (one line, saying what to set) for a configuration the corrector cannot run; the
        corrections check their own fields (`Correction.check`)."""
        for name, value, allowed in (
            ("mode", self.mode, MODES),
            ("el_mode", self.el_mode, EL_MODES),
            ("weighting", self.weighting, WEIGHTINGS),
            ("gripper_rule", self.gripper_rule, GRIPPER_RULES),
            ("chunk", self.chunk, CHUNK_MODES),
            ("place_rule", self.place_rule, PLACE_RULES),
            ("phase_ref", self.phase_ref, PHASE_REFS),
            ("geometry", self.geometry, GEOMETRIES),
            ("lowpass", self.lowpass, LOWPASS_RULES),
            ("lowpass_space", self.lowpass_space, LOWPASS_SPACES),
            ("lowpass_rough", self.lowpass_rough, LOWPASS_ROUGH),
            ("lowpass_lag", self.lowpass_lag, LOWPASS_LAGS),
        ):
            if value not in allowed:
                raise ValueError(f"physvla: unknown {name} {value!r}; choose one of {', '.join(allowed)}")
        if isinstance(self.layout, str) and self.layout not in LAYOUTS:
            raise ValueError(
                f"physvla: unknown action layout {self.layout!r}; choose one of {', '.join(LAYOUTS)} "
                "or pass an ActionLayout"
            )
        if not 0.0 <= self.cap <= 1.0:
            raise ValueError(f"physvla: cap must lie in [0, 1], got {self.cap}")
        for name in ("delta_grasp_m", "h_lift_m", "dls_damping"):
            if not getattr(self, name) > 0:
                raise ValueError(f"physvla: {name} must be > 0, got {getattr(self, name)}")
        if not 0 <= self.eps_nm < self.r0_nm:
            raise ValueError(f"physvla: need 0 <= eps_nm < r0_nm, got {self.eps_nm}, {self.r0_nm}")
        for name in ("phase_caps", "chunk_phase_caps"):
            caps = getattr(self, name)
            if len(caps) not in (0, 4) or not all(0.0 <= c <= 1.0 for c in caps):
                raise ValueError(f"physvla: {name} needs 4 values in [0, 1] (approach, grasp, transport, place) "
                                 f"or none, got {caps}")
        unknown = [p for p in self.lowpass_phases.replace(" ", "").split(",") if p and p not in PHASE_NAMES]
        if unknown:
            raise ValueError(f"physvla: unknown lowpass phase(s) {unknown}; choose from {', '.join(PHASE_NAMES)}")
        if not self.lowpass_speed_hi >= 0.0:
            raise ValueError(f"physvla: lowpass_speed_hi must be >= 0, got {self.lowpass_speed_hi}")
        if not 0.0 <= self.lowpass_alpha_max < 1.0:
            raise ValueError(f"physvla: lowpass_alpha_max must lie in [0, 1), got {self.lowpass_alpha_max}")
        if not 0.0 <= self.lowpass_rough_lo < self.lowpass_rough_hi:
            raise ValueError("physvla: need 0 <= lowpass_rough_lo < lowpass_rough_hi, got "
                             f"{self.lowpass_rough_lo}, {self.lowpass_rough_hi}")
        if not 0.0 <= self.pose_error_m < float("inf"):
            raise ValueError(f"physvla: pose_error_m must be a finite distance >= 0 (m), got {self.pose_error_m}")
        if not 0.0 <= self.pose_noise_m < float("inf"):
            raise ValueError(f"physvla: pose_noise_m must be a finite standard deviation >= 0 (m), got "
                             f"{self.pose_noise_m}")
        if not (isinstance(self.pose_max_age_steps, int) and self.pose_max_age_steps >= 0):
            raise ValueError(f"physvla: pose_max_age_steps must be an int >= 0 (control steps), got "
                             f"{self.pose_max_age_steps!r}")
        if not 0.0 <= self.place_tol_m < float("inf"):
            raise ValueError(f"physvla: place_tol_m must be a finite distance >= 0 (m), got {self.place_tol_m}")
        if not 0.0 < self.place_gain < float("inf"):
            raise ValueError(f"physvla: place_gain must be > 0 (action units per unit of error), got {self.place_gain}")
        if not (self.veto_height_m >= 0 and self.veto_reach_m >= 0):
            raise ValueError(f"physvla: need veto_height_m >= 0 and veto_reach_m >= 0, got {self.veto_height_m}, "
                             f"{self.veto_reach_m}")
        for c in CORRECTIONS:
            if c.check is not None:
                c.check(self)

    @property
    def caps(self) -> tuple[float, ...]:
        """The blender's authority per phase (approach, grasp, transport, place): 4 values."""
        return tuple(self.phase_caps) if self.phase_caps else (self.cap,) * 4

    @property
    def pose_error_told_m(self) -> float:
        """The pose error the corrections answer to, m: pose_error_m, plus twice the noise the pose filter leaves
        (core/pose_filter.py residual_m) where pose_noise_m turns it on."""
        return self.pose_error_m + 2.0 * residual_m(self.pose_noise_m)

    @property
    def lifted_m(self) -> float:
        """Eq. 3's "lifted" threshold as the corrector applies it, m: h_lift_m + the pose error told (an error alone
        never says "lifted")."""
        return self.h_lift_m + self.pose_error_told_m

    def for_policy(self, actions_per_call: int) -> PhysVLAConfig:
        """The configuration for a policy that executes `actions_per_call` actions of each policy call
        open loop (1: a single-step policy; ACT / Diffusion: their n_action_steps): chunk_phase_caps
        become the phase caps where it is set and the policy executes chunks; else self unchanged."""
        if self.chunk_phase_caps and actions_per_call > 1:
            return self.replace(phase_caps=tuple(self.chunk_phase_caps), chunk_phase_caps=())
        return self

    @property
    def lowpass_mask(self) -> tuple[bool, ...]:
        names = set(self.lowpass_phases.replace(" ", "").split(","))
        return tuple(p in names for p in PHASE_NAMES)

    @property
    def action_layout(self) -> ActionLayout:
        return LAYOUTS[self.layout] if isinstance(self.layout, str) else self.layout

    def replace(self, **changes) -> PhysVLAConfig:
        return dataclasses.replace(self, **renamed(changes))

    def to_dict(self) -> dict:
        """The saved form: every field, and `version` (CONFIG_VERSION)."""
        d = {"version": CONFIG_VERSION, **dataclasses.asdict(self)}
        if isinstance(self.layout, ActionLayout):
            d["layout"] = dataclasses.asdict(self.layout)
        d["grasp_offset_m"] = list(self.grasp_offset_m)
        d["phase_caps"] = list(self.phase_caps)
        d["chunk_phase_caps"] = list(self.chunk_phase_caps)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> PhysVLAConfig:
        """From to_dict()'s form (a saved policy_postprocessor.json) or a partial dict ({"cap": 0.1}): a saved
        file of an older version acts as it did (`upgraded`: its missing fields at their values from before they
        existed, old names renamed); the fields nobody named are the shipped default's."""
        d = upgraded(d)
        unknown = set(d) - {f.name for f in dataclasses.fields(cls)}
        if unknown:
            raise ValueError(f"physvla: unknown config keys {sorted(unknown)}")
        if isinstance(d.get("layout"), dict):
            lay = dict(d["layout"])
            lay["pos"] = tuple(lay["pos"])
            lay["rot"] = tuple(lay.get("rot", ()))
            d["layout"] = ActionLayout(**lay)
        for key in ("grasp_offset_m", "phase_caps", "chunk_phase_caps"):
            if key in d:
                d[key] = tuple(d[key])
        return cls(**d)


PhysVLAConfig.__doc__ = _doc()
FIELDS_BY_NAME: dict = {f.name: f for f in FIELDS}


def _declared_as_annotated() -> None:
    """ImportError naming the line to add or remove where the class's fields are not the declared ones, in order."""
    have = [f.name for f in dataclasses.fields(PhysVLAConfig)]
    want = [f.name for f in FIELDS]
    if have != want:
        missing = [f for f in FIELDS if f.name not in have]
        extra = [n for n in have if n not in want]
        say = "; ".join([f"add `{f.name}: {getattr(f.type, '__name__', f.type)} = {f.default!r}` under its group"
                         for f in missing] + [f"remove `{n}` (no file declares it)" for n in extra]) or \
            "order its fields as the declarations are ordered (CORE_FIELDS, the corrections by file name, LATE_FIELDS)"
        raise ImportError(f"physvla: PhysVLAConfig (core/config.py) and the declared fields differ: {say}")


_declared_as_annotated()


# Named presets. `default` is what `--policy.postprocess=physvla` applies with no further flag and what
# PhysVLAConfig() gives, chosen by measurement (docs/method.md "Presets", docs/decisions/); the paper's two
# readings stay one flag away.
PRESETS: dict[str, PhysVLAConfig] = {
    # the main text: eq. (2), a = (1 - c) a_raw + c a_B with c = 0.05, Phys + Dyn (phys_el)
    "paper": PhysVLAConfig.paper(),
    # the supplement's Algorithm 1: Phys executes a_phys in full, Dyn blends w a_phys + (1 - w) a_raw
    "paper_alg1": PhysVLAConfig.paper(cap=1.0),
    # beyond the paper: only corrections that are right from the state alone (docs/method.md): the gripper
    # veto where no finger can reach the object (never opening a closed gripper), the release veto where the
    # held object would land more than 2 cm off the target, the release assist for a still hold over the
    # target, the lift assist for a still, closed, unlifted hold, the rim guide for a hand settled beside
    # the object; the paper's grasp guidance, transport EMA and place deceleration off; and, for a policy whose
    # object or target moved (LIBERO-PRO), the approach pull, which takes a hand that closes 10 cm or more from the
    # object, standing there (not on its way to it), to the object and carries what it lifts over the target, and
    # the carry to the target, which carries an object the policy lowers 10 cm or more from the target over it,
    # never lower than 5 cm over where it rested, with the transport phase given the authority for the carry and
    # its smoothing and lift bias the identity (docs/decisions/29, 30, 35, 36); a close the height veto holds at its
    # onset is held until the pads' centres are at the object's top, and a hand held wide open is no hold for the
    # lift assist (docs/decisions/39)
    "default": PhysVLAConfig(),
}
# The default's fields before the approach pull and the carry joined it (docs/decisions/36-shift-shipped.md): the
# presets measured on it keep them.
BEFORE_PULL: dict = {"approach_pull_m": 0.0, "approach_pull_heading_u": 0.0, "carry_far_m": 0.0,
                     "carry_clear_m": 0.0, "phase_caps": (1.0, 1.0, 0.0, 1.0), "alpha_transport": 0.92,
                     "lift_bias_m": 0.02}
# ... and before a close held at its onset was held to the object's top, with the lift assist taking no wide-open
# hand for a hold (docs/decisions/39-hold-to-top.md)
BEFORE_HOLD: dict = {"veto_hold_to_top": False, "lift_assist_needs_close": False}
# on robot arms (lerobot-rollout): the approach veto alone. The release veto, let go the moment the
# held object is within 2 cm of the target, flung blocks the simulated SO-101 carried at transport
# speed (eval/results/so101_faults), so it stays off on arms until a rule that knows the object's
# speed and height is measured. The lift assist (candidate 15) and the rim guide (candidate 18) are off
# there too: they were measured on LIBERO's delta-pose arm and its bowls only, and they would move the
# arm with the grasp and approach phases' authority; so is the centre guide, measured in simulation only.
PRESETS["arm"] = PRESETS["default"].replace(**{**BEFORE_PULL, **BEFORE_HOLD, "phase_caps": (0.0, 0.0, 0.0, 0.0)},
                                            place_rule="decelerate", release_assist_m=0.0, lift_assist_u=0.0,
                                            lift_assist_at_rest=False, rim_guide_m=0.0, centre_guide=False, beta=0.5)
# for a policy that shakes: the default + a low-pass before and after the carry whose strength follows
# the policy's own measured roughness (the median of its last 9 second differences), so a policy that
# does not shake is left alone (candidate 14's settings). On blocks no decision about it looked at
# (docs/decisions/21-smooth-preset.md): the jittery expert's jerk x0.49 of uncorrected, the Lift / Fetch
# noise sweeps' jerk-degradation ratio 3.96 / 4.78 (the paper's Table A1 asks ~10), every learned ACT
# within 1 pair of the default; the trade: the jittery expert succeeds 6 pp less than under the
# default (2 won / 5 lost), which is why it is not the default.
PRESETS["smooth"] = PRESETS["default"].replace(**BEFORE_PULL, **BEFORE_HOLD, lowpass="adaptive", lowpass_space="target",
                                               lowpass_alpha_max=0.8, lowpass_rough="median",
                                               lowpass_phases="approach,grasp,place")
# `shift`: the name the default's approach pull and carry had while they were opt-in
# (docs/decisions/36-shift-shipped.md)
PRESETS["shift"] = PRESETS["default"]
DEFAULT_PRESET = "default"
ARM_PRESET = "arm"


def preset(name: str = DEFAULT_PRESET, **overrides) -> PhysVLAConfig:
    """A named preset (PRESETS) with fields overridden, e.g. preset("paper", mode="phys")."""
    if name not in PRESETS:
        raise ValueError(f"physvla: unknown preset {name!r}; choose one of {', '.join(PRESETS)}")
    return PRESETS[name].replace(**overrides)


def differing(c: PhysVLAConfig, name: str) -> dict:
    """{field: value} where `c` departs from preset `name`."""
    base = PRESETS[name]
    return {f.name: getattr(c, f.name) for f in FIELDS if getattr(c, f.name) != getattr(base, f.name)}
