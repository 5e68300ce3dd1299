"""The nodes of a probe group "PlateLight Probe <name>" (probe_maps.py binds their images and
values): the four maps sampled along the directions "PlateLight SBRDF" computes, the parallax
search through the distance map, the irradiance grid, the sun's lobes, summed into Lr.

Glossiness n' in [0, 1] blends the maps with tent weights w_k = max(0, 1 - |3 n' - k|),
k = 0..3 for diffuse, glossy1, glossy2, specular (design.md: linear between neighbours): the
rule of addon/ibl/maps.map_weights, built here as nodes from the same constants.
"""
from __future__ import annotations

import math

from ..addon import names
from ..addon.ibl import irradiance_grid, sun_lobe, view_lobe
from ..addon.ibl.anisotropy import TAP_SLOPES
from ..addon.ibl.distance import (BEHIND_BISECT, BEHIND_GROWTH, BEHIND_JUMP, BEHIND_MAPS, BEHIND_NEAR, BEHIND_STEPS,
                                  DISTANCE_NAME, FAR, SECANT_STEPS, STEP_START, STEPS, behind_name)
from ..addon.ibl.maps import (GLOSSINESS_KNOTS, GLOSSINESS_SCALE, MAP_HALF_ANGLES, MAP_NAMES, ROUGHNESS_KNOTS)
from ._build import Graph, float_curve, io_nodes, knot_position, place_io, tent_weights, tents

DISTANCE_BEHIND = behind_name(DISTANCE_NAME)   # the nodes reading the layer behind's distance map
# What the specular look-ups read along the streak: the ladder's maps after the diffuse one (which
# they read once, split by the lobe's reflectance), the glossy ones sunless (or the ladder's rungs,
# which are sunless where the probe has a sun), glossy3 a rung only, the mirror map with its sun.
STREAK_MAPS = tuple(sun_lobe.sunless_name(n) if n in sun_lobe.SUNLESS_MAPS else n for n in view_lobe.LADDER[1:])


def _named_value(g, name, default):
    """A Value node the binding finds by ``name`` and sets (a switch, a grid's size)."""
    node = g.node("ShaderNodeValue")
    node.name = node.label = name
    node.outputs[0].default_value = default
    return node.outputs[0]


def _named_vector(g, name):
    """A Combine XYZ node the binding finds by ``name`` and sets (a probe centre, a box corner)."""
    node = g.node("ShaderNodeCombineXYZ")
    node.name = node.label = name
    return node.outputs["Vector"]


def _parallax(g, direction, behind=False):
    """(direction, footprint ratio, behind weight): the specular look-up direction corrected for
    the shading point's offset from the probe centre, by the distance-impostor search of
    addon/ibl/distance.py (its numpy references parallax_search and, with ``behind``,
    parallax_layers): a linear search over geometric steps, then secant steps; the hit's distance
    from the point over its distance from the centre; and, with the layer behind, 1 where the
    ray passed beside a near occluder and meets what lies past it in the layer behind (None
    without). The switch (0/1, set by the binding) falls back to the uncorrected direction and a
    ratio of 1, as does a ray that meets nothing."""
    position = g.node("ShaderNodeNewGeometry").outputs["Position"]
    centre = _named_vector(g, names.PROBE_CENTRE_NODE)
    switch = _named_value(g, names.PARALLAX_NODE, 0.0)
    p = g.vmath("SUBTRACT", position, centre)
    reflected = g.vmath("NORMALIZE", direction)
    p_len = g.vmath("LENGTH", p)

    def point(t):
        return g.vmath("ADD", p, g.vmath("SCALE", reflected, scale=t))

    def radius(q, map_name):
        node = g.node("ShaderNodeTexEnvironment", interpolation="Closest")
        node["platelight_map"] = map_name
        g.link(q, node.inputs["Vector"])
        return node.outputs["Color"]                 # colour -> r

    def s_of(map_name):
        def s(t):
            q = point(t)
            return g.math("SUBTRACT", g.vmath("LENGTH", q), radius(q, map_name))
        return s

    def looks(found, t):
        hit_point = point(t)
        look = g.mix("VECTOR", found, reflected, g.vmath("NORMALIZE", hit_point))
        ratio = g.math("DIVIDE", t, g.math("MAXIMUM", g.vmath("LENGTH", hit_point), 1e-6))
        ratio = g.math("MINIMUM", g.math("MAXIMUM", ratio, 0.0), 1.0)
        return look, g.math("MULTIPLY_ADD", found, g.math("SUBTRACT", ratio, 1.0), 1.0)

    found, t_hit, t_step, gap = _crossing(g, s_of(DISTANCE_NAME), point, 0.0, g.math("MULTIPLY", p_len, STEP_START),
                                          2.0, STEPS, BEHIND_BISECT if behind else 0)
    corrected, ratio = looks(found, t_hit)
    weight = None
    if behind:
        jump = g.math("GREATER_THAN", gap, g.math("MULTIPLY", g.vmath("LENGTH", point(t_hit)), BEHIND_JUMP))
        near = g.math("LESS_THAN", radius(point(t_step), DISTANCE_NAME), g.math("MULTIPLY", p_len, BEHIND_NEAR))
        passed = g.math("MULTIPLY", g.math("MULTIPLY", found, jump), near)
        found2, t2, _, _ = _crossing(g, s_of(DISTANCE_BEHIND), point, t_hit, t_step, BEHIND_GROWTH, BEHIND_STEPS)
        look2, ratio2 = looks(found2, t2)
        # the point the ray meets (or, escaping, its point at FAR): does the centre see it?
        far = point(g.math("MULTIPLY_ADD", found2, g.math("SUBTRACT", t2, FAR), FAR))
        seen = g.math("LESS_THAN", g.vmath("LENGTH", far),
                      g.math("MULTIPLY", radius(far, DISTANCE_NAME), 1.0 + BEHIND_JUMP + 1e-6))
        corrected = g.mix("VECTOR", passed, corrected, look2)
        ratio = g.math("MULTIPLY_ADD", passed, g.math("SUBTRACT", ratio2, ratio), ratio)
        weight = g.math("MULTIPLY", g.math("MULTIPLY", passed, g.math("SUBTRACT", 1.0, seen)), switch)
    ratio = g.math("MULTIPLY_ADD", switch, g.math("SUBTRACT", ratio, 1.0), 1.0)
    return g.mix("VECTOR", switch, reflected, corrected), ratio, weight


def _crossing(g, s, point, t_start, t_first, growth, steps, bisect=0):
    """distance._Rays.crossing in nodes: (found 0/1, refined t, the step t that first had s > 0,
    the gap between the surfaces at the refined bracket's ends) for the steps t_first growth^k
    after t_start; ``point``: t -> the ray's point."""
    def pick(flag, new, old):                       # flag ? new : old   (flag is 0 or 1)
        return g.math("MULTIPLY_ADD", flag, g.math("SUBTRACT", new, old), old)

    t_a, s_a = t_start, g.math("MINIMUM", s(t_start), -1e-4)
    t_b, s_b, found = t_start, s_a, 0.0
    for k in range(steps):
        t_k = g.math("MULTIPLY", t_first, growth ** k)
        s_k = s(t_k)
        newly = g.math("MULTIPLY", g.math("SUBTRACT", 1.0, found), g.math("GREATER_THAN", s_k, 0.0))
        t_b, s_b = pick(newly, t_k, t_b), pick(newly, s_k, s_b)
        before = g.math("SUBTRACT", g.math("SUBTRACT", 1.0, found), newly)
        t_a, s_a = pick(before, t_k, t_a), pick(before, s_k, s_a)
        found = g.math("MAXIMUM", found, newly)
    t_step = t_b

    def secant():
        return g.math("ADD", t_a, g.math("DIVIDE", g.math("MULTIPLY", g.math("SUBTRACT", t_b, t_a), s_a),
                                         g.math("MINIMUM", g.math("SUBTRACT", s_a, s_b), -1e-9)))
    for k in range(SECANT_STEPS + bisect):
        t_m = secant() if k < SECANT_STEPS else g.math("MULTIPLY", g.math("ADD", t_a, t_b), 0.5)
        s_m = s(t_m)
        hit = g.math("GREATER_THAN", s_m, 0.0)
        t_b, s_b, t_a, s_a = pick(hit, t_m, t_b), pick(hit, s_m, s_b), pick(hit, t_a, t_m), pick(hit, s_a, s_m)
    gap = None
    if bisect:
        def surface(t, s_t):                        # r = |q| - s
            return g.math("SUBTRACT", g.vmath("LENGTH", point(t)), s_t)
        gap = g.math("ABSOLUTE", g.math("SUBTRACT", surface(t_b, s_b), surface(t_a, s_a)))
    return found, secant(), t_step, gap


def _footprint_glossiness(g, glossiness, ratio):
    """addon/ibl/maps.footprint_glossiness as nodes: the glossiness whose lobe's half-energy
    angle (piecewise linear between the maps' MAP_HALF_ANGLES) is ``ratio`` times that of
    ``glossiness``, the ratio fading out between glossy1's angle and the diffuse lobe's."""
    knots = MAP_HALF_ANGLES
    position = g.math("MULTIPLY", g.math("MINIMUM", g.math("MAXIMUM", glossiness, 0.0), 1.0),
                      float(GLOSSINESS_SCALE))
    angle = knots[0]
    for k in range(len(knots) - 1):
        part = g.math("MINIMUM", g.math("MAXIMUM", g.math("SUBTRACT", position, float(k)), 0.0), 1.0)
        angle = g.math("MULTIPLY_ADD", part, knots[k + 1] - knots[k], angle)
    fade = g.math("MINIMUM", g.math("MAXIMUM", g.math("DIVIDE", g.math("SUBTRACT", knots[0], angle),
                                                     knots[0] - knots[1]), 0.0), 1.0)
    ratio = g.math("SUBTRACT", 1.0, g.math("MULTIPLY", g.math("SUBTRACT", 1.0, ratio), fade))
    angle = g.math("MULTIPLY", angle, ratio)
    return g.math("DIVIDE", knot_position(g, knots, angle), float(GLOSSINESS_SCALE))


def _view_lobe(g, inp, roughness, on):
    """view_lobe.ladder_weights at view_lobe.narrowed_roughness, and view_lobe.spread times
    TAP_SCALE, in nodes: (the LADDER maps' weights, the taps' spread vector). ``on`` (0/1, set by
    the binding) off: the roughness is not narrowed, the spread is 0 and glossy3's weight folds
    into its neighbours, which is the four maps' rule exactly."""
    n, view = inp["Diffuse Direction"], inp["Lobe View"]
    mu = g.math("MINIMUM", g.math("MAXIMUM", g.vmath("DOT_PRODUCT", n, view), 0.0), 1.0)
    floored = g.math("MAXIMUM", mu, view_lobe.MU_FLOOR)
    # view_lobe.view_weight: (alpha_b / alpha_t)^2, 1 for a round lobe
    alphas = g.node("ShaderNodeSeparateXYZ")
    g.link(inp["Lobe Alphas"], alphas.inputs["Vector"])
    ratio = g.math("DIVIDE", alphas.outputs["Y"], g.math("MAXIMUM", alphas.outputs["X"], 1e-12))
    amount = g.math("MULTIPLY", on, g.math("MULTIPLY", ratio, ratio))
    factor = g.math("MULTIPLY_ADD", amount, g.math("SUBTRACT", g.math("SQRT", floored), 1.0), 1.0)
    narrow = g.math("MULTIPLY", roughness, factor)
    # the ladder's position (0 = diffuse ... 4 = mirror): exact, piecewise linear in roughness
    knots = view_lobe.LADDER_ROUGHNESS
    weights = tents(g, knot_position(g, knots, narrow), len(knots))
    third = view_lobe.LADDER.index(view_lobe.GLOSSY3)
    folded = g.math("MULTIPLY", weights[third], g.math("SUBTRACT", 1.0, on))
    weights[third - 1] = g.math("MULTIPLY_ADD", folded, view_lobe.fold_share(), weights[third - 1])
    weights[third + 1] = g.math("MULTIPLY_ADD", folded, 1.0 - view_lobe.fold_share(), weights[third + 1])
    weights[third] = g.math("MULTIPLY", weights[third], on)
    # 2 alpha sqrt(1 - mu'^2) (sqrt(1 - mu^2) N + mu T), T the view's part along the surface
    in_plane = g.vmath("NORMALIZE", g.vmath("SUBTRACT", view, g.vmath("SCALE", n, scale=mu)))
    direction = g.vmath("ADD", g.vmath("SCALE", n, scale=g.math("SQRT", g.math("SUBTRACT", 1.0, g.math("MULTIPLY", mu, mu)))),
                        g.vmath("SCALE", in_plane, scale=mu))
    missing = g.math("SQRT", g.math("SUBTRACT", 1.0, g.math("MULTIPLY", floored, floored)))
    size = g.math("MULTIPLY", g.math("MULTIPLY", g.math("MULTIPLY", roughness, roughness), missing),
                  2.0 * view_lobe.TAP_SCALE)
    return weights, g.vmath("SCALE", direction, scale=g.math("MULTIPLY", size, amount))


def _irradiance_grid(g, direction):
    """The diffuse map seen from the shading point: the eight maps of the irradiance grid around
    it (addon/ibl/irradiance_grid.py: trilinear, atlas_uv) read along ``direction``."""
    points = _named_value(g, names.GRID_POINTS_NODE, float(irradiance_grid.DEFAULT_POINTS))
    height = _named_value(g, names.GRID_HEIGHT_NODE, 16.0)
    position = g.node("ShaderNodeNewGeometry").outputs["Position"]
    cell = g.vmath("MULTIPLY", g.vmath("SUBTRACT", position, _named_vector(g, names.GRID_LO_NODE)),
                   _named_vector(g, names.GRID_SCALE_NODE))
    cell = g.vmath("MINIMUM", g.vmath("MAXIMUM", cell, (0.0, 0.0, 0.0)), (1.0, 1.0, 1.0))
    cell = g.vmath("SCALE", cell, scale=g.math("SUBTRACT", points, 1.0))
    split = g.node("ShaderNodeSeparateXYZ")
    g.link(cell, split.inputs["Vector"])
    last = g.math("SUBTRACT", points, 2.0)
    lows, fractions = [], []
    for axis in range(3):
        low = g.math("MINIMUM", g.math("FLOOR", split.outputs[axis]), last)
        lows.append(low)
        fractions.append(g.math("SUBTRACT", split.outputs[axis], low))
    # the direction's equirect (u, v), as addon/ibl/equirect.dir_to_uv
    unit = g.node("ShaderNodeSeparateXYZ")
    g.link(g.vmath("NORMALIZE", direction), unit.inputs["Vector"])
    x, y, z = unit.outputs
    u = g.math("ADD", g.math("DIVIDE", g.math("ARCTAN2", g.math("MULTIPLY", y, -1.0), x), 2.0 * math.pi), 0.5)
    v = g.math("ADD", g.math("DIVIDE", g.math("ARCSINE", z), math.pi), 0.5)
    pad = float(irradiance_grid.PAD)
    tile_w = g.math("MULTIPLY_ADD", height, 2.0, 2.0 * pad)
    atlas_w = g.math("MULTIPLY", g.math("POWER", points, 3.0), tile_w)
    within_u = g.math("MULTIPLY_ADD", u, g.math("MULTIPLY", height, 2.0), pad)
    atlas_v = g.math("DIVIDE", g.math("MULTIPLY_ADD", v, height, pad), g.math("ADD", height, 2.0 * pad))
    # The atlas is read by Environment Texture nodes along the direction whose equirect (u, v) is
    # the atlas position: EEVEE samples an Image Texture with mipmaps chosen from screen-space
    # derivatives, which jump where the tile index changes (grid lines across the object), while
    # its Environment Texture reads the full-resolution level.
    elevation = g.math("MULTIPLY", g.math("SUBTRACT", atlas_v, 0.5), math.pi)
    cos_el, sin_el = g.math("COSINE", elevation), g.math("SINE", elevation)
    total = None
    for corner in range(8):
        steps = [(corner >> axis) & 1 for axis in range(3)]
        index = [g.math("ADD", low, float(step)) for low, step in zip(lows, steps)]
        tile = g.math("MULTIPLY_ADD", g.math("MULTIPLY_ADD", index[2], points, index[1]), points, index[0])
        atlas_u = g.math("DIVIDE", g.math("MULTIPLY_ADD", tile, tile_w, within_u), atlas_w)
        weight = None
        for f, step in zip(fractions, steps):
            factor = f if step else g.math("SUBTRACT", 1.0, f)
            weight = factor if weight is None else g.math("MULTIPLY", weight, factor)
        # equirect (u, v) -> direction: azimuth 2 pi (0.5 - u), elevation pi (v - 0.5)
        azimuth = g.math("MULTIPLY", g.math("SUBTRACT", 0.5, atlas_u), 2.0 * math.pi)
        look = g.node("ShaderNodeCombineXYZ")
        g.link(g.math("MULTIPLY", cos_el, g.math("COSINE", azimuth)), look.inputs["X"])
        g.link(g.math("MULTIPLY", cos_el, g.math("SINE", azimuth)), look.inputs["Y"])
        g.link(sin_el, look.inputs["Z"])
        image = g.node("ShaderNodeTexEnvironment", interpolation="Linear")
        image["platelight_map"] = irradiance_grid.GRID_NAME
        g.link(look.outputs["Vector"], image.inputs["Vector"])
        term = g.vmath("SCALE", image.outputs["Color"], scale=weight)
        total = term if total is None else g.vmath("ADD", total, term)
    return total


def _sun_nodes(g):
    """(direction, irradiance, angular diameter): the group's sun, one node each, which the
    binding finds by name (_bind_sun; its irradiance 0 when it has none)."""
    return (_named_vector(g, names.SUN_DIRECTION_NODE), _named_vector(g, names.SUN_COLOR_NODE),
            _named_value(g, names.SUN_ANGLE_NODE, 0.0))


def _sun_lambert(g, sun, normal):
    """sun_lobe.lambert in nodes: the sun on a diffuse surface of albedo 1, its horizon softened
    over the disc."""
    direction, color, angle = sun
    x = g.vmath("DOT_PRODUCT", normal, direction)
    s = g.math("MAXIMUM", g.math("SINE", g.math("MULTIPLY", angle, 0.5)), sun_lobe.HORIZON_MIN)
    q = g.math("DIVIDE", g.math("ADD", x, s), g.math("MULTIPLY", s, 2.0), clamp=True)
    soft = g.math("MAXIMUM", g.math("MULTIPLY", s, g.math("MULTIPLY", q, q)), x)
    return g.vmath("SCALE", color, scale=g.math("DIVIDE", soft, math.pi))


def _sun_highlight(g, sun, inp):
    """sun_lobe.highlight in nodes: E D(h) G2 / (4 (N.V)) (1 + b (1 - A) / A) of the sun for the
    SBRDF's Lobe View, Lobe Tangent and Lobe Alphas, b = sun_lobe.given_back(Specular Weight)."""
    direction, color, angle = sun
    n, view, tangent = inp["Diffuse Direction"], inp["Lobe View"], inp["Lobe Tangent"]
    bitangent = g.vmath("CROSS_PRODUCT", n, tangent)
    split = g.node("ShaderNodeSeparateXYZ")
    g.link(inp["Lobe Alphas"], split.inputs["Vector"])
    widening = g.math("MULTIPLY", g.math("MULTIPLY", angle, angle), sun_lobe.SIZE_WIDENING)
    a_t, a_b = (g.math("SQRT", g.math("ADD", g.math("POWER", g.math("MAXIMUM", split.outputs[axis],
                                                                    sun_lobe.MIN_ALPHA), 2.0), widening))
                for axis in (0, 1))
    half = g.vmath("NORMALIZE", g.vmath("ADD", direction, view))

    def squared(x):
        return g.math("MULTIPLY", x, x)
    stretched = g.math("ADD", g.math("ADD", squared(g.math("DIVIDE", g.vmath("DOT_PRODUCT", half, tangent), a_t)),
                                     squared(g.math("DIVIDE", g.vmath("DOT_PRODUCT", half, bitangent), a_b))),
                       squared(g.vmath("DOT_PRODUCT", half, n)))
    d = g.math("DIVIDE", 1.0, g.math("MULTIPLY", g.math("MULTIPLY", math.pi, g.math("MULTIPLY", a_t, a_b)),
                                     squared(stretched)))

    def smith(w):
        projected = g.math("ADD", squared(g.math("MULTIPLY", g.vmath("DOT_PRODUCT", w, tangent), a_t)),
                           squared(g.math("MULTIPLY", g.vmath("DOT_PRODUCT", w, bitangent), a_b)))
        ratio = g.math("DIVIDE", projected, g.math("MAXIMUM", squared(g.vmath("DOT_PRODUCT", w, n)), 1e-12))
        return g.math("MULTIPLY", g.math("SUBTRACT", g.math("SQRT", g.math("ADD", ratio, 1.0)), 1.0), 0.5)
    mu_v = g.vmath("DOT_PRODUCT", view, n)
    mu_l = g.vmath("DOT_PRODUCT", direction, n)
    masking = g.math("ADD", g.math("ADD", smith(view), smith(direction)), 1.0)
    # sun_lobe.albedo_roughness: the RMS alpha's roughness
    roughness = g.math("POWER", g.math("MULTIPLY", g.math("ADD", squared(split.outputs[0]), squared(split.outputs[1])),
                                       0.5), 0.25)
    denominator = g.math("MULTIPLY", g.math("MULTIPLY", masking, g.math("MAXIMUM", mu_v, 1e-4)), 4.0)
    above = g.math("MULTIPLY", g.math("GREATER_THAN", mu_v, 0.0), g.math("GREATER_THAN", mu_l, 0.0))
    # what single scattering loses, given back in full for a dielectric, F of it for a metal
    lost = g.math("SUBTRACT", g.math("DIVIDE", 1.0, _lobe_albedo(g, roughness, mu_v)), 1.0)
    weight = inp["Specular Weight"]
    low, high = sun_lobe.METAL_LIKE
    metal = g.math("MULTIPLY_ADD", g.vmath("DOT_PRODUCT", weight, (1 / 3, 1 / 3, 1 / 3)), 1.0 / (high - low),
                   -low / (high - low), clamp=True)
    given_back = g.mix("VECTOR", metal, (1.0, 1.0, 1.0), weight)
    regained = g.vmath("ADD", (1.0, 1.0, 1.0), g.vmath("SCALE", given_back, scale=lost))
    return g.vmath("MULTIPLY", g.vmath("SCALE", color, scale=g.math("MULTIPLY", above, g.math("DIVIDE", d, denominator))),
                   regained)


def _lobe_albedo(g, roughness, mu):
    """sun_lobe.albedo in nodes: each roughness row as a curve over mu, blended by tent weights."""
    knots = sun_lobe.ALBEDO_ROUGHNESS
    r = g.math("MINIMUM", g.math("MAXIMUM", roughness, knots[0]), knots[-1])
    mu = g.math("MINIMUM", g.math("MAXIMUM", mu, 0.0), 1.0)
    total = None
    for k, (knot, row) in enumerate(zip(knots, sun_lobe.ALBEDO)):
        weight = 1.0
        if k > 0:
            weight = g.math("DIVIDE", g.math("SUBTRACT", r, knots[k - 1]), knot - knots[k - 1])
        if k + 1 < len(knots):
            above = g.math("DIVIDE", g.math("SUBTRACT", knots[k + 1], r), knots[k + 1] - knot)
            weight = above if k == 0 else g.math("MINIMUM", weight, above)
        weight = g.math("MINIMUM", g.math("MAXIMUM", weight, 0.0), 1.0)
        term = g.math("MULTIPLY", weight, float_curve(g, sun_lobe.ALBEDO_MU, row, mu))
        total = term if total is None else g.math("ADD", total, term)
    return total


def build(tree, behind=False):
    """The group's nodes; ``behind``: the folder has the layer behind the first surface
    (distance.parallax_layers), read by the specular map's look-ups."""
    g = Graph(tree)
    gin, gout = io_nodes(g)
    inp = gin.outputs

    def env(map_name, direction):
        node = g.node("ShaderNodeTexEnvironment", interpolation="Linear")
        node["platelight_map"] = map_name
        g.link(direction, node.inputs["Vector"])
        return node.outputs["Color"]

    def reflected_env(map_name, direction):
        """A specular look-up: from the layer behind where the ray passed beside an occluder."""
        if behind_weight is None or map_name not in BEHIND_MAPS:
            return env(map_name, direction)
        return g.mix("VECTOR", behind_weight, env(map_name, direction), env(behind_name(map_name), direction))

    def blended(direction, weights, map_names=MAP_NAMES, read=env):
        total = None
        for name, weight in zip(map_names, weights):
            term = g.vmath("SCALE", read(name, direction), scale=weight)
            total = term if total is None else g.vmath("ADD", total, term)
        return total

    sun = _sun_nodes(g)
    switch = _named_value(g, names.DIFFUSE_PARALLAX_NODE, 0.0)
    # the maps without the sun, and the sun's kink at the terminator exact, not blurred between
    # their texels
    sunless = g.mix("VECTOR", switch, env(sun_lobe.sunless_name("diffuse"), inp["Diffuse Direction"]),
                    _irradiance_grid(g, inp["Diffuse Direction"]))
    irradiance = g.vmath("ADD", sunless, _sun_lambert(g, sun, inp["Diffuse Direction"]))
    diffuse = g.vmath("MULTIPLY", inp["Diffuse Weight"], irradiance)
    specular_direction, footprint, behind_weight = _parallax(g, inp["Specular Direction"], behind)
    # The maps are blurred as seen from the centre; a lobe meeting a surface near the shading
    # point covers less of it (docs/decisions.md, "Glossy footprint").
    roughness = float_curve(g, GLOSSINESS_KNOTS, ROUGHNESS_KNOTS,
                            _footprint_glossiness(g, inp["Map Glossiness"], footprint))
    view_on = _named_value(g, names.VIEW_LOBE_NODE, 0.0)
    specular_weights, view_spread = _view_lobe(g, inp, roughness, view_on)
    # An anisotropic lobe: the maps read along the streak (addon/ibl/anisotropy.py), the same
    # expression for every tap; a round lobe seen from an angle: along the plane of incidence
    # (addon/ibl/view_lobe.py).
    spread = g.vmath("ADD", inp["Specular Spread"], view_spread)
    streak = None
    for slope in TAP_SLOPES:
        tap = g.vmath("NORMALIZE", g.vmath("ADD", specular_direction, g.vmath("SCALE", spread, scale=slope)))
        term = blended(tap, specular_weights[1:], STREAK_MAPS, reflected_env)
        streak = term if streak is None else g.vmath("ADD", streak, term)
    streak = g.vmath("SCALE", streak, scale=1.0 / len(TAP_SLOPES))
    # The diffuse map, read once (a streak is far narrower than its lobe), without its sun.
    rough_map = env(sun_lobe.sunless_name("diffuse"), specular_direction)
    streak = g.vmath("ADD", streak, g.vmath("SCALE", rough_map, scale=specular_weights[0]))
    # The sun the sunless maps lack, through the lobe, for their share (view_lobe.sun_share).
    rungs = [specular_weights[view_lobe.LADDER.index(name)] for name in view_lobe.RUNGS]
    sun_share = g.math("ADD", specular_weights[0], g.math("ADD", g.math("ADD", rungs[0], rungs[1]), rungs[2]))
    streak = g.vmath("ADD", streak, g.vmath("SCALE", _sun_highlight(g, sun, inp), scale=sun_share))
    specular = g.vmath("MULTIPLY", inp["Specular Weight"], streak)
    refraction_weights = tent_weights(g, inp["Map Glossiness"])
    channels = []
    for index, channel in enumerate("RGB"):
        sep = g.node("ShaderNodeSeparateColor")
        g.link(blended(inp[f"Refraction Direction {channel}"], refraction_weights), sep.inputs["Color"])
        channels.append(sep.outputs[index])
    combine = g.node("ShaderNodeCombineColor")
    for index, socket in enumerate(channels):
        g.link(socket, combine.inputs[index])
    refraction = g.vmath("MULTIPLY", inp["Refraction Weight"], combine.outputs["Color"])
    lr = g.vmath("ADD", g.vmath("ADD", diffuse, specular),
                 g.vmath("ADD", refraction, inp["Emission"]))
    # Emission shows exactly Lr: the probe already holds the scene's light, so no BSDF here
    # (a BSDF would add the lamps' and world's light a second time).
    emit = g.node("ShaderNodeEmission")
    g.link(lr, emit.inputs["Color"])
    emit.inputs["Strength"].default_value = 1.0
    g.link(emit.outputs["Emission"], gout.inputs["Shader"])
    g.link(lr, gout.inputs["Lr"])
    g.link(diffuse, gout.inputs["Diffuse Term"])
    g.link(specular, gout.inputs["Specular Term"])
    g.link(refraction, gout.inputs["Refraction Term"])
    place_io(g, gin, gout)
