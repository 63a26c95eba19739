"""The corrector on a real arm: a step for `lerobot-rollout`'s robot action processor.

`lerobot-rollout` sends every action through `robot_action_processor((action_dict, raw_observation))`
(lerobot/rollout/strategies/core.py). This step reads the arm's joint positions from the raw
observation, computes s_t with the arm's MuJoCo model (sources/joint_state.py), reads the
joint-target action as the Cartesian move it proposes (arms/joint_targets.py), corrects it, and
writes the corrected joint and gripper targets back into the action dict. Keys the correction
did not change are returned exactly as the policy sent them.

Do-no-harm: on its first call the step checks the observation and the action carry every key the
arm needs and raises a one-line ArmError otherwise (no action has reached the robot yet); after
that it never raises. A non-finite target is replaced by the joint's current reading (hold
still), an unreadable state or any error passes the policy's action through; each is counted in
`passthrough_counts` and warned once.
"""

from __future__ import annotations

import math
import time
import warnings
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lerobot.configs import PipelineFeatureType, PolicyFeature
from lerobot.lerobot_types import EnvTransition, TransitionKey
from lerobot.processor.pipeline import ProcessorStep, ProcessorStepRegistry

from lerobot_physvla.core.config import ARM_PRESET, PRESETS, PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.state import field_offsets
from lerobot_physvla.processor.physvla_processor import _unregister_name_for_saving
from lerobot_physvla.arms.model import ArmError, ArmModel
from lerobot_physvla.sources.joint_state import JointStateSource
from lerobot_physvla.arms.joint_targets import VIRTUAL, JointTargetAdapter
from lerobot_physvla.core.noise_guard import BranchBNoiseGuard
from lerobot_physvla.sources.calibration import load_calibration
from lerobot_physvla.sources.markers import MarkerConfig, MarkerReading, MarkerSource


TIMES_KEPT = 10_000  # ticks whose times summary() takes its percentiles over
POSE_SOURCES = ("markers",)  # besides the default: fixed points (object_xyz) or observation keys (object_key)
MARKER_KEY = "physvla.marker.{}"  # where the step puts a marker's position (3 floats, m) for the state source
MARKER_AGE_KEY = "physvla.marker.pose_age"  # ... and the positions' age (control steps)
MARKER_FIELDS = ("camera", "object_marker", "target_marker", "marker_size_m", "calibration", "object_marker_offset",
                 "target_marker_offset")


def _finite(v) -> bool:
    try:
        return math.isfinite(float(v))
    except (TypeError, ValueError):
        return False


@_unregister_name_for_saving
@ProcessorStepRegistry.register("physvla_robot_corrector")
@dataclass
class PhysVLARobotActionStep(ProcessorStep):
    """Corrects a robot arm's joint-target action dict (lerobot-rollout's robot action processor).

    Attributes:
        arm: a known arm (arms/model.py ARMS: so101, panda, or one registered).
        fps: the control rate, Hz (dt = 1 / fps for the joint velocities).
        object_xyz, target_xyz: fixed object / target points in the arm model's frame, m; or
        object_key, target_key: raw-observation keys holding them (a perception step fills them).
        pose_age_key: a raw-observation key where the perception step reports the poses' age, control steps
            (None: current); the corrector acts on none older than config's pose_max_age_steps.
        pose_source: None (the object / target from the fields above) or "markers": from ArUco markers in a camera
            frame of the raw observation (sources/markers.py), with:
        camera: the raw-observation key of the camera's frame ((H, W, 3) uint8 RGB, as lerobot's cameras give it).
        object_marker, target_marker: the markers' ids (either may stay a fixed point or a key: object_xyz, ...).
        marker_size_m: the printed markers' black square's side, m.
        calibration: the camera's calibration file (sources/calibration.py; lerobot-physvla-calibrate-camera).
        marker_dictionary: the markers' cv2.aruco dictionary.
        marker_max_error_m: a marker position whose error bound is larger (m) is not used (pose_error_high), and
            the corrector is told this much pose error (its pose_error_m, if that is smaller).
        object_marker_offset, target_marker_offset: from the marker's centre to the point the corrector reads, m,
            base frame (e.g. [0, 0, -0.02]: a marker on top of a 4 cm block, to the block's centre).
        pose_counts: Counter of "<object|target> <reason>" over the ticks a marker gave no current position
            (sources/markers.py REASONS), each warned once.
        config: PhysVLAConfig fields (default: the `arm` preset, the approach veto alone); the action layout is
            the virtual Cartesian one (arms/joint_targets.py) and Branch B weights task-space.
        arm_geometry: the approach veto uses the arm's own gripper geometry (ArmSpec.veto_height_m,
            veto_reach_m) where the arm gives it, in place of the config's (tuned on LIBERO's Panda).
        velocity_cutoff_hz: low-pass cutoff of the joint velocities, Hz (None: unfiltered).
        state_delay_s: the readings' age when they arrive, s; positions are carried forward by it.
        reading_noise_deg: the joint readings' noise std, degrees; None: estimated from the readings.
        noise_snr_min: with Branch B (mode phys_el), it runs on a tick only when its residual is at
            least this many times the residual's noise std (core/noise_guard.py); 0: always.
        branch_b_off: Counter of the reasons Branch B was off on a tick (noise_unknown, noise_dominated,
            guard_error).
        ticks, changed: control ticks seen, and how many changed the gripper / joint targets
            (`summary()` reports them with the step's time per tick).
    """

    arm: str = "so101"
    fps: float = 30.0
    object_xyz: list[float] | None = None
    target_xyz: list[float] | None = None
    object_key: str | None = None
    target_key: str | None = None
    pose_age_key: str | None = None
    pose_source: str | None = None
    camera: str | None = None
    object_marker: int | None = None
    target_marker: int | None = None
    marker_size_m: float | None = None
    calibration: str | None = None
    marker_dictionary: str = "DICT_4X4_50"
    marker_max_error_m: float = 0.01
    object_marker_offset: list[float] | None = None
    target_marker_offset: list[float] | None = None
    config: dict[str, Any] = field(default_factory=lambda: PRESETS[ARM_PRESET].to_dict())
    arm_geometry: bool = True
    velocity_cutoff_hz: float | None = 5.0
    state_delay_s: float = 0.0
    reading_noise_deg: float | None = None
    noise_snr_min: float = 3.0
    passthrough_counts: Counter = field(default_factory=Counter, init=False, repr=False)
    branch_b_off: Counter = field(default_factory=Counter, init=False, repr=False)
    pose_counts: Counter = field(default_factory=Counter, init=False, repr=False)

    def __post_init__(self) -> None:
        model = ArmModel(self.arm)  # unknown arm, model, joints: ArmError now
        cfg = PhysVLAConfig.from_dict(self.config).replace(layout=VIRTUAL, weighting="task_space")
        self.markers = self._marker_source(cfg)  # None without pose_source=markers; a bad setting: ArmError now
        keys = {"object": self.object_key, "target": self.target_key, "age": self.pose_age_key}
        if self.markers is not None:
            keys.update({n: MARKER_KEY.format(n) for n in self.markers.markers}, age=MARKER_AGE_KEY)
            # the corrector is told the bound every position used is within (pose_error_high refuses the others)
            cfg = cfg.replace(pose_error_m=max(cfg.pose_error_m, self.marker_max_error_m))
        self.source = JointStateSource(model, 1.0 / self.fps, self.object_xyz, self.target_xyz, keys["object"],
                                       keys["target"], self.velocity_cutoff_hz, self.state_delay_s,
                                       self.reading_noise_deg, keys["age"])
        self.adapter = JointTargetAdapter(model)
        spec = model.spec
        if self.arm_geometry:
            geometry = {k: getattr(spec, k) for k in ("veto_height_m", "veto_reach_m") if getattr(spec, k) is not None}
            cfg = cfg.replace(**geometry)
        self.cfg = cfg
        self.corrector = Corrector(self.cfg, 1)
        b = self.corrector.branch_b is not None and self.noise_snr_min > 0
        self.guard = BranchBNoiseGuard(self.noise_snr_min) if b else None
        if self.guard is not None:
            self.guard.warm_up(model.n_joints)
        self._keys = [f"{m}.pos" for m in spec.motors]
        self._grip = None if spec.gripper_motor is None else f"{spec.gripper_motor}.pos"
        self._to_rad = spec.to_radians
        f = field_offsets(model.n_joints)
        self._eef, self._valid, self._j, self._n = f["eef_pos"], f["valid"], f["J_pos"], model.n_joints
        self._f = f
        m = model.model
        ids = [m.joint(j).id for j in spec.joints]
        limited = m.jnt_limited[ids].astype(bool) & (m.jnt_range[ids, 0] < m.jnt_range[ids, 1])
        self._q_lo = np.where(limited, m.jnt_range[ids, 0], -np.inf)  # rad
        self._q_hi = np.where(limited, m.jnt_range[ids, 1], np.inf)
        self._checked = False
        self._all_keys = self._keys + ([self._grip] if self._grip else [])
        self._last: dict[str, float] = {}  # the targets this step sent last (the hold where nothing else is finite)
        self.ticks = 0
        self.changed: Counter = Counter()
        self._t_us = np.zeros(TIMES_KEPT)  # the last TIMES_KEPT ticks' times (us), a ring: memory stays flat

    def _marker_source(self, cfg: PhysVLAConfig) -> MarkerSource | None:
        """The marker pose source pose_source=markers asks for (None without it); ArmError, one line saying what to
        give, for a setting that cannot work (before the robot moves)."""
        given = [k for k in MARKER_FIELDS if getattr(self, k) is not None]
        if self.pose_source is None:
            if given:
                raise ArmError(f"physvla: {', '.join(given)} need --physvla.pose_source=markers")
            return None
        if self.pose_source not in POSE_SOURCES:
            raise ArmError(f"physvla: pose_source={self.pose_source!r}; choose markers (or leave it out: object_xyz / "
                           "object_key, target_xyz / target_key)")
        if self.camera is None or self.calibration is None or self.marker_size_m is None:
            raise ArmError("physvla: pose_source=markers needs --physvla.camera=<the robot's camera key>, "
                           "--physvla.calibration=<camera file> and --physvla.marker_size_m=<printed side, m>")
        wanted = {n: getattr(self, f"{n}_marker") for n in ("object", "target")
                  if getattr(self, f"{n}_marker") is not None}
        if not wanted:
            raise ArmError("physvla: pose_source=markers needs --physvla.object_marker=<id> and/or "
                           "--physvla.target_marker=<id>")
        for n in wanted:
            both = [k for k in (f"{n}_xyz", f"{n}_key") if getattr(self, k) is not None]
            if both:
                raise ArmError(f"physvla: the {n} is given twice ({n}_marker and {', '.join(both)}); give one")
        if self.pose_age_key is not None:
            raise ArmError("physvla: pose_age_key is a perception step's own; with pose_source=markers the poses' age "
                           "is the markers'")
        try:
            offsets = {n: tuple(getattr(self, f"{n}_marker_offset")) for n in ("object", "target")
                       if getattr(self, f"{n}_marker_offset") is not None}
            mc = MarkerConfig(float(self.marker_size_m), self.marker_dictionary, max_error_m=self.marker_max_error_m,
                              max_age_steps=cfg.pose_max_age_steps)
            return MarkerSource(load_calibration(self.calibration), wanted, mc, offsets)
        except (ValueError, TypeError) as e:
            raise ArmError(f"physvla: {e}") from None

    def _marker_poses(self, observation: dict) -> dict:
        """The observation with the markers' positions and age (MARKER_KEY, MARKER_AGE_KEY) from this tick's frame;
        each reason a marker gives no current position is counted in pose_counts and warned once. Never raises: a
        failure leaves no position (the corrector passes through: missing_pose)."""
        obs = dict(observation)
        ages = []
        try:
            readings = self.markers.observe(observation.get(self.camera))
        except Exception as e:  # noqa: BLE001 - observe does not raise; this is the last net
            readings = {}
            self._warn("marker_error", f"{type(e).__name__}: {e}")
        for name in self.markers.markers:
            r: MarkerReading | None = readings.get(name)
            pos = None if r is None else r.position_m
            obs[MARKER_KEY.format(name)] = np.full(3, np.nan) if pos is None else pos
            ages.append(0.0 if pos is None else float(r.age_steps))
            if r is not None and r.reason is not None:
                key = f"{name} {r.reason}"
                self.pose_counts[key] += 1
                if self.pose_counts[key] == 1:
                    warnings.warn(f"physvla: the {name}'s marker {r.marker_id}: {r.reason} ({r.detail}); "
                                  f"counted in pose_counts", RuntimeWarning, stacklevel=4)
        obs[MARKER_AGE_KEY] = max(ages)
        return obs

    def _warn(self, why: str, detail: str) -> None:
        self.passthrough_counts[why] += 1
        if self.passthrough_counts[why] == 1:
            warnings.warn(f"physvla: {why} ({detail}); see passthrough_counts", RuntimeWarning, stacklevel=4)

    def _check(self, action: dict, observation: dict) -> None:
        self.source.check(observation)
        missing = [k for k in self._all_keys if k not in action]
        if missing:
            raise ArmError(f"physvla: arm {self.arm!r} corrects {missing}, which the policy's action lacks (it has "
                           f"{sorted(action)}); map the robot's motors in ArmSpec.motors")
        self._checked = True

    def __call__(self, transition: EnvTransition) -> EnvTransition:
        action = transition.get(TransitionKey.ACTION)
        observation = transition.get(TransitionKey.OBSERVATION)
        if not isinstance(action, dict) or not isinstance(observation, dict):
            return transition
        if self.markers is not None:
            if not self._checked and self.camera not in observation:
                have = sorted(k for k in observation if isinstance(k, str))
                raise ArmError(f"physvla: the robot's observation has no camera {self.camera!r} (it has {have}); give "
                               "--physvla.camera=<its camera's key>")
            observation = self._marker_poses(observation)
        if not self._checked:
            self._check(action, observation)  # before any action reaches the robot: may raise
        t0 = time.perf_counter()
        try:
            out = self._correct(action, observation)
        except Exception as e:  # noqa: BLE001 - do-no-harm: the corrector never stops a rollout
            self._warn("corrector_error", f"{type(e).__name__}: {e}")
            out = self._held(action, observation)
        out = self._held(out, observation)  # the last net: nothing non-finite reaches the robot
        self._last = {k: out[k] for k in self._all_keys}
        self._tally(action, out, time.perf_counter() - t0)
        new = dict(transition)
        new[TransitionKey.ACTION] = out
        return new

    def _held(self, action: dict, observation: dict) -> dict:
        """The action with every non-finite (or unreadable) target replaced by the joint's current
        reading, or where that is not finite either, by the target this step sent last. On the first
        call, with neither, ArmError (no action has reached the robot yet)."""
        out = None
        for k in self._all_keys:
            if _finite(action.get(k)):
                continue
            out = dict(action) if out is None else out
            if _finite(observation.get(k)):
                out[k] = float(observation[k])
            elif k in self._last:
                out[k] = self._last[k]
            else:
                raise ArmError(f"physvla: {k} has no finite value in the policy's action ({action.get(k)!r}) nor in "
                               f"the robot's reading ({observation.get(k)!r}); nothing safe to send")
        return action if out is None else out

    def _correct(self, action: dict, observation: dict) -> dict:
        q_t = np.array([float(action[k]) for k in self._keys]) * self._to_rad
        g_r = float(action[self._grip]) if self._grip else None
        if not np.isfinite(q_t).all() or (g_r is not None and not math.isfinite(g_r)):
            self._warn("held_nonfinite_action", "a non-finite joint target is replaced by the joint's reading")
            return self._held(action, observation)
        row = self.source.read_packed(observation)
        if row[self._valid] != 1.0:
            self._warn("invalid_state", "the arm's state could not be read; the policy's action passes")
            return dict(action)
        a_raw = self.adapter.to_virtual(q_t, g_r, row[self._eef : self._eef + 3])
        j_pos = row[self._j : self._j + 3 * self._n].reshape(3, self._n)
        if self.guard is not None:
            self._guard_branch_b(row, a_raw, j_pos)
        a_out = self.corrector.correct_packed(a_raw[None], row[None])[0]
        q_new, g_new = self.adapter.from_virtual(a_out, a_raw, q_t, g_r, j_pos)
        if (q_new is not None and not np.isfinite(q_new).all()) or (g_new is not None and not math.isfinite(g_new)):
            self._warn("nonfinite_correction", "the correction mapped back to the joints is not finite; the policy's "
                       "action passes")
            return dict(action)
        out = dict(action)
        if q_new is not None:  # a joint the correction moved, and only those, inside the model's range
            moved = q_new != q_t
            q_new = np.clip(q_new, self._q_lo, self._q_hi) / self._to_rad
            for k, v, m in zip(self._keys, q_new, moved):
                if m:
                    out[k] = float(v)
        if g_new is not None:
            out[self._grip] = float(np.clip(g_new, 0.0, self.source.arm.spec.gripper_full_scale))
        return out

    def _guard_branch_b(self, row: np.ndarray, a_raw: np.ndarray, j_pos: np.ndarray) -> None:
        """Branch B on or off for this tick, by the noise guard (core/noise_guard.py)."""
        f, n, src = self._f, self._n, self.source
        dt = row[f["dt"]]
        v = a_raw[list(VIRTUAL.pos)] * (VIRTUAL.metres_per_unit / dt)  # m/s, as Branch B reads it
        try:
            why = self.guard.check(row[f["M"] : f["M"] + n * n].reshape(n, n), j_pos, row[f["qdot"] : f["qdot"] + n],
                                   row[f["bias"] : f["bias"] + n], row[f["tau"] : f["tau"] + n], v, dt,
                                   self.cfg.dls_damping, src.reading_noise_rad, src.velocity_noise_rad_s)
        except Exception:  # noqa: BLE001 - the guard cannot judge this tick: Branch B off, Branch A still runs
            why = "guard_error"
        self.corrector.set_branch_b(why is None)
        if why is not None:
            self.branch_b_off[why] += 1
            if self.branch_b_off[why] == 1:
                warnings.warn(f"physvla: Branch B off on this tick ({why}: |r_EL| / noise = {self.guard.last_snr:.2f}, "
                              f"below noise_snr_min={self.noise_snr_min}); counted in branch_b_off",
                              RuntimeWarning, stacklevel=5)

    def _tally(self, action: dict, out: dict, seconds: float) -> None:
        """Counts for `summary()`: ticks, ticks whose gripper / joint targets changed, the step's time."""
        self.ticks += 1
        if self._grip and out[self._grip] != action.get(self._grip):
            self.changed["gripper"] += 1
        if any(out[k] != action.get(k) for k in self._keys):
            self.changed["joints"] += 1
        self._t_us[self.ticks % len(self._t_us)] = seconds * 1e6

    def summary(self) -> str:
        """One line: what the step did over the rollout (printed by lerobot-rollout's hook at exit)."""
        if not self.ticks:
            return "physvla: no control tick reached the corrector"
        t = self._t_us[: min(self.ticks, len(self._t_us))]
        p50, p99 = np.percentile(t, [50, 99])
        fmt = lambda c: ", ".join(f"{k} {v}" for k, v in sorted(c.items())) or "none"  # noqa: E731
        c = self.cfg
        markers = ""
        if self.markers is not None and self.markers.seconds:
            markers = (f"; markers: no current position {fmt(self.pose_counts)}, "
                       f"{np.median(self.markers.seconds) * 1e3:.1f} ms per frame p50")
        return (f"physvla: {self.ticks} ticks on arm {self.arm!r} (mode {c.mode}, gripper rule {c.gripper_rule}, "
                f"place rule {c.place_rule}); "
                f"gripper target changed on {self.changed['gripper']}, joint targets on {self.changed['joints']}; "
                f"passed through: {fmt(self.passed_through)}; Branch B off: {fmt(self.branch_b_off)}; "
                f"time per tick p50 {p50:.0f} us, p99 {p99:.0f} us{markers}")

    @property
    def passed_through(self) -> Counter:
        """Ticks passed through, by reason: this step's own (passthrough_counts: an unreadable state, a
        non-finite target, an error) and the corrector's (missing_pose, stale_pose, singular_dynamics, ...)."""
        return self.passthrough_counts + self.corrector.passthrough_counts

    def reset(self) -> None:
        """An episode starts: the state source and the corrector's memory start afresh."""
        self.source.reset()
        self.corrector.reset()
        if self.markers is not None:
            self.markers.reset()
        if self.guard is not None:
            self.guard.reset()

    def get_config(self) -> dict[str, Any]:
        markers = {} if self.pose_source is None else {  # only with markers: a file saved without stays as it was
            k: getattr(self, k) for k in ("pose_source", *MARKER_FIELDS, "marker_dictionary", "marker_max_error_m")}
        return {"arm": self.arm, "fps": self.fps, "object_xyz": self.object_xyz, "target_xyz": self.target_xyz,
                "object_key": self.object_key, "target_key": self.target_key, "pose_age_key": self.pose_age_key,
                **markers,
                "config": self.config,
                "arm_geometry": self.arm_geometry,
                "velocity_cutoff_hz": self.velocity_cutoff_hz, "state_delay_s": self.state_delay_s,
                "reading_noise_deg": self.reading_noise_deg, "noise_snr_min": self.noise_snr_min}

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        return features
