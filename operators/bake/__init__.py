"""Bake per-object reflection probes (paper section 3.3): the operators
``bpy.ops.platelight.bake_probes`` and ``bpy.ops.platelight.check_probes`` and their menu entry.

The bake itself is job.py (ProbeBake: plan, steps, world maps, summary), run here step by step so
the window shows progress and Esc stops it; inputs.py reads what a probe depends on from the
scene, probe_render.py renders the panorama, records.py hashes and packs, scene_state.py puts
the scene back."""
import bpy
from bpy.props import BoolProperty, IntProperty

from ...addon.errors import PlateLightError
from ..common import addon_preferences, report_error
from .job import ProbeBake, target_objects


class _ProbeOperator:
    """What bake_probes and check_probes share: targets, frames, options, running the job."""
    check_only = False

    all_objects: BoolProperty(name="All Objects", default=False,
                              description="Bake every PlateLight object in the scene, not only the selected ones")
    use_frame_range: BoolProperty(name="Frame Range", default=False,
                                  description="Bake every frame from Start to End (per-frame maps)")
    frame_start: IntProperty(name="Start", default=1, description="First frame of the range")
    frame_end: IntProperty(name="End", default=1, description="Last frame of the range")
    force: BoolProperty(name="Re-bake Unchanged", default=False,
                        description="Render probes even when nothing that affects them changed")
    cull: BoolProperty(name="Skip Off-screen Objects", default=True,
                       description="Skip objects outside the camera view in every frame")
    reuse_world: BoolProperty(name="Share World Maps", default=True,
                              description="Objects that see nothing but the world use the world's maps")

    _job = None
    _timer = None

    @classmethod
    def poll(cls, context):
        if context.scene is None:
            return False
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode to bake probes")
            return False
        return True

    def _frames(self, context):
        """(frames, static): the range when asked for (frame_start/frame_end given, or Frame
        Range ticked: the scene's range where they are not), else the current frame with
        single-frame file names."""
        props, scene = self.properties, context.scene
        given_start, given_end = props.is_property_set("frame_start"), props.is_property_set("frame_end")
        if self.use_frame_range or given_start or given_end:
            start = self.frame_start if given_start else (scene.frame_start if self.use_frame_range else 1)
            end = self.frame_end if given_end else (scene.frame_end if self.use_frame_range else start)
            if end < start:
                raise PlateLightError(f"The frame range ends ({end}) before it starts ({start}).")
            return list(range(start, end + 1)), False
        return [context.scene.frame_current], True

    def _make_job(self, context):
        frames, static = self._frames(context)
        prefs = addon_preferences(context)
        use_cache = not self.force and (prefs is None or prefs.cache_bakes)
        return ProbeBake(context, target_objects(context, self.all_objects), frames, static=static,
                         use_cache=use_cache or self.check_only, reuse_world=self.reuse_world,
                         cull=self.cull, check_only=self.check_only)

    def execute(self, context):
        wm = context.window_manager
        try:
            job = self._make_job(context)
        except PlateLightError as err:
            report_error(self, err)
            return {"CANCELLED"}
        wm.progress_begin(0, 1)
        try:
            job.start()
            while job.step():
                done, total = job.progress
                wm.progress_update(done / total)
        except PlateLightError as err:
            report_error(self, err)
            return {"CANCELLED"}
        finally:
            job.end()
            wm.progress_end()
        return self._finish(job)

    def _finish(self, job):
        for warning in job.warnings:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, job.summary())
        return {"CANCELLED"} if job.cancelled else {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None or self.check_only:
            return self.execute(context)
        try:
            self._job = self._make_job(context)
            self._job.start()
        except PlateLightError as err:
            if self._job is not None:
                self._job.end()
            report_error(self, err)
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, 1)
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        job = self._job
        if event.type == "ESC":
            job.cancel()
            return self._stop(context)
        if event.type != "TIMER":
            return {"RUNNING_MODAL"}
        try:
            more = job.step()
        except PlateLightError as err:
            self._stop(context, finish=False)
            report_error(self, err)
            return {"CANCELLED"}
        except Exception:
            self._stop(context, finish=False)      # a bug: still give the user their scene back
            raise
        done, total = job.progress
        context.window_manager.progress_update(done / total)
        context.workspace.status_text_set(f"PlateLight: baking probe {done}/{total} (Esc to cancel)")
        return {"RUNNING_MODAL"} if more else self._stop(context)

    def _stop(self, context, finish=True):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        self._job.end()
        wm.progress_end()
        context.workspace.status_text_set(None)
        return self._finish(self._job) if finish else {"CANCELLED"}


class PLATELIGHT_OT_bake_probes(_ProbeOperator, bpy.types.Operator):
    """Render each PlateLight object's surroundings from its centre and bake its four maps"""
    bl_idname = "platelight.bake_probes"
    bl_label = "Bake PlateLight Probes"
    bl_options = {"REGISTER", "UNDO"}


class PLATELIGHT_OT_check_probes(_ProbeOperator, bpy.types.Operator):
    """Tell which probes are stale (their inputs changed since the bake) without rendering"""
    bl_idname = "platelight.check_probes"
    bl_label = "Check PlateLight Probes"
    bl_options = {"REGISTER", "UNDO"}
    check_only = True


def menu_entry(self, context):
    self.layout.separator()
    self.layout.operator(PLATELIGHT_OT_bake_probes.bl_idname, icon="LIGHTPROBE_SPHERE")


classes = (PLATELIGHT_OT_bake_probes, PLATELIGHT_OT_check_probes)


def register_extra():
    bpy.types.VIEW3D_MT_object.append(menu_entry)
    bpy.types.TOPBAR_MT_render.append(menu_entry)


def unregister_extra():
    bpy.types.VIEW3D_MT_object.remove(menu_entry)
    bpy.types.TOPBAR_MT_render.remove(menu_entry)
