"""Where the corrector's physical state comes from, packed as core/state.py lays it out:
`mujoco.py` (the dynamics oracle: M, bias, tau and the Jacobian read from a live MjData),
`robosuite.py` (robosuite / LIBERO envs: end effector, fingers, the BDDL goal's object and target),
`joint_state.py` (a robot's joint readings through its arm model, arms/model.py), `markers.py` (the object's and
the target's positions from ArUco markers in a camera frame, with `calibration.py`, the camera's file, and
`marker_render.py`, synthetic frames to test them against)."""
