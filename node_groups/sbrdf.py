"""Builder of the shader node group "PlateLight SBRDF": the paper's extended SBRDF (Eq 1-7).

Shader group sockets cannot carry images, so the group does the *geometry* of Eq 1-7 (frame,
Lafortune peak, Fresnel, falloff, refraction) and hands lookup directions and weights to the
probe's own group ("PlateLight Probe <name>", node_groups/probe_maps.py), which samples the four
maps and outputs the shader. The material wires the two together (operators/material.py).

    R   = unit vector surface -> viewer, in the frame (T', B', N), T' = tangent rotated by theta
    p   = Cx (R.T') T' + Cy (R.B') B' + Cz (R.N) N        blended towards R by Retro-Reflection
    g   = max(0, N.p)                                     (clamped: a peak below the surface gets no light)
    f   = c (1 - clamp(R.N, 0, 1))^(1/phi - 1)            (phi clamped to >= 1e-4: finite at phi -> 0;
          c = Fresnel Peak, 1 in the paper: a rough surface's f stops short of 1 at grazing)
    rho_s' = rho_s + (1 - rho_s) f,  n' = n + (1 - n) f,  g' = g + (1 - g) f
    w   = lerp(1, g', P),  rho_d' = lerp(rho_d (1 - rho_s'), rho_d, P)      P = Paper Falloff
          (0, the default: no cosine, layered energy as Principled; 1: the paper's Eq 1, 7)
    d   = normalize(p/|p| + (1 - P) s(n', N.p/|p|) N)    the look-up tilted towards N at grazing
          views, where the surface's horizon cuts the lobe (addon/ibl/lobe_tilt.py); P = 1: p/|p|
    Anisotropy a (addon/ibl/anisotropy.py): n is first narrowed to the lobe's narrow axis, and
    the probe group reads the maps along d + x_k spread, spread = 2 w (1 - f) ((T'.R) N + (N.R) T'),
    w the slope width the narrow lobe lacks along T' (0 at a = 0: one look-up)
    Lr  = alpha rho_d' D(N) + rho_s' w S(d, n') + (1 - alpha) rho_d (1 - rho_s') T(t, n') + E
    The lobe the probe group shines the probe's sun through (addon/ibl/sun_lobe.py): GGX with the
    alphas r^2 / aspect, r^2 aspect of n's roughness with Fresnel's f, seen from the Lobe View
    reflect(p/|p|, N) (the view itself for the default C), along the rotated tangent T'.
"""
from __future__ import annotations

import bpy

from ..addon import names
from ..addon.ibl.anisotropy import ASPECT_SCALE
from ..addon.ibl.lobe_tilt import MU, TILT
from ..addon.ibl.maps import GLOSSINESS_KNOTS, MAP_NAMES, PULL_BELOW, ROUGHNESS_KNOTS
from ..addon.material.params import PARAMETERS
from ._build import VERSION_KEY, Graph, float_curve, io_nodes, place_io, shader_group, sync_interface, tent_weights

# Bump when the group's internals or interface change: older groups are rebuilt in place, and
# inputs added since keep existing materials' look (_default_new_inputs; version 1's falloff).
VERSION = 7
PHI_MIN = 1.0e-4

# The lookup outputs, consumed by name by every "PlateLight Probe" group.
LOOKUP_SOCKETS = (
    ("Diffuse Direction", "NodeSocketVector"),
    ("Specular Direction", "NodeSocketVector"),
    ("Specular Spread", "NodeSocketVector"),
    ("Map Glossiness", "NodeSocketFloat"),
    ("Lobe View", "NodeSocketVector"),
    ("Lobe Tangent", "NodeSocketVector"),
    ("Lobe Alphas", "NodeSocketVector"),
    ("Diffuse Weight", "NodeSocketColor"),
    ("Specular Weight", "NodeSocketColor"),
    ("Refraction Direction R", "NodeSocketVector"),
    ("Refraction Direction G", "NodeSocketVector"),
    ("Refraction Direction B", "NodeSocketVector"),
    ("Refraction Weight", "NodeSocketColor"),
    ("Emission", "NodeSocketColor"),
)
DEBUG_SOCKETS = (
    ("Fresnel", "NodeSocketFloat"),
    ("Falloff", "NodeSocketFloat"),
)


def _interface():
    sockets = []
    for name, socket_type in LOOKUP_SOCKETS + DEBUG_SOCKETS:
        sockets.append(("OUTPUT", name, socket_type, {}))
    for spec in PARAMETERS:
        if spec.kind == "color":
            options = {"default_value": (*spec.default, 1.0)}
            sockets.append(("INPUT", spec.label, "NodeSocketColor", options))
        else:
            options = {"default_value": spec.default, "min_value": spec.minimum,
                       "max_value": spec.maximum}
            sockets.append(("INPUT", spec.label, "NodeSocketFloat", options))
        sockets[-1][3]["description"] = spec.description
    sockets.append(("INPUT", "Normal", "NodeSocketVector",
                    {"hide_value": True, "default_value": (0.0, 0.0, 0.0),
                     "description": "Shading normal (e.g. from a Normal Map node); "
                                    "unconnected: the geometry normal"}))
    return sockets


def ensure_sbrdf_group():
    """Return the "PlateLight SBRDF" group, building it or upgrading an older version in place."""
    tree = shader_group(names.SBRDF_GROUP)
    if tree.get(VERSION_KEY) == VERSION and len(tree.nodes) > 2:
        return tree
    old_version = tree.get(VERSION_KEY) if len(tree.nodes) > 2 else None
    before = {item.name for item in tree.interface.items_tree if getattr(item, "in_out", None) == "INPUT"}
    sync_interface(tree, _interface())
    _default_new_inputs(tree, before)
    if old_version == 1:
        _keep_paper_falloff(tree)
    tree.nodes.clear()
    _build(tree)
    tree[VERSION_KEY] = VERSION
    return tree


def _instances(tree):
    for material in bpy.data.materials:
        if material.node_tree is None:
            continue
        for node in material.node_tree.nodes:
            if getattr(node, "node_tree", None) == tree:
                yield node


def _default_new_inputs(tree, before):
    """Inputs an upgrade adds start at 0 on existing nodes, not at the interface's default (a
    Fresnel Peak of 0 switched an old material's Fresnel off): give them the default."""
    added = [item for item in tree.interface.items_tree
             if getattr(item, "in_out", None) == "INPUT" and item.name not in before
             and hasattr(item, "default_value")]
    for node in _instances(tree):
        for item in added:
            if item.name in node.inputs:
                node.inputs[item.name].default_value = item.default_value


def _keep_paper_falloff(tree):
    """Materials made before the Paper Falloff input rendered with the paper's g': keep their look."""
    for node in _instances(tree):
        if "Paper Falloff" in node.inputs:
            node.inputs["Paper Falloff"].default_value = 1.0


def _build(tree):
    g = Graph(tree)
    gin, gout = io_nodes(g)
    geo = g.node("ShaderNodeNewGeometry")
    inp = gin.outputs

    # Shading normal: the Normal input when connected (non-zero), else the geometry normal.
    use_input = g.math("GREATER_THAN", g.vmath("LENGTH", inp["Normal"]), 0.5)
    n = g.vmath("NORMALIZE", g.mix("VECTOR", use_input, geo.outputs["Normal"], inp["Normal"]))
    r = g.vmath("NORMALIZE", geo.outputs["Incoming"])

    # Tangent frame: radial tangent around object Z, made orthogonal to N, then rotated by theta.
    t0 = g.node("ShaderNodeTangent", direction_type="RADIAL", axis="Z").outputs["Tangent"]
    t = g.vmath("NORMALIZE", g.vmath("SUBTRACT", t0,
                                     g.vmath("SCALE", n, scale=g.vmath("DOT_PRODUCT", t0, n))))
    b = g.vmath("CROSS_PRODUCT", n, t)
    theta = inp["Tangent Rotation"]
    t_rot = g.vmath("ADD", g.vmath("SCALE", t, scale=g.math("COSINE", theta)),
                    g.vmath("SCALE", b, scale=g.math("SINE", theta)))
    b_rot = g.vmath("CROSS_PRODUCT", n, t_rot)

    # Lafortune peak p = diag(C) R in the local frame, back in world space (Eq 2).
    rt = g.vmath("DOT_PRODUCT", r, t_rot)
    rb = g.vmath("DOT_PRODUCT", r, b_rot)
    rn = g.vmath("DOT_PRODUCT", r, n)
    peak = g.vmath("ADD", g.vmath("ADD",
                                  g.vmath("SCALE", t_rot, scale=g.math("MULTIPLY", inp["Cx"], rt)),
                                  g.vmath("SCALE", b_rot, scale=g.math("MULTIPLY", inp["Cy"], rb))),
                   g.vmath("SCALE", n, scale=g.math("MULTIPLY", inp["Cz"], rn)))
    peak = g.mix("VECTOR", inp["Retro-Reflection"], peak, r)
    falloff = g.math("MAXIMUM", g.vmath("DOT_PRODUCT", n, peak), 0.0)       # g (Eq 3)

    # Parameterised Fresnel f (Eq 4) and its effect on rho_s, n and g (Eq 5-7).
    cos_v = g.math("MINIMUM", g.math("MAXIMUM", rn, 0.0), 1.0)
    phi = g.math("MAXIMUM", inp["Fresnel Falloff"], PHI_MIN)
    exponent = g.math("SUBTRACT", g.math("DIVIDE", 1.0, phi), 1.0)
    fresnel = g.math("MULTIPLY", inp["Fresnel Peak"],
                     g.math("POWER", g.math("SUBTRACT", 1.0, cos_v), exponent))
    spec_albedo = g.mix("RGBA", fresnel, inp["Specular Albedo"], (1.0, 1.0, 1.0, 1.0))
    narrow, streak, alphas = _anisotropy(g, inp, fresnel)
    gloss = g.math("ADD", narrow, g.math("MULTIPLY", g.math("SUBTRACT", 1.0, narrow), fresnel))
    falloff_f = g.math("ADD", falloff, g.math("MULTIPLY", g.math("SUBTRACT", 1.0, falloff), fresnel))
    # The maps already hold the lobe's integral, so the paper's cosine g' darkens every rim; the
    # default leaves it out (docs/decisions.md, "Paper Falloff").
    falloff_f = g.math("MULTIPLY_ADD", inp["Paper Falloff"], g.math("SUBTRACT", falloff_f, 1.0), 1.0)

    # Weights of the terms.
    alpha = inp["Alpha"]
    one_minus_spec = g.color_op("SUBTRACT", (1.0, 1.0, 1.0, 1.0), spec_albedo)
    # Energy: by default light reflected by the specular layer does not reach the diffuse one
    # (rho_d (1 - rho_s'), as Blender's Principled BSDF layers them); the paper adds both in full.
    layered = g.color_op("MULTIPLY", inp["Diffuse Albedo"], one_minus_spec)
    diffuse_albedo = g.mix("RGBA", inp["Paper Falloff"], layered, inp["Diffuse Albedo"])
    diffuse_w = g.mix("RGBA", alpha, (0.0, 0.0, 0.0, 1.0), diffuse_albedo)
    specular_w = g.vmath("SCALE", spec_albedo, scale=falloff_f)   # g' may exceed 1 when Cz > 1
    refr_w = g.mix("RGBA", g.math("SUBTRACT", 1.0, alpha), (0.0, 0.0, 0.0, 1.0),
                   g.color_op("MULTIPLY", inp["Diffuse Albedo"], one_minus_spec))
    emission = g.vmath("SCALE", inp["Emission Color"], scale=inp["Emission Strength"])

    # Refraction at the front face, one IOR per channel (dispersion spreads them).
    incident = g.vmath("SCALE", r, scale=-1.0)
    for channel, sign in (("R", -1.0), ("G", 0.0), ("B", 1.0)):
        ior = g.math("MULTIPLY_ADD", inp["Dispersion"], sign, inp["IOR"])
        eta = g.math("DIVIDE", 1.0, g.math("MAXIMUM", ior, 1.0))
        refracted = g.vmath("REFRACT", incident, n, scale=eta)
        g.link(refracted, gout.inputs[f"Refraction Direction {channel}"])

    g.link(n, gout.inputs["Diffuse Direction"])
    lookup = g.vmath("NORMALIZE", peak)
    offset = g.math("MULTIPLY", _tilt_offset(g, gloss, g.vmath("DOT_PRODUCT", n, lookup)),
                    g.math("SUBTRACT", 1.0, inp["Paper Falloff"]))
    g.link(g.vmath("NORMALIZE", g.vmath("ADD", lookup, g.vmath("SCALE", n, scale=offset))),
           gout.inputs["Specular Direction"])
    # The streak narrows with the lobe as Fresnel moves it towards the mirror map.
    across = g.vmath("ADD", g.vmath("SCALE", n, scale=rt), g.vmath("SCALE", t_rot, scale=rn))
    spread_scale = g.math("MULTIPLY", g.math("MULTIPLY", streak, 2.0), g.math("SUBTRACT", 1.0, fresnel))
    g.link(g.vmath("SCALE", across, scale=spread_scale), gout.inputs["Specular Spread"])
    g.link(gloss, gout.inputs["Map Glossiness"])
    # The sun's lobe is seen from the direction whose mirror is the Lafortune peak.
    g.link(g.vmath("REFLECT", g.vmath("SCALE", lookup, scale=-1.0), n), gout.inputs["Lobe View"])
    g.link(t_rot, gout.inputs["Lobe Tangent"])
    g.link(alphas, gout.inputs["Lobe Alphas"])
    g.link(diffuse_w, gout.inputs["Diffuse Weight"])
    g.link(specular_w, gout.inputs["Specular Weight"])
    g.link(refr_w, gout.inputs["Refraction Weight"])
    g.link(emission, gout.inputs["Emission"])
    g.link(fresnel, gout.inputs["Fresnel"])
    g.link(falloff_f, gout.inputs["Falloff"])
    place_io(g, gin, gout)


def _anisotropy(g, inp, fresnel):
    """anisotropy.narrow_glossiness and streak_slope in nodes, and the GGX alphas of the lobe:
    the roughness of Fresnel's glossiness n + (1 - n) f, plus (1 - f) times what the peak's pull
    adds at glossiness 0 (maps.pulled_roughness): (narrow glossiness, slope width, (alpha_t, alpha_b, 0))."""
    glossiness = inp["Glossiness"]
    amount = g.math("MINIMUM", g.math("MAXIMUM", inp["Anisotropy"], 0.0), 1.0)
    aspect = g.math("SQRT", g.math("MULTIPLY_ADD", amount, -ASPECT_SCALE, 1.0))
    roughness = float_curve(g, GLOSSINESS_KNOTS, ROUGHNESS_KNOTS, glossiness)
    sharpened = g.math("ADD", glossiness, g.math("MULTIPLY", g.math("SUBTRACT", 1.0, glossiness), fresnel))
    widest = g.math("MAXIMUM", g.math("ABSOLUTE", inp["Cx"]), g.math("ABSOLUTE", inp["Cy"]))
    pull = g.math("MULTIPLY", g.math("SUBTRACT", 1.0, widest), g.math("LESS_THAN", glossiness, PULL_BELOW),
                  clamp=True)
    widened = g.math("MULTIPLY", g.math("MULTIPLY", pull, 1.0 - ROUGHNESS_KNOTS[0]), g.math("SUBTRACT", 1.0, fresnel))
    alpha = g.math("POWER", g.math("ADD", float_curve(g, GLOSSINESS_KNOTS, ROUGHNESS_KNOTS, sharpened), widened), 2.0)
    alphas = g.node("ShaderNodeCombineXYZ")
    g.link(g.math("DIVIDE", alpha, aspect), alphas.inputs["X"])
    g.link(g.math("MULTIPLY", alpha, aspect), alphas.inputs["Y"])
    narrow_roughness = g.math("MULTIPLY", roughness, g.math("SQRT", aspect))
    # a difference of one curve: anisotropy 0 gives back the glossiness exactly
    narrow = g.math("ADD", glossiness, g.math(
        "SUBTRACT", float_curve(g, ROUGHNESS_KNOTS[::-1], GLOSSINESS_KNOTS[::-1], narrow_roughness),
        float_curve(g, ROUGHNESS_KNOTS[::-1], GLOSSINESS_KNOTS[::-1], roughness)))
    width = g.math("SQRT", g.math("MAXIMUM", g.math("SUBTRACT", g.math("DIVIDE", 1.0, g.math(
        "MULTIPLY", aspect, aspect)), g.math("MULTIPLY", aspect, aspect)), 0.0))
    return narrow, g.math("MULTIPLY", g.math("MULTIPLY", roughness, roughness), width), alphas.outputs["Vector"]


def _tilt_offset(g, glossiness, mu):
    """lobe_tilt.tilt_offset in nodes: each map's row as a curve over mu = N.d, blended with the
    maps' tent weights at glossiness n'."""
    mu = g.math("MINIMUM", g.math("MAXIMUM", mu, 0.0), 1.0)
    total = None
    for name, weight in zip(MAP_NAMES, tent_weights(g, glossiness)):
        if not any(TILT[name]):
            continue
        term = g.math("MULTIPLY", weight, float_curve(g, MU, TILT[name], mu))
        total = term if total is None else g.math("ADD", total, term)
    return total
