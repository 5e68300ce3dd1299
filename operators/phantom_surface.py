"""What phantoms look like to reflections, bounced light and probes: the camera-projected plate
(default, node_groups/phantom_plate.py) or their own hand-made materials
(``scene.platelight.phantom_surface``, overridden per object by ``object.platelight.phantom_surface``).

The plate material is put on the object's material slots as object-linked materials, so the
mesh's own materials are never touched; object-linked materials it replaces are remembered on
the object and given back when the object goes back to its own material."""
import json

import bpy

from ..addon import names
from ..node_groups.phantom_plate import build_phantom_plate_material, pinhole_from_camera
from .common import find_plate_image

KEPT_KEY = names.KEPT_MATERIALS_KEY      # on the object: {slot index: object-linked material name}
MATERIAL_NAME = names.PHANTOM_PLATE_MATERIAL


def phantom_surface(scene, ob):
    mode = ob.platelight.phantom_surface
    return scene.platelight.phantom_surface if mode == "SCENE" else mode


def plate_intrinsics(scene, camera):
    """The plate camera's (fx, fy, cx, cy, dist, width, height): the calibrated lens when the
    scene has one (operators/lens.py), else the Blender camera's pinhole."""
    from .lens import scene_lens

    calibrated = scene_lens(scene)
    if calibrated is not None:
        return calibrated
    fx, fy, cx, cy = pinhole_from_camera(scene, camera)
    return fx, fy, cx, cy, (0.0,) * 5, scene.render.resolution_x, scene.render.resolution_y


def apply_phantom_surfaces(scene, phantoms, view_layer=None):
    """Give each phantom the surface its setting asks for; returns how many show the plate.
    Without a plate or a camera every phantom keeps its own material. Showing the plate renders
    the phantoms once, white, to estimate their albedo (operators/phantom_albedo.py)."""
    from .phantom_albedo import phantom_albedo

    plate = find_plate_image(scene)
    camera = scene.camera
    usable = plate is not None and camera is not None and camera.type == "CAMERA"
    wanted = [ob for ob in phantoms if usable and phantom_surface(scene, ob) == "PLATE"]
    for ob in phantoms:          # the white render must not see the plate material
        if ob not in wanted:
            _give_back(ob)
    if not wanted:
        return 0
    layer = view_layer or bpy.context.view_layer
    albedo_path, radiance_path, world_to_camera, fallback, hidden = phantom_albedo(
        scene, layer, wanted, plate, plate_intrinsics(scene, camera))
    albedo = _load_map(names.PHANTOM_ALBEDO_IMAGE, albedo_path, "STRAIGHT")
    # RGB and A are separate facts (the plate, the distance): neither may scale the other
    radiance = _load_map(names.PHANTOM_RADIANCE_IMAGE, radiance_path, "CHANNEL_PACKED")
    # the maps are in the render camera's frame: its own pinhole, no lens
    material = build_phantom_plate_material(albedo, radiance, world_to_camera, pinhole_from_camera(scene, camera),
                                            (scene.render.resolution_x, scene.render.resolution_y), fallback)
    for ob, hidden_albedo in zip(wanted, hidden):
        _show_plate(ob, material)
        ob[names.HIDDEN_ALBEDO_KEY] = [*(float(c) for c in hidden_albedo), 1.0]
    return len(wanted)


def _load_map(name, path, alpha_mode):
    image = bpy.data.images.get(name)
    if image is not None:
        bpy.data.images.remove(image)
    image = bpy.data.images.load(path, check_existing=False)
    image.name = name
    image.colorspace_settings.name = "Non-Color"
    image.alpha_mode = alpha_mode
    return image


def _show_plate(ob, material):
    if not hasattr(ob.data, "materials"):
        return
    if not ob.material_slots:
        ob.data.materials.append(None)
    kept = json.loads(ob.get(KEPT_KEY, "{}"))
    for index, slot in enumerate(ob.material_slots):
        if slot.link == "OBJECT" and slot.material is not None and slot.material.name != MATERIAL_NAME:
            kept[str(index)] = slot.material.name
        slot.link = "OBJECT"
        slot.material = material
    ob[KEPT_KEY] = json.dumps(kept)


def _give_back(ob):
    if KEPT_KEY not in ob:
        return
    kept = json.loads(ob[KEPT_KEY])
    for index, slot in enumerate(ob.material_slots):
        if slot.link == "OBJECT" and (slot.material is None or slot.material.name == MATERIAL_NAME):
            name = kept.get(str(index))
            slot.material = bpy.data.materials.get(name) if name else None
            if name is None:
                slot.link = "DATA"
    del ob[KEPT_KEY]
    if names.HIDDEN_ALBEDO_KEY in ob:
        del ob[names.HIDDEN_ALBEDO_KEY]
