"""Independent numpy reference of the extended SBRDF (paper Eq 1-7 as design.md states them),
written from the equations, not from the node group: frame, Lafortune peak, Fresnel, falloff,
map blend and bilinear equirect lookups (Environment Texture convention)."""
from __future__ import annotations

import numpy as np

from platelight.addon.ibl import anisotropy, sun_lobe, view_lobe
from platelight.addon.ibl.maps import glossiness_to_roughness, pulled_roughness
from platelight.addon.ibl.lobe_tilt import tilt_offset

ORDER = ("diffuse", "glossy1", "glossy2", "specular")


def _norm(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(n > 0, v / np.where(n > 0, n, 1), 0.0)


def _dot(a, b):
    return np.sum(a * b, axis=-1, keepdims=True)


def fresnel(p, cos_v):
    """Eq 4 with Fresnel Peak c: f = c (1 - clamp(cos, 0, 1))^(1/phi - 1), phi clamped to >= 1e-4
    (``p`` a parameter dict; c defaults to 1, the paper's)."""
    phi = max(p["fresnel_falloff"], 1e-4)
    return p.get("fresnel_peak", 1.0) * (1.0 - np.clip(cos_v, 0, 1)) ** (1.0 / phi - 1.0)


def equirect_uv(d):
    d = _norm(d)
    u = np.arctan2(-d[..., 1], d[..., 0]) / (2 * np.pi) + 0.5
    v = np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1])) / np.pi + 0.5
    return u, v


def bilinear(img, d):
    """Bilinear lookup with texel centres at half-integers, wrapping in u, clamped in v."""
    h, w, _ = img.shape
    u, v = equirect_uv(d)
    x = u * w - 0.5
    y = (1.0 - v) * h - 0.5
    x0 = np.floor(x).astype(int)
    y0 = np.floor(y).astype(int)
    fx = (x - x0)[..., None]
    fy = (y - y0)[..., None]
    xa, xb = x0 % w, (x0 + 1) % w
    ya, yb = np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)
    top = img[ya, xa] * (1 - fx) + img[ya, xb] * fx
    bot = img[yb, xa] * (1 - fx) + img[yb, xb] * fx
    return top * (1 - fy) + bot * fy


def near_pole(d, maps, margin_texels=1.0):
    """True where a lookup falls within ``margin`` texel rows of a pole (Cycles wraps there)."""
    _, v = equirect_uv(d)
    h = min(m.shape[0] for m in maps.values())
    return (v * h < margin_texels) | ((1 - v) * h < margin_texels)


def blend(maps, d, n):
    t = np.clip(n, 0, 1) * 3.0
    out = 0.0
    for k, name in enumerate(ORDER):
        w = np.maximum(0.0, 1.0 - np.abs(t - k))
        out = out + w * bilinear(maps[name], d)
    return out


def refract(i, n, eta):
    cos_i = _dot(n, i)
    k = 1.0 - eta * eta * (1.0 - cos_i * cos_i)
    t = eta * i - (eta * cos_i + np.sqrt(np.maximum(k, 0))) * n
    return np.where(k < 0, 0.0, t)


def sbrdf(P, view, maps, p, sun=None, sunless=None, rungs=None):
    """Lr per point. P: (..., 3) object-space positions on a unit sphere at the origin (the
    shading normal is P/|P|, the tangent circles the object Z axis); view: surface->viewer.
    ``sun`` (a lights.DirectionalLight) and ``sunless`` (the sunless maps by name): the specular
    look-ups read those maps and add the sun through the lobe (addon/ibl/sun_lobe.py). ``rungs``
    (view_lobe.RUNGS by name): the view-dependent ladder's look-ups (addon/ibl/view_lobe.py)."""
    N = _norm(P)
    R = np.broadcast_to(_norm(view), N.shape)
    t0 = np.stack([-P[..., 1], P[..., 0], np.zeros(P.shape[:-1])], axis=-1)
    T = _norm(t0 - _dot(t0, N) * N)
    B = np.cross(N, T)
    th = p["tangent_rotation"]
    Tr = np.cos(th) * T + np.sin(th) * B
    Br = np.cross(N, Tr)
    rt, rb, rn = _dot(R, Tr), _dot(R, Br), _dot(R, N)
    peak = p["cx"] * rt * Tr + p["cy"] * rb * Br + p["cz"] * rn * N
    w = p["retro_reflection"]
    peak = (1 - w) * peak + w * R
    g = np.maximum(_dot(N, peak), 0.0)
    f = fresnel(p, rn)
    rho_s = np.asarray(p["specular_albedo"]) + (1 - np.asarray(p["specular_albedo"])) * f
    amount = p.get("anisotropy", 0.0)
    narrow = anisotropy.narrow_glossiness(p["glossiness"], amount)
    n2 = narrow + (1 - narrow) * f
    g2 = g + (1 - g) * f
    g2 = 1.0 + p.get("paper_falloff", 0.0) * (g2 - 1.0)   # 0: no cosine; 1: the paper's g'
    rho_d = np.asarray(p["diffuse_albedo"])
    a = p["alpha"]
    paper = p.get("paper_falloff", 0.0)       # 0: the diffuse layer gets what the specular leaves
    rho_d_layered = paper * rho_d + (1 - paper) * rho_d * (1 - rho_s)
    if sun is None:
        lr = a * rho_d_layered * bilinear(maps["diffuse"], N)
    else:       # the sunless diffuse map and the sun's own Lambert term
        lr = a * rho_d_layered * (bilinear(dict(maps, **(sunless or {}))["diffuse"], N) + sun_lobe.lambert(N, sun))
    spec_dir = _norm(peak)
    # the look-up tilt towards N (its rule is checked against brute force in test_lobe_tilt.py);
    # the paper's model looks up along p
    tilt = tilt_offset(n2[..., 0], np.clip(_dot(N, spec_dir)[..., 0], 0.0, 1.0))[..., None]
    spec_dir = _norm(spec_dir + (1 - paper) * tilt * N)
    # an anisotropic lobe: the maps read along the streak, narrowing with the Fresnel glossiness
    slope = anisotropy.streak_slope(p["glossiness"], amount) * (1 - f[..., 0])
    streak = anisotropy.spread(N, Tr, R, slope)
    sunless = sunless or {}
    specular_maps = dict(maps, **sunless)          # the specular lobe reads every map sunless
    peak_unit = _norm(peak)
    lobe_view = 2 * _dot(N, peak_unit) * N - peak_unit
    if rungs is None:
        weights = view_lobe.ladder_weights(glossiness_to_roughness(n2[..., 0]), with_glossy3=False)
    else:
        # the ladder at the narrowed roughness, the taps spread along the plane of incidence too
        roughness = glossiness_to_roughness(n2[..., 0])
        mu = np.clip(_dot(N, lobe_view)[..., 0], 0.0, 1.0)
        aspect = anisotropy.aspect(amount)
        weight = view_lobe.view_weight(1.0 / aspect, aspect)
        weights = view_lobe.ladder_weights(view_lobe.narrowed_roughness(roughness, mu, weight))
        streak = streak + view_lobe.spread(N, lobe_view, roughness ** 2) * view_lobe.TAP_SCALE * weight
        specular_maps = dict(specular_maps, **rungs)
    taps = anisotropy.tap_directions(spec_dir, streak)
    # the diffuse map read once, along the streak's centre (the probe group does the same)
    w_d = weights[0][..., None]
    specular = sum(sum(w[..., None] * bilinear(specular_maps[name], d)
                       for name, w in zip(view_lobe.LADDER[1:], weights[1:]) if name in specular_maps)
                   for d in taps) / len(taps) + w_d * bilinear(specular_maps["diffuse"], spec_dir)
    if sun is not None:
        # GGX of the Fresnel-sharpened glossiness (widened by the peak's pull at glossiness 0),
        # seen from the view whose mirror is the peak
        gloss = p["glossiness"]
        widened = pulled_roughness(gloss, p["cx"], p["cy"]) - glossiness_to_roughness(gloss)
        alpha = (glossiness_to_roughness(gloss + (1 - gloss) * f[..., 0]) + widened * (1 - f[..., 0])) ** 2
        aspect = anisotropy.aspect(amount)
        share = view_lobe.sun_share(weights)
        specular = specular + share[..., None] * sun_lobe.highlight(N, Tr, lobe_view, alpha / aspect,
                                                                    alpha * aspect, sun, rho_s * g2)
    lr = lr + rho_s * g2 * specular
    refr = np.zeros_like(lr)
    dirs = [spec_dir, N, *taps]
    for c, sign in enumerate((-1.0, 0.0, 1.0)):
        ior = max(p["ior"] + sign * p["dispersion"], 1.0)
        t = refract(-R, N, 1.0 / ior)
        dirs.append(t)
        refr[..., c] = blend(maps, t, n2)[..., c]
    lr = lr + (1 - a) * rho_d * (1 - rho_s) * refr
    lr = lr + np.asarray(p["emission_color"]) * p["emission_strength"]
    return lr, dirs
