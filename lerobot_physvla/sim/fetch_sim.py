"""gymnasium-robotics FetchPickAndPlace-v4 as a PhysVLA scene (no rendering).

Fetch's arm has no actuators: each action moves a mocap body welded to the gripper by
0.05 m per unit, and the weld constraint drags the 7 arm joints along. The applied joint
torque is therefore the constraint force, so `FetchStateSource` reads tau with
`MujocoDynamicsOracle(..., include_constraint=True)` (which also counts contact forces on the
arm). Positions are read from the live MjData, exactly as the env's observation reports them.
"""

from __future__ import annotations

import warnings
from collections import Counter

import gymnasium as gym
import mujoco
import numpy as np

from lerobot_physvla.core.config import FETCH_4D
from lerobot_physvla.sources.mujoco import MujocoDynamicsOracle
from lerobot_physvla.core.state import SCENE, PhysState, packed_size

ENV_ID = "FetchPickAndPlace-v4"
ARM_JOINTS = tuple(
    f"robot0:{j}"
    for j in ("shoulder_pan_joint", "shoulder_lift_joint", "upperarm_roll_joint", "elbow_flex_joint",
              "forearm_roll_joint", "wrist_flex_joint", "wrist_roll_joint")
)
FINGER_JOINTS = ("robot0:l_gripper_finger_joint", "robot0:r_gripper_finger_joint")  # slides, 0 .. 0.05 m each
EEF_SITE = "robot0:grip"  # between the fingertips
OBJ_SITE = "object0"  # centre of the 0.05 m cube; the env scores this site against the goal
# Control steps per episode: gym's own limit (2 s at 0.04 s). The clean expert holds the cube at
# the goal by step ~45 (seeds 0..49).
HORIZON = 50


def make_fetch_env(max_episode_steps: int = HORIZON) -> gym.Env:
    """FetchPickAndPlace-v4 with no renderer, truncated after max_episode_steps."""
    import gymnasium_robotics

    gym.register_envs(gymnasium_robotics)
    return gym.make(ENV_ID, max_episode_steps=max_episode_steps)


def _require(model: mujoco.MjModel, kind: str, name: str) -> int:
    """Id of the joint/site `name`; ValueError listing the model's names of that kind if absent."""
    obj = {"joint": mujoco.mjtObj.mjOBJ_JOINT, "site": mujoco.mjtObj.mjOBJ_SITE}[kind]
    i = mujoco.mj_name2id(model, obj, name)
    if i < 0:
        n = model.njnt if kind == "joint" else model.nsite
        names = [mujoco.mj_id2name(model, obj, k) for k in range(n)]
        raise ValueError(f"physvla: {kind} {name!r} not in the Fetch model; {kind}s are: {names}")
    return i


class FetchStateSource:
    """Reads s_t of one Fetch env (B = 1); the target is the episode's goal (`env.unwrapped.goal`).

    Attributes:
        env: the gym env (wrappers allowed); it must have been reset once before reading.
        oracle: the MuJoCo dynamics oracle of the 7 arm joints (tau includes the weld constraint).
        dt: control period, s (env.unwrapped.dt = 20 substeps of 2 ms).
        obj_rest_z: the object's height at the last `reset()`, m.
        episode_step: control steps since the last `reset()`.
        failures: Counter of exception types of failed reads (those rows come back invalid).

    At episode step 0, tau is spurious (~3e4 N m): the env's reset leaves the mocap at the world
    origin, so the weld's constraint force of that read is one that never acts (the first step
    moves the mocap back onto the gripper before integrating).
    """

    def __init__(self, env: gym.Env, arm_joints: tuple[str, ...] = ARM_JOINTS, eef_site: str = EEF_SITE,
                 obj_site: str = OBJ_SITE, finger_joints: tuple[str, ...] = FINGER_JOINTS):
        self.env = env
        sim = env.unwrapped
        model: mujoco.MjModel = sim.model
        self.oracle = MujocoDynamicsOracle(model, list(arm_joints), eef_site=eef_site, include_constraint=True)
        self._eef = self.oracle.site_id
        self._obj = _require(model, "site", obj_site)
        self._fingers = np.array([model.jnt_qposadr[_require(model, "joint", j)] for j in finger_joints], dtype=np.intp)
        self.dt = float(sim.dt)
        self.obj_rest_z = float("nan")
        self.episode_step = 0
        self._row = np.zeros(packed_size(self.oracle.n_joints))
        self.failures: Counter = Counter()  # exception type -> count of failed reads

    def reset(self) -> None:
        """Call after the env's reset: records the object's resting height."""
        self.episode_step = 0
        self.obj_rest_z = float(self.env.unwrapped.data.site_xpos[self._obj, 2])

    def step(self) -> None:
        """Call once per executed control step."""
        self.episode_step += 1

    def read_packed(self) -> np.ndarray:
        """The env's state as a flat float64 vector (PhysState.pack layout). Never raises:
        a failed read returns a row with valid = 0 (the corrector then passes actions through)."""
        try:
            sim = self.env.unwrapped
            data = sim.data
            st = PhysState(
                valid=np.array([np.isfinite(self.obj_rest_z)]),
                episode_step=np.array([self.episode_step]),
                dt=np.array([self.dt]),
                eef_pos=data.site_xpos[self._eef][None],
                gripper=np.array([np.abs(data.qpos[self._fingers]).sum()]),
                obj_pos=data.site_xpos[self._obj][None],
                obj_rest_z=np.array([self.obj_rest_z]),
                target_pos=np.asarray(sim.goal, dtype=np.float64)[None],
                pose_age=np.zeros(1),
                scene=np.full((1, len(SCENE)), np.nan),  # not measured: the corrector's fixed distances
                **{k: v[None] for k, v in self.oracle.read(data).items()},
            )
            return st.pack()[0]
        except Exception as e:  # noqa: BLE001 - do-no-harm: an unreadable state disables correction
            self.failures[type(e).__name__] += 1
            if sum(self.failures.values()) == 1:
                warnings.warn(f"physvla: reading the Fetch state failed ({e!r}); correction is off for this step", RuntimeWarning)
            return np.zeros_like(self._row)

    def read(self) -> PhysState:
        return PhysState.unpack(self.read_packed())


class FetchScene:
    """FetchPickAndPlace-v4 under the `Scene` protocol (scenes.py).

    gym's convention: the episode runs the whole horizon and scores `info["is_success"]` (cube
    centre within 5 cm of the goal) at the last step; `step` returns the current is_success and
    the env's reward (-1 / 0). `reset(seed)` seeds the env, so a seed fixes the cube and goal.

    Attributes:
        env: the gym env (make_fetch_env).
        source: its FetchStateSource.
        raw_obs: the env's latest observation dict.
    """

    name = "fetch_pick_place"
    layout = FETCH_4D
    horizon = HORIZON
    stop_on_success = False
    # Grasp the cube at its centre and carry it to the goal; the goal is often in the air, so the
    # expert holds the cube there instead of releasing it.
    expert: dict = {
        "hover_m": 0.05,
        "grasp_offset_m": (0.0, 0.0, 0.0),
        "place_offset_m": (0.0, 0.0, 0.0),
        "close_steps": 3,
        "release": False,
    }

    def __init__(self):
        self.env = make_fetch_env(self.horizon)
        self.source = FetchStateSource(self.env)
        self.raw_obs: dict = {}

    def reset(self, seed: int) -> None:
        self.raw_obs, _ = self.env.reset(seed=seed)
        self.source.reset()

    def read(self) -> PhysState:
        return self.source.read()

    def step(self, action: np.ndarray) -> tuple[bool, float]:
        self.raw_obs, reward, _, _, info = self.env.step(np.asarray(action, dtype=np.float64))
        self.source.step()
        return bool(info["is_success"]), float(reward)
