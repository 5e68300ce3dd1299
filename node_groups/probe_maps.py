"""Per-probe map groups "PlateLight Probe <name>": the four maps of one probe folder, sampled along
the directions that "PlateLight SBRDF" computes, summed into Lr and shown by an Emission shader.

Images cannot travel through group sockets, so each probe folder gets its own small group holding
Environment Texture nodes (bilinear); every material bound to that folder uses the same group, so a
re-bake (images reloaded) or a switch to an image sequence updates all of them at once. The folder
is stored on the group (custom property), which is how the binding finds it again.

This module keeps the groups (built once into a template, copied after) and binds their images and
values to a probe folder's records; probe_nodes.py builds their nodes.
"""
from __future__ import annotations

import os

import numpy as np

import bpy

from ..addon import names
from ..addon.bake.layout import WORLD_FOLDER, read_record
from ..addon.ibl import irradiance_grid, sun_lobe, view_lobe
from ..addon.ibl.distance import BEHIND_MAPS, DISTANCE_NAME, behind_filename, behind_filenames, behind_name, distance_filename
from ..addon.ibl.maps import MAP_NAMES, map_filename
from ._build import VERSION_KEY, drop_keys, hold_per_frame, sync_interface
from . import template_cache
from .probe_nodes import DISTANCE_BEHIND, build as build_nodes
from .sbrdf import LOOKUP_SOCKETS

FOLDER_KEY = "platelight_probe_dir"
VERSION = 12                         # a group built by another version is rebuilt
BEHIND_FILES = {behind_name(name): name for name in BEHIND_MAPS}
BEHIND_KEY = "platelight_behind"     # on the group: built with the layer behind's look-ups
SUN_NODES = (names.SUN_DIRECTION_NODE, names.SUN_COLOR_NODE, names.SUN_ANGLE_NODE)
GRID_NODES = (names.DIFFUSE_PARALLAX_NODE, names.GRID_LO_NODE, names.GRID_SCALE_NODE,
              names.GRID_POINTS_NODE, names.GRID_HEIGHT_NODE)
SEQUENCE_FRAMES = 1048574            # ImageUser.frame_duration's maximum: every frame maps to its file
SUNLESS_NAMES = {sun_lobe.sunless_name(name): name for name in sun_lobe.SUNLESS_MAPS}
OUTPUTS = (("Shader", "NodeSocketShader"), ("Lr", "NodeSocketColor"),
           ("Diffuse Term", "NodeSocketColor"), ("Specular Term", "NodeSocketColor"),
           ("Refraction Term", "NodeSocketColor"))


def find_probe_group(folder: str):
    key = _folder_key(folder)
    for tree in bpy.data.node_groups:
        if tree.bl_idname == "ShaderNodeTree" and FOLDER_KEY in tree \
                and _folder_key(tree[FOLDER_KEY]) == key:
            return tree
    return None


def ensure_probe_group(folder: str, label: str | None = None):
    """The probe group for ``folder`` (a Blender path, may start with //), built or upgraded in
    place, with its images pointing at the folder's current maps (single file or sequence)."""
    key = _folder_key(folder)
    tree = find_probe_group(folder)
    if tree is None:
        folder_name = os.path.basename(os.path.normpath(key))
        # The world's maps are shared by every world-only object: not named after the first one.
        label = "World" if folder_name == WORLD_FOLDER else (label or folder_name or "World")
        tree = bpy.data.node_groups.new(names.PROBE_GROUP_PREFIX + label, "ShaderNodeTree")
        tree[FOLDER_KEY] = key
    return bind_images(tree)


def _sync_probe_interface(tree):
    sync_interface(tree, [("OUTPUT", n, t, {}) for n, t in OUTPUTS]
                   + [("INPUT", n, t, {"hide_value": True}) for n, t in LOOKUP_SOCKETS])


def _interface(tree):
    return [(i.in_out, i.name, i.socket_type, i.identifier) for i in tree.interface.items_tree
            if i.item_type == "SOCKET"]


def _template(behind):
    """The group's nodes as this version builds them, built once per machine (template_cache.py)
    or Blender session and copied after.
    Every node added to a tree re-runs Blender's update of the whole tree, so a build takes time
    quadratic in its size, and a copy almost none (docs/decisions.md, "Probe groups built once")."""
    name = names.PROBE_GROUP_TEMPLATE + (" Behind" if behind else "")
    template = bpy.data.node_groups.get(name)
    if template is not None and (template.bl_idname != "ShaderNodeTree" or template.library is not None
                                 or template.get(VERSION_KEY) != VERSION or FOLDER_KEY in template):
        template.name = name + " (old)"            # not ours to change; set aside, built anew
        template = None
    if template is None:
        template = template_cache.load(name)
    if template is None:
        template = bpy.data.node_groups.new(name, "ShaderNodeTree")
        _sync_probe_interface(template)
        build_nodes(template, behind)
        template[VERSION_KEY] = VERSION
        template[BEHIND_KEY] = behind
        template_cache.save(template)
    return template


def prepare_templates() -> None:
    """Build (or load from this machine's cache) both templates now, e.g. before a timed shot:
    otherwise the first bake after installing or updating the add-on pays their build inside it."""
    _template(False)
    _template(True)


def _build_if_needed(tree, behind):
    """(Re)build the group's nodes when they are from another version or were built with(out)
    the layer behind's look-ups that the folder now has(n't): those cost a mirror's shading
    points about 20 look-ups, which the groups of other objects never pay. Returns the group:
    a copy of this Blender session's template takes the group's place (its users, name and properties)
    where the interfaces agree; otherwise (a group from another version) it is rebuilt in place."""
    if tree.get(VERSION_KEY) == VERSION and len(tree.nodes) > 2 and bool(tree.get(BEHIND_KEY)) == behind:
        return tree
    if tree.library is None:
        template = _template(behind)
        if not tree.interface.items_tree:
            _sync_probe_interface(tree)                # a new group: the template's own order
        if _interface(tree) == _interface(template):
            fresh = template.copy()
            for key in tree.keys():
                if key not in (VERSION_KEY, BEHIND_KEY):
                    fresh[key] = tree[key]
            name, fake_user = tree.name, tree.use_fake_user
            tree.user_remap(fresh)
            fresh.use_fake_user = fake_user
            bpy.data.node_groups.remove(tree)
            fresh.name = name
            return fresh
    _sync_probe_interface(tree)
    tree.nodes.clear()
    build_nodes(tree, behind)
    tree[VERSION_KEY] = VERSION
    tree[BEHIND_KEY] = behind
    return tree


def _present_single(path: str) -> list:
    return [n for n in MAP_NAMES if os.path.isfile(os.path.join(path, map_filename(n)))]


def _sequence_frames(path: str) -> dict:
    """map name -> sorted frame numbers of its ``<name>_####.exr`` files."""
    frames = {}
    for f in os.listdir(path):
        stem, ext = os.path.splitext(f)
        name, _, digits = stem.rpartition("_")
        if ext == ".exr" and name in MAP_NAMES and digits.isdigit():
            frames.setdefault(name, []).append(int(digits))
    return {n: sorted(v) for n, v in frames.items()}


def probe_maps_status(folder: str) -> tuple[str, int | None]:
    """("single" | "sequence" | "missing", first frame or None) for the maps in ``folder``.

    The bake writes only the maps an object's materials read (a matte object gets diffuse
    alone), so any one map makes the folder usable; absent maps are bound as no image."""
    path = bpy.path.abspath(folder) if folder else ""
    if not path or not os.path.isdir(path):
        return "missing", None
    if _present_single(path):
        return "single", None
    frames = _sequence_frames(path)
    if frames:
        return "sequence", min(v[0] for v in frames.values())
    return "missing", None


def missing_maps(folder: str, needed) -> list:
    """The maps of ``needed`` that ``folder`` lacks (as single files, or as a sequence when it
    holds one): a material switched to a glossier preset after an only-needed-maps bake reads
    maps that were never baked, and must be told to re-bake."""
    kind, _ = probe_maps_status(folder)
    if kind == "missing":
        return list(needed)
    path = bpy.path.abspath(folder)
    present = _present_single(path) if kind == "single" else list(_sequence_frames(path))
    return [name for name in needed if name not in present]


def map_nodes(tree) -> list:
    """The group's nodes that read one of the probe's maps (each keyed by the map's name)."""
    return [node for node in tree.nodes
            if node.bl_idname == "ShaderNodeTexEnvironment" and node.get("platelight_map") is not None]


def bind_images(tree):
    """Point the group's Environment Texture nodes at the folder's maps (reloading them); returns
    the group, which a (re)build may have replaced (_build_if_needed)."""
    folder = tree[FOLDER_KEY]
    kind, first = probe_maps_status(folder)
    path = bpy.path.abspath(folder) if folder else ""
    frame = first if kind == "sequence" else None
    records = _frame_records(path, kind)
    tree = _build_if_needed(tree, _behind_on(path, records))
    sun = _steady_sun(path, records)
    ladder = _ladder_on(path, records, sun)
    for node in map_nodes(tree):
        name = node["platelight_map"]
        if kind == "missing":
            filename = None
        elif name == view_lobe.GLOSSY3 or (ladder and SUNLESS_NAMES.get(name) in view_lobe.RUNGS):
            # glossy3 exists only as a rung; glossy1 and glossy2 read their rungs with the ladder on
            filename = view_lobe.rung_filename(SUNLESS_NAMES.get(name, name), frame) if ladder else None
        elif name in SUNLESS_NAMES:
            # without a sun the sunless look-ups read the maps themselves (the sun term is 0)
            base = SUNLESS_NAMES[name]
            filename = sun_lobe.sunless_filename(base, frame) if sun else map_filename(base, frame)
        elif name == DISTANCE_NAME:
            filename = distance_filename(frame)
        elif name == DISTANCE_BEHIND:
            filename = distance_filename(frame, behind=True)
        elif name in BEHIND_FILES:
            filename = behind_filename(BEHIND_FILES[name], frame)
        elif name == irradiance_grid.GRID_NAME:
            filename = irradiance_grid.grid_filename(frame)
        else:
            filename = map_filename(name, frame)
        previous = node.image
        if filename is None or not os.path.isfile(os.path.join(path, filename)):
            node.image = unbaked_map()             # this map was not baked: the lobe reads black
            _drop_dangling(previous)
            continue
        image = _load_image(os.path.join(folder, filename), kind == "sequence")
        node.image = image
        if previous is not image:
            _drop_dangling(previous)
        if kind == "sequence":
            # Scene frame F reads <map>_F.exr, whatever frames exist when binding: farm nodes
            # bake parts of the range in parallel, and a duration counted from the files
            # present made later frames hold the last one seen (silently wrong maps).
            user = node.image_user
            user.frame_start = 1
            user.frame_offset = 0
            user.frame_duration = SEQUENCE_FRAMES
            user.use_auto_refresh = True
    tree["platelight_maps"] = kind
    _bind_sun(tree, sun)
    view_switch = tree.nodes.get(names.VIEW_LOBE_NODE)
    if view_switch is not None:
        view_switch.outputs[0].default_value = 1.0 if ladder else 0.0
    drop_keys(tree, (names.PROBE_CENTRE_NODE, *GRID_NODES))   # an earlier binding's frames
    _bind_parallax(tree, records)
    _bind_grid(tree, records, sun)
    return tree


def _scene_setting(name):
    scene = getattr(bpy.context, "scene", None)
    return bool(getattr(getattr(scene, "platelight", None), name, True))


def _has_baked(tree, map_name):
    node = next((n for n in map_nodes(tree) if n["platelight_map"] == map_name), None)
    return node is not None and is_baked(node.image)


def _bind_parallax(tree, records):
    """The probe's centre (from its bake records: each frame's where an object moves over a baked
    sequence) and the parallax switch: on when the scene asks for it (scene.platelight.
    probe_parallax) and the folder has a distance map and every frame a centre."""
    centre_node, switch = tree.nodes.get(names.PROBE_CENTRE_NODE), tree.nodes.get(names.PARALLAX_NODE)
    if centre_node is None or switch is None:
        return
    origins = {frame: record.get("origin") for frame, record in records.items()}
    on = bool(origins) and all(o is not None for o in origins.values())
    if on:
        for index, axis in enumerate("XYZ"):
            _hold(centre_node.inputs[axis], {f: float(o[index]) for f, o in origins.items()})
    on = on and _scene_setting("probe_parallax") and _has_baked(tree, DISTANCE_NAME)
    switch.outputs[0].default_value = 1.0 if on else 0.0


def _hold(socket, values):
    """``socket`` set to its one value, or keyed per frame where the frames' values differ (a
    moving object's probe centre and grid box: the frame's own, not the first's)."""
    if len(set(values.values())) > 1:
        hold_per_frame(socket, values)
    else:
        socket.default_value = next(iter(values.values()))


def _behind_on(path, records) -> bool:
    """Does the group read the layer behind? When the scene asks for parallax and the layer
    behind (scene.platelight.probe_parallax, probe_behind) and every frame present has it."""
    if not records or not (_scene_setting("probe_parallax") and _scene_setting("probe_behind")):
        return False
    return all(os.path.isfile(os.path.join(path, f)) for frame in records for f in behind_filenames(frame))


def _frame_records(path, kind) -> dict:
    """{frame: bake record} of every frame the folder holds maps for, in order ({None: record}
    for single-frame maps, {} when there are none): the group's switches are one for all frames,
    so each must hold for every frame."""
    if kind == "missing":
        return {}
    if kind == "single":
        return {None: read_record(path, None)}
    frames = sorted({f for numbers in _sequence_frames(path).values() for f in numbers})
    return {frame: read_record(path, frame) for frame in frames}


def _steady_sun(path, records):
    """The sun the group shades through the lobe: the bake record's, when the scene asks for it
    (scene.platelight.probe_sun_lobe), the bake wrote every sunless map beside its maps, and, over
    a baked sequence, every frame has the same sun (the group holds one; a sun that an object
    moves out of would otherwise shine on in frames whose maps no longer hold it). Else None:
    the maps keep their sun."""
    if not records or not _scene_setting("probe_sun_lobe"):
        return None
    sun = sun_lobe.from_record(next(iter(records.values())))
    if sun is None:
        return None
    for frame, record in records.items():
        for name in sun_lobe.SUNLESS_MAPS:
            present = os.path.isfile(os.path.join(path, map_filename(name, frame)))
            if present and not os.path.isfile(os.path.join(path, sun_lobe.sunless_filename(name, frame))):
                return None
        other = sun_lobe.from_record(record)
        if other is None or not (np.allclose(other.direction, sun.direction, atol=1e-4)
                                 and np.allclose(other.rgb, sun.rgb, rtol=1e-3, atol=1e-6)):
            return None
    return sun


def _ladder_on(path, records, sun) -> bool:
    """Does the group read the view-dependent ladder? When the scene asks for it (Glossy Lobes,
    view_lobe.in_use), the bake wrote every rung, and the rungs lack the sun exactly when the
    group adds it through the lobe (a ladder baked sunless, read without the sun term, would lose
    the sun; one baked with it, read with the term, would show it twice). Over a baked sequence
    every frame present must qualify: the switch is one for all frames, and a frame without its
    rungs would read no image (black glossy lobes)."""
    scene = getattr(bpy.context, "scene", None)
    settings = getattr(scene, "platelight", None)
    if not records or settings is None or not view_lobe.in_use(settings.glossy_lobes, settings.sampling):
        return False
    for frame, record in records.items():
        if not all(os.path.isfile(os.path.join(path, f)) for f in view_lobe.ladder_filenames(frame)):
            return False
        sunless = view_lobe.record_sunless(record)
        if sunless is None or sunless != (sun is not None):
            return False
    return True


def _bind_sun(tree, sun):
    """The sun's direction, irradiance (0 without a sun: no term) and size into the group."""
    nodes = [tree.nodes.get(name) for name in SUN_NODES]
    if any(node is None for node in nodes):
        return
    direction, color, angle = nodes
    for axis, d, c in zip("XYZ", sun.direction if sun else (0.0, 0.0, 1.0), sun.rgb if sun else (0.0,) * 3):
        direction.inputs[axis].default_value = float(d)
        color.inputs[axis].default_value = float(c)
    angle.outputs[0].default_value = float(sun.angle) if sun else 0.0


def _bind_grid(tree, records, sun):
    """The irradiance grid's box and shape (from the bake records, keyed per frame where an object
    moves over a baked sequence: a box left behind would clamp every shading point to its far
    face) and its switch: on when the scene asks for it (scene.platelight.probe_diffuse_parallax),
    the folder has a grid and every frame's grid lacks the sun exactly when the group adds it
    (``sun``; as the ladder's rungs)."""
    nodes = [tree.nodes.get(name) for name in GRID_NODES]
    if any(node is None for node in nodes):
        return
    switch, lo_node, scale_node, points_node, height_node = nodes
    grids = {frame: record.get(irradiance_grid.RECORD_KEY) for frame, record in records.items()}
    on = _scene_setting("probe_diffuse_parallax") and _has_baked(tree, irradiance_grid.GRID_NAME) \
        and bool(grids) and all(isinstance(g, dict) and bool(g.get("sunless")) == (sun is not None)
                                for g in grids.values())
    if on:
        for index, axis in enumerate("XYZ"):
            _hold(lo_node.inputs[axis], {f: float(g["lo"][index]) for f, g in grids.items()})
            _hold(scale_node.inputs[axis], {f: _inverse_span(g, index) for f, g in grids.items()})
        _hold(points_node.outputs[0], {f: float(g["points"]) for f, g in grids.items()})
        _hold(height_node.outputs[0], {f: float(g["height"]) for f, g in grids.items()})
    switch.outputs[0].default_value = 1.0 if on else 0.0


def _inverse_span(grid, axis) -> float:
    low, high = float(grid["lo"][axis]), float(grid["hi"][axis])
    return 1.0 / (high - low) if high > low else 0.0


def set_parallax() -> int:
    """Switch parallax correction (specular and diffuse) in every probe group to the scene's
    settings (their update); returns how many groups were touched."""
    count = 0
    for tree in list(bpy.data.node_groups):           # a rebuild replaces the group
        if tree.bl_idname == "ShaderNodeTree" and FOLDER_KEY in tree and names.PARALLAX_NODE in tree.nodes:
            bind_images(tree)
            count += 1
    return count


def unbaked_map():
    """The black stand-in an unbaked map's node reads: a generated image, so Cycles has nothing
    to load (a node without an image made it log "Image file  does not exist" and "Failed to load
    1 image files" on every render before the first bake, the probe renders included)."""
    image = bpy.data.images.get(names.UNBAKED_MAP)
    if image is None or image.source != "GENERATED":
        image = bpy.data.images.new(names.UNBAKED_MAP, 1, 1, alpha=False, float_buffer=True)
        image.generated_color = (0.0, 0.0, 0.0, 1.0)
    return image


def is_baked(image) -> bool:
    """Does a probe node's image hold a baked map (not nothing, not the stand-in)?"""
    return image is not None and image.name != names.UNBAKED_MAP


def _drop_dangling(image):
    """Remove an image no node uses any more whose file is gone (a frame-range bake deletes the
    single-frame maps it supersedes; a matte object loses its glossy maps), so the .blend
    keeps no images pointing at missing files."""
    if image is None or image.users or image.packed_file is not None:
        return
    if not os.path.isfile(bpy.path.abspath(image.filepath)):
        bpy.data.images.remove(image)


def _load_image(filepath, sequence):
    abspath = os.path.normpath(bpy.path.abspath(filepath))
    for image in bpy.data.images:
        if os.path.normpath(bpy.path.abspath(image.filepath)) == abspath:
            image.source = "SEQUENCE" if sequence else "FILE"
            image.reload()
            return image
    image = bpy.data.images.load(filepath, check_existing=False)
    image.source = "SEQUENCE" if sequence else "FILE"
    image.colorspace_settings.name = "Linear Rec.709"
    return image


def _folder_key(folder: str) -> str:
    """One spelling per folder: the bake writes '//platelight_maps/_world/' where the world
    fallback said '//platelight_maps/_world', and the two made two probe groups."""
    folder = folder or ""
    if folder.startswith("//"):
        return "//" + os.path.normpath(folder[2:]).replace(os.sep, "/") if folder[2:] else "//"
    return os.path.normpath(os.path.abspath(folder))
