"""Independent brute-force references for the engine's maps, written without the engine's code.

Directions and texel solid angles are derived here again from design.md's formulas; the
convolution is a direct sum over every source texel: value(n) = Σ L(ω)·k(n·ω)·ΔΩ(ω)."""
from __future__ import annotations

import numpy as np


def texel_grid(height: int):
    """Directions (H*W, 3) and exact solid angles (H*W,) of a (height, 2*height) lat-long map."""
    width = 2 * height
    u = (np.arange(width) + 0.5) / width
    v = 1.0 - (np.arange(height) + 0.5) / height
    az = 2 * np.pi * (u - 0.5)                       # atan2(-y, x)
    el = np.pi * (v - 0.5)
    d = np.empty((height, width, 3))
    d[..., 0] = np.cos(el)[:, None] * np.cos(az)[None, :]
    d[..., 1] = -np.cos(el)[:, None] * np.sin(az)[None, :]
    d[..., 2] = np.sin(el)[:, None]
    top = np.pi / 2 - np.pi * np.arange(height) / height
    bottom = top - np.pi / height
    sa = (2 * np.pi / width) * (np.sin(top) - np.sin(bottom))
    return d.reshape(-1, 3), np.repeat(sa, width)


def phong_kernel(exponent: float):
    return lambda c: (exponent + 1) / (2 * np.pi) * np.maximum(c, 0.0) ** exponent


def ggx_kernel(roughness: float):
    """The directions a GGX surface (alpha = roughness²) seen head-on reflects into, as a function
    of their angle θ from the mirror direction: D at the half vector (θ/2) times Smith's G1 of the
    outgoing direction, normalised to integrate to 1 over the sphere."""
    a2 = roughness ** 4

    def weight(c):
        c = np.clip(c, -1.0, 1.0)
        cos_h2 = (1.0 + c) / 2.0                      # cos²(θ/2)
        d = a2 / (np.pi * (cos_h2 * (a2 - 1.0) + 1.0) ** 2)
        tan2 = (1.0 - c * c) / np.maximum(c * c, 1e-300)
        g1 = 2.0 / (1.0 + np.sqrt(1.0 + a2 * tan2))
        return np.where(c > 0.0, d * g1, 0.0)

    theta = np.linspace(0.0, np.pi / 2, 400001)
    f = weight(np.cos(theta)) * np.sin(theta)
    norm = 2 * np.pi * np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(theta))     # trapezoids (numpy 1 and 2)
    return lambda c: weight(c) / norm


def convolve(env: np.ndarray, kernel, out_height: int, chunk: int = 64) -> np.ndarray:
    """Brute-force spherical convolution of a lat-long map, evaluated at an output grid's texels."""
    src_dirs, sa = texel_grid(env.shape[0])
    src = env.reshape(-1, env.shape[2]).astype(np.float64) * sa[:, None]
    out_dirs, _ = texel_grid(out_height)
    out = np.empty((out_dirs.shape[0], env.shape[2]))
    for s in range(0, out_dirs.shape[0], chunk):
        out[s:s + chunk] = kernel(out_dirs[s:s + chunk] @ src_dirs.T) @ src
    return out.reshape(out_height, 2 * out_height, env.shape[2])


def box_downsample(env: np.ndarray, out_height: int) -> np.ndarray:
    """The specular reference: the solid-angle-weighted mean of the source over each output texel."""
    h = env.shape[0]
    f = h // out_height
    _, sa = texel_grid(h)
    sa = sa.reshape(h, 2 * h, 1)
    num = (env * sa).reshape(out_height, f, 2 * out_height, f, -1).sum(axis=(1, 3))
    den = sa.reshape(out_height, f, 2 * out_height, f, 1).sum(axis=(1, 3))
    return num / den


def reference_map(env: np.ndarray, name: str, out_height: int,
                  glossy1_exponent: float = 8.0, glossy2_exponent: float = 64.0,
                  ggx_roughness: float | None = None) -> np.ndarray:
    if name == "specular":
        return box_downsample(env, out_height)
    if ggx_roughness is not None:
        return convolve(env, ggx_kernel(ggx_roughness), out_height)
    exponent = {"diffuse": 1.0, "glossy1": glossy1_exponent, "glossy2": glossy2_exponent}[name]
    return convolve(env, phong_kernel(exponent), out_height)


def relative_rms(value: np.ndarray, reference: np.ndarray) -> float:
    """Solid-angle weighted RMS error relative to the reference's RMS (all channels)."""
    _, sa = texel_grid(reference.shape[0])
    w = sa.reshape(reference.shape[0], reference.shape[1], 1)
    err = np.sqrt((w * (value - reference) ** 2).sum() / w.sum())
    return float(err / np.sqrt((w * reference ** 2).sum() / w.sum()))


def anisotropic_ggx(env: np.ndarray, alpha_t: float, alpha_b: float, normals, tangents, view,
                    height: int) -> np.ndarray:
    """Brute-force GGX reflection per pixel (D and height-correlated Smith G2 with the projected
    alpha; alpha_t along the tangent, alpha_b across it; no Fresnel), normalised over the
    hemisphere, of ``env`` box-downsampled to ``height`` rows. alpha_t = alpha_b is isotropic GGX."""
    dirs, solid = texel_grid(height)
    radiance = (box_downsample(env, height) if env.shape[0] != height else env).reshape(-1, 3)
    out = []
    for normal, tangent in zip(normals, tangents):
        bitangent = np.cross(normal, tangent)
        above = dirs @ normal > 0
        light = dirs[above]
        half = light + view
        half /= np.linalg.norm(half, axis=1, keepdims=True)
        d = 1 / (np.pi * alpha_t * alpha_b * ((half @ tangent / alpha_t) ** 2
                                              + (half @ bitangent / alpha_b) ** 2
                                              + (half @ normal) ** 2) ** 2)

        def smith(w):
            projected = ((w @ tangent) * alpha_t) ** 2 + ((w @ bitangent) * alpha_b) ** 2
            return (np.sqrt(1 + projected / np.maximum((w @ normal) ** 2, 1e-12)) - 1) / 2
        weight = d / (1 + smith(view[None])[0] + smith(light)) * solid[above]
        out.append((weight[:, None] * radiance[above]).sum(0) / weight.sum())
    return np.array(out)


def tangents_about_z(normals) -> np.ndarray:
    """The SBRDF frame's tangent: circles around the Z axis (unit; normals off the poles)."""
    t = np.stack([-normals[:, 1], normals[:, 0], np.zeros(len(normals))], -1)
    return t / np.linalg.norm(t, axis=1, keepdims=True)


def sky_with_sun(height: int, sun: float) -> np.ndarray:
    """A lat-long sky brighter above than below, with one bright texel 45 degrees up towards +Y."""
    elevation = np.pi * (0.5 - (np.arange(height) + 0.5) / height)
    env = np.zeros((height, 2 * height, 3), np.float32)
    env[:] = (0.2 + 2.0 * np.clip(np.sin(elevation), 0, 1) ** 2)[:, None, None]
    env[height // 4, height // 2] = sun
    return env


def sphere_facing_x(pixels: int = 24):
    """Unit normals of an orthographic sphere seen along -X (from +X), pixels across."""
    ys, zs = np.meshgrid(np.linspace(-0.97, 0.97, pixels), np.linspace(-0.97, 0.97, pixels))
    inside = ys ** 2 + zs ** 2 < 0.97 ** 2
    return np.stack([np.sqrt(1 - ys[inside] ** 2 - zs[inside] ** 2), ys[inside], zs[inside]], -1)
