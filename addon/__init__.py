"""PlateLight's engine: everything here imports and runs without Blender (numpy, OpenEXR, OpenCV).

Blender glue lives in ``addon/ui`` (properties, panels, preferences), ``operators/`` and
``node_groups/``; those are the only places that import ``bpy``.
"""
