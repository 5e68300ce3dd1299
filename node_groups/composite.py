"""Compositor group "PlateLight Differential": differential rendering onto the plate (Debevec 1998,
paper section 4), with the CG's lens and tone presets.

    CG'      = blur(glare(tone(exposure(CG))))                 (CG only: the plate passes untouched)
    CG''     = CG' + Grain Amount · α' · Grain · √(1 − r + r · (CG'/α') / Grain Level)
    ratio    = min(With / max(Without, ε), Shadow Clamp)        (ratio form; catcher pass: Without = 1)
    local    = Ratio Form ? Plate · ratio : Plate + With − Without
    Image    = CG'' + (1 − α_CG) · local                        (premultiplied "over")

Where no CG, shadow or reflection touches a pixel, α = 0 and With = Without, so Image = Plate
exactly (every step is then a multiplication by 1 or an addition of 0 in float32; the grain is
weighted by the CG's alpha α', so it adds exactly 0 there).
Grain: the plate's grain at its reference level (Grain Level), made by platelight.match_grain
(addon/compositing/grain.py); r = Grain Response, the signal-dependent part of its variance, so
the grain's variance follows var(L) = a + b·L at the CG's own level L.

Compositor groups are node trees of type CompositorNodeTree; the Mix and Math nodes and how node
options are set (menu sockets on 5.x, properties on 4.5) come from compat.py.
The builder is idempotent: re-running it rebuilds the same group in place (users keep it).
"""
import bpy

from .. import compat
from ..addon import names

RATIO_EPSILON = 1e-6

# name, socket type, default, (min, max), description
INPUTS = (
    ("Plate", "NodeSocketColor", (0.0, 0.0, 0.0, 1.0), None, "The footage frame"),
    ("CG", "NodeSocketColor", (0.0, 0.0, 0.0, 0.0), None, "CG render, premultiplied alpha"),
    ("With", "NodeSocketColor", (1.0, 1.0, 1.0, 1.0), None,
     "Local scene rendered with the CG objects, or Cycles' Shadow Catcher pass (then Without = 1)"),
    ("Without", "NodeSocketColor", (1.0, 1.0, 1.0, 1.0), None, "Local scene rendered without the CG objects"),
    ("Ratio Form", "NodeSocketFloat", 1.0, (0.0, 1.0),
     "1: Plate × With/Without (shadows scale the plate); 0: Plate + With − Without (additive)"),
    ("Shadow Clamp", "NodeSocketFloat", 4.0, (1.0, 1000.0),
     "Largest brightening the ratio may apply (keeps noise in dark Without pixels from exploding)"),
    ("CG Exposure", "NodeSocketFloat", 0.0, (-20.0, 20.0), "Exposure of the CG in stops, to match the plate"),
    ("Tone Map", "NodeSocketFloat", 0.0, (0.0, 1.0),
     "Blend of Reinhard's x/(1+x) on the CG (use when the plate is display-referred footage)"),
    ("Glare", "NodeSocketFloat", 0.0, (0.0, 1.0), "Bloom on the CG's HDR highlights"),
    ("Glare Threshold", "NodeSocketFloat", 1.0, (0.0, 1000.0), "Brightness above which the CG blooms"),
    ("CG Blur", "NodeSocketFloat", 0.0, (0.0, 100.0),
     "Gaussian blur of the CG (colour and alpha) in pixels, to match a soft or defocused plate"),
    ("Grain", "NodeSocketColor", (0.0, 0.0, 0.0, 1.0), None,
     "Zero-mean grain image with the plate's grain at Grain Level (platelight.match_grain)"),
    ("Grain Amount", "NodeSocketFloat", 0.0, (0.0, 1.0), "How much of the Grain is added to the CG"),
    ("Grain Level", "NodeSocketColor", (1.0, 1.0, 1.0, 1.0), None,
     "Per-channel signal level at which the Grain image has the plate's grain"),
    ("Grain Response", "NodeSocketColor", (0.0, 0.0, 0.0, 1.0), None,
     "Per channel, the part of the grain's variance that grows with the signal (0: the same grain "
     "everywhere; 1: shot noise, grain ∝ √level)"),
)
OUTPUTS = (
    ("Image", "NodeSocketColor", "The composite"),
    ("CG", "NodeSocketColor", "The CG after exposure, tone and glare"),
    ("Shadows", "NodeSocketColor", "What the CG does to the real scene: the ratio (or the difference + 1)"),
)


def _mix(nodes, links, blend, a, b, factor=1.0, location=(0, 0), clamp=False):
    """A colour mix (compat.Mix: node, factor, a, b, result); a and b are sockets or values."""
    mix = compat.compositor_mix(nodes, blend, clamp)
    mix.node.location = location
    mix.factor.default_value = factor
    for socket, value in ((mix.a, a), (mix.b, b)):
        if isinstance(value, bpy.types.NodeSocket):
            links.new(value, socket)
        elif isinstance(value, (int, float)):
            socket.default_value = (value, value, value, 1.0)
        else:
            socket.default_value = value
    return mix


def _link_factor(links, mix, socket):
    links.new(socket, mix.factor)


def _rebuild_interface(tree):
    tree.interface.clear()
    for name, socket_type, default, bounds, description in INPUTS:
        socket = tree.interface.new_socket(name, in_out="INPUT", socket_type=socket_type)
        socket.description = description
        socket.default_value = default
        if bounds is not None:
            socket.min_value, socket.max_value = bounds
    for name, socket_type, description in OUTPUTS:
        socket = tree.interface.new_socket(name, in_out="OUTPUT", socket_type=socket_type)
        socket.description = description


def _grain(nodes, links, inp, cg):
    """CG + Grain Amount · α · Grain · √(1 − r + r · (CG/α) / Grain Level), per channel; returns
    the socket. α is the (blurred) CG's alpha: where it is 0 the grain adds exactly 0."""
    x, y = 700, 700
    alpha = nodes.new("CompositorNodeSeparateColor")
    alpha.location = (x, y)
    links.new(cg, alpha.inputs["Image"])
    safe_alpha = compat.compositor_math(nodes, "MAXIMUM")
    safe_alpha.location = (x, y - 200)
    links.new(alpha.outputs["Alpha"], safe_alpha.inputs[0])
    safe_alpha.inputs[1].default_value = RATIO_EPSILON
    straight = _mix(nodes, links, "DIVIDE", cg, safe_alpha.outputs[0], location=(x + 200, y))
    safe_level = _mix(nodes, links, "LIGHTEN", inp["Grain Level"], RATIO_EPSILON, location=(x + 200, y - 200))
    relative = _mix(nodes, links, "DIVIDE", straight.result, safe_level.result, location=(x + 400, y))
    minus_one = _mix(nodes, links, "SUBTRACT", relative.result, 1.0, location=(x + 600, y))
    weighted = _mix(nodes, links, "MULTIPLY", minus_one.result, inp["Grain Response"], location=(x + 800, y))
    ratio = _mix(nodes, links, "ADD", weighted.result, 1.0, location=(x + 1000, y))
    ratio = _mix(nodes, links, "LIGHTEN", ratio.result, 0.0, location=(x + 1200, y))
    channels = nodes.new("CompositorNodeSeparateColor")
    channels.location = (x + 1400, y)
    links.new(ratio.result, channels.inputs["Image"])
    scale = nodes.new("CompositorNodeCombineColor")
    scale.location = (x + 1800, y)
    for k, channel in enumerate(("Red", "Green", "Blue")):
        root = compat.compositor_math(nodes, "SQRT")
        root.location = (x + 1600, y - 60 * k)
        links.new(channels.outputs[channel], root.inputs[0])
        links.new(root.outputs[0], scale.inputs[channel])
    scaled = _mix(nodes, links, "MULTIPLY", inp["Grain"], scale.outputs["Image"], location=(x + 2000, y - 200))
    covered = _mix(nodes, links, "MULTIPLY", scaled.result, alpha.outputs["Alpha"], location=(x + 2200, y - 200))
    # a colour mix keeps A's (the CG's) alpha
    grained = _mix(nodes, links, "ADD", cg, covered.result, location=(x + 2400, y))
    links.new(inp["Grain Amount"], grained.factor)
    return grained.result


def build_differential_group():
    """Create or rebuild the "PlateLight Differential" compositor group; returns it."""
    tree = bpy.data.node_groups.get(names.DIFFERENTIAL_GROUP)
    if tree is None or tree.bl_idname != "CompositorNodeTree":
        tree = bpy.data.node_groups.new(names.DIFFERENTIAL_GROUP, "CompositorNodeTree")
    tree.nodes.clear()
    _rebuild_interface(tree)
    nodes, links = tree.nodes, tree.links
    group_in = nodes.new("NodeGroupInput")
    group_in.location = (-1200, 0)
    group_out = nodes.new("NodeGroupOutput")
    group_out.location = (3600, 0)
    inp = group_in.outputs

    # --- the CG's lens and tone (never applied to the plate) ---
    exposure = nodes.new("CompositorNodeExposure")
    exposure.location = (-900, 300)
    links.new(inp["CG"], exposure.inputs["Image"])
    links.new(inp["CG Exposure"], exposure.inputs["Exposure"])
    # Reinhard x/(1+x) per channel; alpha is carried by the original CG below
    one_plus = _mix(nodes, links, "ADD", exposure.outputs["Image"], 1.0, location=(-700, 400))
    reinhard = _mix(nodes, links, "DIVIDE", exposure.outputs["Image"], one_plus.result, location=(-500, 400))
    toned = _mix(nodes, links, "MIX", exposure.outputs["Image"], reinhard.result, location=(-300, 300))
    _link_factor(links, toned, inp["Tone Map"])
    glare = nodes.new("CompositorNodeGlare")
    glare.location = (-100, 450)
    compat.set_option(glare, "Type", "Bloom")
    compat.set_option(glare, "Quality", "Medium")
    links.new(toned.result, glare.inputs["Image"])
    links.new(inp["Glare Threshold"], glare.inputs["Threshold"])
    glared = _mix(nodes, links, "MIX", toned.result, glare.outputs["Image"], location=(100, 300))
    _link_factor(links, glared, inp["Glare"])
    # colour mixes keep A's alpha: put the CG's own alpha back explicitly
    cg_alpha = nodes.new("CompositorNodeSeparateColor")
    cg_alpha.location = (-900, 100)
    links.new(inp["CG"], cg_alpha.inputs["Image"])
    cg_out = nodes.new("CompositorNodeSetAlpha")
    cg_out.location = (300, 300)
    compat.set_option(cg_out, "Type", "Replace Alpha")
    links.new(glared.result, cg_out.inputs["Image"])
    links.new(cg_alpha.outputs["Alpha"], cg_out.inputs["Alpha"])

    # --- the CG's effect on the real scene ---
    safe_without = _mix(nodes, links, "LIGHTEN", inp["Without"], RATIO_EPSILON, location=(-700, -200))
    ratio = _mix(nodes, links, "DIVIDE", inp["With"], safe_without.result, location=(-500, -200))
    clamp_colour = nodes.new("CompositorNodeCombineColor")
    clamp_colour.location = (-700, -400)
    for channel in ("Red", "Green", "Blue"):
        links.new(inp["Shadow Clamp"], clamp_colour.inputs[channel])
    clamped = _mix(nodes, links, "DARKEN", ratio.result, clamp_colour.outputs["Image"], location=(-300, -200))
    scaled = _mix(nodes, links, "MULTIPLY", inp["Plate"], clamped.result, location=(-100, -200))
    difference = _mix(nodes, links, "SUBTRACT", inp["With"], inp["Without"], location=(-500, -500))
    added = _mix(nodes, links, "ADD", inp["Plate"], difference.result, location=(-100, -500))
    local = _mix(nodes, links, "MIX", added.result, scaled.result, location=(100, -300))
    _link_factor(links, local, inp["Ratio Form"])
    shadows_additive = _mix(nodes, links, "ADD", difference.result, 1.0, location=(-300, -600))
    shadows = _mix(nodes, links, "MIX", shadows_additive.result, clamped.result, location=(100, -600))
    _link_factor(links, shadows, inp["Ratio Form"])

    blur = nodes.new("CompositorNodeBlur")
    blur.location = (500, 300)
    compat.set_option(blur, "Type", "Gaussian")
    links.new(cg_out.outputs["Image"], blur.inputs["Image"])
    links.new(inp["CG Blur"], blur.inputs["Size"])
    cg_final = _grain(nodes, links, inp, blur.outputs["Image"])

    over = nodes.new("CompositorNodeAlphaOver")
    over.location = (3300, 0)
    background, foreground = compat.alpha_over_inputs(over)
    links.new(local.result, background)
    links.new(cg_final, foreground)
    links.new(over.outputs["Image"], group_out.inputs["Image"])
    links.new(cg_final, group_out.inputs["CG"])
    links.new(shadows.result, group_out.inputs["Shadows"])
    return tree
