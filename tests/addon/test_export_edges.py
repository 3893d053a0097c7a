"""An artist's edge cases of the exporter (session 40 audit): what reaches the XML/PLY must be what Cycles
renders, or be reported.

- UV maps: a mesh with two UV maps exports the render UV map (camera icon, `active_render`), not the map
  selected for editing (`active`), as Cycles does for textures without a Vector link.
- Glint / Frosted Glass sockets typed outside the closure's range (Blender's group sockets limit dragging only):
  the value is clamped into the range with one warning naming node and socket; before, the renderer refused the
  whole scene ("parameter 'density' = 0 is outside [1, 1e+12]").
- View layer collection settings Glimmer cannot render, Holdout and Indirect Only, are reported with the object's
  name (the object's own Holdout already was; the collections' were dropped silently).
- View Layer > Material Override replaces every object's materials, as in Cycles (it was ignored).
- A UV Map node (or a tangent-space Normal Map) naming a UV map other than the exported render map is reported
  (the mesh's one exported UV map was used without a word).
- A Glint node with Placement uv on a mesh without a UV map is reported (the renderer's uv is then each
  triangle's barycentrics: the same flakes on every triangle, without a warning).
- Depth of field: aperture blades (polygonal bokeh) and ratio (anamorphic) are reported (the host has a round
  thin lens; they were dropped silently).
- A texture linked into a Glint/Frosted Glass parameter the closure takes as one constant (not `varying` in the
  schema: glint roughness, frosted absorption colour, ...) is reported at export and the socket's own value is
  written; before, the XML had the link, the renderer warned and used the schema default instead of the value the
  artist had set. Varying parameters (density, frosted roughness) and the colour (a link is the weight) stay links.
- Render passes switched on in the view layer that Glimmer does not write (Emit, Mist, an AOV, ...) are reported
  in one warning (they were missing from the Render Layers node without a word); Normal and Depth are not.
"""
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
mod = util.enable_addon()
out_root = os.path.join(opts.out, "export_edges")
shutil.rmtree(out_root, ignore_errors=True)


new_scene = util.new_glimmer_scene


def export(name):
    return util.export_with_reports(mod, os.path.join(out_root, name))


def ply_uv(name, mesh_name):
    ply = mod.mesh_export.read_ply(os.path.join(out_root, name, "meshes", mesh_name + ".ply"))
    props = ply["props"]
    check("u" in props and "v" in props, "%s: the PLY has no UVs (%s)" % (name, props))
    return ply["vertices"][:, [props.index("u"), props.index("v")]]


# -- UV maps: the render UV map, not the edited one --------------------------------------------------------------
scene = new_scene()
bpy.ops.mesh.primitive_plane_add(size=2.0)
plane = bpy.context.object
plane.name = "Plane"
uvs = plane.data.uv_layers
second = uvs.new(name="Second")
for loop in second.data:  # the second map: the first shifted by 5 in u
    loop.uv = (loop.uv[0] + 5.0, loop.uv[1])
uvs.active = second  # selected for editing (an artist painting on it) ...
check(uvs["UVMap"].active_render and not second.active_render, "setup: UVMap must stay the render UV map")
_, _, reports = export("uv_render_map")
u = ply_uv("uv_render_map", "Plane")[:, 0]
print("render map UVMap, edited map Second: exported u in [%g, %g]" % (u.min(), u.max()))
check(u.min() >= 0.0 and u.max() <= 1.0, "the exported UVs must be the render UV map's (u in [0, 1]), got [%g, %g]"
      % (u.min(), u.max()))
second.active_render = True  # control: the camera icon on Second exports Second
_, _, reports = export("uv_render_map_second")
u = ply_uv("uv_render_map_second", "Plane")[:, 0]
print("render map Second: exported u in [%g, %g]" % (u.min(), u.max()))
check(u.min() >= 5.0 and u.max() <= 6.0, "with Second as the render UV map the exported u must be in [5, 6], got "
      "[%g, %g]" % (u.min(), u.max()))

# -- Glimmer node sockets outside the closure's range ---------------------------------------------------------------
scene = new_scene()
util.add_light(scene, "POINT", 200.0, (0.0, -2.0, 3.0))
materials = {}
for index, (label, idname) in enumerate((("Glint", "GlimmerNodeGlintBsdf"), ("Frost", "GlimmerNodeFrostedGlassBsdf"))):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.8, location=(-1.0 + 2.0 * index, 0.0, 0.0))
    mat = bpy.data.materials.new(label)
    mat.use_nodes = True
    nt = mat.node_tree
    node = nt.nodes.new(idname)
    node.name = label + " Node"
    nt.links.new(node.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    bpy.context.object.data.materials.append(mat)
    materials[label] = node
glint, frost = materials["Glint"], materials["Frost"]
glint.inputs["Density"].default_value = 0.0      # [1, 1e12]: "no flakes" typed by hand
glint.inputs["Gamma"].default_value = 25.0       # [0.1, 10]
glint.inputs["Roughness"].default_value = 0.25   # in range: written as it is, no warning
frost.thin = True
frost.inputs["Thickness"].default_value = 0.0    # [1e-6, 1e6]
frost.inputs["Color"].default_value = (1.5, 0.5, -0.25, 1.0)  # [0, 1] per channel
frost.inputs["IOR"].default_value = 0.7           # in range (IOR < 1 is allowed)
check(abs(glint.inputs["Density"].default_value) < 1e-12, "setup: Blender kept the typed density 0")
xml, _, reports = export("node_ranges")
elements = {el.get("name"): el for el in ET.parse(xml).getroot().iter()
            if el.get("name") in ("Glint_Node", "Frost_Node")}
g, f = elements["Glint_Node"], elements["Frost_Node"]
print("exported: density %s gamma %s roughness %s thickness %s color %s ior %s"
      % (g.get("density"), g.get("gamma"), g.get("roughness"), f.get("thickness"), f.get("color"), f.get("ior")))
check(float(g.get("density")) == 1.0 and float(g.get("gamma")) == 10.0, "glint density/gamma must be clamped to 1 / 10")
check(abs(float(g.get("roughness")) - 0.25) < 1e-6, "an in-range roughness must be written unchanged")
check(abs(float(f.get("thickness")) - 1e-6) < 1e-12, "thickness 0 must become the minimum 1e-6")
check([float(c) for c in f.get("color").split()] == [1.0, 0.5, 0.0], "the colour must be clamped per channel")
check(abs(float(f.get("ior")) - 0.7) < 1e-6, "IOR 0.7 is in range and must be written unchanged")
range_reports = [r for r in reports if "outside the closure's range" in r]
for r in range_reports:
    print("  report:", r)
expected = (("Glint Node", "Density"), ("Glint Node", "Gamma"), ("Frost Node", "Thickness"), ("Frost Node", "Color"))
for node_name, socket in expected:
    check(sum(1 for r in range_reports if "'%s': %s " % (node_name, socket) in r) == 1,
          "one warning naming node '%s' and socket %s expected: %s" % (node_name, socket, range_reports))
check(len(range_reports) == len(expected), "only the out-of-range sockets are reported: %s" % range_reports)
# A linked socket is still a link (the range applies to typed values only).
noise = glint.id_data.nodes.new("ShaderNodeTexNoise")
glint.id_data.links.new(noise.outputs["Fac"], glint.inputs["Density"])
xml_linked, _, reports = export("node_ranges_linked")
root = ET.parse(xml_linked).getroot()
g = next(el for el in root.iter("glint_bsdf"))
check(g.get("density") is None and any(c.get("to") == "Glint_Node density" for c in root.iter("connect")),
      "a linked Density must be exported as a link")
glimmer = os.environ.get("GLIMMER_EXECUTABLE", "")
render_xml = mod.runner.supports_render(glimmer)
if render_xml:
    run = subprocess.run([glimmer, "render", xml, "-o", os.path.join(out_root, "node_ranges", "r.exr"),
                          "--samples", "1", "--threads", "2"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    print("glimmer render of the clamped export: exit %d" % run.returncode)
    check(run.returncode == 0, "the renderer must accept the clamped values:\n" + run.stdout.decode(errors="replace"))

# -- view layer collection settings: Holdout, Indirect Only --------------------------------------------------------
scene = new_scene()
view_layer = bpy.context.view_layer
for name, flag in (("HoldoutSet", "holdout"), ("IndirectSet", "indirect_only"), ("PlainSet", None)):
    coll = bpy.data.collections.new(name)
    scene.collection.children.link(coll)
    bpy.ops.mesh.primitive_cube_add(size=0.5)
    cube = bpy.context.object
    cube.name = name + "Cube"
    for c in cube.users_collection:
        c.objects.unlink(cube)
    coll.objects.link(cube)
    if flag:
        setattr(view_layer.layer_collection.children[name], flag, True)
_, exp, reports = export("collection_flags")
for r in reports:
    print("  report:", r)
check(exp.stats["objects"] == 3, "the three cubes are exported (%d)" % exp.stats["objects"])
holdout = [r for r in reports if "'HoldoutSetCube'" in r and "holdout" in r.lower()]
indirect = [r for r in reports if "'IndirectSetCube'" in r and "Indirect Only" in r]
check(len(holdout) == 1, "one report for the Holdout collection's cube expected: %s" % reports)
check(len(indirect) == 1, "one report for the Indirect Only collection's cube expected: %s" % reports)
check(not any("PlainSetCube" in r for r in reports), "the plain collection's cube must not be reported: %s" % reports)

# -- View Layer > Material Override ---------------------------------------------------------------------------------
scene = new_scene()


def emission_material(name, color):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    emit = nt.nodes.new("ShaderNodeEmission")
    emit.inputs["Color"].default_value = (*color, 1.0)
    nt.links.new(emit.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return mat


red, blue = emission_material("Red", (1.0, 0.0, 0.0)), emission_material("Blue", (0.0, 0.0, 1.0))
bpy.ops.mesh.primitive_plane_add(size=1.0, location=(-0.6, 0.0, 0.0))
two_slots = bpy.context.object
two_slots.data.materials.append(red)
two_slots.data.materials.append(blue)
two_slots.data.polygons[0].material_index = 1
bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0.6, 0.0, 0.0))  # no material at all
override = emission_material("Override", (0.0, 1.0, 0.0))


def mesh_shaders(xml):
    root = ET.parse(xml).getroot()
    return sorted(state.get("shader") for state in root.iter("state") if state.find("mesh") is not None)


xml, _, _ = export("override_off")
print("without override: mesh shaders", mesh_shaders(xml))
check(mesh_shaders(xml) == ["Blue", "glimmer_default"], "setup: the planes use Blue and the default shader")
bpy.context.view_layer.material_override = override
xml, exp, reports = export("override_on")
print("with override: mesh shaders", mesh_shaders(xml), "reports", reports)
check(mesh_shaders(xml) == ["Override", "Override"], "Material Override must replace every object's materials, got %s"
      % mesh_shaders(xml))
check(not reports, "the override is exported, not reported: %s" % reports)

# -- a node naming a UV map that is not the exported one --------------------------------------------------------------
scene = new_scene()
bpy.ops.mesh.primitive_plane_add(size=1.0)
plane = bpy.context.object
plane.name = "TwoMaps"
plane.data.uv_layers.new(name="Decal")
mat = bpy.data.materials.new("DecalMat")
mat.use_nodes = True
nt = mat.node_tree
tex = nt.nodes.new("ShaderNodeTexImage")
tex.image = bpy.data.images.new("decal", 4, 4)
uv_node = nt.nodes.new("ShaderNodeUVMap")
nt.links.new(uv_node.outputs["UV"], tex.inputs["Vector"])
diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")  # its Normal is exported (the Principled BSDF's is not)
nt.links.new(diffuse.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
nt.links.new(tex.outputs["Color"], diffuse.inputs["Color"])
normal_map = nt.nodes.new("ShaderNodeNormalMap")
nt.links.new(normal_map.outputs["Normal"], diffuse.inputs["Normal"])
plane.data.materials.append(mat)


def uv_reports(reports):
    return [r for r in reports if "reads UV map" in r]


for uv_map, normal_uv_map, expected in (("", "", []), ("UVMap", "UVMap", []), ("Decal", "", ["Decal"]),
                                        ("", "Decal", ["Decal"])):
    uv_node.uv_map, normal_map.uv_map = uv_map, normal_uv_map
    mat.node_tree.update_tag()
    _, _, reports = export("uv_map_node_%s_%s" % (uv_map or "none", normal_uv_map or "none"))
    found = uv_reports(reports)
    print("UV Map node '%s', Normal Map '%s': %s" % (uv_map, normal_uv_map, found))
    check(len(found) == len(expected), "expected %d UV map report(s), got %s" % (len(expected), found))
    for r, name in zip(found, expected):
        check("'TwoMaps'" in r and "'DecalMat'" in r and "'%s'" % name in r and "'UVMap'" in r,
              "the report must name object, material, the node's map and the exported one: %s" % r)

# -- a Glint node (Placement uv) on a mesh without a UV map ---------------------------------------------------------
scene = new_scene()
mat = bpy.data.materials.new("Sparkle")
mat.use_nodes = True
nt = mat.node_tree
glint = nt.nodes.new("GlimmerNodeGlintBsdf")
glint.name = "Flakes"
nt.links.new(glint.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
for name, keep_uv in (("NoUV", False), ("WithUV", True)):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.4, location=(0.5 if keep_uv else -0.5, 0.0, 0.0))
    sphere = bpy.context.object
    sphere.name = name
    if not keep_uv:
        sphere.data.uv_layers.remove(sphere.data.uv_layers[0])
    sphere.data.materials.append(mat)
for placement, expected in (("uv", 1), ("object", 0)):
    glint.placement = placement
    _, _, reports = export("glint_no_uv_" + placement)
    found = [r for r in reports if "has no UV map" in r]
    print("placement %s: %s" % (placement, found))
    check(len(found) == expected, "placement %s: %d report(s) about the mesh without UVs expected, got %s"
          % (placement, expected, found))
    check(all("'NoUV'" in r and "'Flakes'" in r and "'Sparkle'" in r for r in found), "names expected: %s" % found)

# -- depth of field: blades and ratio ---------------------------------------------------------------------------------
scene = new_scene()
dof = scene.camera.data.dof
dof.use_dof = True
for blades, ratio, expected in ((0, 1.0, []), (6, 1.0, ["6-blade"]), (0, 2.0, ["aperture ratio 2"]),
                                (5, 0.5, ["5-blade", "aperture ratio 0.5"])):
    dof.aperture_blades, dof.aperture_ratio = blades, ratio
    xml, _, reports = export("dof_%d_%g" % (blades, ratio))
    found = [r for r in reports if "blade" in r or "aperture ratio" in r]
    print("blades %d ratio %g: %s" % (blades, ratio, found))
    check(len(found) == len(expected) and all(any(e in r for r in found) for e in expected),
          "expected reports %s, got %s" % (expected, found))
    check(next(ET.parse(xml).getroot().iter("camera")).get("width") is not None
          and any(c.get("aperturesize") for c in ET.parse(xml).getroot().iter("camera")), "the DOF is still exported")

# -- textures into parameters the closure takes as constants ----------------------------------------------------------
scene = new_scene()
bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5)
sphere = bpy.context.object
nodes_by_kind = {}
for idname in ("GlimmerNodeGlintBsdf", "GlimmerNodeFrostedGlassBsdf"):
    mat = bpy.data.materials.new(idname)
    mat.use_nodes = True
    nt = mat.node_tree
    node = nt.nodes.new(idname)
    nt.links.new(node.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.name = "Grain"
    nodes_by_kind[idname] = (mat, node, noise)
    sphere.data.materials.append(mat)
sphere.data.polygons[0].material_index = 1  # both materials in use
mat, glint, noise = nodes_by_kind["GlimmerNodeGlintBsdf"]
glint.name = "Flakes"
glint.inputs["Roughness"].default_value = 0.2
for socket, output in (("Roughness", "Fac"), ("Density", "Fac"), ("Color", "Color")):
    mat.node_tree.links.new(noise.outputs[output], glint.inputs[socket])
mat, frost, noise = nodes_by_kind["GlimmerNodeFrostedGlassBsdf"]
frost.name = "Pane"
frost.inputs["Absorption Color"].default_value = (0.5, 0.25, 0.125, 1.0)
for socket, output in (("Absorption Color", "Color"), ("Roughness", "Fac")):
    mat.node_tree.links.new(noise.outputs[output], frost.inputs[socket])
xml, _, reports = export("constant_params")
root = ET.parse(xml).getroot()
links = {c.get("to") for c in root.iter("connect")}
g, f = next(root.iter("glint_bsdf")), next(root.iter("frosted_glass_bsdf"))
constant_reports = [r for r in reports if "cannot be textured" in r]
node_links = sorted(x for x in links if x.split()[0] in ("Flakes", "Pane"))
print("glint roughness %s, absorption_color %s; links %s" % (g.get("roughness"), f.get("absorption_color"), node_links))
for r in constant_reports:
    print("  report:", r)
check(g.get("roughness") is not None and abs(float(g.get("roughness")) - 0.2) < 1e-6
      and "Flakes roughness" not in links,
      "a linked glint roughness (not varying) must be written as the socket's value 0.2, without the link")
check([float(c) for c in f.get("absorption_color").split()] == [0.5, 0.25, 0.125]
      and "Pane absorption_color" not in links,
      "a linked absorption colour (not varying) must be written as the socket's value")
check({"Flakes density", "Flakes color", "Pane roughness"} <= links, "varying parameters and the colour stay links")
check(len(constant_reports) == 2 and any("'Flakes': Roughness" in r and "'Grain'" in r for r in constant_reports)
      and any("'Pane': Absorption Color" in r for r in constant_reports),
      "one report each for the glint roughness and the absorption colour expected: %s" % constant_reports)
if render_xml:
    run = subprocess.run([glimmer, "render", xml, "-o", os.path.join(out_root, "constant_params", "r.exr"),
                          "--samples", "1", "--threads", "2"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    text = run.stdout.decode(errors="replace")
    check(run.returncode == 0 and "is not supported" not in text, "the renderer renders it without warnings:\n" + text)

# -- view layer passes Glimmer does not write --------------------------------------------------------------------------
scene = new_scene()
view_layer = bpy.context.view_layer
view_layer.use_pass_z = view_layer.use_pass_normal = True  # written by Glimmer: no report
_, _, reports = export("passes_supported")
check(not [r for r in reports if "passes only" in r], "Combined, Depth and Normal must not be reported: %s" % reports)
view_layer.use_pass_emit = view_layer.use_pass_mist = True
view_layer.aovs.add().name = "dirt"
_, _, reports = export("passes_missing")
found = [r for r in reports if "passes only" in r]
print("passes:", found)
check(len(found) == 1 and all(name in found[0] for name in ("Emit", "Mist", "AOV 'dirt'"))
      and "Normal," not in found[0].split("only;")[1] and "Z" not in found[0].split("only;")[1],
      "one report listing Emit, Mist and the AOV (not Normal/Depth) expected: %s" % found)

util.done("test_export_edges")
