"""Materials that use the PlateLight SBRDF: build, bind to a probe, read and write parameters.

A PlateLight material holds three nodes: the shared "PlateLight SBRDF" group (the parameters, as
its socket values), the probe's "PlateLight Probe <name>" group (the maps) and the Material
Output. ``apply_sbrdf_material(obj, preset)`` is the one call scripts need."""
from __future__ import annotations

import dataclasses
import os

import bpy

from .. import compat
from ..addon import names
from ..addon.bake.layout import DEFAULT_MAPS_DIR, WORLD_FOLDER, object_maps_dir
from ..addon.errors import PlateLightError
from ..addon.material.params import PARAMETERS, SPEC, SBRDFParams
from ..addon.material.principled import CHANGES, principled_to_sbrdf
from ..addon.material.presets import preset_params
from . import probe_maps, ray_twin
from .principled_conversion import ensure_conversion_group
from .principled_nodes import SOCKETS, checked_principled, linked_inputs, principled_node, read_principled
from .sbrdf import LOOKUP_SOCKETS, ensure_sbrdf_group

WORLD_SUBDIR = WORLD_FOLDER          # the bake writes the world's maps there


def sbrdf_node(material):
    """The material's PlateLight SBRDF group node, or None."""
    if material is None or material.node_tree is None:
        return None
    node = material.node_tree.nodes.get(names.SBRDF_GROUP)
    if node is not None and getattr(node, "node_tree", None) is not None \
            and node.node_tree.name == names.SBRDF_GROUP:
        return node
    for node in material.node_tree.nodes:
        if node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None \
                and node.node_tree.name == names.SBRDF_GROUP:
            return node
    return None


def shaded_by_sbrdf(ob) -> bool:
    """Does every material slot of ``ob`` hold a PlateLight SBRDF material that the camera sees
    (not its path-traced twin)? Camera rays then see only probe look-ups, so its pixels are
    noise-free up to their anti-aliasing."""
    slots = [slot.material for slot in getattr(ob, "material_slots", ())]
    return bool(slots) and all(sbrdf_node(material) is not None and ray_twin.camera_sees_sbrdf(material)
                               for material in slots)


def is_metal(material) -> bool:
    """Is the SBRDF material a metal (its Principled twin's Metallic at least a half)?"""
    return ray_twin.twin_values(material, read_params(material)).metallic >= 0.5


def probe_node(material):
    if material is None or material.node_tree is None:
        return None
    return material.node_tree.nodes.get(names.PROBE_NODE)


def probe_groups(objects) -> set:
    """The probe groups that the SBRDF materials of ``objects`` read their maps from."""
    groups = set()
    for ob in objects:
        for slot in getattr(ob, "material_slots", ()):
            node = probe_node(slot.material)
            if node is not None and node.node_tree is not None:
                groups.add(node.node_tree)
    return groups


def read_params(material) -> SBRDFParams:
    node = sbrdf_node(material)
    values = {}
    for spec in PARAMETERS:
        value = node.inputs[spec.label].default_value
        values[spec.name] = tuple(value[:3]) if spec.kind == "color" else float(value)
    return SBRDFParams(**values)


def write_params(material, params: SBRDFParams) -> None:
    node = sbrdf_node(material)
    params = params.clamped()
    for spec in PARAMETERS:
        value = getattr(params, spec.name)
        node.inputs[spec.label].default_value = (*value, 1.0) if spec.kind == "color" else value
    ray_twin.update_twin(material, params)


def world_maps_dir(scene) -> str:
    """Where the world probe's maps live: <scene maps folder>/_world (fallback for objects
    whose own maps are missing)."""
    return os.path.join(scene.platelight.maps_dir or DEFAULT_MAPS_DIR, WORLD_SUBDIR)


def resolve_probe_dir(obj, scene) -> tuple[str, str]:
    """(folder to bind, status sentence) for ``obj``: its own maps (the recorded folder, else
    the one a bake writes to, which a farm bake fills without saving the .blend), else the
    world's."""
    own = obj.platelight.probe_dir or object_maps_dir(scene.platelight.maps_dir, obj.name)
    kind, _ = probe_maps.probe_maps_status(own)
    if kind != "missing":
        return own, f"Probe maps: {kind} in {own}"
    world = world_maps_dir(scene)
    world_kind, _ = probe_maps.probe_maps_status(world)
    if world_kind != "missing":
        return world, f"Maps missing in '{own or '(no folder)'}': using the world maps"
    return world, f"Maps missing in '{own or '(no folder)'}' and no world maps: renders black until Bake Probes"


def build_material(name: str, probe_dir: str, params: SBRDFParams, label: str | None = None,
                   source=None):
    """A new material shading with the SBRDF bound to the maps in ``probe_dir``.

    ``source``: the Principled material it converts. Where links (textures, node chains) drive
    its Principled inputs, the new material is a copy of it, so those chains come along: they
    feed the SBRDF through the conversion group, and the Principled BSDF itself, textures and
    all, becomes the twin the other rays meet (ray_twin.py)."""
    carried = source is not None and bool(linked_inputs(source))
    material = source.copy() if carried else compat.new_material(name)
    material.name = name
    material.use_fake_user = False
    tree = material.node_tree
    if carried:
        twin = principled_node(material)
        twin.name = twin.label = names.TWIN_NODE
        out = ray_twin.material_output(tree) or tree.nodes.new("ShaderNodeOutputMaterial")
        x, y = out.location
    else:
        tree.nodes.clear()
        out = tree.nodes.new("ShaderNodeOutputMaterial")
        x, y = out.location = (300, 0)
    group = tree.nodes.new("ShaderNodeGroup")
    group.node_tree = ensure_sbrdf_group()
    group.name = group.label = names.SBRDF_GROUP
    group.location = (x - 700, y + 400 if carried else y)
    group.width = 240
    material["platelight_sbrdf"] = 1
    bind_probe(material, probe_dir, label)
    write_params(material, params)
    if carried:
        carry_links(material, twin, read_principled(source))
    return material


def carry_links(material, twin, values) -> None:
    """Feed the SBRDF from the links that drive the twin's inputs: each through the conversion
    group (``values``, the Principled values, for its other inputs) into exactly the parameters
    that input changes (principled.CHANGES), the Normal straight in."""
    tree = material.node_tree
    sbrdf = sbrdf_node(material)
    carried = linked_inputs(material, twin)
    if "Normal" in carried:
        tree.links.new(twin.inputs["Normal"].links[0].from_socket, sbrdf.inputs["Normal"])
    driven = [field for field, socket in SOCKETS.items() if socket in carried]
    if not driven:
        return
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = ensure_conversion_group()
    node.name = node.label = names.PRINCIPLED_CONVERSION
    node.location = (sbrdf.location[0] - 300, sbrdf.location[1])
    for field, socket in SOCKETS.items():
        value = getattr(values, field)
        node.inputs[socket].default_value = (*value, 1.0) if field.endswith("color") else value
        if field in driven:
            tree.links.new(twin.inputs[socket].links[0].from_socket, node.inputs[socket])
    for name in {name for field in driven for name in CHANGES[field]}:
        tree.links.new(node.outputs[SPEC[name].label], sbrdf.inputs[SPEC[name].label])
    # the camera sees the emission through the SBRDF; the twin must not light the scene again
    for link in list(twin.inputs[SOCKETS["emission_strength"]].links):
        tree.links.remove(link)


def bind_probe(material, probe_dir: str, label: str | None = None):
    """Wire the material's SBRDF to the probe group of ``probe_dir`` (creating it if needed)."""
    tree = material.node_tree
    node = probe_node(material)
    if node is None:
        node = tree.nodes.new("ShaderNodeGroup")
        node.name = node.label = names.PROBE_NODE
        node.location = (0, 0)
    node.node_tree = probe_maps.ensure_probe_group(probe_dir, label)
    # a .blend from an older PlateLight: its SBRDF group lacks the outputs a new probe group reads
    ensure_sbrdf_group()
    source = sbrdf_node(material)
    for name, _ in LOOKUP_SOCKETS:
        tree.links.new(source.outputs[name], node.inputs[name])
    # the camera sees the probe's emission, every other ray the Principled twin (ray_twin.py)
    ray_twin.wire_twin(material, node.outputs["Shader"], read_params(material))
    material["platelight_probe_dir"] = probe_dir
    return node


def check_editable(obj) -> None:
    """PlateLightError unless ``obj``'s material slots can be changed: an object linked from a
    library, or linked mesh data holding the materials, is read-only (Blender would raise
    half-way, leaving a new material and node groups behind)."""
    if obj.library is not None:
        raise PlateLightError(f"{obj.name} is linked from {obj.library.filepath}; make it local "
                              "(Object > Relations > Make Local) before applying the SBRDF.")
    data = obj.data
    if data is not None and data.library is not None and (
            not obj.material_slots or any(slot.link == "DATA" for slot in obj.material_slots)):
        raise PlateLightError(f"The materials of {obj.name} live in its data {data.name}, linked "
                              f"from {data.library.filepath}; make the data local first.")


def apply_sbrdf_material(obj, preset_name: str | None = None, params: SBRDFParams | None = None,
                         scene=None):
    """Give ``obj`` PlateLight SBRDF materials bound to its probe; returns the active one.

    Existing SBRDF materials are rebound (and get the preset if given); other materials are
    converted (Principled settings mapped where they can be) into new materials, the originals
    kept with a fake user so nothing is lost; links driving their Principled inputs (textures)
    are carried into the SBRDF (build_material)."""
    scene = scene or bpy.context.scene
    check_editable(obj)                     # before anything is created
    folder, _status = resolve_probe_dir(obj, scene)
    if preset_name is not None:
        params = preset_params(preset_name)
    # every slot read before anything changes: a refused one leaves the object as it was
    sources = {} if params is not None else {
        index: checked_principled(slot.material) for index, slot in enumerate(obj.material_slots)
        if sbrdf_node(slot.material) is None}
    if not obj.material_slots:
        obj.data.materials.append(None)
    result = None
    for index, slot in enumerate(obj.material_slots):
        material = slot.material
        if sbrdf_node(material) is None:
            base = params
            if base is None:
                principled = sources.get(index)
                base = principled_to_sbrdf(principled) if principled else SBRDFParams()
            name = f"{material.name} SBRDF" if material else f"{obj.name} SBRDF"
            new = build_material(name, folder, base, label=obj.name,
                                 source=material if params is None else None)
            if material is not None:
                material.use_fake_user = True
                new["platelight_source_material"] = material.name
                ray_twin.update_twin(new, read_params(new))   # the twin is the source's look
            slot.material = new
            material = new
        else:
            bind_probe(material, folder, label=obj.name)
            if params is not None:
                write_params(material, params)
        if index == obj.active_material_index:
            result = material
    return result or obj.material_slots[0].material


def follow_probe(obj, scene=None, reload=True) -> int:
    """Rebind ``obj``'s SBRDF materials to its probe folder after a bake wrote or pointed it
    there (reloading the maps when ``reload``); returns how many materials were rebound.
    Without this a material applied before the bake keeps showing the old (or world) maps."""
    scene = scene or bpy.context.scene
    folder, _status = resolve_probe_dir(obj, scene)
    count = 0
    for slot in obj.material_slots:
        material = slot.material
        if sbrdf_node(material) is None or probe_node(material) is None:
            continue                       # only materials already bound to a probe follow it
        if not reload and material.get("platelight_probe_dir") == folder:
            continue                       # a cache hit on a material already bound there
        bind_probe(material, folder, label=obj.name)
        count += 1
    return count


def refresh_probe_maps(scene=None):
    """Rebind every SBRDF material of the scene's objects to the folder its maps are in now
    (a render node opening a .blend whose maps were baked elsewhere), then reload every probe
    group's maps; returns how many probe groups were refreshed."""
    scene = scene or bpy.context.scene
    for obj in scene.objects:
        follow_probe(obj, scene, reload=False)
    count = 0
    for tree in list(bpy.data.node_groups):           # a rebuild replaces the group
        if tree.bl_idname == "ShaderNodeTree" and probe_maps.FOLDER_KEY in tree:
            probe_maps.bind_images(tree)
            count += 1
    return count


def params_dict(params: SBRDFParams) -> dict:
    return dataclasses.asdict(params)
