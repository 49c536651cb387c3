"""What tools/blender/blender_box.py and blender_studio.py share: one-sided emission and Cycles
settings that drop its approximations, so that Cycles renders what a glTF file means
(docs/results/blender-cycles.md). Imported from those scripts inside Blender (needs `bpy`)."""
import time


def front_face_only(tree, strength_value, strength_socket):
    """glTF emission is one-sided (the front face); Cycles' emission shader emits from both faces.
    Feeds strength_value * (1 - Backfacing) into strength_socket; returns the multiply node."""
    geometry = tree.nodes.new("ShaderNodeNewGeometry")
    front = tree.nodes.new("ShaderNodeMath")
    front.operation = "SUBTRACT"
    front.inputs[0].default_value = 1.0
    tree.links.new(geometry.outputs["Backfacing"], front.inputs[1])
    strength = tree.nodes.new("ShaderNodeMath")
    strength.operation = "MULTIPLY"
    strength.inputs[1].default_value = strength_value
    tree.links.new(front.outputs[0], strength.inputs[0])
    tree.links.new(strength.outputs[0], strength_socket)
    return strength


def render_exact(scene, samples, seed, filepath):
    """Renders with Cycles without its approximations — no clamping, no light threshold, 64 bounces
    of every kind (pf's paths end by Russian roulette, not a depth limit), no denoising, no adaptive
    sampling, a one-pixel box filter (pf averages uniform samples inside each pixel) — to a linear
    32-bit EXR, and prints `cycles_cpu_seconds=<s>`, the process CPU time of the render call
    (bench/cycles_curve.py)."""
    import bpy  # Blender's own module, only inside Blender

    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = samples
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.sample_clamp_direct = 0.0
    cycles.sample_clamp_indirect = 0.0
    cycles.light_sampling_threshold = 0.0
    cycles.max_bounces = 64
    cycles.diffuse_bounces = 64
    cycles.glossy_bounces = 64
    cycles.transmission_bounces = 64
    cycles.transparent_max_bounces = 64
    cycles.min_light_bounces = 0
    cycles.caustics_reflective = True
    cycles.caustics_refractive = True
    cycles.blur_glossy = 0.0
    cycles.pixel_filter_type = "BOX"
    cycles.filter_width = 1.0
    cycles.seed = seed
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.exr_codec = "ZIP"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.filepath = filepath
    start = time.process_time()
    bpy.ops.render.render(write_still=True)
    print(f"cycles_cpu_seconds={time.process_time() - start:.3f}")
