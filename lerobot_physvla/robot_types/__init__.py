"""LeRobot robot types this plugin adds (like lerobot/robots/<name>/): `physvla_sim_so101`, a
MuJoCo-simulated SO-101 behind LeRobot's `Robot` interface."""
