"""One multilayer OpenEXR per frame with named passes, for Nuke, Resolve and Blender's compositor.

Blender 5.2 cannot write it itself: a multilayer File Output node writes only its first input
(measured on 5.2.3, as on 5.0.1), while a File Output node in single-image mode writes every pass
to its own float32 EXR. The render driver does that, and this module joins the files:

    R G B A                       the composite (a reader's main image: Nuke's rgba)
    CG.R CG.G CG.B CG.A           the CG after exposure/tone/glare/grain, premultiplied alpha
    Shadows.R Shadows.G Shadows.B  the ratio the CG applies to the plate: shadows < 1, bleeding > 1
    Holdout.A                     coverage of the phantoms (stand-ins for real things), 0..1
    Depth.Z                       camera distance of the nearest surface (Cycles' Depth pass)
    Normal.X Normal.Y Normal.Z    world-space normal
    CryptoObject00.R ... 02.A     Cryptomatte (object), with its manifest in the header

"LAYER.CHANNEL" is how Nuke names layers and Blender reads a pass of a multilayer file; the
composite's bare R G B A is Nuke's rgba. Every channel is float32 (Cryptomatte ids need all 32
bits), ZIP compressed. The holdout matte is the summed Cryptomatte coverage of the phantoms, so it
is anti-aliased exactly as the render is.
"""
from __future__ import annotations

import json
import struct

import numpy as np

from ..errors import PlateLightError

CRYPTO_NAME = "CryptoObject"
CRYPTO_LEVELS = 3                      # CryptoObject00..02: 6 (id, coverage) ranks, Blender's default
PASSES = ("CG", "Shadows", "Holdout", "Depth", "Normal")


def murmur3_32(data: bytes, seed: int = 0) -> int:
    """MurmurHash3 (x86, 32-bit): the hash Cryptomatte names objects by."""
    c1, c2, mask = 0xCC9E2D51, 0x1B873593, 0xFFFFFFFF
    h = seed & mask
    n = len(data) // 4 * 4
    for (k,) in struct.iter_unpack("<I", data[:n]):
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        h ^= (k * c2) & mask
        h = ((h << 13) | (h >> 19)) & mask
        h = (h * 5 + 0xE6546B64) & mask
    tail = data[n:]
    if tail:
        k = int.from_bytes(tail, "little")
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        h ^= (k * c2) & mask
    h ^= len(data)
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & mask
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & mask
    return h ^ (h >> 16)


def crypto_id(name: str) -> np.float32:
    """An object's Cryptomatte id as the float32 stored in the id channels (the hash with its
    exponent kept off 0 and 255, so it is never a denormal, Inf or NaN)."""
    h = murmur3_32(name.encode("utf-8"))
    exponent = min(max((h >> 23) & 0xFF, 1), 254)
    bits = (h & 0x807FFFFF) | (exponent << 23)
    return np.frombuffer(struct.pack("<I", bits), dtype=np.float32)[0]


def crypto_key(name: str) -> str:
    """The 7-hex-digit key of a Cryptomatte layer's metadata: ``cryptomatte/<key>/name``."""
    return f"{murmur3_32(name.encode('utf-8')):08x}"[:7]


def coverage(crypto: list[np.ndarray], names) -> np.ndarray:
    """Summed coverage of the objects ``names`` in Cryptomatte layers ``crypto`` ((H, W, 4) arrays:
    id, coverage, id, coverage), clipped to [0, 1]."""
    ids = [crypto_id(n) for n in names]
    out = np.zeros(crypto[0].shape[:2], np.float32)
    for layer in crypto:
        for rank in (0, 2):
            hit = np.isin(layer[..., rank], ids)
            out += np.where(hit, layer[..., rank + 1], np.float32(0))
    return np.clip(out, 0.0, 1.0)


def channels(composite, cg, shadows, depth, normal, crypto, phantoms) -> dict[str, np.ndarray]:
    """The file's channels: arrays (H, W, k) in, name -> (H, W) float32 out."""
    if len(crypto) != CRYPTO_LEVELS:
        raise PlateLightError(f"Cryptomatte needs {CRYPTO_LEVELS} layers, got {len(crypto)}.")
    out = {}

    def put(layer, names, image):
        image = np.asarray(image, np.float32)
        for k, channel in enumerate(names):
            out[f"{layer}.{channel}" if layer else channel] = np.ascontiguousarray(image[..., k])

    put("", "RGBA", composite)
    put("CG", "RGBA", cg)
    put("Shadows", "RGB", shadows)
    put("Holdout", "A", coverage(crypto, phantoms)[..., None])
    put("Depth", "Z", depth[..., :1])
    put("Normal", "XYZ", normal)
    for level, layer in enumerate(crypto):
        put(f"{CRYPTO_NAME}{level:02d}", "RGBA", layer)
    return out


def crypto_header(manifest: dict[str, str]) -> dict[str, str]:
    key = crypto_key(CRYPTO_NAME)
    return {f"cryptomatte/{key}/name": CRYPTO_NAME,
            f"cryptomatte/{key}/hash": "MurmurHash3_32",
            f"cryptomatte/{key}/conversion": "uint32_to_float32",
            f"cryptomatte/{key}/manifest": json.dumps(manifest, separators=(",", ":"))}


def manifest_for(names) -> dict[str, str]:
    """name -> 8-hex-digit hash, the Cryptomatte manifest."""
    return {n: f"{murmur3_32(n.encode('utf-8')):08x}" for n in names}


def write(path: str, chans: dict[str, np.ndarray], manifest: dict[str, str]) -> None:
    """Write the channels and the Cryptomatte metadata to ``path`` (the caller renames it into
    place: the render command's whole-file commit)."""
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
              **crypto_header(manifest)}
    OpenEXR.File(header, chans).write(path)


def read_layers(path: str) -> dict[str, np.ndarray]:
    """A multilayer file's layers: '' (the composite, RGBA) and each pass, channels stacked in
    the order of :func:`channels`. For tests and tools."""
    import OpenEXR

    order = {"": "RGBA", "CG": "RGBA", "Shadows": "RGB", "Holdout": "A", "Depth": "Z", "Normal": "XYZ",
             **{f"{CRYPTO_NAME}{k:02d}": "RGBA" for k in range(CRYPTO_LEVELS)}}
    with OpenEXR.File(path, separate_channels=True) as exr:
        chans = {name: c.pixels for name, c in exr.channels().items()}
    return {layer: np.stack([chans[f"{layer}.{c}" if layer else c] for c in names], axis=-1)
            for layer, names in order.items()}


def _read_any(path: str) -> np.ndarray:
    """All channels of a single-pass EXR, in R G B A / X Y Z A order whatever their case."""
    import OpenEXR

    rank = {c: k for k, c in enumerate("RGBA")} | {c: k for k, c in enumerate("XYZ")}
    with OpenEXR.File(path, separate_channels=True) as exr:
        chans = exr.channels()
        names = sorted(chans, key=lambda n: rank.get(n.upper(), 9))
        manifest = {k: v for k, v in exr.header().items() if k.endswith("/manifest")}
        image = np.stack([np.asarray(chans[n].pixels, np.float32) for n in names], axis=-1)
    return image, manifest


def assemble(composite_path: str, pass_files: dict[str, str], phantoms, out_path: str) -> None:
    """Join a frame's composite and its single-pass files (stem -> path, the stems of
    node_groups/passes.py) into one multilayer EXR at ``out_path``."""
    passes = {stem: _read_any(path) for stem, path in pass_files.items()}
    composite, _ = _read_any(composite_path)
    crypto = [passes[f"{CRYPTO_NAME}{k:02d}"][0] for k in range(CRYPTO_LEVELS)]
    manifest = {}
    for _image, meta in passes.values():
        for text in meta.values():
            manifest.update(json.loads(text))
    chans = channels(composite, passes["CG"][0], passes["Shadows"][0], passes["Depth"][0],
                     passes["Normal"][0], crypto, phantoms)
    write(out_path, chans, manifest)
