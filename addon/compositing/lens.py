"""Lens distortion from calibration to composite (bpy-free): OpenCV's model (k1, k2, p1, p2, k3)
carried into Blender's Movie Clip camera, the render camera that sees the whole distorted frame
(overscan), the ST-map that redistorts the CG onto the plate, and the undistorted plate that
the viewport shows behind phantoms.

Pixel conventions: OpenCV pixel centres sit at integers, y down; Blender's Movie Clip camera
and images count from the bottom-left corner, pixel centres at +0.5 (both measured, see
docs/compositing.md, *Lens distortion*).

Why the CG is rendered at the plate's size with a wider field of view and not with extra
pixels: a Blender render's compositor output always has the render's size, and a scene whose
Render Layers another scene's compositor uses is rendered at that scene's size (measured in
Blender 5.2), so the overscan is paid for in pixel density (``RenderFrame.scale`` < 1).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import PlateLightError

# OpenCV's coefficient order; Blender's Brown model has k1..k4 (r^2..r^8) and p1, p2.
OPENCV_NAMES = ("k1", "k2", "p1", "p2", "k3")
# ST-map / background margin (pixels of the plate) so bilinear filtering has data at the rim.
MARGIN_PX = 2.0


def _dist5(dist) -> np.ndarray:
    d = np.zeros(5)
    dist = np.asarray(dist, np.float64).reshape(-1)
    if dist.size > 5 and np.any(dist[5:] != 0):
        raise PlateLightError(
            "The calibration uses OpenCV's rational or thin-prism terms (k4..k6, s1..s4), which "
            "Blender's lens models cannot carry; calibrate with k1, k2, p1, p2, k3 only.")
    d[:min(5, dist.size)] = dist[:5]
    return d


def has_distortion(dist) -> bool:
    return bool(np.any(np.asarray(dist, np.float64) != 0))


def distort_normalized(x, y, dist):
    """OpenCV's forward model on normalised image coordinates (x = X/Z, y = Y/Z, y down)."""
    k1, k2, p1, p2, k3 = _dist5(dist)
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return (x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
            y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y)


def undistort_normalized(xd, yd, dist, iterations=40):
    """Inverse of ``distort_normalized`` by Newton's method (its Jacobian written out), to
    1e-12 where the model is invertible."""
    k1, k2, p1, p2, k3 = _dist5(dist)
    x, y = np.array(xd, np.float64), np.array(yd, np.float64)
    for _ in range(iterations):
        fx, fy = distort_normalized(x, y, dist)
        ex, ey = fx - xd, fy - yd
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        d_radial = k1 + r2 * (2 * k2 + 3 * k3 * r2)        # d radial / d r2
        a = radial + 2 * x * x * d_radial + 2 * p1 * y + 6 * p2 * x
        b = 2 * x * y * d_radial + 2 * p1 * x + 2 * p2 * y
        c = b                                               # the Jacobian is symmetric
        d = radial + 2 * y * y * d_radial + 6 * p1 * y + 2 * p2 * x
        det = a * d - b * c
        x = x - (d * ex - b * ey) / det
        y = y - (a * ey - c * ex) / det
        if max(np.abs(ex).max(initial=0), np.abs(ey).max(initial=0)) < 1e-13:
            break
    return x, y


def clip_camera_settings(fx, fy, cx, cy, dist, width, height) -> dict:
    """Blender Movie Clip camera fields (``clip.tracking.camera``) for an OpenCV calibration.

    Blender's 'BROWN' model is libmv's: radial k1..k4 on r^2..r^8 and a tangential pair whose
    p1 multiplies (r^2 + 2x^2), in image coordinates with y up. OpenCV's p2 multiplies
    (r^2 + 2x^2) with y down, so Blender p1 = OpenCV p2 and Blender p2 = -OpenCV p1 (the y flip);
    k1..k3 carry over. Blender normalises by one focal length and a pixel aspect; the principal
    point is in pixels from the bottom-left corner (OpenCV's cx + 0.5, height - cy - 0.5)."""
    k1, k2, p1, p2, k3 = _dist5(dist)
    return {
        "distortion_model": "BROWN",
        "units": "PIXELS",
        "focal_length_pixels": float(fx),
        "pixel_aspect": 1.0,
        "principal_point_pixels": (float(cx) + 0.5, float(height) - float(cy) - 0.5),
        "brown_k1": float(k1), "brown_k2": float(k2), "brown_k3": float(k3), "brown_k4": 0.0,
        "brown_p1": float(p2), "brown_p2": float(-p1),
    }


@dataclasses.dataclass(frozen=True)
class RenderFrame:
    """The render camera of a distorted plate: a pinhole with the plate's pixel count whose
    field of view holds the undistorted image of the whole distorted frame.
    Render pixel (OpenCV convention) = scale * (ideal pixel - centre) + ((W-1)/2, (H-1)/2)."""
    width: int
    height: int
    scale: float
    centre: tuple      # (u, v) ideal-pixel point that lands in the render's middle

    def ideal_to_render(self, u, v):
        return (self.scale * (u - self.centre[0]) + (self.width - 1) / 2,
                self.scale * (v - self.centre[1]) + (self.height - 1) / 2)

    def render_to_ideal(self, rx, ry):
        return ((rx - (self.width - 1) / 2) / self.scale + self.centre[0],
                (ry - (self.height - 1) / 2) / self.scale + self.centre[1])

    def intrinsics(self, fx, fy, cx, cy):
        """(fx, fy, cx, cy) of the render camera, OpenCV convention."""
        rx, ry = self.ideal_to_render(cx, cy)
        return fx * self.scale, fy * self.scale, rx, ry


def _check_monotonic(fx, fy, cx, cy, dist, width, height):
    """Refuse a calibration whose model folds back inside the frame (high-order terms fitted
    to a few views): there the distorted image is not a function of the undistorted one."""
    corner = max(np.hypot(-cx / fx, -cy / fy), np.hypot((width - 1 - cx) / fx, -cy / fy),
                 np.hypot(-cx / fx, (height - 1 - cy) / fy),
                 np.hypot((width - 1 - cx) / fx, (height - 1 - cy) / fy))
    r = np.linspace(0, corner * 1.05, 512)
    rd, _ = distort_normalized(r, np.zeros_like(r), dist)
    if np.any(np.diff(rd) <= 0):
        raise PlateLightError(
            "The calibration's distortion folds back inside the frame (its radial curve stops "
            "growing), so the plate cannot be undistorted; calibrate from more views that fill "
            "the frame, or fit fewer terms (k1, k2 only).")


def render_frame(fx, fy, cx, cy, dist, width, height) -> RenderFrame:
    """The overscan render frame: undistorts the plate's border (pixel edges plus MARGIN_PX) and
    scales the pinhole so that box fits in width x height."""
    if not has_distortion(_dist5(dist)):
        return RenderFrame(int(width), int(height), 1.0, ((width - 1) / 2, (height - 1) / 2))
    _check_monotonic(fx, fy, cx, cy, dist, width, height)
    m = MARGIN_PX
    n = 256
    xs = np.linspace(-0.5 - m, width - 0.5 + m, n)
    ys = np.linspace(-0.5 - m, height - 0.5 + m, n)
    border = np.concatenate([np.stack([xs, np.full(n, ys[0])], 1), np.stack([xs, np.full(n, ys[-1])], 1),
                             np.stack([np.full(n, xs[0]), ys], 1), np.stack([np.full(n, xs[-1]), ys], 1)])
    xu, yu = undistort_normalized((border[:, 0] - cx) / fx, (border[:, 1] - cy) / fy, dist)
    u, v = fx * xu + cx, fy * yu + cy
    # the plate's own box (pixel edges) is always inside: pincushion needs no overscan
    u0, u1 = min(u.min(), -0.5), max(u.max(), width - 0.5)
    v0, v1 = min(v.min(), -0.5), max(v.max(), height - 0.5)
    scale = min(width / (u1 - u0), height / (v1 - v0), 1.0)
    return RenderFrame(int(width), int(height), float(scale), ((u0 + u1) / 2, (v0 + v1) / 2))


def st_map(fx, fy, cx, cy, dist, width, height, frame: RenderFrame) -> np.ndarray:
    """(H, W, 3) float32 for Blender's Map UV node, first row = top of the plate: for each plate
    pixel, where the undistorted render shows that point (U, V in [0, 1] from the bottom-left
    corner, Blender's convention) and 1 in the third channel (Map UV's mask)."""
    j, i = np.mgrid[0:height, 0:width].astype(np.float64)
    xu, yu = undistort_normalized((i - cx) / fx, (j - cy) / fy, dist)
    rx, ry = frame.ideal_to_render(fx * xu + cx, fy * yu + cy)
    u = (rx + 0.5) / frame.width
    v = 1.0 - (ry + 0.5) / frame.height
    return np.stack([u, v, np.ones_like(u)], -1).astype(np.float32)


def undistort_to_render(image: np.ndarray, fx, fy, cx, cy, dist, frame: RenderFrame) -> np.ndarray:
    """The plate as the render camera sees it (undistorted, in the overscan frame): what the
    viewport shows behind phantoms. Outside the plate: 0."""
    import cv2

    j, i = np.mgrid[0:frame.height, 0:frame.width].astype(np.float64)
    u, v = frame.render_to_ideal(i, j)
    xd, yd = distort_normalized((u - cx) / fx, (v - cy) / fy, dist)
    map_x = (fx * xd + cx).astype(np.float32)
    map_y = (fy * yd + cy).astype(np.float32)
    return cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def blender_camera_fields(fx, fy, cx, cy, width, height, sensor_width) -> dict:
    """A Blender perspective camera (horizontal sensor fit) and render pixel aspect that image
    like the pinhole (fx, fy, cx, cy) on width x height pixels (OpenCV convention)."""
    # Non-square pixels (fx != fy): Blender's pixel aspect is width/height of a pixel = fy/fx,
    # and both of its fields must be >= 1. Calibrations within 0.5 % keep square pixels.
    ratio = fy / fx
    if abs(ratio - 1) < 0.005:
        ratio = 1.0
    return {
        "lens": fx * sensor_width / width,
        # OpenCV's principal point (pixel centres at integers) -> Blender's shift (image widths)
        "shift_x": -(cx - (width - 1) / 2) / width,
        "shift_y": (cy - (height - 1) / 2) / width,
        "pixel_aspect_x": max(ratio, 1.0),
        "pixel_aspect_y": max(1.0 / ratio, 1.0),
    }
