"""Issue 16, step 1-2: nothing is dropped silently, missing textures render magenta with one warning, a
non-executable renderer gives a clear error, curves/text/metaballs are exported once, the light panel and
tooltips, and the standard Cycles shader nodes can be added with Glimmer active."""
import os
import stat
import subprocess
import sys
from types import SimpleNamespace

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
NOT_EXECUTABLE_CHILD = "--not-executable-child" in sys.argv
if NOT_EXECUTABLE_CHILD:  # render with the given non-executable renderer, then exit
    path = sys.argv.pop(sys.argv.index("--not-executable-child") + 1)
    sys.argv.remove("--not-executable-child")
opts = util.args()
mod = util.enable_addon()
if NOT_EXECUTABLE_CHILD:
    bpy.context.scene.render.engine = "GLIMMER"
    bpy.context.preferences.addons["glimmer"].preferences.executable = path
    try:
        bpy.ops.render.render()
    except RuntimeError as e:
        print("render operator:", e)
    print("child: render finished", flush=True)
    sys.exit(0)
glimmer = os.environ.get("GLIMMER_EXECUTABLE", "")
can_render = mod.runner.supports_render(glimmer)

# Every report the engine hands to Blender is recorded (the engine instance is Blender's; its class is wrapped).
engine_reports = []


_send_report = mod.engine.GlimmerRenderEngine.send_report


def recording_report(self, kind, message):
    engine_reports.append((set(kind), message))
    _send_report(self, kind, message)


mod.engine.GlimmerRenderEngine.send_report = recording_report


def export(name):
    reports = []
    out_dir = os.path.join(opts.out, name)
    xml, exp = mod.exporter.export_scene(bpy.context.evaluated_depsgraph_get(), out_dir,
                                         report=lambda kind, msg: reports.append(msg))
    return xml, exp, reports


def camera(scene, location=(0.0, 0.0, 5.0)):
    util.add_camera(scene, location, (0.0, 0.0, 0.0))


# -- 1. a missing image texture renders magenta, one warning naming the image, material and node -------------------
scene = util.empty_exr_scene(24, 16)
scene.glimmer.samples = 4
scene.glimmer.threads = 2
camera(scene)
missing = bpy.data.images.new("glimmer_missing_texture.png", 4, 4)  # as a .blend whose texture file moved away
missing.source = "FILE"
missing.filepath = "/nonexistent/glimmer_missing_texture.png"
for index, x in enumerate((-0.6, 0.6)):  # two materials sharing the missing image: still one warning
    bpy.ops.mesh.primitive_plane_add(size=1.2, location=(x, 0.0, 0.0))
    mat = bpy.data.materials.new("Missing%d" % index)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.remove(nodes["Principled BSDF"])
    tex = nodes.new("ShaderNodeTexImage")
    tex.name = "Albedo Map"
    tex.image = missing
    emit = nodes.new("ShaderNodeEmission")
    links.new(tex.outputs["Color"], emit.inputs["Color"])
    links.new(emit.outputs[0], nodes["Material Output"].inputs["Surface"])
    bpy.context.active_object.data.materials.append(mat)
xml, exp, reports = export("missing_texture")
image_warnings = [m for m in reports if "glimmer_missing_texture" in m]
check(len(image_warnings) == 1, "one warning for the missing image: %s" % reports)
check("Missing0" in image_warnings[0] and "Albedo Map" in image_warnings[0] and "magenta" in image_warnings[0],
      "the warning names material, node and the magenta fallback: %s" % image_warnings[0])
magenta_file = os.path.join(os.path.dirname(xml), "textures", "missing_image_magenta.ppm")
check(os.path.isfile(magenta_file) and magenta_file in open(xml).read(), "the XML reads the magenta texture")
if can_render:
    engine_reports.clear()
    bpy.ops.render.render()
    out = os.path.join(opts.out, "missing_texture.exr")
    bpy.data.images["Render Result"].save_render(out, scene=scene)
    img = bpy.data.images.load(out)
    px = np.array(img.pixels[:]).reshape(16, 24, 4)
    centre = px[8, 6, :3]  # over the left plane
    print("missing texture pixel", centre)
    check(np.allclose(centre, (1.0, 0.0, 1.0), atol=0.02), "magenta where the texture is missing: %s" % centre)
    texture_reports = [m for _, m in engine_reports if "glimmer_missing_texture" in m]
    check(len(texture_reports) == 1, "one report in the render: %s" % engine_reports)
    check(not any("ERROR" in k for k, _ in engine_reports), "no error: %s" % engine_reports)

    # An animation reports each warning once (at its first frame), not once per frame.
    scene.frame_start, scene.frame_end = 1, 2
    scene.render.filepath = os.path.join(opts.out, "anim_####")
    scene.render.image_settings.file_format = "PNG"
    engine_reports.clear()
    bpy.ops.render.render(animation=True)
    frames = [f for f in os.listdir(opts.out) if f.startswith("anim_") and f.endswith(".png")]
    texture_reports = [m for _, m in engine_reports if "glimmer_missing_texture" in m]
    print("animation: %d frames, %d texture reports" % (len(frames), len(texture_reports)))
    check(len(frames) == 2, "two frames rendered: %s" % frames)
    check(len(texture_reports) == 1, "one report for the whole animation: %s" % engine_reports)
    engine_reports.clear()
    bpy.ops.render.render()  # a new render job reports again
    check(len([m for _, m in engine_reports if "glimmer_missing_texture" in m]) == 1, "reported by the next job")
    scene.render.image_settings.file_format = "OPEN_EXR"

# -- 2. a non-executable renderer: a clear error, no traceback ----------------------------------------------------
not_executable = os.path.join(opts.out, "glimmer_not_executable")
with open(not_executable, "w") as f:
    f.write("#!/bin/sh\nexit 0\n")
os.chmod(not_executable, stat.S_IRUSR | stat.S_IWUSR)
problem = mod.engine.executable_problem(not_executable)
check(problem is not None and "not executable" in problem and not_executable in problem, "problem: %s" % problem)
check(mod.engine.executable_problem(os.path.join(opts.out, "absent_glimmer")) is not None, "absent executable")
if can_render:
    check(mod.engine.executable_problem(glimmer) is None, "the real renderer runs")
    # A failed render makes background Blender exit with 1, so the engine's part runs in a child Blender.
    child = subprocess.run([bpy.app.binary_path, "-b", "--factory-startup", "--python", os.path.abspath(__file__),
                            "--", "--out", opts.out, "--not-executable-child", not_executable],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=120)
    log = child.stdout.decode(errors="replace")
    print(log[-1500:])
    errors = [line for line in log.splitlines() if line.startswith("Error: Glimmer:")]
    check("child: render finished" in log, "the child rendered (exit code %d)" % child.returncode)
    check(len(errors) == 1 and "not executable" in errors[0] and not_executable in errors[0],
          "one clear error: %s" % errors)
    check("Traceback" not in log, "no traceback")

# -- 3. curves, text and metaballs are exported once ---------------------------------------------------------------
scene = util.empty_exr_scene(24, 16)
camera(scene)
bpy.ops.object.text_add(location=(0.0, 0.0, 0.0))
bpy.ops.curve.primitive_bezier_circle_add(location=(3.0, 0.0, 0.0))
bpy.context.active_object.data.bevel_depth = 0.1
bpy.ops.object.metaball_add(location=(-3.0, 0.0, 0.0))
bpy.ops.mesh.primitive_cube_add(location=(0.0, 3.0, 0.0))
xml, exp, reports = export("curves_once")
meshes = sorted(os.listdir(os.path.join(os.path.dirname(xml), "meshes")))
print("meshes", meshes)
check(meshes == ["BezierCircle.ply", "Cube.ply", "Mball.ply", "Text.ply"], "each object once: %s" % meshes)
depsgraph = bpy.context.evaluated_depsgraph_get()
expected = 0
for name in ("BezierCircle", "Cube", "Mball", "Text"):
    ob = bpy.data.objects[name].evaluated_get(depsgraph)
    m = ob.to_mesh()
    m.calc_loop_triangles()
    expected += len(m.loop_triangles)
    ob.to_mesh_clear()
check(exp.stats["triangles"] == expected, "triangles %d == evaluated %d" % (exp.stats["triangles"], expected))

# -- 4. what the exporter cannot carry is reported, with names ---------------------------------------------------------
scene = util.empty_exr_scene(24, 16)
camera(scene)
scene.render.film_transparent = True
bpy.ops.mesh.primitive_cube_add()
cube = bpy.context.active_object
cube.visible_camera = False
cube.is_shadow_catcher = True
mat = bpy.data.materials.new("Bumpy")
mat.use_nodes = True
nodes, links = mat.node_tree.nodes, mat.node_tree.links
principled = nodes["Principled BSDF"]
bump = nodes.new("ShaderNodeBump")
bump.name = "Scratches"
links.new(bump.outputs["Normal"], principled.inputs["Normal"])
cube.data.materials.append(mat)
bpy.ops.mesh.primitive_cube_add(location=(3.0, 0.0, 0.0))
brushed = bpy.data.materials.new("Brushed")
brushed.use_nodes = True
aniso = brushed.node_tree.nodes.new("ShaderNodeBsdfAnisotropic")
aniso.name = "Brushed Metal"
aniso.inputs["Anisotropy"].default_value = 0.8
normal_map = brushed.node_tree.nodes.new("ShaderNodeNormalMap")
brushed.node_tree.links.new(normal_map.outputs["Normal"], aniso.inputs["Normal"])
brushed.node_tree.links.new(aniso.outputs[0], brushed.node_tree.nodes["Material Output"].inputs["Surface"])
bpy.context.active_object.data.materials.append(brushed)
lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "AREA"))
lamp.data.diffuse_factor = 0.5
scene.collection.objects.link(lamp)
if hasattr(bpy.data, "hair_curves"):
    hair = bpy.data.objects.new("Hair", bpy.data.hair_curves.new("Hair"))
    scene.collection.objects.link(hair)
scene.render.use_motion_blur = True
xml, exp, reports = export("drops")
print("\n".join(reports))
for words in (("Scratches", "Normal", "Principled BSDF", "Bumpy"), ("Cube", "camera"), ("Cube", "shadow catcher"),
              ("Lamp", "diffuse factor"), ("motion blur",)) + \
        ((("Hair", "hair curves"),) if hasattr(bpy.data, "hair_curves") else ()):
    check(sum(all(w in m for w in words) for m in reports) == 1, "one report with %s: %s" % (words, reports))
check(len(reports) == len(set(reports)), "no repeated report")
# Anisotropy and a Normal Map on an anisotropic BSDF are exported (the renderer's normal/tangent sockets), not reported.
check(not any("Brushed Metal" in m for m in reports), "the brushed metal exports without a report: %s" % reports)
with open(xml) as f:
    text = f.read()
check("<normal_map " in text and 'from="Normal_Map normal" to="Brushed_Metal normal"' in text,
      "the Normal Map is exported into the anisotropic BSDF's normal")
# Film Transparent is exported (Cycles XML: <background transparent="true">), not reported.
check(not any("Transparent" in m for m in reports), "Film Transparent is not reported: %s" % reports)
with open(xml) as f:
    check('<background transparent="true">' in f.read(), "Film Transparent exported")
scene.cycles.film_transparent_glass = True
xml, exp, reports = export("transparent_glass")
check(sum("Transparent Glass" in m for m in reports) == 1, "Transparent Glass reported once: %s" % reports)
scene.cycles.film_transparent_glass = False

# -- 5. UI: one Light panel, which shows Spread; socket tooltips fit Blender's 63 characters ----------------------------
light_panels = [name for name in dir(bpy.types)
                if getattr(getattr(bpy.types, name), "bl_label", "") == "Light"
                and getattr(getattr(bpy.types, name), "bl_context", "") == "data"
                and "GLIMMER" in (getattr(getattr(bpy.types, name), "COMPAT_ENGINES", None) or ())]
check(light_panels == ["GLIMMER_PT_light"], "one Light panel for Glimmer: %s" % light_panels)


class RecordingLayout:
    def __init__(self):
        self.props, self.use_property_split = [], False

    def prop(self, owner, name, **kw):
        self.props.append(name)

    def row(self, **kw):
        return self

    def column(self, **kw):
        return self


area = bpy.data.lights.new("AreaUI", "AREA")
panel = SimpleNamespace(layout=RecordingLayout())
mod.ui.GLIMMER_PT_light.draw(panel, SimpleNamespace(light=area))
check({"energy", "shape", "size", "spread"} <= set(panel.layout.props), "area light panel: %s" % panel.layout.props)

schema, _, _ = mod.current_schema()
glint = mod.schema.closure(schema, "glint")
roughness_doc = next(p["doc"] for p in glint["params"] if p["name"] == "roughness")
check(len(roughness_doc) > 63, "the roughness note is longer than a socket description")
group = mod.nodes.ensure_group(glint)
for sock in mod.nodes.interface_sockets(group, "INPUT"):
    doc = next(p.get("doc", "") for p in glint["params"] if mod.schema.socket_name(p["name"]) == sock.name)
    check(sock.description == mod.nodes.socket_description(doc), "description of %s" % sock.name)
    check(len(sock.description) <= 63 and (sock.description == doc or sock.description.endswith(" (...)")),
          "%s: '%s'" % (sock.name, sock.description))
labels = []
sidebar = SimpleNamespace(prop=lambda *a, **k: None, label=lambda text="": labels.append(text),
                          column=lambda **k: sidebar)
node_cls = bpy.types.Node.bl_rna_get_subclass_py("GlimmerNodeGlintBsdf")
node_cls.draw_buttons_ext(SimpleNamespace(closure_schema=glint, closure_name="glint"), None, sidebar)
check(any(roughness_doc in text for text in labels), "the full roughness note is in the node's sidebar: %s" % labels)
check(mod.nodes.socket_description("a " * 40).endswith("a (...)"), "cut at a word")

# -- 6. the standard shader nodes Glimmer supports are in the Add menu with Glimmer active -----------------------------
scene.render.engine = "GLIMMER"
mat = bpy.data.materials.new("AddMenu")
mat.use_nodes = True


def visible_items(engine, shader_type):
    space = SimpleNamespace(tree_type="ShaderNodeTree", shader_type=shader_type, edit_tree=mat.node_tree)
    context = SimpleNamespace(engine=engine, space_data=space)
    return {item.nodetype for item in mod.ui.shader_node_items() if item.poll is None or item.poll(context)}


items = mod.ui.shader_node_items()
check(len(items) > 50, "Blender's shader node items found (%d)" % len(items))
for shader_type in ("OBJECT", "WORLD"):
    cycles, glimmer_items = visible_items("CYCLES", shader_type), visible_items("GLIMMER", shader_type)
    wanted = cycles & mod.ui.SUPPORTED_SHADER_NODES
    check(wanted <= glimmer_items, "%s: supported nodes hidden with Glimmer: %s" % (shader_type, wanted - glimmer_items))
    check(not (glimmer_items - cycles), "%s: no node Cycles hides" % shader_type)
    hidden = cycles - glimmer_items
    check(not (hidden & mod.ui.SUPPORTED_SHADER_NODES), "unsupported ones only hidden")
    print(shader_type, "with Glimmer: %d nodes, hidden (unsupported): %s" % (len(glimmer_items), sorted(hidden)))
object_items = visible_items("GLIMMER", "OBJECT")
for nodetype in ("ShaderNodeMixShader", "ShaderNodeAddShader", "ShaderNodeBsdfDiffuse", "ShaderNodeBsdfGlossy",
                 "ShaderNodeBsdfGlass", "ShaderNodeBsdfPrincipled", "ShaderNodeEmission", "ShaderNodeOutputMaterial",
                 "ShaderNodeBsdfAnisotropic", "ShaderNodeBsdfRefraction"):
    check(nodetype in object_items, "%s in the Add menu" % nodetype)
    node = mat.node_tree.nodes.new(nodetype)  # and it can be added
    check(node.bl_idname == nodetype, "added %s" % nodetype)
check("ShaderNodeBsdfToon" not in object_items, "unsupported Toon hidden")
check("ShaderNodeBackground" in visible_items("GLIMMER", "WORLD"), "Background in world trees")
mod.ui.return_shader_nodes()
check("ShaderNodeBsdfDiffuse" not in visible_items("GLIMMER", "OBJECT"), "polls restored on unregister")
mod.ui.borrow_shader_nodes()
print("test_artist_workflow: OK")
