"""Tiny helpers that keep node-group builders readable: sockets by name, maths in one call,
and in-place interface sync (so upgrading a group keeps the links and values in materials)."""
from __future__ import annotations

from ..addon.ibl.maps import GLOSSINESS_SCALE, MAP_NAMES

VERSION_KEY = "platelight_version"


class Graph:
    """Adds nodes to ``tree`` left to right; arguments may be sockets or constants."""

    def __init__(self, tree):
        self.tree = tree
        self.column = 0

    def node(self, idname, **props):
        node = self.tree.nodes.new(idname)
        for key, value in props.items():
            setattr(node, key, value)
        node.location = (200 * (self.column // 12), -160 * (self.column % 12))
        self.column += 1
        return node

    def _feed(self, socket, value):
        if hasattr(value, "is_output"):
            self.tree.links.new(value, socket)
        elif value is not None:
            socket.default_value = value

    def math(self, op, a, b=None, c=None, clamp=False):
        node = self.node("ShaderNodeMath", operation=op, use_clamp=clamp)
        for socket, value in zip(node.inputs, (a, b, c)):
            self._feed(socket, value)
        return node.outputs[0]

    def vmath(self, op, a, b=None, scale=None):
        node = self.node("ShaderNodeVectorMath", operation=op)
        self._feed(node.inputs[0], a)
        self._feed(node.inputs[1], b)
        if scale is not None:
            self._feed(node.inputs["Scale"], scale)
        out = "Value" if op in ("DOT_PRODUCT", "LENGTH", "DISTANCE") else "Vector"
        return node.outputs[out]

    def mix(self, data_type, factor, a, b, blend="MIX"):
        """Linear blend a -> b (vectors, colours or floats); MULTIPLY/ADD for colours."""
        node = self.node("ShaderNodeMix", data_type=data_type)
        if data_type == "RGBA":
            node.blend_type = blend
        sockets = [s for s in node.inputs if s.enabled]
        self._feed(sockets[0], factor)
        self._feed(sockets[1], a)
        self._feed(sockets[2], b)
        return next(s for s in node.outputs if s.enabled)

    def color_op(self, blend, a, b):
        return self.mix("RGBA", 1.0, a, b, blend=blend)

    def link(self, src, dst):
        self.tree.links.new(src, dst)


def tents(g, position, count):
    """Weights max(0, 1 - |position - k|) of knots k = 0 .. count - 1: linear between neighbours."""
    return [g.math("MAXIMUM", g.math("SUBTRACT", 1.0,
                                     g.math("ABSOLUTE", g.math("SUBTRACT", position, float(k)))), 0.0)
            for k in range(count)]


def knot_position(g, knots, value):
    """Where ``value`` lies among decreasing ``knots``: k + the fraction of the way to knot k + 1
    (0 at or above the first, len(knots) - 1 at or below the last), piecewise linear."""
    position = 0.0
    for k in range(len(knots) - 1):
        part = g.math("DIVIDE", g.math("SUBTRACT", knots[k], value), knots[k] - knots[k + 1])
        position = g.math("ADD", position, g.math("MINIMUM", g.math("MAXIMUM", part, 0.0), 1.0))
    return position


def tent_weights(g, glossiness):
    """maps.tent_weights in nodes: each map's weight (MAP_NAMES order) for glossiness n'."""
    scaled = g.math("MULTIPLY", g.math("MINIMUM", g.math("MAXIMUM", glossiness, 0.0), 1.0),
                    float(GLOSSINESS_SCALE))
    return tents(g, scaled, len(MAP_NAMES))


def float_curve(g, xs, ys, value):
    """A Float Curve through (xs, ys), linear between the points and flat beyond them. Values
    outside [0, 1] are held scaled into it (a curve's points are clipped to its box)."""
    low, high = min(min(ys), 0.0), max(max(ys), 1.0)
    node = g.node("ShaderNodeFloatCurve")
    curve = node.mapping.curves[0]
    while len(curve.points) < len(xs):
        curve.points.new(0.0, 0.0)
    for point, x, y in zip(curve.points, xs, ys):
        point.location = (x, (y - low) / (high - low))
        point.handle_type = "VECTOR"
    node.mapping.update()
    g.link(value, node.inputs["Value"])
    if (low, high) == (0.0, 1.0):
        return node.outputs["Value"]
    return g.math("MULTIPLY_ADD", node.outputs["Value"], high - low, low)


def sync_interface(tree, sockets):
    """Make the group's interface exactly ``sockets`` (in order), reusing items with the same name
    and type so that links and values in existing materials survive an upgrade.

    ``sockets``: (in_out, name, socket_type, options dict) tuples."""
    wanted = {(io, name) for io, name, _, _ in sockets}
    for item in list(tree.interface.items_tree):
        if item.item_type != "SOCKET":
            continue
        key = (item.in_out, item.name)
        spec = next((s for s in sockets if (s[0], s[1]) == key), None)
        if key not in wanted or spec is None or item.socket_type != spec[2]:
            tree.interface.remove(item)
    for position, (io, name, socket_type, options) in enumerate(sockets):
        item = next((i for i in tree.interface.items_tree
                     if i.item_type == "SOCKET" and i.in_out == io and i.name == name), None)
        if item is None:
            item = tree.interface.new_socket(name, in_out=io, socket_type=socket_type)
        for key, value in options.items():
            setattr(item, key, value)
    # Order: Blender keeps outputs before inputs; order each side as listed.
    for io in ("OUTPUT", "INPUT"):
        names = [name for side, name, _, _ in sockets if side == io]
        for index, name in enumerate(names):
            items = [i for i in tree.interface.items_tree
                     if i.item_type == "SOCKET" and i.in_out == io]
            item = next(i for i in items if i.name == name)
            if items.index(item) != index:
                offset = sum(1 for i in tree.interface.items_tree
                             if i.item_type == "SOCKET" and i.in_out != io
                             and i.position < items[0].position)
                tree.interface.move(item, offset + index)


def shader_group(name: str):
    """The shader node group ``name``, new and empty if there is none; a node group of another
    kind holding the name is renamed aside (kept: it is the user's)."""
    import bpy

    tree = bpy.data.node_groups.get(name)
    if tree is not None and tree.bl_idname != "ShaderNodeTree":
        tree.name = name + " (not a shader group)"
        tree = None
    return tree or bpy.data.node_groups.new(name, "ShaderNodeTree")


def io_nodes(graph):
    gin = graph.node("NodeGroupInput")
    gout = graph.node("NodeGroupOutput")
    return gin, gout


def place_io(graph, gin, gout):
    """The group's input left of its nodes and its output right of them, once they are built."""
    gin.location = (-400, 0)
    gout.location = (200 * (graph.column // 12 + 1), 0)


def strength_against_film_exposure(strength_socket, scene):
    """Drive an Emission's Strength to 1 / ``scene``'s Cycles film exposure. What a PlateLight
    emission shows is already as filmed (the plate) or a ratio, and Cycles' film exposure would
    scale it again on its way to the camera."""
    tree = strength_socket.id_data
    path = strength_socket.path_from_id("default_value")
    tree.driver_remove(path)
    driver = tree.driver_add(path).driver
    driver.type = "SCRIPTED"
    variable = driver.variables.new()
    variable.name = "exposure"
    variable.type = "SINGLE_PROP"
    variable.targets[0].id_type = "SCENE"
    variable.targets[0].id = scene
    variable.targets[0].data_path = "cycles.film_exposure"
    driver.expression = "1 / max(exposure, 1e-6)"     # a simple expression: no Python needed


def _channelbag(idblock):
    """``idblock``'s action's channel bag for its slot (4.4 on keep actions in slots), or None."""
    from bpy_extras import anim_utils

    animation = idblock.animation_data
    if animation is None or animation.action is None:
        return None
    return anim_utils.action_get_channelbag_for_slot(animation.action, animation.action_slot)


def action_fcurves(idblock) -> list:
    """The F-curves of ``idblock``'s action."""
    channelbag = _channelbag(idblock)
    return list(channelbag.fcurves) if channelbag is not None else []


def hold_per_frame(socket, values: dict) -> None:
    """Key ``socket``'s value to ``values`` ({frame: value}), held constant between frames as the
    per-frame maps it goes with are (image sequences: frame F reads file F)."""
    tree = socket.id_data
    for frame, value in sorted(values.items()):
        socket.default_value = value
        socket.keyframe_insert("default_value", frame=frame)
    path = socket.path_from_id("default_value")
    for curve in action_fcurves(tree):
        if curve.data_path == path:
            for point in curve.keyframe_points:
                point.interpolation = "CONSTANT"


def drop_keys(tree, node_names) -> None:
    """Remove the keys on the named nodes' sockets (a rebind's values replace them)."""
    prefixes = tuple(f'nodes["{name}"].' for name in node_names)
    channelbag = _channelbag(tree)
    if channelbag is None:
        return
    for curve in [c for c in channelbag.fcurves if c.data_path.startswith(prefixes)]:
        channelbag.fcurves.remove(curve)
