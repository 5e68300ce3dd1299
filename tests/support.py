"""Constants and small helpers shared by tests and benchmarks (importable: tests/ is on sys.path)."""
import pathlib

REPO = pathlib.Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
GRACE = SHARED / "data" / "probes" / "grace_latlong.exr"
EXT_MODULE = "bl_ext.dev.platelight"
