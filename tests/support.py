"""Constants and small helpers shared by tests and benchmarks (importable: tests/ is on sys.path).

Importing this module makes ``import platelight`` resolve to *this* checkout (a symlink in a
temporary folder put first on sys.path), so tests never pick up another copy by accident."""
from __future__ import annotations

import hashlib
import os
import pathlib
import subprocess
import sys
import tempfile

REPO = pathlib.Path(__file__).resolve().parents[1]
# the shared contracts and data: beside the checkout (/work/main) or above a worktree (/work/wt/NAME)
SHARED = next((p / "shared" for p in REPO.parents if (p / "shared" / "design.md").is_file()),
              REPO.parent / "shared")
GRACE = SHARED / "data" / "probes" / "grace_latlong.exr"

_SHIM = pathlib.Path(tempfile.gettempdir()) / (
    "platelight-shim-" + hashlib.sha1(str(REPO).encode()).hexdigest()[:10])


def _install_shim() -> None:
    _SHIM.mkdir(exist_ok=True)
    link = _SHIM / "platelight"
    if not (link.is_symlink() and os.readlink(link) == str(REPO)):
        tmp = _SHIM / f".platelight-{os.getpid()}"
        tmp.symlink_to(REPO, target_is_directory=True)
        os.replace(tmp, link)
    if str(_SHIM) not in sys.path:
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
