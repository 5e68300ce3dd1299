"""Blender's face of PlateLight: properties, preferences, panels and class registration."""
