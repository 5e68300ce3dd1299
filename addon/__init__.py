"""PlateLight's engine: everything here imports and runs without Blender (numpy, OpenEXR, OpenCV),
and imports nothing from the layers above it (tests/test_layers.py checks both).

Blender's side lives beside it: ``ui/`` (properties, panels, preferences, registration),
``operators/`` (one per user action), ``node_groups/`` (node builders) and ``drivers/`` (bpy
scripts run in headless Blender); ``cli.py`` is the command line over engine and drivers.
"""
