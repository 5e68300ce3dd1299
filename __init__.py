"""PlateLight: CG objects lit by, reflecting and shadowing real camera footage (a Blender extension).

This file must import without Blender (the engine in ``addon/`` is used from the command line,
``python -m platelight``); everything that needs ``bpy`` is imported inside ``register()``.
"""

# Registration order matters: property groups before the panels and operators that use them.
_BPY_MODULES = (
    "ui.properties",
    "ui.preferences",
    "operators",
    "ui.material_panel",
    "ui.panels",
    "ui.composite_panel",
)


def _modules():
    import importlib

    return [importlib.import_module(f"{__package__}.{name}") for name in _BPY_MODULES]


def register():
    for module in _modules():
        module.register()


def unregister():
    for module in reversed(_modules()):
        module.unregister()
