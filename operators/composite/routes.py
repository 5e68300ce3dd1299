"""The composite's routes (CATCHER, LAYERED, DIFFERENTIAL, BAKED, MIXED) as data, and the choice of one.

A Route says only what differs between the routes; setup.py builds any of them by reading its
fields. ``choose_route`` turns what was asked (method, engine) and what the scene holds (a shadow
bake, its currency, motion) into the route, the render engine and the sentences to report."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ... import compat
from ...addon import names
from ...addon.errors import PlateLightError
from ..eevee_check import NO_GL_SENTENCE, eevee_available

# Route.shadows: no Shadows layer, a shadow-catcher one, or one showing the baked shadows
NO_SHADOWS_LAYER, CATCHER_SHADOWS, BAKED_SHADOWS = "NONE", "CATCHER", "BAKED"


@dataclass(frozen=True)
class Route:
    name: str                       # the compositor tree's method and the report's word
    phantoms_catch: bool            # the phantoms are Cycles shadow catchers
    cg_catcher_pass: bool           # the CG layer renders the Shadow Catcher pass
    cg_holds_out_phantoms: bool     # the CG layer holds the phantoms out (they occlude the CG)
    filmed_phantoms: bool           # the CG's rays see the filmed plate, shadowed, on the phantoms
    layers: frozenset[str]          # the view layers it renders
    shadows: str                    # the Shadows layer: NO_SHADOWS_LAYER, CATCHER_SHADOWS or BAKED_SHADOWS
    cg_samples: bool                # CG Samples set the CG layer's samples
    adaptive: bool                  # adaptive sampling allowed: no two renders are differenced
    moving_shadows: bool = False    # a Shadow Catcher layer renders the moving CG's shadows every frame

    @property
    def local_scene(self) -> bool:
        """Debevec's local scene with and without the CG, in two layers of their own."""
        return names.LAYER_LOCAL in self.layers


ROUTES = {route.name: route for route in (
    Route("CATCHER", phantoms_catch=True, cg_catcher_pass=True, cg_holds_out_phantoms=False,
          filmed_phantoms=False, layers=frozenset({names.LAYER_CG}), shadows=NO_SHADOWS_LAYER,
          cg_samples=False, adaptive=True),
    Route("LAYERED", phantoms_catch=True, cg_catcher_pass=False, cg_holds_out_phantoms=True,
          filmed_phantoms=False, layers=frozenset({names.LAYER_CG, names.LAYER_SHADOWS}),
          shadows=CATCHER_SHADOWS, cg_samples=True, adaptive=True),
    # adaptive sampling stops each layer's pixels differently: With and Without would not cancel
    Route("DIFFERENTIAL", phantoms_catch=False, cg_catcher_pass=False, cg_holds_out_phantoms=True,
          filmed_phantoms=False, layers=frozenset({names.LAYER_CG, names.LAYER_LOCAL, names.LAYER_WITHOUT}),
          shadows=NO_SHADOWS_LAYER, cg_samples=False, adaptive=False),
    Route("BAKED", phantoms_catch=False, cg_catcher_pass=False, cg_holds_out_phantoms=True,
          filmed_phantoms=True, layers=frozenset({names.LAYER_CG, names.LAYER_SHADOWS}),
          shadows=BAKED_SHADOWS, cg_samples=True, adaptive=True),
    # BAKED for the CG that stands still, times a catcher's ratio of the moving CG's shadows; the
    # phantoms catch, so the baked layer reads its ratio from an AOV (a catcher renders transparent)
    Route("MIXED", phantoms_catch=True, cg_catcher_pass=False, cg_holds_out_phantoms=True,
          filmed_phantoms=True, layers=frozenset({names.LAYER_CG, names.LAYER_SHADOWS, names.LAYER_MOVING_SHADOWS}),
          shadows=BAKED_SHADOWS, cg_samples=True, adaptive=True, moving_shadows=True),
)}


@dataclass(frozen=True)
class Choice:
    route: Route
    engine: str                     # scene.render.engine
    reports: tuple[tuple[str, str], ...]   # (level, sentence), in the order to report them
    current: bool | None            # does the bake fit the scene (None: not hashed, or no bake)
    moving: frozenset[str] = frozenset()   # the CG whose shadows MIXED renders every frame


def choose_route(method: str, engine: str, *, baked: bool, motion_blur: bool,
                 motions: Callable[[], dict], is_current: Callable[[frozenset], bool | None],
                 phantom_names=frozenset(), moving_baked: Callable[[], bool] = lambda: False) -> Choice:
    """The route and engine for ``method`` (AUTO or a route's name) and ``engine`` (CYCLES or
    EEVEE), given whether the shot's shadows are ``baked`` and the scene's ``motion_blur``.
    ``motions`` ({name: Motion} of the CG and phantoms, ``phantom_names``, that move) and
    ``is_current`` (does the bake fit the scene, given the names of the CG that moves) are called
    only where a bake could be used: both walk the scene. A bake that left the moving CG out
    serves the still CG, the moving CG's shadows rendered by a catcher every frame (MIXED), or
    looked up as baked at every frame where ``moving_baked`` says so (BAKED). Raises
    PlateLightError, having changed nothing, where what was asked cannot be done."""
    if method == "BAKED" and not baked:
        raise PlateLightError("The Baked Shadows method needs the shot's shadows: run Bake "
                              "Shadows (platelight.bake_shadows) first.")
    if engine == "EEVEE" and motion_blur:
        raise PlateLightError("EEVEE's composite does not blur the shadows with the CG: turn "
                              "Motion Blur off (Render Properties) or use Cycles, which blurs both.")
    # a shadow baked once cannot follow what moves: asked only where a bake could be used
    moving = motions() if baked and method in ("AUTO", "BAKED") else {}
    first = next(iter(moving.values()), None)
    # a phantom that moves leaves no bake usable; moving CG, one baked without them
    bakeable = not any(name in phantom_names for name in moving)
    current = None
    if baked and bakeable and method in ("AUTO", "BAKED") and (moving or method == "AUTO"):
        current = is_current(frozenset(moving))
    if method == "BAKED" and moving:
        if not current:
            if not bakeable:                # a moving phantom: no bake can serve
                first = next(m for name, m in moving.items() if name in phantom_names)
            again = "bake the shadows again (the bake leaves what moves out) or " if bakeable else ""
            raise PlateLightError(f"{first.sentence()}, and the shadows baked with it cannot follow it: "
                                  f"{again}use the Automatic or Shadow Catcher method.")
        method = "BAKED" if moving_baked() else "MIXED"

    reports = []
    # a shadow looked up from a frame's panorama does not blur with the CG as the shutter sweeps it
    unblurred = bool(moving) and motion_blur and bool(current) and moving_baked()
    if unblurred:
        sentence = ("Motion Blur is on, and the shadows baked at each frame do not blur with the moving "
                    "CG: {}; Bake Shadows with Moving CG: Shadow Catcher keeps the still CG's baked and "
                    "blurs the moving CG's.")
        if method == "AUTO":
            reports.append(("WARNING", sentence.format("the Shadow Catcher renders them instead")))
            current = None
        else:
            reports.append(("WARNING", sentence.format("the moving CG's shadows stay sharp")))
    if method == "AUTO":
        method = ("BAKED" if not moving or moving_baked() else "MIXED") if current else "CATCHER"
        if moving and not current and not unblurred:     # (the blur's sentence said why)
            reports.append(("WARNING", f"{first.sentence()}: the Shadow Catcher renders the shadows "
                            "every frame instead of the baked ones."))
    if engine == "EEVEE":
        if not eevee_available():
            reports.append(("WARNING", NO_GL_SENTENCE))
            engine = "CYCLES"
        else:
            engine = compat.EEVEE
            # baked shadows are emission, which EEVEE renders exactly (docs/decisions.md); else three
            # layers (EEVEE has no shadow catcher for a moving CG's shadows either)
            if method == "BAKED" and not compat.EEVEE_MATERIAL_OVERRIDE:
                reports.append(("WARNING", "EEVEE in this Blender cannot show the baked shadows "
                                "(it ignores a view layer's material override): it renders its own "
                                "shadows in three layers instead; Cycles or Blender 5 show them."))
            if method != "BAKED" or not compat.EEVEE_MATERIAL_OVERRIDE:
                method = "DIFFERENTIAL"
    else:
        engine = "CYCLES"
    if current is False:
        # said once the engine is known: EEVEE's fallback is its three layers, not a catcher
        fallback = "EEVEE renders its own" if engine == compat.EEVEE else "the Shadow Catcher renders them"
        reports.append(("WARNING", "The baked shadows do not match the scene any more: "
                        f"{fallback} instead; run Bake Shadows again to use them."))
    route = ROUTES[method]
    return Choice(route, engine, tuple(reports), current,
                  frozenset(moving) if route.moving_shadows else frozenset())
