"""What makes a probe up to date, and the maps kept inside the .blend: the content hash of a
probe's inputs (stored in its record by addon/bake/layout.py; an unchanged hash means no
render), the hash of the world's maps, and packing map files into the .blend."""
from __future__ import annotations

import os

import bpy
import numpy as np

from ...addon import names
from ...addon.bake.hashing import content_hash
from ...addon.bake.layout import lookup_filenames
from ...addon.bake.needs import OWNER_INDIRECT
from ...addon.bake.probe_size import MAX_SAMPLE_FACTOR, SAMPLE_ROWS
from ...addon.ibl.distance import BEHIND_VERSION, VERSION as DISTANCE_VERSION
from ...addon.ibl.irradiance_grid import VERSION as GRID_VERSION
from ...addon.ibl.maps import MapSettings, map_filename
from ...addon.ibl import view_lobe
from ...addon.ibl.sun_lobe import VERSION as SUN_LOBE_VERSION
from .probe_render import render_key


def probe_hash(scene, origin, maps, world_digest, seen, map_settings, sized_height=None, owner=None,
               grid=False, behind=False):
    """The hash of one object's probe: where it sits, which maps, the world, the bake settings,
    the probe's height when it is sized to the object on screen, Cycles' bounces and ``seen``
    (sorted (object, description digest) of what the probe sees); ``owner``, ``grid`` and
    ``behind`` as the bake decided them (needs.owner_visibility, needs.wants_irradiance_grid,
    needs.wants_behind_layer); the glossy lobes the bake's ``map_settings`` blur with."""
    settings = scene.platelight
    cycles = scene.cycles
    sized = {"sized_height": sized_height} if sized_height else {}     # older records stay valid
    # An owner seen by the probe's indirect rays makes another probe; the older modes hash as before.
    indirect = {"owner": owner} if owner == OWNER_INDIRECT else {}
    # A probe with an irradiance grid is another bake; one without hashes as before.
    with_grid = {"irradiance_grid": GRID_VERSION} if grid else {}
    with_behind = {"behind": BEHIND_VERSION} if behind else {}     # likewise the layer behind
    return content_hash({
        **sized, **indirect, **with_grid, **with_behind,
        "origin": np.asarray(origin), "maps": list(maps), "world": world_digest,
        "distance": DISTANCE_VERSION, **_sun_key(scene), **_ladder_key(scene),
        "samples_rule": [SAMPLE_ROWS, MAX_SAMPLE_FACTOR],
        "settings": [settings.probe_height, settings.probe_samples, settings.sampling,
                     settings.probe_fast_world, settings.probe_owner_shadows,
                     settings.probe_distance],
        **_lobes_key(map_settings),
        "render": render_key(cycles),
        "seen": seen,
    })


def _lobes_key(map_settings):
    """GGX glossy lobes make other maps; the paper's Phong lobes hash as before (older records stay
    valid)."""
    lobes = map_settings.glossy_lobes()
    return {"lobes": lobes} if lobes != MapSettings.lobes else {}


def _sun_key(scene):
    """A bake with the sun apart (Sun Highlight) writes other files; one without hashes as before."""
    return {"sun_lobe": SUN_LOBE_VERSION} if scene.platelight.probe_sun_lobe else {}


def _ladder_key(scene):
    """A bake with the view-dependent ladder (view_lobe) writes its rungs; one without hashes as before."""
    settings = scene.platelight
    return {"view_lobe": view_lobe.VERSION} if view_lobe.in_use(settings.glossy_lobes, settings.sampling) else {}


def world_maps_hash(scene, world_digest, image, map_settings):
    """The hash of the world's own maps: from ``image`` (a WorldImage: an EXR, its strength and
    rotation) or, when None, from a probe render of the world alone (then the probe settings
    count too)."""
    source = image.path if image is not None else None
    return content_hash({"world": world_digest, "source": source,
                         "strength": image.strength if image else None,
                         "rotation": image.rotation if image else None,
                         "heights": map_settings.heights,
                         "sampling": map_settings.sampling, **_lobes_key(map_settings),
                         **_sun_key(scene), **_ladder_key(scene),
                         "samples": None if source else [scene.platelight.probe_samples, SAMPLE_ROWS,
                                                         MAX_SAMPLE_FACTOR],
                         "probe_height": None if source else scene.platelight.probe_height})


def pack_maps(folder_rel, frame, maps, refresh):
    """Pack the map files of one probe folder (and frame) into the .blend, with the parallax
    look-ups' distance map and irradiance grid where the bake wrote them (a farm node without
    the folder would read them black while the group's switches stay on)."""
    filenames = [map_filename(name, frame) for name in maps]
    filenames += [f for f in lookup_filenames(frame) if os.path.isfile(bpy.path.abspath(folder_rel + f))]
    for filename in filenames:
        label = f"{names.PACKED_MAP_PREFIX}{folder_rel.rstrip('/').rsplit('/', 1)[-1]}/{filename}"
        pack_map(folder_rel + filename, label, refresh)


def pack_map(rel_path, label, refresh):
    """Pack one map file into the .blend as the image ``label`` (its filepath the Blender-relative
    file, so a material loading that file with check_existing finds it). Re-packing updates the
    same image: never a duplicate."""
    image = bpy.data.images.get(label)
    if image is None:
        image = bpy.data.images.load(rel_path, check_existing=True)
        image.name = label
    elif refresh or image.packed_file is None or image.filepath != rel_path:
        if image.packed_file is not None:
            image.unpack(method="REMOVE")
        image.filepath = rel_path
        image.reload()
    else:
        return image
    image.pack()
    return image
