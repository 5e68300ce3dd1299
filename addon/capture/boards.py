"""Printable markers and ChArUco boards: an image (PNG) and a PDF at true physical size."""
from __future__ import annotations

import os
import zlib

import numpy as np

from ..errors import PlateLightError
from .targets import CharucoTarget, MarkerTarget

MM_PER_INCH = 25.4
PT_PER_INCH = 72.0


def target_image(target, dpi: float = 300.0, margin_m: float = 0.01) -> np.ndarray:
    """8-bit grey image of ``target`` at ``dpi`` with a white quiet zone of ``margin_m``."""
    import cv2

    px_per_m = dpi / (MM_PER_INCH / 1000.0)
    w_m, h_m = target.extent
    w, h = int(round(w_m * px_per_m)), int(round(h_m * px_per_m))
    if min(w, h) < 16:
        raise PlateLightError("The board is too small to print at this resolution; raise {dpi} or the size.",
                              dpi="the resolution")
    if isinstance(target, MarkerTarget):
        marker_id = 0 if target.marker_id is None else target.marker_id
        if marker_id >= target.cv_dictionary.bytesList.shape[0]:
            raise PlateLightError(f"Marker id {marker_id} is not in {target.dictionary}.")
        img = cv2.aruco.generateImageMarker(target.cv_dictionary, marker_id, w, borderBits=1)
    elif isinstance(target, CharucoTarget):
        img = target.board.generateImage((w, h), marginSize=0, borderBits=1)
    else:
        raise TypeError(type(target))
    m = int(round(margin_m * px_per_m))
    return cv2.copyMakeBorder(img, m, m, m, m, cv2.BORDER_CONSTANT, value=255)


def write_png(path, gray: np.ndarray) -> None:
    import cv2

    if not cv2.imwrite(os.fspath(path), gray):
        raise PlateLightError(f"Cannot write {path}.")


def write_pdf(path, gray: np.ndarray, dpi: float) -> None:
    """A one-page PDF holding ``gray`` at exactly ``dpi`` (print at 100 %, no 'fit to page')."""
    h, w = gray.shape
    page_w, page_h = w / dpi * PT_PER_INCH, h / dpi * PT_PER_INCH
    data = zlib.compress(np.ascontiguousarray(gray, dtype=np.uint8).tobytes())
    content = f"q {page_w:.4f} 0 0 {page_h:.4f} 0 0 cm /Im0 Do Q".encode()
    objects = [
        b"<< /Type /Catalog /Pages 2 0 R >>",
        b"<< /Type /Pages /Kids [3 0 R] /Count 1 >>",
        (f"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {page_w:.4f} {page_h:.4f}] "
         f"/Resources << /XObject << /Im0 4 0 R >> >> /Contents 5 0 R >>").encode(),
        (f"<< /Type /XObject /Subtype /Image /Width {w} /Height {h} /ColorSpace /DeviceGray "
         f"/BitsPerComponent 8 /Filter /FlateDecode /Length {len(data)} >>\nstream\n").encode()
        + data + b"\nendstream",
        f"<< /Length {len(content)} >>\nstream\n".encode() + content + b"\nendstream",
    ]
    out = bytearray(b"%PDF-1.4\n")
    offsets = []
    for i, body in enumerate(objects, start=1):
        offsets.append(len(out))
        out += f"{i} 0 obj\n".encode() + body + b"\nendobj\n"
    xref = len(out)
    out += f"xref\n0 {len(objects) + 1}\n0000000000 65535 f \n".encode()
    out += b"".join(f"{o:010d} 00000 n \n".encode() for o in offsets)
    out += f"trailer\n<< /Size {len(objects) + 1} /Root 1 0 R >>\nstartxref\n{xref}\n%%EOF\n".encode()
    try:
        with open(path, "wb") as fh:
            fh.write(out)
    except OSError as exc:
        raise PlateLightError(f"Cannot write {path}: {exc.strerror}") from None


def write_target(path, target, dpi: float = 300.0, margin_m: float = 0.01) -> np.ndarray:
    """Write a PNG or PDF (by extension) of ``target``; returns the image."""
    gray = target_image(target, dpi, margin_m)
    if os.fspath(path).lower().endswith(".pdf"):
        write_pdf(path, gray, dpi)
    else:
        write_png(path, gray)
    return gray
