"""Rough glass on a bevelled cube and a UV sphere: Blender 3.4's Cycles vs `glimmer render` (issue 16, item 8).

Scene (docs/blender.md, "Frosted glass / rough glass vs Cycles"): 64x64 pixels, uniform world 0.5, no lights, a
rotated 1.6 m cube with a 4-segment 0.15 m bevel (or a UV sphere), Glass BSDF (GGX, IOR 1.45), same samples,
box filter, no clamps, no filter glossy, all caustics on. Prints mean(glimmer) / mean(cycles) over the centre 32x32
pixels with its standard error. Extra glimmer renders of the same export use other plugin builds, named by
`--plugin LABEL=PATH[:ENV=VALUE]` (e.g. an experimental closure selected by an environment variable), so that all
figures come from one run.

    blender -b --factory-startup --python benchmarks/glass_cube_vs_cycles.py -- --glimmer build/glimmer \\
        [--samples 256] [--roughness 0.4,0.1] [--plugin label=path/libglimmer_closures.so:VAR=1]
"""
import argparse
import math
import os
import subprocess
import sys

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "tests", "addon"))
import addon_test_util as util  # noqa: E402
from scene_build_util import add_camera, load_pixels, material  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
parser = argparse.ArgumentParser()
parser.add_argument("--glimmer", default=os.environ.get("GLIMMER_EXECUTABLE", ""))
parser.add_argument("--out", default="/tmp/glass_cube_vs_cycles")
parser.add_argument("--samples", type=int, default=256)
parser.add_argument("--bounces", type=int, default=8)
parser.add_argument("--roughness", default="0.4,0.1")
parser.add_argument("--shapes", default="cube,sphere")
parser.add_argument("--plugin", action="append", default=[])
opts = parser.parse_args(argv)
glimmer = os.path.abspath(opts.glimmer)
os.environ["GLIMMER_EXECUTABLE"] = glimmer
os.makedirs(opts.out, exist_ok=True)
mod = util.enable_addon()
SIZE = 64


def build(shape, roughness):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    r = scene.render
    r.resolution_x = r.resolution_y = SIZE
    r.resolution_percentage = 100
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.threads_mode, r.threads = "FIXED", 2
    scene.view_settings.view_transform = "Standard"
    c = scene.cycles
    c.device, c.samples, c.use_adaptive_sampling, c.use_denoising, c.seed = "CPU", opts.samples, False, False, 1
    c.pixel_filter_type, c.filter_width = "BOX", 1.0
    c.sample_clamp_direct = c.sample_clamp_indirect = c.blur_glossy = 0.0
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = opts.bounces
    c.transparent_max_bounces = opts.bounces
    c.caustics_reflective = c.caustics_refractive = True
    g = scene.glimmer
    g.samples, g.threads, g.seed = opts.samples, 2, 1
    g.max_bounce = g.max_diffuse_bounce = g.max_glossy_bounce = g.max_transmission_bounce = opts.bounces
    g.transparent_max_bounce = opts.bounces
    g.filter_glossy = g.sample_clamp_direct = g.sample_clamp_indirect = 0.0
    g.filter_type, g.filter_width = "box", 1.0
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
    scene.world = world
    add_camera(scene, (0.0, -6.0, 0.0), (90.0, 0.0, 0.0))
    glass = material("Glass", "ShaderNodeBsdfGlass", distribution="GGX", Roughness=roughness, IOR=1.45)
    if shape == "cube":
        bpy.ops.mesh.primitive_cube_add(size=1.6, rotation=(math.radians(30), math.radians(20), math.radians(40)))
        bevel = bpy.context.active_object.modifiers.new("Bevel", "BEVEL")
        bevel.width, bevel.segments = 0.15, 4
        bpy.ops.object.shade_smooth()
    else:
        bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=64, ring_count=32)
        bpy.ops.object.shade_smooth()
    bpy.context.active_object.data.materials.append(glass)
    return scene


def glimmer_render(xml, exr, plugin=None, env=None):
    cmd = mod.runner.render_command(glimmer, xml, exr, opts.samples, 2, 1, SIZE, SIZE) + ["--quiet"]
    if plugin:
        cmd += ["--plugin", plugin]
    subprocess.run(cmd, check=True, env=dict(os.environ, **(env or {})))
    rgba = exr[:-4] + "_rgba.exr"
    subprocess.run(["oiiotool", exr, "--ch", "ViewLayer.Combined.R,ViewLayer.Combined.G,ViewLayer.Combined.B,"
                    "ViewLayer.Combined.A", "--chnames", "R,G,B,A", "-d", "float", "-o", rgba], check=True)
    return load_pixels(rgba)


def centre_ratio(a, b):
    q = SIZE // 4
    a, b = a[q:3 * q, q:3 * q].mean(axis=-1).ravel(), b[q:3 * q, q:3 * q].mean(axis=-1).ravel()
    sigma = np.std(a - b) / math.sqrt(a.size) / b.mean()
    return a.mean() / b.mean(), sigma, a.mean(), b.mean()


plugins = []
for spec in opts.plugin:
    label, rest = spec.split("=", 1)
    path, _, env = rest.partition(":")
    plugins.append((label, path, dict([env.split("=", 1)]) if env else {}))
for shape in opts.shapes.split(","):
    for roughness in (float(v) for v in opts.roughness.split(",")):
        name = "%s_r%.2f" % (shape, roughness)
        scene = build(shape, roughness)
        scene.render.engine = "CYCLES"
        bpy.ops.render.render()
        cycles_exr = os.path.join(opts.out, name + "_cycles.exr")
        bpy.data.images["Render Result"].save_render(cycles_exr, scene=scene)
        cyc = load_pixels(cycles_exr)
        xml, _ = mod.exporter.export_scene(bpy.context.evaluated_depsgraph_get(), os.path.join(opts.out, name))
        for label, plugin, env in [("glimmer", None, {})] + plugins:
            px = glimmer_render(xml, os.path.join(opts.out, "%s_%s.exr" % (name, label)), plugin, env)
            ratio, sigma, mg, mc = centre_ratio(px, cyc)
            print("%s roughness %.2f, %d spp, %d bounces: %s / cycles = %.4f +- %.4f (means %.4f / %.4f)"
                  % (shape, roughness, opts.samples, opts.bounces, label, ratio, sigma, mg, mc))
util.done("glass_cube_vs_cycles")
