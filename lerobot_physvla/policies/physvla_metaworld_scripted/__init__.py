"""MetaWorld's own scripted policies (`metaworld.policies`) as a LeRobot policy type (`physvla_metaworld_scripted`)."""

from .configuration_physvla_metaworld_scripted import PhysVLAMetaworldScriptedConfig

__all__ = ["PhysVLAMetaworldScriptedConfig"]
