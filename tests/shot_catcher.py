"""Cycles' shadow catcher as a skilled artist sets it up: the benchmark's reference route.

Built with Blender alone (no PlateLight code): the real surfaces' stand-ins are shadow catchers
with an albedo matched to the plate, Cycles' own OIDN with albedo and normal guides denoises the
render and its Shadow Catcher pass, adaptive sampling stops clean pixels, persistent data keeps
the scene between frames. The composite is the one Blender's manual gives: the plate times the
Shadow Catcher pass, the CG over it. docs/compositing.md ("Cycles' shadow catcher, set up
well") lists CATCHER_SETTINGS; tests/blender/test_shot_bench.py checks the two agree."""
from __future__ import annotations

import numpy as np

# (data path from the scene, value): what the artist sets; the truth's own settings where it
# has them (Filter Glossy 0), the tools Cycles offers to be quick otherwise
CATCHER_SETTINGS = {
    "cycles.blur_glossy": 0.0,
    "cycles.use_denoising": True,
    "cycles.denoiser": "OPENIMAGEDENOISE",
    "cycles.denoising_input_passes": "RGB_ALBEDO_NORMAL",
    "cycles.denoising_prefilter": "ACCURATE",
    "cycles.use_adaptive_sampling": True,
    "cycles.adaptive_threshold": 0.0,        # automatic: it falls as the samples rise
    "cycles.use_light_tree": True,
    "render.use_persistent_data": True,
    "render.film_transparent": True,
    "view_layers[0].cycles.use_pass_shadow_catcher": True,
}
# the albedo guess is matched on a small, quick render of the stand-ins alone
MATCH_SCALE, MATCH_SAMPLES, START_ALBEDO = 0.25, 16, 0.5


def resolve(scene, path: str):
    """(owner, attribute) of a CATCHER_SETTINGS data path on ``scene``."""
    owner = scene
    *parts, attribute = path.replace("[0]", ".0").split(".")
    for part in parts:
        owner = owner[int(part)] if part.isdigit() else getattr(owner, part)
    return owner, attribute


def setup_catcher(scene, phantoms, samples: int):
    """The scene's render settings and stand-ins as the artist sets them for ``samples``."""
    for path, value in CATCHER_SETTINGS.items():
        owner, attribute = resolve(scene, path)
        setattr(owner, attribute, value)
    scene.cycles.samples = samples
    for ob in phantoms:
        ob.is_shadow_catcher = True


def guess_albedos(bpy, scene, phantoms, cg, plate, render):
    """Each stand-in gets one diffuse colour, matched to the plate as an artist does: render the
    stand-ins grey and scale the grey by plate / render over what each covers. Glossy stand-ins
    keep their guessed roughness. ``render(scene)`` -> (RGBA image, object-index image)."""
    import cv2

    keep = (scene.render.resolution_percentage, scene.cycles.samples, scene.view_layers[0].use_pass_object_index,
            scene.render.film_transparent)
    hidden = [ob.hide_render for ob in cg]
    catching = [ob.is_shadow_catcher for ob in phantoms]
    for ob in cg:
        ob.hide_render = True
    for ob in phantoms:
        ob.is_shadow_catcher = False          # a catcher renders transparent: nothing to match
    for index, ob in enumerate(phantoms, start=1):
        ob.pass_index = index
        set_colour(ob, (START_ALBEDO,) * 3)
    scene.render.resolution_percentage = int(100 * MATCH_SCALE)
    scene.cycles.samples = MATCH_SAMPLES
    scene.view_layers[0].use_pass_object_index = True
    scene.render.film_transparent = True
    try:
        image, index_image = render(scene)
    finally:
        (scene.render.resolution_percentage, scene.cycles.samples, scene.view_layers[0].use_pass_object_index,
         scene.render.film_transparent) = keep
        for ob, was in zip(cg, hidden):
            ob.hide_render = was
        for ob, was in zip(phantoms, catching):
            ob.is_shadow_catcher = was
    small_plate = cv2.resize(plate, (image.shape[1], image.shape[0]), interpolation=cv2.INTER_AREA)
    guesses = {}
    for index, ob in enumerate(phantoms, start=1):
        mask = (np.abs(index_image[..., 0] - index) < 0.5) & (image[..., 3] > 0.999)
        mask = cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        if not mask.any():
            raise ValueError(f"the stand-in {ob.name} covers no pixel of the plate: no colour to match")
        ratio = np.median(small_plate[mask], axis=0) / np.maximum(np.median(image[mask, :3], axis=0), 1e-6)
        guesses[ob.name] = tuple(float(v) for v in np.clip(START_ALBEDO * ratio, 0.0, 0.95))
        set_colour(ob, guesses[ob.name])
    return guesses


def set_colour(ob, colour):
    """The stand-in's base colour: its Principled BSDF's, else its diffuse BSDF's."""
    for node in ob.active_material.node_tree.nodes:
        if node.type in ("BSDF_PRINCIPLED", "BSDF_DIFFUSE"):
            for link in list(node.inputs[0].links):
                ob.active_material.node_tree.links.remove(link)
            node.inputs[0].default_value = (*colour, 1.0)


def composite(combined, shadow_catcher, plate):
    """Blender's manual's catcher composite: the CG (premultiplied) over plate x Shadow Catcher."""
    alpha = combined[..., 3:4]
    return combined[..., :3] + (1.0 - alpha) * plate * shadow_catcher[..., :3]
