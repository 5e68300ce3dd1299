"""The extended SBRDF's parameters (paper section 3.1, design.md Eq 1-7) with their ranges.

One dataclass is the single source of truth: the node group's socket limits, the material panel's
properties, the presets and the JSON schema are all derived from ``PARAMETERS``."""
from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

from ..errors import PlateLightError


class ParamSpec(NamedTuple):
    name: str          # field name (snake case) and JSON key
    label: str         # node-group socket name and UI label (the paper's names)
    kind: str          # "color" (RGB) or "float"
    default: object
    minimum: float
    maximum: float
    description: str


PARAMETERS = (
    ParamSpec("diffuse_albedo", "Diffuse Albedo", "color", (0.8, 0.8, 0.8), 0.0, 1.0,
              "rho_d: colour of the diffuse term (also tints light refracted through the object)"),
    ParamSpec("specular_albedo", "Specular Albedo", "color", (0.04, 0.04, 0.04), 0.0, 1.0,
              "rho_s: specular colour at normal incidence, before the parameterised Fresnel"),
    ParamSpec("glossiness", "Glossiness", "float", 0.5, 0.0, 1.0,
              "n: 0 diffuse map, 1/3 glossy1, 2/3 glossy2, 1 specular (mirror), blended linearly"),
    ParamSpec("cx", "Cx", "float", -1.0, -10.0, 10.0,
              "Lafortune coefficient along the (rotated) tangent; -1 with Cy=-1 is a mirror"),
    ParamSpec("cy", "Cy", "float", -1.0, -10.0, 10.0,
              "Lafortune coefficient along the bitangent; |Cx| != |Cy| gives anisotropy"),
    ParamSpec("cz", "Cz", "float", 1.0, -10.0, 10.0,
              "Lafortune coefficient along the normal"),
    ParamSpec("fresnel_falloff", "Fresnel Falloff", "float", 0.2, 0.0, 1.0,
              "phi: Fresnel strength; near 0 only grazing angles brighten, 1 makes f = 1 everywhere"),
    ParamSpec("fresnel_peak", "Fresnel Peak", "float", 1.0, 0.0, 1.0,
              "c: the Fresnel term at grazing, f = c (1 - cos)^(1/phi - 1); 1 is the paper's form "
              "(every surface a mirror at grazing), a rough surface reaches less: converted from "
              "Principled it follows GGX's albedo"),
    ParamSpec("tangent_rotation", "Tangent Rotation", "float", 0.0, 0.0, 2.0 * math.pi,
              "Rotation of the tangent frame (radians) in which Cx, Cy and Anisotropy apply"),
    ParamSpec("anisotropy", "Anisotropy", "float", 0.0, 0.0, 1.0,
              "Stretches the lobe along the (rotated) tangent, as Principled's Anisotropic: the "
              "maps are read at the narrow axis's glossiness in several directions along the "
              "streak; 0 is a round lobe and costs nothing extra"),
    ParamSpec("emission_color", "Emission Color", "color", (1.0, 1.0, 1.0), 0.0, 1.0,
              "Colour of light emitted by the surface (headlights, screens)"),
    ParamSpec("emission_strength", "Emission Strength", "float", 0.0, 0.0, 1.0e6,
              "Radiance multiplier of the emission colour (HDR)"),
    ParamSpec("alpha", "Alpha", "float", 1.0, 0.0, 1.0,
              "Opacity: below 1 the maps are seen refracted through the surface"),
    ParamSpec("ior", "IOR", "float", 1.5, 1.0, 4.0,
              "Index of refraction for the refracted lookup"),
    ParamSpec("dispersion", "Dispersion", "float", 0.0, 0.0, 0.5,
              "Per-channel IOR spread: red uses IOR - d, green IOR, blue IOR + d"),
    ParamSpec("retro_reflection", "Retro-Reflection", "float", 0.0, 0.0, 1.0,
              "Blends the Lafortune peak towards the viewer (C = (1, 1, 1)): the paper's retro-reflector"),
    ParamSpec("paper_falloff", "Paper Falloff", "float", 0.0, 0.0, 1.0,
              "1: the paper's Eq 1 and 7 as written: the cosine falloff g' = g + (1 - g) f darkens "
              "the specular term towards the rim, the diffuse term ignores the specular one, and "
              "the maps are looked up along the peak; 0: no cosine (the maps already integrate the "
              "lobe), the diffuse term gets rho_d (1 - rho_s'), which matches a path-traced "
              "Principled BSDF, and glossy look-ups tilt towards the normal at grazing views, where "
              "the surface's horizon cuts the lobe; blends in between"),
)
SPEC = {p.name: p for p in PARAMETERS}


@dataclasses.dataclass
class SBRDFParams:
    diffuse_albedo: tuple = SPEC["diffuse_albedo"].default
    specular_albedo: tuple = SPEC["specular_albedo"].default
    glossiness: float = SPEC["glossiness"].default
    cx: float = SPEC["cx"].default
    cy: float = SPEC["cy"].default
    cz: float = SPEC["cz"].default
    fresnel_falloff: float = SPEC["fresnel_falloff"].default
    fresnel_peak: float = SPEC["fresnel_peak"].default
    tangent_rotation: float = SPEC["tangent_rotation"].default
    anisotropy: float = SPEC["anisotropy"].default
    emission_color: tuple = SPEC["emission_color"].default
    emission_strength: float = SPEC["emission_strength"].default
    alpha: float = SPEC["alpha"].default
    ior: float = SPEC["ior"].default
    dispersion: float = SPEC["dispersion"].default
    retro_reflection: float = SPEC["retro_reflection"].default
    paper_falloff: float = SPEC["paper_falloff"].default

    def clamped(self) -> "SBRDFParams":
        """A copy with every value inside its range (what the node sockets would do)."""
        values = {}
        for spec in PARAMETERS:
            value = getattr(self, spec.name)
            if spec.kind == "color":
                values[spec.name] = tuple(min(max(float(c), spec.minimum), spec.maximum)
                                          for c in value)
            else:
                values[spec.name] = min(max(float(value), spec.minimum), spec.maximum)
        return dataclasses.replace(self, **values)


def validate_value(name: str, value) -> object:
    """Check one parameter's type (not its range: out-of-range values are clamped, as sockets do)."""
    spec = SPEC.get(name)
    if spec is None:
        raise PlateLightError(f"Unknown SBRDF parameter {name!r}.")
    if spec.kind == "color":
        ok = (isinstance(value, (list, tuple)) and len(value) == 3
              and all(_is_number(c) for c in value))
        if not ok:
            raise PlateLightError(f"{name} must be a list of three numbers (R, G, B), "
                                  f"not {value!r}.")
        return tuple(float(c) for c in value)
    if not _is_number(value):
        raise PlateLightError(f"{name} must be a number, not {value!r}.")
    return float(value)


def _is_number(value) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))
