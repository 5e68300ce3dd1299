"""Built-in SBRDF presets: the materials the paper shows (chrome, brushed metal, glass, plastic,
rubber, polished paint, marble, emissive). Values not listed keep the parameter defaults.

The tangent of the SBRDF frame runs in circles around the object's Z axis, so "brushed metal"
gets its circular brushing (the paper's tangent-rotation map) with Tangent Rotation 0 and an
anisotropic |Cx| != |Cy|."""
from __future__ import annotations

import dataclasses

from ..errors import PlateLightError
from ..names import SBRDF_GROUP
from .params import SBRDFParams

PRESETS = {
    "chrome": dict(diffuse_albedo=(0.0, 0.0, 0.0), specular_albedo=(0.9, 0.9, 0.9),
                   glossiness=1.0, fresnel_falloff=0.05),
    "brushed_metal": dict(diffuse_albedo=(0.02, 0.02, 0.02), specular_albedo=(0.8, 0.8, 0.8),
                          glossiness=0.8, cx=-1.0, cy=-0.25, cz=1.0, fresnel_falloff=0.1),
    "glass": dict(diffuse_albedo=(1.0, 1.0, 1.0), specular_albedo=(0.04, 0.04, 0.04),
                  glossiness=1.0, fresnel_falloff=1.0 / 6.0, alpha=0.0, ior=1.5,
                  dispersion=0.01),
    "plastic": dict(diffuse_albedo=(0.6, 0.05, 0.05), specular_albedo=(0.05, 0.05, 0.05),
                    glossiness=0.6, fresnel_falloff=1.0 / 6.0),
    "rubber": dict(diffuse_albedo=(0.04, 0.04, 0.04), specular_albedo=(0.03, 0.03, 0.03),
                   glossiness=0.2, fresnel_falloff=0.1),
    "polished_paint": dict(diffuse_albedo=(0.05, 0.12, 0.45), specular_albedo=(0.06, 0.06, 0.06),
                           glossiness=0.95, fresnel_falloff=1.0 / 6.0),
    "marble": dict(diffuse_albedo=(0.85, 0.83, 0.8), specular_albedo=(0.04, 0.04, 0.04),
                   glossiness=0.7, fresnel_falloff=1.0 / 6.0),
    "emissive": dict(diffuse_albedo=(0.05, 0.05, 0.05), specular_albedo=(0.04, 0.04, 0.04),
                     glossiness=0.9, emission_color=(1.0, 0.85, 0.6), emission_strength=4.0),
}


def preset_names() -> tuple:
    return tuple(PRESETS)


def preset_params(name: str) -> SBRDFParams:
    if name not in PRESETS:
        raise PlateLightError(f"Unknown SBRDF preset {name!r} (known: {', '.join(PRESETS)}).")
    return dataclasses.replace(SBRDFParams(), **PRESETS[name])


def preset_label(name: str) -> str:
    return name.replace("_", " ").title()


PRESET_SUBDIR = "platelight_sbrdf"


def preset_file_text(params: SBRDFParams) -> str:
    """A Blender preset script (the format AddPresetBase writes) setting the SBRDF node's inputs
    of the material in context."""
    from .params import PARAMETERS

    lines = ["import bpy",
             f"node = bpy.context.material.node_tree.nodes[{SBRDF_GROUP!r}]"]
    for spec in PARAMETERS:
        value = getattr(params, spec.name)
        if spec.kind == "color":
            value = (*[float(c) for c in value], 1.0)
        lines.append(f"node.inputs[{spec.label!r}].default_value = {value!r}")
    return "\n".join(lines) + "\n"


def write_preset_files(folder) -> list:
    """Write one preset script per built-in preset (shipped in presets/platelight_sbrdf/)."""
    import os

    os.makedirs(folder, exist_ok=True)
    paths = []
    for name in PRESETS:
        path = os.path.join(folder, preset_label(name) + ".py")
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(preset_file_text(preset_params(name)))
        paths.append(path)
    return paths
