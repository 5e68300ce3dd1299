"""Distance maps: how far the probe's centre sees in each direction (bpy-free).

A probe baked at an object's centre shows a nearby thing (the floor under a ball, a box beside
it) in the direction it has from the *centre*; seen from a point on the object's surface it lies
elsewhere. With the distance r(d) of the surface the centre sees along each direction d, a
reflected ray x(t) = p + t R (p: the shading point relative to the centre) can be followed to the
surface it meets, as in distance impostors (Szirmay-Kalos, Aszódi, Lazányi, Premecz 2005,
"Approximate ray-tracing on the GPU with distance impostors"): the ray has met the surface where

    s(t) = |p + t R| - r(p + t R)

turns positive. A linear search over geometric steps t_k = |p| T0 2^k (k = 0..STEPS-1, scale
free: the steps follow the object's size) brackets the first sign change, and SECANT_STEPS secant
steps refine it; without a crossing the ray escapes and keeps its direction. The maps are then read
along p + t R instead of R. (A plain fixed point r_{k+1} = r(p + t_k R) oscillated near a box's
edges: its reflection's IoU fell from 0.70 at 3 iterations to 0.64 at 6.)
``parallax_directions`` is the numpy reference of what the probe node group computes
(node_groups/probe_maps.py).

The map is rendered from the probe's centre with every surface emitting Camera Data's View
Distance, which for an equirectangular camera is the radial distance from its centre
(tests/blender/test_parallax.py checks it on a floor seen at known angles); the sky (a
transparent texel) reads as FAR, so a look-up towards it keeps its direction.
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import PlateLightError
from ..exr_io import write_exr
from ..fileio import remove_if_present
from .equirect import xyz_to_uv

DISTANCE_NAME = "distance"
VERSION = 1                  # part of the probe hash: bakes without a distance map are redone
# "nothing here": look-ups along it keep their direction (to 1e-4 rad for points 1 m from the
# centre). Not larger: GPU textures may hold it as half floats (max 65504).
FAR = 1.0e4
STEPS = 12                   # t from 0.1 |p| to 205 |p|
STEP_START = 0.1
SECANT_STEPS = 3
# The layer behind (what the centre sees past its first surface): a ray whose search ends on a
# jump of the distance map, not on a surface, passed behind a near occluder as the centre sees
# it, and the layer behind tells what it meets there. The search's bracket is narrowed by
# BEHIND_BISECT bisection steps after the secant ones; a jump is where the surfaces at its two
# ends are still more than BEHIND_JUMP times the hit's distance apart. Only occluders within
# BEHIND_NEAR |p| of the centre count: a floor seen near the horizon jumps by as much between two
# texels of the map (a nearest-texel look-up), and only maps at least BEHIND_MIN_HEIGHT high are
# fine enough for that (on an endless floor no ray of 20000 read the layer behind at 256 or 1024
# texels high). Rays past a box's edges (tests/blender/test_parallax.py): 97 % find what they
# meet (17 % without the layer behind); rays whose hit the centre sees: 97 % right, 88 %
# without the bisection, 0.6 % read the layer behind.
BEHIND_NAME = "behind"       # distance_behind.exr, specular_behind.exr
BEHIND_MAPS = ("specular",)  # the maps read behind the first surface (a mirror's)
BEHIND_VERSION = 1           # part of the probe hash of a probe with the layer behind
BEHIND_JUMP = 0.2
BEHIND_NEAR = 10.0
BEHIND_MIN_HEIGHT = 256
BEHIND_BISECT = 4            # a bracket holding a silhouette and the surface past it: narrowed
                             # to one of them (2: 1.8 % of the seen rays read the layer behind)
BEHIND_STEPS = 10            # t from the occluder on, growing by BEHIND_GROWTH a step
BEHIND_GROWTH = 2.0 ** 0.5


def behind_name(name: str) -> str:
    """A map's (or the distance map's) name in the layer behind the first surface."""
    return f"{name}_{BEHIND_NAME}"


def _filename(stem: str, frame: int | None) -> str:
    return f"{stem}.exr" if frame is None else f"{stem}_{int(frame):04d}.exr"


def distance_filename(frame: int | None = None, behind: bool = False) -> str:
    return _filename(behind_name(DISTANCE_NAME) if behind else DISTANCE_NAME, frame)


def behind_filename(map_name: str, frame: int | None = None) -> str:
    """The file of a map's layer behind the first surface (``specular_behind.exr``)."""
    return _filename(behind_name(map_name), frame)


def read_depth(path) -> np.ndarray:
    """The Depth (Z) plane of a multilayer EXR written by Blender, float32 (H, W)."""
    import OpenEXR

    path = os.fspath(path)
    try:
        with OpenEXR.File(path, separate_channels=True) as exr:
            channels = exr.channels()
            name = next((n for n in channels if n == "Z" or n.endswith(".Z")), None)
            if name is None:
                raise PlateLightError(f"The probe render {path} has no Depth pass (channels {sorted(channels)}).")
            return np.asarray(channels[name].pixels, dtype=np.float32)
    except OSError as exc:
        raise PlateLightError(f"Cannot read the probe render {path}: {exc}") from None


def distance_map(depth: np.ndarray, clip_end: float) -> tuple[np.ndarray, list[str]]:
    """The distance map (H, W) float32 from a panorama's Depth pass, and warnings.

    Texels that saw nothing (at or past ``clip_end``, or not finite) become FAR; texels at zero
    distance (the probe's centre inside or on another object) are kept but reported, because a
    lookup there cannot be corrected (the node group clamps the radius to the shading point's
    own distance, which keeps the direction sensible but not right)."""
    depth = np.asarray(depth, dtype=np.float32)
    far = ~np.isfinite(depth) | (depth >= 0.999 * clip_end) | (depth > 0.1 * FAR)
    out = np.where(far, np.float32(FAR), np.maximum(depth, 0.0)).astype(np.float32)
    warnings = []
    zero = (~far) & (depth <= 1e-6)
    if zero.any():
        warnings.append(f"{100.0 * zero.mean():.1f} % of the distance map is at zero distance "
                        "(the probe's centre touches or is inside another object): reflections "
                        "there are not parallax-corrected")
    return out, warnings


def near_silhouette(distance: np.ndarray, reach: float) -> bool:
    """Does the map show an occluder's edge within BEHIND_NEAR ``reach`` of the centre (``reach``:
    how far the object's surface extends from it): a texel that near whose neighbour (across
    the edge) is more than BEHIND_JUMP farther? Only then can a reflected ray pass behind
    something, and only then is the layer behind worth its renders and its look-ups (a ball on
    a plain floor: none)."""
    d = np.asarray(distance, dtype=np.float64)
    near = d < BEHIND_NEAR * float(reach)
    if not near.any():
        return False
    farther = np.zeros_like(near)
    for neighbour in (np.roll(d, 1, axis=1), np.roll(d, -1, axis=1)):    # the seam wraps
        farther |= neighbour > (1.0 + BEHIND_JUMP) * d
    farther[1:] |= d[:-1] > (1.0 + BEHIND_JUMP) * d[1:]
    farther[:-1] |= d[1:] > (1.0 + BEHIND_JUMP) * d[:-1]
    return bool((near & farther).any())


def coverage_warning(distance: np.ndarray, offsets: np.ndarray) -> str | None:
    """A sentence when the object's surface (``offsets``: its points relative to the probe
    centre, (N, 3)) reaches past the surfaces its distance map holds in more than 2 % of its
    points: there the object pokes through what its probe saw (an object larger than its
    distance map can serve), the iteration is clamped and those reflections are not corrected."""
    offsets = np.asarray(offsets, dtype=np.float64).reshape(-1, 3)
    if not len(offsets):
        return None
    reach = np.linalg.norm(offsets, axis=-1)
    beyond = reach > 1.02 * _equirect_lookup(distance, offsets) + 1e-6
    if beyond.mean() > 0.02:
        return (f"{100.0 * beyond.mean():.0f} % of the object's surface lies beyond the surfaces its "
                "probe sees (it reaches through a phantom or another object): parallax correction "
                "is clamped there; move the probe origin or split the object")
    return None


def write_distance(folder, distance: np.ndarray, frame: int | None = None, behind: bool = False) -> str:
    """Write the map as an RGB EXR (the same value in each channel, so an Environment Texture
    reads it as a colour whose luminance is the distance)."""
    path = os.path.join(os.fspath(folder), distance_filename(frame, behind))
    write_exr(path, np.repeat(np.asarray(distance, np.float32)[..., None], 3, axis=2))
    return path


def remove_distance(folder, frame: int | None = None) -> None:
    """Remove a distance map no longer wanted (the object's material became matte)."""
    remove_if_present(os.path.join(os.fspath(folder), distance_filename(frame)))


def behind_filenames(frame: int | None = None) -> list[str]:
    """The files of the layer behind: its distance map and its maps."""
    return [distance_filename(frame, behind=True)] + [behind_filename(n, frame) for n in BEHIND_MAPS]


def write_behind(folder, specular: np.ndarray, distance: np.ndarray, frame: int | None = None) -> None:
    """Write the layer behind the first surface: its specular map and its distance map."""
    folder = os.fspath(folder)
    write_exr(os.path.join(folder, behind_filename("specular", frame)), np.asarray(specular, np.float32))
    write_distance(folder, distance, frame, behind=True)


def remove_behind(folder, frame: int | None = None) -> None:
    """Remove the layer behind (the object is no longer a sharp reflector, or the scene's Layer
    Behind is off)."""
    for filename in behind_filenames(frame):
        remove_if_present(os.path.join(os.fspath(folder), filename))


def _equirect_lookup(distance: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Nearest-texel lookup in the Environment Texture's layout (equirect.py)."""
    d = np.asarray(directions, dtype=np.float64)
    return _lookup_xyz(distance, d[..., 0], d[..., 1], d[..., 2])


def _lookup_xyz(distance: np.ndarray, x, y, z) -> np.ndarray:
    """_equirect_lookup of directions given as component arrays, in their precision."""
    h, w = distance.shape
    u, v = xyz_to_uv(x, y, z)
    col = np.clip((u * w).astype(np.intp), 0, w - 1)
    row = np.clip(((1.0 - v) * h).astype(np.intp), 0, h - 1)
    return distance.ravel()[row * w + col]


def parallax_directions(distance: np.ndarray, p: np.ndarray, reflected: np.ndarray) -> np.ndarray:
    """Corrected look-up directions for shading points ``p`` (relative to the probe centre,
    (..., 3)) and reflected directions ``reflected`` (..., 3): the reference of the node group."""
    return parallax_search(distance, p, reflected)[0]


def parallax_search(distance: np.ndarray, p: np.ndarray, reflected: np.ndarray):
    """(corrected directions, footprint ratios) for shading points ``p`` and reflected
    directions: the node group's search. The footprint ratio is the hit's distance from the
    shading point over its distance from the probe centre (1 where the ray escapes): a lobe of a
    given angle seen from the point covers that fraction of the width it covers from the centre,
    where the maps were blurred (maps.footprint_glossiness).

    Computed in float32 when ``p`` and ``reflected`` both are (the bake's irradiance grid), else
    float64, on component arrays (numpy's reductions over a last axis of 3 are slow)."""
    rays = _Rays(p, reflected)
    found, t, _, _ = rays.crossing(distance, np.zeros_like(rays.length), rays.length * STEP_START, 2.0, STEPS)
    look, ratio = rays.looks(found, t)
    return rays.shaped(look, 3), rays.shaped(ratio)


def parallax_layers(distance: np.ndarray, behind: np.ndarray, p: np.ndarray, reflected: np.ndarray):
    """(directions, footprint ratios, behind weights): parallax_search with the layer behind the
    first surface (``behind``: its distance map), the reference of the node group that reads it.

    The first layer's search is refined further (BEHIND_BISECT). A ray whose search ends on a
    jump of the distance map (BEHIND_JUMP) at an occluder nearer than BEHIND_NEAR |p| passed
    beside it, behind it as the centre sees it. It is followed on from there through the layer
    behind. The surface it meets is read from the first layer where the centre sees it (weight
    0), else from the layer behind (weight 1)."""
    rays = _Rays(p, reflected)
    found, t, t_behind, gap = rays.crossing(distance, np.zeros_like(rays.length), rays.length * STEP_START, 2.0,
                                            STEPS, BEHIND_BISECT)
    look, ratio = rays.looks(found, t)
    weight = np.zeros_like(rays.length)
    jump = gap > BEHIND_JUMP * _norm(rays.points(t))
    near = _lookup_xyz(distance, *rays.points(t_behind)) < BEHIND_NEAR * rays.length
    passed = np.flatnonzero(found & jump & near)
    if len(passed):
        sub = rays.subset(passed)
        found2, t2, _, _ = sub.crossing(behind, t[passed], t_behind[passed], BEHIND_GROWTH, BEHIND_STEPS)
        look2, ratio2 = sub.looks(found2, t2)
        # the point the ray meets (or, escaping, its point at FAR): does the centre see it?
        far = sub.points(np.where(found2, t2, FAR))
        seen = _norm(far) <= (1.0 + BEHIND_JUMP) * _lookup_xyz(distance, *far)
        look[passed], ratio[passed] = look2, ratio2
        weight[passed] = np.where(seen, 0.0, 1.0)
    return rays.shaped(look, 3), rays.shaped(ratio), rays.shaped(weight)


def _norm(v):
    return np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


class _Rays:
    """Shading points (relative to the probe centre) and their unit reflected directions, as
    flat component arrays (float32 when both inputs are, else float64)."""

    def __init__(self, p, reflected, shape=None):
        if shape is not None:                     # already flat components (subset)
            self.p, self.r, self.shape = p, reflected, shape
        else:
            dtype = np.float32 if np.result_type(p, reflected) == np.float32 else np.float64
            p, reflected = np.broadcast_arrays(np.asarray(p, dtype), np.asarray(reflected, dtype))
            self.shape = p.shape[:-1]
            self.p = [np.ascontiguousarray(p[..., i]).reshape(-1) for i in range(3)]
            r = [np.ascontiguousarray(reflected[..., i]).reshape(-1) for i in range(3)]
            r_len = _norm(r)
            self.r = [c / r_len for c in r]
        self.length = _norm(self.p)

    def subset(self, index):
        return _Rays([c[index] for c in self.p], [c[index] for c in self.r], shape=(len(index),))

    def shaped(self, values, components=None):
        return values.reshape(*self.shape, components) if components else values.reshape(self.shape)

    def points(self, t):
        return [a + t * b for a, b in zip(self.p, self.r)]

    def crossing(self, distance, t_start, t_first, growth, steps, bisect=0):
        """(found, t, t_b, gap) per ray: the first of the steps t_first growth^k (k < steps) where
        s(t) = |p + t R| - r(p + t R) turns positive after t_start (s there taken as at most
        -1e-4), refined by SECANT_STEPS secant steps and ``bisect`` bisection steps (t), the step
        that first had s > 0 (t_b), and |r_b - r_a| at the refined bracket's ends (gap; None
        without bisection steps). Each step evaluates only the rays still unresolved, and the
        refinement only those that crossed: a resolved ray's bracket never changes again."""
        def s(t, pp, rr):
            q = [a + t * b for a, b in zip(pp, rr)]
            return _norm(q) - _lookup_xyz(distance, *q)

        count = len(self.length)
        dtype = self.length.dtype
        t_a, s_a, t_b, s_b = (np.zeros(count, dtype) for _ in range(4))
        rays = np.arange(count)
        open_p, open_r, open_first = self.p, self.r, t_first
        open_t = np.asarray(t_start, dtype)
        open_s = np.minimum(s(open_t, open_p, open_r), -1e-4).astype(dtype)
        for k in range(steps):
            if not len(rays):
                break
            t_k = open_first * growth ** k
            s_k = s(t_k, open_p, open_r)
            crossed = s_k > 0
            ends = rays[crossed]
            t_a[ends], s_a[ends], t_b[ends], s_b[ends] = open_t[crossed], open_s[crossed], t_k[crossed], s_k[crossed]
            stay = ~crossed
            rays, open_first, open_t, open_s = rays[stay], open_first[stay], t_k[stay], s_k[stay]
            open_p, open_r = [c[stay] for c in open_p], [c[stay] for c in open_r]
        found = np.ones(count, bool)
        found[rays] = False
        hits = np.flatnonzero(found)
        hit_p, hit_r = [c[hits] for c in self.p], [c[hits] for c in self.r]
        ta, sa, tb, sb = t_a[hits], s_a[hits], t_b[hits], s_b[hits]
        for k in range(SECANT_STEPS + bisect):
            t_m = ta + (tb - ta) * sa / np.minimum(sa - sb, -1e-9) if k < SECANT_STEPS else 0.5 * (ta + tb)
            s_m = s(t_m, hit_p, hit_r)
            hit = s_m > 0
            tb, sb = np.where(hit, t_m, tb), np.where(hit, s_m, sb)
            ta, sa = np.where(hit, ta, t_m), np.where(hit, sa, s_m)
        t = np.zeros(count, dtype)
        t[hits] = ta + (tb - ta) * sa / np.minimum(sa - sb, -1e-9)
        gap = None
        if bisect:
            # how far apart the surfaces at the bracket's ends are (r = |q| - s): a bracket
            # narrowed onto a surface has them together, one narrowed onto a silhouette keeps
            # them apart
            def reach(t):
                return _norm([a + t * b for a, b in zip(hit_p, hit_r)])

            gap = np.zeros(count, dtype)
            gap[hits] = np.abs(reach(tb) - sb - (reach(ta) - sa))
        return found, t, t_b, gap

    def looks(self, found, t):
        """(unit look-up directions (n, 3), footprint ratios): towards the hit where the ray
        met a surface, along R where it escaped (ratio 1)."""
        hits = np.flatnonzero(found)
        t = t[hits]
        point = [a[hits] + t * b[hits] for a, b in zip(self.p, self.r)]
        reach = _norm(point)
        look = np.stack(self.r, axis=-1)
        look[hits] = np.stack(point, axis=-1) / np.maximum(reach, 1e-30)[:, None]
        ratio = np.ones(len(self.length), self.length.dtype)
        ratio[hits] = np.clip(t / np.maximum(reach, 1e-6), 0.0, 1.0)
        return look, ratio
