"""A synthetic corpus of mirror-ball photos: the ball finder's tuning set, apart from the real
photos it is judged on (shared/data/real, held out).

Each case is traced by an independent forward model: a pinhole (or orthographic) camera, a
mirror sphere of a given reflectance in front of a lat-long environment (Blender's eight bundled
HDRIs, found without importing bpy, and four analytic ones: a hard sun, an overcast sky, a dark
room with small lamps, a night street), a backdrop behind it (the environment itself as the
camera sees it, a dark room, a bright clipped sky, clutter), a stand or a hand, then the camera's
exposure, sensor noise, 8-bit sRGB and JPEG. The truth is the sphere's silhouette, measured on a
3x3 supersampled mask: its centroid and mean radius (a ball off the optical axis projects to an
ellipse). Cases without a ball test that nothing is found."""
from __future__ import annotations

import dataclasses
import importlib.util
import pathlib
from functools import lru_cache

import cv2
import numpy as np

from platelight.addon.capture.mirror_ball import default_camera_rotation, rotation_z
from platelight.addon.exr_io import read_exr
from platelight.addon.ibl.equirect import dir_to_uv, downsample_area, sample_bilinear, texel_directions

ANALYTIC = ("hard_sun", "overcast", "lamp_room", "night_street")
BACKDROPS = ("scene", "dark", "bright", "clutter")
HOLDERS = ("none", "stand", "hand")
SS = 3                                   # sub-pixels a side where the ball is


def bundled_hdris() -> dict[str, pathlib.Path]:
    """Blender's bundled studio-light HDRIs, from the bpy wheel's folder (bpy is not imported)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        return {}
    root = pathlib.Path(list(spec.submodule_search_locations)[0])
    return {p.stem: p for p in sorted(root.glob("*/datafiles/studiolights/world/*.exr"))}


def env_names() -> list[str]:
    return list(bundled_hdris()) + list(ANALYTIC)


@lru_cache(maxsize=16)
def environment(name: str, height: int = 256) -> np.ndarray:
    """The lat-long (height x 2·height x 3, linear) of a bundled HDRI or an analytic one."""
    if name not in ANALYTIC:
        return downsample_area(read_exr(bundled_hdris()[name])[..., :3], height)
    d = texel_directions(height, 2 * height)
    up = np.clip(d[..., 2], 0, 1)[..., None]
    below = d[..., 2] < 0
    if name == "hard_sun":               # blue sky, a sun 0.75 deg across at 40 deg, a dusty ground
        env = np.array([0.25, 0.45, 0.9]) * (0.4 + 0.6 * (1 - up)) * 1.5
        env[below] = (0.25, 0.2, 0.15)
        sun = np.array([0.5, 0.4, np.sin(np.radians(40))])
        env[d @ (sun / np.linalg.norm(sun)) > np.cos(np.radians(0.75))] = (4e4, 3.8e4, 3.4e4)
    elif name == "overcast":             # a soft bright dome, a darker grey ground
        env = np.broadcast_to(0.8 + 0.7 * up, d.shape) * np.array([1.0, 1.0, 1.05])
        env = np.where(below[..., None], np.array([0.15, 0.15, 0.14]), env)
    elif name == "lamp_room":            # dim walls, three small bright lamps, a lit window
        env = 0.03 + 0.02 * np.sin(6 * np.arctan2(d[..., 1], d[..., 0]))[..., None] * np.ones(3)
        for lamp in ((0.6, 0.3, 0.74), (-0.5, 0.6, 0.62), (0.1, -0.8, 0.59)):
            env[d @ (np.array(lamp) / np.linalg.norm(lamp)) > np.cos(np.radians(2.5))] = (300, 240, 160)
        env[(d[..., 0] > 0.85) & (np.abs(d[..., 2] - 0.15) < 0.2)] = (4.0, 4.2, 4.6)
    else:                                # night street: black sky, a row of sodium lamps, wet road
        env = np.full(d.shape, 0.005) + 0.02 * below[..., None]
        for k in range(8):
            a = np.radians(-70 + 20 * k)
            lamp = np.array([np.cos(a), np.sin(a), 0.25])
            env[d @ (lamp / np.linalg.norm(lamp)) > np.cos(np.radians(1.2))] = (800, 420, 90)
    return np.ascontiguousarray(env, dtype=np.float32)


@dataclasses.dataclass(frozen=True)
class Spec:
    env: str
    width: int
    height: int
    size: float                  # ball diameter / the frame's short side (0 = no ball)
    offset: tuple = (0.0, 0.0)   # ball centre in the free room, -1..1 each way
    reflectance: float = 0.75
    camera: str = "perspective"  # or "orthographic"
    backdrop: str = "scene"
    holder: str = "none"
    exposure: float = 0.0        # stops about the frame's auto exposure
    noise: float = 0.0           # read noise (linear, of the auto-exposed mid-grey 0.18)
    jpeg: int = 0                # quality; 0 = PNG
    yaw: float = 0.0             # deg, the camera's heading

    @property
    def label(self) -> str:
        if not self.size:
            return f"no ball, {self.env}, {self.backdrop}, {self.width}x{self.height}"
        return (f"{self.env}, {self.camera[:5]}, {100 * self.size:.0f} %, {self.backdrop}, {self.holder}, "
                f"{self.exposure:+.0f} EV, noise {self.noise:g}, jpeg {self.jpeg or '-'}")


def focal_px(spec: Spec) -> float:
    """The pinhole's focal length: a normal lens (about 43 mm on full frame)."""
    return 1.2 * spec.width


def _clutter(width, height, rng) -> np.ndarray:
    """A cluttered backdrop: rectangles and lines of random greys, a few highlights."""
    img = np.full((height, width, 3), 0.2, np.float32)
    for _ in range(60):
        x, y = rng.integers(0, width), rng.integers(0, height)
        w, h = rng.integers(8, width // 4), rng.integers(8, height // 4)
        cv2.rectangle(img, (int(x), int(y)), (int(x + w), int(y + h)), tuple(float(v) for v in rng.uniform(0.02, 0.9, 3)), -1)
    for _ in range(30):
        p = rng.integers(0, [width, height], size=(2, 2))
        cv2.line(img, tuple(int(v) for v in p[0]), tuple(int(v) for v in p[1]),
                 tuple(float(v) for v in rng.uniform(0.0, 1.5, 3)), int(rng.integers(1, 6)))
    return img


def render(spec: Spec, seed: int = 0):
    """(8-bit BGR photo, truth dict cx, cy, rx, ry in OpenCV pixels or None, linear radiance)."""
    rng = np.random.default_rng(seed)
    env = environment(spec.env)
    w, h = spec.width, spec.height
    to_world = rotation_z(spec.yaw) @ default_camera_rotation()
    focal = focal_px(spec)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    rays = np.stack([(xs - (w - 1) / 2) / focal, -(ys - (h - 1) / 2) / focal, -np.ones_like(xs)], -1)
    backdrop = _lookup(env, rays @ to_world.T)
    ambient = float(np.median(env))          # what lights the stand, the hand and the clutter
    if spec.backdrop == "dark":
        backdrop *= 0.03
    elif spec.backdrop == "bright":          # a sky far brighter than what the ball reflects
        backdrop = backdrop * 0.5 + 8 * ambient
    elif spec.backdrop == "clutter":
        backdrop = _clutter(w, h, rng) * 2 * ambient
    image = backdrop.astype(np.float32)
    truth = None
    if spec.size:
        r = 0.5 * spec.size * min(w, h)
        cx = (w - 1) / 2 + spec.offset[0] * max(0.0, w / 2 - r)
        cy = (h - 1) / 2 + spec.offset[1] * max(0.0, h / 2 - r)
        if spec.holder == "stand":
            cv2.rectangle(image, (int(cx - 0.1 * r), int(cy)), (int(cx + 0.1 * r), h), tuple(ambient * np.array([0.3, 0.3, 0.32])), -1)
        truth = _trace_ball(image, env, to_world, spec, cx, cy, r, focal)
        if spec.holder == "hand":         # fingers over the lower left rim
            for k in range(4):
                a = np.radians(200 + 18 * k)
                cv2.ellipse(image, (int(cx + 0.95 * r * np.cos(a)), int(cy - 0.95 * r * np.sin(a))),
                            (int(0.22 * r), int(0.07 * r)), float(-np.degrees(a)), 0, 360,
                            tuple(ambient * np.array([0.5, 0.3, 0.22])), -1)
    radiance = image
    exposed = radiance * (0.18 / max(float(np.median(radiance.mean(-1))), 1e-6)) * 2.0 ** spec.exposure
    if spec.noise:
        exposed = exposed + rng.normal(0, spec.noise, exposed.shape) * np.sqrt(np.clip(exposed, 0, None) / 0.18 + 0.05)
    srgb = np.where(exposed <= 0.0031308, 12.92 * exposed, 1.055 * np.clip(exposed, 0.0031308, None) ** (1 / 2.4) - 0.055)
    photo = np.round(np.clip(srgb, 0, 1) * 255).astype(np.uint8)[..., ::-1].copy()
    if spec.jpeg:
        ok, data = cv2.imencode(".jpg", photo, [cv2.IMWRITE_JPEG_QUALITY, spec.jpeg])
        photo = cv2.imdecode(data, cv2.IMREAD_COLOR)
    return photo, truth, radiance


def _lookup(env, directions) -> np.ndarray:
    u, v = dir_to_uv(directions)
    return sample_bilinear(env, u, v).astype(np.float32)


def _trace_ball(image, env, to_world, spec, cx, cy, r, focal):
    """Draw the mirror ball over ``image`` (anti-aliased, SS x SS sub-pixels in its box) and
    return its silhouette's centroid and mean radius."""
    h, w = image.shape[:2]
    x0, x1 = max(0, int(cx - 1.2 * r) - 2), min(w, int(cx + 1.2 * r) + 3)
    y0, y1 = max(0, int(cy - 1.2 * r) - 2), min(h, int(cy + 1.2 * r) + 3)
    sub = (np.arange(SS) + 0.5) / SS - 0.5
    ys = (np.arange(y0, y1)[:, None] + sub[None, :]).reshape(-1)
    xs = (np.arange(x0, x1)[:, None] + sub[None, :]).reshape(-1)
    X, Y = np.meshgrid(xs, ys)
    if spec.camera == "orthographic":    # unit ball; rays along -Z from the image plane
        px = np.stack([(X - cx) / r, -(Y - cy) / r], -1)
        inside = (px ** 2).sum(-1) < 1
        nz = np.sqrt(np.clip(1 - (px ** 2).sum(-1), 0, 1))
        normal = np.concatenate([px, nz[..., None]], -1)
        view = np.array([0.0, 0.0, -1.0])
        reflected = view - 2 * (normal @ view)[..., None] * normal
    else:                                # pinhole at the origin; the ball's centre on the ray through (cx, cy)
        aim = np.array([(cx - (w - 1) / 2) / focal, -(cy - (h - 1) / 2) / focal, -1.0])
        aim /= np.linalg.norm(aim)
        centre = aim / np.sin(np.arctan(r / focal))
        d = np.stack([(X - (w - 1) / 2) / focal, -(Y - (h - 1) / 2) / focal, -np.ones_like(X)], -1)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        b = d @ centre
        disc = b * b - (centre @ centre - 1.0)
        inside = disc > 0
        t = b - np.sqrt(np.clip(disc, 0, None))
        normal = t[..., None] * d - centre
        reflected = d - 2 * (d * normal).sum(-1, keepdims=True) * normal
    colour = _lookup(env, reflected @ to_world.T) * spec.reflectance
    coverage = inside.reshape(y1 - y0, SS, x1 - x0, SS).mean(axis=(1, 3))
    ball = (colour * inside[..., None]).reshape(y1 - y0, SS, x1 - x0, SS, 3).sum(axis=(1, 3)) / SS ** 2
    box = image[y0:y1, x0:x1]
    image[y0:y1, x0:x1] = box * (1 - coverage[..., None]) + ball
    m = inside.astype(np.float64)
    area = m.sum()
    mx, my = (m * X).sum() / area, (m * Y).sum() / area
    rx = 2 * np.sqrt((m * (X - mx) ** 2).sum() / area)       # a disc's variance is r²/4 a side
    ry = 2 * np.sqrt((m * (Y - my) ** 2).sum() / area)
    return {"cx": float(mx), "cy": float(my), "rx": float(rx), "ry": float(ry)}


def corpus(count: int, seed: int = 1, no_ball_share: float = 0.15) -> list[Spec]:
    """``count`` cases drawn across every factor (environments in turn, sizes log-uniform 5-100 %
    of the short side), about ``no_ball_share`` of them without a ball."""
    rng = np.random.default_rng(seed)
    names = env_names()
    frames = ((1200, 900), (1600, 1200), (1600, 900), (1000, 1000), (2400, 1600))
    out = []
    for i in range(count):
        w, h = frames[int(rng.integers(len(frames)))]
        size = 0.0 if rng.random() < no_ball_share else float(np.exp(rng.uniform(np.log(0.05), np.log(1.0))))
        if size < 0.12 and size:         # a small ball is photographed on a big sensor
            w, h = 2400, 1600
        out.append(Spec(env=names[i % len(names)], width=w, height=h, size=size,
                        offset=tuple(float(v) for v in rng.uniform(-1, 1, 2)),
                        reflectance=float(rng.uniform(0.5, 0.9)),
                        camera="orthographic" if rng.random() < 0.25 else "perspective",
                        backdrop=BACKDROPS[int(rng.integers(len(BACKDROPS)))],
                        holder=HOLDERS[int(rng.integers(len(HOLDERS)))],
                        exposure=float(rng.choice([-2, -1, 0, 0, 1, 2])),
                        noise=float(rng.choice([0, 0, 0.005, 0.02])),
                        jpeg=int(rng.choice([0, 95, 75, 50])),
                        yaw=float(rng.uniform(0, 360))))
    return out


def score(found, truth) -> tuple[float, float]:
    """(centre error, radius error) relative to the truth's mean radius."""
    r = 0.5 * (truth["rx"] + truth["ry"])
    return (float(np.hypot(found.cx - truth["cx"], found.cy - truth["cy"]) / r),
            float(abs(0.5 * (found.rx + found.ry) / r - 1)))
