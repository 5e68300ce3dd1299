"""Probe baking in headless Blender (Cycles, tiny renders): colour bleeding from phantoms,
other objects at the right direction, the owner never in its own probe, caching, frame ranges,
culling, world maps, and the scene left as it was."""
from __future__ import annotations

import json

import numpy as np
import pytest

from bake_scenes import (add_plane, add_sphere, angle_deg, bake_module, bright_direction, maps_folder,
                         new_scene, probe_renders, read_map, scene_snapshot)
from support import compat


def bake(bpy, **kwargs):
    result = bpy.ops.platelight.bake_probes(**kwargs)
    assert result == {"FINISHED"}, result
    return result


def test_red_phantom_bleeds_into_diffuse_and_world_maps_stay(bpy_clean, tmp_path):
    bpy = bpy_clean
    new_scene(bpy, tmp_path, world_color=(1.0, 1.0, 1.0))
    sphere = add_sphere(bpy, "Sphere", (0, 0, 1.0), radius=0.5, color=(1, 1, 1))
    lonely = add_sphere(bpy, "Lonely", (0, 2000, 0), radius=0.5)    # beyond every probe distance
    lonely.platelight.enabled = True
    add_plane(bpy, "Floor", (0, 0, 0), size=20, color=(0.8, 0.0, 0.0), phantom=True)
    bpy.context.scene.platelight.probe_distance = 100
    bpy.context.scene.camera.data.clip_end = 5000
    bake(bpy, all_objects=True, cull=False)

    diffuse = read_map(tmp_path, "Sphere", "diffuse")
    bottom, top = diffuse[-1].mean(axis=0), diffuse[0].mean(axis=0)
    # Looking down the sphere sees the red floor: red, with green and blue well below.
    assert bottom[0] > 0.3 and bottom[1] < 0.35 * bottom[0] and bottom[2] < 0.35 * bottom[0]
    # Looking up it sees the white sky (and a little red floor through the cosine lobe).
    assert top[1] > 0.85 and top[2] > 0.85
    # The object that sees only the world shares the world's maps, which the floor does not tint.
    assert lonely.platelight.probe_dir.endswith("_world/")
    world = read_map(tmp_path, "_world", "diffuse")
    np.testing.assert_allclose(world, 1.0, atol=0.03)
    assert sphere.platelight.probe_dir == "//platelight_maps/Sphere/"


def test_other_object_appears_in_specular_at_its_direction_and_owner_never(bpy_clean, tmp_path):
    bpy = bpy_clean
    new_scene(bpy, tmp_path, world_color=(0.0, 0.0, 0.0), height=32)
    # Green glowing owner, red glowing neighbour 3 m along +X.
    owner = add_sphere(bpy, "Owner", (0, 0, 0), radius=0.5, color=(0, 0, 0), emission=(0, 5, 0))
    other = add_sphere(bpy, "Other", (3, 0, 0), radius=0.8, color=(0, 0, 0), emission=(5, 0, 0))
    bake(bpy, all_objects=True, cull=False)

    spec = read_map(tmp_path, "Owner", "specular")            # 32 x 64 (probe height)
    assert spec.shape == (32, 64, 3)
    assert spec[..., 1].max() < 1e-3, "the owner shows up in its own probe"
    red = spec[..., 0]
    # One texel is 5.6 degrees at 64 columns.
    assert angle_deg(bright_direction(red), (1, 0, 0)) < 3
    # The sphere of radius 0.8 at 3 m subtends ~15.5 degrees: about 3 texels wide at 64 columns.
    assert (red > 1.0).sum() >= 4

    # And the neighbour's probe sees the green owner at -X, never itself.
    spec_other = read_map(tmp_path, "Other", "specular")
    assert spec_other[..., 0].max() < 1e-3
    assert angle_deg(bright_direction(spec_other[..., 1]), (-1, 0, 0)) < 3
    assert owner.platelight.probe_status == other.platelight.probe_status == "baked"


def test_unchanged_rebake_is_a_cache_hit_and_moving_rebakes_only_who_sees_it(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path, world_color=(0.5, 0.5, 0.5))
    scene.platelight.probe_distance = 20
    scene.camera.data.clip_end = 1000
    a = add_sphere(bpy, "A", (0, 0, 0))
    b = add_sphere(bpy, "B", (3, 0, 0), color=(0.2, 0.9, 0.2))
    c = add_sphere(bpy, "C", (0, 200, 0))           # 200 m away: outside A's and B's range
    d = add_sphere(bpy, "D", (0, 205, 0))           # C's only neighbour
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() >= 4
    stamps = {n: (maps_folder(tmp_path, n) / "diffuse.exr").stat().st_mtime_ns for n in "ABCD"}

    before = probe_renders()
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before, "an unchanged scene rendered again"
    assert all(bpy.data.objects[n].platelight.probe_status == "baked (unchanged)" for n in "ABCD")

    b.location.x = 2.5
    # Checking says who is stale, renders nothing and writes nothing.
    assert bpy.ops.platelight.check_probes(all_objects=True, cull=False) == {"FINISHED"}
    assert probe_renders() == before
    assert [bpy.data.objects[n].platelight.probe_status for n in "ABCD"] == \
        ["stale", "stale", "up to date", "up to date"]
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 2        # A (sees B) and B (its origin moved)
    after = {n: (maps_folder(tmp_path, n) / "diffuse.exr").stat().st_mtime_ns for n in "ABCD"}
    assert after["A"] != stamps["A"] and after["B"] != stamps["B"]
    assert after["C"] == stamps["C"] and after["D"] == stamps["D"]

    # A material edit on B is an input of A's probe too.
    b.data.materials[0].node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (1, 0, 0, 1)
    before = probe_renders()
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 1        # only A sees B's material
    # force re-renders everything
    before = probe_renders()
    bake(bpy, all_objects=True, cull=False, force=True)
    assert probe_renders() == before + 4


def test_frame_range_writes_per_frame_maps_of_a_moving_object(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path, world_color=(0.0, 0.0, 0.0))
    owner = add_sphere(bpy, "Owner", (0, 0, 0))
    lamp = add_sphere(bpy, "Lamp", (3, 0, 0), color=(0, 0, 0), emission=(5, 5, 5))
    lamp.location = (3, 0, 0)
    lamp.keyframe_insert("location", frame=1)
    lamp.location = (0, 3, 0)
    lamp.keyframe_insert("location", frame=3)
    lamp.platelight.enabled = False
    owner.select_set(True)
    bpy.context.view_layer.objects.active = owner
    scene.frame_set(2)
    before = scene_snapshot(bpy)
    bake(bpy, frame_start=1, frame_end=3, cull=False)
    assert scene_snapshot(bpy) == before
    folder = maps_folder(tmp_path, "Owner")
    for frame in (1, 2, 3):
        assert (folder / f"specular_{frame:04d}.exr").is_file()
        assert (folder / f"bake_{frame:04d}.json").is_file()
    assert not (folder / "specular.exr").exists()
    # The lamp moves from +X (frame 1) to +Y (frame 3): the brightest texel follows it.
    for frame, direction in ((1, (1, 0, 0)), (3, (0, 1, 0))):
        spec = read_map(tmp_path, "Owner", "specular", frame=frame)
        assert angle_deg(bright_direction(spec[..., 0]), direction) < 3
    assert owner.platelight.probe_status.startswith("baked (frames 1-3)")


def test_a_rebake_renders_without_the_maps_no_probe_camera_sees(bpy_clean, tmp_path, monkeypatch):
    """A frame-range re-bake of one object: its own maps, bound as image sequences since the first
    bake, are unseen by its probe camera (the owner is hidden from camera rays), so they are held
    at the black stand-in during the renders (Cycles reloaded them at every frame) and bound again
    after; a neighbour's maps, which the probe sees, stay. The maps are those of a re-bake that
    keeps them all bound, to the bit."""
    from platelight.addon.names import PROBE_GROUP_PREFIX, UNBAKED_MAP
    from platelight.node_groups.probe_maps import map_nodes

    bpy = bpy_clean
    new_scene(bpy, tmp_path, world_color=(0.2, 0.3, 0.4))
    add_plane(bpy, "Floor", (0, 0, -0.5), color=(0.8, 0.1, 0.1), phantom=True)
    neighbour = add_sphere(bpy, "Neighbour", (1.5, 0, 0))
    owner = add_sphere(bpy, "Owner", (0, 0, 0))
    for frame, x in ((1, -0.5), (3, 0.5)):
        owner.location = (x, 0, 0)
        owner.keyframe_insert("location", frame=frame)
    for ob in (neighbour, owner):
        bpy.context.view_layer.objects.active = ob
        assert bpy.ops.platelight.apply_sbrdf(preset="NONE") == {"FINISHED"}
    bake(bpy, all_objects=True, frame_start=1, frame_end=3, cull=False)

    groups = {name: bpy.data.node_groups[PROBE_GROUP_PREFIX + name] for name in ("Owner", "Neighbour")}
    bound = {node.name: node.image.name for node in map_nodes(groups["Owner"])}
    assert UNBAKED_MAP not in bound.values()
    for ob in bpy.context.selected_objects:
        ob.select_set(False)
    owner.select_set(True)
    bpy.context.view_layer.objects.active = owner

    def rebake():
        seen = []

        def note_images(*_):
            seen.append({name: {node.image.name for node in map_nodes(tree)} for name, tree in groups.items()})

        bpy.app.handlers.render_pre.append(note_images)
        try:
            bake(bpy, frame_start=1, frame_end=3, cull=False, force=True)
        finally:
            bpy.app.handlers.render_pre.remove(note_images)
        assert len(seen) >= 3
        return seen, [read_map(tmp_path, "Owner", "specular", frame=f) for f in (1, 2, 3)]

    seen, detached = rebake()
    for images in seen:
        assert images["Owner"] == {UNBAKED_MAP}
        assert UNBAKED_MAP not in images["Neighbour"]
    assert {node.name: node.image.name for node in map_nodes(groups["Owner"])} == bound

    monkeypatch.setattr(bake_module("job"), "detach_unseen_maps", lambda *_: set())
    seen, kept_bound = rebake()
    assert all(UNBAKED_MAP not in images["Owner"] for images in seen)
    for a, b in zip(detached, kept_bound):
        np.testing.assert_array_equal(a, b)


def test_a_slowly_moving_object_reuses_its_probe_until_it_has_moved_a_quarter_of_its_size(bpy_clean, tmp_path):
    """Probe Reuse: over a frame range a probe is rendered again only once its object has moved
    more than Probe Reuse bounding radii since the last one; a frame between takes that probe whole,
    with its centre (the group's parallax look-ups start there). A second bake renders nothing;
    Probe Reuse 0 renders the frames that reused, and only those."""
    from platelight.addon.bake.layout import read_record
    from platelight.addon.names import PROBE_CENTRE_NODE, PROBE_GROUP_PREFIX
    from platelight.operators.bake.inputs import world_bounds

    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path, world_color=(0.2, 0.3, 0.4))
    assert scene.platelight.probe_reuse == 0.0            # off unless asked
    scene.platelight.probe_reuse = 0.25
    add_plane(bpy, "Floor", (0, 0, -0.5), color=(0.8, 0.1, 0.1), phantom=True)
    owner = add_sphere(bpy, "Owner", (0, 0, 0))
    for frame, x in ((1, 0.0), (7, 0.9)):
        owner.location = (x, 0, 0)
        owner.keyframe_insert("location", frame=frame)
    bpy.context.view_layer.objects.active = owner
    assert bpy.ops.platelight.apply_sbrdf(preset="NONE") == {"FINISHED"}
    radius = world_bounds(owner)[1]
    renders = probe_renders()
    bake(bpy, all_objects=True, frame_start=1, frame_end=7, cull=False)
    rendered = probe_renders() - renders
    folder = maps_folder(tmp_path, "Owner")
    records = {f: read_record(str(folder), f) for f in range(1, 8)}
    took = {f: r["reused"]["frame"] for f, r in records.items() if "reused" in r}
    assert took and rendered == 7 - len(took)
    last = None
    for frame in range(1, 8):
        scene.frame_set(frame)
        here = np.array(owner.matrix_world.translation)
        if frame in took:                      # within a quarter of its size of the probe it took
            source = took[frame]
            assert source not in took and source < frame
            assert np.linalg.norm(here - records[source]["origin"]) <= 0.25 * radius + 1e-6
            assert records[frame]["origin"] == records[source]["origin"]
            for name in ("diffuse", "specular", "distance"):
                assert (folder / f"{name}_{frame:04d}.exr").read_bytes() == \
                    (folder / f"{name}_{source:04d}.exr").read_bytes()
        else:                                  # rendered: it had moved too far from the last one
            if last is not None:
                assert np.linalg.norm(here - records[last]["origin"]) > 0.25 * radius
            last = frame
    centre = bpy.data.node_groups[PROBE_GROUP_PREFIX + "Owner"].nodes[PROBE_CENTRE_NODE]
    frame = min(took)
    scene.frame_set(frame)
    assert [centre.inputs[a].default_value for a in "XYZ"] == pytest.approx(records[took[frame]]["origin"], abs=1e-5)

    renders = probe_renders()
    bake(bpy, all_objects=True, frame_start=1, frame_end=7, cull=False)
    assert probe_renders() == renders                      # all cached, the reused frames too
    scene.platelight.probe_reuse = 0.0
    bake(bpy, all_objects=True, frame_start=1, frame_end=7, cull=False)
    assert probe_renders() - renders == len(took)
    assert not any("reused" in read_record(str(folder), f) for f in range(1, 8))


def test_only_the_maps_the_materials_read_are_baked(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path, world_color=(0.3, 0.3, 0.3))
    # which maps, not how sharp: the mirrors' probes stay small (their distance maps still reach
    # the layer behind's 256 rows)
    scene.platelight.probe_max_height = 128
    add_plane(bpy, "Floor", (0, 0, -1), color=(0.5, 0.5, 0.5), phantom=True)
    matte = add_sphere(bpy, "Matte", (-1, 0, 0))
    mirror = add_sphere(bpy, "Mirror", (1, 0, 0))
    plain = add_sphere(bpy, "Plain", (0, 0, 1))       # no material: any SBRDF may come later
    brushed = add_sphere(bpy, "Brushed", (0, 0, -0.5))
    for ob, diffuse, specular, glossiness, fresnel, anisotropy in (
            (matte, 0.8, 0.0, 0.0, 0.0, 0.0), (mirror, 0.0, 1.0, 1.0, 0.2, 0.0),
            (brushed, 0.0, 1.0, 2 / 3, 0.0, 0.8)):
        mat = compat().new_material(ob.name)
        group = bpy.data.node_groups.get("PlateLight SBRDF") or _fake_sbrdf_group(bpy)
        node = mat.node_tree.nodes.new("ShaderNodeGroup")
        node.node_tree = group
        node.inputs["Diffuse Albedo"].default_value = (diffuse,) * 3 + (1,)
        node.inputs["Specular Albedo"].default_value = (specular,) * 3 + (1,)
        node.inputs["Glossiness"].default_value = glossiness
        node.inputs["Fresnel Falloff"].default_value = fresnel
        node.inputs["Anisotropy"].default_value = anisotropy
        ob.data.materials.append(mat)
    bake(bpy, all_objects=True, cull=False)
    names = lambda n: sorted(p.name for p in maps_folder(tmp_path, n).glob("*.exr"))
    # the diffuse look-up reads the irradiance grid, seen through the distance map
    assert names("Matte") == ["diffuse.exr", "diffuse_grid.exr", "distance.exr"]
    # the mirror sees the other balls close by: it also bakes the layer behind them
    assert names("Mirror") == ["distance.exr", "distance_behind.exr", "specular.exr", "specular_behind.exr"]
    # a lobe that reads glossy2 gets the view-dependent ladder's rungs (Glossy Lobes' default)
    ladder = ["ladder_glossy1.exr", "ladder_glossy2.exr", "ladder_glossy3.exr"]
    assert names("Plain") == ["diffuse.exr", "diffuse_grid.exr", "distance.exr", "glossy1.exr", "glossy2.exr",
                              *ladder, "specular.exr"]
    # brushed: its narrow axis reads above glossy2's glossiness (a sharp reflector: the layer behind)
    assert names("Brushed") == ["distance.exr", "distance_behind.exr", "glossy2.exr", *ladder, "specular.exr",
                                "specular_behind.exr"]
    # The mirror turns matte: the next bake computes only the diffuse map and drops the old one.
    node = mirror.data.materials[0].node_tree.nodes["Group"]
    node.inputs["Diffuse Albedo"].default_value = (0.5, 0.5, 0.5, 1)
    node.inputs["Specular Albedo"].default_value = (0, 0, 0, 1)
    node.inputs["Fresnel Falloff"].default_value = 0.0
    bake(bpy, all_objects=True, cull=False)
    assert names("Mirror") == ["diffuse.exr", "diffuse_grid.exr", "distance.exr"]
    # Diffuse parallax off: the paper's look-up needs neither grid nor distances.
    bpy.context.scene.platelight.probe_diffuse_parallax = False
    bake(bpy, all_objects=True, cull=False)
    assert names("Mirror") == ["diffuse.exr"] == names("Matte")


def _fake_sbrdf_group(bpy):
    """The SBRDF group's interface as design.md names it (the real builder is the sbrdf branch's;
    only the inputs matter to which maps a bake computes)."""
    group = bpy.data.node_groups.new("PlateLight SBRDF", "ShaderNodeTree")
    for name, kind in (("Diffuse Albedo", "NodeSocketColor"), ("Specular Albedo", "NodeSocketColor"),
                       ("Glossiness", "NodeSocketFloat"), ("Fresnel Falloff", "NodeSocketFloat"),
                       ("Anisotropy", "NodeSocketFloat")):
        group.interface.new_socket(name, in_out="INPUT", socket_type=kind)
    group.interface.new_socket("BSDF", in_out="OUTPUT", socket_type="NodeSocketShader")
    return group


def test_objects_off_screen_in_every_frame_are_skipped(bpy_clean, tmp_path):
    bpy = bpy_clean
    new_scene(bpy, tmp_path, world_color=(0.5, 0.5, 0.5))
    seen = add_sphere(bpy, "Seen", (0, 0, 0))
    behind = add_sphere(bpy, "Behind", (0, -20, 0))     # behind the camera at y = -10
    before = probe_renders()
    bpy.ops.platelight.bake_probes(all_objects=True)
    assert probe_renders() == before + 1
    assert behind.platelight.probe_status.startswith("skipped")
    assert not maps_folder(tmp_path, "Behind").exists()
    assert seen.platelight.probe_status == "baked"


def test_world_probe_render_matches_the_world_maps(bpy_clean, tmp_path, studio_hdris):
    """Blender's panorama of the world alone and the engine's maps of the world EXR agree:
    same direction convention, no mirror, no shift."""
    bpy = bpy_clean
    from platelight.addon.ibl.maps import MapSettings, compute_maps

    exr = studio_hdris["forest"]
    new_scene(bpy, tmp_path, env_exr=exr, height=64, samples=16)
    ob = add_sphere(bpy, "Probe", (0, 0, 0))
    bake(bpy, all_objects=True, cull=False)                 # sees only the world: world maps
    assert ob.platelight.probe_dir.endswith("_world/")
    world_maps = {n: read_map(tmp_path, "_world", n) for n in ("diffuse", "glossy1")}

    module = bake_module()
    job = module.ProbeBake(bpy.context, [ob], [1], reuse_world=False, cull=False)
    job.start()
    try:
        panorama = job.render_probe((0, 0, 0), hidden=[ob])
    finally:
        job.end()
    assert panorama.shape == (64, 128, 3)
    heights = {"diffuse": 16, "glossy1": 32}
    rendered = compute_maps(panorama, MapSettings(heights=heights), which=tuple(heights)).maps
    for name in heights:
        ref = world_maps[name]
        err = np.abs(rendered[name] - ref).mean() / ref.mean()
        print(name, "relative mean error", err)
        assert err < 0.03, (name, err)
        # Shifting by a quarter turn or mirroring left-right would be far worse.
        shifted = np.roll(ref, ref.shape[1] // 4, axis=1)
        assert np.abs(rendered[name] - shifted).mean() / ref.mean() > 3 * err
        mirrored = ref[:, ::-1]
        assert np.abs(rendered[name] - mirrored).mean() / ref.mean() > 3 * err


def test_phantom_shadow_catcher_is_seen_in_probes_and_restored(bpy_clean, tmp_path):
    bpy = bpy_clean
    new_scene(bpy, tmp_path, world_color=(1.0, 1.0, 1.0))
    sphere = add_sphere(bpy, "Sphere", (0, 0, 1.0))
    floor = add_plane(bpy, "Floor", (0, 0, 0), size=20, color=(0.0, 0.0, 0.8), phantom=True)
    floor.is_shadow_catcher = True
    # A compositing setup's extra view layer and a held-out collection must not change probes.
    scene = bpy.context.scene
    held = bpy.data.collections.new("Held")
    scene.collection.children.link(held)
    scene.collection.objects.unlink(floor)
    held.objects.link(floor)
    layer_collection = bpy.context.view_layer.layer_collection.children["Held"]
    layer_collection.holdout = True
    scene.view_layers.new("Shadows")
    bake(bpy, all_objects=True, cull=False)
    assert floor.is_shadow_catcher and layer_collection.holdout
    assert not scene.render.use_single_layer
    bottom = read_map(tmp_path, "Sphere", "diffuse")[-1].mean(axis=0)
    assert bottom[2] > 3 * bottom[0]


def test_panels_draw_and_menus_list_the_operator(bpy_clean, tmp_path):
    """The UI code runs (draw() against real property groups) and the menus hold the operator."""
    bpy = bpy_clean
    new_scene(bpy, tmp_path)
    ob = add_sphere(bpy, "Sphere", (0, 0, 0))
    assert bake_module(None).menu_entry in bpy.types.VIEW3D_MT_object._dyn_ui_initialize()
    panels = __import__(bake_module(None).__name__.rsplit(".", 2)[0] + ".ui.panels", fromlist=["x"])

    class Recorder:
        """Stands in for UILayout, which only Blender's window code can create."""
        def __init__(self):
            self.calls = []

        def __getattr__(self, name):
            def call(*args, **kwargs):
                self.calls.append((name, args, kwargs))
                if name in {"column", "row"}:
                    return self
                if name == "operator":
                    return type("Props", (), {})()
                return None
            return call

    for panel_cls in (panels.PLATELIGHT_PT_object, panels.PLATELIGHT_PT_scene):
        recorder = Recorder()
        panel = type("P", (), {"layout": recorder})()
        panel_cls.draw(panel, bpy.context)
        props = [args[1] for name, args, _ in recorder.calls if name == "prop"]
        ops = [args[0] for name, args, _ in recorder.calls if name == "operator"]
        assert "platelight.bake_probes" in ops
        for prop in props:   # every drawn property exists
            owner = ob.platelight if panel_cls is panels.PLATELIGHT_PT_object else bpy.context.scene.platelight
            assert hasattr(owner, prop), prop


def turn_world(bpy, scene, rotation, vector_type="POINT"):
    """Turn the world's Environment Texture with a Mapping node fed by Generated coordinates."""
    tree = scene.world.node_tree
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.vector_type = vector_type
    coords = tree.nodes.new("ShaderNodeTexCoord")
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], tree.nodes["Environment Texture"].inputs["Vector"])
    mapping.inputs["Rotation"].default_value = rotation
    return mapping


def test_world_maps_follow_strength_and_a_mapping_rotation(bpy_clean, tmp_path, studio_hdris):
    bpy = bpy_clean
    from platelight.addon.exr_io import read_exr
    from platelight.addon.ibl.maps import MapSettings, compute_maps

    exr = studio_hdris["interior"]
    scene = new_scene(bpy, tmp_path, env_exr=exr, height=64, samples=16)
    background = scene.world.node_tree.nodes["Background"]
    background.inputs["Strength"].default_value = 2.0
    add_sphere(bpy, "Probe", (0, 0, 0))
    bake(bpy, all_objects=True, cull=False)
    env = read_exr(exr)
    direct = compute_maps(env, MapSettings(), which=("diffuse",)).maps["diffuse"]
    np.testing.assert_allclose(read_map(tmp_path, "_world", "diffuse"), 2 * direct, rtol=1e-4, atol=1e-6)

    # A quarter turn about Z through a Mapping node turns the lookup vector by +90 degrees (+X
    # looks up +Y), so the texel at u shows the EXR at u - 1/4 (u = atan2(-y, x)/2pi + 0.5): the
    # maps are the EXR's rolled by +W/4, read from the file without rendering (a render of this
    # world's tiny lamp at 16 samples misses its energy by 15 %).
    turn_world(bpy, scene, (0, 0, np.pi / 2))
    background.inputs["Strength"].default_value = 1.5
    before = probe_renders()
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before
    turned = compute_maps(np.roll(env, env.shape[1] // 4, axis=1), MapSettings(), which=("diffuse",))
    np.testing.assert_allclose(read_map(tmp_path, "_world", "diffuse"), 1.5 * turned.maps["diffuse"],
                               rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize("vector_type", ["POINT", "TEXTURE"])
def test_world_maps_read_from_a_turned_world_match_cycles_rendering_it(bpy_clean, tmp_path, studio_hdris,
                                                                       vector_type):
    """Any Mapping rotation (Euler XYZ, Point or its inverse Texture) and strength, read from the
    file, agree with Cycles rendering the same world (forced by a neutral Gamma node)."""
    bpy = bpy_clean
    from platelight.addon.ibl.equirect import downsample_area

    scene = new_scene(bpy, tmp_path, env_exr=studio_hdris["courtyard"], height=32, samples=64)
    tree = scene.world.node_tree
    tree.nodes["Background"].inputs["Strength"].default_value = 1.3
    turn_world(bpy, scene, (0.5, -0.3, 2.0), vector_type)
    add_sphere(bpy, "Probe", (0, 0, 0))
    before = probe_renders()
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before                     # read from the file
    read = read_map(tmp_path, "_world", "diffuse")

    gamma = tree.nodes.new("ShaderNodeGamma")            # gamma 1: the same world, but unreadable
    tree.links.new(tree.nodes["Environment Texture"].outputs["Color"], gamma.inputs["Color"])
    tree.links.new(gamma.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 1                 # rendered by Cycles
    rendered = read_map(tmp_path, "_world", "diffuse")
    expected = downsample_area(read, rendered.shape[0])
    err = np.abs(rendered - expected).mean() / expected.mean()
    mapping = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeMapping")
    mapping.vector_type = "TEXTURE" if vector_type == "POINT" else "POINT"   # the inverse turn
    tree.nodes.remove(gamma)                             # readable again
    tree.links.new(tree.nodes["Environment Texture"].outputs["Color"], tree.nodes["Background"].inputs["Color"])
    bake(bpy, all_objects=True, cull=False)
    inverse = downsample_area(read_map(tmp_path, "_world", "diffuse"), rendered.shape[0])
    wrong = np.abs(rendered - inverse).mean() / expected.mean()
    assert err < 0.02 and wrong > 5 * err, (err, wrong)


def test_probe_origin_object_sets_the_probe_centre(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path, world_color=(0.0, 0.0, 0.0))
    ob = add_sphere(bpy, "Sphere", (0, 0, 0), radius=0.5)
    add_sphere(bpy, "Lamp", (0, 0, 3), radius=0.3, enabled=False, color=(0, 0, 0), emission=(4, 4, 4))
    origin = bpy.data.objects.new("Origin", None)
    scene.collection.objects.link(origin)
    origin.location = (0, 0, 5)               # above the lamp: the lamp is straight down from it
    ob.platelight.probe_origin = origin
    bake(bpy, all_objects=True, cull=False)
    record = json.loads((maps_folder(tmp_path, "Sphere") / "bake.json").read_text())
    assert record["origin"] == pytest.approx([0, 0, 5])
    spec = read_map(tmp_path, "Sphere", "specular")
    assert angle_deg(bright_direction(spec[..., 0]), (0, 0, -1)) < 5


def test_pack_maps_into_the_blend_without_duplicates(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path, world_color=(0.5, 0.5, 0.5))
    scene.platelight.pack_maps = True
    ob = add_sphere(bpy, "Sphere", (0, 0, 0))
    lamp = add_sphere(bpy, "Lamp", (2, 0, 0), enabled=False, color=(0, 0, 0), emission=(3, 3, 3))
    bake(bpy, all_objects=True, cull=False)
    images = {im.name: im for im in bpy.data.images if im.name.startswith("PlateLight ")}
    # the four maps, the parallax look-ups' files and the view-dependent ladder's rungs
    assert sorted(images) == [f"PlateLight Sphere/{n}.exr" for n in
                              ("diffuse", "diffuse_grid", "distance", "glossy1", "glossy2", "ladder_glossy1",
                               "ladder_glossy2", "ladder_glossy3", "specular")]
    assert all(im.packed_file is not None for im in images.values())
    assert images["PlateLight Sphere/diffuse.exr"].filepath == ob.platelight.probe_dir + "diffuse.exr"

    lamp.location.x = -2                       # changes the probe: re-bake re-packs in place
    bake(bpy, all_objects=True, cull=False)
    again = [im for im in bpy.data.images if im.name.startswith("PlateLight ")]
    assert len(again) == len(images) and len(bpy.data.images) == len(images)
    spec = images["PlateLight Sphere/specular.exr"]
    packed = np.array(spec.pixels[:], dtype=np.float32).reshape(spec.size[1], spec.size[0], 4)[::-1, :, :3]
    np.testing.assert_allclose(packed, read_map(tmp_path, "Sphere", "specular"), rtol=1e-6, atol=1e-7)
    assert angle_deg(bright_direction(packed[..., 0] - 0.5), (-1, 0, 0)) < 10


def test_lights_are_probe_inputs_but_not_something_a_probe_sees(bpy_clean, tmp_path):
    """A sun far away still lights what a probe sees (its change makes the probe stale); a scene
    with only lights around the object still shares the world maps (lights are invisible to
    camera rays)."""
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path, world_color=(0.2, 0.2, 0.2))
    scene.platelight.probe_distance = 10
    a = add_sphere(bpy, "A", (0, 0, 0))
    lonely = add_sphere(bpy, "Lonely", (0, 500, 0))
    add_sphere(bpy, "Neighbour", (2, 0, 0), enabled=False, color=(0.8, 0.8, 0.8))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    scene.collection.objects.link(sun)
    sun.location = (0, 0, 1000)                       # far beyond probe_distance
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    scene.collection.objects.link(lamp)
    lamp.location = (0, 501, 0)
    bake(bpy, all_objects=True, cull=False)
    assert lonely.platelight.probe_dir.endswith("_world/")
    assert a.platelight.probe_status == "baked"
    before = probe_renders()
    sun.data.energy = 3.0
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 1          # A's probe sees the sun-lit neighbour
    assert a.platelight.probe_status == "baked"


def test_shape_key_modifier_and_text_changes_make_probes_stale(bpy_clean, tmp_path):
    """Geometry that changes without its transform or mesh data changing (shape keys, modifiers)
    is hashed from the evaluated mesh."""
    bpy = bpy_clean
    new_scene(bpy, tmp_path, world_color=(0.4, 0.4, 0.4))
    a = add_sphere(bpy, "A", (0, 0, 0))
    b = add_sphere(bpy, "B", (2, 0, 0), enabled=False, color=(0.9, 0.2, 0.2))
    b.shape_key_add(name="Basis")
    key = b.shape_key_add(name="Squash")
    for point in key.data:
        point.co.z *= 0.3
    key.value = 0.0
    bake(bpy, all_objects=True, cull=False)
    before = probe_renders()
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before              # unchanged: cache hit
    key.value = 1.0
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 1
    b.modifiers.new("Twist", "SIMPLE_DEFORM").angle = 0.5
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 2
    b.modifiers["Twist"].angle = 0.9
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 3
    # Text: editing the characters changes the probe.
    text = bpy.data.objects.new("Sign", bpy.data.curves.new("Sign", "FONT"))
    bpy.context.scene.collection.objects.link(text)
    text.location = (0, 2, 0)
    text.data.body = "AR"
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 4
    text.data.body = "VR"
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 5
    assert a.platelight.probe_status == "baked"


def test_fast_world_sampling_is_a_setting_that_makes_probes_stale(bpy_clean, tmp_path):
    """The world's own importance map is the default (a small sun needs it); the 256-column cap
    is opt-in, and switching it re-renders the probes it affects."""
    bpy = bpy_clean
    new_scene(bpy, tmp_path, world_color=(0.4, 0.4, 0.4))
    a = add_sphere(bpy, "A", (0, 0, 0))
    add_sphere(bpy, "B", (2, 0, 0), enabled=False)
    module = bake_module()
    scene = bpy.context.scene
    assert module.ProbeBake(bpy.context, [a], [1]).world_map_resolution is None
    scene.platelight.probe_fast_world = True
    cap = bake_module("probe_render").PROBE_WORLD_MAP_RESOLUTION
    assert module.ProbeBake(bpy.context, [a], [1]).world_map_resolution == cap
    scene.platelight.probe_fast_world = False
    sampling = (scene.world.cycles.sampling_method, scene.world.cycles.sample_map_resolution)
    bake(bpy, all_objects=True, cull=False)
    before = probe_renders()
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before              # unchanged: cache hit
    scene.platelight.probe_fast_world = True
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 1
    assert (scene.world.cycles.sampling_method, scene.world.cycles.sample_map_resolution) == sampling


def test_glossy_lobes_are_a_setting_that_reblurs_the_glossy_maps(bpy_clean, tmp_path):
    """Glossy Lobes GGX makes the bake blur glossy1 and glossy2 with GGX's lobes (the same probe
    render otherwise); switching it makes the probes stale, and back gives the Phong maps again.
    The default, View-Dependent GGX, keeps the four Phong maps and writes the ladder's GGX rungs
    beside them (glossy1 and glossy2 as GGX's own, and glossy3); the others remove the rungs."""
    from platelight.addon.exr_io import read_exr
    from platelight.addon.ibl import view_lobe

    bpy = bpy_clean
    new_scene(bpy, tmp_path, world_color=(0.3, 0.3, 0.3))
    add_plane(bpy, "Floor", (0, 0, -1), color=(0.9, 0.1, 0.1), phantom=True)
    add_sphere(bpy, "A", (0, 0, 0))
    scene = bpy.context.scene
    names = ("diffuse", "glossy1", "glossy2", "specular")
    assert scene.platelight.glossy_lobes == view_lobe.MODE
    bake(bpy, all_objects=True, cull=False)
    phong = {m: read_map(tmp_path, "A", m) for m in names}
    folder = maps_folder(tmp_path, "A")
    rungs = {m: read_exr(folder / view_lobe.rung_filename(m)) for m in view_lobe.RUNGS}
    rows = min(view_lobe.RUNG_HEIGHTS[view_lobe.GLOSSY3], scene.platelight.probe_height)
    assert rungs[view_lobe.GLOSSY3].shape == (rows, 2 * rows, 3)      # capped by the probe's height
    assert view_lobe.record_sunless(json.loads((folder / "bake.json").read_text())) is False   # no sun here
    before = probe_renders()
    scene.platelight.glossy_lobes = "ggx"
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 1
    assert not any((folder / f).exists() for f in view_lobe.ladder_filenames(None))
    ggx = {m: read_map(tmp_path, "A", m) for m in names}
    for m in ("glossy1", "glossy2"):       # the rungs are GGX's maps of the same probe
        np.testing.assert_allclose(rungs[m], ggx[m], rtol=1e-3, atol=1e-5, err_msg=m)
    for m in ("diffuse", "specular"):
        np.testing.assert_allclose(ggx[m], phong[m], rtol=1e-4, atol=1e-6, err_msg=m)
    for m in ("glossy1", "glossy2"):
        change = np.sqrt(np.mean((ggx[m] - phong[m]) ** 2) / np.mean(phong[m] ** 2))
        assert change > 0.005, (m, change)          # measured 1.8 % and 1.5 %; the renders match
    scene.platelight.glossy_lobes = "phong"
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 2
    np.testing.assert_allclose(read_map(tmp_path, "A", "glossy2"), phong["glossy2"], rtol=1e-4, atol=1e-6)


def test_owner_shadows_its_floor_in_its_own_probe_unless_the_papers_probe_is_asked(bpy_clean, tmp_path):
    """A ball resting on a sunlit floor sees the floor under it in its own shadow (default); the
    paper's probe hides the owner, so the same floor shows sunlit. Either way the owner itself is
    not in the probe, its ray visibility is restored, and switching the setting re-bakes."""
    bpy = bpy_clean
    new_scene(bpy, tmp_path, world_color=(0.05, 0.05, 0.05))
    ball = add_sphere(bpy, "Ball", (0, 0, 0.5), radius=0.5, color=(0, 0, 0), emission=(0, 5, 0))
    add_plane(bpy, "Floor", (0, 0, 0), size=20, color=(0.8, 0.8, 0.8), phantom=True)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    bpy.context.scene.collection.objects.link(sun)           # pointing straight down
    scene = bpy.context.scene
    flags = {f: getattr(ball, f) for f in bake_module("probe_render").SHADOW_ONLY_HIDDEN_RAYS}

    def below():
        spec = read_map(tmp_path, "Ball", "specular")
        green = spec[..., 1] - spec[..., 0]                   # the owner glows green
        assert green.max() < 0.02, f"the owner (or its glow) is in its probe: {green.max()}"
        h = spec.shape[0]
        return float(spec[-max(h // 8, 1):].mean())            # looking down: the floor under it

    assert scene.platelight.probe_owner_shadows
    bake(bpy, all_objects=True, cull=False)
    shadowed = below()
    assert {f: getattr(ball, f) for f in flags} == flags
    before = probe_renders()
    scene.platelight.probe_owner_shadows = False
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 1                  # the setting is in the hash
    sunlit = below()
    # Sunlit floor: 0.8/pi * 3 W/m^2 ~ 0.76 plus sky; in the ball's shadow only the dim sky.
    assert sunlit > 0.5 and shadowed < 0.25 * sunlit, (shadowed, sunlit)


def test_a_mirror_owner_lights_and_shades_the_floor_of_its_own_probe(bpy_clean, tmp_path):
    """A sharp reflector reads the floor under itself, so its probe shows that floor as it is: the
    owner, invisible to the probe's camera, still blocks and bounces the floor's light (here its
    green glow reaches the floor). A matte owner only shadows it. Each mode hashes apart, and the
    owner's ray visibility is restored."""
    bpy = bpy_clean
    new_scene(bpy, tmp_path, world_color=(0.05, 0.05, 0.05))
    ball = add_sphere(bpy, "Ball", (0, 0, 0.5), radius=0.5, color=(0, 0, 0), emission=(0, 5, 0))
    add_plane(bpy, "Floor", (0, 0, 0), size=20, color=(0.8, 0.8, 0.8), phantom=True)
    bsdf = ball.active_material.node_tree.nodes["Principled BSDF"]
    flags = {f: getattr(ball, f) for f in bake_module("probe_render").SHADOW_ONLY_HIDDEN_RAYS}

    def floor_green():
        spec = read_map(tmp_path, "Ball", "specular")
        below = spec[-max(spec.shape[0] // 8, 1):]                # looking down: the floor under it
        return float((below[..., 1] - below[..., 0]).mean())

    bsdf.inputs["Roughness"].default_value = 1.0                 # matte: shadows only
    bake(bpy, all_objects=True, cull=False)
    matte = floor_green()
    before = probe_renders()
    bsdf.inputs["Roughness"].default_value = 0.05                # a mirror: blocks and bounces too
    bake(bpy, all_objects=True, cull=False)
    assert probe_renders() == before + 1
    mirror = floor_green()
    assert {f: getattr(ball, f) for f in flags} == flags
    assert matte < 0.02 and mirror > 0.1, (matte, mirror)


def test_sky_of_an_image_world_is_the_image_itself_not_sampled(bpy_clean, tmp_path):
    """Where the world is an equirectangular image, the probe's sky is that image area-averaged
    (exact: a small sun's energy does not depend on where camera samples land), under what the
    render shows of the scene; the distance map still sees the sky as far away."""
    from platelight.addon.exr_io import read_exr, write_exr
    from platelight.addon.ibl.distance import FAR
    from platelight.addon.ibl.equirect import downsample_area

    bpy = bpy_clean
    env = np.full((64, 128, 3), 0.2, np.float32)
    env[20:22, 90:92] = (20000.0, 15000.0, 9000.0)       # a sun 2 texels wide
    write_exr(tmp_path / "sun.exr", env)
    new_scene(bpy, tmp_path, env_exr=tmp_path / "sun.exr", height=16, samples=2)
    add_sphere(bpy, "Owner", (0, 0, 0), radius=0.3, color=(0.5, 0.5, 0.5))
    add_plane(bpy, "Floor", (0, 0, -1.0), size=30, color=(0.8, 0.0, 0.0), phantom=True)
    bake(bpy, all_objects=True, cull=False)

    spec = read_map(tmp_path, "Owner", "specular")                # the probe itself (16 x 32)
    sky = downsample_area(env, 16)
    # The floor (30 m square, 1 m below) covers the lower half down to ~4 degrees under the horizon.
    np.testing.assert_allclose(spec[:7], sky[:7], rtol=1e-4)
    assert spec[12:, :, 0].mean() > 3 * spec[12:, :, 1].mean()   # below: the red floor, rendered
    distance = read_exr(maps_folder(tmp_path, "Owner") / "distance.exr")[..., 0]
    assert distance[: distance.shape[0] // 3].min() >= FAR * 0.99
    assert np.median(distance[-2:]) == pytest.approx(1.0, rel=0.05)


def test_the_probes_sun_is_baked_apart_and_shaded_through_the_lobe(bpy_clean, tmp_path):
    """A glossy object's bake under a world with a small sun writes the sunless maps and the sun
    (its direction, all its energy) in the record; the probe group shines that sun through the
    lobe and reads the sunless maps, and the scene's Sun Highlight setting switches both back."""

    from bl_ext.dev.platelight.node_groups import probe_maps, sbrdf_material
    from platelight.addon import names
    from platelight.addon.exr_io import read_exr, write_exr
    from platelight.addon.ibl.equirect import texel_directions, texel_solid_angles
    from platelight.addon.material.params import SBRDFParams

    bpy = bpy_clean
    env = np.full((64, 128, 3), 0.2, np.float32)
    env[20:22, 90:92] = (20000.0, 15000.0, 9000.0)       # a sun 2 texels wide
    write_exr(tmp_path / "sun.exr", env)
    new_scene(bpy, tmp_path, env_exr=tmp_path / "sun.exr", height=32, samples=2)
    ball = add_sphere(bpy, "Ball", (0, 0, 0), radius=0.3)
    add_plane(bpy, "Floor", (0, 0, -1.0), size=30, color=(0.5, 0.5, 0.5), phantom=True)
    sbrdf_material.apply_sbrdf_material(ball, params=SBRDFParams(specular_albedo=(0.9, 0.9, 0.9), glossiness=0.5))
    bake(bpy, all_objects=True, cull=False)

    folder = maps_folder(tmp_path, "Ball")
    record = json.loads((folder / "bake.json").read_text())
    sun = record["sun"]
    want = texel_directions(64, 128)[20:22, 90:92].reshape(-1, 3).mean(axis=0)
    assert angle_deg(np.array(sun["direction"]), want) < 1.0
    energy = (env[20:22, 90:92] - 0.2).reshape(-1, 3).T @ texel_solid_angles(64, 128)[20:22, 90:92].reshape(-1)
    np.testing.assert_allclose(sun["rgb"], energy, rtol=0.02)
    glossy2, sunless = read_map(tmp_path, "Ball", "glossy2"), read_exr(folder / "glossy2_sunless.exr")
    assert glossy2.max() > 20 * sunless.max() and sunless.min() > 0.1   # the sky stays

    group = probe_maps.find_probe_group(ball.platelight.probe_dir)

    def bound():
        rgb = [group.nodes[names.SUN_COLOR_NODE].inputs[a].default_value for a in "XYZ"]
        files = {n["platelight_map"]: n.image.filepath.rsplit("/", 1)[-1] for n in group.nodes
                 if n.get("platelight_map", "").endswith("_sunless") and n.image}
        return rgb, files
    rgb, files = bound()
    np.testing.assert_allclose(rgb, sun["rgb"], rtol=1e-6)
    # the default (View-Dependent GGX) reads the ladder's rungs, made without the sun too
    assert files["glossy2_sunless"] == "ladder_glossy2.exr"
    rung = read_exr(folder / "ladder_glossy2.exr")
    assert glossy2.max() > 20 * rung.max() and rung.min() > 0.1
    bpy.context.scene.platelight.glossy_lobes = "phong"
    rgb, files = bound()
    np.testing.assert_allclose(rgb, sun["rgb"], rtol=1e-6)
    assert files["glossy2_sunless"] == "glossy2_sunless.exr"
    bpy.context.scene.platelight.probe_sun_lobe = False
    rgb, files = bound()
    assert rgb == [0.0, 0.0, 0.0] and files["glossy2_sunless"] == "glossy2.exr"
    bpy.context.scene.platelight.probe_sun_lobe = True
    assert bound()[1]["glossy2_sunless"] == "glossy2_sunless.exr"
    # the setting is part of the probe's inputs: off, the re-bake writes the paper's files alone
    bpy.context.scene.platelight.probe_sun_lobe = False
    bake(bpy, all_objects=True, cull=False)
    assert not list(folder.glob("*_sunless*")) and "sun" not in json.loads((folder / "bake.json").read_text())


def _bake_seeing(bpy, what):
    """Bake every object; returns ``what(scene)`` as each of the bake's renders starts."""
    seen = []

    def record(render_scene, *_):
        seen.append(what(render_scene))
    bpy.app.handlers.render_pre.append(record)
    try:
        bake(bpy, all_objects=True, cull=False)
    finally:
        bpy.app.handlers.render_pre.remove(record)
    return seen


def test_small_probe_renders_with_more_samples_and_the_scene_keeps_its_own(bpy_clean, tmp_path):
    """probe_size.samples_for: a 32-row probe at Probe Samples 2 renders at 4 spp; the scene's own
    render samples are back afterwards."""
    from platelight.addon.bake.probe_size import samples_for
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path, world_color=(0.5, 0.5, 0.5), height=32, samples=2)
    scene.cycles.samples = 7
    add_sphere(bpy, "Sphere", (0, 0, 0), radius=0.5, color=(1, 1, 1))
    seen = _bake_seeing(bpy, lambda render_scene: render_scene.cycles.samples)
    assert seen and set(seen) == {samples_for(2, 32)} == {4}
    assert scene.cycles.samples == 7


def test_every_probe_render_sees_the_scene_world(bpy_clean, tmp_path):
    """The distance map's render reads the sky from the film's alpha rather than a world of its
    own: a world swapped in and out made Cycles rebuild the scene world's light-importance map
    at every probe (docs/bench/bake.md). The distance map still says FAR towards the sky."""
    from platelight.addon.exr_io import read_exr
    from platelight.addon.ibl.distance import FAR
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path, world_color=(0.5, 0.5, 0.5), height=32, samples=2)
    add_plane(bpy, "Floor", (0, 0, 0), size=8, color=(0.5, 0.5, 0.5), phantom=True)
    add_sphere(bpy, "Sphere", (0, 0, 0.5), radius=0.5, color=(1, 1, 1))
    worlds = _bake_seeing(bpy, lambda render_scene: render_scene.world.name)
    assert len(worlds) >= 2 and set(worlds) == {scene.world.name}      # the probe and its distance map
    distance = read_exr(tmp_path / "platelight_maps" / "Sphere" / "distance.exr")[..., 0]
    rows = distance.shape[0]
    assert np.all(distance[: rows // 4] == FAR)                  # the sky above
    assert np.all(distance[-rows // 4:] < 10.0)                 # the floor below


def test_a_disabled_view_layer_still_bakes_true_distances(bpy_clean, tmp_path):
    """Headless (the CLI, a farm), the context's view layer is the first one, which
    setup_composite turns off; Cycles ignores a disabled layer's material override, so the
    distance map showed the floor's own shading (all FAR under a bright world: no parallax).
    The bake enables the layer while it renders and turns it off again."""
    from platelight.addon.exr_io import read_exr
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path, world_color=(0.5, 0.5, 0.5), height=32, samples=2)
    add_plane(bpy, "Floor", (0, 0, 0), size=8, color=(0.5, 0.5, 0.5), phantom=True)
    add_sphere(bpy, "Sphere", (0, 0, 0.5), radius=0.5, color=(1, 1, 1))
    first = scene.view_layers[0]
    scene.view_layers.new("Other")
    first.use = False
    with bpy.context.temp_override(view_layer=first):
        bake(bpy, all_objects=True, cull=False)
    assert first.use is False
    distance = read_exr(tmp_path / "platelight_maps" / "Sphere" / "distance.exr")[..., 0]
    np.testing.assert_allclose(distance[-1], 0.5, rtol=0.02)      # straight down: the floor, 0.5 m
