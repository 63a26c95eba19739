"""LeRobot policy types (like `lerobot/policies/<name>/`): the scripted expert `physvla_scripted`."""
