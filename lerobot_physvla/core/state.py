"""The physical state s_t the corrector reads: one record per env, batched over B envs.

`PhysState` holds B envs as arrays (struct of arrays), so the corrector works on all envs at
once. It also packs to / unpacks from one flat float vector per env with a fixed layout, which
is how state crosses process boundaries (async vector envs) and LeRobot observation dicts.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

# Why the corrector passed an env's action through unchanged (status codes of its kernels).
# missing_pose: the object's or the target's pose is not finite (the state source has none); stale_pose: the
# pose is older than the configuration's pose_max_age_steps (the `pose_age` field); unsupported_goal: the
# source says the task is outside what the corrector models (`valid` = UNSUPPORTED_GOAL_VALID).
REASONS = ("ok", "invalid_state", "nonfinite_state", "nonfinite_action", "singular_dynamics", "nonfinite_output",
           "invalid_dt", "missing_pose", "stale_pose", "unsupported_goal")
(OK, INVALID_STATE, NONFINITE_STATE, NONFINITE_ACTION, SINGULAR, NONFINITE_OUTPUT, INVALID_DT, MISSING_POSE,
 STALE_POSE, UNSUPPORTED_GOAL) = range(10)
UNSUPPORTED_GOAL_VALID = -1.0  # `valid` of a state whose task has no grasp-carry-place of one object to model
# What the safety net did to an emitted action (Corrector.guard_counts).
GUARDS = ("none", "clipped_to_bounds", "held_nonfinite_action")
GUARD_NONE, GUARD_CLIPPED, GUARD_HELD = range(3)

# Fields in packing order: (name, shape given the arm's joint count n).
_FIELDS = (
    ("valid", lambda n: ()),  # 1.0 read successfully; 0.0 not read; -1.0 the task is outside the model
    ("episode_step", lambda n: ()),  # control steps since the env's last reset (0 at reset)
    ("dt", lambda n: ()),  # control period, s
    ("eef_pos", lambda n: (3,)),  # end-effector position, m (world)
    ("gripper", lambda n: ()),  # gripper opening, m
    ("obj_pos", lambda n: (3,)),  # manipulated object position, m
    ("obj_rest_z", lambda n: ()),  # object's resting height (read at reset), m
    ("target_pos", lambda n: (3,)),  # target (e.g. plate) position, m
    ("q", lambda n: (n,)),  # arm joint positions, rad
    ("qdot", lambda n: (n,)),  # arm joint velocities, rad/s
    ("M", lambda n: (n, n)),  # arm block of the joint-space inertia matrix, kg m^2
    ("bias", lambda n: (n,)),  # C(q, qdot) qdot + G(q), N m
    ("tau", lambda n: (n,)),  # applied joint torques (actuator + applied), N m
    ("J_pos", lambda n: (3, n)),  # translational Jacobian of the end-effector, m/rad
    # control steps since the object and target poses were observed (the older of the two; 0 = this step, as
    # a simulator's exact state always is)
    ("pose_age", lambda n: ()),
    # the scene's geometry (SCENE: the object's and the target's extents, the hand's; sources/geometry.py), m;
    # NaN where the source does not measure it (the corrector then uses its fixed distances)
    ("scene", lambda n: (len(SCENE),)),
    # how long the fingers take to close from wide open to the object's narrower width, s, simulated on the
    # source's own model at reset (sources/geometry.py close_time); NaN where not measured
    ("close_time", lambda n: ()),
)
# What `scene` holds, in order (metres): the object's larger horizontal half-extent (its radius), its narrower
# horizontal half-extent, its top above its origin; the target's narrower horizontal half-extent; the hand's widest
# opening, its finger pads' half width and half height.
SCENE = ("obj_radius", "obj_half_width", "obj_top", "target_half_width", "hand_span", "pad_half_width",
         "pad_half_height")
# Fields appended after the first layout, oldest first, with what a packed state written before each existed
# reads as: pose_age 0 (its source read the simulator's exact pose), scene and close time unknown. Every earlier
# field keeps its offset, so a shorter packed state is the current one cut after some of these (`upgrade`).
APPENDED = (("pose_age", 0.0), ("scene", float("nan")), ("close_time", float("nan")))


@functools.lru_cache(maxsize=None)
def packed_size(n_joints: int) -> int:
    """Length of the flat vector that holds one env's state for an arm of n_joints."""
    return sum(int(np.prod(shape(n_joints), dtype=int)) for _, shape in _FIELDS)


@functools.lru_cache(maxsize=None)
def _layout(n_joints: int) -> tuple[tuple[str, int, int, tuple[int, ...]], ...]:
    """(name, start, length, shape) of every field, in packing order."""
    out, i = [], 0
    for name, shape in _FIELDS:
        s = shape(n_joints)
        k = int(np.prod(s, dtype=int))
        out.append((name, i, k, s))
        i += k
    return tuple(out)


@functools.lru_cache(maxsize=None)
def field_offsets(n_joints: int) -> dict[str, int]:
    """Start of each field in the packed vector (the kernels read the packed rows directly); cached,
    read-only: the step reads it every control tick."""
    out, i = {}, 0
    for name, shape in _FIELDS:
        out[name] = i
        i += int(np.prod(shape(n_joints), dtype=int))
    return out


def _appended_sizes(n_joints: int) -> list[tuple[int, np.ndarray]]:
    """(length, the fill of what it lacks) of each shorter layout a packed state was once written in, newest first."""
    shapes = dict((name, shape(n_joints)) for name, shape in _FIELDS)
    out, size, tail = [], packed_size(n_joints), []
    for name, fill in reversed(APPENDED):
        k = int(np.prod(shapes[name], dtype=int))
        size -= k
        tail = [np.full(k, fill)] + tail
        out.append((size, np.concatenate(tail)))
    return out


@functools.lru_cache(maxsize=None)
def n_joints_from_size(size: int) -> int:
    """Inverse of packed_size (a packed state written before some of the APPENDED fields existed too: every
    field it has at the same offset); raises if no joint count gives this length."""
    for n in range(1, 64):
        if packed_size(n) == size or any(k == size for k, _ in _appended_sizes(n)):
            return n
    raise ValueError(f"physvla: a packed state of length {size} matches no arm joint count")


@functools.lru_cache(maxsize=None)
def is_legacy_size(size: int) -> bool:
    """A packed state written before some of the APPENDED fields existed (shorter than packed_size(n) by them)."""
    return any(k == size for n in range(1, 64) for k, _ in _appended_sizes(n))


def upgrade(flat: np.ndarray) -> np.ndarray:
    """A (B, L) packed state as the current layout holds it: one written before some of the APPENDED fields
    existed gets them as APPENDED says (pose_age 0, scene NaN); a current one is returned as it is."""
    if flat.ndim == 2 and is_legacy_size(flat.shape[1]):
        n = n_joints_from_size(flat.shape[1])
        fill = next(f for k, f in _appended_sizes(n) if k == flat.shape[1])
        return np.concatenate([np.asarray(flat, dtype=np.float64), np.tile(fill, (flat.shape[0], 1))], axis=1)
    return flat


@dataclass
class PhysState:
    """Physical state of B envs (see _FIELDS for each attribute's meaning and unit).

    A state made by `unpack` (or `empty`) keeps its fields as views into one (B, L) float64
    buffer, so in-place edits (`st.M[0] = ...`) show in `pack()` at no cost; rebinding a field
    (`st.M = ...`) detaches the buffer and `pack()` concatenates again.
    """

    valid: np.ndarray  # (B,) 1.0 = read successfully, 0.0 = not
    episode_step: np.ndarray  # (B,)
    dt: np.ndarray  # (B,)
    eef_pos: np.ndarray  # (B, 3)
    gripper: np.ndarray  # (B,)
    obj_pos: np.ndarray  # (B, 3)
    obj_rest_z: np.ndarray  # (B,)
    target_pos: np.ndarray  # (B, 3)
    q: np.ndarray  # (B, n)
    qdot: np.ndarray  # (B, n)
    M: np.ndarray  # (B, n, n)
    bias: np.ndarray  # (B, n)
    tau: np.ndarray  # (B, n)
    J_pos: np.ndarray  # (B, 3, n)
    pose_age: np.ndarray  # (B,) control steps
    scene: np.ndarray  # (B, len(SCENE)) m, NaN where not measured
    close_time: np.ndarray | None = None  # (B,) s, NaN where not measured (None: unmeasured, in pack())

    @property
    def batch_size(self) -> int:
        return self.eef_pos.shape[0]

    @property
    def n_joints(self) -> int:
        return self.q.shape[1]

    @classmethod
    def empty(cls, batch_size: int, n_joints: int) -> PhysState:
        """All-invalid state (the corrector passes every action through), its scene unmeasured (NaN)."""
        flat = np.zeros((batch_size, packed_size(n_joints)))
        flat[:, field_offsets(n_joints)["scene"]:] = np.nan
        return cls.unpack(flat)

    def __setattr__(self, name, value):
        d = self.__dict__
        if d.get("_flat") is not None and name != "_flat":
            d["_flat"] = None
        d[name] = value

    def pack(self) -> np.ndarray:
        """(B, packed_size(n)) float64 array with the fixed field layout (no copy when it has one)."""
        flat = self.__dict__.get("_flat")
        if flat is not None:
            return flat
        b = self.batch_size
        parts = [np.full((b, 1), np.nan) if getattr(self, name) is None  # close_time not given: unmeasured
                 else np.asarray(getattr(self, name), dtype=np.float64).reshape(b, -1) for name, _ in _FIELDS]
        return np.concatenate(parts, axis=1)

    @classmethod
    def unpack(cls, flat: np.ndarray) -> PhysState:
        """Inverse of pack, for a (B, L) or (L,) array; fields are views into it (made C-contiguous float64)."""
        flat = np.ascontiguousarray(flat, dtype=np.float64)
        if flat.ndim == 1:
            flat = flat[None]
        flat = upgrade(flat)  # a packed state from before pose_age, scene or close_time
        if flat.ndim != 2:
            raise ValueError(f"physvla: packed state must be (B, L), got shape {flat.shape}")
        b = flat.shape[0]
        out = {name: flat[:, i : i + k].reshape((b, *s)) for name, i, k, s in _layout(n_joints_from_size(flat.shape[1]))}
        st = cls(**out)
        object.__setattr__(st, "_flat", flat)
        return st

    def is_finite(self) -> np.ndarray:
        """(B,) True where every field of the env's record is finite (the scene aside: NaN there says unmeasured)."""
        return np.isfinite(self.pack()[:, : field_offsets(self.n_joints)["scene"]]).all(axis=1)
