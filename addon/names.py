"""Every "PlateLight …" name PlateLight gives to a Blender datablock or node, written once.

Scripts and outside checks find things by these names (the node groups are part of design.md's
scripting contract), so a name changed here changes it everywhere and nowhere else."""

# --- shader node groups and the material's nodes (node_groups/sbrdf*.py, probe_maps.py)
SBRDF_GROUP = "PlateLight SBRDF"            # the paper's SBRDF (Eq 1-7); also the node's name
PROBE_GROUP_PREFIX = "PlateLight Probe "    # + probe folder: the group sampling its four maps
# The probe group's nodes as built once per Blender session (the dot hides it; no users: never saved)
PROBE_GROUP_TEMPLATE = ".PlateLight Probe Template"
PROBE_NODE = "PlateLight Probe"             # the material's node holding that group
PROBE_CENTRE_NODE = "PlateLight Probe Centre"   # in a probe group: the bake's centre (parallax)
PARALLAX_NODE = "PlateLight Parallax"       # in a probe group: 1 = parallax-corrected look-ups
DIFFUSE_PARALLAX_NODE = "PlateLight Diffuse Parallax"   # in a probe group: 1 = irradiance grid
SUN_DIRECTION_NODE = "PlateLight Sun Direction"   # in a probe group: the sun shaded through the lobe...
SUN_COLOR_NODE = "PlateLight Sun Irradiance"    # ... its rgb (0: no sun) ...
SUN_ANGLE_NODE = "PlateLight Sun Angle"         # ... and its angular diameter (radians)
VIEW_LOBE_NODE = "PlateLight View Lobe"   # in a probe group: 1 = the view-dependent ladder's look-ups
GRID_LO_NODE = "PlateLight Grid Low Corner"  # in a probe group: the irradiance grid's box...
GRID_SCALE_NODE = "PlateLight Grid Scale"    # ... 1 / its size per axis (0 on a flat axis)
GRID_POINTS_NODE = "PlateLight Grid Points"  # ... points per axis
GRID_HEIGHT_NODE = "PlateLight Grid Height"  # ... height of each map in the atlas
PRINCIPLED_CONVERSION = "PlateLight Principled Conversion"   # textured inputs -> SBRDF; also its node
TWIN_NODE = "PlateLight Principled Twin"    # in an SBRDF material: what non-camera rays meet
RAY_SPLIT_NODE = "PlateLight Ray Split"     # max(Is Camera Ray x Camera Sees SBRDF, Emission For All Rays)
RAY_CAMERA_NODE = "PlateLight Camera Sees SBRDF"    # Is Camera Ray x (1: the SBRDF, 0: the twin)
RAY_MIX_NODE = "PlateLight Ray Mix"
LIGHT_PATH_NODE = "PlateLight Light Path"
PROBE_DISTANCE = "PlateLight Probe Distance"    # the bake's temporary distance material
PROBE_DISTANCE_BEHIND = "PlateLight Probe Distance Behind"   # ... its peeled copy (behind_render.py)
UNBAKED_MAP = "PlateLight Unbaked Map"   # 1x1 black stand-in for a map not baked yet

# --- compositing (node_groups/composite.py, node_groups/compositor_tree.py)
DIFFERENTIAL_GROUP = "PlateLight Differential"   # the compositor group; also the node's name
COMPOSITOR_TREE = "PlateLight Composite"
PASSES_NODE = "PlateLight Passes"           # File Output node of the CG, Shadows and Plate passes
PASS_FILES_NODE = "PlateLight Pass Files"   # File Output node behind render --format multilayer
CG_COLLECTION = "PlateLight CG"
PHANTOM_COLLECTION = "PlateLight Phantoms"
MOVING_CG_COLLECTION = "PlateLight Moving CG"   # the baked route's CG that moves: shadows every frame
LAYER_CG = "PlateLight CG"                  # view layers of the differential method
LAYER_LOCAL = "PlateLight Local"
LAYER_WITHOUT = "PlateLight Local Without"
LAYER_SHADOWS = "PlateLight Shadows"        # the layered catcher's shadow layer (and the baked one)
LAYER_MOVING_SHADOWS = "PlateLight Moving Shadows"   # the baked route's per-frame catcher of the moving CG
BAKED_SHADOW_MATERIAL = "PlateLight Baked Shadows"   # that layer's override in the baked method
BAKED_RATIO_AOV = "platelight_baked_ratio"   # ... which also writes its ratio to this AOV
BAKED_RATIO_GROUP = "PlateLight Baked Ratio"   # the baked shadow ratio at a point (its material, the filmed phantoms)
SHADOWS_FOLDER = "_shadows"                 # in the maps folder: the shot's baked shadow panorama
SHADOW_BAKE_LAYER = "PlateLight Shadow Bake"   # the shadow bake's temporary view layer
PASS_DENOISE = "PlateLight Pass Denoise"   # the temporary scene (and 5.x compositor group) that denoises one pass

# --- footage and grain (operators/plate.py, operators/grain.py)
PLATE_IMAGE = "PlateLight Plate"
GRAIN_IMAGE = "PlateLight Grain"
BALL_CANDIDATES_IMAGE = "PlateLight Ball Candidates"   # the ball photo with the finder's circles drawn
GRAIN_NODE = "PlateLight Grain"

# --- lens distortion and phantoms (operators/lens.py, node_groups/redistortion.py, phantom_plate.py)
PLATE_CLIP = "PlateLight Plate"             # the plate's Movie Clip, carrying the calibrated lens
LENS_STMAP_IMAGE = "PlateLight Lens ST-Map"  # plate pixel -> where the undistorted render shows it
PLATE_UNDISTORTED_IMAGE = "PlateLight Plate Undistorted"   # the camera's background image
REDISTORT_NODE = "PlateLight Redistort"     # label of the Map UV nodes after the render layers
PHANTOM_PLATE_MATERIAL = "PlateLight Phantom Plate"
PHANTOM_ALBEDO_IMAGE = "PlateLight Phantom Albedo"   # plate / phantoms rendered white
PHANTOM_WHITE_MATERIAL = "PlateLight Phantom White"  # the white override of that render
PHANTOM_RADIANCE_IMAGE = "PlateLight Phantom Radiance"   # the plate where the camera saw a phantom (A: its distance)

# --- lights, tracking, world probe, bake
LIGHTS_COLLECTION = "PlateLight Lights"
LIGHT_PREFIX = "PlateLight"                # + " Sun" / " Sky 00": the lamps made from the probe
TRACK_CAMERA = "PlateLight Camera"
MARKER_PLANE = "PlateLight Marker Plane"
WORLD = "PlateLight World"
WORLD_PROBE_NODE = "PlateLight Probe"      # the world's Environment Texture node
PROBE_CAMERA = "PlateLight Probe Camera"   # the bake's temporary panoramic camera
PACKED_MAP_PREFIX = "PlateLight "          # + <probe folder>/<map file>: a map packed in the .blend

# --- the material presets preview (node_groups/sbrdf_preview.py)
PRESETS_SCENE = "PlateLight Presets"
PRESETS_CAMERA = "PlateLight Presets Camera"

# --- custom properties PlateLight stores on datablocks
PLATE_FRAME_OFFSET_KEY = "platelight_frame_offset"   # on the plate image: file frame = scene frame + this
LENS_KEY = "platelight_lens"   # on the scene: the calibrated lens {fx, fy, cx, cy, dist, width, height}
KEPT_MATERIALS_KEY = "platelight_kept_materials"   # on a phantom: object-linked materials to give back
# on a plate-surfaced phantom: its albedo (R, G, B, 1) where the plate's camera did not see it
HIDDEN_ALBEDO_KEY = "platelight_hidden_albedo"
# on a plate-surfaced phantom: the mean albedo (R, G, B) of what the plate's camera saw of it
MEAN_ALBEDO_KEY = "platelight_mean_albedo"
# on a view layer: 1 where the phantoms show the CG's rays the filmed plate times the baked shadows
FILMED_PHANTOMS_KEY = "platelight_filmed_phantoms"
# on a view layer: 1 where it holds the phantoms out (the camera sees the plate through them there)
HELD_OUT_PHANTOMS_KEY = "platelight_phantoms_held_out"
# the view-layer switches of the phantoms' plate material, off in every bake's render
PHANTOM_LAYER_KEYS = (FILMED_PHANTOMS_KEY, HELD_OUT_PHANTOMS_KEY)
GRAIN_SETTINGS_KEY = "platelight_grain"   # on the grain image: {"amount", "level", "response"} measured
