"""What a probe depends on, read from the Blender scene (for the bake, job.py): plain-data
descriptions for the content hash, which objects a probe sees, where a probe sits, which maps a
material reads, and whether the world is just an EXR."""
from __future__ import annotations

import os

import bpy
import numpy as np

from ...addon import names
from ...addon.bake import culling, needs
from ...addon.bake.hashing import content_hash



# --------------------------------------------------------------------------- describing inputs

_SKIP_PROPS = {"rna_type", "name", "label", "location", "width", "height", "dimensions", "select",
               "show_options", "show_preview", "show_texture", "hide", "mute", "parent",
               "use_custom_color", "color", "bl_idname", "bl_label", "bl_description", "bl_icon",
               "bl_static_type", "bl_width_default", "bl_width_min", "bl_width_max",
               "bl_height_default", "bl_height_min", "bl_height_max", "type", "inputs", "outputs",
               "internal_links", "location_absolute", "warning_propagation", "color_tag"}


def _rna_values(struct):
    """Simple-typed RNA property values of a node, light, modifier... (what changes its look)."""
    out = {}
    for prop in struct.bl_rna.properties:
        key = prop.identifier
        if key in _SKIP_PROPS or prop.type in {"POINTER", "COLLECTION"}:
            continue
        try:
            value = getattr(struct, key)
        except AttributeError:
            continue
        if hasattr(value, "__len__") and not isinstance(value, str):
            value = [float(v) if isinstance(v, float) else v for v in value]
        out[key] = value
    return out


def _image_description(image):
    if image is None:
        return None
    path = bpy.path.abspath(image.filepath, library=image.library) if image.filepath else ""
    try:
        stamp = os.stat(path).st_mtime_ns if path else None
    except OSError:
        stamp = None
    return {"name": image.name, "path": path, "mtime": stamp, "packed": bool(image.packed_file),
            "source": image.source, "colorspace": image.colorspace_settings.name}


def describe_tree(tree, seen=None, camera_blind=False):
    """Everything in a node tree that changes its result: nodes' settings, unlinked input values,
    images (with file modification time), links, and nested groups. ``camera_blind``: leave out
    what only camera rays see (the SBRDF/twin switch of names.RAY_CAMERA_NODE), for a render that
    hides the object from its camera."""
    if tree is None:
        return None
    seen = set() if seen is None else seen
    if tree.name in seen:
        return tree.name
    seen.add(tree.name)
    nodes = []
    for node in tree.nodes:
        if camera_blind and node.name == names.RAY_CAMERA_NODE:
            continue
        # what a bake made (the filmed phantoms' shadow ratio): no bake renders it (it is off
        # outside the composite's CG layer), and describing it would make the next bake stale
        if node.name == names.BAKED_RATIO_GROUP:
            continue
        inputs = {}
        for sock in node.inputs:
            if not sock.is_linked and hasattr(sock, "default_value"):
                value = sock.default_value
                inputs[sock.identifier] = list(value) if hasattr(value, "__len__") and not isinstance(value, str) else value
        entry = {"id": node.bl_idname, "name": node.name, "in": inputs, "props": _rna_values(node)}
        if getattr(node, "image", None) is not None:
            entry["image"] = _image_description(node.image)
        if getattr(node, "node_tree", None) is not None:
            entry["group"] = describe_tree(node.node_tree, seen, camera_blind)
        nodes.append(entry)
    links = [(l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier)
             for l in tree.links if not l.is_muted]
    return {"nodes": nodes, "links": sorted(links)}


class Describer:
    """Plain-data descriptions of objects for the content hash, memoised per data block for the
    duration of one bake (a mesh shared by many objects is read once). ``camera_blind``: materials
    described as rays other than the camera's meet them (describe_tree)."""

    def __init__(self, camera_blind=False):
        self.camera_blind = camera_blind
        self._data = {}
        self._materials = {}
        self._digests = {}

    def seen_digest(self, ob, frame):
        """Digest of ``seen_object``, computed once per object and frame however many probes
        see the object (hashing dominates a cache hit otherwise)."""
        key = (ob.name_full, frame)
        if key not in self._digests:
            self._digests[key] = content_hash(self.seen_object(ob, frame))
        return self._digests[key]

    def data(self, ob, frame=None):
        data = ob.data
        if data is None:
            return None
        if (isinstance(data, bpy.types.Mesh) and (len(ob.modifiers) or data.shape_keys is not None)
                or ob.type in {"CURVE", "SURFACE", "FONT", "META"}):
            # Curves, text and metaballs keep their shape in collections the RNA walk skips.
            return self.evaluated_mesh(ob, frame)
        key = (type(data).__name__, data.name_full)
        if key not in self._data:
            desc = {"type": type(data).__name__}
            if isinstance(data, bpy.types.Mesh):
                co = np.empty(len(data.vertices) * 3, dtype=np.float32)
                data.vertices.foreach_get("co", co)
                faces = np.empty(len(data.loops), dtype=np.int32)
                data.loops.foreach_get("vertex_index", faces)
                desc.update(co=co, loops=faces.astype(np.float64), n_polys=len(data.polygons))
            elif isinstance(data, bpy.types.Light):
                desc.update(_rna_values(data))
            else:
                desc.update({k: v for k, v in _rna_values(data).items() if not k.startswith("is_")})
            self._data[key] = desc
        return self._data[key]

    def evaluated_mesh(self, ob, frame):
        """Vertex positions after modifiers and shape keys (armatures, animated modifiers, shape
        key values all end up here), read from the evaluated object of this frame."""
        key = ("evaluated", ob.name_full, frame)
        if key not in self._data:
            evaluated = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
            mesh = evaluated.to_mesh()
            try:
                co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
                mesh.vertices.foreach_get("co", co)
                corners = np.empty(len(mesh.loops), dtype=np.int32)
                mesh.loops.foreach_get("vertex_index", corners)
                self._data[key] = {"type": "EvaluatedMesh", "co": co,
                                   "loops": corners.astype(np.float64), "n_polys": len(mesh.polygons)}
            finally:
                evaluated.to_mesh_clear()
        return self._data[key]

    def material(self, mat):
        if mat is None:
            return None
        if mat.name_full not in self._materials:
            tree = describe_tree(mat.node_tree, camera_blind=self.camera_blind)
            self._materials[mat.name_full] = {"name": mat.name_full, "tree": tree,
                                              "diffuse": list(mat.diffuse_color)}
        return self._materials[mat.name_full]

    def seen_object(self, ob, frame=None):
        """What an object contributes to another object's probe at the current frame."""
        return {
            "name": ob.name_full,
            "matrix": np.array(ob.matrix_world, dtype=np.float64),
            "data": self.data(ob, frame),
            "modifiers": [(m.type, m.show_render, _rna_values(m)) for m in getattr(ob, "modifiers", [])],
            "materials": [self.material(slot.material) for slot in ob.material_slots],
            "visibility": [ob.visible_camera, ob.visible_diffuse, ob.visible_glossy,
                           ob.visible_transmission, ob.visible_shadow],
            "phantom": ob.platelight.phantom,
        }


# --------------------------------------------------------------------------- scene queries

def renderable(ob, view_layer):
    """Objects that change a probe render: what the camera sees, and lights (they light it)."""
    if ob.hide_render or ob.type in {"CAMERA", "EMPTY", "SPEAKER", "LIGHT_PROBE", "ARMATURE", "LATTICE"}:
        return False
    return ob.name in view_layer.objects   # not in an excluded collection


def visible_in_probe(ob):
    """Does the object itself show up in a panorama? Lights are invisible to camera rays unless
    the user turned that on, so a probe that sees only lights and the world shows the world."""
    return ob.type != "LIGHT" or ob.visible_camera


def world_corners(ob) -> np.ndarray:
    """The eight corners of the object's bounding box in world space, (8, 3)."""
    return np.array([ob.matrix_world @ _vec(c) for c in ob.bound_box], dtype=np.float64)


def world_bounds(ob):
    return culling.bounding_sphere(world_corners(ob))


def _vec(c):
    from mathutils import Vector

    return Vector(c)


def probe_origin(ob):
    """The probe's centre: the chosen origin object's location, else the bounding-box centre."""
    origin = ob.platelight.probe_origin
    if origin is not None:
        return np.array(origin.matrix_world.translation, dtype=np.float64)
    centre, _ = world_bounds(ob)
    return centre


def lobes_of_material(mat) -> needs.Lobes:
    """What a material asks of the probe: read from the PlateLight SBRDF group node when there is
    one, from a Principled BSDF otherwise (metallic removes the diffuse map, 1 - roughness is the
    glossiness); anything else needs every map."""
    if mat is None or mat.node_tree is None:
        return needs.Lobes()
    nodes = mat.node_tree.nodes
    for node in nodes:
        tree = getattr(node, "node_tree", None)
        if node.bl_idname == "ShaderNodeGroup" and tree is not None and tree.name.startswith(names.SBRDF_GROUP):
            return needs.Lobes(diffuse=_nonzero(node, "Diffuse Albedo"),
                               specular=_nonzero(node, "Specular Albedo"),
                               glossiness=_scalar(node, "Glossiness"),
                               fresnel=_nonzero(node, "Fresnel Falloff"),
                               # a group from before the Anisotropy input: a round lobe
                               anisotropy=_scalar(node, "Anisotropy") if _socket(node, "Anisotropy") else 0.0)
    for node in nodes:
        if node.bl_idname == "ShaderNodeBsdfPrincipled":
            metallic = _scalar(node, "Metallic")
            roughness = _scalar(node, "Roughness")
            return needs.Lobes(diffuse=metallic is None or metallic < 1.0, specular=True,
                               glossiness=None if roughness is None else 1.0 - roughness, fresnel=True)
    return needs.Lobes()


def _socket(node, name):
    return node.inputs.get(name)


def _scalar(node, name):
    sock = _socket(node, name)
    if sock is None or sock.is_linked or not hasattr(sock, "default_value"):
        return None
    value = sock.default_value
    return float(value) if not hasattr(value, "__len__") else float(max(value[:3]))


def _nonzero(node, name):
    sock = _socket(node, name)
    if sock is None:
        return False
    if sock.is_linked or not hasattr(sock, "default_value"):
        return True
    value = sock.default_value
    values = list(value)[:3] if hasattr(value, "__len__") else [value]
    return any(abs(float(v)) > 0 for v in values)


def maps_for(ob) -> tuple[str, ...]:
    return needs.maps_needed(_lobes(ob))


def wants_sharp_probe(ob) -> bool:
    """Is ``ob``'s reflection sharp enough that its probe is sized to it on screen (needs.py)?"""
    return needs.needs_sharp_specular(_lobes(ob))


def wants_behind_layer(ob, maps, settings, distance_height) -> bool:
    """Does ``ob``'s probe bake the layer behind its first surface (needs.py)?"""
    return needs.wants_behind_layer(_lobes(ob), maps, settings.probe_parallax, settings.probe_behind,
                                    distance_height)


def owner_visibility(ob, owner_shadows: bool) -> str:
    """How ``ob``'s own probe sees it (needs.owner_visibility)."""
    return needs.owner_visibility(_lobes(ob), owner_shadows)


def _lobes(ob) -> list:
    return [lobes_of_material(slot.material) for slot in ob.material_slots]


def point_inside(ob, depsgraph, point) -> bool:
    """Is a world-space point inside a (closed) mesh object? Bounding box first, then the
    nearest surface point's normal: it faces away from a point that is inside."""
    if ob.type != "MESH":
        return False
    local = ob.matrix_world.inverted() @ _vec(point)
    bb = np.array(ob.bound_box)
    if np.any(np.array(local) < bb.min(axis=0) - 1e-9) or np.any(np.array(local) > bb.max(axis=0) + 1e-9):
        return False
    evaluated = ob.evaluated_get(depsgraph)
    try:
        found, location, normal, _ = evaluated.closest_point_on_mesh(local)
    except RuntimeError:
        return False
    return bool(found) and (local - location).dot(normal) < -1e-9


def world_description(scene):
    world = scene.world
    settings = scene.platelight
    path = bpy.path.abspath(settings.world_probe) if settings.world_probe else ""
    try:
        stamp = os.stat(path).st_mtime_ns if path else None
    except OSError:
        stamp = None
    return {"world": world.name_full, "tree": describe_tree(world.node_tree),
            "color": list(world.color), "probe": path, "probe_mtime": stamp}
