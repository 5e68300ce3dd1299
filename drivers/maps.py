"""`python -m platelight maps ENV.exr --out DIR`: the four maps and sh.json (design.md contract)."""
from __future__ import annotations

import argparse
import os
import sys
import time

from ..addon.errors import PlateLightError
from ..addon.wording import CLI_FLAGS, worded
from ..addon.hdr_io import read_probe
from ..addon.fileio import ensure_writable_folder, write_json_atomic
from ..addon.ibl.equirect import from_pbrt_latlong
from ..addon.ibl.maps import LOBES, MAP_NAMES, SH_JSON_LMAX, MapSettings, compute_maps, write_maps


def _map_list(text: str) -> tuple:
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    bad = [n for n in names if n not in MAP_NAMES]
    if bad or not names:
        raise argparse.ArgumentTypeError(f"maps must be a comma list of {', '.join(MAP_NAMES)}")
    return names


def _sizes(text: str) -> dict:
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError("sizes must be four integers, e.g. 16,32,64,128") from None
    if len(values) != 4:
        raise argparse.ArgumentTypeError("sizes must be four map heights: diffuse,glossy1,glossy2,specular")
    return dict(zip(MAP_NAMES, values))


def add_parser(sub) -> None:
    p = sub.add_parser("maps", help="probe EXR or .hdr -> diffuse/glossy1/glossy2/specular maps and sh.json",
                       description="Compute the four blurred maps of a lat-long probe.")
    p.add_argument("env", metavar="ENV.exr|ENV.hdr",
                   help="equirectangular probe, OpenEXR or Radiance .hdr (width = 2 x height)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--sampling", choices=("exact", "paper"), default="exact",
                   help="exact quadrature (default) or the paper's stratified sampling (Eq 8-9)")
    p.add_argument("--samples", type=int, default=4096, help="paper mode: number of samples")
    p.add_argument("--seed", type=int, default=0, help="paper mode: jitter seed")
    p.add_argument("--maps", type=_map_list, default=MAP_NAMES, help="which maps (default: all four)")
    p.add_argument("--sizes", type=_sizes, default=None, metavar="D,G1,G2,S",
                   help="map heights (default 16,32,64,128)")
    p.add_argument("--glossy1-exponent", type=float, default=8.0)
    p.add_argument("--glossy2-exponent", type=float, default=64.0)
    p.add_argument("--lobes", choices=LOBES, default=MapSettings.lobes,
                   help="glossy maps' lobes: the paper's Phong (default) or GGX's at each map's "
                        "roughness (exact sampling only)")
    p.add_argument("--layout", choices=("blender", "pbrt"), default="blender",
                   help="input layout: Blender's Environment Texture (default) or pbrt's lat-long")
    p.set_defaults(func=run)


def run(args) -> int:
    out = ensure_writable_folder(args.out)
    settings = MapSettings(sampling=args.sampling, samples=args.samples, seed=args.seed,
                           glossy1_exponent=args.glossy1_exponent,
                           glossy2_exponent=args.glossy2_exponent, lobes=args.lobes)
    if args.sizes:
        settings.heights = args.sizes
    t0 = time.perf_counter()
    env = read_probe(args.env)
    if args.layout == "pbrt":
        env = from_pbrt_latlong(env)
    read_s = time.perf_counter() - t0
    result = compute_maps(env, settings, which=args.maps)
    for warning in result.warnings:
        print(f"platelight maps: warning: {worded(warning, CLI_FLAGS)}", file=sys.stderr)
    paths = write_maps(out, result.maps)
    write_json_atomic(os.path.join(out, "sh.json"), {
        "lmax": SH_JSON_LMAX,
        "coefficients": result.sh.tolist(),
        "order": "l*l + l + m, real orthonormal SH (Ramamoorthi & Hanrahan convention)",
        "sampling": settings.sampling,
        "lobes": settings.glossy_lobes(),
        "samples": settings.samples if settings.sampling == "paper" else None,
        "seed": settings.seed if settings.sampling == "paper" else None,
        "source": os.path.abspath(args.env),
        "source_size": [int(env.shape[1]), int(env.shape[0])],
        "maps": {name: os.path.basename(path) for name, path in paths.items()},
        "timings_ms": {"read": round(read_s * 1e3, 2),
                       **{k: round(v * 1e3, 2) for k, v in result.timings.items()}},
        "warnings": result.warnings,
        "stats": result.stats,
    })
    print(f"wrote {', '.join(sorted(paths))} and sh.json to {out}")
    return 0
