"""Glint / Frosted Glass nodes: sockets match the schema, the inner group is a
working Cycles fallback, and a saved .blend reopens with links and values."""
import math
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
mod = util.enable_addon()
schema, origin, _ = mod.current_schema()
print("schema origin:", origin)

mat = bpy.data.materials.new("GlintMaterial")
mat.use_nodes = True
tree = mat.node_tree
output = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
for n in [n for n in tree.nodes if n != output]:
    tree.nodes.remove(n)

glint = tree.nodes.new("GlimmerNodeGlintBsdf")
frosted = tree.nodes.new("GlimmerNodeFrostedGlassBsdf")
mix = tree.nodes.new("ShaderNodeMixShader")
checker = tree.nodes.new("ShaderNodeTexChecker")
glint.name, frosted.name, mix.name, checker.name = "glint", "frosted", "mix", "checker"

# Sockets follow the schema: one per float/int/colour/vector parameter with its default.
for node, closure_name in ((glint, "glint"), (frosted, "frosted_glass")):
    closure = mod.schema.closure(schema, closure_name)
    socket_params = [p for p in closure["params"] if mod.schema.is_socket_param(p)]
    names = [s.name for s in node.inputs]
    check(names == [mod.schema.socket_name(p["name"]) for p in socket_params],
          "%s sockets %s follow the schema" % (closure_name, names))
    for p in socket_params:
        value = node.inputs[mod.schema.socket_name(p["name"])].default_value
        expected = p["default"]
        got = list(value)[:3] if p["type"] == "color" else value
        if isinstance(expected, list):
            check(all(abs(a - b) < 1e-6 for a, b in zip(got, expected)), "%s default" % p["name"])
        else:
            check(abs(got - expected) <= 1e-6 * max(1.0, abs(expected)), "%s default %r != %r" % (p["name"], got,
                                                                                                 expected))
    check(node.outputs[0].name == "BSDF", "BSDF output")
    # The inner group renders in Cycles: group input -> Glossy/Glass BSDF -> group output.
    inner = {n.bl_idname for n in node.node_tree.nodes}
    check(mod.nodes.FALLBACKS[closure_name]["node"] in inner, "fallback BSDF inside the group")
    check(any(n.bl_idname == "NodeGroupOutput" and n.inputs["BSDF"].is_linked for n in node.node_tree.nodes),
          "fallback wired to the group output")

# Enum parameters are node properties (schema default, then the other choice).
glint_schema = mod.schema.closure(schema, "glint")
frosted_schema = mod.schema.closure(schema, "frosted_glass")


def enum_param(closure):
    return next(p for p in closure["params"] if p["type"] == "enum")


glint_enum, frosted_enum = enum_param(glint_schema), enum_param(frosted_schema)
glint_prop, frosted_prop = mod.nodes.property_name(glint_enum["name"]), mod.nodes.property_name(frosted_enum["name"])
check(getattr(glint, glint_prop) == glint_enum["default"], "enum default")
glint_choice = next(c for c in glint_enum["choices"] if c != glint_enum["default"])
# frosted_glass's method: a choice other than the default (sg), or the only one if the enum had one.
frosted_choice = next((c for c in frosted_enum["choices"] if c != frosted_enum["default"]), frosted_enum["default"])
setattr(glint, glint_prop, glint_choice)
setattr(frosted, frosted_prop, frosted_choice)
# A further float parameter of the glint closure (the schema decides which), set inside its range.
extra = next(p for p in glint_schema["params"] if p["type"] == "float" and p["name"] not in ("roughness", "density"))
extra_socket = mod.schema.socket_name(extra["name"])
extra_value = min(extra["max"], extra["default"] * 1.5 + 0.25)

glint.inputs["Roughness"].default_value = 0.123
glint.inputs["Density"].default_value = 54321.0
glint.inputs[extra_socket].default_value = extra_value
frosted.inputs["IOR"].default_value = 1.33
frosted.inputs["Color"].default_value = (0.9, 0.8, 0.7, 1.0)
mix.inputs["Fac"].default_value = 0.25
tree.links.new(checker.outputs["Color"], glint.inputs["Color"])
tree.links.new(glint.outputs["BSDF"], mix.inputs[1])
tree.links.new(frosted.outputs["BSDF"], mix.inputs[2])
tree.links.new(mix.outputs["Shader"], output.inputs["Surface"])

# A copy shares the inner group.
copy = tree.nodes.new("GlimmerNodeGlintBsdf")
check(copy.node_tree == glint.node_tree, "nodes of one kind share the inner group")
tree.nodes.remove(copy)

bpy.ops.mesh.primitive_cube_add()
bpy.context.active_object.data.materials.append(mat)
path = os.path.join(opts.out, "nodes_save_reload.blend")
bpy.ops.wm.save_as_mainfile(filepath=path)

# Reopen (the addon stays enabled) and compare.
bpy.ops.wm.read_homefile(use_empty=True)
check(bpy.data.materials.get("GlintMaterial") is None, "cleared before reload")
bpy.ops.wm.open_mainfile(filepath=path)
mat = bpy.data.materials["GlintMaterial"]
tree = mat.node_tree
glint, frosted, mix = tree.nodes["glint"], tree.nodes["frosted"], tree.nodes["mix"]
check(glint.bl_idname == "GlimmerNodeGlintBsdf" and frosted.bl_idname == "GlimmerNodeFrostedGlassBsdf",
      "node types survive")
check(glint.node_tree is not None and glint.node_tree.name == ".Glimmer Glint BSDF", "inner group survives")
check(math.isclose(glint.inputs["Roughness"].default_value, 0.123, rel_tol=1e-6), "roughness value")
check(math.isclose(glint.inputs["Density"].default_value, 54321.0, rel_tol=1e-6), "density value")
check(math.isclose(glint.inputs[extra_socket].default_value, extra_value, rel_tol=1e-6), "%s value" % extra_socket)
check(math.isclose(frosted.inputs["IOR"].default_value, 1.33, rel_tol=1e-6), "ior value")
check(all(math.isclose(a, b, rel_tol=1e-6) for a, b in zip(frosted.inputs["Color"].default_value, (0.9, 0.8, 0.7))),
      "colour value")
check(getattr(glint, glint_prop) == glint_choice and getattr(frosted, frosted_prop) == frosted_choice,
      "enum properties survive")
check(glint.inputs["Color"].is_linked and glint.inputs["Color"].links[0].from_node.name == "checker",
      "texture link survives")
check(mix.inputs[1].links[0].from_node == glint and mix.inputs[2].links[0].from_node == frosted, "shader links")
out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
check(out.inputs["Surface"].links[0].from_node == mix, "output link")
check(math.isclose(mix.inputs["Fac"].default_value, 0.25), "mix factor")

# The fallback is what Cycles renders: make sure Cycles accepts the material (tiny render).
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.samples = 1
scene.cycles.device = "CPU"
scene.cycles.use_denoising = False
scene.render.resolution_x = scene.render.resolution_y = 8
scene.render.resolution_percentage = 100
if scene.camera is None:
    bpy.ops.object.camera_add(location=(4, -4, 3), rotation=(1.1, 0, 0.8))
    scene.camera = bpy.context.active_object
bpy.ops.render.render()
util.done("test_nodes_save_reload")
