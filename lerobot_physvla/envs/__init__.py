"""LeRobot env types (like `lerobot/envs`): `libero_physvla`, `metaworld_physvla`, `so101_physvla`."""
