"""Capture: marker/board tracking, HDR bracket merging and mirror-ball unwrapping (bpy-free)."""
