"""Material operators: apply the PlateLight SBRDF (bound to the object's probe), presets,
Principled <-> SBRDF conversion, JSON export/import, refreshing the maps after a bake."""
from __future__ import annotations

import os

import bpy
from bl_operators.presets import AddPresetBase
from bpy.props import EnumProperty, StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper

from ..addon import names
from ..addon.errors import PlateLightError
from ..addon.material.params import PARAMETERS
from ..addon.material.presets import PRESET_SUBDIR, preset_label, preset_names, preset_params
from ..node_groups import sbrdf_material as sm
from ..node_groups.principled_nodes import linked_inputs
from .common import report_error

BUILTIN_PRESETS = os.path.join(os.path.dirname(os.path.dirname(__file__)), "presets", PRESET_SUBDIR)
_PRESET_ITEMS = [("NONE", "Keep Settings", "Keep the current (or converted) material settings")] + [
    (name, preset_label(name), f"The {preset_label(name).lower()} preset") for name in preset_names()]


def _can_hold_materials(obj) -> bool:
    return obj is not None and obj.type in {"MESH", "CURVE", "SURFACE", "META", "FONT"}


def _maps_not_baked(obj, folder):
    """Maps the object's materials now read that its probe folder lacks ([] when all there)."""
    from ..node_groups.probe_maps import missing_maps
    from .bake.inputs import maps_for

    if not obj.platelight.probe_dir or folder != obj.platelight.probe_dir:
        return []                      # no own bake yet: the status line already says so
    return missing_maps(folder, maps_for(obj))


def _active_sbrdf_material(context):
    material = getattr(context, "material", None) or (
        context.object.active_material if context.object else None)
    return material if sm.sbrdf_node(material) is not None else None



class _OnActiveSBRDFMaterial:
    """Mixin: the operator needs the active material to be a PlateLight SBRDF material."""

    @classmethod
    def poll(cls, context):
        if _active_sbrdf_material(context) is None:
            cls.poll_message_set("The active material is not a PlateLight SBRDF material")
            return False
        return True


class PLATELIGHT_OT_apply_sbrdf(bpy.types.Operator):
    """Give the active object a PlateLight SBRDF material bound to its probe maps"""
    bl_idname = "platelight.apply_sbrdf"
    bl_label = "Apply PlateLight SBRDF"
    bl_options = {"REGISTER", "UNDO"}

    preset: EnumProperty(name="Preset", items=_PRESET_ITEMS, default="NONE")

    @classmethod
    def poll(cls, context):
        if not _can_hold_materials(context.object):
            cls.poll_message_set("Select a mesh, curve or text object")
            return False
        return True

    def execute(self, context):
        obj = context.object
        # read before the conversion: the slots then hold the new materials
        driven = {} if self.preset != "NONE" else {
            slot.material.name: linked_inputs(slot.material) for slot in obj.material_slots
            if slot.material is not None and sm.sbrdf_node(slot.material) is None}
        try:
            material = sm.apply_sbrdf_material(
                obj, None if self.preset == "NONE" else self.preset, scene=context.scene)
        except PlateLightError as err:
            report_error(self, err)
            return {"CANCELLED"}
        folder, status = sm.resolve_probe_dir(obj, context.scene)
        # maps not baked yet is the README's next step (Bake Probes), not something gone wrong
        self.report({"INFO"}, f"{material.name}: {status}")
        for name, inputs in driven.items():
            if inputs:
                self.report({"INFO"}, f"{name}'s {', '.join(inputs)} came from links (textures, "
                            "node chains): carried into the SBRDF through the Principled "
                            "conversion; the material editor shows them as from a texture")
        absent = _maps_not_baked(obj, folder)
        if absent:
            self.report({"WARNING"}, f"{material.name} reads the {', '.join(absent)} map(s), which "
                        "the last bake did not write (it baked only what the old material read): "
                        "bake the probes again")
        return {"FINISHED"}


class PLATELIGHT_OT_sbrdf_preset(_OnActiveSBRDFMaterial, bpy.types.Operator):
    """Set the active PlateLight SBRDF material to a built-in preset"""
    bl_idname = "platelight.sbrdf_preset"
    bl_label = "Apply SBRDF Preset"
    bl_options = {"REGISTER", "UNDO"}

    preset: EnumProperty(name="Preset", items=_PRESET_ITEMS[1:])

    def execute(self, context):
        material = _active_sbrdf_material(context)
        sm.write_params(material, preset_params(self.preset))
        self.report({"INFO"}, f"{material.name}: preset {preset_label(self.preset)}")
        return {"FINISHED"}


class PLATELIGHT_MT_sbrdf_presets(bpy.types.Menu):
    bl_label = "SBRDF Presets"
    preset_subdir = PRESET_SUBDIR
    preset_operator = "script.execute_preset"

    def draw(self, context):
        # Built-in presets ship with the extension; user presets live in the usual folder.
        paths = [BUILTIN_PRESETS] + bpy.utils.preset_paths(PRESET_SUBDIR)
        self.path_menu(paths, self.preset_operator, props_default={"menu_idname": self.bl_idname},
                       filter_ext=lambda ext: ext.lower() == ".py")


class PLATELIGHT_OT_sbrdf_preset_add(_OnActiveSBRDFMaterial, AddPresetBase, bpy.types.Operator):
    """Save the active SBRDF material's parameters as a preset (or remove one)"""
    bl_idname = "platelight.sbrdf_preset_add"
    bl_label = "Add SBRDF Preset"
    preset_menu = "PLATELIGHT_MT_sbrdf_presets"
    preset_subdir = PRESET_SUBDIR
    preset_defines = [f"node = bpy.context.material.node_tree.nodes[{names.SBRDF_GROUP!r}]"]
    preset_values = [f"node.inputs[{spec.label!r}].default_value" for spec in PARAMETERS]


class PLATELIGHT_OT_sbrdf_to_principled(bpy.types.Operator):
    """Replace the active SBRDF material by the closest Principled BSDF material (the SBRDF
    material is kept in the file)"""
    bl_idname = "platelight.sbrdf_to_principled"
    bl_label = "Convert to Principled BSDF"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if context.object is None or _active_sbrdf_material(context) is None:
            cls.poll_message_set("The active object's material is not a PlateLight SBRDF material")
            return False
        return True

    def execute(self, context):
        from ..addon.material.principled import sbrdf_to_principled
        from ..node_groups.principled_nodes import build_principled_material

        obj = context.object
        material = obj.active_material
        name = material.get("platelight_source_material") or f"{material.name} Principled"
        new = build_principled_material(name, sbrdf_to_principled(sm.read_params(material)))
        material.use_fake_user = True
        obj.material_slots[obj.active_material_index].material = new
        self.report({"INFO"}, f"{material.name} converted to {new.name} (Principled BSDF)")
        return {"FINISHED"}


class PLATELIGHT_OT_sbrdf_export(_OnActiveSBRDFMaterial, bpy.types.Operator, ExportHelper):
    """Write the active SBRDF material's parameters to a JSON file"""
    bl_idname = "platelight.sbrdf_export"
    bl_label = "Export SBRDF Material"
    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})

    def execute(self, context):
        from ..addon.material.json_io import save_params

        material = _active_sbrdf_material(context)
        try:
            save_params(self.filepath, sm.read_params(material), material.name)
        except PlateLightError as err:
            report_error(self, err)
            return {"CANCELLED"}
        self.report({"INFO"}, f"Wrote {self.filepath}")
        return {"FINISHED"}


class PLATELIGHT_OT_sbrdf_import(_OnActiveSBRDFMaterial, bpy.types.Operator, ImportHelper):
    """Read SBRDF parameters from a JSON file into the active SBRDF material"""
    bl_idname = "platelight.sbrdf_import"
    bl_label = "Import SBRDF Material"
    bl_options = {"REGISTER", "UNDO"}
    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})

    def execute(self, context):
        from ..addon.material.json_io import load_params

        material = _active_sbrdf_material(context)
        try:
            params, _name = load_params(self.filepath)   # validated before anything changes
        except PlateLightError as err:
            report_error(self, err)
            return {"CANCELLED"}
        sm.write_params(material, params)
        self.report({"INFO"}, f"{material.name}: parameters from {os.path.basename(self.filepath)}")
        return {"FINISHED"}


class PLATELIGHT_OT_refresh_sbrdf_maps(bpy.types.Operator):
    """Reload every PlateLight probe's maps (after a bake, or a switch to an image sequence)"""
    bl_idname = "platelight.refresh_sbrdf_maps"
    bl_label = "Refresh Probe Maps"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        count = sm.refresh_probe_maps()
        self.report({"INFO"}, f"Reloaded the maps of {count} probe(s)")
        return {"FINISHED"}


classes = (
    PLATELIGHT_OT_apply_sbrdf,
    PLATELIGHT_OT_sbrdf_preset,
    PLATELIGHT_MT_sbrdf_presets,
    PLATELIGHT_OT_sbrdf_preset_add,
    PLATELIGHT_OT_sbrdf_to_principled,
    PLATELIGHT_OT_sbrdf_export,
    PLATELIGHT_OT_sbrdf_import,
    PLATELIGHT_OT_refresh_sbrdf_maps,
)
