"""Can this Blender render with EEVEE? Asked once per Blender session, in a child process.

In the window a GL context always exists. Headless (``blender -b``, the bpy module) EEVEE needs
one from EGL; where none can be made (no GPU driver, no software GL) Blender does not raise: the
process prints EGL errors and exits (measured with __EGL_VENDOR_LIBRARY_DIRS pointing nowhere:
bpy.ops.render.render never returned). So the question is put to a child Blender that renders
an 8×8 EEVEE image; the answer is cached for the Blender session.
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile

import bpy

from .. import compat

NO_GL_SENTENCE = ("EEVEE cannot render here: this Blender could not make a GL context (headless, "
                  "no GPU driver or software GL); the composite is set up for Cycles instead.")
_CHILD = r"""
import bpy, sys
bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
s = bpy.context.scene
s.render.engine = sys.argv[-2]
s.render.resolution_x = s.render.resolution_y = 8
cam = bpy.data.objects.new("C", bpy.data.cameras.new("C"))
s.collection.objects.link(cam)
s.camera = cam
s.eevee.taa_render_samples = 1
s.render.image_settings.file_format = "PNG"
s.render.filepath = sys.argv[-1]
bpy.ops.render.render(write_still=True)
"""
_answer: bool | None = None


def _child_command(png: str) -> list[str]:
    if bpy.app.binary_path:                       # Blender itself: run it in background mode
        return [bpy.app.binary_path, "-b", "--factory-startup", "--python-expr", _CHILD, "--", compat.EEVEE, png]
    return [sys.executable, "-c", "import sys; exec(sys.argv[1])", _CHILD, compat.EEVEE, png]   # the bpy module


def eevee_available(timeout: float = 300.0) -> bool:
    """True when EEVEE can render in this Blender session (always in the window)."""
    global _answer
    if not bpy.app.background:
        return True
    if _answer is None:
        with tempfile.TemporaryDirectory(prefix="platelight-eevee-") as folder:
            png = os.path.join(folder, "probe.png")
            try:
                subprocess.run(_child_command(png), stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL, timeout=timeout, check=False)
            except (OSError, subprocess.TimeoutExpired):
                pass
            _answer = os.path.isfile(png) and os.path.getsize(png) > 0
    return _answer
