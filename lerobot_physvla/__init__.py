"""lerobot-physvla: inference-time physics-aware action correction for frozen LeRobot policies."""
__version__ = "0.1.0"
