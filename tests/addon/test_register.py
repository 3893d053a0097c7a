"""Register / unregister the addon twice; the engine, nodes, menu entry and panels come and go."""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

util.args()

for round_index in range(2):
    mod = util.enable_addon()
    check = util.check
    check("GLIMMER" in {e.bl_idname for e in bpy.types.RenderEngine.__subclasses__()}, "engine registered")
    check(mod.engine.GlimmerRenderEngine.bl_use_shading_nodes_custom is False, "Cycles nodes are used")
    check(bpy.types.Node.bl_rna_get_subclass_py("GlimmerNodeGlintBsdf") is not None, "Glint BSDF node registered")
    check(bpy.types.Node.bl_rna_get_subclass_py("GlimmerNodeFrostedGlassBsdf") is not None, "Frosted Glass BSDF node registered")
    check(hasattr(bpy.types.Scene, "glimmer"), "scene settings registered")
    scene = bpy.context.scene
    scene.render.engine = "GLIMMER"
    check(scene.render.engine == "GLIMMER", "engine selectable")
    check(scene.glimmer.samples == 64, "default samples")
    # Integrator settings shared with Cycles default to Blender 3.4's Cycles values
    # (scene.cycles), so a scene renders alike when switching engines.
    cycles_rna = type(scene.cycles).bl_rna.properties
    ours_rna = type(scene.glimmer).bl_rna.properties
    shared_settings = {
        "max_bounce": "max_bounces", "max_diffuse_bounce": "diffuse_bounces",
        "max_glossy_bounce": "glossy_bounces", "max_transmission_bounce": "transmission_bounces",
        "transparent_max_bounce": "transparent_max_bounces",
        "sample_clamp_direct": "sample_clamp_direct", "sample_clamp_indirect": "sample_clamp_indirect",
    }
    for ours, cycles in shared_settings.items():
        check(ours_rna[ours].default == cycles_rna[cycles].default,
              "default %s = %r, Cycles' %s = %r" % (ours, ours_rna[ours].default, cycles, cycles_rna[cycles].default))

    # The nodes are in the Shader Editor's Add menu (Shader submenu in 3.x and 4.x).
    menu_name = mod.nodes.menu_class()
    check(menu_name is not None, "shader Add submenu found")
    menu = getattr(bpy.types, menu_name)
    draw_funcs = getattr(menu.draw, "_draw_funcs", [])
    check(mod.nodes.menu_draw_function() in draw_funcs, "draw function appended to %s" % menu_name)
    # Drawing the entry adds one node.add_node operator per Glimmer node in shader trees only.
    from types import SimpleNamespace

    class RecordingLayout:
        def __init__(self):
            self.ops = []

        def operator(self, idname, text=""):
            props = SimpleNamespace()
            self.ops.append((idname, text, props))
            return props

        def separator(self):
            pass

    for tree_type, expected in (("ShaderNodeTree", 2), ("GeometryNodeTree", 0)):
        layout = RecordingLayout()
        fake_menu = SimpleNamespace(layout=layout)
        mod.nodes.menu_draw_function()(fake_menu, SimpleNamespace(space_data=SimpleNamespace(tree_type=tree_type)))
        check(len(layout.ops) == expected, "%d menu entries in a %s" % (len(layout.ops), tree_type))
        if expected:
            check({(op[1], op[2].type) for op in layout.ops} ==
                  {("Glint BSDF", "GlimmerNodeGlintBsdf"), ("Frosted Glass BSDF", "GlimmerNodeFrostedGlassBsdf")},
                  "menu entries add the Glimmer nodes")
    # Panels: ours and borrowed ones (camera properties) list the engine; Blender's light panels are replaced
    # by Glimmer's own (test_artist_workflow).
    check("GLIMMER" in bpy.types.GLIMMER_PT_sampling.COMPAT_ENGINES, "sampling panel")
    check("GLIMMER" in bpy.types.DATA_PT_camera.COMPAT_ENGINES, "camera panel borrowed")
    check("GLIMMER" not in bpy.types.DATA_PT_light.COMPAT_ENGINES, "Blender's light panel not borrowed")
    check(len(mod.ui._patched_items) > 10, "standard shader nodes made available")

    # The preference default points at the build next to the repository (or $GLIMMER_EXECUTABLE).
    exe = mod.preferences.executable_path()
    print("executable:", exe, "schema:", mod._schema_origin)
    if os.environ.get("GLIMMER_EXECUTABLE"):
        check(exe == os.environ["GLIMMER_EXECUTABLE"], "executable from the environment")
        check(mod._schema_origin == "live", "live schema from the executable")

    util.disable_addon()
    check(bpy.types.Node.bl_rna_get_subclass_py("GlimmerNodeGlintBsdf") is None, "node unregistered")
    check(not hasattr(bpy.types.Scene, "glimmer"), "settings unregistered")
    check("GLIMMER" not in bpy.types.DATA_PT_camera.COMPAT_ENGINES, "borrowed panel returned")
    check(not mod.ui._patched_items, "shader node polls returned")
    check(mod.nodes.menu_draw_function() not in getattr(menu.draw, "_draw_funcs", []), "menu entry removed")

util.done("test_register")
