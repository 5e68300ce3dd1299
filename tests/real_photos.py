"""Real photographs (shared/data/real, README there) with their ground truth, and variants of
them for the ball finder: the shipped mirror-ball photos rescaled, re-encoded, cropped to the
frame's edge, stretched, re-exposed, and set small into a wider real photo.

Only four real ball photos exist here (no network but PyPI), so the variants are augmented
cases of the same four balls, not new photos; tests and the benchmark say so. The ladle photo's
ground truth is the author's crop for unwrapping a soup ladle's bowl: it lies outside the bowl's
visible outline (its row 1037 has the rim at x = 64 and 1986, the circle at 39 and 2024), so the
ladle is measured against its visible outline (``LADLE_CHORDS``) as well."""
from __future__ import annotations

import json

import numpy as np

import support

BALLS = support.REAL / "mirrorball_photos"
CHARUCO = support.REAL / "charuco_calibration"
FROBISHER = support.REAL / "brackets_frobisher"
# Rows of ladle.jpg and the x of its rim's steepest step on the left and right (5 rows averaged,
# Gaussian sigma 1): an independent measurement of the visible outline.
LADLE_CHORDS = {700: (132, 1914), 900: (75, 1963), 1037: (64, 1986), 1200: (75, 1971)}


def ball_truth() -> dict:
    """name -> dict(cx, cy, rx, ry, fills) from ball_circles.json."""
    data = json.loads((BALLS / "ball_circles.json").read_text())["images"]
    return {name: {"cx": d["ball_center_xy"][0], "cy": d["ball_center_xy"][1],
                   "rx": d["ball_radius_xy"][0], "ry": d["ball_radius_xy"][1],
                   "fills": d["ball_fills_frame"]} for name, d in data.items()}


def read(path) -> np.ndarray:
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    assert img is not None, path
    return img


def _scaled(img, t, s):
    import cv2

    h, w = img.shape[:2]
    out = cv2.resize(img, (round(w * s), round(h * s)), interpolation=cv2.INTER_AREA)
    sx, sy = out.shape[1] / w, out.shape[0] / h
    return out, dict(t, cx=(t["cx"] + 0.5) * sx - 0.5, cy=(t["cy"] + 0.5) * sy - 0.5, rx=t["rx"] * sx,
                     ry=t["ry"] * sy)


def _jpeg(img, quality):
    import cv2

    ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])
    return cv2.imdecode(data, cv2.IMREAD_COLOR)


def _exposed(img, gain):
    """The photo re-exposed by ``gain`` in linear light (clipping where it overflows)."""
    v = img.astype(np.float32) / 255
    lin = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4) * gain
    lin = np.clip(lin, 0, 1)
    out = np.where(lin <= 0.0031308, lin * 12.92, 1.055 * lin ** (1 / 2.4) - 0.055)
    return np.round(out * 255).astype(np.uint8)


def _crop(img, t, x0, y0, x1, y1):
    h, w = img.shape[:2]
    x0, y0, x1, y1 = max(0, int(x0)), max(0, int(y0)), min(w, int(x1)), min(h, int(y1))
    return np.ascontiguousarray(img[y0:y1, x0:x1]), dict(t, cx=t["cx"] - x0, cy=t["cy"] - y0)


def ball_cases(full: bool = True):
    """(label, kind, BGR image, truth dict) for every real ball photo and its variants. ``kind``
    is "fills" or "small" (the ball in a wider picture). ``full=False``: the originals and one
    variant of each kind only (for the test suite's time)."""
    import cv2

    truth = ball_truth()
    background = read(FROBISHER / "IMG_2601.jpg")
    for name, t in truth.items():
        img = read(BALLS / name)
        kind = "fills" if t["fills"] else "small"
        yield f"{name}", kind, img, t
        # work on at most ~1500 px (the 4096 px photo halves twice)
        base, bt = img, t
        while max(base.shape[:2]) > 1600:
            base, bt = _scaled(base, bt, 0.5)
        if not full:
            if kind == "fills" and _margin(base, bt) > 0.02:
                small, st = _in_wide_shot(base, bt, background)
                yield f"{name} small in a wide shot", "small", small, st
            continue
        if base is not img:
            yield f"{name} at {base.shape[1]} px", kind, base, bt
        yield f"{name} JPEG quality 40", kind, _jpeg(base, 40), bt
        yield f"{name} 1/3 exposure", kind, _exposed(base, 1 / 3), bt
        yield f"{name} 3x exposure (clipped)", kind, _exposed(base, 3.0), bt
        stretched = cv2.resize(base, (round(base.shape[1] * 1.04), base.shape[0]), interpolation=cv2.INTER_AREA)
        sx = stretched.shape[1] / base.shape[1]
        yield f"{name} 4 % wider (elliptical)", kind, stretched, dict(bt, cx=(bt["cx"] + 0.5) * sx - 0.5,
                                                                    rx=bt["rx"] * sx)
        rotated = np.ascontiguousarray(np.rot90(base))          # 90 deg counter-clockwise
        h = base.shape[0]
        w = base.shape[1]
        yield f"{name} turned 90 deg", kind, rotated, dict(bt, cx=bt["cy"], cy=w - 1 - bt["cx"], rx=bt["ry"], ry=bt["rx"])
        if kind == "small":
            # the frame's edge touching the ball (right side), and a tighter crop around it
            x1 = bt["cx"] + bt["rx"] + 1
            yield f"{name} touching the frame", kind, *_crop(base, bt, 0, 0, x1, h)
            m = 1.6 * bt["rx"]
            yield f"{name} cropped around the ball", "fills", *_crop(base, bt, bt["cx"] - m, bt["cy"] - m,
                                                                      bt["cx"] + m, bt["cy"] + m)
        elif _margin(base, bt) > 0.02:
            # (not a ball touching its own frame: pasted small, the frame's edges would run
            # along the ball's rim, an outline no real photo has)
            small, st = _in_wide_shot(base, bt, background)
            yield f"{name} small in a wide shot", "small", small, st
            yield f"{name} small in a wide shot, JPEG 50", "small", _jpeg(small, 50), st


def _margin(img, t) -> float:
    """The narrowest gap between the ball's outline and the photo's edge, relative to the radius."""
    h, w = img.shape[:2]
    return min(t["cx"] - t["rx"], w - 1 - t["cx"] - t["rx"], t["cy"] - t["ry"], h - 1 - t["cy"] - t["ry"]) / t["rx"]


def _in_wide_shot(img, t, background):
    """The whole ball photo (its real rim and surroundings) shrunk to a ball of ~70 px radius
    and set into a real street photo of 1280 x 852: a small ball among clutter."""
    import cv2

    s = 70.0 / max(t["rx"], t["ry"])
    small, st = _scaled(img, t, s)
    canvas = cv2.resize(background, (1280, 852), interpolation=cv2.INTER_CUBIC)
    y0, x0 = 300, 760
    canvas[y0:y0 + small.shape[0], x0:x0 + small.shape[1]] = small
    return canvas, dict(st, cx=st["cx"] + x0, cy=st["cy"] + y0)


def radius_error(found, t) -> float:
    """Relative error of the ball's mean radius, (rx + ry) / 2, against the truth's."""
    return float(0.5 * (found.rx + found.ry) / (0.5 * (t["rx"] + t["ry"])) - 1)


def centre_error(found, t) -> float:
    """Distance of the found centre from the truth's, relative to the radius."""
    return float(np.hypot(found.cx - t["cx"], found.cy - t["cy"]) / (0.5 * (t["rx"] + t["ry"])))
