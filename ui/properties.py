"""Per-object, per-scene PlateLight settings (``object.platelight``, ``scene.platelight``).

Names listed in design.md's scripting contract (``phantom``, ``probe_dir``) are stable API."""
import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty,
                       StringProperty)

from ..addon.bake.probe_reuse import DEFAULT_TOLERANCE as PROBE_REUSE_DEFAULT
from .registration import register_classes, unregister_classes


class PlateLightObjectSettings(bpy.types.PropertyGroup):
    enabled: BoolProperty(
        name="PlateLight Object",
        description="Shade this object with a PlateLight probe baked from its centre",
        default=False,
        options=set(),
    )
    phantom: BoolProperty(
        name="Phantom",
        description="Stand-in for real geometry: seen in other objects' probes, holds out CG "
        "behind it and receives shadows, but is not rendered as CG itself",
        default=False,
        options=set(),
    )
    phantom_surface: EnumProperty(
        name="Phantom Surface",
        description="What this phantom looks like in reflections, bounced light and probes",
        items=(
            ("SCENE", "Scene Setting", "As the scene's Phantom Surface says"),
            ("PLATE", "Plate", "The plate, projected from the plate's camera"),
            ("MATERIAL", "Own Material", "The object's own (hand-made) material"),
        ),
        default="SCENE",
    )
    probe_dir: StringProperty(
        name="Probe Folder",
        description="Folder holding this object's diffuse/glossy1/glossy2/specular EXR maps",
        subtype="DIR_PATH",
        default="",
        options={"PATH_SUPPORTS_BLEND_RELATIVE"},
    )
    probe_origin: PointerProperty(
        name="Probe Origin",
        description="Object whose location is the probe's centre (default: bounding-box centre)",
        type=bpy.types.Object,
    )
    probe_status: StringProperty(
        name="Probe Status",
        description="State of the last bake of this object's probe",
        default="not baked",
        options=set(),
    )
    probe_hash: StringProperty(
        name="Probe Hash",
        description="Content hash of the inputs of the last bake (used to skip unchanged bakes)",
        default="",
        options={"HIDDEN"},
    )


def _parallax_changed(settings, context):
    from ..node_groups.probe_maps import set_parallax

    set_parallax()


class PlateLightSceneSettings(bpy.types.PropertyGroup):
    probe_height: IntProperty(
        name="Probe Height",
        description="Height in pixels of each object's panoramic probe render (width is twice)",
        default=64, min=8, soft_max=512, max=4096,
    )
    probe_auto_size: BoolProperty(
        name="Size to Screen",
        description="Render the probe of a mirror-like object (one with a sharp specular map) at "
        "twice its largest width on screen in pixels, from Probe Height up to Max Probe Height: a "
        "probe smaller than the mirror blurs its reflection",
        default=True,
    )
    probe_max_height: IntProperty(
        name="Max Probe Height",
        description="Largest height Size to Screen may give a probe (the bake's time grows with "
        "its area)",
        default=1024, min=8, soft_max=2048, max=4096,
    )
    probe_samples: IntProperty(
        name="Probe Samples",
        description="Cycles samples per pixel for probe renders. A probe under 128 pixels high gets "
        "more, up to twice as many, no more than a 128-pixel probe costs: its noise shows in glossy "
        "reflections",
        default=16, min=1, soft_max=256, max=65536,
    )
    maps_dir: StringProperty(
        name="Maps Folder",
        description="Where baked maps are written (relative to the .blend when it starts with //)",
        default="//platelight_maps",
        subtype="DIR_PATH",
        options={"PATH_SUPPORTS_BLEND_RELATIVE"},
    )
    world_probe: StringProperty(
        name="World Probe",
        description="Equirectangular EXR of the real place (empty: the world's environment texture)",
        default="",
        subtype="FILE_PATH",
        options={"PATH_SUPPORTS_BLEND_RELATIVE"},
    )
    probe_distance: FloatProperty(
        name="Probe Distance",
        description="Probes see objects up to this far away; objects farther off neither appear "
        "in a probe nor make it stale when they move",
        default=1000.0, min=0.01, soft_max=10000.0, unit="LENGTH",
    )
    probe_reuse: FloatProperty(
        name="Probe Reuse",
        description="Over a frame range, a moving object's probe is rendered again only once the "
        "object has moved or turned by more than this fraction of its size since the last one "
        "(or anything it sees changed); the frames between reuse that probe from its own centre "
        "(faster for large probes, but the object's own shadow in its probe lags behind). "
        "0: a probe every frame",
        default=PROBE_REUSE_DEFAULT, min=0.0, soft_max=1.0,
    )
    probe_fast_world: BoolProperty(
        name="Fast World Sampling",
        description="Cap the world's light-importance map at 256 columns for probe renders: "
        "about 3x faster probes, but a small bright sun is then sampled poorly (fireflies, "
        "darker sunlit surfaces in the probe)",
        default=False,
    )
    probe_owner_shadows: BoolProperty(
        name="Owner Shadows",
        description="The object still casts its shadows in its own probe (it is invisible to the "
        "probe's rays, not removed): the floor under a ball is seen shadowed from the ball, as it "
        "is; a mirror-like or metal object also blocks and bounces the floor's indirect light there. "
        "Off: the paper's probe, with the owner simply hidden",
        default=True,
    )
    probe_parallax: BoolProperty(
        name="Parallax Correction",
        description="Follow each reflected ray from the shading point to the surface the probe's "
        "distance map holds (distance impostors), so nearby things reflect where they are, and "
        "narrow a glossy reflection of a nearby surface to its footprint; off: the paper's "
        "look-up from the probe's centre",
        default=True,
        update=lambda self, context: _parallax_changed(self, context),
    )
    probe_behind: BoolProperty(
        name="Layer Behind",
        description="For a mirror-like object, bake what its probe's centre sees behind the first "
        "surface too (two more renders), so a reflected ray that passes beside a nearby phantom "
        "shows what lies past it instead of the phantom's edge (needs Parallax Correction; "
        "switching it makes mirror probes stale)",
        default=True,
        update=lambda self, context: _parallax_changed(self, context),
    )
    probe_diffuse_parallax: BoolProperty(
        name="Diffuse Parallax",
        description="Light the diffuse layer from a grid of irradiance maps over the object, each "
        "seen from its own point through the probe's distance map, so the lower half of a ball on "
        "a floor sees that floor as it does; off: the paper's irradiance map at the probe's centre",
        default=True,
        update=lambda self, context: _parallax_changed(self, context),
    )
    probe_sun_lobe: BoolProperty(
        name="Sun Highlight",
        description="Shade the probe's sun (a small, very bright light the bake finds in it) "
        "through each glossy lobe's own GGX shape, and read the glossy maps without it: exact "
        "highlights, streaks on brushed metal; off: the paper's maps, the sun blurred into them "
        "(switching it makes the probes stale: the bake writes the sunless maps only when on)",
        default=True,
        update=lambda self, context: _parallax_changed(self, context),
    )
    pack_maps: BoolProperty(
        name="Pack Maps",
        description="Also pack the baked maps into the .blend (one image per map file, updated in "
        "place on re-bake), so the file renders without its maps folder",
        default=False,
    )
    phantom_surface: EnumProperty(
        name="Phantom Surface",
        description="What phantoms look like in reflections, bounced light and probes (each "
        "phantom may override it)",
        items=(
            ("PLATE", "Plate", "The real surfaces' albedo, estimated from the plate and shaded by the "
             "scene's lights: CG reflects the real surfaces, with its shadows, and their colours "
             "bleed onto it"),
            ("MATERIAL", "Own Material", "Each phantom's own (hand-made) material"),
        ),
        default="PLATE",
    )
    sampling: EnumProperty(
        name="Sampling",
        description="How spherical harmonics are computed from the probe",
        items=(
            ("exact", "Exact", "Exact quadrature on the probe's texels (accurate and fast)"),
            ("paper", "Paper", "The paper's jittered uniform sampling (Eq 8-9), for comparison"),
        ),
        default="exact",
    )
    glossy_lobes: EnumProperty(
        name="Glossy Lobes",
        description="The lobes the glossy maps are blurred with, and how the shader reads them "
        "(exact sampling; the paper's sampling keeps the paper's Phong lobes and four maps; "
        "switching it makes the probes stale)",
        items=(
            ("phong", "Phong", "The paper's normalised Phong lobes, cos^8 and cos^64"),
            ("ggx", "GGX", "The GGX reflection lobe of each map's roughness, as Cycles' Principled "
             "BSDF reflects light (more light from around a bright sun)"),
            ("view", "View-Dependent GGX", "The four maps keep the paper's Phong lobes; the glossy "
             "look-ups read a ladder of GGX maps with a fifth, sharper one, narrowed across the "
             "plane of incidence as the view grazes, as a real glossy lobe does (the most accurate)"),
        ),
        default="view",
        update=lambda self, context: _parallax_changed(self, context),
    )


classes = (PlateLightObjectSettings, PlateLightSceneSettings)


def register():
    register_classes(classes)
    bpy.types.Object.platelight = PointerProperty(type=PlateLightObjectSettings)
    bpy.types.Scene.platelight = PointerProperty(type=PlateLightSceneSettings)


def unregister():
    for owner in (bpy.types.Object, bpy.types.Scene):
        if hasattr(owner, "platelight"):
            del owner.platelight
    unregister_classes(classes)
