"""The scene's geometry, read from a MuJoCo model: how big the object and the target are, how wide the hand opens.

    Extent   an object's or target's box about its origin at rest, world axes, metres: the union of
             its collision geoms (the body and every body under it), or a region site's box
    Hand     the gripper: its widest opening and its finger pads' half sizes, metres

The corrector's distances are expressed relative to these (core/geometry.py says which quantity
each one stands for), so the same configuration fits a bowl, a can and a bottle.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import mujoco
import numpy as np

_CORNERS = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))  # (8, 3) unit box corners


@dataclass(frozen=True)
class Extent:
    """An axis-aligned box about a body's or site's origin, world axes, metres.

    Attributes:
        lo, hi: its lower and upper corners relative to the origin (x, y, z), m.
    """

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    @property
    def radius_m(self) -> float:
        """The larger horizontal half-extent: how far its edge reaches from its origin, m."""
        return float(max(-self.lo[0], self.hi[0], -self.lo[1], self.hi[1]))

    @property
    def half_width_m(self) -> float:
        """The narrower horizontal half-extent (half of the width a hand closes across), m."""
        return float(min((self.hi[0] - self.lo[0]) / 2, (self.hi[1] - self.lo[1]) / 2))

    @property
    def top_m(self) -> float:
        """Its top above its origin, m."""
        return float(self.hi[2])

    @property
    def bottom_m(self) -> float:
        """Its bottom above its origin (negative: below), m."""
        return float(self.lo[2])


@dataclass(frozen=True)
class Hand:
    """A parallel gripper's geometry, metres.

    Attributes:
        span_m: its widest opening, the fingers' joint ranges summed.
        pad_half_width_m: a finger pad's half width across the closing direction (0 where it has no pads).
        pad_half_height_m: a finger pad's half height (0 where it has no pads).
    """

    span_m: float
    pad_half_width_m: float = 0.0
    pad_half_height_m: float = 0.0


def subtree(model: mujoco.MjModel, body_id: int) -> list[int]:
    """The body and every body under it."""
    out = [body_id]
    for b in range(body_id + 1, model.nbody):  # MuJoCo numbers a child after its parent
        if model.body_parentid[b] in out:
            out.append(b)
    return out


def body_extent(model: mujoco.MjModel, data: mujoco.MjData, body_id: int) -> Extent:
    """The box of the collision geoms (contype or conaffinity set) of a body and its subtree, about its origin, in
    the world axes of `data`'s pose; ValueError where it has none."""
    bodies = subtree(model, body_id)
    geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] in bodies
             and (model.geom_contype[g] or model.geom_conaffinity[g])]
    if not geoms:
        raise ValueError(f"physvla: body {model.body(body_id).name!r} has no collision geom to measure")
    pts = []
    for g in geoms:
        centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        rot = data.geom_xmat[g].reshape(3, 3)
        pts.append(data.geom_xpos[g] + (centre + _CORNERS * half) @ rot.T)
    pts = np.concatenate(pts) - data.xpos[body_id]
    return Extent(tuple(pts.min(axis=0).tolist()), tuple(pts.max(axis=0).tolist()))


def site_extent(model: mujoco.MjModel, data: mujoco.MjData, site_id: int) -> Extent:
    """The box of a site about its own origin (a LIBERO region: a box site, its size the half extents), world
    axes; a sphere or cylinder site by its radius (and half height)."""
    size = np.asarray(model.site_size[site_id], dtype=float)
    kind = model.site_type[site_id]
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        half = np.array([size[0]] * 3)
    elif kind in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE):
        half = np.array([size[0], size[0], size[1]])
    else:
        half = size[:3]
    pts = (_CORNERS * half) @ data.site_xmat[site_id].reshape(3, 3).T
    return Extent(tuple(pts.min(axis=0).tolist()), tuple(pts.max(axis=0).tolist()))


def hand(model: mujoco.MjModel, finger_joints: list[int], pad_geoms: list[int] = ()) -> Hand:
    """A parallel gripper from its finger joints (slide joints: their ranges' spans summed, m) and its finger pads
    (box geoms: the larger of their first two half sizes is the pad's half width, the third its half height)."""
    if not finger_joints:
        raise ValueError("physvla: no finger joints to measure the hand's span from")
    span = float(sum(abs(model.jnt_range[j, 1] - model.jnt_range[j, 0]) for j in finger_joints))
    if not pad_geoms:
        return Hand(span)
    half = np.array([model.geom_size[g] for g in pad_geoms])
    return Hand(span, float(half[:, :2].max()), float(half[:, 2].max()))


def close_time(model: mujoco.MjModel, data: mujoco.MjData, opening, open_fingers, close_command, width_m: float,
               horizon_s: float = 1.0) -> float:
    """How long the fingers take to close from wide open to `width_m` (the object's width), s: the model simulated
    on a copy of `data` (the live simulation is never written) with the gripper's own close command.

    opening(d) -> m: the fingers' opening in a MjData; open_fingers(d): sets a copy's fingers wide open and at rest;
    close_command(d): writes the close command into a copy's ctrl before each physics step (through the gripper's
    own controller, so a ramped command is timed as it acts). NaN where the fingers do not reach `width_m` within
    `horizon_s`, or where `width_m` is not below the opening they start from (an object the hand cannot close across).
    """
    import copy

    s = copy.copy(data)
    open_fingers(s)
    mujoco.mj_forward(model, s)
    start = opening(s)
    if not 0.0 < width_m < start:
        return float("nan")
    for k in range(1, int(horizon_s / model.opt.timestep) + 1):
        close_command(s)
        mujoco.mj_step(model, s)
        if opening(s) <= width_m:
            return k * float(model.opt.timestep)
    return float("nan")
