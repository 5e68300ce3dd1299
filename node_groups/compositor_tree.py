"""The scene's compositor tree "PlateLight Composite": the plate, the render layers and the
"PlateLight Differential" group (node_groups/composite.py) wired to the output; the grain image
that platelight.match_grain made, wired into the group; and the File Output of the passes.
Rebuilt in place by platelight.setup_composite (operators/composite/)."""
import bpy

from .. import compat
from ..addon import names
from ..addon.compositing.baked_shadows import CATCHER_ALBEDO
from .composite import build_differential_group
from .redistortion import wire_redistortion

# A raw 1 of a shadow pass stays raw (the plate exact) only where the denoised estimate finds less
# shadow than this: a pixel of a soft shadow's fringe that no sample tied to the CG stays a
# speckle kept raw (docs/decisions.md, "Denoise only what is noisy")
SHADOW_KEPT_WITHIN = 0.01
# ... and wherever no raw pixel within this many pixels differs from 1
SHADOW_CHANGE_REACH = 4


def build_compositor_tree(scene, plate_image, method, ratio_form, shadow_clamp, denoise_shadows,
                          denoise_cg):
    """The scene's compositor tree (rebuilt in place): plate + render layers -> group -> output.
    ``denoise_shadows``: OIDN on the shadow / local-scene passes; ``denoise_cg``: on the CG's
    fully covered pixels."""
    group = build_differential_group()
    tree = compat.new_compositor_tree(scene, names.COMPOSITOR_TREE)
    nodes, links = tree.nodes, tree.links

    plate = nodes.new("CompositorNodeImage")
    plate.name = plate.label = "Plate"
    plate.image = plate_image
    plate.location = (-600, 300)
    if plate_image.source in {"SEQUENCE", "MOVIE"}:
        plate.frame_duration = max(1, scene.frame_end - scene.frame_start + 1)
        plate.frame_start = scene.frame_start
        plate.frame_offset = int(plate_image.get(names.PLATE_FRAME_OFFSET_KEY, 0))
        plate.use_auto_refresh = True
    diff = nodes.new("CompositorNodeGroup")
    diff.name = diff.label = names.DIFFERENTIAL_GROUP
    diff.node_tree = group
    diff.location = (0, 0)
    diff.inputs["Ratio Form"].default_value = 1.0 if ratio_form else 0.0
    diff.inputs["Shadow Clamp"].default_value = shadow_clamp
    links.new(plate.outputs["Image"], diff.inputs["Plate"])

    cg = nodes.new("CompositorNodeRLayers")
    cg.name = cg.label = names.LAYER_CG
    cg.scene = scene
    cg.layer = names.LAYER_CG
    cg.location = (-600, 0)

    def on_every_channel(socket_a, socket_b_or_value, location, operation="COMPARE"):
        """A factor that is 1 where every RGB channel of a equals b (a socket or a number), or
        with ``operation="GREATER_THAN"`` exceeds it."""
        x, y = location
        sep_a = nodes.new("CompositorNodeSeparateColor")
        sep_a.location = (x, y)
        links.new(socket_a, sep_a.inputs["Image"])
        sep_b = None
        if isinstance(socket_b_or_value, bpy.types.NodeSocket):
            sep_b = nodes.new("CompositorNodeSeparateColor")
            sep_b.location = (x, y - 150)
            links.new(socket_b_or_value, sep_b.inputs["Image"])
        result = None
        for k, channel in enumerate(("Red", "Green", "Blue")):
            cmp = compat.compositor_math(nodes, operation)
            cmp.location = (x + 150, y - 60 * k)
            links.new(sep_a.outputs[channel], cmp.inputs[0])
            if sep_b is not None:
                links.new(sep_b.outputs[channel], cmp.inputs[1])
            else:
                cmp.inputs[1].default_value = socket_b_or_value
            if operation == "COMPARE":
                cmp.inputs[2].default_value = 0.0
            if result is None:
                result = cmp.outputs[0]
            else:
                both = compat.compositor_math(nodes, "MULTIPLY")
                both.location = (x + 300, y - 60 * k)
                links.new(result, both.inputs[0])
                links.new(cmp.outputs[0], both.inputs[1])
                result = both.outputs[0]
        return result

    def denoised_unless(socket, keep_factor, location, normal=None, kept_within=None):
        """OIDN on ``socket``, except where ``keep_factor`` is 1: there the raw pixel is kept,
        so denoising never touches pixels the CG does not reach (the plate stays exact);
        ``kept_within``: only where the denoised pixel is within that of 1, too, or where no raw
        pixel within SHADOW_CHANGE_REACH differs from 1.
        ``normal``: a Denoising Normal pass to guide it, with the constant albedo Cycles' own
        denoiser gives a Shadow Catcher pass (CATCHER_ALBEDO); the guides are
        noise-free first hits, so not prefiltered."""
        x, y = location
        node = nodes.new("CompositorNodeDenoise")
        node.location = (x, y)
        links.new(socket, node.inputs["Image"])
        if normal is not None:
            # an image of the albedo, not a value: the node ignores a single-value albedo (and
            # then the normal too, as OIDN takes no normal without an albedo)
            albedo = compat.compositor_math(nodes, "MULTIPLY_ADD")
            albedo.location = (x - 200, y - 150)
            links.new(normal, albedo.inputs[0])
            albedo.inputs[1].default_value = 0.0
            albedo.inputs[2].default_value = CATCHER_ALBEDO
            links.new(albedo.outputs[0], node.inputs["Albedo"])
            links.new(normal, node.inputs["Normal"])
            compat.set_option(node, "Prefilter", "None")
        if kept_within is not None:
            trusted = on_every_channel(node.outputs["Image"], 1.0 - kept_within, (x, y - 300), "GREATER_THAN")
            # ... or no raw pixel within reach differs from 1: no shadow can be there (OIDN strayed
            # by up to 0.2 near the frame's border, far from any shadow)
            unchanged = compat.compositor_erode(nodes, SHADOW_CHANGE_REACH)
            unchanged.location = (x, y - 500)
            links.new(keep_factor, unchanged.inputs["Mask"])
            either = compat.compositor_math(nodes, "MAXIMUM")
            either.location = (x + 100, y - 400)
            links.new(trusted, either.inputs[0])
            links.new(unchanged.outputs["Mask"], either.inputs[1])
            both = compat.compositor_math(nodes, "MULTIPLY")
            both.location = (x + 100, y - 150)
            links.new(keep_factor, both.inputs[0])
            links.new(either.outputs[0], both.inputs[1])
            keep_factor = both.outputs[0]
        mix = compat.compositor_mix(nodes)
        mix.node.location = (x + 200, y)
        links.new(keep_factor, mix.factor)
        links.new(node.outputs["Image"], mix.a)
        links.new(socket, mix.b)
        return mix.result

    def caught(source, y):
        """``source``'s Shadow Catcher pass, denoised (where it is not 1) when asked, guided by the
        layer's Denoising Normal as Cycles' denoiser is."""
        catcher = source.outputs["Shadow Catcher"]
        if denoise_shadows:
            scene.view_layers[source.layer].cycles.denoising_store_passes = True
            catcher = denoised_unless(catcher, on_every_channel(catcher, 1.0, (-900, y)), (-300, y + 50),
                                      normal=source.outputs["Denoising Normal"], kept_within=SHADOW_KEPT_WITHIN)
        return catcher

    cg_image = cg.outputs["Image"]
    if denoise_cg:
        # Only where the CG covers the pixel: OIDN knows no alpha, so on an edge it mixed the
        # transparent black in and left a dark rim (measured at 4 spp: frame -0.3 to -0.8 dB).
        partly_covered = compat.compositor_math(nodes, "LESS_THAN")
        partly_covered.location = (-450, 150)
        links.new(cg.outputs["Alpha"], partly_covered.inputs[0])
        partly_covered.inputs[1].default_value = 1.0
        cg_image = denoised_unless(cg_image, partly_covered.outputs[0], (-300, 100))
    links.new(cg_image, diff.inputs["CG"])
    if method in ("CATCHER", "LAYERED"):
        source = cg
        if method == "LAYERED":              # the shadows from their own layer and samples
            source = _render_layer(nodes, scene, names.LAYER_SHADOWS, (-600, -300))
        links.new(caught(source, -250), diff.inputs["With"])
    elif method == "BAKED":
        # the phantoms emit the baked ratio; elsewhere (alpha 0: no phantom) the ratio is 1
        source = _render_layer(nodes, scene, names.LAYER_SHADOWS, (-600, -300))
        links.new(_covered_ratio(nodes, source.outputs["Image"], source.outputs["Alpha"], 1.0, (-400, -300)),
                  diff.inputs["With"])
    elif method == "MIXED":
        # the still CG's baked ratio times the moving CG's catcher ratio: where both shadows fall,
        # the light left is the product of what each leaves (exact for a sun's hard shadows)
        source = _render_layer(nodes, scene, names.LAYER_SHADOWS, (-600, -300))
        aov = source.outputs[names.BAKED_RATIO_AOV]
        weight = nodes.new("CompositorNodeSeparateColor")
        weight.location = (-450, -450)
        links.new(aov, weight.inputs["Image"])
        baked_ratio = _covered_ratio(nodes, aov, weight.outputs["Alpha"], CATCHER_AOV_WEIGHT, (-300, -300))
        catcher = caught(_render_layer(nodes, scene, names.LAYER_MOVING_SHADOWS, (-600, -700)), -650)
        product = compat.compositor_mix(nodes, blend="MULTIPLY")
        product.node.location = (-100, -400)
        product.factor.default_value = 1.0
        links.new(baked_ratio, product.a)
        links.new(catcher, product.b)
        links.new(product.result, diff.inputs["With"])
    else:
        local = {}
        for name, socket, y in ((names.LAYER_LOCAL, "With", -300), (names.LAYER_WITHOUT, "Without", -600)):
            local[socket] = _render_layer(nodes, scene, name, (-600, y)).outputs["Image"]
        if denoise_shadows:
            same = on_every_channel(local["With"], local["Without"], (-900, -450))
            local = {k: denoised_unless(v, same, (-300, -300 if k == "With" else -600)) for k, v in local.items()}
        for socket, value in local.items():
            links.new(value, diff.inputs[socket])
    out = compat.composite_output(tree)
    out.node.location = (400, 0)
    links.new(diff.outputs["Image"], out)
    scene.render.use_compositing = True
    wire_grain(scene, tree)      # grain matched earlier (platelight.match_grain) stays wired
    wire_redistortion(scene, tree)   # a calibrated lens: the layers land through the plate's lens
    return tree


# Cycles writes an AOV twice per sample on a shadow catcher (the paths with and without the
# other objects both shade it): measured on 4.5, 5.2 and 5.3, weight 2 where a catcher covers the pixel
CATCHER_AOV_WEIGHT = 2.0


def _render_layer(nodes, scene, name, location):
    """A Render Layers node of ``scene``'s view layer ``name``."""
    node = nodes.new("CompositorNodeRLayers")
    node.name = node.label = name
    node.scene = scene
    node.layer = name
    node.location = location
    return node


def _covered_ratio(nodes, ratio, weight, full_weight, location):
    """The shadow ratio of a layer whose phantoms give ``ratio`` times their coverage
    (``weight`` / ``full_weight``, premultiplied) and nothing elsewhere: ratio / full_weight plus
    1 where no phantom is (1 - weight / full_weight)."""
    x, y = location
    links = nodes.id_data.links
    uncovered = compat.compositor_math(nodes, "MULTIPLY_ADD")
    uncovered.location = (x, y - 150)
    links.new(weight, uncovered.inputs[0])
    uncovered.inputs[1].default_value = -1.0 / full_weight
    uncovered.inputs[2].default_value = 1.0
    scaled = ratio
    if full_weight != 1.0:
        scale = compat.compositor_mix(nodes, blend="MULTIPLY")
        scale.node.location = (x, y)
        scale.factor.default_value = 1.0
        links.new(ratio, scale.a)
        scale.b.default_value = (1.0 / full_weight,) * 3 + (1.0,)
        scaled = scale.result
    total = compat.compositor_mix(nodes, blend="ADD")
    total.node.location = (x + 200, y)
    total.factor.default_value = 1.0
    links.new(scaled, total.a)
    links.new(uncovered.outputs[0], total.b)
    return total.result


def differential_node(scene):
    tree = compat.compositor_tree(scene)
    if tree is None:
        return None
    node = tree.nodes.get(names.DIFFERENTIAL_GROUP)
    if node is None or node.bl_idname != "CompositorNodeGroup" or node.node_tree is None:
        return None
    return node


def wire_grain(scene, tree=None):
    """Connect the grain image (if match_grain made one) to the Differential group of ``tree``
    (the scene's compositor tree) with its stored settings. Returns the image node or None."""
    image = bpy.data.images.get(names.GRAIN_IMAGE)
    settings = image.get(names.GRAIN_SETTINGS_KEY) if image is not None else None
    tree = tree or compat.compositor_tree(scene)
    diff = tree.nodes.get(names.DIFFERENTIAL_GROUP) if tree is not None else None
    if settings is None or diff is None:
        return None
    node = tree.nodes.get(names.GRAIN_NODE)
    if node is None or node.bl_idname != "CompositorNodeImage":
        node = tree.nodes.new("CompositorNodeImage")
        node.name = node.label = names.GRAIN_NODE
    node.location = (diff.location.x - 600, diff.location.y + 400)
    node.image = image
    if image.source == "SEQUENCE":
        # files are numbered by scene frame: file number = (frame - start + 1) + offset = frame
        node.frame_start = scene.frame_start
        node.frame_offset = scene.frame_start - 1
        node.frame_duration = max(1, scene.frame_end - scene.frame_start + 1)
        node.use_auto_refresh = True
    tree.links.new(node.outputs["Image"], diff.inputs["Grain"])
    diff.inputs["Grain Amount"].default_value = float(settings["amount"])
    diff.inputs["Grain Level"].default_value = (*settings["level"], 1.0)
    diff.inputs["Grain Response"].default_value = (*settings["response"], 1.0)
    return node


def float_exr_file_output(tree, name, directory, inputs, location):
    """The File Output node ``name`` of ``tree`` (made or reused) writing one float32 RGBA EXR per
    input name into ``directory`` (compat.file_output_path names the files)."""
    node = tree.nodes.get(name) or tree.nodes.new("CompositorNodeOutputFile")
    node.name = node.label = name
    node.location = location
    compat.set_still_image(node.format)
    node.format.file_format = "OPEN_EXR"
    node.format.color_depth = "32"
    node.format.color_mode = "RGBA"
    compat.set_file_output(node, directory, inputs)
    return node


def add_pass_outputs(scene, directory):
    """Also write the group's CG and Shadows outputs and the plate as float EXRs into ``directory``
    (one file per pass; pass_output_path says which); used by the demo and the tests."""
    tree = compat.compositor_tree(scene)
    diff = tree.nodes[names.DIFFERENTIAL_GROUP]
    node = float_exr_file_output(tree, names.PASSES_NODE, directory, ("CG", "Shadows", "Plate"), (400, -300))
    tree.links.new(diff.outputs["CG"], node.inputs["CG"])
    tree.links.new(diff.outputs["Shadows"], node.inputs["Shadows"])
    tree.links.new(tree.nodes["Plate"].outputs["Image"], node.inputs["Plate"])
    return node


def pass_output_path(scene, directory, name):
    """The file add_pass_outputs' pass ``name`` ("CG", "Shadows", "Plate") is written to when the
    scene's current frame is rendered."""
    return compat.file_output_path(directory, name, scene.frame_current)
