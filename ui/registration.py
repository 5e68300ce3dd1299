"""Small helper so every bpy module registers the same way: a ``classes`` tuple, in order."""
import bpy


def register_classes(classes):
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister_classes(classes):
    for cls in reversed(classes):
        # A failed earlier register() must not make unregister() raise as well.
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
