"""Constants and small helpers shared by tests and benchmarks (importable: tests/ is on sys.path).

Importing this module makes ``import platelight`` resolve to *this* checkout (a symlink in a
temporary folder of this process, put first on sys.path and removed at exit), so tests never
pick up another copy by accident."""
from __future__ import annotations

import atexit
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

REPO = pathlib.Path(__file__).resolve().parents[1]
# the shared data sit beside the main checkout (/work/shared next to /work/main); a worktree
# (/work/wt/NAME) finds them one level further up
SHARED = next((p / "shared" for p in REPO.parents if (p / "shared" / "data").is_dir()), REPO.parent / "shared")
REAL = SHARED / "data" / "real"
GRACE = SHARED / "data" / "probes" / "grace_latlong.exr"

# This process's own folder holding a `platelight` link to the checkout, removed at exit.
_SHIM = pathlib.Path(tempfile.mkdtemp(prefix="platelight-shim-"))
atexit.register(shutil.rmtree, _SHIM, ignore_errors=True)


def _install_shim() -> None:
    (_SHIM / "platelight").symlink_to(REPO, target_is_directory=True)
    sys.path.insert(0, str(_SHIM))


_install_shim()
from platelight.drivers.headless import EXT_MODULE  # noqa: E402  (the checkout just put on the path)


def cli_env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(_SHIM) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def run_cli(*args, cwd=None, timeout=600) -> subprocess.CompletedProcess:
    """Run ``python -m platelight ARGS`` on this checkout; returns the completed process."""
    return subprocess.run([sys.executable, "-m", "platelight", *map(str, args)], cwd=cwd,
                          env=cli_env(), capture_output=True, text=True, timeout=timeout)


def compat():
    """The checkout's compat.py (the Blender-version glue; it imports bpy, so call it from
    Blender tests only)."""
    import importlib

    return importlib.import_module("platelight.compat")
