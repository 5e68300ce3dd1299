"""bpy.ops.platelight.export_farm_job(): write an Open Job Description bundle of the saved scene
(addon/farm/jobs.py), the same as ``python -m platelight farm-job``.

The bundle is self-contained: the scene is saved as a copy into JOBDIR/scene/ and every file it
reads (plate, world probe, grain, textures, baked maps) is linked or copied beside it, with the
copy's paths made relative to it. Files under the .blend's folder keep their place; others go to
scene/external/N/. The user's own scene and files are never changed (paths are restored).
"""
from __future__ import annotations

import glob
import os
import shutil
import sys

import bpy
from bpy.props import EnumProperty, IntProperty, StringProperty

from ..addon.bake.layout import DEFAULT_MAPS_DIR
from ..addon.errors import PlateLightError
from ..addon.farm import jobs
from ..addon.fileio import ensure_writable_folder
from ..addon.footage import NUMBERED_FILE, sequence_frame_path
from ..addon.names import PLATE_FRAME_OFFSET_KEY
from .common import find_plate_image, report_error

EXTERNAL = "external"


def _files_of(path, source):
    """Every file a datablock path stands for: a sequence's numbered siblings, UDIM tiles."""
    if source == "TILED":
        return sorted(glob.glob(glob.escape(path).replace(glob.escape("<UDIM>"), "[0-9][0-9][0-9][0-9]")))
    if source == "SEQUENCE":
        folder, name = os.path.split(path)
        match = NUMBERED_FILE.match(name)
        if match:
            prefix, digits, ext = match.groups()
            return sorted(glob.glob(os.path.join(glob.escape(folder), glob.escape(prefix) + "[0-9]" * len(digits)
                                                 + "*" + glob.escape(ext))))
    return [path] if os.path.isfile(path) else []


def _check_plate(scene, frames):
    """One sentence when the plate or its frames in ``frames`` are missing."""
    image = find_plate_image(scene)
    if image is None or image.packed_file is not None:
        return
    path = os.path.normpath(bpy.path.abspath(image.filepath, library=image.library))
    if image.source == "SEQUENCE":
        offset = int(image.get(PLATE_FRAME_OFFSET_KEY, 0))
        missing = [f for f in frames if not os.path.isfile(sequence_frame_path(path, f + offset))]
        if missing:
            raise PlateLightError(f"The plate has no file for frame(s) {jobs.range_expression(missing)} "
                                  f"({sequence_frame_path(path, missing[0] + offset)} is missing).")
    elif not os.path.isfile(path):
        raise PlateLightError(f"The plate file {path} is missing; set up the plate again "
                              "(Scene > PlateLight Compositing > Plate).")


def external_files(scene):
    """[(datablock, attribute, absolute path, [files])] for every file the scene reads, plus the
    world probe. Raises PlateLightError for a missing plate, probe or other file."""
    found = []
    for collection in (bpy.data.images, bpy.data.movieclips, bpy.data.sounds, bpy.data.volumes):
        for block in collection:
            if getattr(block, "packed_file", None) is not None or not block.filepath:
                continue
            source = getattr(block, "source", "FILE")
            if source in {"GENERATED", "VIEWER"}:
                continue
            path = os.path.normpath(bpy.path.abspath(block.filepath, library=block.library))
            files = _files_of(path, source)
            if not files and block.users:
                raise PlateLightError(f"The file {path} ({block.name!r}) is missing; the farm job "
                                      "needs every file the scene reads.")
            found.append((block, "filepath", path, files))
    probe = scene.platelight.world_probe
    if probe:
        path = os.path.normpath(bpy.path.abspath(probe))
        if not os.path.isfile(path):
            raise PlateLightError(f"The world probe {path} is missing; choose it again in "
                                  "Scene > PlateLight > World Probe.")
        found.append((scene.platelight, "world_probe", path, [path]))
    return found


def _bundle_place(path, blend_dir, scene_dir, externals):
    """Where ``path`` goes in the bundle: the same place relative to the .blend when it lies
    under the .blend's folder, else scene/external/N/ (one N per source folder)."""
    rel = os.path.relpath(path, blend_dir)
    if not rel.startswith(os.pardir + os.sep) and rel != os.pardir and not os.path.isabs(rel):
        return os.path.join(scene_dir, rel)
    folder = os.path.dirname(path)
    index = externals.setdefault(folder, len(externals))
    return os.path.join(scene_dir, EXTERNAL, str(index), os.path.basename(path))


def _link_or_copy(src, dst):
    os.makedirs(os.path.dirname(dst), exist_ok=True)
    if os.path.exists(dst):
        if os.path.samefile(src, dst):
            return
        os.unlink(dst)
    try:
        os.link(src, dst)                  # same file system: no copy, no extra space
    except OSError:
        shutil.copy2(src, dst)


def check_frames(scene, frames):
    lo, hi = scene.frame_start, scene.frame_end
    outside = [f for f in frames if not lo <= f <= hi]
    if outside:
        raise PlateLightError(f"Frames {jobs.range_expression(outside)} lie outside the scene's frame "
                              f"range {lo}-{hi}.")


def check_job_folder(folder):
    """The bundle folder must be new, empty or an earlier bundle (never someone's other files)."""
    folder = ensure_writable_folder(folder)
    names = [n for n in os.listdir(folder) if not n.startswith(".")]
    if names and jobs.TEMPLATE not in names:
        raise PlateLightError(f"The folder {folder} holds other files; choose an empty folder "
                              "for the farm job.")
    return folder


def export_farm_job(context, folder, frames, chunk=1, fmt="exr", prefix="composite", python=None,
                    progress=None):
    """Write the bundle of the current (saved) scene into ``folder``; returns the FarmJob.
    ``progress(done, total)`` is called as the scene's files are linked or copied."""
    scene = context.scene
    blend = bpy.data.filepath
    if not blend:
        raise PlateLightError("Save the .blend file first: the farm job renders the saved scene.")
    if chunk < 1:
        raise PlateLightError(f"The chunk size must be at least 1 frame, not {chunk}.")
    if scene.camera is None:
        raise PlateLightError(f"The scene {scene.name} has no camera to render from.")
    check_frames(scene, frames)
    maps_dir = scene.platelight.maps_dir or DEFAULT_MAPS_DIR
    if not maps_dir.startswith("//"):
        raise PlateLightError(f"The Maps Folder {maps_dir} is absolute; make it relative to the .blend "
                              f"(e.g. {DEFAULT_MAPS_DIR}) so the maps travel with the farm job.")
    _check_plate(scene, frames)
    files = external_files(scene)
    folder = check_job_folder(folder)

    blend_dir = os.path.dirname(blend)
    scene_dir = os.path.join(folder, jobs.SCENE_FOLDER)
    scene_file = os.path.join(scene_dir, os.path.basename(blend))
    externals = {}
    restore = []
    try:
        for index, (block, attr, path, sources) in enumerate(files):
            if progress:
                progress(index, len(files))
            place = _bundle_place(path, blend_dir, scene_dir, externals)
            for src in sources:
                _link_or_copy(src, os.path.join(os.path.dirname(place), os.path.basename(src)))
            restore.append((block, attr, getattr(block, attr)))
            setattr(block, attr, "//" + os.path.relpath(place, scene_dir).replace(os.sep, "/"))
        # baked maps and their records come along, so the farm's bake reuses what is up to date
        maps_root = os.path.normpath(bpy.path.abspath(maps_dir))
        if os.path.isdir(maps_root):
            for root, _dirs, names in os.walk(maps_root):
                for name in names:
                    if not name.startswith("."):
                        src = os.path.join(root, name)
                        _link_or_copy(src, _bundle_place(src, blend_dir, scene_dir, externals))
        os.makedirs(scene_dir, exist_ok=True)
        bpy.ops.wm.save_as_mainfile(filepath=scene_file, copy=True, relative_remap=False)
    except OSError as exc:
        raise PlateLightError(f"Cannot write the farm job into {folder}: {exc.strerror}.") from None
    finally:
        for block, attr, value in reversed(restore):
            setattr(block, attr, value)

    has_objects = any(ob.platelight.enabled for ob in scene.objects)
    job = jobs.FarmJob(
        name=f"PlateLight {os.path.splitext(os.path.basename(blend))[0]} {jobs.range_expression(frames)}",
        scene=f"{jobs.SCENE_FOLDER}/{os.path.basename(blend)}", frames=list(frames), chunk=chunk,
        prefix=prefix, format=fmt, python=python or sys.executable, bake=has_objects)
    jobs.write_bundle(folder, job)
    return job


class PLATELIGHT_OT_export_farm_job(bpy.types.Operator):
    """Write an Open Job Description job (AWS Deadline Cloud bundle) that bakes the probes and renders
    the composite of the saved scene on a render farm; `openjd run FOLDER/template.yaml` runs it here"""

    bl_idname = "platelight.export_farm_job"
    bl_label = "Export Farm Job"
    bl_options = {"REGISTER"}

    directory: StringProperty(name="Job Folder", subtype="DIR_PATH",
                              description="An empty folder for the job bundle")
    frame_start: IntProperty(name="Start", description="First frame (0: the scene's start)", default=0)
    frame_end: IntProperty(name="End", description="Last frame (0: the scene's end)", default=0)
    chunk: IntProperty(name="Chunk Size", description="Frames per render task", default=10, min=1)
    format: EnumProperty(
        name="Format",
        items=(("exr", "EXR", "The composite, float RGBA OpenEXR"),
               ("multilayer", "Multilayer EXR", "The composite and named passes in one EXR per frame"),
               ("png", "PNG", "The composite, 8-bit RGBA")),
        default="exr")

    @classmethod
    def poll(cls, context):
        if context.scene is None or context.scene.camera is None:
            cls.poll_message_set("The scene needs a camera")
            return False
        if not bpy.data.filepath:
            cls.poll_message_set("Save the .blend file first")
            return False
        return True

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        scene = context.scene
        start = self.frame_start or scene.frame_start
        end = self.frame_end or scene.frame_end
        if end < start:
            self.report({"ERROR"}, f"The frame range {start}-{end} ends before it starts.")
            return {"CANCELLED"}
        if not self.directory:
            self.report({"ERROR"}, "Choose a Job Folder for the farm job.")
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, 1)
        try:
            job = export_farm_job(context, bpy.path.abspath(self.directory), list(range(start, end + 1)),
                                  chunk=self.chunk, fmt=self.format,
                                  progress=lambda done, total: wm.progress_update(done / max(total, 1)))
        except PlateLightError as err:
            report_error(self, err)
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        tasks = len(jobs.chunks(job.frames, job.chunk))
        self.report({"INFO"}, f"Farm job written to {self.directory}: "
                    f"{'a bake task and ' if job.bake else ''}{tasks} render task(s).")
        return {"FINISHED"}


classes = (PLATELIGHT_OT_export_farm_job,)
