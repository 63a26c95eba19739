"""LeRobot env types (like `lerobot/envs`): `libero_physvla`."""
