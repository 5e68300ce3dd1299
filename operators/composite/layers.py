"""The composite's collections and view layers: CG and phantoms each in a collection of their own,
so that every view layer can show, hide, hold out or make indirect-only either set."""
import bpy

from ...addon import names


def collection(scene, name):
    """The collection ``name`` (made if need be), linked to the scene."""
    coll = bpy.data.collections.get(name)
    if coll is None:
        coll = bpy.data.collections.new(name)
    if coll.name not in scene.collection.children:
        scene.collection.children.link(coll)
    return coll


def move_into(objects, coll):
    """Make ``coll`` the only collection of each object (so view layers can switch them)."""
    for ob in objects:
        if coll not in ob.users_collection:
            coll.objects.link(ob)
        for other in list(ob.users_collection):
            if other != coll:
                other.objects.unlink(ob)


def unlink_if_empty(scene, name):
    """Take our collection ``name`` out of the scene once a route no longer puts objects in it."""
    coll = bpy.data.collections.get(name)
    if coll is not None and not coll.all_objects and coll.name in scene.collection.children:
        scene.collection.children.unlink(coll)


def view_layer(scene, name):
    layer = scene.view_layers.get(name) or scene.view_layers.new(name)
    layer.use = True
    return layer


def _layer_collection(layer, coll):
    for child in layer.layer_collection.children:
        if child.collection == coll:
            return child
    raise RuntimeError(f"collection {coll.name} is not in view layer {layer.name}")


def configure_layer(layer, cg_coll, phantom_coll, cg_state, phantom_holdout, moving=None):
    """Show the CG collection in ``layer`` as ``cg_state`` ("visible", "indirect", "holdout" or
    "excluded") and the phantoms held out or not; ``moving``: (the moving CG's collection, its
    state), where the route keeps them apart."""
    for coll, state in [(cg_coll, cg_state)] + ([moving] if moving else []):
        cg = _layer_collection(layer, coll)
        cg.exclude = state == "excluded"
        if not cg.exclude:
            cg.indirect_only = state == "indirect"
            # EEVEE has no indirect-only: a held-out CG still casts its shadows there and the
            # pixels it covers are the CG layer's anyway (alpha 1)
            cg.holdout = state == "holdout"
    ph = _layer_collection(layer, phantom_coll)
    ph.exclude = False
    ph.holdout = phantom_holdout
    ph.indirect_only = False
    # the phantoms' plate material gives camera rays a holdout without shading itself there
    layer[names.HELD_OUT_PHANTOMS_KEY] = 1.0 if phantom_holdout else 0.0
    # other collections stay as they are: after the move they hold only lights, cameras,
    # empties and objects hidden from render, and the lights must keep lighting every layer


def configure_eevee(scene):
    """EEVEE's differential route: the world's sun becomes a shadow-casting light (EEVEE's sun
    extraction), shadows and ray tracing on, so phantoms get the CG's shadows."""
    scene.eevee.use_shadows = True
    scene.eevee.use_raytracing = True
    world = scene.world
    if world is not None:
        world.use_sun_shadow = True
        world.sun_threshold = min(world.sun_threshold, 10.0)
