"""Read and write a material's Principled BSDF node as PrincipledValues (bpy glue)."""
from __future__ import annotations

import dataclasses

from .. import compat
from ..addon.errors import PlateLightError
from ..addon.material.principled import PrincipledValues, nonfinite_fields

# PrincipledValues field -> Principled BSDF input socket (Blender 4.x / 5.0 names).
SOCKETS = {
    "base_color": "Base Color", "metallic": "Metallic", "roughness": "Roughness", "ior": "IOR",
    "specular_ior_level": "Specular IOR Level", "transmission": "Transmission Weight",
    "alpha": "Alpha", "anisotropic": "Anisotropic",
    "anisotropic_rotation": "Anisotropic Rotation", "emission_color": "Emission Color",
    "emission_strength": "Emission Strength",
}


def principled_node(material):
    if material is None or material.node_tree is None:
        return None
    return next((n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"),
                None)


def read_principled(material) -> PrincipledValues | None:
    """The socket values of the material's Principled BSDF (None without one); a material
    without nodes gives its viewport colour, metallic and roughness."""
    node = principled_node(material)
    if node is None:
        if material is None:
            return None
        return PrincipledValues(base_color=tuple(material.diffuse_color[:3]),
                                metallic=material.metallic, roughness=material.roughness)
    values = {}
    for field, socket in SOCKETS.items():
        if socket in node.inputs:
            value = node.inputs[socket].default_value
            values[field] = tuple(value[:3]) if field.endswith("color") else float(value)
    return PrincipledValues(**values)


def linked_inputs(material, node=None) -> list[str]:
    """The inputs of the material's Principled BSDF (or of ``node``) that links drive (a texture,
    a normal map): the conversion carries them into the SBRDF (sbrdf_material.carry_links)."""
    node = node or principled_node(material)
    if node is None:
        return []
    return [name for name in (*SOCKETS.values(), "Normal")
            if name in node.inputs and node.inputs[name].is_linked]


def checked_principled(material) -> PrincipledValues | None:
    """read_principled(), refused with one sentence where a value is NaN: converting it would put
    NaN into the SBRDF and every pixel it shades."""
    values = read_principled(material)
    bad = nonfinite_fields(values) if values is not None else []
    if bad:
        where = f"{material.name}'s Principled BSDF" if principled_node(material) else material.name
        raise PlateLightError(f"{where} has {', '.join(SOCKETS[field] for field in bad)} set to "
                              "NaN; give it a number and convert again.")
    return values


def build_principled_material(name: str, values: PrincipledValues):
    import bpy

    material = compat.new_material(name)
    node = principled_node(material)
    for field, value in dataclasses.asdict(values).items():
        socket = SOCKETS[field]
        if socket in node.inputs:
            node.inputs[socket].default_value = (*value, 1.0) if field.endswith("color") else value
    return material
