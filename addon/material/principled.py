"""Closest SBRDF parameters for a Principled BSDF and back (bpy-free maths).

Mapping (documented in docs/sbrdf.md):
- rho_d = base (1 - metallic);  rho_s = lerp(F0, base, metallic), F0 = ((ior-1)/(ior+1))^2 * 2 level
- glossiness from roughness through each map's lobe: the roughness r whose GGX (alpha = r^2)
  reflection lobe at normal incidence holds half its energy within the same angle as the map's
  Phong lobe around R, (s+1)/(2 pi) cos^s: specular r = 0, glossy2 (s = 64, 8.35 deg) r = 0.270,
  glossy1 (s = 8, 22.2 deg) r = 0.443, diffuse (s = 1, 45 deg) r = 0.644; linear between.
  (Not s = 2/alpha^2 - 2: that Blinn exponent belongs to a lobe around the half vector, whose
  reflection lobe is twice as wide.)
- Fresnel from roughness, f = c (1 - cos)^(1/phi - 1) (c: Fresnel Peak), fitted by least squares
  at each roughness knot to the rise towards grazing of the layer's directional albedo E(cos):
  - a dielectric (IOR 1.5, Cycles' multiscatter GGX): E(cos) = E(1) + (1 - E(1)) f, and rho_s
    scaled by E(1) / F0 (masking: a roughness-1 plastic reflects 1.5 % head-on, not F0's 4 %).
    Polished, c = 0.87 and k = 4.4 (Fresnel's own curve); rough, c = 0.05: its rim reflects 9 %,
    not the mirror's 100 %. The paper's c = 1 with one exponent cannot have both
    (docs/decisions.md, "A dielectric's Fresnel").
  - a metal: c and k fitted to the rise of the metal's own multiscatter albedo (Schlick's
    Fresnel on the microfacets, F0 0.3-0.9): c = 1, k = 5 polished, c = 0.51 at roughness 0.3,
    0.21 at 0.6, 0.14 rough; the converted metal follows E within 2 % from cos 0.1 to 1 up to
    roughness 0.7 (docs/decisions.md, "A metal's rim").
  - a metal's ρs is base × E(1)/F0 too: W + F_avg (1 - W), W white GGX's single-scattering
    albedo head-on, F_avg = F0 + (1 - F0)/21 (what Cycles' multiscatter gives back); 1 polished,
    0.80 for F0 0.7 at roughness 1 (docs/decisions.md, "A rough metal reflects less than its F0
    head-on").
  Blended by metallic.
- rougher than the diffuse map (r > 0.644, glossiness 0): the lobe's peak is pulled from the
  mirror direction to the normal, Cx = Cy = -(1 - t), t = (r - 0.644) / (1 - 0.644), because a
  GGX lobe's light comes from ever nearer N as it widens and at r = 1 (alpha = 1, D uniform)
  from around N itself, whatever the view (lobe_tilt.kept_lobe_centroid; docs/decisions.md, "A
  rough lobe peaks at the normal").
- alpha = principled alpha * (1 - transmission (1 - metallic)); IOR as is; emission as is.
- anisotropy: as is, with Cx = Cy = -1 (the peak at the mirror direction) and the glossiness of
  the roughness; the group reads the maps at the narrow axis's glossiness along the streak
  (addon/ibl/anisotropy.py); not a Lafortune Cy = -(1 - 0.9 a), which moves the peak towards the
  normal instead of stretching the lobe (docs/decisions.md). The anisotropic rotation sets
  Tangent Rotation (2 pi * rotation).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..ibl import maps
from .params import SBRDFParams

METAL_THRESHOLD = 0.2
# A metal's Fresnel Peak c and exponent k, fitted by tests/test_material.py::
# test_metal_fresnel_knots_follow_the_ggx_albedo (brute force): c (1 - mu)^k is the rise of
# Cycles' multiscatter GGX metal albedo towards grazing, in relative error over F0 0.3-0.9. A
# rough metal's rise is small (its microfacets average the Fresnel rise away, and masking takes
# light): c falls from 1 polished to 0.14 at roughness 1.
FALLOFF_ROUGHNESS = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 1.0])
FALLOFF_PEAK = np.array([1.0, 0.985, 0.807, 0.509, 0.322, 0.255, 0.212, 0.162, 0.138, 0.141])
FALLOFF_EXPONENT = np.array([5.0, 4.97, 4.62, 4.09, 4.21, 5.22, 5.31, 3.70, 2.36, 1.69])
# White GGX's single-scattering albedo head-on (Fresnel 1) at FALLOFF_ROUGHNESS, by
# tests/test_material.py::test_metal_head_on_follows_the_multiscatter_albedo (brute force).
WHITE_HEAD_ON = np.array([1.0, 1.0, 1.0, 0.991, 0.968, 0.916, 0.825, 0.698, 0.555, 0.307])
# The diffuse map's roughness: every rougher lobe has glossiness 0 and its peak pulled to N.
_DIFFUSE_ROUGHNESS = float(maps.ROUGHNESS_KNOTS[0])
# A dielectric's (IOR 1.5, multiscatter GGX): Fresnel Peak c, exponent k and E(1) / F0, fitted by
# tests/test_material.py::test_dielectric_fresnel_knots_follow_the_ggx_albedo (brute force).
DIELECTRIC_ROUGHNESS = np.linspace(0.0, 1.0, 11)
DIELECTRIC_PEAK = np.array([0.874, 0.830, 0.635, 0.423, 0.276, 0.181, 0.125, 0.093, 0.073, 0.061, 0.053])
DIELECTRIC_EXPONENT = np.array([4.40, 4.25, 3.65, 3.05, 2.70, 2.50, 2.45, 2.45, 2.35, 2.30, 2.25])
DIELECTRIC_HEAD_ON = np.array([1.0, 1.0, 1.001, 0.995, 0.977, 0.934, 0.855, 0.742, 0.612, 0.487, 0.382])


@dataclasses.dataclass
class PrincipledValues:
    base_color: tuple = (0.8, 0.8, 0.8)
    metallic: float = 0.0
    roughness: float = 0.5
    ior: float = 1.5
    specular_ior_level: float = 0.5
    transmission: float = 0.0
    alpha: float = 1.0
    anisotropic: float = 0.0
    anisotropic_rotation: float = 0.0
    emission_color: tuple = (1.0, 1.0, 1.0)
    emission_strength: float = 0.0


# Which SBRDF parameters each Principled input changes through principled_to_sbrdf(): where a
# texture drives an input, the conversion's node group (node_groups/principled_conversion.py)
# drives exactly these, and the material editor keeps the rest (tests/test_material.py checks
# the map against principled_to_sbrdf itself).
CHANGES = {
    "base_color": ("diffuse_albedo", "specular_albedo"),
    "metallic": ("diffuse_albedo", "specular_albedo", "fresnel_falloff", "fresnel_peak", "alpha"),
    "roughness": ("specular_albedo", "glossiness", "cx", "cy", "fresnel_falloff", "fresnel_peak"),
    "ior": ("specular_albedo", "ior"),
    "specular_ior_level": ("specular_albedo",),
    "transmission": ("alpha",),
    "alpha": ("alpha",),
    "anisotropic": ("anisotropy",),
    "anisotropic_rotation": ("tangent_rotation",),
    "emission_color": ("emission_color",),
    "emission_strength": ("emission_strength",),
}


# Each map's roughness (maps.MAP_ROUGHNESS) is fitted by tests/test_material.py::
# test_roughness_knots_match_the_ggx_lobes, brute force.
def roughness_to_glossiness(roughness: float) -> float:
    return float(maps.roughness_to_glossiness(roughness))


def glossiness_to_roughness(glossiness: float) -> float:
    return float(maps.glossiness_to_roughness(glossiness))


def _metal_exponent(roughness: float) -> float:
    return float(np.interp(roughness, FALLOFF_ROUGHNESS, FALLOFF_EXPONENT))


def roughness_to_fresnel_falloff(roughness: float) -> float:
    """A metal's phi (its Fresnel Peak: metal_fresnel_peak)."""
    return 1.0 / (1.0 + _metal_exponent(roughness))


def metal_fresnel_peak(roughness: float) -> float:
    return float(np.interp(roughness, FALLOFF_ROUGHNESS, FALLOFF_PEAK))


def dielectric_fresnel(roughness: float) -> tuple[float, float, float]:
    """A dielectric's (exponent k = 1/phi - 1, Fresnel Peak c, E(1) / F0) at this roughness."""
    knots = DIELECTRIC_ROUGHNESS
    return tuple(float(np.interp(roughness, knots, table))
                 for table in (DIELECTRIC_EXPONENT, DIELECTRIC_PEAK, DIELECTRIC_HEAD_ON))


def fresnel_terms(roughness: float, metallic: float) -> tuple[float, float, float]:
    """(phi, Fresnel Peak, the factor on the dielectric's F0): a dielectric's and a metal's
    exponent and peak blended by metallic."""
    exponent_d, peak_d, head_on = dielectric_fresnel(roughness)
    exponent = (1.0 - metallic) * exponent_d + metallic * _metal_exponent(roughness)
    peak = (1.0 - metallic) * peak_d + metallic * metal_fresnel_peak(roughness)
    return 1.0 / (1.0 + exponent), peak, head_on


def metal_head_on(base, roughness: float):
    """E(1) / F0 of a metal of reflectance ``base`` (per channel): Cycles' multiscatter GGX gives
    back what single scattering loses (1 - W, W its white albedo) times the average Fresnel, so a
    rough metal reflects W + F_avg (1 - W) of F0 head-on (0.80 for F0 0.7 at roughness 1)."""
    base = np.asarray(base, dtype=float)
    white = float(np.interp(roughness, FALLOFF_ROUGHNESS, WHITE_HEAD_ON))
    return white + (base + (1.0 - base) / 21.0) * (1.0 - white)


def _metal_base(specular, roughness: float) -> np.ndarray:
    """The base whose base * metal_head_on(base, roughness) is ``specular`` (its quadratic's root)."""
    specular = np.asarray(specular, dtype=float)
    lost = 1.0 - float(np.interp(roughness, FALLOFF_ROUGHNESS, WHITE_HEAD_ON))
    a, b = lost * 20.0 / 21.0, 1.0 - lost + lost / 21.0
    if a < 1e-12:
        return specular / b
    return (-b + np.sqrt(b * b + 4.0 * a * specular)) / (2.0 * a)


def peak_pull(roughness: float) -> float:
    """t in [0, 1]: how far a lobe of this roughness peaks from the mirror direction towards the
    normal (0 up to the diffuse map's roughness, 1 at roughness 1); Cx = Cy = -(1 - t)."""
    return float(min(max((roughness - _DIFFUSE_ROUGHNESS) / (1.0 - _DIFFUSE_ROUGHNESS), 0.0), 1.0))


def roughness_of(s: SBRDFParams) -> float:
    """The roughness principled_to_sbrdf() read ``s`` from: the glossiness's, and beyond the
    diffuse map's the one whose peak_pull() made Cx and Cy (the group's sun lobe reads it too)."""
    return float(maps.pulled_roughness(s.glossiness, s.cx, s.cy))


def nonfinite_fields(p: PrincipledValues) -> list[str]:
    """The fields of ``p`` that hold NaN (a socket set from Python can; Blender stores an
    infinity as the largest float, which converts like any large value)."""
    return [field.name for field in dataclasses.fields(p)
            if not np.all(np.isfinite(np.asarray(getattr(p, field.name), dtype=float)))]


def _f0(ior: float, level: float) -> float:
    return min(((ior - 1.0) / (ior + 1.0)) ** 2 * 2.0 * level, 1.0)


def principled_to_sbrdf(p: PrincipledValues) -> SBRDFParams:
    base = np.clip(np.asarray(p.base_color[:3], dtype=float), 0.0, 1.0)
    metal = min(max(p.metallic, 0.0), 1.0)
    f0 = _f0(max(p.ior, 1.0), p.specular_ior_level)
    roughness = min(max(p.roughness, 0.0), 1.0)
    phi, peak, head_on = fresnel_terms(roughness, metal)
    specular = (1.0 - metal) * f0 * head_on + metal * base * metal_head_on(base, roughness)
    lafortune = -(1.0 - peak_pull(roughness))
    alpha = p.alpha * (1.0 - p.transmission * (1.0 - metal))
    return SBRDFParams(
        diffuse_albedo=tuple(float(c) for c in base * (1.0 - metal)),
        specular_albedo=tuple(float(c) for c in specular),
        glossiness=roughness_to_glossiness(roughness),
        cx=lafortune, cy=lafortune, cz=1.0,
        fresnel_falloff=phi, fresnel_peak=peak,
        tangent_rotation=2.0 * math.pi * (p.anisotropic_rotation % 1.0),
        anisotropy=float(p.anisotropic),
        emission_color=tuple(float(c) for c in p.emission_color[:3]),
        emission_strength=float(p.emission_strength),
        alpha=float(min(max(alpha, 0.0), 1.0)),
        ior=float(max(p.ior, 1.0)),
    ).clamped()


def sbrdf_to_principled(s: SBRDFParams) -> PrincipledValues:
    spec = np.asarray(s.specular_albedo, dtype=float)
    diff = np.asarray(s.diffuse_albedo, dtype=float)
    metal = 1.0 if spec.max() > METAL_THRESHOLD and spec.max() >= diff.max() else 0.0
    if metal:
        base, level = _metal_base(spec, roughness_of(s)), 0.5
    else:
        base = diff
        f0_ior = _f0(max(s.ior, 1.0), 0.5) * dielectric_fresnel(roughness_of(s))[2]
        level = 0.5 * float(spec.mean()) / f0_ior if f0_ior > 0 else 0.5
    transmission = 1.0 - s.alpha if not metal else 0.0
    wide, narrow = max(abs(s.cx), abs(s.cy)), min(abs(s.cx), abs(s.cy))
    anis = (1.0 - narrow / wide) / 0.9 if wide > narrow else 0.0     # equal: round (a rough peak_pull)
    return PrincipledValues(
        base_color=tuple(float(c) for c in base), metallic=metal,
        roughness=roughness_of(s), ior=float(s.ior),
        specular_ior_level=float(min(max(level, 0.0), 1.0)),
        transmission=float(transmission), alpha=1.0 if transmission > 0 else float(s.alpha),
        anisotropic=float(min(max(max(anis, s.anisotropy), 0.0), 1.0)),
        anisotropic_rotation=float(s.tangent_rotation / (2.0 * math.pi)),
        emission_color=tuple(s.emission_color), emission_strength=float(s.emission_strength),
    )
