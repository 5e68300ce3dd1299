"""The command line's subcommands (cli.py): `maps`, `track` and `probe` run the engine without
Blender; `bake`, `render`, `demo` (and the demo's AR stage) are bpy scripts run in headless
Blender inside this process. headless.py is the one place that starts Blender (the tests'
fixtures use it too). Importing these modules does not import bpy; running them does."""
