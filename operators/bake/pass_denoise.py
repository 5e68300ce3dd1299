"""A render pass denoised by the compositor's Denoise node (OpenImageDenoise), in a temporary
scene of its own: the user's compositor is never touched (on 4.5 it is the scene's own
tree). The shadow bake's catcher render uses it so that OIDN runs on the Shadow Catcher pass only,
where Cycles' denoiser also runs on Combined and the catcher matte (docs/decisions.md).

The temporary scene's compositor holds Image nodes only (the pass and its guides, as images of
their own: only the rows given, where the compositor would denoise the whole EXR), no Render
Layers node, so rendering it renders no view layer and needs no camera; the scene, its tree and
the images are removed after."""
from __future__ import annotations

import os

import bpy
import numpy as np

from ... import compat
from ...addon import names
from ...addon.compositing.baked_shadows import CATCHER_ALBEDO
from ...addon.errors import PlateLightError
from ...addon.exr_io import read_exr

# Cycles' enum identifiers -> the Denoise node's item names.
_QUALITY = {"HIGH": "High", "BALANCED": "Balanced", "FAST": "Fast"}


def available() -> bool:
    """Can this Blender denoise in the compositor (built with OpenImageDenoise)?"""
    try:
        import _cycles
    except ImportError:
        return False
    return bool(getattr(_cycles, "with_openimagedenoise", False)) and \
        hasattr(bpy.types, "CompositorNodeDenoise")


def denoise_pass(image, normal, cycles, out_path):
    """``image`` (H, W, 3, a Shadow Catcher pass; the first row the top) denoised as Cycles'
    settings ``cycles`` (a scene's ``.cycles``) ask: their quality and guides (``normal``, the
    Denoising Normal pass, when the input passes name it; the constant albedo when they name
    albedo); float32 (H, W, 3), also written to ``out_path``.

    The guides are never prefiltered, whatever the scene's prefilter: a constant albedo and the
    first-hit normal of the phantoms have no noise to take out. Cycles' default (Accurate) ran OIDN
    twice more for the same ratio (shadow PSNR 43.4700 against 43.4701 at 512 x 16; denoise 4.0
    against 1.3 s; docs/decisions.md, "The shadow bake's diffuse bounces, its guides unfiltered")."""
    height, width = image.shape[:2]
    scene = bpy.data.scenes.new(names.PASS_DENOISE)
    images = []

    def source(pixels):
        block = bpy.data.images.new(names.PASS_DENOISE, width, height, float_buffer=True)
        images.append(block)
        block.colorspace_settings.is_data = True          # the values as they are
        rgba = np.ones((height, width, 4), dtype=np.float32)
        rgba[..., :3] = pixels
        # Blender's first row is the bottom
        block.pixels.foreach_set(np.ascontiguousarray(rgba[::-1]).ravel())
        node = tree.nodes.new("CompositorNodeImage")
        node.image = block
        return node.outputs["Image"]

    try:
        tree = compat.new_compositor_tree(scene, names.PASS_DENOISE)
        denoise = tree.nodes.new("CompositorNodeDenoise")
        compat.set_option(denoise, "Prefilter", "None")
        compat.set_option(denoise, "Quality", _QUALITY[cycles.denoising_quality])
        compat.set_option(denoise, "HDR", True)
        tree.links.new(source(image), denoise.inputs["Image"])
        # an image, not the input's value: the node ignores a single-value albedo, and with it the
        # normal (OIDN takes no normal without an albedo)
        if "ALBEDO" in cycles.denoising_input_passes:
            tree.links.new(source(CATCHER_ALBEDO), denoise.inputs["Albedo"])
        if "NORMAL" in cycles.denoising_input_passes:
            tree.links.new(source(normal), denoise.inputs["Normal"])
        tree.links.new(denoise.outputs[0], compat.composite_output(tree))
        render = scene.render
        render.resolution_x, render.resolution_y, render.resolution_percentage = width, height, 100
        render.use_compositing, render.use_sequencer = True, False
        render.filepath = out_path
        fmt = render.image_settings
        compat.set_still_image(fmt)
        fmt.file_format, fmt.color_mode, fmt.color_depth = "OPEN_EXR", "RGB", "32"
        try:
            bpy.ops.render.render(write_still=True, scene=scene.name)
        except RuntimeError as exc:
            raise PlateLightError(f"The compositor could not denoise the shadow catcher pass "
                                  f"({str(exc).strip() or 'unknown error'}); bake with Cycles as the "
                                  "denoiser.") from None
        if not os.path.isfile(out_path):
            raise PlateLightError("The compositor wrote no denoised shadow catcher pass; bake with Cycles "
                                  "as the denoiser.")
        return read_exr(out_path, "RGB")
    finally:
        compat.remove_compositor_tree(scene)
        bpy.data.scenes.remove(scene)
        for block in images:
            bpy.data.images.remove(block)
