"""The plate's colour space (bpy): the one its file declares, or the one the user names; the
names come from the running Blender's OCIO config, never from a fixed list (they differ
between releases: Blender 5.2 knows ARRI LogC4, S-Log3, V-Log... that 4.5 does not)."""
import bpy

from ..addon.compositing.plate_encoding import file_encoding


def colour_space_names():
    """Every input colour space the running Blender knows."""
    prop = bpy.types.ColorManagedInputColorspaceSettings.bl_rna.properties["name"]
    return [item.identifier for item in prop.enum_items]


def search_colour_spaces(_self, _context, edit_text):
    """StringProperty search callback: the colour spaces containing what was typed."""
    text = edit_text.lower()
    return [name for name in colour_space_names() if text in name.lower()]


def check_colour_space(name):
    """An error sentence for an unknown colour space name, else None."""
    if not name or name in colour_space_names():
        return None
    known = colour_space_names()
    close = [n for n in known if name.lower() in n.lower() or n.lower() in name.lower()]
    hint = f" (did you mean {', '.join(repr(n) for n in close[:3])}?)" if close else ""
    return (f"Blender's colour management has no colour space '{name}'{hint}; pick one from the "
            f"Colour Space field's list, e.g. sRGB, Linear Rec.709 or ACEScg.")


def apply_plate_colour_space(image, path, requested=""):
    """Tag ``image`` with ``requested`` or with what the file at ``path`` declares; returns the
    reason shown to the user."""
    if requested:
        image.colorspace_settings.name = requested
        return "set by you"
    encoding = file_encoding(path)
    if encoding.colorspace and encoding.colorspace in colour_space_names():
        image.colorspace_settings.name = encoding.colorspace
    return encoding.reason
