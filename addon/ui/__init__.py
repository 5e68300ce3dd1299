"""Blender-side face of PlateLight: properties, preferences and panels (imports bpy)."""
