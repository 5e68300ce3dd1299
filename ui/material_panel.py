"""Properties > Material > PlateLight SBRDF: the paper's parameters, presets, probe status,
conversion and JSON export/import. The values live on the material's "PlateLight SBRDF" node,
so the panel, the node editor and scripts all edit the same thing."""
import os

import bpy

from ..node_groups import sbrdf_material as sm
from ..node_groups.probe_maps import probe_maps_status
from .registration import register_classes, unregister_classes

SECTIONS = (
    ("Albedo", ("Diffuse Albedo", "Specular Albedo")),
    ("Lobe", ("Glossiness", "Anisotropy", "Cx", "Cy", "Cz", "Tangent Rotation", "Retro-Reflection")),
    ("Fresnel", ("Fresnel Falloff", "Fresnel Peak", "Paper Falloff")),
    ("Transparency", ("Alpha", "IOR", "Dispersion")),
    ("Emission", ("Emission Color", "Emission Strength")),
)


class PLATELIGHT_PT_material(bpy.types.Panel):
    bl_label = "PlateLight SBRDF"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return context.object is not None

    def draw(self, context):
        layout = self.layout
        material = context.material
        node = sm.sbrdf_node(material)
        if node is None:
            layout.label(text="Not a PlateLight SBRDF material", icon="INFO")
            layout.operator("platelight.apply_sbrdf", icon="MATERIAL")
            return

        row = layout.row(align=True)
        row.menu("PLATELIGHT_MT_sbrdf_presets", text="Presets")
        row.operator("platelight.sbrdf_preset_add", text="", icon="ADD")
        row.operator("platelight.sbrdf_preset_add", text="", icon="REMOVE").remove_active = True

        folder = material.get("platelight_probe_dir", "")
        kind, _first = probe_maps_status(folder)
        own = context.object.platelight.probe_dir
        if kind == "missing":
            layout.label(text=f"Maps missing in {folder or '(no folder)'}: renders black",
                         icon="ERROR")
        elif own and os.path.normpath(bpy.path.abspath(own)) != os.path.normpath(
                bpy.path.abspath(folder)):
            layout.label(text="Object's maps missing: using the world maps", icon="ERROR")
        else:
            layout.label(text=f"Probe maps ({kind}): {folder}", icon="WORLD")
        layout.operator("platelight.apply_sbrdf", text="Rebind to Object's Probe", icon="FILE_REFRESH")

        layout.use_property_split = True
        for title, labels in SECTIONS:
            col = layout.column(heading=title)
            for label in labels:
                socket = node.inputs[label]
                if socket.is_linked:
                    col.label(text=f"{label}: from a texture")
                else:
                    col.prop(socket, "default_value", text=label)

        layout.use_property_split = False
        row = layout.row(align=True)
        row.operator("platelight.sbrdf_export", text="Export JSON", icon="EXPORT")
        row.operator("platelight.sbrdf_import", text="Import JSON", icon="IMPORT")
        layout.operator("platelight.sbrdf_to_principled", icon="NODE_MATERIAL")


class PLATELIGHT_PT_material_preview(bpy.types.Panel):
    bl_label = "Preview"
    bl_parent_id = "PLATELIGHT_PT_material"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "material"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return sm.sbrdf_node(context.material) is not None

    def draw(self, context):
        self.layout.template_preview(context.material)




classes = (PLATELIGHT_PT_material, PLATELIGHT_PT_material_preview)


def register():
    register_classes(classes)


def unregister():
    unregister_classes(classes)
