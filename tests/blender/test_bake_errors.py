"""Bad input to the bake: one clear sentence, {'CANCELLED'}, nothing written, the scene as it was."""
from __future__ import annotations

import pytest

from platelight.addon import names

from bake_scenes import add_plane, add_sphere, bake_module, maps_folder, new_scene, scene_snapshot


def assert_refused(bpy, tmp_path, match, **kwargs):
    before = scene_snapshot(bpy)
    with pytest.raises(RuntimeError, match=match) as info:
        bpy.ops.platelight.bake_probes(**kwargs)
    message = str(info.value).strip().splitlines()[0]
    assert "Traceback" not in str(info.value)
    assert message.count(". ") == 0, f"not one sentence: {message}"
    assert scene_snapshot(bpy) == before
    assert not (tmp_path / "platelight_maps" / "Sphere").exists()
    return message


def test_no_camera(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path)
    add_sphere(bpy, "Sphere", (0, 0, 0))
    scene.camera = None
    assert_refused(bpy, tmp_path, "no camera", all_objects=True)


def test_no_world(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path)
    add_sphere(bpy, "Sphere", (0, 0, 0))
    scene.world = None
    assert_refused(bpy, tmp_path, "no world", all_objects=True)


def test_nothing_selected(bpy_clean, tmp_path):
    bpy = bpy_clean
    new_scene(bpy, tmp_path)
    add_sphere(bpy, "Sphere", (0, 0, 0)).select_set(False)
    assert_refused(bpy, tmp_path, "No PlateLight objects")


def test_object_without_geometry(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path)
    empty = bpy.data.objects.new("Sphere", None)
    scene.collection.objects.link(empty)
    empty.platelight.enabled = True
    assert_refused(bpy, tmp_path, "has no geometry", all_objects=True)


def test_mesh_without_vertices(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path)
    ob = bpy.data.objects.new("Sphere", bpy.data.meshes.new("Nothing"))
    scene.collection.objects.link(ob)
    ob.platelight.enabled = True
    assert_refused(bpy, tmp_path, "has no geometry", all_objects=True)


def test_zero_size(bpy_clean, tmp_path):
    bpy = bpy_clean
    new_scene(bpy, tmp_path)
    add_sphere(bpy, "Sphere", (0, 0, 0)).scale = (0, 0, 0)
    assert_refused(bpy, tmp_path, "zero size", all_objects=True)


def test_probe_origin_inside_another_object(bpy_clean, tmp_path):
    bpy = bpy_clean
    new_scene(bpy, tmp_path)
    add_sphere(bpy, "Sphere", (0, 0, 0), radius=0.2)
    bpy.ops.mesh.primitive_cube_add(size=2, location=(0.3, 0, 0))     # swallows the sphere's centre
    assert_refused(bpy, tmp_path, "lies inside 'Cube'", all_objects=True)


def test_origin_near_but_outside_another_object_is_fine(bpy_clean, tmp_path):
    bpy = bpy_clean
    new_scene(bpy, tmp_path)
    add_sphere(bpy, "Sphere", (0, 0, 0), radius=0.2)
    bpy.ops.mesh.primitive_cube_add(size=2, location=(1.1, 0.0, 0.0))  # bounding box stops at 0.1
    assert bpy.ops.platelight.bake_probes(all_objects=True, cull=False) == {"FINISHED"}


def test_linked_library_object(bpy_clean, tmp_path):
    bpy = bpy_clean
    new_scene(bpy, tmp_path, save=False)
    add_sphere(bpy, "Sphere", (0, 0, 0))
    library = tmp_path / "library.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(library), copy=True)
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = new_scene(bpy, tmp_path)
    with bpy.data.libraries.load(str(library), link=True) as (src, dst):
        dst.objects = ["Sphere"]
    scene.collection.objects.link(dst.objects[0])
    assert dst.objects[0].library is not None and dst.objects[0].platelight.enabled
    assert_refused(bpy, tmp_path, "linked from the library", all_objects=True)


def test_unsaved_blend_with_relative_maps_folder(bpy_clean, tmp_path):
    bpy = bpy_clean
    new_scene(bpy, tmp_path, save=False)
    add_sphere(bpy, "Sphere", (0, 0, 0))
    assert_refused(bpy, tmp_path, "Save the .blend file first", all_objects=True)


def test_unwritable_maps_folder(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path)
    add_sphere(bpy, "Sphere", (0, 0, 0))
    scene.platelight.maps_dir = "/proc/platelight-maps"     # nobody, not even root, writes here
    assert_refused(bpy, tmp_path, "Cannot create the maps folder", all_objects=True)


def test_missing_world_exr(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path)
    add_sphere(bpy, "Sphere", (0, 0, 0))
    scene.platelight.world_probe = str(tmp_path / "no-such-probe.exr")
    assert_refused(bpy, tmp_path, "does not exist", all_objects=True)


def test_reversed_frame_range(bpy_clean, tmp_path):
    bpy = bpy_clean
    new_scene(bpy, tmp_path)
    add_sphere(bpy, "Sphere", (0, 0, 0))
    assert_refused(bpy, tmp_path, "before it starts", all_objects=True, frame_start=5, frame_end=2)


def test_cancel_midway_keeps_finished_maps_and_restores_the_scene(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path)
    a = add_sphere(bpy, "A", (0, 0, 0))
    b = add_sphere(bpy, "B", (2, 0, 0))
    add_plane(bpy, "Floor", (0, 0, -1), phantom=True).is_shadow_catcher = True
    scene.frame_set(3)
    before = scene_snapshot(bpy)
    module = bake_module()
    job = module.ProbeBake(bpy.context, [a, b], [1, 2, 3], static=False, cull=False)
    job.start()
    try:
        assert job.step()                      # one object-frame done, five to go
        assert scene.camera.name == names.PROBE_CAMERA
        job.cancel()                           # what Esc does in the modal operator
        assert not job.step()
    finally:
        job.end()
    assert scene_snapshot(bpy) == before
    assert job.cancelled and len(job.baked) == 1
    assert "cancelled" in job.summary()
    assert (maps_folder(tmp_path, "A") / "diffuse_0001.exr").is_file()
    assert not (maps_folder(tmp_path, "A") / "diffuse_0002.exr").exists()
    assert b.platelight.probe_status == "cancelled"
    # Nothing half-written: no temporary files next to the maps.
    assert not [p for p in maps_folder(tmp_path, "A").iterdir() if p.name.startswith(".tmp")]


def test_error_during_bake_restores_the_scene(bpy_clean, tmp_path, monkeypatch):
    """A failure after the scene was changed (here: the engine refusing the render) still puts
    everything back."""
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path)
    add_sphere(bpy, "Sphere", (0, 0, 0))
    module = bake_module()

    def refuse(*args, **kwargs):
        raise module.PlateLightError("The probe could not be turned into maps.")

    monkeypatch.setattr(module, "compute_maps", refuse)
    before = scene_snapshot(bpy)
    with pytest.raises(RuntimeError, match="could not be turned into maps"):
        bpy.ops.platelight.bake_probes(all_objects=True, cull=False)
    assert scene_snapshot(bpy) == before
