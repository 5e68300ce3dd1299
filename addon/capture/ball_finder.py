"""Find a mirror ball's outline in a real photo: candidates, rim refinement, a confidence.

A chrome ball's outline is a weak edge: just inside the rim the ball reflects what lies behind
it, often the same background that surrounds it, while the compressed reflections further in
have far stronger edges. So the finder does not trust any single edge detector:

1. candidate circles come from two Hough transforms (OpenCV's gradient-direction ALT variant and
   the classic accumulator) on a copy of at most ``SEARCH_SIZE`` px, plus the circle inscribed
   in a square-ish frame (most ball photos are cropped to the ball);
2. each candidate is refined on the rim: along 720 rays the *outermost* strong step of the
   linear-light luminance within a band around the guess is located to a sub-sample, and an
   axis-aligned ellipse (a ball seen off the optical axis, or non-square pixels, is slightly
   elliptical) or a circle is fitted with outlier rejection; rays leaving the photo are skipped.
   A step counts when it is strong on its ray, or when it is sharp and stands well above the
   calm beyond it: a ball in front of what it reflects (its rim mirrors the light straight
   behind it, the background itself) shows only the reflectance's loss at its outline;
3. the candidate whose rim is supported on the largest share of its outline wins; that share is
   its confidence (0..1). Two well-supported, separate balls, or none, are errors that say how
   to give the circle by hand.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import PlateLightError
from ..imaging import SRGB8_TO_LINEAR, srgb_to_linear

SEARCH_SIZE = 800           # px, longest side of the copy the candidates are searched on
RAYS = 720
MIN_ARC_RAYS = 10            # 5 degrees of unbroken rim
MAX_RIM_WIDTH_PX = 4.0       # a rim step wider than this (px, at half its peak gradient)...
MAX_RIM_WIDTH = 0.03         # ...and than this share of the radius is a glow, not a ball's outline
# A ball is accepted when its rim is found on this share of its outline; below UNSURE the
# result comes with a warning to check it (measured: the real balls and their variants 0.34-0.87,
# the strongest circle in 7 real photos without a ball <= 0.09; docs/capture.md).
MIN_CONFIDENCE = 0.3
UNSURE_CONFIDENCE = 0.5
MAX_ELLIPTICITY = 0.08      # |rx/ry - 1| beyond this is not "a ball seen slightly off-axis"
RIVAL_SHARE = 0.6           # a second, separate ball this well supported (relative to the best,
MIN_RIVAL = 0.25            # and absolutely) makes the choice ambiguous
ELLIPSE_GAIN = 0.02         # an ellipse must see this much more of the rim than a circle
MIN_RADIUS_PX = 32          # smaller balls unwrap to too few pixels to be worth finding by themselves
# A ray whose band is clipped (8/16-bit white) on this share of its samples cannot show a rim: a
# ball reflecting a white sky against that sky. Such rays, like rays leaving the photo, do not
# count against the ball, as long as at least MIN_SEEN of the outline can be seen.
CLIPPED_BAND = 0.9
CLIP_LEVEL = 0.97 * 255     # linear luminance (0..255 scale) at which an 8/16-bit pixel is white
MIN_SEEN = 0.5
# A weaker step also counts as a rim candidate when it is this many times stronger than any
# step beyond it on its ray (more than OUTER_GAP_PX further out), and its gradient is at least
# MIN_RIM_CONTRAST of the brighter side's level per pixel (a sharp step of about 10 %).
OUTER_CALM = 3.0
OUTER_GAP_PX = 1.5
MIN_RIM_CONTRAST = 0.05
HOW_TO_GIVE = "give its circle with {ball}"        # {ball}: named by each front end (wording.py)
BALL = {"ball": "its centre and radius in pixels"}


@dataclasses.dataclass
class BallFit:
    cx: float
    cy: float
    rx: float
    ry: float
    confidence: float                  # share of the visible outline where a sharp rim was found
    outside: float = 0.0               # share of the outline's search band outside the photo
    blurred_support: float = 0.0       # the same share counting blurred steps too
    rim_width: float = 0.0             # median width (px) of the rim's step

    @property
    def radius(self) -> float:
        return 0.5 * (self.rx + self.ry)


def luminance_planes(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(display, linear) float32 luminance of an 8/16-bit photo (BGR as OpenCV reads it) or a
    float radiance image: ``display`` is perceptual 0..255 (log for HDR) for the Hough search,
    ``linear`` is proportional to light, where a blurred step's midpoint is the true edge."""
    img = np.asarray(image)
    if img.ndim == 3:
        img = img[..., :3]
    if np.issubdtype(img.dtype, np.floating):
        lum = np.maximum(np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0), 0).astype(np.float32)
        lum = lum.mean(axis=-1) if lum.ndim == 3 else lum
        few = lum[::4, ::4]
        floor = np.float32(np.percentile(few, 1) + 1e-8)
        log = np.log2(np.maximum(lum, floor))
        lo, hi = np.percentile(np.log2(np.maximum(few, floor)), [1, 99.5])
        display = np.clip((log - lo) * np.float32(255.0 / max(hi - lo, 1e-6)), 0, 255)
        linear = np.clip(lum * np.float32(255.0 / max(float(np.percentile(few, 99)), 1e-12)), 0, 380)
        return display.astype(np.float32), linear.astype(np.float32)
    import cv2

    if img.dtype == np.uint16:
        img = (img.astype(np.float32) * np.float32(255.0 / 65535.0))
    elif img.dtype != np.uint8:
        raise PlateLightError(f"Cannot look for a ball in a {img.dtype} image.")
    if img.ndim == 2:
        img = img[..., None]
    if img.dtype == np.uint8:
        linear = cv2.LUT(img if img.shape[2] != 1 else img[..., 0], SRGB8_TO_LINEAR)
        display = img.astype(np.float32)
    else:                                                       # 16-bit, as 0..255 floats
        linear = srgb_to_linear(img / np.float32(255.0)) * np.float32(255.0)
        display = img
    linear = linear.reshape(img.shape[:2] + (-1,))
    display = display.reshape(img.shape[:2] + (-1,))
    if display.shape[2] == 3:
        display = cv2.cvtColor(np.ascontiguousarray(display, dtype=np.float32), cv2.COLOR_BGR2GRAY)
        linear = cv2.cvtColor(np.ascontiguousarray(linear, dtype=np.float32), cv2.COLOR_BGR2GRAY)
    else:
        display, linear = display[..., 0], linear[..., 0]
    return display.astype(np.float32), linear.astype(np.float32)


def _candidates(display: np.ndarray) -> list[tuple[float, float, float, float]]:
    """Ellipses (cx, cy, rx, ry) in full-resolution pixels: Hough (two variants) on a small copy, and
    the circle inscribed in a square-ish frame."""
    import cv2

    h, w = display.shape
    shrink = max(1.0, max(h, w) / SEARCH_SIZE)
    small = cv2.resize(display, (max(1, round(w / shrink)), max(1, round(h / shrink))),
                       interpolation=cv2.INTER_AREA) if shrink > 1 else display
    sh, sw = small.shape
    blur = np.clip(cv2.GaussianBlur(small, (0, 0), 1.5), 0, 255).astype(np.uint8)
    # down to the smallest ball worth finding (a 5 % ball in a 24 MP photo is ~60 px across)
    lo, hi = max(4, int(0.8 * MIN_RADIUS_PX / shrink)), int(max(sh, sw) * 0.55)
    found = []
    alt = cv2.HoughCircles(blur, cv2.HOUGH_GRADIENT_ALT, dp=1.5, minDist=min(sh, sw) / 8, param1=60,
                           param2=0.6, minRadius=lo, maxRadius=hi)
    # the classic accumulator costs ~ pixels x radii: on a copy half the size
    half = cv2.resize(blur, (sw // 2, sh // 2), interpolation=cv2.INTER_AREA)
    classic = cv2.HoughCircles(half, cv2.HOUGH_GRADIENT, dp=1.0, minDist=min(sh, sw) / 16, param1=80,
                               param2=25, minRadius=lo // 2, maxRadius=hi // 2)
    if classic is not None:
        classic = classic * np.float32([2, 2, 2]) + np.float32([0.5, 0.5, 0])
    for circles, keep in ((alt, 6), (classic, 6)):
        if circles is not None:
            found += [tuple(map(float, c)) for c in circles.reshape(-1, 3)[:keep]]
    out = [((x + 0.5) * shrink - 0.5, (y + 0.5) * shrink - 0.5, r * shrink, r * shrink) for x, y, r in found]
    if max(h, w) <= 1.15 * min(h, w):            # a crop around the ball: its inscribed circle
        out.append(((w - 1) / 2.0, (h - 1) / 2.0, min(h, w) / 2.0, min(h, w) / 2.0))
        if w != h:                               # (and ellipse: a stretched photo)
            out.append(((w - 1) / 2.0, (h - 1) / 2.0, w / 2.0, h / 2.0))
    return out


@dataclasses.dataclass
class RimSteps:
    """Every strong linear-light step on each ray around a guessed ellipse."""
    ray: np.ndarray          # (N,) ray index of each step
    rel: np.ndarray          # (N,) position along the ray, relative to the guessed radius
    width: np.ndarray        # (N,) px, width at half the step's peak gradient
    strength: np.ndarray     # (N,) the step's peak gradient
    weak: np.ndarray         # (N,) counted only for the calm beyond it (not a strong step)
    usable: np.ndarray       # (RAYS,) rays whose band lies inside the photo
    seen: np.ndarray         # (RAYS,) usable rays whose band is not clipped white
    theta: np.ndarray        # (RAYS,) ray angles
    guess: tuple             # (cx, cy, rx, ry)

    def points(self, idx) -> np.ndarray:
        cx, cy, rx, ry = self.guess
        t, q = self.theta[self.ray[idx]], self.rel[idx]
        return np.stack([cx + np.cos(t) * rx * q, cy + np.sin(t) * ry * q], axis=1)


def rim_steps(linear: np.ndarray, cx: float, cy: float, rx: float, ry: float, reach: float,
              rays: int = RAYS, clip: float | None = None) -> RimSteps:
    """The strong steps (local maxima of the gradient above 35 % of the ray's strongest) on
    ``rays`` rays within ``reach`` (relative) of the ellipse, to a sub-sample (``linear``
    already smoothed: see ``smoothed``). Rays whose band leaves the photo are not used; rays
    whose band is white (``linear`` >= ``clip``) are marked unseen."""
    import cv2

    r = max(rx, ry)
    step = min(0.25, 0.25 * r / 50.0) / r                      # <= 1/4 px, finer on small balls
    rel = np.arange(1 - reach, 1 + reach + step / 2, step)
    theta = np.linspace(0, 2 * np.pi, rays, endpoint=False)
    xs = cx + np.cos(theta)[:, None] * rx * rel[None, :]
    ys = cy + np.sin(theta)[:, None] * ry * rel[None, :]
    prof = cv2.remap(linear, xs.astype(np.float32), ys.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    inside = np.isfinite(prof)
    # a ray is used while most of its band lies in the photo (a ball touching the frame)
    usable = inside.mean(axis=1) > 0.6
    seen = usable.copy()
    if clip is not None:
        white = (np.nan_to_num(prof) >= clip).sum(axis=1) >= CLIPPED_BAND * np.maximum(inside.sum(axis=1), 1)
        seen &= ~white
    grad = np.abs(np.diff(np.nan_to_num(prof), axis=1))
    grad[~usable] = 0
    grad[~(inside[:, 1:] & inside[:, :-1])] = 0
    # the strength a step needs: a share of this ray's strongest step and of the typical one
    gmax = grad.max(axis=1, keepdims=True)
    typical = float(np.median(gmax[usable])) if usable.any() else 0.0
    g0, g1, g2 = grad[:, :-2], grad[:, 1:-1], grad[:, 2:]
    strong = (g1 > 0.35 * gmax) & (gmax > max(1.0, 0.15 * typical))
    # ...or a step that stands out of the calm beyond it: a ball's rim reflects what lies just
    # behind the ball, often the very background around it, so its step is only the
    # reflectance's loss (-25 % for a chrome of 0.75), far weaker than the compressed
    # reflections inside it; but it is the last step before that background
    spx = step * r                                             # px per sample
    m = max(2, int(np.ceil(OUTER_GAP_PX / spx)))
    after = np.maximum.accumulate(grad[:, ::-1], axis=1)[:, ::-1]   # max of grad[j:] per j
    beyond = np.full_like(grad, np.inf)
    beyond[:, :-m] = after[:, m:]
    beyond[:, -m:] = np.inf                                    # nothing beyond: cannot tell
    val = np.nan_to_num(prof)
    lvl = np.maximum(val[:, :-1], val[:, 1:])
    level = np.maximum(np.roll(lvl, m, axis=1), np.roll(lvl, -m, axis=1))   # the brighter side
    calm = (g1 > OUTER_CALM * beyond[:, 1:-1]) & (g1 > MIN_RIM_CONTRAST * spx * level[:, 1:-1]) & (g1 > 1e-3 * spx)
    peak = (g1 >= g0) & (g1 > g2) & (strong | calm)
    weak = (calm & ~strong)[peak]
    ray, k = np.nonzero(peak)
    k = k + 1
    a, b, c = grad[ray, k - 1], grad[ray, k], grad[ray, k + 1]
    den = a - 2 * b + c
    frac = np.clip(0.5 * (a - c) / np.where(np.abs(den) > 1e-9, den, 1.0), -0.5, 0.5) * (np.abs(den) > 1e-9)
    pos = rel[k] + (0.5 + frac) * step                          # a difference sits between samples
    # width at half the peak: count the neighbouring samples above it (both sides, up to 40)
    half = 0.5 * b
    width = np.ones(len(k))
    n = grad.shape[1]
    for side in (-1, 1):
        alive = np.ones(len(k), bool)
        for d in range(1, 41):
            j = k + side * d
            ok = alive & (j >= 0) & (j < n)
            ok[ok] &= grad[ray[ok], j[ok]] > half[ok]
            width += ok
            alive = ok
            if not alive.any():
                break
    width = width * spx
    # a weak step only counts while sharp: a ripple on the tail of a blurred edge is not a rim
    keep = ~weak | (width <= max(MAX_RIM_WIDTH_PX, MAX_RIM_WIDTH * r))
    return RimSteps(ray[keep], pos[keep], width[keep], b[keep], weak[keep], usable, seen, theta, (cx, cy, rx, ry))


def smoothed(linear: np.ndarray) -> np.ndarray:
    """Light smoothing against JPEG blocks and sensor noise before the rim is located."""
    import cv2

    return cv2.GaussianBlur(linear, (0, 0), 0.5)


def fit_ellipse(points: np.ndarray, allow_ellipse: bool):
    """Least-squares axis-aligned ellipse (or circle) through ``points``: (cx, cy, rx, ry)."""
    x, y = points[:, 0], points[:, 1]
    if allow_ellipse:
        # x^2 + p y^2 + q x + s y + t = 0
        a = np.stack([y * y, x, y, np.ones_like(x)], axis=1)
        (p, q, s, t), *_ = np.linalg.lstsq(a, -x * x, rcond=None)
        if p > 0:
            cx, cy = -q / 2, -s / (2 * p)
            rx2 = cx * cx + p * cy * cy - t
            if rx2 > 0:
                return float(cx), float(cy), float(np.sqrt(rx2)), float(np.sqrt(rx2 / p))
    a = np.stack([x, y, np.ones_like(x)], axis=1)
    (d, e, f), *_ = np.linalg.lstsq(a, x * x + y * y, rcond=None)
    cx, cy = d / 2, e / 2
    r = float(np.sqrt(max(f + cx * cx + cy * cy, 0.0)))
    return float(cx), float(cy), r, r


def _radial_residual(points, cx, cy, rx, ry) -> np.ndarray:
    """Distance (px, approximately) of each point from the ellipse along its ray."""
    dx, dy = (points[:, 0] - cx) / rx, (points[:, 1] - cy) / ry
    rho = np.hypot(dx, dy)
    return (rho - 1) * np.hypot(dx * rx, dy * ry) / np.maximum(rho, 1e-9)


def _robust_fit(pts: np.ndarray, angles: np.ndarray, allow_ellipse: bool):
    """Ellipse (or circle) through ``pts`` with iterative outlier rejection, or None."""
    keep = np.ones(len(pts), bool)
    fit = None
    for _ in range(6):
        if keep.sum() < 0.15 * RAYS:
            return None
        # an ellipse only when the points go round most of the outline (else it is unconstrained)
        spread = len(np.unique(np.floor(angles[keep] / (np.pi / 8)))) >= 12
        fit = fit_ellipse(pts[keep], allow_ellipse and spread)
        res = np.abs(_radial_residual(pts, *fit))
        mad = float(np.median(res[keep])) + 1e-6
        keep = res < max(3 * 1.4826 * mad, 0.25, 0.002 * fit[2])
    return fit


def _pick(steps: RimSteps, target_rel: np.ndarray, window: float, by: str = "outermost") -> np.ndarray:
    """Per ray, the index of its outermost (or strongest) step within ``window`` (relative) of
    ``target_rel`` (per step); -1 where there is none. The outermost: a ball's own outline is
    often weaker than the compressed reflections just inside it, but it is the last step before
    the background. The strongest: JPEG rings just outside a high-contrast rim, and the last
    ripple is then the outermost step."""
    near = np.abs(steps.rel - target_rel) <= window
    best = np.full(RAYS, -1)
    order = np.nonzero(near)[0]
    key = steps.rel if by == "outermost" else steps.strength
    order = order[np.argsort(key[order])]                     # ascending: later ones win
    best[steps.ray[order]] = order
    return best


def refine(linear: np.ndarray, cx: float, cy: float, rx: float, ry: float, reach: float,
           allow_ellipse: bool = True, clip: float | None = None, strongest: bool = False) -> BallFit | None:
    """Fit the rim near a guess; None when too little of the outline shows a step.

    Two starts: the outermost strong step on each ray, and the step nearest the guess (in
    clutter, or where the photo's own frame runs just outside the ball, the outermost step is
    not the rim); with ``strongest``, a third: the strongest step, where the outermost
    steps are mostly weak ones (JPEG's ripples just outside a high-contrast rim are the
    outermost steps there; only near a found ball, where clutter cannot pull the fit away). Each is refitted twice from the outermost (the strongest) step
    near its own outline, and the start with the larger rim support wins."""
    steps = rim_steps(linear, cx, cy, rx, ry, reach, clip=clip)
    if len(steps.ray) < 0.15 * RAYS:
        return None
    angles_all = steps.theta[steps.ray]
    nearest = np.full(RAYS, -1)
    dist = np.abs(steps.rel - 1)
    for i in np.argsort(-dist):                                # nearest last wins
        nearest[steps.ray[i]] = i
    anywhere = np.ones(len(steps.rel))
    outermost = _pick(steps, anywhere, reach + 1)
    starts = ((outermost, "outermost"), (nearest, "outermost"))
    # ripples are weak steps: where the outermost are mostly strong, clutter is what is strong
    if strongest and steps.weak[outermost[outermost >= 0]].mean() > 0.5:
        starts += ((_pick(steps, anywhere, reach + 1, by="strongest"), "strongest"),)
    best = {}
    # a circle unless an ellipse fits clearly more of the rim (an occluded part of the outline
    # leaves an ellipse free to stretch)
    for ellipse in ((False, True) if allow_ellipse else (False,)):
        for chosen, by in starts:
            idx = chosen[chosen >= 0]
            fit = _robust_fit(steps.points(idx), angles_all[idx], ellipse)
            for _ in range(2):
                if fit is None:
                    break
                # where the fitted outline crosses each step's ray, relative to the guess
                target = _outline_rel(steps, fit)
                idx = _pick(steps, target, max(0.015, 2.0 / fit[2]), by)
                idx = idx[idx >= 0]
                fit = _robust_fit(steps.points(idx), angles_all[idx], ellipse)
            scored = None if fit is None else _score(steps, fit)
            if scored is not None and abs(scored.rx / scored.ry - 1) <= MAX_ELLIPTICITY and (
                    ellipse not in best or scored.confidence > best[ellipse].confidence):
                best[ellipse] = scored
    if True in best and (False not in best or best[True].confidence > best[False].confidence + ELLIPSE_GAIN):
        return best[True]
    return best.get(False)


def _outline_rel(steps: RimSteps, fit) -> np.ndarray:
    """For every step, the relative position on its ray where the ellipse ``fit`` lies."""
    gcx, gcy, grx, gry = steps.guess
    cx, cy, rx, ry = fit
    t = steps.theta[steps.ray]
    # solve ((gcx + cos t grx q - cx)/rx)^2 + ((gcy + sin t gry q - cy)/ry)^2 = 1 for q > 0
    ax, bx = np.cos(t) * grx / rx, (gcx - cx) / rx
    ay, by = np.sin(t) * gry / ry, (gcy - cy) / ry
    qa = ax * ax + ay * ay
    qb = 2 * (ax * bx + ay * by)
    qc = bx * bx + by * by - 1
    disc = np.maximum(qb * qb - 4 * qa * qc, 0)
    return (-qb + np.sqrt(disc)) / (2 * qa)


def _score(steps: RimSteps, fit) -> BallFit | None:
    """The fit's support: rays with a sharp step on the fitted outline, counted only in
    unbroken arcs (a true rim is continuous; edges of clutter cross a circle in short,
    scattered runs). A ball's rim is in focus: a blurred glow (the sun behind trees) has round
    but wide edges, counted only in ``blurred_support``."""
    cx, cy, rx, ry = fit
    if not (np.isfinite(rx) and np.isfinite(ry)) or rx <= 0 or ry <= 0:
        return None
    res = np.abs(_radial_residual(steps.points(np.arange(len(steps.ray))), cx, cy, rx, ry))
    close = res < max(0.5, 0.005 * 0.5 * (rx + ry))
    sharp = steps.width <= max(MAX_RIM_WIDTH_PX, MAX_RIM_WIDTH * 0.5 * (rx + ry))
    on = np.zeros(RAYS, bool)
    on[steps.ray[close & sharp]] = True
    loose = np.zeros(RAYS, bool)
    loose[steps.ray[close]] = True
    width = float(np.median(steps.width[close])) if close.any() else 0.0
    # the share of the outline that could show a rim (in the photo, not clipped white) that does
    seen = max(float(steps.seen.mean()), MIN_SEEN)
    return BallFit(cx, cy, rx, ry, min(1.0, arc_support(on) / seen), float(1 - steps.usable.mean()),
                   min(1.0, arc_support(loose) / seen), width)


def arc_support(on: np.ndarray, min_run: int = MIN_ARC_RAYS) -> float:
    """Share of the rays that lie in circular runs of at least ``min_run`` supported rays."""
    if on.all():
        return 1.0
    start = int(np.argmin(on))                     # rotate so that a gap comes first
    seq = np.roll(on, -start)
    edges = np.diff(np.concatenate([[0], seq.astype(np.int8), [0]]))
    runs = np.nonzero(edges == -1)[0] - np.nonzero(edges == 1)[0]
    return float(runs[runs >= min_run].sum() / len(on))


class BallNotFound(PlateLightError):
    """No ball, or two: ``candidates`` holds the circles the finder saw (best first), for the
    front ends to show the user."""

    def __init__(self, message: str, candidates, **inputs: str):
        super().__init__(message, **inputs)
        self.candidates = list(candidates)


def find_ball(image: np.ndarray) -> BallFit:
    """The mirror ball in a photo (8/16-bit BGR or float radiance), or BallNotFound."""
    return find_ball_and_candidates(image)[0]


def find_ball_and_candidates(image: np.ndarray) -> tuple[BallFit, list[BallFit]]:
    """(the mirror ball in a photo, every circle the finder saw, best first), or BallNotFound."""
    import cv2

    display, linear = luminance_planes(image)
    clip = CLIP_LEVEL if np.issubdtype(np.asarray(image).dtype, np.integer) else None
    h, w = display.shape
    # candidates are refined on a copy of the search size, the best few then at full resolution
    shrink = max(1.0, max(h, w) / SEARCH_SIZE)
    small = smoothed(cv2.resize(linear, (round(w / shrink), round(h / shrink)), interpolation=cv2.INTER_AREA)
                     if shrink > 1 else linear)

    def to_small(v):
        return (v + 0.5) / shrink - 0.5

    coarse = []
    for cx, cy, rx, ry in _candidates(display):
        fit = refine(small, to_small(cx), to_small(cy), rx / shrink, ry / shrink, reach=0.12, clip=clip)
        if fit is not None:          # Hough's circle can be >12 % off (a ball the frame cuts)
            closer = refine(small, fit.cx, fit.cy, fit.rx, fit.ry, reach=0.06, clip=clip)
            if closer is not None and closer.confidence >= fit.confidence:     # (it can lose the rim)
                fit = closer
        if fit is not None and MIN_RADIUS_PX <= fit.radius * shrink <= 0.6 * max(h, w):
            coarse.append(fit)
    full = smoothed(linear) if shrink > 1 else small
    fits = []
    for f in _distinct(coarse)[:4]:
        cx, cy = (f.cx + 0.5) * shrink - 0.5, (f.cy + 0.5) * shrink - 0.5
        fine = refine(full, cx, cy, f.rx * shrink, f.ry * shrink, reach=max(0.02, 3.0 / f.radius),  # 3 px of the copy
                      clip=clip, strongest=True)
        if fine is not None:
            fits.append(fine)
    fits = _distinct(fits)
    good = [f for f in fits if f.confidence >= MIN_CONFIDENCE]
    if not good:
        blurred = [f for f in fits if f.blurred_support >= MIN_CONFIDENCE]
        if blurred:
            raise BallNotFound(
                f"The photo is too blurred at the ball's outline (its edge is {blurred[0].rim_width:.0f} px wide) "
                f"to find the ball; refocus on the ball, or {HOW_TO_GIVE}.", fits, **BALL)
        raise BallNotFound(f"No mirror ball was found in the photo; {HOW_TO_GIVE}.", fits, **BALL)
    best = good[0]
    rival = next((f for f in fits if f is not best and not _overlap(f, best)
                  and f.confidence >= max(RIVAL_SHARE * best.confidence, MIN_RIVAL)), None)
    if rival is not None:
        raise BallNotFound(
            f"Two mirror balls were found (at {best.cx:.0f},{best.cy:.0f} r {best.radius:.0f} and "
            f"{rival.cx:.0f},{rival.cy:.0f} r {rival.radius:.0f} px); {HOW_TO_GIVE} of the one to use.",
            fits, **BALL)
    return best, fits


def _overlap(a: BallFit, b: BallFit) -> bool:
    return np.hypot(a.cx - b.cx, a.cy - b.cy) < max(a.radius, b.radius)


def _distinct(fits: list[BallFit]) -> list[BallFit]:
    """Fits sorted by confidence, near-duplicates (same ball from several candidates) merged."""
    out: list[BallFit] = []
    for f in sorted(fits, key=lambda f: -f.confidence):
        if not any(np.hypot(f.cx - g.cx, f.cy - g.cy) < 0.05 * g.radius and abs(f.radius / g.radius - 1) < 0.05
                   for g in out):
            out.append(f)
    return out
