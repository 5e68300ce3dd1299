"""bpy.ops.platelight.setup_composite(): the view layers and the compositor tree that put the CG
objects into the plate by differential rendering.

Objects are sorted into two collections: "PlateLight Phantoms" (object.platelight.phantom: stand-ins
for real things) and "PlateLight CG" (every other renderable object). The methods (AUTO, the
default, takes BAKED when the shot's shadows are baked and current and no CG object or phantom
moves or deforms during the shot (operators/motion.py), else CATCHER):

- CATCHER (one render per frame): phantoms are Cycles shadow catchers. They hide CG
  behind them (a catcher is transparent in the render and occludes what is behind it), and the
  Shadow Catcher pass is the ratio (with CG)/(without CG) of the light they receive: shadows,
  reflections and colour bleeding in one pass. The ratio form with Without = 1.
- DIFFERENTIAL (Debevec 1998, three renders): "PlateLight CG" renders the CG with phantoms as
  holdouts; "PlateLight Local" renders the phantoms with the CG indirect-only (they cast shadows
  and light, unseen); "PlateLight Local Without" renders the phantoms alone. Ratio or additive.
- LAYERED: the CG alone at CG Samples, the shadows in a catcher layer at the scene's samples.
- BAKED: the CG at CG Samples, and the phantoms showing the shot's shadows baked once by
  platelight.bake_shadows (operators/baked_shadows.py): no path-traced shadow per frame.

Either way the phantoms are lit by whatever lights the scene: the world probe (path-traced, the
reference) or lamps made by platelight.lights_from_probe (sharp sun shadows; in Cycles not
faster than the world at equal error, docs/bench/composite.md).
The plate passes unchanged: Standard view transform, no look, exposure 0, gamma 1.
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty

from .. import compat
from ..addon import names
from ..node_groups.compositor_tree import build_compositor_tree
from ..node_groups import ray_twin
from ..node_groups.sbrdf_material import is_metal, sbrdf_node, shaded_by_sbrdf
from .bake.inputs import wants_sharp_probe
from . import motion
from .baked_shadows import baked_is_current
from .common import classify_objects, find_plate_image, set_plate_colour_management
from .eevee_check import NO_GL_SENTENCE, eevee_available
from .phantoms import apply_phantom_surfaces


def smooth_without_denoiser(ob) -> bool:
    """Is ``ob``'s image smooth at a few samples? An SBRDF object without a sharp reflection shows
    blurred probe look-ups only: OIDN on it gained nothing and darkened its edges (docs/decisions.md).
    A sharp reflection's sub-pixel detail, and a path-traced object's noise, it does smooth."""
    return shaded_by_sbrdf(ob) and not wants_sharp_probe(ob)


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
        # EEVEE has no indirect-only: a held-out CG still casts its shadows there and the
        # pixels it covers are the CG layer's anyway (alpha 1)
        cg.holdout = cg_state == "holdout"
    ph = _layer_collection(layer, phantom_coll)
    ph.exclude = False
    ph.holdout = phantom_holdout
    ph.indirect_only = False
    # the phantoms' plate material gives camera rays a holdout without shading itself there
    layer[names.HELD_OUT_PHANTOMS_KEY] = 1.0 if phantom_holdout else 0.0
    # other collections stay as they are: after the move they hold only lights, cameras,
    # empties and objects hidden from render, and the lights must keep lighting every layer


def configure_eevee(scene):
    """EEVEE's differential route: the world's sun becomes a shadow-casting light (EEVEE's sun
    extraction), shadows and ray tracing on, so phantoms get the CG's shadows."""
    scene.eevee.use_shadows = True
    scene.eevee.use_raytracing = True
    world = scene.world
    if world is not None:
        world.use_sun_shadow = True
        world.sun_threshold = min(world.sun_threshold, 10.0)


# What Cycles' camera sees of an SBRDF metal. Path-traced, the metal over the same baked shadows
# reached the catcher's object PSNR 4.1-4.4x sooner at 960x540 at 4 CG samples (mirror, glossy,
# anisotropic and rough metal; 6.9-9.5x at the automatic 64 with adaptive sampling), where its SBRDF stopped at 38.2 dB (glossy copper; the catcher 42.2) or matched it
# at the same samples at more cost a sample (mirror): anti-aliasing, not shading, sets a metal's
# cost (docs/decisions.md, "Metals path-traced, the SBRDF for the rest")
METAL_SHADINGS = (("PATH_TRACED", "Path-Traced", "The Principled material the SBRDF was converted from "
                   "(its twin), path-traced and denoised: the more accurate at equal time"),
                  ("SBRDF", "SBRDF", "The paper's probe-shaded SBRDF, noise-free at one sample"))
DEFAULT_METAL_SHADING = "PATH_TRACED"


def set_camera_shading(objects, engine, metals):
    """Give the camera each SBRDF material's SBRDF, or its path-traced twin where ``metals`` asks
    for that of a metal in Cycles."""
    for material in {slot.material for ob in objects for slot in ob.material_slots}:
        if sbrdf_node(material) is not None and ray_twin.has_ray_split(material):
            twin = engine == "CYCLES" and metals == "PATH_TRACED" and is_metal(material)
            ray_twin.set_camera_sees_sbrdf(material, not twin)


# The CG layer's automatic samples (Layered and Baked Shadows). Noise-free SBRDF objects need
# only their edges anti-aliased; in Cycles a path-traced one (or an SBRDF's sharp reflection)
# converges: at 960x540 a path-traced mirror gave 42.0 dB at 16 samples, 42.8 at 32, 43.3 at 64
# (the catcher's at 64), adaptive sampling stopping the clean pixels (docs/decisions.md,
# "Adaptive sampling, and the CG layer's samples")
SMOOTH_CG_SAMPLES, PATH_TRACED_CG_SAMPLES = 4, 64
# Adaptive sampling's first check. Cycles' automatic minimum (0) saved nothing at 64 samples
# (9.18 s against 9.16 off); 2, 4 and 8 gave the same image in 5.2-5.3 s
# (docs/bench/cg_layer_mirror_960x540.md)
ADAPTIVE_MIN_SAMPLES = 4
# With the filmed phantoms a path ends on an emitter where it used to go on and be clamped as
# indirect light (Cycles' default clamp, 10): a rare sample of enormous weight off a path-traced
# metal then counts as direct light, unclamped (one 7.6e5 sample in a 256-sample glossy copper
# frame, spread by the denoiser into a 31.7 dB object against 43.6). Direct light is clamped here,
# unless the scene clamps it harder; the sun's own reflection in a mirror (4000 under the
# benchmark's HDRI) stays far above white (docs/decisions.md, "Filmed phantoms")
FILMED_CLAMP_DIRECT = 100.0


class PLATELIGHT_OT_setup_composite(bpy.types.Operator):
    """Build the view layers and compositor tree that composite the CG objects onto the plate
    (differential rendering: shadows and reflections on phantoms, occlusion by phantoms)"""

    bl_idname = "platelight.setup_composite"
    bl_label = "Set Up Composite"
    bl_options = {"REGISTER", "UNDO"}

    method: EnumProperty(
        name="Method",
        items=(
            ("AUTO", "Automatic", "Baked Shadows when the shot's shadows are baked, still fit the "
             "scene and nothing moves or deforms during the shot (the fastest route at equal error), "
             "else Shadow Catcher"),
            ("CATCHER", "Shadow Catcher", "One render: phantoms are shadow catchers; the catcher pass "
             "is the with/without ratio (fast)"),
            ("LAYERED", "Layered Catcher", "Two renders: the CG alone at CG Samples (noise-free "
             "SBRDF materials need few), the shadows on the catchers at Samples, denoised"),
            ("DIFFERENTIAL", "Differential", "Debevec's three renders: CG, local scene with CG and "
             "without CG (additive or ratio form)"),
            ("BAKED", "Baked Shadows", "Two cheap renders: the CG at CG Samples, and the phantoms "
             "showing the shot's shadows baked once by Bake Shadows (a still CG on matte phantoms, "
             "the camera free to move)"),
        ),
        default="AUTO",
    )
    engine: EnumProperty(
        name="Engine",
        items=(("CYCLES", "Cycles", "Path-traced shadows (shadow catchers)"),
               ("EEVEE", "EEVEE", "Rasterised (EEVEE has no shadow catcher): with the shot's "
                "shadows baked (Bake Shadows), two emission-only renders showing them; else "
                "differential rendering, three renders with shadows from EEVEE's shadow maps and "
                "the world's sun extracted as a shadow-casting light")),
        default="CYCLES",
    )
    cg_samples: IntProperty(
        name="CG Samples",
        description="Samples of the CG layer in the Layered and Baked Shadows methods (0: "
        "automatic: 4 where every CG object is a noise-free SBRDF, which only its edges need, 64 "
        "where one is path-traced; Cycles' adaptive sampling stops every pixel once it is clean)",
        default=0, min=0, max=1 << 20,
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
        description="Run OpenImageDenoise on the shadow/local-scene passes before dividing (smooth "
        "at few samples), and on the CG's inside where a CG object is path-traced or shows a sharp "
        "reflection (other SBRDF materials are smooth: denoising only darkened their edges); pixels "
        "the CG does not reach keep their raw, exact values",
        default=True,
    )
    baked_samples: IntProperty(
        name="Baked Shadow Samples",
        description="Samples of the layer showing the baked shadows (Baked Shadows method): the "
        "bake is noise-free, so one per pixel serves; raise it to anti-alias a shadow that crosses "
        "a phantom's outline",
        default=1, min=1, max=1 << 20,
    )
    samples: IntProperty(
        name="Samples",
        description="Cycles samples per pixel (0 keeps the scene's setting)",
        default=0, min=0, max=1 << 20,
    )
    metals: EnumProperty(
        name="Metals",
        description="What the camera sees of an SBRDF metal in Cycles (EEVEE always shows the SBRDF)",
        items=METAL_SHADINGS,
        default=DEFAULT_METAL_SHADING,
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
        baked = bpy.data.materials.get(names.BAKED_SHADOW_MATERIAL)
        if self.method == "BAKED" and baked is None:
            self.report({"ERROR"}, "The Baked Shadows method needs the shot's shadows: run Bake "
                        "Shadows (platelight.bake_shadows) first.")
            return {"CANCELLED"}

        if self.engine == "EEVEE" and scene.render.use_motion_blur:
            self.report({"ERROR"}, "EEVEE's composite does not blur the shadows with the CG: turn "
                        "Motion Blur off (Render Properties) or use Cycles, which blurs both.")
            return {"CANCELLED"}
        # a shadow baked once cannot follow what moves: asked only where a bake could be used
        moving = motion.motions(scene, cg + phantoms) if baked is not None and self.method in ("AUTO", "BAKED") else {}
        if self.method == "BAKED" and moving:
            self.report({"ERROR"}, f"{next(iter(moving.values())).sentence()}, and the shadows baked "
                        "once cannot follow it: use the Automatic or Shadow Catcher method.")
            return {"CANCELLED"}

        method = self.method
        current = None                  # does the shadow bake fit the scene (hashed once, when asked)
        if method == "AUTO":
            current = baked_is_current(scene) if baked is not None and not moving else None
            method = "BAKED" if current else "CATCHER"
            if moving:
                self.report({"WARNING"}, f"{next(iter(moving.values())).sentence()}: the Shadow "
                            "Catcher renders the shadows every frame instead of the baked ones.")
        if self.engine == "EEVEE":
            if not eevee_available():
                self.report({"WARNING"}, NO_GL_SENTENCE)
                engine = "CYCLES"
            else:
                engine = compat.EEVEE
                # Baked shadows are emission on the phantoms, which EEVEE renders exactly: the
                # shot's path-traced shadow instead of EEVEE's shadow maps (docs/decisions.md).
                # Without a current bake, or where EEVEE ignores the layer's material override
                # (4.5), Debevec's three layers.
                if method == "BAKED" and not compat.EEVEE_MATERIAL_OVERRIDE:
                    self.report({"WARNING"}, "EEVEE in this Blender cannot show the baked shadows "
                                "(it ignores a view layer's material override): it renders its own "
                                "shadows in three layers instead; Cycles or Blender 5 show them.")
                if method != "BAKED" or not compat.EEVEE_MATERIAL_OVERRIDE:
                    method = "DIFFERENTIAL"
        else:
            engine = "CYCLES"
        if current is False:
            # said once the engine is known: EEVEE has no shadow catcher (its three layers instead),
            # and a machine without GL falls back to Cycles' catcher
            fallback = "EEVEE renders its own" if engine == compat.EEVEE else "the Shadow Catcher renders them"
            self.report({"WARNING"}, "The baked shadows do not match the scene any more: "
                        f"{fallback} instead; run Bake Shadows again to use them.")

        # --- build
        scene.render.engine = engine
        scene.render.film_transparent = True
        # a shot renders many frames of one scene: sync it once (the probes already serve every
        # frame of a static shot from one bake)
        scene.render.use_persistent_data = True
        if self.samples:
            scene.cycles.samples = self.samples
            scene.eevee.taa_render_samples = self.samples
        # The render's own denoiser and adaptive sampling change every pixel differently in each
        # layer, so Differential's With/Without would no longer cancel where the CG does not reach
        # (measured: ±3-7 % speckle over the whole plate at 16 spp). Denoise in the compositor
        # instead. The other methods take no difference of two renders: adaptive sampling stops
        # the pixels that are clean (a path-traced mirror at 64 samples: 5.3 s a frame against 9.2)
        scene.cycles.use_denoising = False
        scene.cycles.use_adaptive_sampling = method != "DIFFERENTIAL"
        if scene.cycles.use_adaptive_sampling:
            scene.cycles.adaptive_min_samples = ADAPTIVE_MIN_SAMPLES
        set_plate_colour_management(scene)
        cg_coll = _collection(scene, names.CG_COLLECTION)
        phantom_coll = _collection(scene, names.PHANTOM_COLLECTION)
        _move_into(cg, cg_coll)
        _move_into(phantoms, phantom_coll)
        for ob in cg:
            ob.is_shadow_catcher = False
            ob.is_holdout = False
        for ob in phantoms:
            ob.is_shadow_catcher = method in ("CATCHER", "LAYERED")
            ob.is_holdout = False
        apply_phantom_surfaces(scene, phantoms)   # the plate on the phantoms (or their own materials)

        ours = {names.LAYER_CG, names.LAYER_LOCAL, names.LAYER_WITHOUT, names.LAYER_SHADOWS}
        for layer in scene.view_layers:
            if layer.name not in ours:
                layer.use = False
        cg_layer = _view_layer(scene, names.LAYER_CG)
        cg_layer.cycles.use_pass_shadow_catcher = method == "CATCHER"
        _configure_layer(cg_layer, cg_coll, phantom_coll, "visible", method != "CATCHER")
        # with baked shadows the CG's rays see the filmed plate, shadowed, on the phantoms
        # (node_groups/phantom_plate.py): no noise from path-tracing what the camera filmed
        cg_layer[names.FILMED_PHANTOMS_KEY] = 1.0 if method == "BAKED" else 0.0
        clamped = ""
        if method == "BAKED" and phantoms and not 0.0 < scene.cycles.sample_clamp_direct <= FILMED_CLAMP_DIRECT:
            before = scene.cycles.sample_clamp_direct
            scene.cycles.sample_clamp_direct = FILMED_CLAMP_DIRECT
            clamped = (f"; direct light clamped at {FILMED_CLAMP_DIRECT:g} (was "
                       f"{f'{before:g}' if before > 0 else 'off'}) against fireflies off the filmed phantoms")
        if method == "DIFFERENTIAL":
            local_cg = "holdout" if engine == compat.EEVEE else "indirect"
            _configure_layer(_view_layer(scene, names.LAYER_LOCAL), cg_coll, phantom_coll, local_cg, False)
            _configure_layer(_view_layer(scene, names.LAYER_WITHOUT), cg_coll, phantom_coll, "excluded", False)
        if method in ("LAYERED", "BAKED"):
            shadows = _view_layer(scene, names.LAYER_SHADOWS)
            shadows.cycles.use_pass_shadow_catcher = method == "LAYERED"
            if method == "LAYERED":
                shadows.samples = 0
                shadows.material_override = None
                _configure_layer(shadows, cg_coll, phantom_coll, "indirect", False)
            else:   # the phantoms emit the baked, noise-free ratio: one sample serves (measured)
                shadows.samples = self.baked_samples
                shadows.material_override = baked
                _configure_layer(shadows, cg_coll, phantom_coll, "excluded", False)
        used = {"CATCHER": {names.LAYER_CG}, "LAYERED": {names.LAYER_CG, names.LAYER_SHADOWS},
                "BAKED": {names.LAYER_CG, names.LAYER_SHADOWS},
                "DIFFERENTIAL": {names.LAYER_CG, names.LAYER_LOCAL, names.LAYER_WITHOUT}}[method]
        for name in (names.LAYER_LOCAL, names.LAYER_WITHOUT, names.LAYER_SHADOWS):
            if name in scene.view_layers and name not in used:
                scene.view_layers[name].use = False
        if engine == compat.EEVEE and method == "DIFFERENTIAL":
            configure_eevee(scene)
        if context.window is not None:
            context.window.view_layer = cg_layer
        set_camera_shading(cg, engine, self.metals)
        noisy = [ob for ob in cg if not smooth_without_denoiser(ob)]   # path-traced, or a sharp SBRDF
        # EEVEE's samples anti-alias a noise-free image: its SBRDF needs no more than the edges do
        converging = bool(noisy) and engine == "CYCLES"
        cg_samples = self.cg_samples or (PATH_TRACED_CG_SAMPLES if converging else SMOOTH_CG_SAMPLES)
        cg_layer.samples = cg_samples if method in ("LAYERED", "BAKED") else 0
        denoise_cg = self.denoise_shadows and bool(noisy)
        build_compositor_tree(scene, plate_image, method, self.ratio_form, self.shadow_clamp,
                              self.denoise_shadows, denoise_cg)

        if method == "BAKED":
            if current is None:         # BAKED asked for by name: not hashed yet
                current = baked_is_current(scene)
            if not current:
                self.report({"WARNING"}, "The baked shadows do not match the scene any more (an "
                            "object, the world or a setting changed): run Bake Shadows again.")
        if not phantoms:
            self.report({"WARNING"}, f"Composite set up for {len(cg)} CG object(s), but there are no "
                        "phantoms: the CG casts no shadows and nothing real hides it (mark stand-ins "
                        "for real surfaces as Phantom).")
        else:
            layer = f", the CG at {cg_samples} samples" if method in ("LAYERED", "BAKED") else ""
            self.report({"INFO"}, f"Composite set up ({method.lower()}, {engine.lower()}): "
                        f"{len(cg)} CG object(s) ({len(noisy)} path-traced or with a sharp "
                        f"reflection{layer}), {len(phantoms)} phantom(s), plate '{plate_image.name}'{clamped}.")
        return {"FINISHED"}


classes = (PLATELIGHT_OT_setup_composite,)
