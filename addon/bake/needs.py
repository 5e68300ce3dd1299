"""Which of the four maps an object's materials read, so a bake computes only those.

Glossiness n in [0, 1] blends linearly between the maps anchored at 0 (diffuse), 1/3
(glossy1), 2/3 (glossy2) and 1 (specular) (design.md; the rule is ibl/maps.map_weights). Eq 4-7's Fresnel term raises the
glossiness towards 1 at grazing angles (n' = n + (1 - n) f) and adds specular reflection even
where the specular albedo is 0 (rho_s' = rho_s + (1 - rho_s) f), so a lobe with Fresnel on needs
every map from n up to the specular one. So does any lobe sharper than the diffuse map's: near a
contact the parallax search's glossy footprint (ibl/maps.footprint_glossiness) narrows its look-up
towards the specular map, even with Fresnel off. An anisotropic lobe reads the maps at its narrow
axis's glossiness (ibl/anisotropy.narrow_glossiness), which is what counts here."""
from __future__ import annotations

import dataclasses

from ..ibl.anisotropy import narrow_glossiness
from ..ibl.distance import BEHIND_MIN_HEIGHT
from ..ibl.maps import MAP_NAMES, map_weights


@dataclasses.dataclass(frozen=True)
class Lobes:
    """What one material asks of a probe. ``None`` for a value means "varies" (a texture or a
    link drives it), which is answered conservatively."""
    diffuse: bool = True                 # diffuse albedo not black
    specular: bool = True                # specular albedo not black
    glossiness: float | None = None      # None: textured, any value in [0, 1]
    fresnel: bool = True                 # Fresnel falloff phi > 0
    anisotropy: float | None = 0.0       # None: textured

    @property
    def map_glossiness(self) -> float | None:
        """The glossiness the maps are read at: an anisotropic lobe's narrow axis."""
        if self.glossiness is None or self.anisotropy is None:
            return None
        return float(narrow_glossiness(self.glossiness, self.anisotropy))


def glossy_maps(n: float | None, fresnel: bool) -> set[str]:
    """Maps a specular lobe of glossiness ``n`` reads: all from n up to 1 when Fresnel raises it
    or the glossy footprint can sharpen it (any n > 0; the parallax correction is a scene setting
    that changes without a re-bake, so the plan assumes it)."""
    if n is None:
        return set(MAP_NAMES)            # the specular lobe may blend down to the diffuse map at n = 0
    wanted = {name for name, weight in map_weights(n).items() if weight > 0}
    # n' = n + (1 - n) f reaches every glossiness up to 1; so does a footprint narrowed towards 0
    # (footprint_glossiness fades its narrowing out only at the diffuse map's lobe, n = 0)
    if fresnel or n > 0:
        wanted.update(MAP_NAMES[min(MAP_NAMES.index(name) for name in wanted):])
    return wanted


def maps_needed(materials: list[Lobes]) -> tuple[str, ...]:
    """Maps (in MAP_NAMES order) needed by an object with these materials; an object without a
    PlateLight material (``materials`` empty) gets all four, as any SBRDF may be applied later."""
    if not materials:
        return MAP_NAMES
    wanted: set[str] = set()
    for lobes in materials:
        if lobes.diffuse:
            wanted.add("diffuse")
        if lobes.specular or lobes.fresnel:
            wanted |= glossy_maps(lobes.map_glossiness, lobes.fresnel)
    if not wanted:                       # black, non-reflective: still give it a diffuse map
        wanted.add("diffuse")
    return tuple(name for name in MAP_NAMES if name in wanted)


def needs_sharp_specular(materials: list[Lobes]) -> bool:
    """Does an object show the specular map head-on, so that its probe's resolution shows in its
    reflection? True when a material's specular lobe blends the specular map at normal incidence
    (glossiness above glossy2's) or its glossiness varies. Fresnel alone reaches the specular map
    only at the grazing rim, where the reflection is compressed and a Probe Height probe serves."""
    return any(lobes.specular and (lobes.map_glossiness is None
                                   or map_weights(lobes.map_glossiness)["specular"] > 0)
               for lobes in materials)


def wants_behind_layer(materials: list[Lobes], maps, parallax: bool, behind: bool, distance_height: int) -> bool:
    """Does a probe bake the layer behind its first surface (operators/bake/behind_render.py)?
    Only for a sharp reflector (needs_sharp_specular) whose look-ups are parallax-corrected, when
    the scene asks for it (a blurred lobe averages a silhouette's few texels away), and with a
    distance map fine enough to tell a silhouette from a floor (distance.BEHIND_MIN_HEIGHT)."""
    return (behind and parallax and "specular" in maps and distance_height >= BEHIND_MIN_HEIGHT
            and needs_sharp_specular(materials))


def wants_irradiance_grid(maps, diffuse_parallax: bool) -> bool:
    """Does a probe bake the diffuse irradiance grid (addon/ibl/irradiance_grid.py)? Only when
    the object reads the diffuse map and the scene asks for diffuse parallax."""
    return diffuse_parallax and "diffuse" in maps


# How a probe sees its own owner (operators/bake/job.py renders accordingly).
OWNER_HIDDEN = "hidden"        # the paper: removed, so the floor under a ball is sunlit
OWNER_SHADOWS = "shadows"      # invisible to every ray but shadow rays: it shadows the floor
OWNER_INDIRECT = "indirect"    # hidden from the probe's camera only: it also blocks and bounces
                               # the floor's indirect light, as the real object would


def owner_visibility(materials: list[Lobes], owner_shadows: bool) -> str:
    """What the owner is to its own probe's rays. A sharp reflector or a glossy metal reads the
    floor under itself through parallax-corrected specular look-ups, so its probe shows that
    floor as it is (OWNER_INDIRECT). An object with a diffuse term keeps OWNER_SHADOWS: the full
    occlusion darkens a matte ball's lower half; so does a metal whose lobe reads the diffuse
    map: seen from the centre, the floor the owner darkens fills the directions straight down,
    and a lobe that wide blurs it over the lower half (the numbers: docs/decisions.md, "A sharp
    reflector's or glossy metal's probe sees its owner with indirect rays")."""
    if not owner_shadows:
        return OWNER_HIDDEN
    sharp = needs_sharp_specular(materials) or is_glossy_metal(materials)
    return OWNER_INDIRECT if sharp else OWNER_SHADOWS


def is_glossy_metal(materials: list[Lobes]) -> bool:
    """Do all the object's materials reflect without a diffuse term and with a lobe that reads no
    part of the diffuse map (a metal, polished or brushed, up to glossy1's roughness 0.443)?"""
    return bool(materials) and all(
        lobes.specular and not lobes.diffuse
        and (lobes.glossiness is None or map_weights(lobes.glossiness)["diffuse"] == 0.0)
        for lobes in materials)
