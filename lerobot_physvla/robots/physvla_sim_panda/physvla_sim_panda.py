"""A MuJoCo-simulated Franka Panda behind LeRobot's `Robot` interface (robots/sim_arm.py).

Scene, built from the arm model the corrector uses (robosuite's Panda, arms/model.py): the torque
motors replaced by a position servo per joint (gravity compensated, as Franka's controller does),
a two-finger parallel gripper of 0.08 m opening on the hand, a floor and a 4 cm block. Keys: "joint1.pos" ..
"joint7.pos" in radians, "gripper.pos" 0 (closed) .. 100 (open).
"""

from __future__ import annotations

import mujoco

from lerobot_physvla.arms.model import ARMS, arm_mjspec
from lerobot_physvla.robots.physvla_sim_panda.config_physvla_sim_panda import SimPandaConfig
from lerobot_physvla.robots.sim_arm import SimArm

KP, KV = 400.0, 40.0  # joint servos, N m / rad and N m s / rad
FINGER_TRAVEL_M = 0.04  # each finger; the opening is twice this


class SimPanda(SimArm):
    """The simulated Panda (see module docstring and `SimArm`)."""

    config_class = SimPandaConfig
    name = "physvla_sim_panda"
    arm = "panda"
    gripper_joint = "finger_l"

    def build_scene(self):
        spec = ARMS["panda"]
        ms = arm_mjspec(spec)
        ms.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST  # the servos' damping, stably
        for act in list(ms.actuators):
            ms.delete(act)
        for body in ms.bodies:
            if body.name != "world":
                body.gravcomp = 1.0
        for j in spec.joints:
            a = ms.add_actuator(name=j, target=j, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            a.set_to_position(kp=KP, kv=KV)
        hand = ms.body(spec.eef_body)
        for side, sign in (("l", 1.0), ("r", -1.0)):
            finger = hand.add_body(name=f"finger_{side}", pos=[0.0, 0.0, 0.07])
            finger.gravcomp = 1.0
            finger.add_joint(name=f"finger_{side}", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0.0, sign, 0.0],
                             range=[0.0, FINGER_TRAVEL_M], damping=5.0)
            finger.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.01, 0.004, 0.025], pos=[0.0, sign * 0.005, 0.025],
                            mass=0.05, friction=[2.0, 0.05, 0.001])
            a = ms.add_actuator(name=f"finger_{side}", target=f"finger_{side}", trntype=mujoco.mjtTrn.mjTRN_JOINT)
            a.set_to_position(kp=300.0, kv=10.0)
        ms.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[2.0, 2.0, 0.1])
        block = ms.worldbody.add_body(name="block", pos=[0.55, 0.0, 0.02])
        block.add_freejoint(name="block")
        block.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02, 0.02, 0.02], mass=0.1, friction=[2.0, 0.05, 0.001])
        model = ms.compile()
        return model, {"finger_l": (0.0, FINGER_TRAVEL_M), "finger_r": (0.0, FINGER_TRAVEL_M)}
