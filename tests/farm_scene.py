"""A tiny saved shot for the farm tests: a 4-frame plate sequence (48×27) outside the .blend's
folder, a world probe EXR, a moving PlateLight sphere with its SBRDF material, a phantom ground
that catches its shadow, and the composite set up (2 spp)."""
from __future__ import annotations

import numpy as np

from bake_scenes import add_plane, add_sphere, new_scene
from composite_scene import add_sun
from platelight.addon.exr_io import write_exr

FRAMES = 4
PW, PH = 48, 27


def make_shot(bpy, root, frames=FRAMES):
    """Build and save ``root/shot/scene.blend``; returns (blend path, {frame: plate})."""
    scene = new_scene(bpy, root, world_color=(0.3, 0.3, 0.3), save=False, height=8, samples=2)
    plates = {}
    for k in range(1, frames + 1):
        plates[k] = (0.1 + 0.8 * np.random.default_rng(k).random((PH, PW, 3))).astype(np.float32)
        write_exr(root / "plate" / f"plate_{k:04d}.exr", plates[k])
    probe = np.full((16, 32, 3), 0.3, np.float32)
    probe[2:5, 10:13] = 40.0                                   # a small sun in the probe
    write_exr(root / "probe" / "probe.exr", probe)
    scene.platelight.world_probe = str(root / "probe" / "probe.exr")
    add_plane(bpy, "Ground", (0, 0, -0.5), size=8.0, phantom=True)
    ball = add_sphere(bpy, "Ball", (0, 0, 0), color=(0.8, 0.5, 0.2))
    ball.keyframe_insert("location", frame=1)
    ball.location = (0.6, 0, 0.2)
    ball.keyframe_insert("location", frame=frames)
    bpy.context.view_layer.objects.active = ball
    assert bpy.ops.platelight.apply_sbrdf() == {"FINISHED"}
    add_sun(bpy, scene)
    assert bpy.ops.platelight.setup_plate(filepath=str(root / "plate" / "plate_0001.exr")) == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(samples=2) == {"FINISHED"}
    scene.frame_set(1)
    path = root / "shot" / "scene.blend"
    path.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path, plates
