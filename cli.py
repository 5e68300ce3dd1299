"""`python -m platelight SUBCOMMAND ...`: the command-line contract of design.md.

Each subcommand lives in its own module exposing ``add_parser(subparsers)`` (which sets
``func``); a user's mistake becomes a PlateLightError: one sentence on stderr and exit 2."""
from __future__ import annotations

import argparse
import importlib
import sys

from .addon.errors import PlateLightError
from .addon.wording import CLI_FLAGS as FLAGS

# subcommand -> module (relative to this package) that defines add_parser(); maps, track and
# probe run the engine without Blender, the others start headless Blender (drivers/headless.py)
SUBCOMMANDS = {
    "maps": ".drivers.maps",
    "demo": ".drivers.demo",
    "track": ".drivers.track",
    "probe": ".drivers.probe",
    "bake": ".drivers.bake",
    "render": ".drivers.render",
    "farm-job": ".drivers.farm_job",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m platelight",
        description="PlateLight: image-based lighting maps, tracking and probes for AR compositing.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, module_name in SUBCOMMANDS.items():
        module = importlib.import_module(module_name, __package__)
        module.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except PlateLightError as err:
        print(f"platelight {args.command}: error: {err.worded(FLAGS)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"platelight {args.command}: interrupted; nothing half-written was left.", file=sys.stderr)
        return 130
