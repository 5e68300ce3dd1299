"""Run by test_install_from_disk.py in a fresh Python: install the built zip the way Edit ›
Preferences › Get Extensions › Install from Disk does, into the empty user folder named by
BLENDER_USER_RESOURCES, enable it, and bake and composite a small scene with the installed copy.

The project's environment also has OpenEXR and cv2; they are hidden here, so every import of them
must find the copies the zip carries. Prints one JSON line of facts for the test to check."""
import importlib
import importlib.abc
import importlib.machinery
import json
import os
import sys
import sysconfig

ZIP, WORK = sys.argv[1], sys.argv[2]
BUNDLED = ("OpenEXR", "cv2")
ENV_SITE = os.path.realpath(sysconfig.get_paths()["purelib"])


class HideEnvironmentCopies(importlib.abc.MetaPathFinder):
    """OpenEXR and cv2 come only from outside the environment's site-packages."""

    def find_spec(self, name, path=None, target=None):
        if name not in BUNDLED:
            return None
        elsewhere = [p for p in sys.path if os.path.realpath(p or ".") != ENV_SITE]
        spec = importlib.machinery.PathFinder.find_spec(name, elsewhere)
        if spec is None:
            raise ModuleNotFoundError(f"{name} is not bundled in the extension", name=name)
        return spec


sys.meta_path.insert(0, HideEnvironmentCopies())
import bpy  # noqa: E402

facts = {"blender": bpy.app.version_string}
result = bpy.ops.extensions.package_install_files(filepath=ZIP, repo="user_default",
                                                  enable_on_install=True)
module = "bl_ext.user_default.platelight"
facts["installed"] = sorted(result)
facts["enabled"] = module in bpy.context.preferences.addons
compat = importlib.import_module(module + ".compat")
exr_io = importlib.import_module(module + ".addon.exr_io")
import cv2  # noqa: E402
import numpy as np  # noqa: E402
import OpenEXR  # noqa: E402

user = os.path.realpath(os.environ["BLENDER_USER_RESOURCES"])
facts["bundled_from_user_folder"] = {m.__name__: os.path.realpath(m.__file__).startswith(user)
                                     for m in (cv2, OpenEXR)}
marker = cv2.aruco.generateImageMarker(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50), 7, 60)
facts["aruco"] = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)) \
    .detectMarkers(np.pad(marker, 20, constant_values=255))[1].ravel().tolist()

# A small scene: a glossy sphere (CG) on a phantom floor, lit by a turned, brightened HDRI.
bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.render.resolution_x, scene.render.resolution_y = 48, 32
scene.render.resolution_percentage = 100
world = compat.new_world("Place")
tree = world.node_tree
env = tree.nodes.new("ShaderNodeTexEnvironment")
hdri = os.path.join(bpy.utils.system_resource("DATAFILES", path="studiolights/world"), "courtyard.exr")
env.image = bpy.data.images.load(hdri)
mapping = tree.nodes.new("ShaderNodeMapping")
coords = tree.nodes.new("ShaderNodeTexCoord")
tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
mapping.inputs["Rotation"].default_value = (0.0, 0.0, 1.0)
tree.links.new(env.outputs["Color"], tree.nodes["Background"].inputs["Color"])
tree.nodes["Background"].inputs["Strength"].default_value = 1.5
scene.world = world
cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
scene.collection.objects.link(cam)
cam.location, cam.rotation_euler = (0.0, -4.0, 1.0), (1.396, 0.0, 0.0)
scene.camera = cam
bpy.ops.mesh.primitive_plane_add(size=20.0)
bpy.context.object.platelight.phantom = True
bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0.0, 0.0, 0.5), segments=16, ring_count=8)
sphere = bpy.context.object
sphere.platelight.enabled = True
scene.platelight.probe_height = 16
scene.platelight.probe_samples = 4
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(WORK, "smoke.blend"))
facts["bake"] = sorted(bpy.ops.platelight.bake_probes(all_objects=True, cull=False))
facts["maps"] = sorted(os.listdir(os.path.join(WORK, "platelight_maps")))
bpy.context.view_layer.objects.active = sphere
facts["sbrdf"] = sorted(bpy.ops.platelight.apply_sbrdf(preset="chrome"))
plate_path = os.path.join(WORK, "plate.exr")
PLATE_VALUE = 0.25
plate = np.full((32, 48, 3), PLATE_VALUE, np.float32)
exr_io.write_exr(plate_path, plate)
facts["plate"] = sorted(bpy.ops.platelight.setup_plate(filepath=plate_path))
facts["composite"] = sorted(bpy.ops.platelight.setup_composite(method="CATCHER", samples=4))
scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_depth = "32"
scene.render.filepath = os.path.join(WORK, "composite.exr")
bpy.ops.render.render(write_still=True)
out = exr_io.read_exr(scene.render.filepath, "RGB")
facts["composite_finite"] = bool(np.isfinite(out).all())
facts["corner_is_plate"] = float(np.abs(out[0, 0] - PLATE_VALUE).max())       # sky: no CG, no shadow
# the chrome sphere: its upper half reflects the sky (its lower half the floor, which looks like the
# plate: the pixel at the frame's centre differed from it by 0.01 converged, which 4 samples' noise
# made pass or fail)
facts["sphere_differs"] = float(np.abs(out[8:16, 16:32] - PLATE_VALUE).max())
print("SMOKE " + json.dumps(facts), flush=True)
compat.exit_process(0)
