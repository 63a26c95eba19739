"""The scripted pick-and-place expert as a LeRobot policy type (`physvla_scripted`)."""

from .configuration_physvla_scripted import PhysVLAScriptedConfig

__all__ = ["PhysVLAScriptedConfig"]
