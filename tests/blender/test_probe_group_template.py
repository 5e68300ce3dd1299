"""Probe groups are copies of a template built once (node_groups/probe_maps.py, template_cache.py):
a rebuilt group keeps its place (users, links, name, properties), a new Blender session appends the
template from the cache, and a corrupt or stale cache file falls back to building."""
from __future__ import annotations

import os

from platelight.addon import names
from support import compat


def _modules():
    from bl_ext.dev.platelight.node_groups import probe_maps, template_cache
    return probe_maps, template_cache


def test_a_rebuilt_group_takes_the_old_ones_place(bpy_clean, tmp_path):
    bpy = bpy_clean
    probe_maps, _ = _modules()
    group = probe_maps.ensure_probe_group(str(tmp_path / "Ball"), "Ball")
    material = compat().new_material("Ball")
    node = material.node_tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    emission = material.node_tree.nodes.new("ShaderNodeEmission")
    material.node_tree.links.new(node.outputs["Specular Term"], emission.inputs["Color"])
    folder, name = group[probe_maps.FOLDER_KEY], group.name
    assert not group.get(probe_maps.BEHIND_KEY)
    plain = probe_maps._template(False)
    assert len(group.nodes) == len(plain.nodes) and len(group.links) == len(plain.links)

    rebuilt = probe_maps._build_if_needed(group, True)      # the bake found the layer behind
    behind = probe_maps._template(True)
    assert rebuilt.name == name and rebuilt[probe_maps.FOLDER_KEY] == folder and rebuilt[probe_maps.BEHIND_KEY]
    assert len(rebuilt.nodes) == len(behind.nodes) > len(plain.nodes)
    assert node.node_tree == rebuilt                           # the material's node follows
    assert [(link.from_socket.name, link.to_node.name) for link in material.node_tree.links
            if link.from_node == node] == [("Specular Term", emission.name)]
    assert [g for g in bpy.data.node_groups if g.name.startswith(names.PROBE_GROUP_PREFIX)] == [rebuilt]
    # templates are unused: they are not saved with the file
    assert plain.users == 0 and behind.users == 0
    assert probe_maps._build_if_needed(rebuilt, True) == rebuilt      # nothing to do: the same group


def test_a_new_session_appends_the_template_and_a_bad_cache_is_rebuilt(bpy_clean):
    bpy = bpy_clean
    probe_maps, template_cache = _modules()
    built = probe_maps._template(False)
    count, links = len(built.nodes), len(built.links)
    path = template_cache._path(built.name)
    assert os.path.isfile(path)

    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    cached = template_cache.load(names.PROBE_GROUP_TEMPLATE)
    assert cached is not None and (len(cached.nodes), len(cached.links)) == (count, links)
    assert cached.get(probe_maps.VERSION_KEY) == probe_maps.VERSION and not list(bpy.data.libraries)

    # a corrupt file is no group: built again, and the cache rewritten
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    with open(path, "wb") as f:
        f.write(b"not a blend file")
    assert template_cache.load(names.PROBE_GROUP_TEMPLATE) is None
    template = probe_maps._template(False)
    assert (len(template.nodes), len(template.links)) == (count, links)
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    assert template_cache.load(names.PROBE_GROUP_TEMPLATE) is not None

    # a template of another version in the file is set aside, not used
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    old = bpy.data.node_groups.new(names.PROBE_GROUP_TEMPLATE, "ShaderNodeTree")
    old[probe_maps.VERSION_KEY] = probe_maps.VERSION - 1
    template = probe_maps._template(False)
    assert template != old and template.name == names.PROBE_GROUP_TEMPLATE and len(template.nodes) == count


def test_the_cache_is_named_by_the_sources(bpy_clean, tmp_path, monkeypatch):
    """Any change to the add-on's node or engine sources names another file: a stale template
    is never appended."""
    import shutil

    _, template_cache = _modules()
    root = tmp_path / "platelight"
    for folder in template_cache._SOURCES:
        shutil.copytree(template_cache._PACKAGE_ROOT / folder, root / folder)
    monkeypatch.setattr(template_cache, "_PACKAGE_ROOT", root)
    monkeypatch.setattr(template_cache, "_digest", None)
    before = template_cache._path("x")
    assert template_cache._path("x") == before                 # the same sources, the same file
    constants = root / "addon" / "ibl" / "distance.py"
    constants.write_text(constants.read_text().replace("BEHIND_JUMP = 0.2", "BEHIND_JUMP = 0.25"))
    monkeypatch.setattr(template_cache, "_digest", None)
    assert template_cache._path("x") != before


def test_prepare_templates_leaves_both_templates_ready(bpy_clean):
    """What a timed shot calls first (bench_composite.py): both templates in the file, unused,
    and both on disk for the next Blender session."""
    bpy = bpy_clean
    probe_maps, template_cache = _modules()
    probe_maps.prepare_templates()
    for name in (names.PROBE_GROUP_TEMPLATE, names.PROBE_GROUP_TEMPLATE + " Behind"):
        template = bpy.data.node_groups[name]
        assert template.users == 0 and len(template.nodes) > 2
        assert bool(template.get(probe_maps.BEHIND_KEY)) == name.endswith("Behind")
        assert os.path.isfile(template_cache._path(name))
