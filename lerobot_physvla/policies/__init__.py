"""LeRobot policy types (like `lerobot/policies/<name>/`): the scripted expert `physvla_scripted` and MetaWorld's own
scripted policies `physvla_metaworld_scripted`."""
