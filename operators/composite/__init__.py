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

routes.py holds the routes as data and chooses one, setup.py builds it (``setup_composite``, the
operator's work as a plain function), layers.py makes the collections and view layers."""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty

from ...addon import names
from ...addon.errors import PlateLightError
from ..common import report_error
from .routes import ROUTES, Route, choose_route
from .setup import (ADAPTIVE_MIN_SAMPLES, BAKED_SHADOW_SAMPLES, CAMERA_SHADINGS, DEFAULT_SELF_SHADOWING_SHADING,
                    DEFAULT_METAL_SHADING, FILMED_CLAMP_DIRECT, PATH_TRACED_CG_SAMPLES, SMOOTH_CG_SAMPLES, set_camera_shading, setup_composite,
                    smooth_without_denoiser)
from .layers import configure_eevee

__all__ = ("ADAPTIVE_MIN_SAMPLES", "BAKED_SHADOW_SAMPLES", "CAMERA_SHADINGS", "DEFAULT_SELF_SHADOWING_SHADING",
           "DEFAULT_METAL_SHADING", "FILMED_CLAMP_DIRECT",
           "PATH_TRACED_CG_SAMPLES", "PLATELIGHT_OT_setup_composite", "ROUTES", "Route",
           "SMOOTH_CG_SAMPLES", "choose_route", "classes", "configure_eevee", "set_camera_shading",
           "setup_composite", "smooth_without_denoiser")


class PLATELIGHT_OT_setup_composite(bpy.types.Operator):
    """Build the view layers and compositor tree that composite the CG objects onto the plate
    (differential rendering: shadows and reflections on phantoms, occlusion by phantoms)"""

    bl_idname = "platelight.setup_composite"
    bl_label = "Set Up Composite"
    bl_options = {"REGISTER", "UNDO"}

    method: EnumProperty(
        name="Method",
        items=(
            ("AUTO", "Automatic", "Baked Shadows when the shot's shadows are baked and still fit the "
             "scene (the fastest route at equal error), a CG that moves or deforms getting its shadow "
             "every frame from a shadow-catcher layer of its own; else Shadow Catcher"),
            ("CATCHER", "Shadow Catcher", "One render: phantoms are shadow catchers; the catcher pass "
             "is the with/without ratio (fast)"),
            ("LAYERED", "Layered Catcher", "Two renders: the CG alone at CG Samples (noise-free "
             "SBRDF materials need few), the shadows on the catchers at Samples, denoised"),
            ("DIFFERENTIAL", "Differential", "Debevec's three renders: CG, local scene with CG and "
             "without CG (additive or ratio form)"),
            ("BAKED", "Baked Shadows", "Two cheap renders: the CG at CG Samples, and the phantoms "
             "showing the shot's shadows baked once by Bake Shadows (a still CG on matte phantoms, "
             "the camera free to move; a moving CG left out of the bake adds a shadow-catcher layer)"),
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
        "bake is noise-free, so these only anti-alias the shadow's edges (a hard sun's most); "
        "lower them for soft shadows",
        default=BAKED_SHADOW_SAMPLES, min=1, max=1 << 20,
    )
    samples: IntProperty(
        name="Samples",
        description="Cycles samples per pixel (0 keeps the scene's setting)",
        default=0, min=0, max=1 << 20,
    )
    metals: EnumProperty(
        name="Metals",
        description="What the camera sees of an SBRDF metal in Cycles (EEVEE always shows the SBRDF)",
        items=CAMERA_SHADINGS,
        default=DEFAULT_METAL_SHADING,
    )
    self_shadowing: EnumProperty(
        name="Self-Shadowing CG",
        description="What the camera sees in Cycles of an SBRDF object that shadows itself: one whose "
        "shape changes over the shot (an armature, shape keys, animated modifiers) or whose surface "
        "hides part of its own sky (a hollow, a fold). The SBRDF does not shadow itself, so a bending "
        "limb stays lit where it folds (EEVEE always shows the SBRDF)",
        items=CAMERA_SHADINGS,
        default=DEFAULT_SELF_SHADOWING_SHADING,
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
        try:
            reports = setup_composite(
                scene, method=self.method, engine=self.engine, cg_samples=self.cg_samples,
                ratio_form=self.ratio_form, shadow_clamp=self.shadow_clamp,
                denoise_shadows=self.denoise_shadows, baked_samples=self.baked_samples,
                samples=self.samples, metals=self.metals, self_shadowing=self.self_shadowing)
        except PlateLightError as err:
            report_error(self, err)
            return {"CANCELLED"}
        if context.window is not None:
            context.window.view_layer = scene.view_layers[names.LAYER_CG]
        for level, sentence in reports:
            self.report({level}, sentence)
        return {"FINISHED"}


classes = (PLATELIGHT_OT_setup_composite,)
