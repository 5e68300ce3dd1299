"""Builder of "PlateLight Principled Conversion": principled_to_sbrdf() in shader nodes.

Converting a Principled material reads its socket values once, in numpy. Where a texture drives
an input (an albedo map, a roughness map), that value varies per pixel, so the conversion has to
run where the texture is sampled: this group takes the Principled inputs (named as on the
Principled BSDF) and gives the SBRDF parameters they change (principled.CHANGES), with the same
knots and clamps as addon/material/principled.py. The knot tables are Float Curves (Blender
evaluates them from 256-entry tables: within about 1e-3 of np.interp)."""
from __future__ import annotations

import math

from ..addon import names
from ..addon.ibl.maps import GLOSSINESS_KNOTS, ROUGHNESS_KNOTS
from ..addon.material import principled as pr
from ..addon.material.params import SPEC
from ._build import VERSION_KEY, Graph, float_curve, io_nodes, shader_group, sync_interface
from .principled_nodes import SOCKETS

VERSION = 2
OUTPUTS = tuple(name for name in SPEC if any(name in changed for changed in pr.CHANGES.values()))


def _interface():
    sockets = [("OUTPUT", SPEC[name].label,
                "NodeSocketColor" if SPEC[name].kind == "color" else "NodeSocketFloat", {})
               for name in OUTPUTS]
    defaults = pr.PrincipledValues()
    for field, socket in SOCKETS.items():
        value = getattr(defaults, field)
        kind = "NodeSocketColor" if field.endswith("color") else "NodeSocketFloat"
        sockets.append(("INPUT", socket, kind,
                        {"default_value": (*value, 1.0) if field.endswith("color") else value}))
    return sockets


def ensure_conversion_group():
    """Return the group, building it (or rebuilding an older version in place)."""
    tree = shader_group(names.PRINCIPLED_CONVERSION)
    if tree.get(VERSION_KEY) == VERSION and len(tree.nodes) > 2:
        return tree
    sync_interface(tree, _interface())
    tree.nodes.clear()
    _build(tree)
    tree[VERSION_KEY] = VERSION
    return tree


def _clamp(g, value, low=0.0, high=1.0):
    return g.math("MINIMUM", g.math("MAXIMUM", value, low), high)


def _clamp_colour(g, value):
    return g.vmath("MINIMUM", g.vmath("MAXIMUM", value, (0.0, 0.0, 0.0)), (1.0, 1.0, 1.0))


def _build(tree):
    g = Graph(tree)
    gin, gout = io_nodes(g)
    inp = {field: gin.outputs[socket] for field, socket in SOCKETS.items()}
    out = {name: gout.inputs[SPEC[name].label] for name in OUTPUTS}

    base = _clamp_colour(g, inp["base_color"])
    metal = _clamp(g, inp["metallic"])
    dielectric = g.math("SUBTRACT", 1.0, metal)
    rough = _clamp(g, inp["roughness"])
    ior = g.math("MAXIMUM", inp["ior"], 1.0)
    # F0 = ((ior - 1) / (ior + 1))^2 * 2 level, at most 1
    ratio = g.math("DIVIDE", g.math("SUBTRACT", ior, 1.0), g.math("ADD", ior, 1.0))
    f0 = g.math("MINIMUM", g.math("MULTIPLY", g.math("MULTIPLY", ratio, ratio),
                                  g.math("MULTIPLY", inp["specular_ior_level"], 2.0)), 1.0)

    def table(xs, ys):
        return float_curve(g, tuple(float(x) for x in xs), tuple(float(y) for y in ys), rough)

    exponent = g.mix("FLOAT", metal, table(pr.DIELECTRIC_ROUGHNESS, pr.DIELECTRIC_EXPONENT),
                     table(pr.FALLOFF_ROUGHNESS, pr.FALLOFF_EXPONENT))
    g.link(_clamp(g, g.math("DIVIDE", 1.0, g.math("ADD", exponent, 1.0))), out["fresnel_falloff"])
    peak = g.mix("FLOAT", metal, table(pr.DIELECTRIC_ROUGHNESS, pr.DIELECTRIC_PEAK),
                 table(pr.FALLOFF_ROUGHNESS, pr.FALLOFF_PEAK))
    g.link(_clamp(g, peak), out["fresnel_peak"])

    # specular = (1 - m) F0 E(1)/F0 + m base metal_head_on(base), metal_head_on linear in base:
    # white + (1 - white) / 21 + base (1 - white) 20 / 21
    lost = g.math("SUBTRACT", 1.0, table(pr.FALLOFF_ROUGHNESS, pr.WHITE_HEAD_ON))
    given_back = g.math("MULTIPLY", lost, 20.0 / 21.0)
    head_on = g.vmath("ADD", g.vmath("SCALE", base, scale=given_back), g.math("SUBTRACT", 1.0, given_back))
    metal_specular = g.vmath("SCALE", g.vmath("MULTIPLY", base, head_on), scale=metal)
    dielectric_specular = g.math("MULTIPLY", g.math("MULTIPLY", dielectric, f0),
                                 table(pr.DIELECTRIC_ROUGHNESS, pr.DIELECTRIC_HEAD_ON))
    specular = g.vmath("ADD", metal_specular, dielectric_specular)
    g.link(_clamp_colour(g, specular), out["specular_albedo"])
    g.link(g.vmath("SCALE", base, scale=dielectric), out["diffuse_albedo"])

    g.link(_clamp(g, float_curve(g, ROUGHNESS_KNOTS[::-1], GLOSSINESS_KNOTS[::-1], rough)),
           out["glossiness"])
    # the peak pulled to the normal beyond the diffuse map's roughness: C = -(1 - pull)
    knot = float(ROUGHNESS_KNOTS[0])
    pull = _clamp(g, g.math("DIVIDE", g.math("SUBTRACT", rough, knot), 1.0 - knot))
    lafortune = g.math("SUBTRACT", pull, 1.0)
    g.link(lafortune, out["cx"])
    g.link(lafortune, out["cy"])

    turns = inp["anisotropic_rotation"]
    fraction = g.math("SUBTRACT", turns, g.math("FLOOR", turns))     # Python's % 1.0
    g.link(g.math("MULTIPLY", fraction, 2.0 * math.pi), out["tangent_rotation"])
    g.link(_clamp(g, inp["anisotropic"]), out["anisotropy"])
    g.link(_clamp_colour(g, inp["emission_color"]), out["emission_color"])
    g.link(_clamp(g, inp["emission_strength"], 0.0, SPEC["emission_strength"].maximum),
           out["emission_strength"])
    opaque = g.math("SUBTRACT", 1.0, g.math("MULTIPLY", inp["transmission"], dielectric))
    g.link(_clamp(g, g.math("MULTIPLY", inp["alpha"], opaque)), out["alpha"])
    g.link(_clamp(g, ior, 1.0, SPEC["ior"].maximum), out["ior"])
