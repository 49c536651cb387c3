"""Builds the `blender-studio` scene in Blender, exports it as glTF 2.0 for pf, and renders Cycles'
image of the same scene (docs/results/blender-cycles.md, "Second scene").

Run through tools/blender/cycles_reference.sh (Blender 3.4, Debian's `blender` package):
    blender --background --factory-startup --python-exit-code 1 --python tools/blender/blender_studio.py -- \
        OUT_DIR WIDTH HEIGHT SAMPLES VARIANT OUTPUT.exr [SEED]

Writes OUT_DIR/blender-studio.gltf (+ .bin, floor.png), OUT_DIR/sky.hdr and OUTPUT.exr (linear,
32-bit), and prints `cycles_cpu_seconds=<s>`: the process CPU time of the render call, for the
equal-CPU comparison of bench/cycles_curve.py. SEED (default 1, the references') is Cycles'
sampling seed.

What the scene holds, in one frame: an image texture (the floor's checker, sRGB PNG), a rough
metal (copper, roughness 0.3), smooth glass (a sphere) and rough glass (a cube, roughness 0.3),
emissive geometry (a panel on the back wall), a spot lamp and an equirectangular HDR sky.

VARIANT `gltf` renders in Cycles the BSDF pf reads from the exported file (docs/renderer.md,
"Microfacet lobes"), so that the two renderers share the scattering model and differ only in light
transport:
  * a non-metal of base colour c and roughness r: Diffuse BSDF (Lambert) of 0.96 c plus Glossy BSDF
    (GGX, single scattering) of 0.04 and roughness r, which is pf's glTF mapping (Schlick's F capped
    at F90 = F0 = 0.04 for a non-metal);
  * a metal: Cycles' Principled BSDF with metallic 1 and the GGX distribution (its Fresnel rises to
    white by the dielectric curve of IOR 1.5 where pf's rises by Schlick's: a small difference
    confined to grazing angles);
  * glass: Cycles' Glass BSDF (GGX, IOR 1.5) of the exported roughness, white;
  * the emitter: a pure Emission shader, one-sided like glTF's.
VARIANT `principled` renders the Principled BSDFs as Blender shows them (emitter one-sided too).

The exporter writes no world: pf gets the same sky.hdr through the manifest (blender-studio.json).
The sky image's centre column is Blender's +X; pf's is its −Z, Blender's +Y (glTF is Y-up), so the
manifest turns pf's environment by −90° (docs/scene-manifest.md, "Environment object"). Texels are
looked up nearest (Cycles: Closest) as pf's environment does.
"""
import math
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cycles_setup  # noqa: E402 (tools/blender/cycles_setup.py, beside this script)

arguments = sys.argv[sys.argv.index("--") + 1:]
out_dir, width, height, samples, variant, output = arguments[:6]
width, height, samples = int(width), int(height), int(samples)
seed = int(arguments[6]) if len(arguments) > 6 else 1
if variant not in ("gltf", "principled"):
    sys.exit(f"blender_studio.py: VARIANT must be gltf or principled, not {variant!r}")

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene


def write_floor_texture(path):
    """A 64 x 64 checker of 8 x 8-pixel squares, an 8-bit sRGB PNG."""
    size, square = 64, 8
    light, dark = (0.8, 0.78, 0.72), (0.55, 0.25, 0.15)
    image = bpy.data.images.new("floor", size, size, alpha=False)
    pixels = []
    for y in range(size):
        for x in range(size):
            linear = light if ((x // square) + (y // square)) % 2 == 0 else dark
            pixels.extend((*linear, 1.0))
    image.pixels = pixels  # a byte image: these are the stored (sRGB-encoded) values
    image.filepath_raw = path
    image.file_format = "PNG"
    image.save()
    bpy.data.images.remove(image)
    return bpy.data.images.load(path)  # Cycles reads the file pf reads


def write_rgbe(path, width, height, rows):
    """A Radiance HDR of flat (not run-length encoded) RGBE scanlines, top row first. Blender's own
    image.save() would encode a float image for display (sRGB) first."""
    data = bytearray(f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {height} +X {width}\n".encode())
    for row in rows:
        for r, g, b in row:
            top = max(r, g, b)
            if top < 1e-32:
                data += bytes(4)
                continue
            mantissa, exponent = math.frexp(top)
            scale = mantissa * 256.0 / top
            data += bytes((int(r * scale), int(g * scale), int(b * scale), exponent + 128))
    with open(path, "wb") as f:
        f.write(data)


def write_sky(path):
    """A 128 x 64 equirectangular Radiance HDR: a blue gradient over a dim ground and a soft sun
    (a Gaussian of 5 degrees, peak 40) 35 degrees up, towards -X+Y in Blender's frame."""
    w, h = 128, 64
    sun_elevation, sun_azimuth, sun_sigma = math.radians(35), math.radians(135), math.radians(5)
    sun = (math.cos(sun_elevation) * math.cos(sun_azimuth), math.cos(sun_elevation) * math.sin(sun_azimuth),
           math.sin(sun_elevation))
    rows = []
    for row in range(h):  # the file's first row is the zenith
        elevation = math.pi / 2 - (row + 0.5) / h * math.pi
        pixels = []
        for column in range(w):
            # Cycles' equirectangular mapping: u = 0.5 - atan2(y, x) / (2 pi).
            azimuth = (0.5 - (column + 0.5) / w) * 2 * math.pi
            d = (math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
                 math.sin(elevation))
            if elevation > 0:
                t = math.sin(elevation)
                color = [(1 - t) * a + t * b for a, b in zip((0.9, 0.95, 1.1), (0.25, 0.45, 1.0))]
            else:
                color = [0.22, 0.2, 0.18]
            cos_angle = max(-1.0, min(1.0, sum(a * b for a, b in zip(d, sun))))
            glow = 40.0 * math.exp(-0.5 * (math.acos(cos_angle) / sun_sigma) ** 2)
            pixels.append([c + glow * s for c, s in zip(color, (1.0, 0.9, 0.75))])
        rows.append(pixels)
    write_rgbe(path, w, h, rows)
    # Cycles reads the file pf reads (8-bit mantissas included).
    image = bpy.data.images.load(path)
    image.colorspace_settings.name = "Linear"
    return image


floor_image = write_floor_texture(f"{out_dir}/floor.png")
sky_image = write_sky(f"{out_dir}/sky.hdr")


def principled(name, color, roughness=1.0, metallic=0.0, transmission=0.0, emission=None, strength=0.0,
               texture=None):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tree = mat.node_tree
    bsdf = tree.nodes["Principled BSDF"]
    bsdf.distribution = "GGX"
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Transmission"].default_value = transmission
    bsdf.inputs["IOR"].default_value = 1.5
    if emission is not None:
        bsdf.inputs["Emission"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
    if texture is not None:
        node = tree.nodes.new("ShaderNodeTexImage")
        node.image = texture
        # Closest: Cycles 3.4 filters an 8-bit sRGB image before decoding it (its floor renders 3 %
        # darker with Linear); pf decodes, then filters bilinearly, which keeps the area mean of
        # the nearest texels (docs/results/blender-cycles.md).
        node.interpolation = "Closest"
        node.extension = "REPEAT"
        tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def place(obj, material, smooth=False):
    obj.data.materials.append(material)
    if smooth:
        for polygon in obj.data.polygons:
            polygon.use_smooth = True
    return obj


floor = principled("floor", (1.0, 1.0, 1.0), roughness=0.6, texture=floor_image)
wall = principled("wall", (0.7, 0.7, 0.68), roughness=0.8)
copper = principled("copper", (0.95, 0.64, 0.54), roughness=0.3, metallic=1.0)
glass = principled("glass", (1.0, 1.0, 1.0), roughness=0.0, transmission=1.0)
frosted = principled("frosted", (1.0, 1.0, 1.0), roughness=0.3, transmission=1.0)
panel = principled("panel", (0.0, 0.0, 0.0), emission=(1.0, 0.55, 0.25), strength=8.0)

# Blender is Z-up: a 6 x 6 m floor at z = 0 (its UVs span the checker twice: 16 x 16 squares) and a
# back wall at y = 2 facing -Y; the rest is open to the sky.
bpy.ops.mesh.primitive_plane_add(size=6, location=(0, 0, 0))
floor_object = place(bpy.context.object, floor)
for loop_uv in floor_object.data.uv_layers.active.data:
    loop_uv.uv = (loop_uv.uv[0] * 2.0, loop_uv.uv[1] * 2.0)
bpy.ops.mesh.primitive_plane_add(size=1, location=(0, 2, 1.5), rotation=(math.pi / 2, 0, 0))
back = place(bpy.context.object, wall)
back.scale = (6, 3, 1)
# The emitting panel just in front of the wall, facing -Y.
bpy.ops.mesh.primitive_plane_add(size=1, location=(0.3, 1.98, 1.7), rotation=(math.pi / 2, 0, 0))
emitter = place(bpy.context.object, panel)
emitter.scale = (0.9, 0.35, 1)

bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=0.45, location=(-1.0, 0.6, 0.45))
place(bpy.context.object, copper, smooth=True)
bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=0.4, location=(0.15, -0.3, 0.4))
place(bpy.context.object, glass, smooth=True)
bpy.ops.mesh.primitive_cube_add(size=0.6, location=(1.1, 0.7, 0.3), rotation=(0, 0, math.radians(30)))
place(bpy.context.object, frosted)

# The spot lamp: a point lamp (no radius: glTF's punctual light) with a hard 36-degree cone aimed
# at the copper sphere's side of the floor, away from the smooth glass (a point lamp seen through
# smooth glass is a path no path tracer samples: Cycles would render no caustic where pf's photon
# map does).
spot_data = bpy.data.lights.new("spot", type="SPOT")
spot_data.energy = 300.0
spot_data.color = (1.0, 0.95, 0.85)
spot_data.spot_size = math.radians(36)
spot_data.spot_blend = 0.0
spot_data.shadow_soft_size = 0.0
spot = bpy.data.objects.new("spot", spot_data)
spot.location = (-1.8, -0.6, 3.2)
target = (-1.1, 1.0, 0.0)
direction = [t - s for t, s in zip(target, spot.location)]
# A lamp shines along its local -Z: turn -Z onto `direction`.
spot.rotation_euler = (0, 0, 0)
spot.rotation_mode = "QUATERNION"
from mathutils import Vector  # noqa: E402 (Blender's own module, only inside Blender)

spot.rotation_quaternion = Vector((0, 0, -1)).rotation_difference(Vector(direction).normalized())
scene.collection.objects.link(spot)

camera_data = bpy.data.cameras.new("camera")
camera_data.sensor_fit = "VERTICAL"
camera_data.angle_y = math.radians(40)
camera = bpy.data.objects.new("camera", camera_data)
camera.location = (0, -4.6, 1.4)
camera.rotation_euler = (math.radians(80), 0, 0)
scene.collection.objects.link(camera)
scene.camera = camera

scene.render.resolution_x = width
scene.render.resolution_y = height
scene.render.resolution_percentage = 100

bpy.ops.export_scene.gltf(filepath=f"{out_dir}/blender-studio.gltf", export_format="GLTF_SEPARATE",
                          export_cameras=True, export_lights=True, export_apply=True, export_yup=True)


def gltf_dielectric(material):
    """pf's glTF mapping of a non-metal: Lambert of 0.96 x base colour plus GGX of 0.04."""
    tree = material.node_tree
    bsdf = tree.nodes["Principled BSDF"]
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Roughness"].default_value = 0.0
    color_links = [link for link in tree.links if link.to_socket == bsdf.inputs["Base Color"]]
    scale = tree.nodes.new("ShaderNodeMixRGB")
    scale.blend_type = "MULTIPLY"
    scale.inputs["Fac"].default_value = 1.0
    scale.inputs["Color2"].default_value = (0.96, 0.96, 0.96, 1.0)
    if color_links:
        tree.links.new(color_links[0].from_socket, scale.inputs["Color1"])
    else:
        scale.inputs["Color1"].default_value = bsdf.inputs["Base Color"].default_value
    tree.links.new(scale.outputs["Color"], diffuse.inputs["Color"])
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
    glossy.distribution = "GGX"
    glossy.inputs["Color"].default_value = (0.04, 0.04, 0.04, 1.0)
    glossy.inputs["Roughness"].default_value = bsdf.inputs["Roughness"].default_value
    add = tree.nodes.new("ShaderNodeAddShader")
    tree.links.new(diffuse.outputs["BSDF"], add.inputs[0])
    tree.links.new(glossy.outputs["BSDF"], add.inputs[1])
    tree.links.new(add.outputs["Shader"], tree.nodes["Material Output"].inputs["Surface"])


def gltf_glass(material):
    tree = material.node_tree
    bsdf = tree.nodes["Principled BSDF"]
    glass_node = tree.nodes.new("ShaderNodeBsdfGlass")
    roughness = bsdf.inputs["Roughness"].default_value
    glass_node.distribution = "MULTI_GGX" if roughness > 0 else "SHARP"
    glass_node.inputs["Color"].default_value = bsdf.inputs["Base Color"].default_value
    glass_node.inputs["Roughness"].default_value = roughness
    glass_node.inputs["IOR"].default_value = bsdf.inputs["IOR"].default_value
    tree.links.new(glass_node.outputs["BSDF"], tree.nodes["Material Output"].inputs["Surface"])


if variant == "gltf":
    for material in (floor, wall):
        gltf_dielectric(material)
    for material in (glass, frosted):
        gltf_glass(material)

# One-sided emission: an Emission shader of the panel's colour times strength times (1 - Backfacing).
tree = panel.node_tree
bsdf = tree.nodes["Principled BSDF"]
emission = tree.nodes.new("ShaderNodeEmission")
emission.inputs["Color"].default_value = bsdf.inputs["Emission"].default_value
strength = cycles_setup.front_face_only(tree, bsdf.inputs["Emission Strength"].default_value,
                                        emission.inputs["Strength"])
tree.links.new(emission.outputs["Emission"], tree.nodes["Material Output"].inputs["Surface"])

world = bpy.data.worlds.new("sky")
world.use_nodes = True
environment = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
environment.image = sky_image
environment.interpolation = "Closest"
environment.projection = "EQUIRECTANGULAR"
world.node_tree.links.new(environment.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
scene.world = world

world.cycles.sampling_method = "AUTOMATIC"
# A diagnostic: PF_STUDIO_LIGHTS=sky,spot,panel (the default) names the lights Cycles renders; the
# export above always has them all.
lights = os.environ.get("PF_STUDIO_LIGHTS", "sky,spot,panel").split(",")
if "sky" not in lights:
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
if "spot" not in lights:
    spot.hide_render = True
if "panel" not in lights:
    strength.inputs[1].default_value = 0.0
cycles_setup.render_exact(scene, samples, seed, output)
