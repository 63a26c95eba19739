"""Physical state of lerobot-env-so101's MuJoCo simulation of the SO-101 arm, for the corrector.

`SO101StateSource` reads one env's s_t from the live model of that package's task env (`SO101PickPlaceGymEnv`,
the env `--env.type=so101 --env.task=SO101PickPlace-v0` builds):

    eef_pos      the point the action moves, the env's own `ik_point_pos`: with the pick-place task's top-down IK
                 the grasp point between the jaws (the pads' midpoint at the grasp jaw angle, fixed in the
                 `gripperframe` site's frame), else the `gripperframe` site. The action's position channels move
                 exactly this point's IK target, so Branch B's Cartesian velocity and the corrections' distances
                 are of the point the policy steers (agent_pos reports `gripperframe`, 2.6 cm from it)
    gripper      the jaws' opening, m: the gap between the two fingertip pads' faces along the jaw axis (the
                 site's z), 0 where they meet (shut on nothing they overlap along it: 0); 0.040 at the env's grasp
                 jaw angle (0.46 rad, where the pads are parallel), 0.091 wide open; the 4 cm block held by the
                 package's scripted controller: ~0.032 (each pad's soft contact 4 mm into the block)
    obj_pos      the block's centre (the env's `block_pos` sensor, what environment_state reports)
    target_pos   the goal: the pick-place env's `goal_pos` (where the block's centre should rest)
    q .. J_pos   the arm's 5 joints (shoulder_pan .. wrist_roll; `MujocoDynamicsOracle`); tau = qfrc_actuator
                 (the position servos) + qfrc_applied + qfrc_passive (the joints' damping, 0.6 N m s/rad); the
                 joints' friction loss and limits and the contacts (qfrc_constraint) are not in it. J_pos is the
                 translational Jacobian of eef_pos (mj_jac at that point on the gripper body)
    dt           the env's control period (`control_dt`: 0.1 s, 50 physics steps of 2 ms)
    pose_age 0; scene measured at `reset()` (below)

The env's step ends with mj_step and no forward pass, so positions, M, the bias and the Jacobian are of the last
physics substep's start (2 ms older than q and qdot, mutually consistent), as the env's own observation is.

Scene (core/state.py SCENE), from the model: the block's box (its collision geom); the target's half width: the
goal is a point with no geometry, so it is the region the block lies wholly inside when the task counts it placed
(its centre within `PLACE_SUCCESS_DISTANCE`, 3 cm, of the goal): 3 cm + the block's half width; the hand's
widest opening (the pad gap at the gripper joint's open limit) and a pad's half width across the closing direction
(the site's y) and half height (the site's x, the approach axis: vertical in the top-down grasp), both at the grasp
jaw angle, where the pads are parallel. A value that cannot be read is NaN (the corrector keeps its fixed
distances).

Tasks. The corrector models a grasp, a carry and a place of one object: `SO101PickPlace-v0` is one. The pick-cube
task (`SO101PickCube-v0`) is a lift with no place: it raises `UnsupportedTask` and its actions pass through as
unsupported_goal (UNSUPPORTED says why). A target made up above the block would put every lift straight into the
place phase, where the release assist opens a still hand over its target: it would drop the block the task needs
held.

Action (core/config.py `so101_layout`): [dx, dy, dz, grasp]; the IK target moves action * action_scale m a control
step (the env config's `action_scale`), grasp an absolute target in [0, 1], 1 open, 0 closed.
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

ARM_JOINTS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")
EEF_SITE = "gripperframe"  # on the fixed jaw's inner face; the IK point is fixed in its frame
GRIPPER_JOINT = "gripper"
PADS = ("fixed_jaw_pad", "moving_jaw_pad")  # box geoms at the fingertips
BLOCK_BODY = "block"
JAW_AXIS, ACROSS_AXIS, APPROACH_AXIS = 2, 1, 0  # the site's axes: fixed jaw -> moving jaw, across, out along the jaws
GRASP_JAW_ANGLE = 0.46  # rad: the pads parallel, 40 mm apart (lerobot_env_so101.mujoco_env._GRASP_JAW_ANGLE)

MODELLED: dict[str, str] = {
    "SO101PickPlace-v0": "a 4 cm block grasped, lifted (the task counts a rise of 3 cm) and placed with its centre "
                         "within 3 cm of a goal point on the table, the jaw open",
}
UNSUPPORTED: dict[str, str] = {
    "SO101PickCube-v0": "a lift with no place: success is the block held 10 cm above its rest at the gripper; a "
                        "target made up above it would put the lift in the place phase, whose release assist opens "
                        "the hand",
}


class UnsupportedTask(UnsupportedGoal):
    """An SO-101 task outside what the corrector models. Attribute `goal`: the task and why, in words."""

    def __init__(self, task: str, reason: str):
        self.goal = f"{task} ({reason})"
        ValueError.__init__(self, f"physvla: unsupported_goal: {self.goal}: the corrector models a grasp, a carry "
                                  "and a place of one object, so this task's actions pass through unchanged")


def check_task(task: str) -> None:
    """UnsupportedTask unless `task` (e.g. "SO101PickPlace-v0", a "lerobot_env_so101/" prefix allowed) is in
    MODELLED."""
    task = task.rpartition("/")[2]
    if task not in MODELLED:
        raise UnsupportedTask(task, UNSUPPORTED.get(task, "not an SO-101 task this source knows"))


def task_of(env) -> str:
    """The task name of one of lerobot-env-so101's task envs (its class; "" for another)."""
    from lerobot_env_so101.pick_env import SO101PickCubeGymEnv
    from lerobot_env_so101.pick_place_env import SO101PickPlaceGymEnv

    return {SO101PickPlaceGymEnv: "SO101PickPlace-v0", SO101PickCubeGymEnv: "SO101PickCube-v0"}.get(type(env), "")


def pad_gap(model: mujoco.MjModel, data: mujoco.MjData, site: int, pads) -> float:
    """The gap between the two pads' faces along the site's jaw axis, m (negative where they overlap along it):
    the moving pad's near face less the fixed pad's near face, each box projected on the axis."""
    axis = data.site_xmat[site].reshape(3, 3)[:, JAW_AXIS]
    lo_hi = []
    for g in pads:
        half = float(np.abs(data.geom_xmat[g].reshape(3, 3).T @ axis) @ model.geom_size[g])
        centre = float(data.geom_xpos[g] @ axis)
        lo_hi.append((centre - half, centre + half))
    return lo_hi[1][0] - lo_hi[0][1]


class SO101StateSource(PackedHeader):
    """Reads s_t of one lerobot-env-so101 env (module docstring).

    Attributes:
        env: the task env (`SO101PickPlaceGymEnv`), unwrapped.
        task: its task name, e.g. "SO101PickPlace-v0".
        oracle: the MuJoCo dynamics oracle of the arm (end-effector: the `gripperframe` site; the source writes the
            IK point and its Jacobian over it).
        dt: the control period, s.
        obj_rest_z: the block's height at the last `reset()`, m.
        episode_step: control steps since the last `reset()`.
        failures: Counter of exception types of failed reads (those rows come back invalid).
    Raises UnsupportedTask for a task outside MODELLED.
    """

    def __init__(self, env, task: str | None = None):
        env = getattr(env, "unwrapped", env)
        self.task = (task or task_of(env)).rpartition("/")[2]
        check_task(self.task)
        self.env = env
        m = self.model = env.model
        self.oracle = MujocoDynamicsOracle(m, list(ARM_JOINTS), eef_site=EEF_SITE)
        self._site = m.site(EEF_SITE).id
        self._site_body = int(m.site_bodyid[self._site])
        self._pads = [m.geom(g).id for g in PADS]
        self._gripper = m.joint(GRIPPER_JOINT).id
        self._block = m.body(BLOCK_BODY).id
        self._arm_dofs = self.oracle.dof_ids
        self._jacp = np.zeros((3, m.nv))
        self.dt = float(env.control_dt)
        n = self.oracle.n_joints
        self._size = packed_size(n)
        f = self._f = field_offsets(n)
        # header fields written as they are: valid, episode_step, dt, obj_rest_z, the scene (measured at reset)
        self._header = header_rows(f, self.dt)
        self.failures: Counter = Counter()
        self.read_packed()  # compiles the read now, never inside the first control tick

    def eef(self) -> np.ndarray:
        """The point the action moves, m (the env's `ik_point_pos`)."""
        return np.asarray(self.env.ik_point_pos, dtype=np.float64).copy()

    def object_pos(self) -> np.ndarray:
        """The block's centre, m (the env's `block_pos` sensor)."""
        return np.asarray(self.env.data.sensor("block_pos").data, dtype=np.float64).copy()

    def target_pos(self) -> np.ndarray:
        """The goal, m (the env's `goal_pos`)."""
        return np.asarray(self.env.goal_pos, dtype=np.float64).reshape(3).copy()

    def opening(self, data: mujoco.MjData | None = None) -> float:
        """The jaws' opening, m: the pads' face gap (`pad_gap`), 0 where they meet or overlap."""
        data = self.env.data if data is None else data
        return max(0.0, pad_gap(self.model, data, self._site, self._pads))

    def reset(self) -> None:
        """Call after the env's reset: records the block's resting height and the scene's geometry."""
        self.episode_step = 0
        self.obj_rest_z = float(self.object_pos()[2])
        self._measure()

    def step(self) -> None:
        """Call once per executed control step."""
        self._header[1, 1] += 1.0

    def _measure(self) -> None:
        """The scene's geometry (SCENE) into the header; NaN where it cannot be read."""
        rows = self._header[4:, 1]
        rows[:] = np.nan
        try:
            obj, hand = self.extent(), self.hand()
            rows[0:3] = obj.radius_m, obj.half_width_m, obj.top_m
            rows[3] = self.target_half_width(obj)
            rows[4:7] = hand.span_m, hand.pad_half_width_m, hand.pad_half_height_m
            rows[7] = self.close_time(2.0 * obj.half_width_m)
        except Exception as e:  # noqa: BLE001 - an unmeasured scene keeps the fixed distances
            rows[:] = np.nan
            self.failures[f"scene: {type(e).__name__}"] += 1

    def extent(self) -> geometry.Extent:
        """The block's box about its centre (its collision geom as it stands now: read it at rest), m."""
        return geometry.body_extent(self.model, self.env.data, self._block)

    def target_half_width(self, obj: geometry.Extent | None = None) -> float:
        """The goal's half width, m: the region the block lies wholly inside when the task counts it placed, its
        centre within PLACE_SUCCESS_DISTANCE of the goal (module docstring)."""
        from lerobot_env_so101.pick_place_env import PLACE_SUCCESS_DISTANCE

        obj = self.extent() if obj is None else obj
        return float(PLACE_SUCCESS_DISTANCE) + obj.half_width_m

    def close_time(self, width_m: float) -> float:
        """How long the jaws take to close from wide open to `width_m`, s (sources/geometry.py close_time): the jaw's
        position servo given the env's closed command (grasp 0, `normalized_to_ctrl`), as its step gives it."""
        from lerobot_env_so101.gripper import normalized_to_ctrl

        m = self.model
        act = m.actuator("gripper").id
        shut = normalized_to_ctrl(0.0, m.actuator_ctrlrange[act])
        adr, dof = m.jnt_qposadr[self._gripper], m.jnt_dofadr[self._gripper]

        def open_fingers(d):
            d.qpos[adr] = m.jnt_range[self._gripper, 1]
            d.qvel[dof] = 0.0
            d.ctrl[act] = d.qpos[adr]

        def close(d):
            d.ctrl[act] = shut

        return geometry.close_time(m, self.env.data, self.opening, open_fingers, close, width_m)

    def hand(self) -> geometry.Hand:
        """The gripper, in its own frame (so at any pose of the arm): its widest opening (the pad gap at the gripper
        joint's open limit) and a pad's half sizes across the closing direction and along the approach axis at the
        grasp jaw angle (pads parallel), the larger of the two pads'."""
        m, s = self.model, mujoco.MjData(self.model)
        s.qpos[:] = self.env.data.qpos
        adr = m.jnt_qposadr[self._gripper]
        s.qpos[adr] = m.jnt_range[self._gripper, 1]
        mujoco.mj_kinematics(m, s)
        span = pad_gap(m, s, self._site, self._pads)
        s.qpos[adr] = GRASP_JAW_ANGLE
        mujoco.mj_kinematics(m, s)
        frame = s.site_xmat[self._site].reshape(3, 3)
        half = []
        for g in self._pads:
            axes = frame.T @ s.geom_xmat[g].reshape(3, 3)  # the pad's axes in the site's frame
            ext = np.abs(axes) @ m.geom_size[g]  # its half extents along the site's axes
            half.append([ext[ACROSS_AXIS], ext[APPROACH_AXIS]])
        half = np.array(half)
        return geometry.Hand(float(span), float(half[:, 0].max()), float(half[:, 1].max()))

    def read_packed(self) -> np.ndarray:
        """One env's state as a flat float64 vector (PhysState.pack layout), a new array. Never raises: a failed
        read returns a row with valid = 0 (the corrector then passes actions through).

        The oracle's compiled read writes the arm's fields and the header; the IK point, its Jacobian (mj_jac at
        that point on the gripper body), the joints' damping (added to tau), the jaw opening, the block and the
        goal are written over it. The simulation is never written.
        """
        row = np.zeros(self._size)
        try:
            return pack_arm_row(self, self.env.data, row, self.eef(), self._site_body)
        except Exception as e:  # noqa: BLE001 - do-no-harm: an unreadable state disables correction
            self.failures[type(e).__name__] += 1
            if sum(self.failures.values()) == 1:
                warnings.warn(f"physvla: reading the SO-101 state failed ({e!r}); correction is off for this step",
                              RuntimeWarning, stacklevel=2)
            return np.zeros(self._size)

    def read(self) -> PhysState:
        return PhysState.unpack(self.read_packed())
