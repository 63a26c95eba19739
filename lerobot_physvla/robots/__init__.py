"""LeRobot robot types this plugin adds (like lerobot/robots/<name>/): `physvla_sim_so101` and
`physvla_sim_panda`, MuJoCo-simulated arms behind LeRobot's `Robot` interface (their shared base:
sim_arm.py)."""

ROBOT_TYPES = ("physvla_sim_so101", "physvla_sim_panda")  # their `--robot.type` names (plugin.py registers them)
