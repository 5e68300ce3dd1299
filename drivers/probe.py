"""`python -m platelight probe IMAGES... [--exposures T1,T2,...] --out probe.exr`."""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

from ..addon.errors import PlateLightError
from ..addon.wording import CLI_FLAGS, typed_numbers, worded
from ..addon.fileio import ensure_writable_folder, write_json_atomic
from ..addon.capture.mirror_ball import FILLS


def _floats(count: int | None):
    def parse(text: str):
        try:
            values = typed_numbers(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got '{text}'") from None
        if count is not None and len(values) != count:
            raise argparse.ArgumentTypeError(f"expected {count} comma-separated numbers, got '{text}'")
        return values
    return parse


def add_parser(sub) -> None:
    p = sub.add_parser("probe", help="chrome-ball photo or exposure brackets -> lat-long probe EXR",
                       description="Merge differently exposed photos of a mirror ball (or take one photo: an "
                                   "LDR probe) and unwrap the ball into an equirectangular probe (Blender's "
                                   "Environment Texture layout).")
    p.add_argument("images", nargs="+", metavar="IMAGES",
                   help="one photo or the brackets (JPEG/PNG/TIFF, 8 or 16 bit; one .hdr/.exr is HDR already)")
    p.add_argument("--exposures", type=_floats(None), metavar="T1,T2,...",
                   help="exposure times in seconds (1/250 allowed), in the order of IMAGES; default: EXIF")
    p.add_argument("--out", required=True, metavar="probe.exr", help="output EXR (float32 RGB)")
    p.add_argument("--height", type=int, default=256, help="probe height in pixels (width = 2 x height)")
    p.add_argument("--ball", type=_floats(None), metavar="CX,CY,R",
                   help="ball circle in pixels (CX,CY,RX,RY for a slightly elliptical outline; default: found)")
    p.add_argument("--reflectance", type=float, default=1.0,
                   help="the ball's reflectance (a chrome ball is about 0.6-0.8; default 1)")
    p.add_argument("--camera-from", metavar="POSES.json",
                   help="take the photo's camera rotation from a poses.json (marker seen in the photo)")
    p.add_argument("--frame", type=int, default=1, help="frame of --camera-from to use (default 1)")
    p.add_argument("--align-marker", type=float, metavar="SIZE",
                   help="align on an ArUco marker of this side (metres) seen in the photos (the tracked "
                        "scene's marker); needs --focal-px or --focal-mm")
    p.add_argument("--dictionary", default="DICT_4X4_50", help="dictionary of --align-marker")
    p.add_argument("--focal-px", type=float, help="the photos' focal length in pixels: the unwrap looks along "
                   "the ray through the ball (an off-centre ball), and --align-marker needs it")
    p.add_argument("--focal-mm", type=float, help="the focal length in mm, with --sensor-width (as --focal-px)")
    p.add_argument("--sensor-width", type=float, default=36.0, help="sensor width in mm (default 36)")
    p.add_argument("--rotate-z", type=float, default=0.0, metavar="DEG",
                   help="turn the probe about +Z to align it with the tracked scene")
    p.add_argument("--grey-card", type=_floats(4), metavar="X0,Y0,X1,Y1",
                   help="pixel box of a grey card in the photos: repairs light clipped in every bracket")
    p.add_argument("--card-albedo", type=float, default=0.18, help="grey card albedo (default 0.18)")
    p.add_argument("--card-normal", type=_floats(3), metavar="X,Y,Z",
                   help="grey card normal in the probe's frame (default: towards the clipped light)")
    p.add_argument("--per-channel-response", action="store_true",
                   help="recover R, G, B response curves separately (default: one shared curve)")
    p.add_argument("--fill", choices=FILLS, default="nearest",
                   help="directions a ball cut by the frame does not show: copied from the nearest seen "
                        "ones (default) or left black")
    p.add_argument("--report", metavar="FILE.json", help="write the ball, the finder's candidate circles, the "
                   "response curve and warnings, and FILE.png: the photo with the circles drawn")
    p.set_defaults(func=run)


def write_candidates(report: str, images, fits, err) -> None:
    """The report of a search that chose no ball: its candidates, the error, their picture."""
    import cv2

    from ..addon.footage import read_image
    from ..addon.capture.probe import candidate_json, candidates_picture

    write_json_atomic(report, {"error": worded(err, CLI_FLAGS), "candidates": [candidate_json(f) for f in fits]})
    cv2.imwrite(picture_path(report), candidates_picture(read_image(images[len(images) // 2]), fits))


def picture_path(report: str) -> str:
    """FILE.json -> FILE.png: the report's picture of the candidate circles."""
    return os.path.splitext(report)[0] + ".png"


def camera_from_poses(path: str, frame: int):
    try:
        with open(path, encoding="utf-8") as fh:
            data = json.load(fh)
        for entry in data["frames"]:
            if entry["frame"] == frame and entry.get("camera_to_world"):
                return entry["camera_to_world"]
    except FileNotFoundError:
        raise PlateLightError(f"Poses file not found: {path}") from None
    except (ValueError, KeyError, TypeError):
        raise PlateLightError(f"Not a PlateLight poses.json: {path}") from None
    raise PlateLightError(f"Frame {frame} has no camera pose in {path}.")


def run(args) -> int:
    import cv2

    from ..addon.exr_io import write_exr
    from ..addon.capture.mirror_ball import Ball
    from ..addon.capture.probe import candidates_picture, make_probe

    if args.height < 4:
        raise PlateLightError("The probe height must be at least 4 pixels.")
    if args.ball is not None and len(args.ball) not in (3, 4):
        raise PlateLightError(f"--ball needs CX,CY,R (or CX,CY,RX,RY), not {len(args.ball)} numbers.")
    ensure_writable_folder(os.path.dirname(os.path.abspath(args.out)))
    camera = camera_from_poses(args.camera_from, args.frame) if args.camera_from else None
    align, intrinsics = None, None
    if args.align_marker is not None:
        from ..addon.capture.targets import MarkerTarget

        align = MarkerTarget(args.dictionary, args.align_marker)
        if args.focal_px is None and args.focal_mm is None:
            raise PlateLightError("Aligning on a marker needs the camera's focal length (--focal-px or --focal-mm).")
    if (args.focal_px is not None or args.focal_mm is not None) and os.path.isfile(args.images[0]):
        from ..addon.footage import read_image
        from ..addon.capture.intrinsics import Intrinsics

        h, w = read_image(args.images[0]).shape[:2]     # (a missing bracket is reported by make_probe)
        intrinsics = (Intrinsics.from_focal_px(args.focal_px, w, h) if args.focal_px is not None
                      else Intrinsics.from_lens(args.focal_mm, args.sensor_width, w, h))
    t0 = time.perf_counter()
    try:
        result = make_probe(args.images, exposures=args.exposures,
                            ball=Ball(*args.ball) if args.ball else None, height=args.height,
                            camera_to_world=camera, rotate_z_deg=args.rotate_z, reflectance=args.reflectance,
                            card_box=args.grey_card, card_albedo=args.card_albedo, card_normal=args.card_normal,
                            shared_response=not args.per_channel_response, align_target=align,
                            intrinsics=intrinsics, fill=args.fill)
    except PlateLightError as err:
        seen = getattr(err, "candidates", ())
        if args.report and seen:      # not found, or two balls: show what was seen
            write_candidates(args.report, args.images, seen, err)
        raise
    write_exr(args.out, result.probe)
    if args.report:
        write_json_atomic(args.report, result.report())
        cv2.imwrite(picture_path(args.report), candidates_picture(result.photo, result.candidates, result.ball))
    for w in result.warnings:
        print(f"platelight probe: warning: {worded(w, CLI_FLAGS)}", file=sys.stderr)
    b = result.ball
    shape = f"r={b.radius:.1f}" if b.radius_y is None else f"rx={b.radius:.1f} ry={b.radius_y:.1f}"
    found = "given" if b.confidence is None else f"found, rim seen on {100 * b.confidence:.0f} % of the outline"
    photos = "1 photo" if len(result.times) == 1 else f"{len(result.times)} brackets"
    print(f"ball at ({b.cx:.1f}, {b.cy:.1f}) {shape} px ({found}); {photos}; "
          f"{time.perf_counter() - t0:.2f} s -> {args.out}")
    return 0
