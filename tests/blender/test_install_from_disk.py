"""The package `make dist` builds installs the way Edit › Preferences › Get Extensions › Install
from Disk does, into a clean user folder, enables, and bakes and composites a small scene with the
wheels it carries — on the Blender release this suite runs on (`make test BLENDER=X.Y`)."""
import json
import os
import platform
import subprocess
import sys

import pytest

import support

PLATFORM = {("Linux", "x86_64"): "linux-x64", ("Windows", "AMD64"): "windows-x64",
            ("Darwin", "arm64"): "macos-arm64"}.get((platform.system(), platform.machine()))


@pytest.mark.slow
@pytest.mark.skipif(PLATFORM is None, reason="no package is built for this platform")
def test_built_zip_installs_enables_bakes_and_composites(tmp_path):
    # Only this platform's zip (the wheels are cached in wheels/ after the first download).
    build = subprocess.run([sys.executable, str(support.REPO / "tools" / "extension.py"), "build",
                            "--out", str(tmp_path / "dist"), "--platform", PLATFORM],
                           capture_output=True, text=True, timeout=1200)
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    (package,) = (tmp_path / "dist").glob("*.zip")
    user, work = tmp_path / "user", tmp_path / "work"
    user.mkdir()
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["BLENDER_USER_RESOURCES"] = str(user)
    smoke = subprocess.run([sys.executable, str(support.REPO / "tests" / "blender" / "install_smoke.py"),
                            str(package), str(work)], cwd=work, env=env, capture_output=True, text=True,
                           timeout=600)
    lines = [line for line in smoke.stdout.splitlines() if line.startswith("SMOKE ")]
    assert smoke.returncode == 0 and lines, smoke.stdout[-3000:] + smoke.stderr[-3000:]
    facts = json.loads(lines[-1][len("SMOKE "):])
    assert facts["installed"] == ["FINISHED"] and facts["enabled"], facts
    assert facts["bundled_from_user_folder"] == {"cv2": True, "OpenEXR": True}, facts
    assert facts["aruco"] == [7]
    assert facts["bake"] == facts["sbrdf"] == facts["plate"] == facts["composite"] == ["FINISHED"], facts
    assert facts["maps"] == ["Sphere"], facts
    assert facts["composite_finite"]
    assert facts["corner_is_plate"] < 1e-5, facts       # untouched plate where nothing is
    assert facts["sphere_differs"] > 1.0, facts         # the chrome sphere's sky
