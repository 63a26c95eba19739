"""Physical state of a robosuite / LIBERO simulation, for the corrector.

`RobosuiteStateSource` reads one env's s_t from its live MuJoCo model: end-effector site,
gripper finger joints, arm joints (through `MujocoDynamicsOracle`), the manipulated object and
the target. Object and target come from the LIBERO task's own goal predicate (e.g.
`On(akita_black_bowl_1, plate_1)` in the BDDL file), never from hard-coded names; plain
robosuite envs (no BDDL) name them explicitly, or give the target as a fixed world point
(`target_xyz`, e.g. robosuite Lift's goal in the air).
"""

from __future__ import annotations

import warnings
from collections import Counter

import mujoco
import numpy as np

from lerobot_physvla.core.dynamics import MujocoDynamicsOracle
from lerobot_physvla.core.state import PhysState, field_offsets, packed_size

_GOAL_PREDICATES = ("on", "in")


def goal_object_and_target(env) -> tuple[str, str]:
    """(object, target) named by the first binary On/In predicate of a LIBERO env's BDDL goal."""
    goal = getattr(env, "parsed_problem", {}).get("goal_state")
    if not goal:
        raise ValueError("physvla: this env has no BDDL goal (parsed_problem['goal_state']); name object and target")
    for pred in goal:
        if len(pred) == 3 and str(pred[0]).lower() in _GOAL_PREDICATES:
            return str(pred[1]), str(pred[2])
    raise ValueError(f"physvla: no On/In(object, target) predicate in the goal {goal}; name object and target")


class RobosuiteStateSource:
    """Reads s_t of one robosuite env (LIBERO problem envs included).

    Attributes:
        env: the robosuite env (for LIBERO: `ControlEnv.env`); it must have been reset once.
        obj_name, target_name: LIBERO object / fixture / region names, or MuJoCo body names.
        target_xyz: a fixed world target point, m (set it per episode), read instead of
            target_name's body when not None.
        oracle: the MuJoCo dynamics oracle of the arm.
        obj_rest_z: the object's height at the last `reset()`, m.
        episode_step: control steps since the last `reset()`.
        failures: Counter of exception types of failed reads (those rows come back invalid).
    """

    def __init__(self, env, obj_name: str | None = None, target_name: str | None = None, robot_index: int = 0,
                 target_xyz=None):
        self.env = env
        self.target_xyz = None if target_xyz is None else np.asarray(target_xyz, dtype=np.float64)
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
        self.obj_rest_z = float("nan")
        self.episode_step = 0
        self._row = np.zeros(packed_size(self.oracle.n_joints))
        self.failures: Counter = Counter()  # exception type -> count of failed reads
        f = self._f = field_offsets(self.oracle.n_joints)
        kind = {"body": 0, "site": 1}
        points = [self.oracle._eef_point[0], [f["obj_pos"], kind[self._obj[0]], self._obj[1]]]
        if self._tgt is not None:
            points.append([f["target_pos"], kind[self._tgt[0]], self._tgt[1]])
        self._points = np.array(points, dtype=np.intp)  # positions the compiled read copies
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

    def _pos(self, data: mujoco.MjData, ref: tuple[str, int]) -> np.ndarray:
        kind, i = ref
        return data.xpos[i] if kind == "body" else data.site_xpos[i]

    def reset(self) -> None:
        """Call after the env's reset (and settle steps): records the object's resting height."""
        self.episode_step = 0
        self.obj_rest_z = float(self._pos(self.env.sim.data._data, self._obj)[2])

    def step(self) -> None:
        """Call once per executed control step."""
        self.episode_step += 1

    def read_packed(self) -> np.ndarray:
        """One env's state as a flat float64 vector (PhysState.pack layout), a new array. Never
        raises: a failed read returns a row with valid = 0 (the corrector then passes actions through).

        Read from the live MjData as the simulator left it (`MujocoDynamicsOracle.read_live_into`:
        positions, M, bias and tau one 2 ms physics substep older than q and qdot), in one
        compiled call; nothing is recomputed and the simulation is never written.
        """
        row, f = self._row, self._f
        try:
            data = self.env.sim.data._data
            self.oracle.read_live_into(data, row, self._points)
            qpos = self.oracle._live[1][0]
            row[f["valid"]] = 1.0 if np.isfinite(self.obj_rest_z) else 0.0
            row[f["episode_step"]] = self.episode_step
            row[f["dt"]] = self.dt
            row[f["gripper"]] = sum(abs(float(qpos[i])) for i in self._finger_qpos)  # finger opening, m
            row[f["obj_rest_z"]] = self.obj_rest_z
            if self.target_xyz is not None:  # a fixed world point overrides the target body
                row[f["target_pos"] : f["target_pos"] + 3] = self.target_xyz
            return row.copy()
        except Exception as e:  # noqa: BLE001 - do-no-harm: an unreadable state disables correction
            self.failures[type(e).__name__] += 1
            if sum(self.failures.values()) == 1:
                warnings.warn(f"physvla: reading the sim state failed ({e!r}); correction is off for this step", RuntimeWarning)
            return np.zeros_like(self._row)

    def read(self) -> PhysState:
        return PhysState.unpack(self.read_packed())
