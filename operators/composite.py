"""bpy.ops.platelight.setup_composite(): the view layers and the compositor tree that put the CG
objects into the plate by differential rendering.

Objects are sorted into two collections: "PlateLight Phantoms" (object.platelight.phantom: stand-ins
for real things) and "PlateLight CG" (every other renderable object). Two methods:

- CATCHER (default, one render per frame): phantoms are Cycles shadow catchers. They hide CG
  behind them (a catcher is transparent in the render and occludes what is behind it), and the
  Shadow Catcher pass is the ratio (with CG)/(without CG) of the light they receive: shadows,
  reflections and colour bleeding in one pass. The ratio form with Without = 1.
- DIFFERENTIAL (Debevec 1998, three renders): "PlateLight CG" renders the CG with phantoms as
  holdouts; "PlateLight Local" renders the phantoms with the CG indirect-only (they cast shadows
  and light, unseen); "PlateLight Local Without" renders the phantoms alone. Ratio or additive.

Either way the phantoms are lit by whatever lights the scene: the world probe (path-traced, the
reference) or lamps made by platelight.lights_from_probe (sharp sun shadows; in Cycles not
faster than the world at equal error, docs/bench/composite.md).
The plate passes unchanged: Standard view transform, no look, exposure 0, gamma 1.
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty

from .. import compat
from ..node_groups.composite import build_differential_group
from .common import PLATE_FRAME_OFFSET_KEY, find_plate_image

TREE_NAME = "PlateLight Composite"
CG_COLLECTION = "PlateLight CG"
PHANTOM_COLLECTION = "PlateLight Phantoms"
LAYER_CG = "PlateLight CG"
LAYER_LOCAL = "PlateLight Local"
LAYER_WITHOUT = "PlateLight Local Without"
RENDERABLE = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME"}


def classify_objects(scene):
    """(cg, phantoms): renderable objects of the scene, split by object.platelight.phantom."""
    cg, phantoms = [], []
    for ob in scene.objects:
        if ob.type not in RENDERABLE or ob.hide_render:
            continue
        (phantoms if ob.platelight.phantom else cg).append(ob)
    return cg, phantoms


def _collection(scene, name):
    coll = bpy.data.collections.get(name)
    if coll is None:
        coll = bpy.data.collections.new(name)
    if coll.name not in scene.collection.children:
        scene.collection.children.link(coll)
    return coll


def _move_into(objects, coll):
    """Make ``coll`` the only collection of each object (so view layers can switch them)."""
    for ob in objects:
        if coll not in ob.users_collection:
            coll.objects.link(ob)
        for other in list(ob.users_collection):
            if other != coll:
                other.objects.unlink(ob)


def _view_layer(scene, name):
    layer = scene.view_layers.get(name) or scene.view_layers.new(name)
    layer.use = True
    return layer


def _layer_collection(layer, coll):
    for child in layer.layer_collection.children:
        if child.collection == coll:
            return child
    raise RuntimeError(f"collection {coll.name} is not in view layer {layer.name}")


def _configure_layer(layer, cg_coll, phantom_coll, cg_state, phantom_holdout):
    cg = _layer_collection(layer, cg_coll)
    cg.exclude = cg_state == "excluded"
    if not cg.exclude:
        cg.indirect_only = cg_state == "indirect"
        cg.holdout = False
    ph = _layer_collection(layer, phantom_coll)
    ph.exclude = False
    ph.holdout = phantom_holdout
    ph.indirect_only = False
    # other collections stay as they are: after the move they hold only lights, cameras,
    # empties and objects hidden from render, and the lights must keep lighting every layer


def build_compositor_tree(scene, plate_image, method, ratio_form, shadow_clamp, denoise_shadows):
    """The scene's compositor tree (rebuilt in place): plate + render layers -> group -> output."""
    group = build_differential_group()
    tree = compat.new_compositor_tree(scene, TREE_NAME)
    nodes, links = tree.nodes, tree.links

    plate = nodes.new("CompositorNodeImage")
    plate.name = plate.label = "Plate"
    plate.image = plate_image
    plate.location = (-600, 300)
    if plate_image.source in {"SEQUENCE", "MOVIE"}:
        plate.frame_duration = max(1, scene.frame_end - scene.frame_start + 1)
        plate.frame_start = scene.frame_start
        plate.frame_offset = int(plate_image.get(PLATE_FRAME_OFFSET_KEY, 0))
        plate.use_auto_refresh = True
    diff = nodes.new("CompositorNodeGroup")
    diff.name = diff.label = "PlateLight Differential"
    diff.node_tree = group
    diff.location = (0, 0)
    diff.inputs["Ratio Form"].default_value = 1.0 if ratio_form else 0.0
    diff.inputs["Shadow Clamp"].default_value = shadow_clamp
    links.new(plate.outputs["Image"], diff.inputs["Plate"])

    cg = nodes.new("CompositorNodeRLayers")
    cg.name = cg.label = LAYER_CG
    cg.scene = scene
    cg.layer = LAYER_CG
    cg.location = (-600, 0)

    def equal_everywhere(socket_a, socket_b_or_value, location):
        """A factor that is 1 where all RGB channels of a equal b (a socket or a number)."""
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
            cmp = compat.compositor_math(nodes, "COMPARE")
            cmp.location = (x + 150, y - 60 * k)
            links.new(sep_a.outputs[channel], cmp.inputs[0])
            if sep_b is not None:
                links.new(sep_b.outputs[channel], cmp.inputs[1])
            else:
                cmp.inputs[1].default_value = socket_b_or_value
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

    def denoised_unless(socket, keep_factor, location):
        """OIDN on ``socket``, except where ``keep_factor`` is 1: there the raw pixel is kept,
        so denoising never touches pixels the CG does not reach (the plate stays exact)."""
        x, y = location
        node = nodes.new("CompositorNodeDenoise")
        node.location = (x, y)
        links.new(socket, node.inputs["Image"])
        mix = compat.compositor_mix(nodes)
        mix.node.location = (x + 200, y)
        links.new(keep_factor, mix.factor)
        links.new(node.outputs["Image"], mix.a)
        links.new(socket, mix.b)
        return mix.result

    cg_image = cg.outputs["Image"]
    if denoise_shadows:
        alpha_zero = compat.compositor_math(nodes, "COMPARE")
        alpha_zero.location = (-450, 150)
        links.new(cg.outputs["Alpha"], alpha_zero.inputs[0])
        alpha_zero.inputs[1].default_value = 0.0
        alpha_zero.inputs[2].default_value = 0.0
        cg_image = denoised_unless(cg_image, alpha_zero.outputs[0], (-300, 100))
    links.new(cg_image, diff.inputs["CG"])
    if method == "CATCHER":
        catcher = cg.outputs["Shadow Catcher"]
        if denoise_shadows:
            catcher = denoised_unless(catcher, equal_everywhere(catcher, 1.0, (-900, -250)), (-300, -200))
        links.new(catcher, diff.inputs["With"])
    else:
        local = {}
        for name, socket, y in ((LAYER_LOCAL, "With", -300), (LAYER_WITHOUT, "Without", -600)):
            node = nodes.new("CompositorNodeRLayers")
            node.name = node.label = name
            node.scene = scene
            node.layer = name
            node.location = (-600, y)
            local[socket] = node.outputs["Image"]
        if denoise_shadows:
            same = equal_everywhere(local["With"], local["Without"], (-900, -450))
            local = {k: denoised_unless(v, same, (-300, -300 if k == "With" else -600)) for k, v in local.items()}
        for socket, value in local.items():
            links.new(value, diff.inputs[socket])
    out = compat.composite_output(tree)
    out.node.location = (400, 0)
    links.new(diff.outputs["Image"], out)
    scene.render.use_compositing = True
    from .grain import wire_grain  # grain matched earlier (platelight.match_grain) stays wired

    wire_grain(scene, tree)
    return tree


def set_plate_colour_management(scene):
    """Plates pass through unchanged: no view transform, look, exposure or gamma."""
    view = scene.view_settings
    view.view_transform = "Standard"
    view.look = "None"
    view.exposure = 0.0
    view.gamma = 1.0
    view.use_curve_mapping = False
    scene.render.dither_intensity = 0.0  # dither noise would change 8-bit plates
    scene.sequencer_colorspace_settings.name = "Linear Rec.709"


class PLATELIGHT_OT_setup_composite(bpy.types.Operator):
    """Build the view layers and compositor tree that composite the CG objects onto the plate
    (differential rendering: shadows and reflections on phantoms, occlusion by phantoms)"""

    bl_idname = "platelight.setup_composite"
    bl_label = "Set Up Composite"
    bl_options = {"REGISTER", "UNDO"}

    method: EnumProperty(
        name="Method",
        items=(
            ("CATCHER", "Shadow Catcher", "One render: phantoms are shadow catchers; the catcher pass "
             "is the with/without ratio (fast)"),
            ("DIFFERENTIAL", "Differential", "Debevec's three renders: CG, local scene with CG and "
             "without CG (additive or ratio form)"),
        ),
        default="CATCHER",
    )
    ratio_form: BoolProperty(
        name="Ratio Form",
        description="Plate × With/Without (shadows darken the plate in proportion); off: the additive "
        "form Plate + With − Without",
        default=True,
    )
    shadow_clamp: FloatProperty(
        name="Shadow Clamp",
        description="Largest brightening factor the ratio may apply (limits noise where the local "
        "scene is dark)",
        default=4.0, min=1.0, max=1000.0,
    )
    denoise_shadows: BoolProperty(
        name="Denoise",
        description="Run OpenImageDenoise on the CG and on the shadow/local-scene passes before "
        "dividing (smooth at few samples); pixels the CG does not reach keep their raw, exact values",
        default=False,
    )
    samples: IntProperty(
        name="Samples",
        description="Cycles samples per pixel (0 keeps the scene's setting)",
        default=0, min=0, max=1 << 20,
    )

    @classmethod
    def poll(cls, context):
        scene = context.scene
        if scene is None or scene.camera is None:
            cls.poll_message_set("The scene needs a camera (set up the plate and track it first)")
            return False
        return True

    def execute(self, context):
        scene = context.scene
        # --- check everything before changing anything: a failed run leaves the scene as it was
        if scene.camera is None:
            self.report({"ERROR"}, "The scene has no camera; set up the plate and its camera first.")
            return {"CANCELLED"}
        plate_image = find_plate_image(scene)
        if plate_image is None:
            self.report({"ERROR"}, "No plate found; run Set Up Plate (platelight.setup_plate) first.")
            return {"CANCELLED"}
        cg, phantoms = classify_objects(scene)
        if not cg:
            self.report({"ERROR"}, "There are no CG objects to composite: every renderable object "
                        "is a phantom or hidden from render.")
            return {"CANCELLED"}

        # --- build
        scene.render.engine = "CYCLES"
        scene.render.film_transparent = True
        if self.samples:
            scene.cycles.samples = self.samples
        # The render's own denoiser and adaptive sampling change every pixel differently in each
        # layer, so With/Without would no longer cancel where the CG does not reach (measured:
        # ±3-7 % speckle over the whole plate at 16 spp). Denoise in the compositor instead.
        scene.cycles.use_denoising = False
        scene.cycles.use_adaptive_sampling = False
        set_plate_colour_management(scene)
        cg_coll = _collection(scene, CG_COLLECTION)
        phantom_coll = _collection(scene, PHANTOM_COLLECTION)
        _move_into(cg, cg_coll)
        _move_into(phantoms, phantom_coll)
        for ob in cg:
            ob.is_shadow_catcher = False
            ob.is_holdout = False
        for ob in phantoms:
            ob.is_shadow_catcher = self.method == "CATCHER"
            ob.is_holdout = False

        ours = {LAYER_CG} if self.method == "CATCHER" else {LAYER_CG, LAYER_LOCAL, LAYER_WITHOUT}
        for layer in scene.view_layers:
            if layer.name not in ours:
                layer.use = False
        cg_layer = _view_layer(scene, LAYER_CG)
        cg_layer.cycles.use_pass_shadow_catcher = self.method == "CATCHER"
        _configure_layer(cg_layer, cg_coll, phantom_coll, "visible", self.method != "CATCHER")
        if self.method == "DIFFERENTIAL":
            _configure_layer(_view_layer(scene, LAYER_LOCAL), cg_coll, phantom_coll, "indirect", False)
            _configure_layer(_view_layer(scene, LAYER_WITHOUT), cg_coll, phantom_coll, "excluded", False)
        else:
            for name in (LAYER_LOCAL, LAYER_WITHOUT):
                if name in scene.view_layers:
                    scene.view_layers[name].use = False
        if context.window is not None:
            context.window.view_layer = cg_layer
        build_compositor_tree(scene, plate_image, self.method, self.ratio_form, self.shadow_clamp,
                              self.denoise_shadows)

        if not phantoms:
            self.report({"WARNING"}, f"Composite set up for {len(cg)} CG object(s), but there are no "
                        "phantoms: the CG casts no shadows and nothing real hides it (mark stand-ins "
                        "for real surfaces as Phantom).")
        else:
            self.report({"INFO"}, f"Composite set up ({self.method.lower()}): {len(cg)} CG object(s), "
                        f"{len(phantoms)} phantom(s), plate '{plate_image.name}'.")
        return {"FINISHED"}


classes = (PLATELIGHT_OT_setup_composite,)


def add_pass_outputs(scene, directory):
    """Also write the group's CG and Shadows outputs and the plate as float EXRs into ``directory``
    (one file per pass; pass_output_path says which); used by the demo and the tests."""
    tree = compat.compositor_tree(scene)
    diff = tree.nodes["PlateLight Differential"]
    node = tree.nodes.get("PlateLight Passes") or tree.nodes.new("CompositorNodeOutputFile")
    node.name = node.label = "PlateLight Passes"
    node.location = (400, -300)
    compat.set_still_image(node.format)
    node.format.file_format = "OPEN_EXR"
    node.format.color_depth = "32"
    node.format.color_mode = "RGBA"
    compat.set_file_output(node, directory, ("CG", "Shadows", "Plate"))
    tree.links.new(diff.outputs["CG"], node.inputs["CG"])
    tree.links.new(diff.outputs["Shadows"], node.inputs["Shadows"])
    tree.links.new(tree.nodes["Plate"].outputs["Image"], node.inputs["Plate"])
    return node


def pass_output_path(scene, directory, name):
    """The file add_pass_outputs' pass ``name`` ("CG", "Shadows", "Plate") is written to when the
    scene's current frame is rendered."""
    return compat.file_output_path(directory, name, scene.frame_current)
