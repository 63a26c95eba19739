"""The physical state s_t of a robot arm from its joint readings and its MuJoCo model.

A LeRobot robot reports joint positions ("<motor>.pos" in its observation dict). From them and the
arm's model (`arms.ArmModel`) this computes what the corrector reads: end-effector position
(forward kinematics), gripper opening, M(q), bias C(q, qdot) qdot + G(q), the end-effector
Jacobian; joint velocities are finite differences of the positions over the control period,
low-passed (the readings are noisy: the paper names noisy velocities as what blocks Branch B on
hardware). The object and target come from configuration (fixed points in the model's frame) or
from observation keys a perception step fills. A robot has no torque sensing here, so tau is
taken as the bias torque (the arm held where it is): r_EL (eq. 4) is then M qddot of the motion
the action proposes.
"""

from __future__ import annotations

import math
import warnings
from collections import Counter

import numpy as np

from lerobot_physvla.core.state import field_offsets, packed_size
from lerobot_physvla.arms.model import ArmError, ArmModel, ArmSpec


NOISE_WINDOW = 30  # readings over which the reading noise is estimated (1 s at 30 Hz)
MIN_NOISE_SAMPLES = 8


class JointStateSource:
    """s_t of one arm from its joint readings, as a packed state row (state.py layout).

    Attributes:
        arm: the arm's model.
        dt: control period, s.
        object_xyz, target_xyz: fixed object / target positions in the model's frame, m, or None.
        object_key, target_key: observation keys holding them (3 floats, m, model frame), or the
            stem of three float keys "<key>.x", "<key>.y", "<key>.z" (lerobot robots report floats), or None.
            A non-finite value there (the perception step lost the object) is a missing pose: the
            corrector passes through (missing_pose).
        pose_age_key: an observation key where the perception step reports how old the poses are, control
            steps (its lag and the steps it has held a lost pose); None: 0, the poses are current.
        velocity_cutoff_hz: cutoff of the first-order low-pass on the finite-difference joint
            velocity, Hz (None: unfiltered).
        state_delay_s: how old the readings are when they arrive, s (bus and driver latency); the
            positions are carried forward by qdot * state_delay_s (0: taken as they are).
        obj_rest_z: the object's resting height, m: its height at the episode's first read.
        episode_step: reads since the last `reset()`.
        reading_noise_deg: std of the joint readings' noise, degrees, as configured; None: estimated
            online from the readings (`reading_noise_rad`).
        failures: Counter of exception types of failed reads (those rows come back invalid).
    """

    def __init__(self, arm: str | ArmSpec | ArmModel, dt: float, object_xyz=None, target_xyz=None,
                 object_key: str | None = None, target_key: str | None = None,
                 velocity_cutoff_hz: float | None = 5.0, state_delay_s: float = 0.0,
                 reading_noise_deg: float | None = None, pose_age_key: str | None = None):
        self.arm = arm if isinstance(arm, ArmModel) else ArmModel(arm)
        if not (dt > 0 and math.isfinite(dt)):
            raise ArmError(f"physvla: control period dt={dt!r} s; give the robot's period (e.g. 1/30)")
        if (object_xyz is None) == (object_key is None) or (target_xyz is None) == (target_key is None):
            raise ArmError("physvla: give the object's and the target's position, each either as a fixed point "
                           "(object_xyz, target_xyz: m, in the arm model's frame) or as an observation key")
        self.dt = float(dt)
        self.object_xyz = None if object_xyz is None else np.asarray(object_xyz, dtype=np.float64).reshape(3)
        self.target_xyz = None if target_xyz is None else np.asarray(target_xyz, dtype=np.float64).reshape(3)
        self.object_key, self.target_key, self.pose_age_key = object_key, target_key, pose_age_key
        self.velocity_cutoff_hz = velocity_cutoff_hz
        if not (state_delay_s >= 0 and math.isfinite(state_delay_s)):
            raise ArmError(f"physvla: state_delay_s={state_delay_s!r}; give the readings' age in seconds (>= 0)")
        self.state_delay_s = float(state_delay_s)
        if reading_noise_deg is not None and not (reading_noise_deg >= 0 and math.isfinite(reading_noise_deg)):
            raise ArmError(f"physvla: reading_noise_deg={reading_noise_deg!r}; give the joint readings' noise std "
                           "in degrees (>= 0), or None to estimate it from the readings")
        self.reading_noise_deg = reading_noise_deg
        fc = velocity_cutoff_hz  # the velocity estimate's noise per unit of reading noise (see velocity_noise_rad_s)
        a = 1.0 if fc is None else self.dt / (self.dt + 1.0 / (2.0 * math.pi * fc))
        self._qdot_gain = a * math.sqrt(2.0 / (2.0 - a)) / self.dt
        spec = self.arm.spec
        self._keys = [f"{m}.pos" for m in spec.motors]
        self._grip_key = None if spec.gripper_motor is None else f"{spec.gripper_motor}.pos"
        self._f = field_offsets(self.arm.n_joints)
        self._not_pose = np.ones(packed_size(self.arm.n_joints), bool)  # every field but obj_pos, obj_rest_z,
        self._not_pose[self._f["obj_pos"] : self._f["target_pos"] + 3] = False  # target_pos (they lie together)
        self._size = packed_size(self.arm.n_joints)
        self.failures: Counter = Counter()
        # |third differences| of the readings, a ring buffer kept across episodes (the sensor's noise)
        self._d3 = np.full((NOISE_WINDOW, self.arm.n_joints), np.nan)
        self._n_d3 = 0
        self.reset()

    def reset(self) -> None:
        """Call at an episode's start: the next read starts the step counter, velocities and the
        object's resting height afresh (the reading-noise estimate is kept)."""
        self.episode_step = 0
        self.obj_rest_z = float("nan")
        self._q_prev: np.ndarray | None = None
        self._qdot = np.zeros(self.arm.n_joints)
        self._hist = np.full((4, self.arm.n_joints), np.nan)  # the last 4 readings (rad), newest last

    @property
    def reading_noise_rad(self) -> np.ndarray:
        """Per joint, the readings' noise std, rad: as configured, or estimated from the last
        NOISE_WINDOW third differences of the readings (robust: median |d3| / 0.6745 / sqrt(20), since
        d3 = q_t - 3 q_t-1 + 3 q_t-2 - q_t-3 of white noise has variance 20 sigma^2 and a smooth
        motion's d3 is its jerk * dt^3, ~0). NaN until MIN_NOISE_SAMPLES differences are seen."""
        n = self.arm.n_joints
        if self.reading_noise_deg is not None:
            return np.full(n, self.reading_noise_deg * math.pi / 180.0)
        if self._n_d3 < MIN_NOISE_SAMPLES:
            return np.full(n, np.nan)
        return np.median(self._d3[: min(self._n_d3, NOISE_WINDOW)], axis=0) / (0.6745 * math.sqrt(20.0))

    @property
    def velocity_noise_rad_s(self) -> np.ndarray:
        """Per joint, the std of the velocity estimate's noise, rad/s: the reading noise through the
        finite difference and the low-pass (for white reading noise sigma, the filter's output has
        std sigma / dt * a sqrt(2 / (2 - a)), a its smoothing factor; a = 1 unfiltered: sqrt(2) sigma / dt)."""
        return self.reading_noise_rad * self._qdot_gain

    def _track_noise(self, q: np.ndarray) -> None:
        h = self._hist
        h[:-1] = h[1:]
        h[-1] = q
        if self.episode_step >= 3:
            self._d3[self._n_d3 % NOISE_WINDOW] = np.abs(h[3] - 3.0 * h[2] + 3.0 * h[1] - h[0])
            self._n_d3 += 1

    def check(self, observation: dict) -> None:
        """Raises a one-line ArmError when the observation lacks a key this arm needs (call it on the
        first observation, before the robot moves)."""
        need = self._keys + ([self._grip_key] if self._grip_key else []) + [
            k if k in observation else f"{k}.{c}" for k in (self.object_key, self.target_key) if k is not None
            for c in ("x",) + (("y", "z") if k not in observation else ())] + (
            [self.pose_age_key] if self.pose_age_key else [])
        missing = [k for k in need if k not in observation]
        if missing:
            have = sorted(k for k in observation if isinstance(k, str))
            raise ArmError(f"physvla: arm {self.arm.spec.name!r} reads {missing}, which the robot's observation "
                           f"lacks (it has {have}); map the robot's motors in ArmSpec.motors")

    def _point(self, fixed, key, observation) -> np.ndarray:
        if key is None:
            return fixed
        if key in observation:
            return np.asarray(observation[key], dtype=np.float64).reshape(3)
        return np.array([float(observation[f"{key}.{c}"]) for c in "xyz"])

    def read_packed(self, observation: dict) -> np.ndarray:
        """s_t as a new packed row. Never raises: a failed read (a missing or non-numeric key, a
        model error) returns a row with valid = 0, counted in `failures` and warned once, so the
        corrector passes actions through."""
        try:
            return self._read(observation)
        except Exception as e:  # noqa: BLE001 - do-no-harm: an unreadable state disables correction
            self.failures[type(e).__name__] += 1
            if sum(self.failures.values()) == 1:
                warnings.warn(f"physvla: reading the arm's state failed ({e!r}); correction is off while it does",
                              RuntimeWarning, stacklevel=2)
            return np.zeros(self._size)

    def _read(self, observation: dict) -> np.ndarray:
        spec, f = self.arm.spec, self._f
        q = np.array([float(observation[k]) for k in self._keys]) * spec.to_radians
        if not np.isfinite(q).all():  # skipped: it must not poison the velocity filter or the noise estimate
            raise ValueError(f"non-finite joint reading {q.tolist()}")
        self._track_noise(q)
        if self._q_prev is None:
            self._qdot[:] = 0.0
        else:
            raw = (q - self._q_prev) / self.dt  # rad/s
            if self.velocity_cutoff_hz is None:
                self._qdot[:] = raw
            else:  # first-order low-pass: alpha = dt / (dt + 1 / (2 pi fc))
                alpha = self.dt / (self.dt + 1.0 / (2.0 * math.pi * self.velocity_cutoff_hz))
                self._qdot += alpha * (raw - self._qdot)
        self._q_prev = q
        if self.state_delay_s > 0:  # where the joints are now, not when they were read
            q = q + self._qdot * self.state_delay_s
        dyn = self.arm.dynamics(q, self._qdot)
        obj = self._point(self.object_xyz, self.object_key, observation)
        tgt = self._point(self.target_xyz, self.target_key, observation)
        if self.episode_step == 0 or not math.isfinite(self.obj_rest_z):
            self.obj_rest_z = float(obj[2])
        row = np.zeros(self._size)
        row[f["valid"]] = 1.0  # a non-finite pose stays in the row: the corrector names it (missing_pose)
        row[f["episode_step"]] = self.episode_step
        row[f["dt"]] = self.dt
        row[f["eef_pos"] : f["eef_pos"] + 3] = dyn["eef_pos"]
        if self._grip_key is not None:  # the opening, m, from the gripper's reading
            row[f["gripper"]] = float(observation[self._grip_key]) / spec.gripper_full_scale * spec.gripper_open_m
        row[f["obj_pos"] : f["obj_pos"] + 3] = obj
        row[f["obj_rest_z"]] = self.obj_rest_z
        row[f["target_pos"] : f["target_pos"] + 3] = tgt
        n = self.arm.n_joints
        for name in ("q", "qdot", "bias"):
            row[f[name] : f[name] + n] = dyn[name]
        row[f["M"] : f["M"] + n * n] = dyn["M"].ravel()
        row[f["tau"] : f["tau"] + n] = dyn["bias"]  # no torque sensing: the arm held where it is
        row[f["J_pos"] : f["J_pos"] + 3 * n] = dyn["J_pos"].ravel()
        if self.pose_age_key is not None:
            row[f["pose_age"]] = float(observation[self.pose_age_key])
        if not np.isfinite(row[self._not_pose]).all():  # a reading out of this world (inf, NaN): no state to correct from
            row[f["valid"]] = 0.0
        self.episode_step += 1
        return row
