"""robosuite Lift as a `Scene`, plain and extended with a place-on-plate check (no rendering).

    lift        pick the cube up and hold it at a goal 10 cm above its resting position;
                robosuite's own success (cube more than 4 cm above the table) at the last step
    lift_plate  the paper's real-world sim verification: pick the cube, place it on a plate (a
                purely geometric disk on the table top) and let go; success once the cube has
                rested on the plate, released, for HOLD_STEPS control steps in a row

The state source reads the cube (`cube_main`) as the object and a fixed world point per episode
as the target (Lift has no target body). robosuite draws the cube placement, its yaw and the
arm's initial-joint noise from numpy's global RNG, so `reset(seed)` seeds it first.
"""

from __future__ import annotations

import numpy as np

from lerobot_physvla.core.config import LIBERO_OSC_POSE
from lerobot_physvla.core.state import PhysState

HORIZON = 250  # control steps per episode (20 Hz: 12.5 s); the clean expert places in ~100
SETTLE_STEPS = 10  # no-op steps after reset: the cube, spawned 1 cm above the table, drops and settles
NO_OP = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0])  # hold the pose, gripper open
BUILD_SEED = 0  # numpy seed while building: the cube's size is drawn once, then (no hard reset) kept
LIFT_GOAL_M = 0.10  # plain lift's goal: this high above the cube's resting position, m
PLATE_XY_M = (0.18, -0.12)  # plate centre relative to the table centre, m
PLATE_RADIUS_M = 0.045  # the cube's centre must lie within this of the plate centre (xy), m
PLACED_HEIGHT_M = 0.06  # ... at most this far above the table top (its centre), m
OPEN_GRIPPER_M = 0.07  # finger opening that counts as released (~0.06 on the cube, ~0.079 fully open), m
HOLD_STEPS = 5  # consecutive control steps the placed-and-released check must hold
RELEASE_HEIGHT_M = 0.035  # lift_plate's expert lets go with its grip point (the cube's centre) this
# far above the plate: the cube's half-height (~2.1 cm) plus a ~1.4 cm drop


def make_lift_env(horizon: int = HORIZON):
    """robosuite Lift, Panda, OSC_POSE at 20 Hz, shaped reward, no renderer and no cameras.

    Soft resets (`hard_reset=False`: no model reload, so the state source stays bound to the same
    MuJoCo model); robosuite's own `done` is ignored, the scene's horizon ends an episode.
    """
    import robosuite
    from robosuite.controllers import load_controller_config

    rng_state = np.random.get_state()
    np.random.seed(BUILD_SEED)
    try:
        return robosuite.make(
            "Lift", robots="Panda", controller_configs=load_controller_config(default_controller="OSC_POSE"),
            control_freq=20, horizon=horizon, reward_shaping=True, has_renderer=False,
            has_offscreen_renderer=False, use_camera_obs=False, hard_reset=False, ignore_done=True,
        )
    finally:
        np.random.set_state(rng_state)


def lift_expert(plate: bool) -> dict:
    """ExpertConfig overrides for the cube: grasp at its centre, 6 cm hover legs; lift holds it at
    the goal (release=False), lift_plate lets go RELEASE_HEIGHT_M above the plate."""
    return {"grasp_offset_m": (0.0, 0.0, 0.0), "hover_m": 0.06, "release": plate,
            "place_offset_m": (0.0, 0.0, RELEASE_HEIGHT_M if plate else 0.0)}


class LiftScene:
    """robosuite Lift (plate=False) or Lift + place-on-plate (plate=True); see the module docstring.

    Attributes:
        plate: the place-on-plate variant.
        name: "lift" or "lift_plate".
        layout: LIBERO_OSC_POSE (robosuite's OSC_POSE action).
        horizon: control steps per episode.
        stop_on_success: False for lift (scored at the last step, as robosuite's Lift), True for
            lift_plate.
        expert: ExpertConfig overrides for the cube: grasp at its centre, 6 cm hover legs; lift
            holds it at the goal (release=False), lift_plate lets go just above the plate.
        env: the robosuite env.
        source: the RobosuiteStateSource (object: the cube; target: `target`).
        target: this episode's target point, m (world): the lift goal or the plate centre.
        table_top_z: height of the table top, m.
        held: consecutive steps the plate check has held (lift_plate).
    """

    layout = LIBERO_OSC_POSE
    horizon = HORIZON

    def __init__(self, plate: bool = False):
        from lerobot_physvla.sources.robosuite import RobosuiteStateSource

        self.plate = plate
        self.name = "lift_plate" if plate else "lift"
        self.stop_on_success = plate
        self.expert = lift_expert(plate)
        self.env = make_lift_env(self.horizon)
        self.env.reset()
        self.table_top_z = float(self.env.table_offset[2])
        self.target = np.zeros(3)
        self.source = RobosuiteStateSource(self.env, obj_name=self.env.cube.root_body, target_xyz=self.target)
        self._fingers = np.asarray(self.env.robots[0]._ref_gripper_joint_pos_indexes)
        self.held = 0

    def reset(self, seed: int) -> None:
        """Seeded episode start (cube placement and yaw, arm init noise), settled, source reset."""
        np.random.seed(seed)
        self.env.robots[0].gripper.current_action[:] = 0.0  # a command ramp robosuite's reset keeps
        self.env.reset()
        for _ in range(SETTLE_STEPS):
            self.env.step(NO_OP)
        self.source.reset()
        if self.plate:
            self.target = np.array([*(self.env.table_offset[:2] + PLATE_XY_M), self.table_top_z])
        else:
            self.target = self.env.sim.data.body_xpos[self.env.cube_body_id] + (0.0, 0.0, LIFT_GOAL_M)
        self.source.target_xyz = self.target
        self.held = 0

    def read(self) -> PhysState:
        return self.source.read()

    def step(self, action: np.ndarray) -> tuple[bool, float]:
        """(success now, reward): lift, robosuite's check and shaped reward; lift_plate, the plate
        check and 1.0 once it succeeds (Lift's shaped reward scores lifting, not placing)."""
        _, reward, _, _ = self.env.step(np.asarray(action, dtype=np.float64))
        self.source.step()
        if not self.plate:
            return bool(self.env._check_success()), float(reward)
        self.held = self.held + 1 if self._on_plate_released() else 0
        success = self.held >= HOLD_STEPS
        return success, float(success)

    def _on_plate_released(self) -> bool:
        cube = self.env.sim.data.body_xpos[self.env.cube_body_id]
        opening = np.abs(self.env.sim.data.qpos[self._fingers]).sum()
        return bool(
            np.linalg.norm(cube[:2] - self.target[:2]) < PLATE_RADIUS_M
            and cube[2] - self.table_top_z < PLACED_HEIGHT_M
            and opening > OPEN_GRIPPER_M
        )
