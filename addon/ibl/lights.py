"""A probe as a handful of directional lights, for shadows (bpy-free).

The paper casts shadows with shadow maps of hand-placed lights. To place them automatically we
(1) find the sun: a small, very bright connected blob that holds a large share of the probe's
energy, turned into one light with the sun's real (small) angular size, so its shadow is sharp;
(2) cut the rest of the probe into regions of equal energy with Debevec's median cut (2005),
one soft light per region at its energy centroid.

Units: a light's ``rgb`` is the irradiance it delivers to a surface facing it, ∫ L dΩ over its
region, which is exactly Blender's sun strength (W/m²): a constant world of radiance 1 and its
lights light a white diffuse surface to the same brightness. The lights' ``rgb`` add up to the
probe's ∫ L dΩ over the sphere (energy is kept exactly).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import PlateLightError
from .equirect import check_shape, downsample_area, texel_directions, texel_solid_angles

LUMA = np.array([0.2126, 0.7152, 0.0722])
# Median cut runs on a downsampled probe: region boundaries need no more detail than this.
MEDIAN_CUT_HEIGHT = 128


@dataclasses.dataclass
class DirectionalLight:
    direction: np.ndarray      # unit vector from the scene towards the light (world, Z up)
    rgb: np.ndarray            # irradiance on a surface facing the light (Blender sun strength)
    angle: float               # angular diameter in radians (0 = perfectly sharp shadow)
    is_sun: bool = False

    @property
    def strength(self) -> float:
        return float(np.max(self.rgb))

    @property
    def color(self) -> np.ndarray:
        return self.rgb / self.strength if self.strength > 0 else np.ones(3)


@dataclasses.dataclass
class SunSettings:
    # texels brighter than this fraction of the peak belong to the sun's blob
    blob_fraction: float = 0.02
    # a sun is small (solid angle, sr; the real sun is 6.8e-5 sr, blurry HDRIs spread it) ...
    max_solid_angle: float = 0.02
    # ... and carries a good share of the light
    min_energy_share: float = 0.02


def _prepare(env: np.ndarray) -> np.ndarray:
    env = np.asarray(env)
    check_shape(env, "probe")
    env = np.asarray(env[..., :3], dtype=np.float64)
    return np.where(np.isfinite(env), np.maximum(env, 0.0), 0.0)


def find_sun(env: np.ndarray, settings: SunSettings | None = None):
    """The sun of a probe as (DirectionalLight, mask of its texels), or None when it has none."""
    import cv2

    settings = settings or SunSettings()
    env = _prepare(env)
    h, w = env.shape[:2]
    lum = env @ LUMA
    omega = texel_solid_angles(h, w)
    total = float((lum * omega).sum())
    if total <= 0:
        return None
    peak_index = np.unravel_index(np.argmax(lum), lum.shape)
    mask = (lum > settings.blob_fraction * lum[peak_index]).astype(np.uint8)
    _, labels = cv2.connectedComponents(mask, connectivity=8)
    blob = labels == labels[peak_index]
    # the blob may cross the seam at u = 0/1: join the component touching the other edge
    if blob[:, 0].any() or blob[:, -1].any():
        for edge_a, edge_b in ((0, -1), (-1, 0)):
            rows = np.nonzero(blob[:, edge_a])[0]
            for label in np.unique(labels[rows, edge_b]):
                if label:
                    blob |= labels == label
    blob_omega = float(omega[blob].sum())
    energy = env[blob] * omega[blob][:, None]
    share = float((energy @ LUMA).sum() / total)
    if blob_omega > settings.max_solid_angle or share < settings.min_energy_share:
        return None
    dirs = texel_directions(h, w)[blob]
    weights = (lum * omega)[blob]
    direction = (dirs * weights[:, None]).sum(axis=0)
    direction /= np.linalg.norm(direction)
    angle = 2.0 * np.arccos(max(-1.0, 1.0 - blob_omega / (2.0 * np.pi)))   # cone of that solid angle
    return DirectionalLight(direction, energy.sum(axis=0), float(angle), True), blob


def _fill_blob(env: np.ndarray, blob: np.ndarray) -> np.ndarray:
    """The probe with the sun's texels replaced by the mean of a ring of sky around them."""
    import cv2

    ring = cv2.dilate(blob.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool) & ~blob
    filled = env.copy()
    filled[blob] = env[ring].mean(axis=0) if ring.any() else 0.0
    return filled


def median_cut(env: np.ndarray, count: int) -> list[DirectionalLight]:
    """Debevec's median cut: split the probe into ``count`` regions of about equal energy (always
    the region holding the most energy is split, across its longer side measured on the sphere,
    at its energy median) and make one light per region."""
    if not 1 <= count <= 4096:
        raise PlateLightError(f"The number of lights must be between 1 and 4096, not {count}.")
    env = _prepare(env)
    if env.shape[0] > MEDIAN_CUT_HEIGHT:
        # only the light grid is coarser: each texel keeps its exact energy (area-correct)
        env = downsample_area(env, MEDIAN_CUT_HEIGHT).astype(np.float64)
    h, w = env.shape[:2]
    omega = texel_solid_angles(h, w)
    energy_rgb = env * omega[..., None]
    energy = energy_rgb @ LUMA
    lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
    regions = [(0, h, 0, w)]

    def region_energy(r):
        return float(energy[r[0]:r[1], r[2]:r[3]].sum())

    while len(regions) < count:
        splittable = [r for r in regions if (r[1] - r[0]) > 1 or (r[3] - r[2]) > 1]
        if not splittable:
            break
        r = max(splittable, key=region_energy)
        r0, r1, c0, c1 = r
        height_rad = (r1 - r0) * np.pi / h
        width_rad = (c1 - c0) * 2 * np.pi / w * np.cos(lat[(r0 + r1) // 2])
        block = energy[r0:r1, c0:c1]
        split_rows = (height_rad >= width_rad and r1 - r0 > 1) or c1 - c0 == 1
        profile = block.sum(axis=1) if split_rows else block.sum(axis=0)
        cumulative = np.cumsum(profile)
        cut = int(np.searchsorted(cumulative, cumulative[-1] / 2.0)) + 1
        cut = min(max(cut, 1), len(profile) - 1)
        regions.remove(r)
        if split_rows:
            regions += [(r0, r0 + cut, c0, c1), (r0 + cut, r1, c0, c1)]
        else:
            regions += [(r0, r1, c0, c0 + cut), (r0, r1, c0 + cut, c1)]

    dirs = texel_directions(h, w)
    lights = []
    for r0, r1, c0, c1 in regions:
        weights = energy[r0:r1, c0:c1]
        rgb = energy_rgb[r0:r1, c0:c1].reshape(-1, 3).sum(axis=0)
        region_dirs = dirs[r0:r1, c0:c1].reshape(-1, 3)
        region_weights = weights.reshape(-1)
        if region_weights.sum() <= 0:
            region_weights = omega[r0:r1, c0:c1].reshape(-1)
        direction = region_weights @ region_dirs
        norm = np.linalg.norm(direction)
        direction = direction / norm if norm > 0 else np.array([0.0, 0.0, 1.0])
        solid_angle = float(omega[r0:r1, c0:c1].sum())
        angle = min(2.0 * np.arccos(max(-1.0, 1.0 - solid_angle / (2.0 * np.pi))), np.pi / 2)
        lights.append(DirectionalLight(direction, rgb, float(angle), False))
    return [light for light in lights if light.strength > 0]


def split_sun(env: np.ndarray, sun: SunSettings | None = None):
    """(sun light, the probe without its sun) or (None, probe): the sun's texels are filled with
    the surrounding sky and the light carries exactly the energy taken out, so
    sun light + sun-less probe = the probe (energy kept)."""
    env = _prepare(env)
    found = find_sun(env, sun)
    if found is None:
        return None, env
    sun_light, blob = found
    filled = _fill_blob(env, blob)
    omega = texel_solid_angles(*env.shape[:2])
    removed = (env[blob] * omega[blob][:, None]).sum(axis=0)
    added = (filled[blob] * omega[blob][:, None]).sum(axis=0)
    sun_light.rgb = removed - added
    return sun_light, filled


def probe_lights(env: np.ndarray, count: int = 16, detect_sun: bool = True,
                 sun: SunSettings | None = None) -> list[DirectionalLight]:
    """The lights of a probe: its sun (if any and ``detect_sun``) first, then ``count`` median-cut
    lights of the rest. Their rgb add up to the probe's ∫ L dΩ."""
    env = _prepare(env)
    lights = []
    if detect_sun:
        sun_light, env = split_sun(env, sun)
        if sun_light is not None:
            lights.append(sun_light)
    return lights + median_cut(env, count)


def irradiance(lights: list[DirectionalLight], normals: np.ndarray) -> np.ndarray:
    """Irradiance the lights deliver to surfaces with the given unit normals (..., 3) -> (..., 3),
    ignoring shadows: Σ rgb · max(0, N·d)."""
    normals = np.asarray(normals, dtype=np.float64)
    out = np.zeros(normals.shape[:-1] + (3,))
    for light in lights:
        out += np.maximum(normals @ light.direction, 0.0)[..., None] * light.rgb
    return out
