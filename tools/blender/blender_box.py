"""Builds the `blender-box` scene in Blender, exports it as glTF 2.0 for pf, and renders Cycles'
reference image of the same scene (docs/results/blender-cycles.md).

Run through tools/blender/cycles_reference.sh (Blender 3.4, Debian's `blender` package):
    blender --background --factory-startup --python-exit-code 1 --python tools/blender/blender_box.py -- \
        OUT_DIR RESOLUTION SAMPLES VARIANT [SEED]

Writes OUT_DIR/blender-box.gltf (+ .bin) and OUT_DIR/cycles-<VARIANT>-<RESOLUTION>.exr (linear,
32-bit), and prints `cycles_cpu_seconds=<s>`, the process CPU time of the render call
(bench/cycles_curve.py). SEED (default 1, the references') is Cycles' sampling seed.

VARIANT `principled` renders the materials as Blender shows them (Cycles' Principled BSDF);
`lambert` replaces every non-emitting material by Cycles' Diffuse BSDF (Lambert) of the
base colour and the emitter by a pure Emission shader, which is what scenes/blender-box's
blender-box-lambert.json asks of pf: the two renderers then share the scattering model exactly
and differ only in light transport.

The room is built only from what glTF carries and pf reads (docs/gltf.md): Principled BSDF
materials (base colour, metallic, roughness, emission), smooth-shaded meshes and one perspective
camera. Two adjustments make Cycles render what the glTF file means, applied after the export so
they do not change the exported file:
  * glTF emission is one-sided (the front face); Cycles' emission shader emits from both faces,
    so the emitter's emission is multiplied by (1 - Backfacing) for the render;
  * Cycles' render settings drop its approximations: no clamping, no light threshold, 64 bounces
    of every kind (pf's paths end by Russian roulette, not a depth limit, in this scene's range),
    no denoising, no adaptive sampling, a one-pixel box filter (pf averages uniform samples
    inside each pixel), a black world (the exporter writes no world; pf's scene has no sky).
"""
import math
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cycles_setup  # noqa: E402 (tools/blender/cycles_setup.py, beside this script)

arguments = sys.argv[sys.argv.index("--") + 1:]
out_dir, resolution, samples, variant = arguments[:4]
resolution, samples = int(resolution), int(samples)
seed = int(arguments[4]) if len(arguments) > 4 else 1
if variant not in ("principled", "lambert"):
    sys.exit(f"blender_box.py: VARIANT must be principled or lambert, not {variant!r}")

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene


def principled(name, color, roughness=1.0, metallic=0.0, emission=None, strength=0.0):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    if emission is not None:
        bsdf.inputs["Emission"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
    return mat


def place(obj, material, smooth=False):
    obj.data.materials.append(material)
    if smooth:
        for polygon in obj.data.polygons:
            polygon.use_smooth = True
    return obj


white = principled("white", (0.8, 0.8, 0.8))
red = principled("red", (0.75, 0.08, 0.06))
green = principled("green", (0.1, 0.6, 0.12))
blue = principled("blue", (0.2, 0.25, 0.7), roughness=0.5)
gold = principled("gold", (0.95, 0.7, 0.35), roughness=0.35, metallic=1.0)
lamp = principled("lamp", (0.0, 0.0, 0.0), emission=(1.0, 0.92, 0.8), strength=12.0)

# A 2 x 2 x 2 room (Blender is Z-up: the floor at z = 0), open towards the camera at y = -1.
# A plane's normal is +Z before rotation; every wall faces the inside.
walls = [
    ((0, 0, 0), (0, 0, 0), white),  # floor
    ((0, 0, 2), (math.pi, 0, 0), white),  # ceiling
    ((0, 1, 1), (math.pi / 2, 0, 0), white),  # back wall
    ((-1, 0, 1), (0, math.pi / 2, 0), red),  # left wall
    ((1, 0, 1), (0, -math.pi / 2, 0), green),  # right wall
]
for location, rotation, material in walls:
    bpy.ops.mesh.primitive_plane_add(size=2, location=location, rotation=rotation)
    place(bpy.context.object, material)

# The light: a 0.6 x 0.6 panel just below the ceiling, facing down.
bpy.ops.mesh.primitive_plane_add(size=0.6, location=(0, 0.1, 1.985), rotation=(math.pi, 0, 0))
emitter = place(bpy.context.object, lamp)

bpy.ops.mesh.primitive_cube_add(size=0.6, location=(-0.4, 0.3, 0.3), rotation=(0, 0, math.radians(25)))
place(bpy.context.object, blue)
bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=0.35, location=(0.4, -0.1, 0.35))
place(bpy.context.object, gold, smooth=True)
bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=0.25, location=(-0.35, -0.45, 0.25))
place(bpy.context.object, white, smooth=True)

camera_data = bpy.data.cameras.new("camera")
camera_data.angle = math.radians(42)
camera = bpy.data.objects.new("camera", camera_data)
camera.location = (0, -3.2, 1.0)
camera.rotation_euler = (math.pi / 2, 0, 0)  # looks along +Y
scene.collection.objects.link(camera)
scene.camera = camera

scene.render.resolution_x = resolution
scene.render.resolution_y = resolution
scene.render.resolution_percentage = 100

bpy.ops.export_scene.gltf(filepath=f"{out_dir}/blender-box.gltf", export_format="GLTF_SEPARATE",
                          export_cameras=True, export_lights=True, export_apply=True, export_yup=True)


def lambert(material):
    """Replaces the material's Principled BSDF by a Diffuse BSDF (roughness 0: Lambert)."""
    tree = material.node_tree
    principled_node = tree.nodes["Principled BSDF"]
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = principled_node.inputs["Base Color"].default_value
    diffuse.inputs["Roughness"].default_value = 0.0
    tree.links.new(diffuse.outputs["BSDF"], tree.nodes["Material Output"].inputs["Surface"])


if variant == "lambert":
    for material in (white, red, green, blue, gold):
        lambert(material)

# One-sided emission for Cycles (see the module comment): the emitter's strength times
# (1 - Backfacing); in the lambert variant through an Emission shader without any reflection.
tree = lamp.node_tree
bsdf = tree.nodes["Principled BSDF"]
if variant == "lambert":
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = bsdf.inputs["Emission"].default_value
    tree.links.new(emission.outputs["Emission"], tree.nodes["Material Output"].inputs["Surface"])
    strength_input = emission.inputs["Strength"]
else:
    strength_input = bsdf.inputs["Emission Strength"]
cycles_setup.front_face_only(tree, bsdf.inputs["Emission Strength"].default_value, strength_input)

world = bpy.data.worlds.new("black")
world.use_nodes = False
world.color = (0.0, 0.0, 0.0)
scene.world = world

cycles_setup.render_exact(scene, samples, seed, f"{out_dir}/cycles-{variant}-{resolution}.exr")
