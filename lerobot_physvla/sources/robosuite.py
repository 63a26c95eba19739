"""Physical state of a robosuite / LIBERO simulation, for the corrector.

`RobosuiteStateSource` reads one env's s_t from its live MuJoCo model: end-effector site,
gripper finger joints, arm joints (through `MujocoDynamicsOracle`), the manipulated object and
the target. Object and target come from the LIBERO task's own goal predicate (e.g.
`On(akita_black_bowl_1, plate_1)` in the BDDL file), never from hard-coded names; plain
robosuite envs (no BDDL) name them explicitly, or give the target as a fixed world point
(`target_xyz`, e.g. robosuite Lift's goal in the air).

A goal of several predicates (LIBERO-10's `In(alphabet_soup_1, basket_1) & In(tomato_sauce_1,
basket_1)`) is an ordered list of sub-goals: the source follows the first one not yet satisfied
(judged by LIBERO's own predicate, `env._eval_predicate`, after every step) and switches object and
target when it is met. A current sub-goal that is not On / In (an Open, a TurnOn) marks the rows
valid = -1: the corrector passes through (unsupported_goal) until it is met.
"""

from __future__ import annotations

import warnings
from collections import Counter

import mujoco
import numpy as np

from lerobot_physvla.sources import geometry
from lerobot_physvla.sources.header import N_HEADER, PackedHeader, header_rows
from lerobot_physvla.sources.mujoco import MujocoDynamicsOracle
from lerobot_physvla.core.state import UNSUPPORTED_GOAL_VALID, PhysState, field_offsets, packed_size

_GOAL_PREDICATES = ("on", "in")


class UnsupportedGoal(ValueError):
    """A LIBERO goal with no On / In(object, target) predicate: nothing the corrector models (a grasp, a carry
    and a place of one object). Attribute `goal`: the goal in words, e.g. "open(wooden_cabinet_1_middle_region)"."""

    def __init__(self, goal: str):
        self.goal = goal
        super().__init__(f"physvla: the goal {goal} has no On / In(object, target) predicate: the corrector models a "
                         "grasp, a carry and a place of one object, so this task's actions pass through unchanged")


def goal_text(goal) -> str:
    """A BDDL goal in words: its predicates, name(args), joined by ' & '."""
    return " & ".join(f"{str(p[0]).lower()}({', '.join(str(a) for a in p[1:])})" for p in goal)


def subgoals(env) -> list[tuple]:
    """A LIBERO env's BDDL goal as its ordered predicates (each a tuple: name, args...); [] without one."""
    return [tuple(p) for p in (getattr(env, "parsed_problem", {}) or {}).get("goal_state") or []]


def modelled(pred: tuple) -> bool:
    """An On / In(object, target) predicate: a grasp, a carry and a place the corrector models."""
    return len(pred) == 3 and str(pred[0]).lower() in _GOAL_PREDICATES


def goal_object_and_target(env) -> tuple[str, str]:
    """(object, target) named by the first binary On/In predicate of a LIBERO env's BDDL goal; UnsupportedGoal
    when it has none."""
    goal = getattr(env, "parsed_problem", {}).get("goal_state")
    if not goal:
        raise ValueError("physvla: this env has no BDDL goal (parsed_problem['goal_state']); name object and target")
    for pred in goal:
        if len(pred) == 3 and str(pred[0]).lower() in _GOAL_PREDICATES:
            return str(pred[1]), str(pred[2])
    raise UnsupportedGoal(goal_text(goal))


class RobosuiteStateSource(PackedHeader):
    """Reads s_t of one robosuite env (LIBERO problem envs included).

    Attributes:
        env: the robosuite env (for LIBERO: `ControlEnv.env`); it must have been reset once.
        obj_name, target_name: LIBERO object / fixture / region names, or MuJoCo body names.
        target_xyz: a fixed world target point, m (set it per episode), read instead of
            target_name's body when not None.
        goal: the goal's predicates in order, followed one at a time where there are several (module doc);
            () where object and target were named.
        subgoal: the index of the predicate followed now.
        oracle: the MuJoCo dynamics oracle of the arm.
        obj_rest_z: the object's height at the last `reset()`, m.
        episode_step: control steps since the last `reset()`.
        failures: Counter of exception types of failed reads (those rows come back invalid).
    """

    def __init__(self, env, obj_name: str | None = None, target_name: str | None = None, robot_index: int = 0,
                 target_xyz=None):
        self.env = env
        follow = obj_name is None and target_name is None and target_xyz is None
        if obj_name is None or (target_name is None and target_xyz is None):
            g_obj, g_tgt = goal_object_and_target(env)
            obj_name = obj_name or g_obj
            target_name = target_name or g_tgt
        self.obj_name, self.target_name = obj_name, target_name
        robot = env.robots[robot_index]
        self.model: mujoco.MjModel = env.sim.model._model
        self.oracle = MujocoDynamicsOracle(
            self.model, list(robot.robot_joints), eef_site=self.model.site(robot.eef_site_id).name
        )
        fingers = getattr(robot, "_ref_gripper_joint_pos_indexes", None)
        self._finger_qpos = np.asarray(fingers if fingers is not None else [], dtype=np.intp)
        self._obj = self._resolve(obj_name)
        self._tgt = None if target_name is None else self._resolve(target_name)
        self.dt = 1.0 / float(env.control_freq)
        self._size = packed_size(self.oracle.n_joints)
        self.failures: Counter = Counter()  # exception type -> count of failed reads
        f = self._f = field_offsets(self.oracle.n_joints)
        # header fields the compiled read writes as they are: valid, episode_step, dt, obj_rest_z, the scene's
        # geometry (SCENE, measured at reset), then the fixed target point (3) when there is one (rows (offset,
        # value), see pack_live_row)
        self._header = np.concatenate([header_rows(f, self.dt), [[f["target_pos"] + k, 0.0] for k in range(3)]])
        self._n_consts = N_HEADER
        self._consts = self._header[: self._n_consts]
        self.obj_rest_z = float("nan")
        self.episode_step = 0
        self.target_xyz = target_xyz
        kind = {"body": 0, "site": 1}
        points = [self.oracle._eef_point[0], [f["obj_pos"], kind[self._obj[0]], self._obj[1]]]
        if self._tgt is not None:
            points.append([f["target_pos"], kind[self._tgt[0]], self._tgt[1]])
        self._points = np.array(points, dtype=np.intp)  # positions the compiled read copies
        self.goal = tuple(subgoals(env)) if follow else ()
        self._refs = {k: (self._resolve(p[1]), self._resolve(p[2])) for k, p in enumerate(self.goal) if modelled(p)}
        self.subgoal = next((k for k in self._refs), 0)
        self.read_packed()  # loads the compiled read now, never inside the first control tick

    def _resolve(self, name: str) -> tuple[str, int]:
        """('body'|'site', id) of a LIBERO object/fixture/region name or a raw MuJoCo body/site name."""
        m, env = self.model, self.env
        body_ids = getattr(env, "obj_body_id", {})
        if name in body_ids:
            return "body", int(body_ids[name])
        sites = getattr(env, "object_sites_dict", {})
        if name in sites:
            site_name = getattr(sites[name], "root_body", None) or name
            sid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, site_name)
            if sid >= 0:
                return "site", sid
            bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, site_name)
            if bid >= 0:
                return "body", bid
        for kind, obj in (("body", mujoco.mjtObj.mjOBJ_BODY), ("site", mujoco.mjtObj.mjOBJ_SITE)):
            i = mujoco.mj_name2id(m, obj, name)
            if i >= 0:
                return kind, i
        known = sorted(set(body_ids) | set(sites)) or [m.body(i).name for i in range(m.nbody)]
        raise ValueError(f"physvla: {name!r} names no object, region or body of this scene; known: {known}")

    @property
    def target_xyz(self) -> np.ndarray | None:
        return self._target_xyz

    @target_xyz.setter
    def target_xyz(self, value) -> None:
        self._target_xyz = None if value is None else np.asarray(value, dtype=np.float64).reshape(3)
        if self._target_xyz is not None:
            self._header[self._n_consts:, 1] = self._target_xyz
        self._consts = self._header if self._target_xyz is not None else self._header[: self._n_consts]

    def _pos(self, data: mujoco.MjData, ref: tuple[str, int]) -> np.ndarray:
        kind, i = ref
        return data.xpos[i] if kind == "body" else data.site_xpos[i]

    def reset(self) -> None:
        """Call after the env's reset (and settle steps): records the object's resting height and its scene's
        geometry and, for a goal of several predicates, which one is followed."""
        self.episode_step = 0
        self.obj_rest_z = float(self._pos(self.env.sim.data._data, self._obj)[2])
        self._measure()
        if len(self.goal) > 1:
            self.subgoal = -1  # judged afresh
            self._follow()

    def _measure(self) -> None:
        """The scene's geometry (SCENE) of the object and target followed now, into the header; left unmeasured
        (NaN: the corrector keeps its fixed distances) where it cannot be read."""
        rows = self._header[4 : self._n_consts, 1]
        try:
            obj, hand = self.extent("object"), self.hand()
            tgt = self.extent("target") if self._tgt is not None else None
            rows[:] = np.nan
            rows[:7] = (obj.radius_m, obj.half_width_m, obj.top_m, tgt.half_width_m if tgt else np.nan, hand.span_m,
                        hand.pad_half_width_m, hand.pad_half_height_m)
            rows[7] = self.close_time(2.0 * obj.half_width_m)
        except Exception as e:  # noqa: BLE001 - an unmeasured scene keeps the fixed distances
            rows[:] = np.nan
            self.failures[f"scene: {type(e).__name__}"] += 1

    def step(self) -> None:
        """Call once per executed control step."""
        self._header[1, 1] += 1.0
        if len(self.goal) > 1:
            self._follow()

    def _follow(self) -> None:
        """Follow the first predicate of the goal not yet satisfied (the last once all are): its object and
        target, the object's height now as its rest (which makes the rows valid); a predicate that is not On / In
        marks them valid = -1."""
        if len(self.goal) < 2:
            return
        k = next((i for i, p in enumerate(self.goal) if not self.env._eval_predicate(p)), len(self.goal) - 1)
        if k == self.subgoal:
            return
        self.subgoal = k
        if k in self._refs:
            self._obj, self._tgt = self._refs[k]
            kind = {"body": 0, "site": 1}
            self._points = self._points.copy()  # a new array: the compiled read's arena is made per points array
            self._points[1, 1:] = kind[self._obj[0]], self._obj[1]
            self._points[2, 1:] = kind[self._tgt[0]], self._tgt[1]
            self.obj_rest_z = float(self._pos(self.env.sim.data._data, self._obj)[2])
            self._measure()
        else:
            self._header[0, 1] = UNSUPPORTED_GOAL_VALID  # the compiled read writes valid from the header

    @property
    def following(self) -> str:
        """The predicate followed now, in words ("" where object and target were named)."""
        return goal_text([self.goal[self.subgoal]]) if self.goal else ""

    def extent(self, which: str = "object") -> geometry.Extent:
        """The followed object's ("object") or target's ("target") box about its origin, as it stands now (read it at
        rest: after `reset()`), metres."""
        ref = self._obj if which == "object" else self._tgt
        if ref is None:
            raise ValueError(f"physvla: this source has no {which} to measure (a fixed target point has no extent)")
        data = self.env.sim.data._data
        kind, i = ref
        return geometry.body_extent(self.model, data, i) if kind == "body" else geometry.site_extent(self.model, data, i)

    def opening(self, data: mujoco.MjData) -> float:
        """The fingers' opening in `data`, m: the |q| of the gripper's finger joints summed (what the state reads)."""
        return float(np.abs(data.qpos[self._finger_qpos]).sum())

    def close_time(self, width_m: float) -> float:
        """How long the fingers take to close from wide open to `width_m`, s (sources/geometry.py close_time), through
        robosuite's own gripper control as each physics substep applies it (`Manipulator.grip_action`: the gripper's
        `format_action`, a ramp for the Panda's, scaled to the actuators' ranges); NaN for a robot without fingers."""
        robot = self.env.robots[0]
        grip, m = robot.gripper, self.model
        if not self._finger_qpos.size or not getattr(grip, "actuators", None):
            return float("nan")
        acts = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in grip.actuators]
        lo, hi = m.actuator_ctrlrange[acts, 0], m.actuator_ctrlrange[acts, 1]
        saved = getattr(grip, "current_action", None)
        saved = None if saved is None else np.array(saved, copy=True)

        def command(d, g: float) -> None:
            d.ctrl[acts] = 0.5 * (hi + lo) + 0.5 * (hi - lo) * grip.format_action(np.full(grip.dof, g))

        def open_fingers(d) -> None:
            for _ in range(int(0.5 / m.opt.timestep)):
                command(d, -1.0)
                mujoco.mj_step(m, d)

        try:
            return geometry.close_time(m, self.env.sim.data._data, self.opening, open_fingers,
                                       lambda d: command(d, 1.0), width_m)
        finally:
            if saved is not None:
                grip.current_action = saved

    def hand(self) -> geometry.Hand:
        """The robot's gripper: its widest opening and finger pads (robosuite's gripper model names them)."""
        m, grip = self.model, self.env.robots[0].gripper
        joints = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in getattr(grip, "joints", [])]
        important = getattr(grip, "important_geoms", {}) or {}
        pads = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, g)
                for k in ("left_fingerpad", "right_fingerpad") for g in important.get(k, [])]
        return geometry.hand(m, [j for j in joints if j >= 0], [g for g in pads if g >= 0])

    def read_packed(self) -> np.ndarray:
        """One env's state as a flat float64 vector (PhysState.pack layout), a new array. Never
        raises: a failed read returns a row with valid = 0 (the corrector then passes actions through).

        Read from the live MjData as the simulator left it (`MujocoDynamicsOracle.read_live_into`:
        positions, M, bias and tau one 2 ms physics substep older than q and qdot), in one
        compiled call that also writes the header (valid, step, dt, gripper opening, resting
        height, a fixed target); nothing is recomputed and the simulation is never written.
        """
        row = np.zeros(self._size)
        try:
            self.oracle.read_live_into(self.env.sim.data._data, row, self._points, self._consts, self._finger_qpos)
            return row
        except Exception as e:  # noqa: BLE001 - do-no-harm: an unreadable state disables correction
            self.failures[type(e).__name__] += 1
            if sum(self.failures.values()) == 1:
                warnings.warn(f"physvla: reading the sim state failed ({e!r}); correction is off for this step", RuntimeWarning)
            return np.zeros(self._size)

    def read(self) -> PhysState:
        return PhysState.unpack(self.read_packed())
