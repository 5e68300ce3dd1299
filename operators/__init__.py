"""One module per user action. Each module has a ``classes`` tuple and may have
``register_extra()``/``unregister_extra()`` (menu entries). Add new modules to _MODULES."""
import importlib

_MODULES = ("bake", "material", "track", "capture_probe", "composite", "baked_shadows", "plate",
            "lights", "grain", "farm_job", "lens")


def _load():
    return [importlib.import_module(f"{__package__}.{name}") for name in _MODULES]


def register():
    from ..ui.registration import register_classes

    for module in _load():
        register_classes(module.classes)
        if hasattr(module, "register_extra"):
            module.register_extra()


def unregister():
    from ..ui.registration import unregister_classes

    for module in reversed(_load()):
        if hasattr(module, "unregister_extra"):
            module.unregister_extra()
        unregister_classes(module.classes)
