"""The Frosted Glass BSDF node renders with the `frosted_glass` closure in Glimmer
(method path / sg / auto chosen on the node), and its inner node group keeps a
Cycles Glass BSDF fallback that Cycles renders (issue 12, Blender line).

Scene: a frosted sphere (roughness 0.3, IOR 1.5) in front of an emissive
checker wall under a dim world. Checked:
- the exporter writes `frosted_glass_bsdf` with the node's method, roughness and IOR;
- a Glimmer render through the engine equals the CLI render of the XML the engine
  exported (sg: the method reaches the renderer), the engine's scene.xml equals the
  exporter's, and sg's image differs from path's. The CLI renders the engine's own
  export, not a second export: Blender's vertex normals of one mesh differ by up to
  one ulp between two evaluations (measured: 548 of 24192 normal components,
  <= 6e-8), which moved up to 4 % of the pixels by <= 3e-6 and made the comparison
  fail in 2 of 8 runs under load (docs/blender.md "Meshes");
- on the sphere the means agree: sg vs path within 15 % (sg's measured bias on a
  frosted sphere is 4 %, docs/frosted_glass.md), Cycles' fallback (Glass BSDF,
  GGX) vs Glimmer's path within 10 %; the wall's light does pass (the sphere is
  far brighter than a black glass would be, and darker than the wall).
"""
import math
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
mod, glimmer = util.enable_addon_with_renderer()

schema, _, _ = mod.current_schema()
if mod.schema.closure(schema, "frosted_glass").get("source") != "dso":
    util.skip("the plugin does not list frosted_glass")

W, H, SPP = 48, 32, 64
scene = util.empty_exr_scene(W, H)
scene.glimmer.samples = SPP
scene.glimmer.threads = 2
scene.glimmer.seed = 3
scene.glimmer.export_dir = os.path.join(opts.out, "engine_export")  # the engine keeps what it rendered
util.add_camera(scene, (0.0, -5.0, 0.0), (math.pi / 2, 0.0, 0.0))
util.set_world_color(scene, (0.05, 0.05, 0.05))

# The emissive checker wall behind the sphere, facing the camera.
bpy.ops.mesh.primitive_plane_add(size=12.0, location=(0.0, 3.0, 0.0), rotation=(math.pi / 2, 0.0, 0.0))
wall = bpy.data.materials.new("Wall")
wall.use_nodes = True
nodes, links = wall.node_tree.nodes, wall.node_tree.links
nodes.remove(nodes["Principled BSDF"])
emission = nodes.new("ShaderNodeEmission")
emission.inputs["Strength"].default_value = 2.0
checker = nodes.new("ShaderNodeTexChecker")
checker.inputs["Scale"].default_value = 6.0
checker.inputs["Color1"].default_value = (1.0, 0.9, 0.7, 1.0)
checker.inputs["Color2"].default_value = (0.1, 0.2, 0.4, 1.0)
links.new(checker.outputs["Color"], emission.inputs["Color"])
links.new(emission.outputs["Emission"], nodes["Material Output"].inputs["Surface"])
bpy.context.active_object.data.materials.append(wall)

bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=64, ring_count=32, location=(0.0, 0.0, 0.0))
bpy.ops.object.shade_smooth()
frosted_mat = bpy.data.materials.new("Frosted")
frosted_mat.use_nodes = True
tree = frosted_mat.node_tree
tree.nodes.remove(tree.nodes["Principled BSDF"])
frosted = tree.nodes.new("GlimmerNodeFrostedGlassBsdf")
frosted.name = "frosted"
frosted.inputs["Roughness"].default_value = 0.3
frosted.inputs["IOR"].default_value = 1.5
tree.links.new(frosted.outputs["BSDF"], tree.nodes["Material Output"].inputs["Surface"])
bpy.context.active_object.data.materials.append(frosted_mat)
method_prop = mod.nodes.property_name("method")

# The inner group is the Cycles/EEVEE fallback: Group Input -> Glass BSDF (GGX) -> Group Output.
group = frosted.node_tree
glass = [n for n in group.nodes if n.bl_idname == "ShaderNodeBsdfGlass"]
check(len(glass) == 1 and glass[0].distribution == "GGX", "inner group holds one GGX Glass BSDF")
out_links = [l for l in group.links if l.to_node.bl_idname == "NodeGroupOutput"]
check(len(out_links) == 1 and out_links[0].from_node == glass[0], "the Glass BSDF feeds the group output")
linked = {l.to_socket.name for l in group.links if l.to_node == glass[0]}
check({"Color", "Roughness", "IOR"} <= linked, "colour, roughness and IOR reach the fallback: %s" % linked)


def pixels(path):
    img = bpy.data.images.load(path)
    px = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px[..., :3]


def render_engine(name):
    path = os.path.join(opts.out, name + ".exr")
    bpy.ops.render.render()
    bpy.data.images["Render Result"].save_render(path, scene=scene)
    return pixels(path)


# The sphere (radius 1 at distance 5, default 50 mm lens) covers the middle of the frame: a central box well
# inside its silhouette, and a box on the wall outside it.
sphere_box = (slice(H // 2 - 5, H // 2 + 5), slice(W // 2 - 5, W // 2 + 5))
wall_box = (slice(2, 10), slice(2, 10))
images = {}
for method in ("path", "sg", "auto"):
    setattr(frosted, method_prop, method)
    bpy.context.view_layer.update()  # the depsgraph update after an edit (the property must tag the tree)
    export_dir = os.path.join(opts.out, "export_" + method)
    xml, _ = mod.exporter.export_scene(bpy.context.evaluated_depsgraph_get(), export_dir)
    shader = {s.get("name"): s for s in ET.parse(xml).getroot().findall("shader")}["Frosted"]
    el = shader.find("frosted_glass_bsdf")
    check(el is not None, "%s: frosted_glass_bsdf exported (not the glass fallback)" % method)
    check(el.get("method") == method, "%s: method written (%s)" % (method, el.get("method")))
    check(abs(float(el.get("roughness")) - 0.3) < 1e-6 and abs(float(el.get("ior")) - 1.5) < 1e-6,
          "%s: roughness and IOR written" % method)
    images[method] = render_engine("frosted_" + method)
    img = images[method]
    check(np.isfinite(img).all() and img.min() >= 0.0, "%s: finite, non-negative pixels" % method)
    if method == "sg":  # the XML the engine rendered, through the CLI, renders the same image
        engine_xml = os.path.join(opts.out, "engine_export", "frame_%04d" % scene.frame_current, "scene.xml")
        with open(engine_xml) as a, open(xml) as b:
            check(a.read() == b.read(), "sg: the engine's scene.xml equals the exporter's")
        cli_exr = os.path.join(opts.out, "frosted_sg_cli.exr")
        cmd = mod.runner.render_command(glimmer, engine_xml, cli_exr, SPP, 2, 3, W, H)
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        check(proc.returncode == 0, "CLI render: %s" % proc.stdout.decode(errors="replace")[-1500:])
        rgba = os.path.join(opts.out, "frosted_sg_cli_rgba.exr")
        channels = mod.engine.exr_channels(cli_exr)
        combined = [c for c in channels if ".Combined." in c]
        order = ["%s.Combined.%s" % (combined[0].split(".Combined.")[0], c) for c in "RGBA"] if combined else \
            list("RGBA")
        subprocess.run(["oiiotool", cli_exr, "--ch", ",".join(order), "--chnames", "R,G,B,A", "-d", "float", "-o",
                        rgba], check=True)
        diff = np.abs(pixels(rgba) - img).max()
        check(diff <= 1e-6, "sg: engine render equals the CLI render of the engine's XML (max diff %g)" % diff)

means = {m: images[m][sphere_box].mean() for m in images}
wall_mean = images["path"][wall_box].mean()
print("sphere means: " + ", ".join("%s %.4f" % kv for kv in means.items()) + "; wall %.4f" % wall_mean)
check(np.abs(images["sg"] - images["path"]).max() > 1e-3, "sg renders another estimator than path")
check(0.2 * wall_mean < means["path"] < wall_mean, "light passes through the frosted sphere")
for method in ("sg", "auto"):
    check(abs(means[method] / means["path"] - 1.0) <= 0.15, "%s vs path on the sphere: %.4f vs %.4f"
          % (method, means[method], means["path"]))

# Cycles renders the node through its inner Glass BSDF.
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.samples = 256
scene.cycles.use_denoising = False
scene.cycles.seed = 3
scene.render.threads_mode = "FIXED"
scene.render.threads = 2
cycles_img = render_engine("frosted_cycles")
cycles_mean = cycles_img[sphere_box].mean()
cycles_wall = cycles_img[wall_box].mean()
print("Cycles fallback: sphere %.4f, wall %.4f" % (cycles_mean, cycles_wall))
check(abs(cycles_wall / wall_mean - 1.0) <= 0.05, "the wall agrees between the renderers")
check(abs(cycles_mean / means["path"] - 1.0) <= 0.10, "Cycles' Glass fallback vs Glimmer's frosted path: %.4f vs "
      "%.4f" % (cycles_mean, means["path"]))
util.done("test_frosted_node")
