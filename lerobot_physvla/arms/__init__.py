"""Arms the corrector reads state from on a robot: an arm's MuJoCo model and the map from the
robot's motor names to its joints (`arms.py`), and the physical state s_t computed from joint
readings with that model (`joint_state.py`)."""
