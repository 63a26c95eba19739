"""Physical state of a MetaWorld simulation, for the corrector.

`MetaworldStateSource` reads one env's s_t from the live MuJoCo model of metaworld's `SawyerXYZEnv` (the env
lerobot's `MetaworldEnv` holds as `_env`):

    eef_pos      the env's own `tcp_center`: the midpoint of the two finger sites, m
    gripper      the fingers' opening: each finger's distance from its closed stop, summed, m (0 = shut)
    obj_pos      the task's object, `_get_pos_objects()[:3]` (the task's own definition), m
    target_pos   the task's target, `_target_pos`, m
    q .. J_pos   the Sawyer arm's 7 joints (`MujocoDynamicsOracle`); its arm has no actuators (a mocap weld
                 drives it), so tau is every joint force but inertia and bias: the weld's and the contacts'
                 (qfrc_constraint) and the joints' damping (qfrc_passive, 10 N m s/rad): M qdd + bias = tau
    dt           the env's control period (`env.dt`: 5 physics steps of 2.5 ms = 12.5 ms)
    pose_age 0, scene measured at `reset()` from the model where it can be read honestly (else NaN)

The corrector models a grasp, a carry and a place of one object. MODELLED names the MetaWorld tasks that are one
(each with why); every other task (UNSUPPORTED: doors, drawers, buttons, pushes, reaches, tools, ...) raises
`UnsupportedTask` (an `UnsupportedGoal`) with its reason, and the env exports its rows as unsupported_goal.
The judgement of each task is from its success definition in metaworld's env source and from its own scripted
expert's run (seeds 0 and 1): how high the task's object point rose, and how far from the target it was at
success.

Action (the `metaworld` layout, core/config.py): [dx, dy, dz, g]; the mocap target moves action * 0.01 m per
control step (`action_scale`), and the finger actuators get [g, -g]: +1 closes, -1 opens.
"""

from __future__ import annotations

import warnings
from collections import Counter

import mujoco
import numpy as np

from lerobot_physvla.core.state import PhysState, field_offsets, packed_size
from lerobot_physvla.sources import geometry
from lerobot_physvla.sources.header import PackedHeader, header_rows, pack_arm_row
from lerobot_physvla.sources.mujoco import MujocoDynamicsOracle
from lerobot_physvla.sources.robosuite import UnsupportedGoal

ARM_JOINTS = tuple(f"right_j{k}" for k in range(7))  # the Sawyer arm
HAND_BODY = "hand"  # the body the fingers slide on
HAND_SITE = "endEffector"  # a site on the hand, 5 mm above the tcp (the oracle's end-effector point)
FINGER_SITES = ("rightEndEffector", "leftEndEffector")  # tcp_center is their midpoint
# the finger joints and the way a close command drives each (SawyerXYZEnv.step: do_simulation([g, -g]))
FINGERS = (("r_close", +1), ("l_close", -1))
PADS = ("rightpad_geom", "leftpad_geom")  # the finger pads (SawyerXYZEnv.touching_object's)

# The tasks the corrector models: one object grasped, carried (lifted) and brought to a target point, success
# judged by the object's distance to that point. Lifts and distances are from each task's scripted expert.
MODELLED: dict[str, str] = {
    "pick-place-v3": "a puck grasped, lifted (5-9 cm) and carried to a goal point; success: puck within 7 cm of it",
    "pick-place-wall-v3": "pick-place over a wall: the puck lifted (23 cm) and carried to the goal point",
    "bin-picking-v3": "a cube grasped, lifted (12 cm) and placed into the other bin; success: within 5 cm of it",
    "shelf-place-v3": "a block grasped, lifted (27 cm) and placed on a shelf; success: within 7 cm of the goal",
    "basketball-v3": "a ball grasped, lifted (30 cm) and carried into the hoop; success: within 8 cm of it",
    "pick-out-of-hole-v3": "a puck grasped in a hole, lifted (16 cm) and carried to a goal point above the table",
}
# Every other task, and why the corrector passes its actions through.
UNSUPPORTED: dict[str, str] = {
    "assembly-v3": "the grasped handle is not the point placed: the nut's ring goes over the peg 13 cm away",
    "disassemble-v3": "a nut lifted off a peg: success is a height, no place",
    "box-close-v3": "the lid's point (top_link) never rises more than 4 mm: no lifted carry to see",
    "hand-insert-v3": "the block is dragged (lifted about 2 cm) and pushed into a hole: no lifted carry",
    "peg-insert-side-v3": "the peg's head, 20 cm from the grasped point, is what must reach the hole",
    "peg-unplug-side-v3": "no grasp-carry-place: a peg is pulled out of its socket",
    "coffee-pull-v3": "no grasp-carry-place: a mug is slid along the table",
    "coffee-push-v3": "no grasp-carry-place: a mug is pushed",
    "coffee-button-v3": "no grasp-carry-place: a button is pressed",
    "button-press-v3": "no grasp-carry-place: a button is pressed",
    "button-press-wall-v3": "no grasp-carry-place: a button is pressed",
    "button-press-topdown-v3": "no grasp-carry-place: a button is pressed",
    "button-press-topdown-wall-v3": "no grasp-carry-place: a button is pressed",
    "dial-turn-v3": "no grasp-carry-place: a dial is turned",
    "door-open-v3": "no grasp-carry-place: a door is pulled",
    "door-close-v3": "no grasp-carry-place: a door is pushed",
    "door-lock-v3": "no grasp-carry-place: a lock is turned",
    "door-unlock-v3": "no grasp-carry-place: a lock is turned",
    "drawer-open-v3": "no grasp-carry-place: a drawer is pulled",
    "drawer-close-v3": "no grasp-carry-place: a drawer is pushed",
    "faucet-open-v3": "no grasp-carry-place: a faucet is turned",
    "faucet-close-v3": "no grasp-carry-place: a faucet is turned",
    "handle-press-v3": "no grasp-carry-place: a handle is pressed",
    "handle-press-side-v3": "no grasp-carry-place: a handle is pressed",
    "handle-pull-v3": "no grasp-carry-place: a handle is pulled",
    "handle-pull-side-v3": "no grasp-carry-place: a handle is pulled",
    "lever-pull-v3": "no grasp-carry-place: a lever is pulled",
    "window-open-v3": "no grasp-carry-place: a window is pushed",
    "window-close-v3": "no grasp-carry-place: a window is pushed",
    "plate-slide-v3": "no grasp-carry-place: a plate is slid",
    "plate-slide-side-v3": "no grasp-carry-place: a plate is slid",
    "plate-slide-back-v3": "no grasp-carry-place: a plate is slid",
    "plate-slide-back-side-v3": "no grasp-carry-place: a plate is slid",
    "push-v3": "no grasp-carry-place: a puck is pushed",
    "push-back-v3": "no grasp-carry-place: a puck is pushed",
    "push-wall-v3": "no grasp-carry-place: a puck is pushed",
    "soccer-v3": "no grasp-carry-place: a ball is pushed",
    "sweep-v3": "no grasp-carry-place: a puck is swept",
    "sweep-into-v3": "no grasp-carry-place: a puck is swept",
    "reach-v3": "no grasp-carry-place: no object is moved",
    "reach-wall-v3": "no grasp-carry-place: no object is moved",
    "hammer-v3": "tool use: a hammer drives a nail",
    "stick-push-v3": "tool use: a stick pushes a box",
    "stick-pull-v3": "tool use: a stick pulls a box",
}


class UnsupportedTask(UnsupportedGoal):
    """A MetaWorld task outside what the corrector models. Attribute `goal`: the task and why, in words, e.g.
    "door-open-v3 (no grasp-carry-place: a door is pulled)"."""

    def __init__(self, task: str, reason: str):
        self.goal = f"{task} ({reason})"
        ValueError.__init__(self, f"physvla: unsupported_goal: {self.goal}: the corrector models a grasp, a carry "
                                  "and a place of one object, so this task's actions pass through unchanged")


def check_task(task: str) -> None:
    """UnsupportedTask unless `task` (e.g. "pick-place-v3", "metaworld-" prefix allowed) is in MODELLED."""
    task = task.removeprefix("metaworld-")
    if task not in MODELLED:
        raise UnsupportedTask(task, UNSUPPORTED.get(task, "not a MetaWorld v3 task this source knows"))


def task_of(env) -> str:
    """The MetaWorld task name of a SawyerXYZEnv, from metaworld's own registry ("" if it is not there)."""
    from metaworld.env_dict import ALL_V3_ENVIRONMENTS

    return next((name for name, cls in ALL_V3_ENVIRONMENTS.items() if type(env) is cls), "")


class MetaworldStateSource(PackedHeader):
    """Reads s_t of one MetaWorld env (module docstring).

    Attributes:
        env: metaworld's SawyerXYZEnv, its task set (it must have been reset once).
        task: the MetaWorld task name, e.g. "pick-place-v3".
        oracle: the MuJoCo dynamics oracle of the arm (end-effector point: the hand's site; the source writes the
            tcp and its Jacobian over it).
        dt: the control period, s.
        obj_rest_z: the object's height at the last `reset()`, m.
        episode_step: control steps since the last `reset()`.
        failures: Counter of exception types of failed reads (those rows come back invalid).
    Raises UnsupportedTask for a task outside MODELLED.
    """

    def __init__(self, env, task: str | None = None):
        self.task = (task or task_of(env)).removeprefix("metaworld-")
        check_task(self.task)
        self.env = env
        m = self.model = env.model
        self.oracle = MujocoDynamicsOracle(m, list(ARM_JOINTS), eef_site=HAND_SITE, include_constraint=True)
        self._sites = np.array([m.site(s).id for s in FINGER_SITES], dtype=np.intp)
        self._hand = m.body(HAND_BODY).id
        fingers = [(m.joint(j).id, sign) for j, sign in FINGERS]
        self._finger_qpos = np.array([m.jnt_qposadr[j] for j, _ in fingers], dtype=np.intp)
        # where each finger stops when shut: the end of its range a close command drives it to
        self._finger_shut = np.array([m.jnt_range[j, 1] if s > 0 else m.jnt_range[j, 0] for j, s in fingers])
        self._finger_sign = np.array([s for _, s in fingers], dtype=np.float64)
        self._finger_joints = [j for j, _ in fingers]
        self._pads = [m.geom(g).id for g in PADS]
        self._arm_dofs = self.oracle.dof_ids
        self._jacp = np.zeros((3, m.nv))
        self.dt = float(env.dt)
        n = self.oracle.n_joints
        self._size = packed_size(n)
        f = self._f = field_offsets(n)
        # header fields written as they are: valid, episode_step, dt, obj_rest_z, the scene (measured at reset)
        self._header = header_rows(f, self.dt)
        self.failures: Counter = Counter()
        self.read_packed()  # compiles the read now, never inside the first control tick

    def object_pos(self) -> np.ndarray:
        """The task's object position, m (its own `_get_pos_objects()`, first object)."""
        return np.asarray(self.env._get_pos_objects(), dtype=np.float64)[:3].copy()

    def target_pos(self) -> np.ndarray:
        """The task's target position, m (its own `_target_pos`)."""
        return np.asarray(self.env._target_pos, dtype=np.float64).reshape(3).copy()

    def tcp(self, data: mujoco.MjData | None = None) -> np.ndarray:
        """The tool centre point, m: the finger sites' midpoint (the env's `tcp_center`)."""
        data = self.env.data if data is None else data
        return data.site_xpos[self._sites].mean(axis=0)

    def opening(self, data: mujoco.MjData | None = None) -> float:
        """The fingers' opening, m: each finger's distance from its shut stop, summed (0 = shut on nothing; the
        hand's span, `hand().span_m`, = wide open)."""
        data = self.env.data if data is None else data
        return float(max(0.0, np.sum(self._finger_sign * (self._finger_shut - data.qpos[self._finger_qpos]))))

    def reset(self) -> None:
        """Call after the env's reset: records the object's resting height and the scene's geometry."""
        self.episode_step = 0
        self.obj_rest_z = float(self.object_pos()[2])
        self._measure()

    def step(self) -> None:
        """Call once per executed control step."""
        self._header[1, 1] += 1.0

    def _measure(self) -> None:
        """The scene's geometry (SCENE) into the header; NaN (the corrector keeps its fixed distances) where it
        cannot be read: an object or target that is a point of no body with collision geoms."""
        rows = self._header[4:, 1]
        rows[:] = np.nan
        try:
            obj, tgt, hand = self.extent("object"), self.extent("target"), self.hand()
            if obj is not None:
                rows[0:3] = obj.radius_m, obj.half_width_m, obj.top_m
            if tgt is not None:
                rows[3] = tgt.half_width_m
            rows[4:7] = hand.span_m, hand.pad_half_width_m, hand.pad_half_height_m
            if obj is not None:
                rows[7] = self.close_time(2.0 * obj.half_width_m)
        except Exception as e:  # noqa: BLE001 - an unmeasured scene keeps the fixed distances
            rows[:] = np.nan
            self.failures[f"scene: {type(e).__name__}"] += 1

    def _body_at(self, point: np.ndarray) -> int | None:
        """The body whose origin is exactly `point` and which has collision geoms (in it or under it), or None."""
        m, d = self.model, self.env.data
        for b in np.flatnonzero((d.xpos == point).all(axis=1)):
            bodies = geometry.subtree(m, int(b))
            if any(m.geom_bodyid[g] in bodies and (m.geom_contype[g] or m.geom_conaffinity[g]) for g in range(m.ngeom)):
                return int(b)
        return None

    def extent(self, which: str = "object") -> geometry.Extent | None:
        """The object's ("object") or target's ("target") box about its point, m, where the point is a body's
        origin (its collision geoms, as they stand now: read it at rest); None where it is not (a goal in the air,
        a site)."""
        b = self._body_at(self.object_pos() if which == "object" else self.target_pos())
        return None if b is None else geometry.body_extent(self.model, self.env.data, b)

    def close_time(self, width_m: float) -> float:
        """How long the fingers take to close from wide open to `width_m`, s (sources/geometry.py close_time): the
        Sawyer's finger actuators driven as SawyerXYZEnv.step drives them on a close (+1: ctrl [1, -1])."""
        m = self.model
        acts = [int(np.flatnonzero((m.actuator_trntype == mujoco.mjtTrn.mjTRN_JOINT) & (m.actuator_trnid[:, 0] == j))[0])
                for j in self._finger_joints]

        def open_fingers(d):
            d.qpos[self._finger_qpos] = [m.jnt_range[j, 0] if s > 0 else m.jnt_range[j, 1]
                                         for j, s in zip(self._finger_joints, self._finger_sign)]
            d.qvel[:] = 0.0

        def close(d):
            d.ctrl[acts] = self._finger_sign

        return geometry.close_time(m, self.env.data, self.opening, open_fingers, close, width_m)

    def hand(self) -> geometry.Hand:
        """The gripper: its widest opening (the fingers' ranges summed) and its pads' half sizes in the world, across
        the closing direction (horizontal) and vertical (the pads are boxes; read with the hand level)."""
        m, d = self.model, self.env.data
        span = float(sum(abs(m.jnt_range[j, 1] - m.jnt_range[j, 0]) for j in self._finger_joints))
        close = d.site_xpos[self._sites[0]] - d.site_xpos[self._sites[1]]
        across = np.cross(close, [0.0, 0.0, 1.0])
        across /= np.linalg.norm(across)
        half = []
        for g in self._pads:
            if m.geom_type[g] != mujoco.mjtGeom.mjGEOM_BOX:
                raise ValueError(f"physvla: pad {m.geom(g).name!r} is not a box")
            axes = d.geom_xmat[g].reshape(3, 3)  # columns: the box's axes in the world
            half.append([float(np.abs(axes.T @ across) @ m.geom_size[g]), float(np.abs(axes[2]) @ m.geom_size[g])])
        half = np.array(half)
        return geometry.Hand(span, float(half[:, 0].max()), float(half[:, 1].max()))

    def read_packed(self) -> np.ndarray:
        """One env's state as a flat float64 vector (PhysState.pack layout), a new array. Never raises: a failed
        read returns a row with valid = 0 (the corrector then passes actions through).

        metaworld's step ends with mj_forward, so every quantity is of the current q and qdot. The oracle's
        compiled read writes the arm's fields and the header; the tcp, its Jacobian (mj_jac at the tcp on the
        hand), the joints' damping (added to tau), the finger opening, the object and the target are written
        over it. The simulation is never
        written.
        """
        row = np.zeros(self._size)
        try:
            d = self.env.data
            return pack_arm_row(self, d, row, self.tcp(d), self._hand)
        except Exception as e:  # noqa: BLE001 - do-no-harm: an unreadable state disables correction
            self.failures[type(e).__name__] += 1
            if sum(self.failures.values()) == 1:
                warnings.warn(f"physvla: reading the MetaWorld state failed ({e!r}); correction is off for this step",
                              RuntimeWarning, stacklevel=2)
            return np.zeros(self._size)

    def read(self) -> PhysState:
        return PhysState.unpack(self.read_packed())
