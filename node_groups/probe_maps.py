"""Per-probe map groups "PlateLight Probe <name>": the four maps of one probe folder, sampled along
the directions that "PlateLight SBRDF" computes, summed into Lr and shown by an Emission shader.

Images cannot travel through group sockets, so each probe folder gets its own small group holding
Environment Texture nodes (bilinear); every material bound to that folder uses the same group, so a
re-bake (images reloaded) or a switch to an image sequence updates all of them at once. The folder
is stored on the group (custom property), which is how the binding finds it again.

Glossiness n' in [0, 1] blends the maps with tent weights w_k = max(0, 1 - |3 n' - k|),
k = 0..3 for diffuse, glossy1, glossy2, specular (design.md: linear between neighbours): the
rule of addon/ibl/maps.map_weights, built here as nodes from the same constants.
"""
from __future__ import annotations

import math
import os

import numpy as np

import bpy

from ..addon import names
from ..addon.bake.layout import WORLD_FOLDER, read_record
from ..addon.ibl import irradiance_grid, sun_lobe, view_lobe
from ..addon.ibl.anisotropy import TAP_SLOPES
from ..addon.ibl.distance import (BEHIND_BISECT, BEHIND_GROWTH, BEHIND_JUMP, BEHIND_MAPS, BEHIND_NEAR, BEHIND_STEPS,
                                  DISTANCE_NAME, FAR, SECANT_STEPS, STEP_START, STEPS, behind_filename,
                                  behind_filenames, behind_name, distance_filename)
from ..addon.ibl.maps import (GLOSSINESS_KNOTS, GLOSSINESS_SCALE, MAP_HALF_ANGLES, MAP_NAMES, ROUGHNESS_KNOTS,
                              map_filename)
from ._build import VERSION_KEY, Graph, float_curve, io_nodes, knot_position, sync_interface, tent_weights, tents
from . import template_cache
from .sbrdf import LOOKUP_SOCKETS

FOLDER_KEY = "platelight_probe_dir"
VERSION = 12                         # a group built by another version is rebuilt
DISTANCE_BEHIND = behind_name(DISTANCE_NAME)   # the nodes reading the layer behind's distance map
BEHIND_FILES = {behind_name(name): name for name in BEHIND_MAPS}
BEHIND_KEY = "platelight_behind"     # on the group: built with the layer behind's look-ups
CENTRE_NODE = names.PROBE_CENTRE_NODE
PARALLAX_NODE = names.PARALLAX_NODE
SUN_NODES = (names.SUN_DIRECTION_NODE, names.SUN_COLOR_NODE, names.SUN_ANGLE_NODE)
GRID_NODES = (names.DIFFUSE_PARALLAX_NODE, names.GRID_LO_NODE, names.GRID_SCALE_NODE,
              names.GRID_POINTS_NODE, names.GRID_HEIGHT_NODE)
SEQUENCE_FRAMES = 1048574            # ImageUser.frame_duration's maximum: every frame maps to its file
# What the specular look-ups read along the streak: the ladder's maps after the diffuse one (which
# they read once, split by the lobe's reflectance), the glossy ones sunless (or the ladder's rungs,
# which are sunless where the probe has a sun), glossy3 a rung only, the mirror map with its sun.
SUNLESS_NAMES = {sun_lobe.sunless_name(name): name for name in sun_lobe.SUNLESS_MAPS}
STREAK_MAPS = tuple(sun_lobe.sunless_name(n) if n in sun_lobe.SUNLESS_MAPS else n for n in view_lobe.LADDER[1:])
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
        _build(template, behind)
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
    _build(tree, behind)
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


def bind_images(tree):
    """Point the group's Environment Texture nodes at the folder's maps (reloading them); returns
    the group, which a (re)build may have replaced (_build_if_needed)."""
    folder = tree[FOLDER_KEY]
    kind, first = probe_maps_status(folder)
    path = bpy.path.abspath(folder) if folder else ""
    frame = first if kind == "sequence" else None
    records = _frame_records(path, kind)
    tree = _build_if_needed(tree, _behind_on(path, records))
    record = records.get(frame, {})
    sun = _steady_sun(path, records)
    ladder = _ladder_on(path, records, sun)
    for node in tree.nodes:
        name = node.get("platelight_map")
        if node.bl_idname != "ShaderNodeTexEnvironment" or name is None:
            continue
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
    _bind_parallax(tree, record)
    _bind_grid(tree, record, sun, moving=kind == "sequence" and _grid_moves(path))
    return tree


def _scene_setting(name):
    scene = getattr(bpy.context, "scene", None)
    return bool(getattr(getattr(scene, "platelight", None), name, True))


def _has_baked(tree, map_name):
    node = next((n for n in tree.nodes if n.get("platelight_map") == map_name), None)
    return node is not None and is_baked(node.image)


def _bind_parallax(tree, record):
    """The probe's centre (from its bake record) and the parallax switch: on when the scene asks
    for it (scene.platelight.probe_parallax) and the folder has a distance map and a centre."""
    centre_node, switch = tree.nodes.get(CENTRE_NODE), tree.nodes.get(PARALLAX_NODE)
    if centre_node is None or switch is None:
        return
    origin = record.get("origin")
    if origin is not None:
        for axis, value in zip("XYZ", origin):
            centre_node.inputs[axis].default_value = float(value)
    on = _scene_setting("probe_parallax") and _has_baked(tree, DISTANCE_NAME) and origin is not None
    switch.outputs[0].default_value = 1.0 if on else 0.0




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


def _grid_moves(path) -> bool:
    """Does the irradiance grid's box change over a sequence's frames (a moving object)?"""
    boxes = set()
    for frame in _sequence_frames(path).get("diffuse", []):
        grid = read_record(path, frame).get(irradiance_grid.RECORD_KEY)
        if isinstance(grid, dict):
            boxes.add(tuple(round(float(v), 5) for v in [*grid["lo"], *grid["hi"]]))
    return len(boxes) > 1


def _bind_grid(tree, record, sun, moving=False):
    """The irradiance grid's box and shape (from the bake record) and its switch: on when the
    scene asks for it (scene.platelight.probe_diffuse_parallax), the folder has a grid and the
    grid lacks the sun exactly when the group adds it (``sun``; as the ladder's rungs). The
    group holds one box (the first frame's), so an object that moves over a baked sequence
    (``moving``) reads the paper's diffuse map of each frame instead: a box left behind would
    clamp every shading point to its far face."""
    nodes = [tree.nodes.get(name) for name in GRID_NODES]
    if any(node is None for node in nodes):
        return
    switch, lo_node, scale_node, points_node, height_node = nodes
    grid = record.get(irradiance_grid.RECORD_KEY)
    on = _scene_setting("probe_diffuse_parallax") and _has_baked(tree, irradiance_grid.GRID_NAME) \
        and isinstance(grid, dict) and not moving and bool(grid.get("sunless")) == (sun is not None)
    if on:
        for axis, low, high in zip("XYZ", grid["lo"], grid["hi"]):
            lo_node.inputs[axis].default_value = float(low)
            scale_node.inputs[axis].default_value = 1.0 / (high - low) if high > low else 0.0
        points_node.outputs[0].default_value = float(grid["points"])
        height_node.outputs[0].default_value = float(grid["height"])
    switch.outputs[0].default_value = 1.0 if on else 0.0


def set_parallax() -> int:
    """Switch parallax correction (specular and diffuse) in every probe group to the scene's
    settings (their update); returns how many groups were touched."""
    count = 0
    for tree in list(bpy.data.node_groups):           # a rebuild replaces the group
        if tree.bl_idname == "ShaderNodeTree" and FOLDER_KEY in tree and PARALLAX_NODE in tree.nodes:
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


def _named_value(g, name, default):
    """A Value node the binding finds by ``name`` and sets (a switch, a grid's size)."""
    node = g.node("ShaderNodeValue")
    node.name = node.label = name
    node.outputs[0].default_value = default
    return node.outputs[0]


def _named_vector(g, name):
    """A Combine XYZ node the binding finds by ``name`` and sets (a probe centre, a box corner)."""
    node = g.node("ShaderNodeCombineXYZ")
    node.name = node.label = name
    return node.outputs["Vector"]


def _parallax(g, direction, behind=False):
    """(direction, footprint ratio, behind weight): the specular look-up direction corrected for
    the shading point's offset from the probe centre, by the distance-impostor search of
    addon/ibl/distance.py (its numpy references parallax_search and, with ``behind``,
    parallax_layers): a linear search over geometric steps, then secant steps; the hit's distance
    from the point over its distance from the centre; and, with the layer behind, 1 where the
    ray passed beside a near occluder and meets what lies past it in the layer behind (None
    without). The switch (0/1, set by the binding) falls back to the uncorrected direction and a
    ratio of 1, as does a ray that meets nothing."""
    position = g.node("ShaderNodeNewGeometry").outputs["Position"]
    centre = _named_vector(g, CENTRE_NODE)
    switch = _named_value(g, PARALLAX_NODE, 0.0)
    p = g.vmath("SUBTRACT", position, centre)
    reflected = g.vmath("NORMALIZE", direction)
    p_len = g.vmath("LENGTH", p)

    def point(t):
        return g.vmath("ADD", p, g.vmath("SCALE", reflected, scale=t))

    def radius(q, map_name):
        node = g.node("ShaderNodeTexEnvironment", interpolation="Closest")
        node["platelight_map"] = map_name
        g.link(q, node.inputs["Vector"])
        return node.outputs["Color"]                 # colour -> r

    def s_of(map_name):
        def s(t):
            q = point(t)
            return g.math("SUBTRACT", g.vmath("LENGTH", q), radius(q, map_name))
        return s

    def looks(found, t):
        hit_point = point(t)
        look = g.mix("VECTOR", found, reflected, g.vmath("NORMALIZE", hit_point))
        ratio = g.math("DIVIDE", t, g.math("MAXIMUM", g.vmath("LENGTH", hit_point), 1e-6))
        ratio = g.math("MINIMUM", g.math("MAXIMUM", ratio, 0.0), 1.0)
        return look, g.math("MULTIPLY_ADD", found, g.math("SUBTRACT", ratio, 1.0), 1.0)

    found, t_hit, t_step, gap = _crossing(g, s_of(DISTANCE_NAME), point, 0.0, g.math("MULTIPLY", p_len, STEP_START),
                                          2.0, STEPS, BEHIND_BISECT if behind else 0)
    corrected, ratio = looks(found, t_hit)
    weight = None
    if behind:
        jump = g.math("GREATER_THAN", gap, g.math("MULTIPLY", g.vmath("LENGTH", point(t_hit)), BEHIND_JUMP))
        near = g.math("LESS_THAN", radius(point(t_step), DISTANCE_NAME), g.math("MULTIPLY", p_len, BEHIND_NEAR))
        passed = g.math("MULTIPLY", g.math("MULTIPLY", found, jump), near)
        found2, t2, _, _ = _crossing(g, s_of(DISTANCE_BEHIND), point, t_hit, t_step, BEHIND_GROWTH, BEHIND_STEPS)
        look2, ratio2 = looks(found2, t2)
        # the point the ray meets (or, escaping, its point at FAR): does the centre see it?
        far = point(g.math("MULTIPLY_ADD", found2, g.math("SUBTRACT", t2, FAR), FAR))
        seen = g.math("LESS_THAN", g.vmath("LENGTH", far),
                      g.math("MULTIPLY", radius(far, DISTANCE_NAME), 1.0 + BEHIND_JUMP + 1e-6))
        corrected = g.mix("VECTOR", passed, corrected, look2)
        ratio = g.math("MULTIPLY_ADD", passed, g.math("SUBTRACT", ratio2, ratio), ratio)
        weight = g.math("MULTIPLY", g.math("MULTIPLY", passed, g.math("SUBTRACT", 1.0, seen)), switch)
    ratio = g.math("MULTIPLY_ADD", switch, g.math("SUBTRACT", ratio, 1.0), 1.0)
    return g.mix("VECTOR", switch, reflected, corrected), ratio, weight


def _crossing(g, s, point, t_start, t_first, growth, steps, bisect=0):
    """distance._Rays.crossing in nodes: (found 0/1, refined t, the step t that first had s > 0,
    the gap between the surfaces at the refined bracket's ends) for the steps t_first growth^k
    after t_start; ``point``: t -> the ray's point."""
    def pick(flag, new, old):                       # flag ? new : old   (flag is 0 or 1)
        return g.math("MULTIPLY_ADD", flag, g.math("SUBTRACT", new, old), old)

    t_a, s_a = t_start, g.math("MINIMUM", s(t_start), -1e-4)
    t_b, s_b, found = t_start, s_a, 0.0
    for k in range(steps):
        t_k = g.math("MULTIPLY", t_first, growth ** k)
        s_k = s(t_k)
        newly = g.math("MULTIPLY", g.math("SUBTRACT", 1.0, found), g.math("GREATER_THAN", s_k, 0.0))
        t_b, s_b = pick(newly, t_k, t_b), pick(newly, s_k, s_b)
        before = g.math("SUBTRACT", g.math("SUBTRACT", 1.0, found), newly)
        t_a, s_a = pick(before, t_k, t_a), pick(before, s_k, s_a)
        found = g.math("MAXIMUM", found, newly)
    t_step = t_b

    def secant():
        return g.math("ADD", t_a, g.math("DIVIDE", g.math("MULTIPLY", g.math("SUBTRACT", t_b, t_a), s_a),
                                         g.math("MINIMUM", g.math("SUBTRACT", s_a, s_b), -1e-9)))
    for k in range(SECANT_STEPS + bisect):
        t_m = secant() if k < SECANT_STEPS else g.math("MULTIPLY", g.math("ADD", t_a, t_b), 0.5)
        s_m = s(t_m)
        hit = g.math("GREATER_THAN", s_m, 0.0)
        t_b, s_b, t_a, s_a = pick(hit, t_m, t_b), pick(hit, s_m, s_b), pick(hit, t_a, t_m), pick(hit, s_a, s_m)
    gap = None
    if bisect:
        def surface(t, s_t):                        # r = |q| - s
            return g.math("SUBTRACT", g.vmath("LENGTH", point(t)), s_t)
        gap = g.math("ABSOLUTE", g.math("SUBTRACT", surface(t_b, s_b), surface(t_a, s_a)))
    return found, secant(), t_step, gap


def _footprint_glossiness(g, glossiness, ratio):
    """addon/ibl/maps.footprint_glossiness as nodes: the glossiness whose lobe's half-energy
    angle (piecewise linear between the maps' MAP_HALF_ANGLES) is ``ratio`` times that of
    ``glossiness``, the ratio fading out between glossy1's angle and the diffuse lobe's."""
    knots = MAP_HALF_ANGLES
    position = g.math("MULTIPLY", g.math("MINIMUM", g.math("MAXIMUM", glossiness, 0.0), 1.0),
                      float(GLOSSINESS_SCALE))
    angle = knots[0]
    for k in range(len(knots) - 1):
        part = g.math("MINIMUM", g.math("MAXIMUM", g.math("SUBTRACT", position, float(k)), 0.0), 1.0)
        angle = g.math("MULTIPLY_ADD", part, knots[k + 1] - knots[k], angle)
    fade = g.math("MINIMUM", g.math("MAXIMUM", g.math("DIVIDE", g.math("SUBTRACT", knots[0], angle),
                                                     knots[0] - knots[1]), 0.0), 1.0)
    ratio = g.math("SUBTRACT", 1.0, g.math("MULTIPLY", g.math("SUBTRACT", 1.0, ratio), fade))
    angle = g.math("MULTIPLY", angle, ratio)
    return g.math("DIVIDE", knot_position(g, knots, angle), float(GLOSSINESS_SCALE))


def _view_lobe(g, inp, roughness, on):
    """view_lobe.ladder_weights at view_lobe.narrowed_roughness, and view_lobe.spread times
    TAP_SCALE, in nodes: (the LADDER maps' weights, the taps' spread vector). ``on`` (0/1, set by
    the binding) off: the roughness is not narrowed, the spread is 0 and glossy3's weight folds
    into its neighbours, which is the four maps' rule exactly."""
    n, view = inp["Diffuse Direction"], inp["Lobe View"]
    mu = g.math("MINIMUM", g.math("MAXIMUM", g.vmath("DOT_PRODUCT", n, view), 0.0), 1.0)
    floored = g.math("MAXIMUM", mu, view_lobe.MU_FLOOR)
    # view_lobe.view_weight: (alpha_b / alpha_t)^2, 1 for a round lobe
    alphas = g.node("ShaderNodeSeparateXYZ")
    g.link(inp["Lobe Alphas"], alphas.inputs["Vector"])
    ratio = g.math("DIVIDE", alphas.outputs["Y"], g.math("MAXIMUM", alphas.outputs["X"], 1e-12))
    amount = g.math("MULTIPLY", on, g.math("MULTIPLY", ratio, ratio))
    factor = g.math("MULTIPLY_ADD", amount, g.math("SUBTRACT", g.math("SQRT", floored), 1.0), 1.0)
    narrow = g.math("MULTIPLY", roughness, factor)
    # the ladder's position (0 = diffuse ... 4 = mirror): exact, piecewise linear in roughness
    knots = view_lobe.LADDER_ROUGHNESS
    weights = tents(g, knot_position(g, knots, narrow), len(knots))
    third = view_lobe.LADDER.index(view_lobe.GLOSSY3)
    folded = g.math("MULTIPLY", weights[third], g.math("SUBTRACT", 1.0, on))
    weights[third - 1] = g.math("MULTIPLY_ADD", folded, view_lobe.fold_share(), weights[third - 1])
    weights[third + 1] = g.math("MULTIPLY_ADD", folded, 1.0 - view_lobe.fold_share(), weights[third + 1])
    weights[third] = g.math("MULTIPLY", weights[third], on)
    # 2 alpha sqrt(1 - mu'^2) (sqrt(1 - mu^2) N + mu T), T the view's part along the surface
    in_plane = g.vmath("NORMALIZE", g.vmath("SUBTRACT", view, g.vmath("SCALE", n, scale=mu)))
    direction = g.vmath("ADD", g.vmath("SCALE", n, scale=g.math("SQRT", g.math("SUBTRACT", 1.0, g.math("MULTIPLY", mu, mu)))),
                        g.vmath("SCALE", in_plane, scale=mu))
    missing = g.math("SQRT", g.math("SUBTRACT", 1.0, g.math("MULTIPLY", floored, floored)))
    size = g.math("MULTIPLY", g.math("MULTIPLY", g.math("MULTIPLY", roughness, roughness), missing),
                  2.0 * view_lobe.TAP_SCALE)
    return weights, g.vmath("SCALE", direction, scale=g.math("MULTIPLY", size, amount))


def _irradiance_grid(g, direction):
    """The diffuse map seen from the shading point: the eight maps of the irradiance grid around
    it (addon/ibl/irradiance_grid.py: trilinear, atlas_uv) read along ``direction``."""
    points = _named_value(g, names.GRID_POINTS_NODE, float(irradiance_grid.DEFAULT_POINTS))
    height = _named_value(g, names.GRID_HEIGHT_NODE, 16.0)
    position = g.node("ShaderNodeNewGeometry").outputs["Position"]
    cell = g.vmath("MULTIPLY", g.vmath("SUBTRACT", position, _named_vector(g, names.GRID_LO_NODE)),
                   _named_vector(g, names.GRID_SCALE_NODE))
    cell = g.vmath("MINIMUM", g.vmath("MAXIMUM", cell, (0.0, 0.0, 0.0)), (1.0, 1.0, 1.0))
    cell = g.vmath("SCALE", cell, scale=g.math("SUBTRACT", points, 1.0))
    split = g.node("ShaderNodeSeparateXYZ")
    g.link(cell, split.inputs["Vector"])
    last = g.math("SUBTRACT", points, 2.0)
    lows, fractions = [], []
    for axis in range(3):
        low = g.math("MINIMUM", g.math("FLOOR", split.outputs[axis]), last)
        lows.append(low)
        fractions.append(g.math("SUBTRACT", split.outputs[axis], low))
    # the direction's equirect (u, v), as addon/ibl/equirect.dir_to_uv
    unit = g.node("ShaderNodeSeparateXYZ")
    g.link(g.vmath("NORMALIZE", direction), unit.inputs["Vector"])
    x, y, z = unit.outputs
    u = g.math("ADD", g.math("DIVIDE", g.math("ARCTAN2", g.math("MULTIPLY", y, -1.0), x), 2.0 * math.pi), 0.5)
    v = g.math("ADD", g.math("DIVIDE", g.math("ARCSINE", z), math.pi), 0.5)
    pad = float(irradiance_grid.PAD)
    tile_w = g.math("MULTIPLY_ADD", height, 2.0, 2.0 * pad)
    atlas_w = g.math("MULTIPLY", g.math("POWER", points, 3.0), tile_w)
    within_u = g.math("MULTIPLY_ADD", u, g.math("MULTIPLY", height, 2.0), pad)
    atlas_v = g.math("DIVIDE", g.math("MULTIPLY_ADD", v, height, pad), g.math("ADD", height, 2.0 * pad))
    # The atlas is read by Environment Texture nodes along the direction whose equirect (u, v) is
    # the atlas position: EEVEE samples an Image Texture with mipmaps chosen from screen-space
    # derivatives, which jump where the tile index changes (grid lines across the object), while
    # its Environment Texture reads the full-resolution level.
    elevation = g.math("MULTIPLY", g.math("SUBTRACT", atlas_v, 0.5), math.pi)
    cos_el, sin_el = g.math("COSINE", elevation), g.math("SINE", elevation)
    total = None
    for corner in range(8):
        steps = [(corner >> axis) & 1 for axis in range(3)]
        index = [g.math("ADD", low, float(step)) for low, step in zip(lows, steps)]
        tile = g.math("MULTIPLY_ADD", g.math("MULTIPLY_ADD", index[2], points, index[1]), points, index[0])
        atlas_u = g.math("DIVIDE", g.math("MULTIPLY_ADD", tile, tile_w, within_u), atlas_w)
        weight = None
        for f, step in zip(fractions, steps):
            factor = f if step else g.math("SUBTRACT", 1.0, f)
            weight = factor if weight is None else g.math("MULTIPLY", weight, factor)
        # equirect (u, v) -> direction: azimuth 2 pi (0.5 - u), elevation pi (v - 0.5)
        azimuth = g.math("MULTIPLY", g.math("SUBTRACT", 0.5, atlas_u), 2.0 * math.pi)
        look = g.node("ShaderNodeCombineXYZ")
        g.link(g.math("MULTIPLY", cos_el, g.math("COSINE", azimuth)), look.inputs["X"])
        g.link(g.math("MULTIPLY", cos_el, g.math("SINE", azimuth)), look.inputs["Y"])
        g.link(sin_el, look.inputs["Z"])
        image = g.node("ShaderNodeTexEnvironment", interpolation="Linear")
        image["platelight_map"] = irradiance_grid.GRID_NAME
        g.link(look.outputs["Vector"], image.inputs["Vector"])
        term = g.vmath("SCALE", image.outputs["Color"], scale=weight)
        total = term if total is None else g.vmath("ADD", total, term)
    return total


def _sun_nodes(g):
    """(direction, irradiance, angular diameter): the group's sun, one node each, which the
    binding finds by name (_bind_sun; its irradiance 0 when it has none)."""
    return (_named_vector(g, names.SUN_DIRECTION_NODE), _named_vector(g, names.SUN_COLOR_NODE),
            _named_value(g, names.SUN_ANGLE_NODE, 0.0))


def _sun_lambert(g, sun, normal):
    """sun_lobe.lambert in nodes: the sun on a diffuse surface of albedo 1, its horizon softened
    over the disc."""
    direction, color, angle = sun
    x = g.vmath("DOT_PRODUCT", normal, direction)
    s = g.math("MAXIMUM", g.math("SINE", g.math("MULTIPLY", angle, 0.5)), sun_lobe.HORIZON_MIN)
    q = g.math("DIVIDE", g.math("ADD", x, s), g.math("MULTIPLY", s, 2.0), clamp=True)
    soft = g.math("MAXIMUM", g.math("MULTIPLY", s, g.math("MULTIPLY", q, q)), x)
    return g.vmath("SCALE", color, scale=g.math("DIVIDE", soft, math.pi))


def _sun_highlight(g, sun, inp):
    """sun_lobe.highlight in nodes: E D(h) G2 / (4 (N.V)) (1 + b (1 - A) / A) of the sun for the
    SBRDF's Lobe View, Lobe Tangent and Lobe Alphas, b = sun_lobe.given_back(Specular Weight)."""
    direction, color, angle = sun
    n, view, tangent = inp["Diffuse Direction"], inp["Lobe View"], inp["Lobe Tangent"]
    bitangent = g.vmath("CROSS_PRODUCT", n, tangent)
    split = g.node("ShaderNodeSeparateXYZ")
    g.link(inp["Lobe Alphas"], split.inputs["Vector"])
    widening = g.math("MULTIPLY", g.math("MULTIPLY", angle, angle), sun_lobe.SIZE_WIDENING)
    a_t, a_b = (g.math("SQRT", g.math("ADD", g.math("POWER", g.math("MAXIMUM", split.outputs[axis],
                                                                    sun_lobe.MIN_ALPHA), 2.0), widening))
                for axis in (0, 1))
    half = g.vmath("NORMALIZE", g.vmath("ADD", direction, view))

    def squared(x):
        return g.math("MULTIPLY", x, x)
    stretched = g.math("ADD", g.math("ADD", squared(g.math("DIVIDE", g.vmath("DOT_PRODUCT", half, tangent), a_t)),
                                     squared(g.math("DIVIDE", g.vmath("DOT_PRODUCT", half, bitangent), a_b))),
                       squared(g.vmath("DOT_PRODUCT", half, n)))
    d = g.math("DIVIDE", 1.0, g.math("MULTIPLY", g.math("MULTIPLY", math.pi, g.math("MULTIPLY", a_t, a_b)),
                                     squared(stretched)))

    def smith(w):
        projected = g.math("ADD", squared(g.math("MULTIPLY", g.vmath("DOT_PRODUCT", w, tangent), a_t)),
                           squared(g.math("MULTIPLY", g.vmath("DOT_PRODUCT", w, bitangent), a_b)))
        ratio = g.math("DIVIDE", projected, g.math("MAXIMUM", squared(g.vmath("DOT_PRODUCT", w, n)), 1e-12))
        return g.math("MULTIPLY", g.math("SUBTRACT", g.math("SQRT", g.math("ADD", ratio, 1.0)), 1.0), 0.5)
    mu_v = g.vmath("DOT_PRODUCT", view, n)
    mu_l = g.vmath("DOT_PRODUCT", direction, n)
    masking = g.math("ADD", g.math("ADD", smith(view), smith(direction)), 1.0)
    # sun_lobe.albedo_roughness: the RMS alpha's roughness
    roughness = g.math("POWER", g.math("MULTIPLY", g.math("ADD", squared(split.outputs[0]), squared(split.outputs[1])),
                                       0.5), 0.25)
    denominator = g.math("MULTIPLY", g.math("MULTIPLY", masking, g.math("MAXIMUM", mu_v, 1e-4)), 4.0)
    above = g.math("MULTIPLY", g.math("GREATER_THAN", mu_v, 0.0), g.math("GREATER_THAN", mu_l, 0.0))
    # what single scattering loses, given back in full for a dielectric, F of it for a metal
    lost = g.math("SUBTRACT", g.math("DIVIDE", 1.0, _lobe_albedo(g, roughness, mu_v)), 1.0)
    weight = inp["Specular Weight"]
    low, high = sun_lobe.METAL_LIKE
    metal = g.math("MULTIPLY_ADD", g.vmath("DOT_PRODUCT", weight, (1 / 3, 1 / 3, 1 / 3)), 1.0 / (high - low),
                   -low / (high - low), clamp=True)
    given_back = g.mix("VECTOR", metal, (1.0, 1.0, 1.0), weight)
    regained = g.vmath("ADD", (1.0, 1.0, 1.0), g.vmath("SCALE", given_back, scale=lost))
    return g.vmath("MULTIPLY", g.vmath("SCALE", color, scale=g.math("MULTIPLY", above, g.math("DIVIDE", d, denominator))),
                   regained)


def _lobe_albedo(g, roughness, mu):
    """sun_lobe.albedo in nodes: each roughness row as a curve over mu, blended by tent weights."""
    knots = sun_lobe.ALBEDO_ROUGHNESS
    r = g.math("MINIMUM", g.math("MAXIMUM", roughness, knots[0]), knots[-1])
    mu = g.math("MINIMUM", g.math("MAXIMUM", mu, 0.0), 1.0)
    total = None
    for k, (knot, row) in enumerate(zip(knots, sun_lobe.ALBEDO)):
        weight = 1.0
        if k > 0:
            weight = g.math("DIVIDE", g.math("SUBTRACT", r, knots[k - 1]), knot - knots[k - 1])
        if k + 1 < len(knots):
            above = g.math("DIVIDE", g.math("SUBTRACT", knots[k + 1], r), knots[k + 1] - knot)
            weight = above if k == 0 else g.math("MINIMUM", weight, above)
        weight = g.math("MINIMUM", g.math("MAXIMUM", weight, 0.0), 1.0)
        term = g.math("MULTIPLY", weight, float_curve(g, sun_lobe.ALBEDO_MU, row, mu))
        total = term if total is None else g.math("ADD", total, term)
    return total


def _build(tree, behind=False):
    """The group's nodes; ``behind``: the folder has the layer behind the first surface
    (distance.parallax_layers), read by the specular map's look-ups."""
    g = Graph(tree)
    gin, gout = io_nodes(g)
    inp = gin.outputs

    def env(map_name, direction):
        node = g.node("ShaderNodeTexEnvironment", interpolation="Linear")
        node["platelight_map"] = map_name
        g.link(direction, node.inputs["Vector"])
        return node.outputs["Color"]

    def reflected_env(map_name, direction):
        """A specular look-up: from the layer behind where the ray passed beside an occluder."""
        if behind_weight is None or map_name not in BEHIND_MAPS:
            return env(map_name, direction)
        return g.mix("VECTOR", behind_weight, env(map_name, direction), env(behind_name(map_name), direction))

    def blended(direction, weights, map_names=MAP_NAMES, read=env):
        total = None
        for name, weight in zip(map_names, weights):
            term = g.vmath("SCALE", read(name, direction), scale=weight)
            total = term if total is None else g.vmath("ADD", total, term)
        return total

    sun = _sun_nodes(g)
    switch = _named_value(g, names.DIFFUSE_PARALLAX_NODE, 0.0)
    # the maps without the sun, and the sun's kink at the terminator exact, not blurred between
    # their texels
    sunless = g.mix("VECTOR", switch, env(sun_lobe.sunless_name("diffuse"), inp["Diffuse Direction"]),
                    _irradiance_grid(g, inp["Diffuse Direction"]))
    irradiance = g.vmath("ADD", sunless, _sun_lambert(g, sun, inp["Diffuse Direction"]))
    diffuse = g.vmath("MULTIPLY", inp["Diffuse Weight"], irradiance)
    specular_direction, footprint, behind_weight = _parallax(g, inp["Specular Direction"], behind)
    # The maps are blurred as seen from the centre; a lobe meeting a surface near the shading
    # point covers less of it (docs/decisions.md, "Glossy footprint").
    roughness = float_curve(g, GLOSSINESS_KNOTS, ROUGHNESS_KNOTS,
                            _footprint_glossiness(g, inp["Map Glossiness"], footprint))
    view_on = _named_value(g, names.VIEW_LOBE_NODE, 0.0)
    specular_weights, view_spread = _view_lobe(g, inp, roughness, view_on)
    # An anisotropic lobe: the maps read along the streak (addon/ibl/anisotropy.py), the same
    # expression for every tap; a round lobe seen from an angle: along the plane of incidence
    # (addon/ibl/view_lobe.py).
    spread = g.vmath("ADD", inp["Specular Spread"], view_spread)
    streak = None
    for slope in TAP_SLOPES:
        tap = g.vmath("NORMALIZE", g.vmath("ADD", specular_direction, g.vmath("SCALE", spread, scale=slope)))
        term = blended(tap, specular_weights[1:], STREAK_MAPS, reflected_env)
        streak = term if streak is None else g.vmath("ADD", streak, term)
    streak = g.vmath("SCALE", streak, scale=1.0 / len(TAP_SLOPES))
    # The diffuse map, read once (a streak is far narrower than its lobe), without its sun.
    rough_map = env(sun_lobe.sunless_name("diffuse"), specular_direction)
    streak = g.vmath("ADD", streak, g.vmath("SCALE", rough_map, scale=specular_weights[0]))
    # The sun the sunless maps lack, through the lobe, for their share (view_lobe.sun_share).
    rungs = [specular_weights[view_lobe.LADDER.index(name)] for name in view_lobe.RUNGS]
    sun_share = g.math("ADD", specular_weights[0], g.math("ADD", g.math("ADD", rungs[0], rungs[1]), rungs[2]))
    streak = g.vmath("ADD", streak, g.vmath("SCALE", _sun_highlight(g, sun, inp), scale=sun_share))
    specular = g.vmath("MULTIPLY", inp["Specular Weight"], streak)
    refraction_weights = tent_weights(g, inp["Map Glossiness"])
    channels = []
    for index, channel in enumerate("RGB"):
        sep = g.node("ShaderNodeSeparateColor")
        g.link(blended(inp[f"Refraction Direction {channel}"], refraction_weights), sep.inputs["Color"])
        channels.append(sep.outputs[index])
    combine = g.node("ShaderNodeCombineColor")
    for index, socket in enumerate(channels):
        g.link(socket, combine.inputs[index])
    refraction = g.vmath("MULTIPLY", inp["Refraction Weight"], combine.outputs["Color"])
    lr = g.vmath("ADD", g.vmath("ADD", diffuse, specular),
                 g.vmath("ADD", refraction, inp["Emission"]))
    # Emission shows exactly Lr: the probe already holds the scene's light, so no BSDF here
    # (a BSDF would add the lamps' and world's light a second time).
    emit = g.node("ShaderNodeEmission")
    g.link(lr, emit.inputs["Color"])
    emit.inputs["Strength"].default_value = 1.0
    g.link(emit.outputs["Emission"], gout.inputs["Shader"])
    g.link(lr, gout.inputs["Lr"])
    g.link(diffuse, gout.inputs["Diffuse Term"])
    g.link(specular, gout.inputs["Specular Term"])
    g.link(refraction, gout.inputs["Refraction Term"])
    gin.location = (-400, 0)
    gout.location = (200 * (g.column // 12 + 1), 0)
