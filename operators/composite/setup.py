"""setup_composite(): the work of platelight.setup_composite, callable without an operator.

Everything is checked before anything changes (a failed run raises PlateLightError and leaves the
scene as it was); then the route chosen by routes.py is built by reading its fields: collections,
view layers (layers.py), render settings, the phantoms' surfaces and the compositor tree."""
import bpy

from ... import compat
from ...addon import names
from ...addon.errors import PlateLightError
from ...node_groups.compositor_tree import build_compositor_tree
from ...node_groups import ray_twin
from ...node_groups.sbrdf_material import is_metal, sbrdf_node, shaded_by_sbrdf
from ..bake.inputs import wants_sharp_probe
from .. import motion
from ..baked_shadows import baked_is_current, moving_baked
from ..common import classify_objects, find_plate_image, set_plate_colour_management
from ...node_groups.baked_shadow import ensure_ratio_aov
from ..phantoms import apply_phantom_surfaces
from .self_occlusion import self_shadowing
from .layers import collection, configure_eevee, configure_layer, move_into, unlink_if_empty, view_layer
from .routes import BAKED_SHADOWS, CATCHER_SHADOWS, NO_SHADOWS_LAYER, choose_route


def smooth_without_denoiser(ob) -> bool:
    """Is ``ob``'s image smooth at a few samples? An SBRDF object without a sharp reflection shows
    blurred probe look-ups only: OIDN on it gained nothing and darkened its edges (docs/decisions.md).
    A sharp reflection's sub-pixel detail, and a path-traced object's noise, it does smooth."""
    return shaded_by_sbrdf(ob) and not wants_sharp_probe(ob)


# What Cycles' camera sees of an SBRDF material: its path-traced twin or the paper's SBRDF
CAMERA_SHADINGS = (("PATH_TRACED", "Path-Traced", "The Principled material the SBRDF was converted from "
                    "(its twin), path-traced and denoised"),
                   ("SBRDF", "SBRDF", "The paper's probe-shaded SBRDF, noise-free at one sample"))
# Path-traced, a metal converges sooner (docs/decisions.md, "Metals path-traced, the SBRDF for the rest")
DEFAULT_METAL_SHADING = "PATH_TRACED"
# The SBRDF shades from one probe and does not shadow itself: a column bent by its armature kept
# the face under the bend lit, Suzanne its eyes (docs/decisions.md, "A CG that shadows itself path-traced")
DEFAULT_SELF_SHADOWING_SHADING = "PATH_TRACED"


def set_camera_shading(objects, engine, metals, self_shadowing=DEFAULT_SELF_SHADOWING_SHADING, shadowing=()):
    """Give the camera each SBRDF material's SBRDF, or its path-traced twin where ``metals`` asks
    for that of a metal in Cycles, or ``self_shadowing`` for that of an object in ``shadowing``
    (names)."""
    twinned = {slot.material for ob in objects if ob.name in shadowing for slot in ob.material_slots} \
        if self_shadowing == "PATH_TRACED" else set()
    for material in {slot.material for ob in objects for slot in ob.material_slots}:
        if sbrdf_node(material) is not None and ray_twin.has_ray_split(material):
            twin = engine == "CYCLES" and ((metals == "PATH_TRACED" and is_metal(material))
                                           or material in twinned)
            ray_twin.set_camera_sees_sbrdf(material, not twin)


def shadowing_itself(scene, cg, metals) -> dict:
    """{name: why} of the CG objects an SBRDF would shade (not a metal the camera already sees
    path-traced) that shadow themselves: those that deform over the shot, whose shape may fold, and
    those whose surface hides part of its own sky (addon/material/self_occlusion.py)."""
    def sbrdf_shaded(material):
        return sbrdf_node(material) is not None and not (metals == "PATH_TRACED" and is_metal(material))

    candidates = [ob for ob in cg if any(sbrdf_shaded(slot.material) for slot in ob.material_slots)]
    found = {name: "deforms" for name in motion.motions(scene, candidates, kinds=("deforms",))}
    rigid = [ob for ob in candidates if ob.name not in found]
    for name, fraction in self_shadowing(rigid, motion.scene_depsgraph(scene)).items():
        found[name] = f"hides {100 * fraction:.1f} % of its own sky"
    return found


# A noise-free SBRDF needs only its edges anti-aliased, a path-traced object must converge (docs/decisions.md)
SMOOTH_CG_SAMPLES, PATH_TRACED_CG_SAMPLES = 4, 64
# The baked-shadow layer's samples: its ratio is noise-free, but one sample a pixel point-samples a
# hard shadow's edge (docs/decisions.md, "The baked shadows at 16 samples")
BAKED_SHADOW_SAMPLES = 16
# Cycles' automatic minimum saved nothing (docs/bench/cg_layer_mirror_960x540.md)
ADAPTIVE_MIN_SAMPLES = 4
# paths off a metal that end on a filmed phantom count as direct light (docs/decisions.md, "Filmed phantoms")
FILMED_CLAMP_DIRECT = 100.0


def setup_composite(scene, method="AUTO", engine="CYCLES", cg_samples=0, ratio_form=True,
                    shadow_clamp=4.0, denoise_shadows=True, baked_samples=BAKED_SHADOW_SAMPLES, samples=0,
                    metals=DEFAULT_METAL_SHADING, self_shadowing=DEFAULT_SELF_SHADOWING_SHADING):
    """Composite ``scene``'s CG objects onto its plate by ``method`` (AUTO or a route of routes.py)
    in ``engine``; the options are platelight.setup_composite's. Returns the report's lines,
    (level, sentence) with level INFO or WARNING; raises PlateLightError before changing anything."""
    # --- check everything before changing anything: a failed run leaves the scene as it was
    if scene.camera is None:
        raise PlateLightError("The scene has no camera; set up the plate and its camera first.")
    plate_image = find_plate_image(scene)
    if plate_image is None:
        raise PlateLightError("No plate found; run Set Up Plate (platelight.setup_plate) first.")
    cg, phantoms = classify_objects(scene)
    if not cg:
        raise PlateLightError("There are no CG objects to composite: every renderable object "
                              "is a phantom or hidden from render.")
    baked = bpy.data.materials.get(names.BAKED_SHADOW_MATERIAL)
    choice = choose_route(method, engine, baked=baked is not None,
                          motion_blur=scene.render.use_motion_blur,
                          motions=lambda: motion.motions(scene, cg + phantoms),
                          is_current=lambda moving: baked_is_current(scene, moving),
                          phantom_names=frozenset(ob.name for ob in phantoms),
                          moving_baked=lambda: moving_baked(scene))
    route, engine = choice.route, choice.engine
    reports = list(choice.reports)

    # --- build
    scene.render.engine = engine
    scene.render.film_transparent = True
    # a shot renders many frames of one scene: sync it once
    scene.render.use_persistent_data = True
    if samples:
        scene.cycles.samples = samples
        scene.eevee.taa_render_samples = samples
    # the render's denoiser changes each layer's pixels differently: the compositor denoises
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = route.adaptive
    if scene.cycles.use_adaptive_sampling:
        scene.cycles.adaptive_min_samples = ADAPTIVE_MIN_SAMPLES
    set_plate_colour_management(scene)
    cg_coll = collection(scene, names.CG_COLLECTION)
    phantom_coll = collection(scene, names.PHANTOM_COLLECTION)
    moving_cg = [ob for ob in cg if ob.name in choice.moving]
    move_into([ob for ob in cg if ob.name not in choice.moving], cg_coll)
    move_into(phantoms, phantom_coll)
    moving_coll = None
    if moving_cg:     # a collection of their own: their shadows have a layer of their own
        moving_coll = collection(scene, names.MOVING_CG_COLLECTION)
        move_into(moving_cg, moving_coll)
    else:
        unlink_if_empty(scene, names.MOVING_CG_COLLECTION)

    def moving_as(state):
        return (moving_coll, state) if moving_coll is not None else None
    for ob in cg:
        ob.is_shadow_catcher = False
        ob.is_holdout = False
    for ob in phantoms:
        ob.is_shadow_catcher = route.phantoms_catch
        ob.is_holdout = False
    apply_phantom_surfaces(scene, phantoms)   # the plate on the phantoms (or their own materials)

    ours = {names.LAYER_CG, names.LAYER_LOCAL, names.LAYER_WITHOUT, names.LAYER_SHADOWS,
            names.LAYER_MOVING_SHADOWS}
    for layer in scene.view_layers:
        if layer.name not in ours:
            layer.use = False
    cg_layer = view_layer(scene, names.LAYER_CG)
    cg_layer.cycles.use_pass_shadow_catcher = route.cg_catcher_pass
    configure_layer(cg_layer, cg_coll, phantom_coll, "visible", route.cg_holds_out_phantoms,
                    moving_as("visible"))
    # no noise from path-tracing what the camera filmed (node_groups/phantom_plate.py)
    cg_layer[names.FILMED_PHANTOMS_KEY] = 1.0 if route.filmed_phantoms else 0.0
    clamped = ""
    if route.filmed_phantoms and phantoms and not 0.0 < scene.cycles.sample_clamp_direct <= FILMED_CLAMP_DIRECT:
        before = scene.cycles.sample_clamp_direct
        scene.cycles.sample_clamp_direct = FILMED_CLAMP_DIRECT
        clamped = (f"; direct light clamped at {FILMED_CLAMP_DIRECT:g} (was "
                   f"{f'{before:g}' if before > 0 else 'off'}) against fireflies off the filmed phantoms")
    if route.local_scene:
        local_cg = "holdout" if engine == compat.EEVEE else "indirect"
        configure_layer(view_layer(scene, names.LAYER_LOCAL), cg_coll, phantom_coll, local_cg, False)
        configure_layer(view_layer(scene, names.LAYER_WITHOUT), cg_coll, phantom_coll, "excluded", False)
    if route.shadows != NO_SHADOWS_LAYER:
        shadows = view_layer(scene, names.LAYER_SHADOWS)
        shadows.cycles.use_pass_shadow_catcher = route.shadows == CATCHER_SHADOWS
        if route.shadows == CATCHER_SHADOWS:
            shadows.samples = 0
            shadows.material_override = None
            configure_layer(shadows, cg_coll, phantom_coll, "indirect", False)
        else:   # the phantoms emit the baked, noise-free ratio: the samples anti-alias its edges
            shadows.samples = baked_samples
            shadows.material_override = baked
            configure_layer(shadows, cg_coll, phantom_coll, "excluded", False, moving_as("excluded"))
            if route.phantoms_catch:   # a catcher renders transparent: the ratio comes by its AOV
                ensure_ratio_aov(baked)
                if names.BAKED_RATIO_AOV not in shadows.aovs:
                    aov = shadows.aovs.add()
                    aov.name, aov.type = names.BAKED_RATIO_AOV, "COLOR"
    if route.moving_shadows:
        # the moving CG's shadows, every frame: phantoms catch them, the still CG's are baked
        moving_layer = view_layer(scene, names.LAYER_MOVING_SHADOWS)
        moving_layer.cycles.use_pass_shadow_catcher = True
        moving_layer.samples = 0
        moving_layer.material_override = None
        configure_layer(moving_layer, cg_coll, phantom_coll, "excluded", False, moving_as("indirect"))
        moving_layer[names.FILMED_PHANTOMS_KEY] = 0.0
    for name in (names.LAYER_LOCAL, names.LAYER_WITHOUT, names.LAYER_SHADOWS, names.LAYER_MOVING_SHADOWS):
        if name in scene.view_layers and name not in route.layers:
            scene.view_layers[name].use = False
    if engine == compat.EEVEE and route.local_scene:
        configure_eevee(scene)
    # a material shared with an object that shadows itself is path-traced on every object that wears it
    shadowing = shadowing_itself(scene, cg, metals) \
        if engine == "CYCLES" and self_shadowing == "PATH_TRACED" else {}
    set_camera_shading(cg, engine, metals, self_shadowing, shadowing)
    noisy = [ob for ob in cg if not smooth_without_denoiser(ob)]   # path-traced, or a sharp SBRDF
    # EEVEE's samples anti-alias a noise-free image: its SBRDF needs no more than the edges do
    converging = bool(noisy) and engine == "CYCLES"
    layer_samples = cg_samples or (PATH_TRACED_CG_SAMPLES if converging else SMOOTH_CG_SAMPLES)
    cg_layer.samples = layer_samples if route.cg_samples else 0
    denoise_cg = denoise_shadows and bool(noisy)
    build_compositor_tree(scene, plate_image, route.name, ratio_form, shadow_clamp,
                          denoise_shadows, denoise_cg)

    if route.shadows == BAKED_SHADOWS:
        current = choice.current
        if current is None:         # BAKED asked for by name, nothing moving (choose_route saw): not hashed yet
            current = baked_is_current(scene, frozenset())
        if not current:
            reports.append(("WARNING", "The baked shadows do not match the scene any more (an "
                            "object, the world or a setting changed): run Bake Shadows again."))
    if not phantoms:
        reports.append(("WARNING", f"Composite set up for {len(cg)} CG object(s), but there are no "
                        "phantoms: the CG casts no shadows and nothing real hides it (mark stand-ins "
                        "for real surfaces as Phantom)."))
    else:
        layer = f", the CG at {layer_samples} samples" if route.cg_samples else ""
        if moving_cg:
            layer += f"; the shadows of {len(moving_cg)} moving CG object(s) rendered every frame"
        if shadowing:
            layer += ("; path-traced where they shadow themselves (the SBRDF does not): "
                      + ", ".join(f"{name!r} ({why})" for name, why in sorted(shadowing.items())))
        reports.append(("INFO", f"Composite set up ({route.name.lower()}, {engine.lower()}): "
                        f"{len(cg)} CG object(s) ({len(noisy)} path-traced or with a sharp "
                        f"reflection{layer}), {len(phantoms)} phantom(s), plate '{plate_image.name}'{clamped}."))
    return reports
