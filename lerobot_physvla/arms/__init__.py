"""Robot arms: an arm's MuJoCo model and the map from a robot's motor names to its joints
(`model.py`: so101, panda, or your own MJCF), and the corrected joint targets sent back to it
(`joint_targets.py`). The state read from an arm's joints is sources/joint_state.py."""
