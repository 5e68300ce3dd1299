"""bpy scripts run in headless Blender inside this process: the `bake`, `render` and `demo`
commands and the demo's AR stage. headless.py is the one place that starts Blender (the tests'
fixtures use it too). Importing these modules does not import bpy; running them does."""
