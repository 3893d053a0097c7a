"""A render through the engine equals the CLI render of the exported XML.

Skipped (exit 77) only while the `glimmer` executable has no `render`
sub-command; it runs as soon as the renderer lands."""
import os
import subprocess
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
mod, glimmer = util.enable_addon_with_renderer()

schema, origin, _ = mod.current_schema()
dso_closures = {c["name"] for c in schema["closures"] if c.get("source") == "dso"}

scene = util.empty_exr_scene(48, 32)
scene.glimmer.samples = 8
scene.glimmer.threads = 2
scene.glimmer.seed = 5

util.add_camera(scene, (0.0, -6.0, 2.0), (1.35, 0.0, 0.0))
util.set_world_color(scene, (0.3, 0.35, 0.4))
util.add_light(scene, "POINT", 800.0, (2.0, -2.0, 4.0))

bpy.ops.mesh.primitive_plane_add(size=10.0)
floor = bpy.data.materials.new("Floor")
floor.use_nodes = True
floor.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.6, 0.6, 0.6, 1.0)
bpy.context.active_object.data.materials.append(floor)

bpy.ops.mesh.primitive_uv_sphere_add(location=(0.0, 0.0, 1.0))
bpy.ops.object.shade_smooth()
sphere_mat = bpy.data.materials.new("Sphere")
sphere_mat.use_nodes = True
tree = sphere_mat.node_tree
out = tree.nodes["Material Output"]
if "glint" in dso_closures:  # the glint closure once the DSO lists it, else a glossy BSDF
    bsdf = tree.nodes.new("GlimmerNodeGlintBsdf")
else:
    bsdf = tree.nodes.new("ShaderNodeBsdfGlossy")
tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
bpy.context.active_object.data.materials.append(sphere_mat)

# 1. Through the engine.
engine_exr = os.path.join(opts.out, "render_engine.exr")
bpy.ops.render.render()
bpy.data.images["Render Result"].save_render(engine_exr, scene=scene)

# 2. The exported XML through the CLI with the same settings.
export_dir = os.path.join(opts.out, "render_export")
xml, _ = mod.exporter.export_scene(bpy.context.evaluated_depsgraph_get(), export_dir)
cli_exr = os.path.join(opts.out, "render_cli.exr")
cmd = mod.runner.render_command(glimmer, xml, cli_exr, 8, 2, 5, 48, 32)
proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
print(proc.stdout.decode(errors="replace")[-2000:])
check(proc.returncode == 0, "CLI render exit code %d" % proc.returncode)

# Both as RGBA arrays (the CLI's multilayer EXR through the engine's own loader code path is what we test
# against, so read it independently with oiiotool).
channels = mod.engine.exr_channels(cli_exr)
combined = [c for c in channels if ".Combined." in c]
order = ["%s.Combined.%s" % (combined[0].split(".Combined.")[0], c) for c in "RGBA"] if combined else list("RGBA")
cli_rgba = os.path.join(opts.out, "render_cli_rgba.exr")
subprocess.run(["oiiotool", cli_exr, "--ch", ",".join(order), "--chnames", "R,G,B,A", "-d", "float", "-o",
                cli_rgba], check=True)


def pixels(path):
    img = bpy.data.images.load(path)
    px = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px


a, b = pixels(engine_exr), pixels(cli_rgba)
check(a.shape == b.shape == (32, 48, 4), "image sizes %s %s" % (a.shape, b.shape))
diff = np.abs(a - b).max()
print("engine vs CLI: max abs difference %.3g, mean %.4f" % (diff, a[..., :3].mean()))
check(a[..., :3].mean() > 0.01, "the render is not black")
check(diff <= 1e-6, "engine render equals the CLI render of the exported XML (max diff %g)" % diff)

# The Albedo, Normal and Depth passes reach Blender's render result (its Denoise node reads Albedo and Normal).
scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
engine_layers = os.path.join(opts.out, "render_engine_layers.exr")
bpy.data.images["Render Result"].save_render(engine_layers, scene=scene)
layer = combined[0].split(".Combined.")[0]


def pass_pixels(path, file_layer, pass_name, chans):
    out = os.path.join(opts.out, "pass_%s_%d.exr" % (pass_name, abs(hash(path))))
    names = ["%s.%s.%s" % (file_layer, pass_name, c) for c in chans]
    subprocess.run(["oiiotool", path, "--ch", ",".join(names + ["0"] * (3 - len(chans)) + ["1"]),
                    "--chnames", "R,G,B,A", "-d", "float", "-o", out], check=True)
    return pixels(out)[..., :len(chans)]


view_layer = bpy.context.view_layer.name
for pass_name, chans in (("Albedo", "RGB"), ("Normal", "XYZ"), ("Depth", "Z")):
    check(any(c.startswith("%s.%s." % (view_layer, pass_name)) for c in mod.engine.exr_channels(engine_layers)),
          "%s pass in Blender's result" % pass_name)
    ours, theirs = pass_pixels(engine_layers, view_layer, pass_name, chans), pass_pixels(cli_exr, layer, pass_name,
                                                                                          chans)
    pass_diff = np.abs(ours - theirs).max()
    print("%s pass: engine vs CLI max difference %.3g (range %.3g..%.3g)" % (pass_name, pass_diff, theirs.min(),
                                                                            theirs.max()))
    check(theirs.max() > theirs.min(), "%s pass has content" % pass_name)
    check(pass_diff == 0.0, "%s pass equals the CLI's (a copy of the same floats)" % pass_name)
util.done("test_render")
