"""The Principled twin of an SBRDF material: what the CG is for every ray but the camera's.

The SBRDF shades with an Emission closure from one probe at the object's centre. Seen by the
camera that is the paper's noise-free look, but for the rays of the shadow/bleeding layers (a
phantom floor's diffuse bounce hitting the underside of a resting ball) it made the ball glow with
the light its centre probe sees, and that glow filled in its own contact shadow (floor within
0.2 m of contact at 0.62 of the plate against the truth's 0.50, issue 11). A real surface there
reflects the dark floor it faces; the Principled twin does exactly that when path-traced.

So the material's output is  Mix(twin, probe emission, max(Is Camera Ray x Camera Sees SBRDF,
Emission For All Rays)).  ``Emission For All Rays`` = 1 is the paper's model (the emission lights
everything) and stays selectable; 0, the default, gives the twin to every non-camera ray. Both
engines evaluate Light Path's Is Camera Ray (EEVEE: 1 when rasterising the view, 0 in its
light-probe captures). ``Camera Sees SBRDF`` = 0 gives the camera the twin too: the object is
path-traced as the Principled material it came from (setup_composite does that for metals in
Cycles, where it measured more accurate at equal time; docs/decisions.md). Cycles folds the
constant 0 through the Math and Mix nodes, so the SBRDF's nodes are then not evaluated at all.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..addon import names
from ..addon.material.principled import PrincipledValues, principled_to_sbrdf, sbrdf_to_principled
from .principled_nodes import SOCKETS, read_principled

TWIN_NODE = names.TWIN_NODE
SPLIT_NODE = names.RAY_SPLIT_NODE            # max(Is Camera Ray x Camera Sees SBRDF, Emission For All Rays)
CAMERA_NODE = names.RAY_CAMERA_NODE          # Is Camera Ray x Camera Sees SBRDF
MIX_NODE = names.RAY_MIX_NODE
LIGHT_PATH_NODE = names.LIGHT_PATH_NODE
SOURCE_KEY = "platelight_source_material"     # set by apply_sbrdf on a converted material


def twin_values(material, params) -> PrincipledValues:
    """The Principled values the twin gets: the material it was converted from when that still
    exists (exact: the Principled look the user had), else the SBRDF parameters converted back."""
    import bpy

    source = bpy.data.materials.get(material.get(SOURCE_KEY, "")) if SOURCE_KEY in material else None
    values = read_principled(source) if source is not None else None
    if values is None or not _same(principled_to_sbrdf(values), params):   # edited since
        values = sbrdf_to_principled(params)
    # the emission is seen by the camera through the SBRDF; the twin must not emit it again
    return dataclasses.replace(values, emission_strength=0.0)


def _same(a, b) -> bool:
    a, b = dataclasses.asdict(a.clamped()), dataclasses.asdict(b.clamped())
    return all(np.allclose(a[k], b[k], atol=1e-4) for k in a)


def _node(tree, name, idname, location):
    node = tree.nodes.get(name)
    if node is None or node.bl_idname != idname:
        if node is not None:
            tree.nodes.remove(node)
        node = tree.nodes.new(idname)
        node.name = node.label = name
    node.location = location
    return node


def wire_twin(material, emission_socket, params, emission_for_all_rays=None):
    """Route ``emission_socket`` (the probe group's Shader) to the camera and the Principled twin
    to all other rays; idempotent. ``emission_for_all_rays``: None keeps the material's choice."""
    tree = material.node_tree
    out = material_output(tree)
    x, y = out.location
    twin = _node(tree, TWIN_NODE, "ShaderNodeBsdfPrincipled", (x - 300, y - 300))
    update_twin(material, params, twin)
    path = _node(tree, LIGHT_PATH_NODE, "ShaderNodeLightPath", (x - 500, y + 300))
    fresh = tree.nodes.get(SPLIT_NODE) is None
    split = _node(tree, SPLIT_NODE, "ShaderNodeMath", (x - 300, y + 250))
    split.operation = "MAXIMUM"
    if fresh and emission_for_all_rays is None:
        emission_for_all_rays = False           # the default: the twin for non-camera rays
    if emission_for_all_rays is not None:
        split.inputs[1].default_value = 1.0 if emission_for_all_rays else 0.0
    _emission_sampling(material)
    mix = _node(tree, MIX_NODE, "ShaderNodeMixShader", (x - 120, y))
    _camera_switch(tree, path, split)
    tree.links.new(split.outputs[0], mix.inputs["Fac"])
    tree.links.new(twin.outputs["BSDF"], mix.inputs[1])
    tree.links.new(emission_socket, mix.inputs[2])
    tree.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    return mix


def _camera_switch(tree, path, split):
    """The Camera Sees SBRDF factor between Is Camera Ray and the split (1, the SBRDF, where it is
    new: materials from before it keep their look); returns the node."""
    fresh = tree.nodes.get(CAMERA_NODE) is None
    x, y = split.location
    camera = _node(tree, CAMERA_NODE, "ShaderNodeMath", (x - 180, y + 150))
    camera.operation = "MULTIPLY"
    if fresh:
        camera.inputs[1].default_value = 1.0
    tree.links.new(path.outputs["Is Camera Ray"], camera.inputs[0])
    tree.links.new(camera.outputs[0], split.inputs[0])
    return camera


def camera_sees_sbrdf(material) -> bool:
    """Does the camera see the material's SBRDF (else its Principled twin, path-traced)?"""
    tree = material.node_tree if material is not None else None
    camera = tree.nodes.get(CAMERA_NODE) if tree is not None else None
    return camera is None or camera.inputs[1].default_value >= 0.5


def has_ray_split(material) -> bool:
    """Was the material wired by wire_twin (its Light Path and ray split there)?"""
    return material.node_tree is not None and SPLIT_NODE in material.node_tree.nodes \
        and LIGHT_PATH_NODE in material.node_tree.nodes


def set_camera_sees_sbrdf(material, value: bool) -> None:
    """Give the camera the SBRDF (True) or the Principled twin (False)."""
    if not has_ray_split(material):
        raise ValueError(f"{material.name} has no PlateLight ray split (not an SBRDF material)")
    nodes = material.node_tree.nodes
    camera = _camera_switch(material.node_tree, nodes[LIGHT_PATH_NODE], nodes[SPLIT_NODE])
    camera.inputs[1].default_value = 1.0 if value else 0.0


def material_output(tree):
    """The Material Output the renderers use (the active one where a tree holds several)."""
    outputs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    return next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)


def update_twin(material, params, twin=None):
    """Copy the twin's values from the SBRDF parameters (or the source Principled material)."""
    twin = twin or material.node_tree.nodes.get(TWIN_NODE)
    if twin is None:
        return
    for field, value in dataclasses.asdict(twin_values(material, params)).items():
        socket = SOCKETS[field]
        if socket in twin.inputs:
            twin.inputs[socket].default_value = (*value, 1.0) if field.endswith("color") else value


def emission_for_all_rays(material) -> bool:
    """True when the material lights the scene with its emission (the paper's model)."""
    split = material.node_tree.nodes.get(SPLIT_NODE) if material and material.node_tree else None
    return split is None or split.inputs[1].default_value >= 0.5


def set_emission_for_all_rays(material, value: bool) -> None:
    split = material.node_tree.nodes.get(SPLIT_NODE)
    if split is None:
        raise ValueError(f"{material.name} has no PlateLight ray split (not an SBRDF material)")
    split.inputs[1].default_value = 1.0 if value else 0.0
    _emission_sampling(material)


def _emission_sampling(material) -> None:
    """Cycles light-samples emissive meshes, and evaluates their emission then with the path
    state of the point being lit: a floor pixel seen by the camera reads Is Camera Ray = 1 and
    gets the probe emission through next-event estimation. Measured on a resting diffuse sphere:
    the floor in front of the contact darkened 0.79 instead of the truth's 0.89 with the twin on
    and light sampling left on. So with the twin the emission is never light-sampled (BSDF rays
    still see the twin); the paper's model keeps Cycles' automatic choice."""
    settings = getattr(material, "cycles", None)
    if settings is not None and hasattr(settings, "emission_sampling"):
        settings.emission_sampling = "AUTO" if emission_for_all_rays(material) else "NONE"
