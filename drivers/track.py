"""`python -m platelight track FRAMES --dictionary D --marker-size M ... --out poses.json`."""
from __future__ import annotations

import argparse
import os
import sys
import time

from ..addon.errors import PlateLightError
from ..addon.wording import CLI_FLAGS, worded
from ..addon.fileio import ensure_writable_folder, write_json_atomic


def _squares(text: str) -> tuple[int, int]:
    try:
        cols, rows = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError("squares must look like 5x7 (columns x rows)") from None
    return cols, rows


def add_parser(sub) -> None:
    p = sub.add_parser("track", help="ArUco marker / ChArUco board tracking -> camera poses JSON",
                       description="Track a printed marker or ChArUco board through a clip or an image "
                                   "folder and write the camera path in the marker's frame.")
    p.add_argument("frames", nargs="?", metavar="FRAMES",
                   help="folder of images (sorted by name, frames from 1) or a video file")
    p.add_argument("--dictionary", default="DICT_4X4_50", help="OpenCV ArUco dictionary (default DICT_4X4_50)")
    p.add_argument("--marker-size", type=float, help="marker side in metres (black border to black border)")
    p.add_argument("--marker-id", type=int, default=None, help="track only this marker id (default: largest seen)")
    p.add_argument("--board", choices=("marker", "charuco"), default="marker", help="target type")
    p.add_argument("--squares", type=_squares, default=(5, 7), help="ChArUco squares, columns x rows")
    p.add_argument("--square-size", type=float, help="ChArUco square side in metres")
    p.add_argument("--legacy-board", action="store_true", help="ChArUco pattern of OpenCV < 4.6")
    cam = p.add_argument_group("camera (one of)")
    cam.add_argument("--focal-px", type=float, help="focal length in pixels")
    cam.add_argument("--focal-mm", type=float, help="focal length in millimetres (with --sensor-width)")
    cam.add_argument("--sensor-width", type=float, default=36.0, help="sensor width in mm (default 36)")
    cam.add_argument("--calibration", metavar="FILE", help="JSON (fx, fy, cx, cy[, dist]) or OpenCV YAML")
    cam.add_argument("--calibrate", action="store_true", help="calibrate from the frames (ChArUco only)")
    p.add_argument("--smooth", type=float, default=0.0, metavar="SIGMA",
                   help="Gaussian smoothing of the path, sigma in frames (default 0: off)")
    p.add_argument("--lost", choices=("interpolate", "skip"), default="interpolate",
                   help="frames where tracking is lost: interpolate (default) or leave without a pose")
    p.add_argument("--print-board", metavar="FILE.pdf|png",
                   help="write a printable marker/board at true size instead of tracking")
    p.add_argument("--dpi", type=float, default=300.0, help="resolution of --print-board")
    p.add_argument("--out", metavar="poses.json", help="output JSON")
    p.set_defaults(func=run)


def make_target(args):
    from ..addon.capture.targets import CharucoTarget, MarkerTarget

    if args.marker_size is None:
        raise PlateLightError("Give the printed marker's side with --marker-size (metres).")
    if args.board == "charuco":
        if args.square_size is None:
            raise PlateLightError("A ChArUco board needs --square-size (metres) as well as --marker-size.")
        return CharucoTarget(args.dictionary, args.squares, args.square_size, args.marker_size,
                             legacy=args.legacy_board)
    return MarkerTarget(args.dictionary, args.marker_size, args.marker_id)


def run(args) -> int:
    from ..addon.capture.intrinsics import load_calibration
    from ..addon.capture.tracking import track

    target = make_target(args)
    if args.print_board:
        from ..addon.capture.boards import write_target

        ensure_writable_folder(os.path.dirname(os.path.abspath(args.print_board)))
        write_target(args.print_board, target, dpi=args.dpi)
        print(f"wrote {args.print_board} (print at 100 % scale)")
        return 0
    if not args.frames:
        raise PlateLightError("Give the frames to track (an image folder or a video file).")
    if not args.out:
        raise PlateLightError("Give the output file with --out poses.json.")
    ensure_writable_folder(os.path.dirname(os.path.abspath(args.out)))
    intrinsics = load_calibration(args.calibration) if args.calibration else None
    t0 = time.perf_counter()
    result = track(args.frames, target, intrinsics=intrinsics, focal_px=args.focal_px,
                   lens_mm=args.focal_mm, sensor_width_mm=args.sensor_width, calibrate=args.calibrate,
                   smooth_sigma=args.smooth, lost=args.lost)
    write_json_atomic(args.out, result.to_json())
    for w in result.warnings:
        print(f"platelight track: warning: {worded(w, CLI_FLAGS)}", file=sys.stderr)
    n = len(result.frames)
    print(f"tracked {result.tracked_count}/{n} frames in {time.perf_counter() - t0:.2f} s -> {args.out}")
    return 0
