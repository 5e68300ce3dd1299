"""Every difference between the Blender releases PlateLight runs on (4.5 LTS, 5.2 LTS, 5.3), in
one place; the rest of the code calls these functions instead of testing versions itself.

What differs (README, "Supported Blender versions"):
- Materials and worlds: on 4.5 a new one has no node tree until ``use_nodes`` is set; on 5.x it
  always has one (and ``use_nodes`` is deprecated).
- The compositor: 4.5 keeps the scene's tree in ``scene.node_tree`` (after ``scene.use_nodes``)
  and its result is the Composite node; 5.x assigns a CompositorNodeTree group to
  ``scene.compositing_node_group`` and its result is the group's "Image" output.
- Compositor maths: 4.5 has CompositorNodeMixRGB / CompositorNodeMath; 5.x uses the shader-style
  ShaderNodeMix / ShaderNodeMath there.
- Node options: 5.x turned many compositor options into menu input sockets (Glare "Type", Blur
  "Type", Set Alpha "Type", Denoise "Quality" ...); on 4.5 they are node properties. Alpha Over's
  inputs are named Background/Foreground on 5.x and are the 2nd/3rd "Image" on 4.5.
- File Output node: ``directory`` / ``file_output_items`` on 5.x, ``base_path`` / ``file_slots``
  on 4.5.
- ``ImageFormatSettings.media_type`` exists only on 5.x (a multilayer EXR is its media type
  there, a file format on 4.5); a File Output node's still-frame files carry the frame number on
  4.5 only.
- EEVEE's engine identifier: BLENDER_EEVEE_NEXT on 4.5, BLENDER_EEVEE on 5.x.
- A multilayer EXR names the Object Index pass "IndexOB" on 4.5, "Object Index" on 5.x.
- 4.5's bpy can deadlock at process exit (exit_process).
"""
from __future__ import annotations

from collections import namedtuple

import bpy

VERSION = tuple(bpy.app.version[:2])
# Every difference below is between 4.5 and 5.x (5.2 and 5.3 agree on all of them).
BLENDER_4 = VERSION < (5, 0)

Mix = namedtuple("Mix", "node factor a b result")
# The render engine identifier of EEVEE (4.2-4.5 called the new EEVEE "EEVEE Next").
EEVEE = "BLENDER_EEVEE_NEXT" if BLENDER_4 else "BLENDER_EEVEE"
# EEVEE honours a view layer's material override from 5.0 on; 4.5's EEVEE renders the objects'
# own materials (measured: its baked-shadow layer showed the lit phantoms, not the ratio).
EEVEE_MATERIAL_OVERRIDE = not BLENDER_4
# The Object Index pass's layer in a multilayer EXR (its one channel is X).
OBJECT_INDEX_LAYER = "IndexOB" if BLENDER_4 else "Object Index"


# ---- materials and worlds
def node_tree(idblock):
    """The shader node tree a material or world renders with; on 4.5 its nodes are switched on
    (a new one has none until then, and one with them off renders without its tree)."""
    if BLENDER_4 and not idblock.use_nodes:
        idblock.use_nodes = True
    return idblock.node_tree


def shader_tree(idblock):
    """The node tree a material or world renders with, or None (4.5 ignores the tree of one whose
    ``use_nodes`` is off; never creates one)."""
    if idblock is None:
        return None
    if BLENDER_4 and not idblock.use_nodes:
        return None
    return idblock.node_tree


def new_material(name):
    material = bpy.data.materials.new(name)
    node_tree(material)
    return material


def new_world(name):
    world = bpy.data.worlds.new(name)
    node_tree(world)
    return world


# ---- image formats
def still_image_format():
    """(attribute, value) pairs that make an ImageFormatSettings write a still image."""
    return [] if BLENDER_4 else [("media_type", "IMAGE")]


def multilayer_exr_format():
    """(attribute, value) pairs, in order, that make an ImageFormatSettings write a multilayer
    EXR (every pass of the render, not only Combined)."""
    if BLENDER_4:
        return [("file_format", "OPEN_EXR_MULTILAYER")]
    return [("media_type", "MULTI_LAYER_IMAGE"), ("file_format", "OPEN_EXR_MULTILAYER")]


def set_still_image(fmt):
    for attr, value in still_image_format():
        setattr(fmt, attr, value)


# ---- the scene's compositor tree
def compositor_tree(scene):
    """The scene's compositor node tree, or None."""
    if BLENDER_4:
        return scene.node_tree if scene.use_nodes else None
    return scene.compositing_node_group


def new_compositor_tree(scene, name):
    """An empty compositor tree that the scene composites with (its own one reused and cleared).
    On 5.x it is the node group ``name`` with an "Image" output; on 4.5 the scene's own tree."""
    if BLENDER_4:
        scene.use_nodes = True
        tree = scene.node_tree
        tree.nodes.clear()
        return tree
    tree = scene.compositing_node_group
    if tree is None or tree.bl_idname != "CompositorNodeTree":
        tree = bpy.data.node_groups.get(name)
    if tree is None or tree.bl_idname != "CompositorNodeTree":
        tree = bpy.data.node_groups.new(name, "CompositorNodeTree")
    tree.nodes.clear()
    tree.interface.clear()
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    scene.compositing_node_group = tree
    return tree


def remove_compositor_tree(scene):
    """Remove the compositor tree new_compositor_tree() gave ``scene`` (on 4.5 it is the scene's
    own and goes with the scene; on 5.x a node group of its own)."""
    if not BLENDER_4 and scene.compositing_node_group is not None:
        tree = scene.compositing_node_group
        scene.compositing_node_group = None
        bpy.data.node_groups.remove(tree)


def composite_output(tree):
    """The input socket whose image is the render's composite (a new output node in ``tree``)."""
    if BLENDER_4:
        return tree.nodes.new("CompositorNodeComposite").inputs["Image"]
    return tree.nodes.new("NodeGroupOutput").inputs["Image"]


# ---- compositor nodes
def compositor_mix(nodes, blend="MIX", clamp=False):
    """A colour mix node in a compositor tree: Mix(node, factor, a, b, result) sockets."""
    if BLENDER_4:
        node = nodes.new("CompositorNodeMixRGB")
        node.blend_type = blend
        node.use_clamp = clamp
        return Mix(node, node.inputs[0], node.inputs[1], node.inputs[2], node.outputs[0])
    node = nodes.new("ShaderNodeMix")
    node.data_type = "RGBA"
    node.blend_type = blend
    node.clamp_result = clamp
    return Mix(node, node.inputs[0], node.inputs[6], node.inputs[7], node.outputs[2])


def compositor_math(nodes, operation):
    """A float Math node in a compositor tree (inputs 0-2, output 0 on every version)."""
    node = nodes.new("CompositorNodeMath" if BLENDER_4 else "ShaderNodeMath")
    node.operation = operation
    return node


def compositor_erode(nodes, pixels):
    """A Dilate/Erode node in Step mode that shrinks its Mask input's 1s by ``pixels`` (input
    "Mask", output "Mask"): 1 where every pixel within that reach is 1. 4.5 keeps the size in its
    ``distance`` property as well as the Size socket of 5.x; both are set."""
    node = nodes.new("CompositorNodeDilateErode")
    if BLENDER_4:
        node.mode = "STEP"
        node.distance = -pixels
    else:
        node.inputs["Type"].default_value = "Steps"
    node.inputs["Size"].default_value = -pixels
    return node


# On 4.5 these menu sockets of 5.x are properties of the node; values are the menu item names.
_OPTION_PROPERTIES = {
    ("CompositorNodeGlare", "Type"): "glare_type",
    ("CompositorNodeGlare", "Quality"): "quality",
    ("CompositorNodeBlur", "Type"): "filter_type",
    ("CompositorNodeSetAlpha", "Type"): "mode",
    ("CompositorNodeDenoise", "Prefilter"): "prefilter",
    ("CompositorNodeDenoise", "Quality"): "quality",
    ("CompositorNodeDenoise", "HDR"): "use_hdr",
}


def set_option(node, name, value):
    """Set a node option by its 5.x menu socket name and item name (e.g. Glare "Type" = "Bloom")."""
    if not BLENDER_4:
        node.inputs[name].default_value = value
        return
    prop = _OPTION_PROPERTIES[(node.bl_idname, name)]
    if node.bl_rna.properties[prop].type != "ENUM":
        setattr(node, prop, value)
        return
    items = node.bl_rna.properties[prop].enum_items
    wanted = value.casefold()
    match = next((i.identifier for i in items if i.name.casefold() == wanted), None)
    if match is None:     # 4.5 names a few items differently ("Gaussian" is "Gaussian" / "GAUSS")
        match = next(i.identifier for i in items if i.identifier.casefold().startswith(wanted[:4]))
    setattr(node, prop, match)


def alpha_over_inputs(node):
    """(background, foreground) image inputs of an Alpha Over node."""
    if BLENDER_4:
        return node.inputs[1], node.inputs[2]
    return node.inputs["Background"], node.inputs["Foreground"]


def set_file_output(node, directory, names):
    """Point a File Output node at ``directory`` with one RGBA input per name, files <name><frame>."""
    if BLENDER_4:
        node.base_path = directory
        node.file_slots.clear()
        for name in names:
            node.file_slots.new(name)
        return
    node.directory = directory
    node.file_name = ""
    node.file_output_items.clear()
    for name in names:
        node.file_output_items.new("RGBA", name)


def file_output_path(directory, name, frame):
    """The file a File Output input ``name`` (set_file_output) writes when ``frame`` is rendered as
    a still: 4.5 always appends the frame number, 5.x does not for a still."""
    import os

    return os.path.join(directory, f"{name}{frame:04d}.exr" if BLENDER_4 else f"{name}.exr")


# ---- process exit
def exit_process(code):
    """End a process that ran bpy with exit status ``code``. What Blender prints while it shuts
    down (its leak report, "Error: Not freed memory blocks ...") goes to stderr, so stdout holds
    only the command's own output. Blender 4.5's bpy can deadlock in its C exit handlers (a
    delayed file-close thread waits on a condition variable that a global destructor is
    destroying), so there Python's own exit handlers run and the C ones are skipped."""
    import os
    import sys

    sys.stdout.flush()
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    if not BLENDER_4:
        return
    import atexit
    import shutil

    atexit._run_exitfuncs()
    # Blender's own session folder (blender_XXXXXX in the temp folder) is removed by the C exit
    # handlers that are skipped here, so remove it ourselves.
    if bpy.app.tempdir:
        shutil.rmtree(bpy.app.tempdir, ignore_errors=True)
    sys.stderr.flush()
    os._exit(int(code or 0))
