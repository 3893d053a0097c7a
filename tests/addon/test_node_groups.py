"""The artist's own node groups are flattened by the exporter (session 41; before, any group other than Glimmer's own
nodes was exported as a grey diffuse BSDF with a warning, so a Glint node inside a group rendered as grey diffuse).

- A Glint node inside a group: exported as glint_bsdf. The group node's inputs reach the nodes inside: a texture
  linked outside stays a link (Density, varying), a value typed on the group node is the value inside (Roughness, a
  constant-only parameter: no "cannot be textured" warning; Color: a constant colour node).
- The same group used twice with other values, a nested group, and a node inside with the name of a node outside:
  each exported once per use, with its own values.
- A texture inside the group linked into a constant-only parameter is still reported, naming the texture.
- The exported scene renders with glimmer (the constant nodes are valid scene XML).
- A texture reaching a constant-only parameter through a Reroute is reported by the texture's name (the session-40
  audit found the Reroute named instead).
- Hidden-value sockets (a texture's Vector, a BSDF's Normal) fed by an unlinked group socket read the shading point,
  as Blender unlinks them; linked outside, the link is followed (Texture Coordinate > Generated into a noise inside).
  An idle group value (Subsurface 0) gives no "not supported" warning.
- Negative control, run by hand (session 41): this script against 3be2087's exporter fails at its first check ("one
  glint_bsdf expected, got 0"; the report "node group 'Flakes Use' is not supported").
"""
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
mod = util.enable_addon()
out_root = os.path.join(opts.out, "node_groups")
shutil.rmtree(out_root, ignore_errors=True)


new_scene = util.new_glimmer_scene


def export(name):
    xml, _, reports = util.export_with_reports(mod, os.path.join(out_root, name))
    shader = next(el for el in ET.parse(xml).getroot().iter("shader") if el.get("name") == "Grouped")
    return shader, reports  # the material's shader (the scene also has glimmer_default, a diffuse)


def flakes_group():
    """A group 'Flakes' (inputs Density, Roughness, Tint; output Shader) holding a Glint node named 'Glint'."""
    group = bpy.data.node_groups.new("Flakes", "ShaderNodeTree")
    group.inputs.new("NodeSocketFloat", "Density").default_value = 1e4
    group.inputs.new("NodeSocketFloat", "Roughness").default_value = 0.5
    group.inputs.new("NodeSocketColor", "Tint").default_value = (1.0, 1.0, 1.0, 1.0)
    group.outputs.new("NodeSocketShader", "Shader")
    g_in, g_out = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    glint = group.nodes.new("GlimmerNodeGlintBsdf")
    glint.name = "Glint"
    glint.inputs["Roughness"].default_value = 0.9  # what the session-40 exporter would have written
    group.links.new(g_in.outputs["Density"], glint.inputs["Density"])
    group.links.new(g_in.outputs["Roughness"], glint.inputs["Roughness"])
    group.links.new(g_in.outputs["Tint"], glint.inputs["Color"])
    group.links.new(glint.outputs[0], g_out.inputs["Shader"])
    return group


def connects(root):
    return {(c.get("from"), c.get("to")) for c in root.iter("connect")}


# -- a Glint node inside a group ---------------------------------------------------------------------------------
scene = new_scene()
util.add_light(scene, "POINT", 200.0, (0.0, -2.0, 3.0))
bpy.ops.mesh.primitive_uv_sphere_add(radius=0.8)
mat = bpy.data.materials.new("Grouped")
mat.use_nodes = True
nt = mat.node_tree
nt.nodes.remove(nt.nodes["Principled BSDF"])
flakes = flakes_group()
use = nt.nodes.new("ShaderNodeGroup")
use.name = "Flakes Use"
use.node_tree = flakes
noise = nt.nodes.new("ShaderNodeTexNoise")
nt.links.new(noise.outputs["Fac"], use.inputs["Density"])
use.inputs["Roughness"].default_value = 0.33
use.inputs["Tint"].default_value = (0.2, 0.4, 0.6, 1.0)
nt.links.new(use.outputs["Shader"], nt.nodes["Material Output"].inputs["Surface"])
bpy.context.object.data.materials.append(mat)
root, reports = export("one_group")
for r in reports:
    print("  report:", r)
glints = list(root.iter("glint_bsdf"))
check(len(glints) == 1, "one glint_bsdf expected, got %d" % len(glints))
check(not list(root.iter("diffuse_bsdf")), "no diffuse fallback expected")
check(not any("not supported" in r or "cannot be textured" in r for r in reports),
      "no 'not supported' / 'cannot be textured' warning expected: %s" % reports)
g = glints[0]
name = g.get("name")
print("glint %s: roughness %s density %s color %s" % (name, g.get("roughness"), g.get("density"), g.get("color")))
check(abs(float(g.get("roughness")) - 0.33) < 1e-6, "the group node's Roughness 0.33 must be the glint's (got %s)"
      % g.get("roughness"))
noise_el = next(root.iter("noise_texture"), None)
check(noise_el is not None and (noise_el.get("name") + " fac", name + " density") in connects(root),
      "the noise outside the group must feed the glint's density: %s" % connects(root))
colour = [el for el in root.iter("color") if (el.get("name") + " color", name + " color") in connects(root)]
check(len(colour) == 1 and max(abs(float(a) - b) for a, b in zip(colour[0].get("value").split(), (0.2, 0.4, 0.6)))
      < 1e-6, "the group node's Tint must reach the glint's colour as a constant colour node: %s"
      % [(el.get("name"), el.get("value")) for el in root.iter("color")])

# The exported scene renders (the constant nodes feeding the glint are valid scene XML).
glimmer = os.environ.get("GLIMMER_EXECUTABLE", "")
if glimmer:
    scene_dir = os.path.join(out_root, "one_group")
    proc = subprocess.run([glimmer, "render", os.path.join(scene_dir, "scene.xml"), "-o",
                           os.path.join(scene_dir, "render.exr"), "--samples", "2", "--quiet"],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          env=dict(os.environ, GLIMMER_CACHE_DIR=os.path.join(out_root, "cache")))
    print(proc.stdout.decode(errors="replace").strip())
    check(proc.returncode == 0, "glimmer render of the exported group scene failed (exit %d)" % proc.returncode)

# -- the same group twice, nested in another group, and a node of the same name outside ----------------------------
outer = bpy.data.node_groups.new("Paint", "ShaderNodeTree")
outer.inputs.new("NodeSocketFloat", "Roughness").default_value = 0.5
outer.outputs.new("NodeSocketShader", "Shader")
o_in, o_out = outer.nodes.new("NodeGroupInput"), outer.nodes.new("NodeGroupOutput")
inner = outer.nodes.new("ShaderNodeGroup")
inner.node_tree = flakes
inner.inputs["Density"].default_value = 5e4
outer.links.new(o_in.outputs["Roughness"], inner.inputs["Roughness"])
diffuse = outer.nodes.new("ShaderNodeBsdfDiffuse")
mix = outer.nodes.new("ShaderNodeMixShader")
outer.links.new(diffuse.outputs[0], mix.inputs[1])
outer.links.new(inner.outputs["Shader"], mix.inputs[2])
outer.links.new(mix.outputs[0], o_out.inputs["Shader"])
nested = nt.nodes.new("ShaderNodeGroup")
nested.node_tree = outer
nested.inputs["Roughness"].default_value = 0.21
outside = nt.nodes.new("GlimmerNodeGlintBsdf")
outside.name = "Glint"  # the name of the node inside Flakes
outside.inputs["Roughness"].default_value = 0.6
add1, add2 = nt.nodes.new("ShaderNodeAddShader"), nt.nodes.new("ShaderNodeAddShader")
nt.links.new(use.outputs["Shader"], add1.inputs[0])
nt.links.new(nested.outputs["Shader"], add1.inputs[1])
nt.links.new(add1.outputs[0], add2.inputs[0])
nt.links.new(outside.outputs[0], add2.inputs[1])
nt.links.new(add2.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
root, reports = export("groups_nested")
for r in reports:
    print("  report:", r)
glints = list(root.iter("glint_bsdf"))
rough = sorted(round(float(el.get("roughness")), 6) for el in glints)
print("glints:", [(el.get("name"), el.get("roughness"), el.get("density")) for el in glints])
check(rough == [0.21, 0.33, 0.6], "three glints (the group twice, once nested; the one outside) with roughness "
      "0.21 / 0.33 / 0.6 expected, got %s" % rough)
check(len({el.get("name") for el in glints}) == 3, "three distinct glint names expected")
nested_glint = next(el for el in glints if abs(float(el.get("roughness")) - 0.21) < 1e-6)
density_sources = [c.get("from") for c in root.iter("connect") if c.get("to") == nested_glint.get("name") + " density"]
values = {el.get("name"): el.get("value") for el in root.iter("value")}
check(len(density_sources) == 1 and abs(float(values.get(density_sources[0].split()[0], "nan")) - 5e4) < 1e-3,
      "the nested use's Density 5e4 (typed on the inner group node) must reach its glint: %s %s"
      % (density_sources, values))
check(len(list(root.iter("diffuse_bsdf"))) == 1 and len(list(root.iter("mix_closure"))) == 1,
      "the nested group's diffuse and mix must be exported")
check(not any("not supported" in r for r in reports), "no 'not supported' warning expected: %s" % reports)

# -- a texture inside a group into a constant-only parameter is still reported ---------------------------------------
wave = flakes.nodes.new("ShaderNodeTexWave")
wave.name = "Wave Inside"
flakes.links.new(wave.outputs["Fac"], flakes.nodes["Glint"].inputs["Roughness"])
root, reports = export("constant_in_group")
constant = [r for r in reports if "cannot be textured" in r]
print("constant-only reports:", constant)
check(any("Wave Inside" in r for r in constant), "the wave texture linked into Roughness inside the group must be "
      "reported by name: %s" % reports)

# -- through a Reroute, the report names the texture, not the Reroute (the session-40 audit's finding) -------------
flakes.links.remove(next(l for l in flakes.links if l.to_node.name == "Glint" and l.to_socket.name == "Roughness"))
reroute = flakes.nodes.new("NodeReroute")
flakes.links.new(wave.outputs["Fac"], reroute.inputs[0])
flakes.links.new(reroute.outputs[0], flakes.nodes["Glint"].inputs["Roughness"])
root, reports = export("constant_through_reroute")
constant = [r for r in reports if "cannot be textured" in r]
print("constant-only reports through a reroute:", constant)
check(constant and all("Wave Inside" in r and "Reroute" not in r for r in constant),
      "the report must name the wave texture behind the Reroute: %s" % constant)

# -- hidden-value sockets and coordinates through a group ----------------------------------------------------------
# Blender unlinks a texture's Vector / a BSDF's Normal from a Group Input whose group socket is unlinked: they read
# the shading point (not the group socket's hidden value 0 0 0). Linked outside, the link is followed: a Texture
# Coordinate > Generated outside the group reaches the texture inside.
coords = bpy.data.node_groups.new("Coords", "ShaderNodeTree")
coords.inputs.new("NodeSocketVector", "Vector")
coords.inputs.new("NodeSocketVector", "Normal")
coords.inputs.new("NodeSocketFloat", "Subsurface").default_value = 0.0  # idle: no "not supported" warning
coords.outputs.new("NodeSocketShader", "Shader")
c_in, c_out = coords.nodes.new("NodeGroupInput"), coords.nodes.new("NodeGroupOutput")
noise_in = coords.nodes.new("ShaderNodeTexNoise")
noise_in.name = "Noise Inside"
principled = coords.nodes.new("ShaderNodeBsdfPrincipled")
principled.name = "Principled Inside"
coords.links.new(c_in.outputs["Vector"], noise_in.inputs["Vector"])
coords.links.new(c_in.outputs["Normal"], principled.inputs["Normal"])
coords.links.new(c_in.outputs["Subsurface"], principled.inputs["Subsurface"])
coords.links.new(noise_in.outputs["Color"], principled.inputs["Base Color"])
coords.links.new(principled.outputs[0], c_out.inputs["Shader"])
for link in list(nt.links):
    nt.links.remove(link)
coords_use = nt.nodes.new("ShaderNodeGroup")
coords_use.node_tree = coords
nt.links.new(coords_use.outputs["Shader"], nt.nodes["Material Output"].inputs["Surface"])
root, reports = export("hidden_unlinked")
for r in reports:
    print("  report:", r)
noise_el = next(el for el in root.iter("noise_texture"))
into = {c.get("to"): c.get("from") for c in root.iter("connect")}
check(noise_el.get("name") + " vector" not in into and noise_el.get("vector") is None,
      "an unlinked group Vector must leave the texture's Vector unlinked (it reads the shading point): %s" % into)
check(not list(root.iter("combine_xyz")), "no constant vector expected for hidden sockets")
principled_el = next(root.iter("principled_bsdf"))
check(principled_el.get("name") + " normal" not in into, "an unlinked group Normal must not feed the BSDF's Normal")
check(not any("Subsurface" in r or "subsurface" in r or "Group Input" in r for r in reports),
      "no warning about an idle group Subsurface or a Group Input link expected: %s" % reports)
texcoord = nt.nodes.new("ShaderNodeTexCoord")
nt.links.new(texcoord.outputs["Generated"], coords_use.inputs["Vector"])
root, reports = export("hidden_linked")
into = {c.get("to"): c.get("from") for c in root.iter("connect")}
noise_el = next(el for el in root.iter("noise_texture"))
tc = [el.get("name") for el in root.iter("texture_coordinate")]
check(len(tc) == 1 and into.get(noise_el.get("name") + " vector") == tc[0] + " generated",
      "the Generated coordinates outside the group must reach the noise inside: %s %s" % (tc, into))
check(not any("is not exported" in r for r in reports), "no 'Vector ... is not exported' warning expected: %s"
      % reports)

print("node groups: OK")
