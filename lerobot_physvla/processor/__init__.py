"""LeRobot processor steps (like `lerobot/processor`): state capture and the corrector step."""
