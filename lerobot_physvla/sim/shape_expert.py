"""A scripted pick-and-place expert that grasps each object the way its shape asks (privileged state).

`ShapeExpert` is `experts.PickPlaceExpert`'s reach -> grasp -> lift -> transport -> place state machine
(same action layout, same gains, same injectable failure modes with the same config fields and random
draws), with its two fixed offsets replaced by a plan made from the scene's geometry: the object's
footprint (how wide it is across its narrow and its long side, and which way it lies), its height, the
hand's span, and the target's top. It also turns the wrist (the drz channel) and keeps the gripper
pointing down (drx, dry), which the bowl expert never needed.

Grasp rule (`plan_grasp`; widths are of the object's footprint, the hand's span is 8 cm on the Panda):
    centre grasp   the object's narrower footprint width <= span - 2 * fit_margin_m (cans, bottles, boxes,
                   the cream cheese, the wine bottle, an upright book): the grasp point is the footprint's
                   centre; the fingers close across the narrow side, the wrist turned to it (the smaller
                   turn, <= 90 deg) when the footprint is elongated (long / narrow >= elongated_ratio), no
                   turn for round or square footprints. Height: the object's middle, raised so that the
                   palm (2.4 cm above the grasp site on the Panda) clears the top (at most grasp_depth_m
                   below the top: a tall bottle is held by its upper body), and never lower than
                   table_clear_m above its bottom (the finger tips reach 1.3 cm below the site: a flat
                   box is held just above the table).
    rim grasp      wider than that (bowls, mugs, the moka pot): on the rim, at the footprint's half width
                   less a finger pad's half width from its centre, rim_depth_m below the top, on the side
                   (of -y, +y, -x, +x, in that order of preference) that reaches least far from the
                   object's origin (a mug's handle side reaches further), fingers closing across the
                   wall (a quarter turn of the wrist for the x sides).
    Neighbours: the rule's grasp is one of a few candidates (`grasp_candidates`: a slide of up to long/2 - 2 cm
                   along an elongated object's long side, the other rim sides, a quarter turn on a round
                   object), each costed by how much of the hand's footprint (palm 21 x 6.4 cm, fingers) would
                   sit over a taller neighbour (LIBERO's other objects and fixtures, `scene_obstacles`) at the
                   pick and at the place (`hand_overlap`), plus a small preference for the rule's own grasp:
                   the cheapest is taken (e.g. the bowl's +y rim when a cabinet stands on the plate's -y side).
                   The approach comes in with the finger tips 2 cm above every neighbour within 15 cm, then
                   descends straight down (a low approach sweeps a milk carton off its place).
Place rule (`plan_place`): the object's origin over the target's centre (a region site's centre, a body's
    origin: LIBERO's On / In predicates test the object's origin), its bottom `place_clear_m` above the
    target's support top, then released. The support top is the highest of the target's own top and the
    top of the body the target region belongs to (a basket's rim, a stove's burner, the cabinet's top): an
    In(basket) object is dropped in from just above the rim, an On(plate / stove / cabinet top / bowl)
    object is set down just above it. Where the target region is elongated (long / narrow >=
    elongated_ratio, e.g. a caddy compartment) and the object is held by a centre grasp, the wrist turns
    during the transport so that the object's long side follows the region's long side. The transport
    carries the object's bottom carry_clear_m above the higher of its resting bottom and the support top.
    The waypoints of the transport and the place are servoed on the object's position (the end effector
    moves by the object's error to its goal), so a grasp that holds the object off-centre still places it
    on the target.
Several sub-goals (LIBERO-10's two-object goals): `act_source` follows the state source's current sub-goal;
    when it switches, the current object is first released and the hand raised (a switch can come while the
    object is still held, as soon as it is In the basket), then the expert plans and picks the next one.

Coverage (all judged by the goal's BDDL predicates, `sources.robosuite.subgoals`):
    LIBERO-Object: all 10 tasks, In(<item>, basket_1_contain_region).
    LIBERO-Goal: the pick-place tasks 1, 2, 4, 6, 8, 9. Not tasks 0 (open a drawer) and 7 (turn on the
        stove): no On / In predicate. Task 3 ("open the top drawer and put the bowl inside"): its goal is only
        In(bowl, wooden_cabinet_1_top_region), but the region is inside a closed drawer, so the carry ends
        against the cabinet's front: it needs a drawer-opening skill (grasp the handle, pull along the slide)
        before the pick-place, which a grasp-carry-place machine does not have. Task 5 ("push the plate to the
        front of the stove"): On(plate_1, main_table_stove_front_region) is a place on paper, but the plate is
        14 cm wide and 1.9 cm tall, wider than the 8 cm span and too flat for a rim grasp above the table, so it
        has to be pushed (a contact move along the table), which this expert does not do.
    LIBERO-10: the tasks whose predicates are all On / In: 0, 1, 4, 5, 6, 7 (2, 3, 8, 9 also need a TurnOn or a
        Close of a door or drawer).

Construction and use:
    expert = ShapeExpert(cfg=ShapeExpertConfig(...))       # failure modes: ExpertConfig's fields
    expert.reset(seed)                                      # each episode, after the env's reset
    action = expert.act_source(source)                      # each step; source: RobosuiteStateSource
    or, geometry by hand (tests, other sims):
    expert.set_plan(plan_for(obj_shape, tgt_shape, support_top_z, hand, cfg))
    action = expert.act(eef_pos, obj_pos, target_pos, eef_yaw=..., obj_yaw=...)
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from lerobot_physvla.core.config import LIBERO_OSC_POSE, ActionLayout
from lerobot_physvla.sim.experts import ExpertConfig, PickPlaceExpert
from lerobot_physvla.sources.geometry import Hand

_CORNERS = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
_ROT_METRES = 0.5  # rad of OSC_POSE rotation goal per action unit on drx, dry, drz (robosuite's output_max)


@dataclass
class ShapeExpertConfig(ExpertConfig):
    """ExpertConfig (gains, hover height, every failure mode with its meaning unchanged) plus the shape rule's
    geometry, metres. `grasp_offset_m` and `place_offset_m` are not used: the plan replaces them.

    Attributes:
        fit_margin_m: room left on each side of an object inside the open hand for a centre grasp.
        elongated_ratio: long / narrow footprint width from which the wrist turns to the narrow side.
        grasp_depth_m: deepest the grasp site goes below an object's top (the palm must clear the top).
        table_clear_m: lowest the grasp site goes above the object's bottom (finger tips off the table).
        rim_depth_m: the grasp site below a rim's top.
        place_clear_m: the object's bottom above the target's support top at release.
        carry_clear_m: the object's bottom above the support top (and its rest) while carried.
        rot_gain: drz (and drx, dry) action units per radian of wrist error, times 0.5 rad per unit.
        rot_tol_rad: the wrist counts as turned within this.
        upright: keep the gripper pointing down with drx, dry.
    """

    fit_margin_m: float = 0.006
    elongated_ratio: float = 1.3
    grasp_depth_m: float = 0.022
    table_clear_m: float = 0.012
    rim_depth_m: float = 0.017
    place_clear_m: float = 0.015
    carry_clear_m: float = 0.05
    rot_gain: float = 0.5
    rot_tol_rad: float = 0.06
    upright: bool = True


@dataclass(frozen=True)
class Shape:
    """A horizontal footprint and height about an origin, world axes, metres.

    Attributes:
        centre_xy: the footprint's centre relative to the origin.
        narrow_yaw: world yaw (rad, in [0, pi)) of the direction across the narrower side.
        narrow_m, long_m: the footprint's width across its narrow side and along it.
        bottom_m, top_m: lowest and highest point above the origin.
        reach: how far the footprint reaches from the origin along -y, +y, -x, +x.
    """

    centre_xy: tuple[float, float]
    narrow_yaw: float
    narrow_m: float
    long_m: float
    bottom_m: float
    top_m: float
    reach: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    @property
    def ratio(self) -> float:
        return self.long_m / max(self.narrow_m, 1e-9)


def shape_from_points(pts: np.ndarray, step_deg: float = 1.0) -> Shape:
    """The Shape of a point cloud given relative to its origin (world axes): the narrow direction is the one of
    least width over yaws in [0, 180) deg (a rectangle's footprint: its short side, a disc's: any, taken as x)."""
    pts = np.asarray(pts, dtype=float).reshape(-1, 3)
    xy = pts[:, :2]
    yaws = np.radians(np.arange(0.0, 180.0, step_deg))
    dirs = np.stack([np.cos(yaws), np.sin(yaws)], axis=1)
    proj = xy @ dirs.T  # (N, K)
    width = proj.max(axis=0) - proj.min(axis=0)
    k = int(np.argmin(width))
    if width[0] - width[k] < 1e-4:  # ties (round, square): keep the world axes
        k = 0
    u = dirs[k]
    v = np.array([-u[1], u[0]])
    pu, pv = xy @ u, xy @ v
    c = u * (pu.max() + pu.min()) / 2 + v * (pv.max() + pv.min()) / 2
    reach = (-xy[:, 1].min(), xy[:, 1].max(), -xy[:, 0].min(), xy[:, 0].max())
    return Shape((float(c[0]), float(c[1])), float(yaws[k]), float(width[k]), float(pv.max() - pv.min()),
                 float(pts[:, 2].min()), float(pts[:, 2].max()), tuple(float(r) for r in reach))


def box_shape(lo, hi) -> Shape:
    """The Shape of an axis-aligned box about its origin (e.g. a geometry.Extent's lo, hi)."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    return shape_from_points(lo + (_CORNERS + 1) / 2 * (hi - lo))


@dataclass(frozen=True)
class Grasp:
    """Where and how the hand closes on an object.

    Attributes:
        kind: "centre" or "rim".
        offset: the grasp site's goal relative to the object's origin, world axes, m.
        yaw: world yaw (rad) of the fingers' closing direction; None: keep the wrist as it is.
    """

    kind: str
    offset: tuple[float, float, float]
    yaw: float | None


# The Panda hand's footprint about its grasp site, in the hand's frame (x: along the fingers' closing direction,
# y: across it), metres: (x lo, x hi, y half width, height of its lowest point above the site); measured from
# robosuite's Panda gripper collision geoms, fingers open.
HAND_PARTS = ((-0.105, 0.105, 0.032, 0.026), (-0.068, -0.032, 0.011, -0.012), (0.032, 0.068, 0.011, -0.012))


def grasp_candidates(shape: Shape, hand: Hand, cfg: ShapeExpertConfig | None = None,
                     current_yaw: float = np.pi / 2) -> list[tuple[Grasp, float]]:
    """The grasps the module's rule allows for an object of `shape`, each with its preference cost (lower first):
    the rule's own grasp costs 0; a slide along an elongated object's long side, the other rim sides, or a quarter
    turn of the wrist on a round object cost a little (they are taken only to keep the hand off its neighbours)."""
    c = cfg or ShapeExpertConfig()
    out: list[tuple[Grasp, float]] = []
    if shape.narrow_m <= hand.span_m - 2 * c.fit_margin_m:
        mid = (shape.bottom_m + shape.top_m) / 2
        z = max(mid, shape.top_m - c.grasp_depth_m)
        z = min(max(z, shape.bottom_m + c.table_clear_m), shape.top_m)
        cx, cy = shape.centre_xy
        if shape.ratio >= c.elongated_ratio:
            yaw = shape.narrow_yaw
            along = np.array([-np.sin(yaw), np.cos(yaw)])  # the long side
            smax = max(0.0, shape.long_m / 2 - 0.02)
            for s in np.linspace(-smax, smax, 5) if smax > 0 else [0.0]:
                out.append((Grasp("centre", (cx + along[0] * s, cy + along[1] * s, z), yaw), 10.0 * abs(s)))
        else:
            out.append((Grasp("centre", (cx, cy, z), None), 0.0))
            out.append((Grasp("centre", (cx, cy, z), _wrap_half_turn(current_yaw + np.pi / 2) % np.pi), 0.3))
        return out
    radius = (shape.narrow_m / 2) - hand.pad_half_width_m
    z = max(shape.top_m - c.rim_depth_m, shape.bottom_m + c.table_clear_m)
    reach = np.asarray(shape.reach)
    for k, (sx, sy) in enumerate(((0.0, -1.0), (0.0, 1.0), (-1.0, 0.0), (1.0, 0.0))):  # -y, +y, -x, +x
        xy = np.asarray(shape.centre_xy) + np.array([sx, sy]) * radius
        yaw = None if sx == 0 else 0.0  # the Panda's fingers close along world y at rest
        cost = 0.01 * k + (0.3 if sx != 0 else 0.0) + (5.0 if reach[k] > reach.min() + 0.008 else 0.0)
        out.append((Grasp("rim", (float(xy[0]), float(xy[1]), z), yaw), cost))
    return out


def hand_overlap(centre: np.ndarray, yaw: float, site_z: float, obstacles) -> int:
    """How many sample points of the hand's footprint (HAND_PARTS) at grasp site `centre` (x, y), closing direction
    `yaw`, site height site_z fall inside an obstacle box ((x lo, y lo), (x hi, y hi), top z) whose top is above the
    part's bottom."""
    if not obstacles:
        return 0
    u = np.array([np.cos(yaw), np.sin(yaw)])
    v = np.array([-u[1], u[0]])
    n = 0
    for x0, x1, hw, dz in HAND_PARTS:
        xs, ys = np.linspace(x0, x1, 9 if x1 - x0 > 0.1 else 3), np.linspace(-hw, hw, 3)
        pts = centre[None, :2] + xs.repeat(len(ys))[:, None] * u + np.tile(ys, len(xs))[:, None] * v
        for lo, hi, top in obstacles:
            if top > site_z + dz:
                n += int(np.all((pts > np.asarray(lo) - 0.005) & (pts < np.asarray(hi) + 0.005), axis=1).sum())
    return n


def plan_grasp(shape: Shape, hand: Hand, cfg: ShapeExpertConfig | None = None, obstacles=(),
               obj_pos=(0.0, 0.0, 0.0), place_pos=None, current_yaw: float = np.pi / 2) -> Grasp:
    """The grasp of the module's rule for an object of `shape` (about its origin) and a hand of `hand`: among
    `grasp_candidates`, the one whose hand footprint overlaps the obstacles least, at the pick (object at obj_pos)
    and at the place (object's origin at place_pos, if given), then the preferred one."""
    best, best_cost = None, np.inf
    for g, pref in grasp_candidates(shape, hand, cfg, current_yaw):
        yaw = current_yaw if g.yaw is None else g.yaw
        cost = pref
        for at in (obj_pos, place_pos):
            if at is not None:
                p = np.asarray(at, dtype=float) + np.asarray(g.offset)
                cost += hand_overlap(p[:2], yaw, p[2], obstacles)
        if cost < best_cost:
            best, best_cost = g, cost
    return best


@dataclass(frozen=True)
class Plan:
    """One pick and place: the grasp, the object's goal and the heights of the carry.

    Attributes:
        grasp: the grasp (offset relative to the object's origin).
        shape: the object's shape at planning.
        obj_yaw: the object's yaw at planning (the grasp yaw follows the object's yaw after it).
        place_offset: the object's origin at release relative to the target's origin, world axes, m.
        support_top_z: the target's support top relative to the target's origin, m.
        carry_z: the object's bottom while carried, relative to the target's origin, m (at least).
        place_yaw: world yaw of the closing direction while placing (an elongated region), or None.
        approach_z: the grasp site's height above the object's origin on the approach (clears the neighbours).
    """

    grasp: Grasp
    shape: Shape
    obj_yaw: float
    place_offset: tuple[float, float, float]
    support_top_z: float
    carry_z: float
    place_yaw: float | None = None
    approach_z: float | None = None


def plan_place(obj: Shape, target: Shape, support_top_z: float, grasp: Grasp,
               cfg: ShapeExpertConfig | None = None) -> tuple[tuple[float, float, float], float | None]:
    """(object origin at release relative to the target's origin, closing yaw while placing or None): over the
    target's centre, the object's bottom place_clear_m above the support top (relative to the target's origin)."""
    c = cfg or ShapeExpertConfig()
    z = support_top_z + c.place_clear_m - obj.bottom_m
    yaw = None
    if grasp.kind == "centre" and grasp.yaw is not None and target.ratio >= c.elongated_ratio:
        yaw = target.narrow_yaw  # the object's narrow side across the region's narrow side
    return (target.centre_xy[0], target.centre_xy[1], z), yaw


def plan_for(obj: Shape, target: Shape, support_top_z: float, hand: Hand, cfg: ShapeExpertConfig | None = None,
             obj_yaw: float = 0.0, obj_rest_bottom_z: float = -np.inf, obstacles=(), obj_pos=None, target_pos=None,
             current_yaw: float = np.pi / 2) -> Plan:
    """The whole plan. Heights of the target side are relative to the target's origin; obj_rest_bottom_z: the
    object's resting bottom relative to the target's origin (the carry clears it too). obstacles: the other bodies'
    footprint boxes ((x lo, y lo), (x hi, y hi), top z), world; with obj_pos and target_pos (world) the grasp keeps
    the hand off them at the pick and at the place (`plan_grasp`)."""
    c = cfg or ShapeExpertConfig()
    place, _ = plan_place(obj, target, support_top_z, Grasp("centre", (0.0, 0.0, 0.0), None), c)
    place_pos = None if target_pos is None else np.asarray(target_pos, dtype=float) + np.asarray(place)
    grasp = plan_grasp(obj, hand, c, obstacles if obj_pos is not None else (),
                       obj_pos if obj_pos is not None else (0.0, 0.0, 0.0), place_pos, current_yaw)
    place, yaw = plan_place(obj, target, support_top_z, grasp, c)
    carry = max(support_top_z, obj_rest_bottom_z) + c.carry_clear_m
    approach = grasp.offset[2] + c.hover_m
    if obj_pos is not None:  # the finger tips 2 cm above every neighbour within 15 cm
        near = [top for lo, hi, top in obstacles
                if np.all(np.asarray(obj_pos[:2]) > np.asarray(lo) - 0.15) and np.all(np.asarray(obj_pos[:2]) < np.asarray(hi) + 0.15)]
        if near:
            approach = max(approach, max(near) - float(obj_pos[2]) + 0.012 + 0.02)
    return Plan(grasp, obj, obj_yaw, place, support_top_z, carry, yaw, approach)


def _wrap_half_turn(a: float) -> float:
    """An angle into [-pi/2, pi/2): a parallel gripper is the same turned by half a turn."""
    return float((a + np.pi / 2) % np.pi - np.pi / 2)


class ShapeExpert(PickPlaceExpert):
    """One env's shape-aware scripted expert (module doc); `reset()` each episode, then `act_source(source)` (or
    `set_plan(...)` and `act(...)`) each step. STAGES: PickPlaceExpert's."""

    def __init__(self, layout: ActionLayout = LIBERO_OSC_POSE, cfg: ShapeExpertConfig | None = None):
        self.plan: Plan | None = None
        super().__init__(layout, cfg or ShapeExpertConfig())
        self._refs = None

    # ---- episode / plan -------------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._refs = None  # (obj ref, target ref, sub-goal index) planned for, from act_source
        self._pending = False  # the source moved on to another sub-goal: finish this place first
        self._retreat_z = None
        self._hold_yaw = None

    def set_plan(self, plan: Plan) -> None:
        """Plan the next pick and place and start it from the approach."""
        self.plan = plan
        self.stage, self.count = 0, 0
        self._best, self._stall = np.inf, 0
        self._lift_z = None
        self._hold_yaw = None
        self._retreat_z = None

    # ---- the state machine ----------------------------------------------------------------------------
    def _turn(self, eef_yaw: float, want: float | None) -> tuple[float, float]:
        """(drz action, |error| rad) turning the closing direction at eef_yaw to `want` (None: hold)."""
        if want is None or not np.isfinite(eef_yaw):
            return 0.0, 0.0
        err = _wrap_half_turn(want - eef_yaw)
        return float(np.clip(self.cfg.rot_gain * err / _ROT_METRES, -1.0, 1.0)), abs(err)

    def act(self, eef_pos: np.ndarray, obj_pos: np.ndarray, target_pos: np.ndarray, eef_yaw: float = np.nan,
            obj_yaw: float = np.nan, eef_down: np.ndarray | None = None) -> np.ndarray:
        """One action. eef_yaw: world yaw of the fingers' closing direction; obj_yaw: the object's yaw (the grasp
        yaw turns with it from the plan's); eef_down: the gripper's pointing direction (unit; for `upright`)."""
        if self.plan is None:
            raise RuntimeError("physvla: ShapeExpert has no plan: call set_plan() or use act_source()")
        c, lay, p = self.cfg, self.layout, self.plan
        eef_pos, obj_pos, target_pos = (np.asarray(v, dtype=float) for v in (eef_pos, obj_pos, target_pos))
        a = np.zeros(lay.dim)
        close, grip = -lay.gripper_open, lay.gripper_open
        name = self.STAGES[self.stage]
        turn = 0.0 if not np.isfinite(obj_yaw) else obj_yaw - p.obj_yaw
        g_yaw = None if p.grasp.yaw is None else p.grasp.yaw + turn
        grasp = obj_pos + np.asarray(p.grasp.offset) + self.aim
        if turn and p.grasp.offset[:2] != (0.0, 0.0):  # the grasp point turns with the object
            cs, sn = np.cos(turn), np.sin(turn)
            ox, oy = p.grasp.offset[:2]
            grasp[:2] = obj_pos[:2] + (cs * ox - sn * oy, sn * ox + cs * oy) + self.aim[:2]
        obj_goal = target_pos + np.asarray(p.place_offset) + self.place_bias  # the object's origin at release
        carry_dz = max(0.0, (target_pos[2] + p.carry_z) - (obj_goal[2] + p.shape.bottom_m))
        up = np.array([0.0, 0.0, max(c.hover_m, carry_dz)])
        # the end effector's goal at the place: where it is, moved by the object's error
        place = eef_pos + (obj_goal - obj_pos)
        drz, yaw_err = 0.0, 0.0
        if name == "hover_obj":
            above = np.array([grasp[0], grasp[1], obj_pos[2] + (p.approach_z if p.approach_z is not None
                                                                 else p.grasp.offset[2] + c.hover_m)])
            d, err = self._move(eef_pos, above)
            drz, yaw_err = self._turn(eef_yaw, g_yaw)
            done = np.linalg.norm((grasp - eef_pos)[:2]) < c.tol_m and yaw_err < c.rot_tol_rad
            if self.close_early and np.linalg.norm((grasp - eef_pos)[:2]) < 0.12:
                grip = close  # premature close, mid-flight
        elif name == "descend":
            d, err = self._move(eef_pos, grasp)
            drz, _ = self._turn(eef_yaw, g_yaw)
            done = err < c.tol_m
        elif name == "close":
            d, _ = self._move(eef_pos, grasp)
            grip, self.count = close, self.count + 1
            done = self.count >= c.close_steps
        elif name == "lift":  # the object's bottom to the carry height (fixed when the lift starts)
            if self._lift_z is None:
                self._hold_yaw = eef_yaw if np.isfinite(eef_yaw) else None  # the wrist holds this while carrying
                need = target_pos[2] + p.carry_z - (obj_pos[2] + p.shape.bottom_m)
                self._lift_z = eef_pos[2] + max(need, c.hover_m / 2)
            d, err = self._move(eef_pos, np.array([*eef_pos[:2], self._lift_z]))
            grip, done = close, err < c.tol_m
        elif name == "hover_tgt":
            goal = place + up
            goal[2] = max(goal[2], self._lift_z if self._lift_z is not None else goal[2])
            d, _ = self._move(eef_pos, goal, fast=c.no_decel)
            drz, yaw_err = self._turn(eef_yaw, p.place_yaw if p.place_yaw is not None else self._hold_yaw)
            grip = close
            done = np.linalg.norm((obj_goal - obj_pos)[:2]) < c.tol_m and yaw_err < c.rot_tol_rad
        elif name == "lower":
            d, err = self._move(eef_pos, place, fast=c.no_decel)
            drz, _ = self._turn(eef_yaw, p.place_yaw if p.place_yaw is not None else self._hold_yaw)
            grip, done = close, err < c.tol_m
        elif name == "release" and not c.release:  # hold the object at the target
            d, _ = self._move(eef_pos, place)
            grip, done = close, False
        elif name == "release":
            d, self.count = np.zeros(3), self.count + 1
            done = self.count >= c.release_steps
        else:  # done: raise the hand clear of the placed object
            if self._retreat_z is None:
                self._retreat_z = eef_pos[2] + c.hover_m
            d, _ = self._move(eef_pos, np.array([*eef_pos[:2], self._retreat_z]))
            done = False
        if name in ("hover_obj", "descend", "lift", "hover_tgt", "lower"):
            e = float(np.linalg.norm(grasp - eef_pos)) if name in ("hover_obj", "descend") else \
                float(np.linalg.norm(obj_goal - obj_pos))
            done = self._progress(e + yaw_err * 0.05, done)  # a turning wrist is progress too
        if done:
            self._advance()
        near_grasp = name in ("descend", "close") or (
            name == "hover_obj" and np.linalg.norm((grasp - eef_pos)[:2]) < self.GRASP_ZONE_M)
        placing = name == "lower" or (
            name == "hover_tgt" and np.linalg.norm((obj_goal - obj_pos)[:2]) < self.GRASP_ZONE_M)
        d = self._faults(d, near_grasp, placing)
        a[list(lay.pos)] = d
        if len(lay.rot) == 3:
            rot = np.zeros(3)
            if c.upright and eef_down is not None:  # tilt back to pointing straight down
                axis = np.cross(np.asarray(eef_down, dtype=float), [0.0, 0.0, -1.0])
                rot[:2] = np.clip(c.rot_gain * axis[:2] / _ROT_METRES, -1.0, 1.0)
            rot[2] = drz
            a[list(lay.rot)] = rot
        if lay.gripper is not None:
            a[lay.gripper] = grip
        return np.clip(a, lay.low, lay.high)

    # ---- from a robosuite / LIBERO state source -------------------------------------------------------
    def act_source(self, source) -> np.ndarray:
        """One action for the env of a `RobosuiteStateSource` (read after its reset / step): plans from the scene's
        geometry at the start and whenever the source's followed sub-goal changes (after releasing a held object)."""
        key = (source._obj, source._tgt, getattr(source, "subgoal", 0))
        if self._refs is None:
            self._replan(source)
        elif key != self._refs and not self._pending:
            if self.STAGES[self.stage] in ("hover_obj", "descend"):
                self._replan(source)  # nothing held: go for the new object at once
            else:
                self._pending = True
        if self._pending and self.STAGES[self.stage] == "done" and self._retreat_z is not None:
            data = source.env.sim.data._data
            if self._eef(source)[0][2] > self._retreat_z - 0.03:
                self._replan(source)
        data = source.env.sim.data._data
        eef, yaw, down = self._eef(source)
        obj_ref, tgt_ref = self._refs[0], self._refs[1]
        obj_pos, obj_yaw = _pose(data, obj_ref)
        tgt_pos, _ = _pose(data, tgt_ref)
        return self.act(eef, obj_pos, tgt_pos, eef_yaw=yaw, obj_yaw=obj_yaw, eef_down=down)

    def _eef(self, source):
        data = source.env.sim.data._data
        sid = source.env.robots[0].eef_site_id
        m = data.site_xmat[sid].reshape(3, 3)
        return data.site_xpos[sid].copy(), float(np.arctan2(m[1, 0], m[0, 0])), m[:, 2].copy()

    def _replan(self, source) -> None:
        self._pending = False
        model, data = source.model, source.env.sim.data._data
        obj_ref, tgt_ref = source._obj, source._tgt
        obj = measure(model, data, obj_ref)
        tgt = measure(model, data, tgt_ref)
        obj_pos, obj_yaw = _pose(data, obj_ref)
        tgt_pos, _ = _pose(data, tgt_ref)
        support = support_top(model, data, tgt_ref) - tgt_pos[2]
        rest_bottom = obj_pos[2] + obj.bottom_m - tgt_pos[2]
        obstacles = scene_obstacles(model, data, source.env, skip=(obj_ref[1],) if obj_ref[0] == "body" else ())
        self.set_plan(plan_for(obj, tgt, support, source.hand(), self.cfg, obj_yaw, rest_bottom, obstacles,
                               obj_pos, tgt_pos, self._eef(source)[1]))
        self._refs = (obj_ref, tgt_ref, getattr(source, "subgoal", 0))


# ---- MuJoCo measurements ------------------------------------------------------------------------------
def _pose(data, ref) -> tuple[np.ndarray, float]:
    """(position, yaw of its x axis) of a ('body'|'site', id)."""
    kind, i = ref
    pos = data.xpos[i] if kind == "body" else data.site_xpos[i]
    m = (data.xmat[i] if kind == "body" else data.site_xmat[i]).reshape(3, 3)
    return np.array(pos), float(np.arctan2(m[1, 0], m[0, 0]))


def _subtree(model, body_id: int) -> list[int]:
    out = [body_id]
    for b in range(body_id + 1, model.nbody):
        if model.body_parentid[b] in out:
            out.append(b)
    return out


def body_points(model, data, body_id: int) -> np.ndarray:
    """The corners of the boxes of a body's (and its subtree's) collision geoms, relative to its origin, world axes."""
    bodies = _subtree(model, body_id)
    pts = []
    for g in range(model.ngeom):
        if model.geom_bodyid[g] in bodies and (model.geom_contype[g] or model.geom_conaffinity[g]):
            centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
            rot = data.geom_xmat[g].reshape(3, 3)
            pts.append(data.geom_xpos[g] + (centre + _CORNERS * half) @ rot.T)
    if not pts:
        raise ValueError(f"physvla: body {model.body(body_id).name!r} has no collision geom to measure")
    return np.concatenate(pts) - data.xpos[body_id]


def measure(model, data, ref) -> Shape:
    """The Shape of a ('body'|'site', id) as it stands: a body's collision geoms, a site's box."""
    kind, i = ref
    if kind == "body":
        return shape_from_points(body_points(model, data, i))
    import mujoco

    size = np.asarray(model.site_size[i], dtype=float)
    if model.site_type[i] == mujoco.mjtGeom.mjGEOM_SPHERE:
        half = np.array([size[0]] * 3)
    elif model.site_type[i] in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE):
        half = np.array([size[0], size[0], size[1]])
    else:
        half = size[:3]
    return shape_from_points((_CORNERS * half) @ data.site_xmat[i].reshape(3, 3).T)


def support_top(model, data, ref) -> float:
    """World height an object set on / dropped into a target must clear: the target's top, and for a region site
    the top of the body it belongs to within the region's footprint (a basket's rim, a burner, a cabinet's top)."""
    kind, i = ref
    pos, _ = _pose(data, ref)
    top = pos[2] + measure(model, data, ref).top_m
    if kind == "site":
        b = int(model.site_bodyid[i])
        if b > 0:
            try:
                top = max(top, float(data.xpos[b][2] + body_points(model, data, b)[:, 2].max()))
            except ValueError:
                pass
    return float(top)


def scene_obstacles(model, data, env, skip=()) -> list[tuple]:
    """Footprint boxes ((x lo, y lo), (x hi, y hi), top z), world, of the LIBERO scene's objects and fixtures
    (env.obj_body_id) but the bodies in `skip` (the object being picked)."""
    out = []
    for bid in dict(getattr(env, "obj_body_id", {}) or {}).values():
        if int(bid) in skip:
            continue
        try:
            pts = body_points(model, data, int(bid)) + data.xpos[int(bid)]
        except ValueError:
            continue
        out.append((tuple(pts[:, :2].min(0)), tuple(pts[:, :2].max(0)), float(pts[:, 2].max())))
    return out
