"""Glimmer: glint and frosted-glass closures in a Cycles-style path tracer, from Blender.

Render engine "Glimmer" (exports the scene to Cycles XML + PLY and runs the
`glimmer` command-line renderer), Glint BSDF / Frosted Glass BSDF shader nodes
with Cycles/EEVEE fallbacks. See docs/blender.md in the Glimmer repository.
"""

bl_info = {
    "name": "Glimmer",
    "author": "Glimmer project",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Render Properties > Render Engine > Glimmer; Shader Editor > Add > Shader",
    "description": "Glint and frosted-glass closures rendered by the Glimmer path tracer",
    "doc_url": "",
    "category": "Render",
}

if "bpy" in locals():
    import importlib

    for _module in (schema, preferences, properties, nodes, mesh_export, exporter, runner, viewport, engine, farm,
                    ui):  # noqa: F821
        importlib.reload(_module)

import bpy

from . import schema, preferences, properties, nodes, mesh_export, exporter, runner, viewport, engine, farm, ui

_schema_origin = None


def current_schema():
    """(schema, origin 'live' | 'snapshot', error) for the configured executable."""
    return schema.merged_schema(preferences.executable_path())


def register():
    global _schema_origin
    bpy.utils.register_class(preferences.GlimmerPreferences)
    bpy.utils.register_class(properties.GlimmerRenderSettings)
    bpy.types.Scene.glimmer = bpy.props.PointerProperty(type=properties.GlimmerRenderSettings)
    bpy.utils.register_class(engine.GlimmerRenderEngine)
    bpy.utils.register_class(farm.GLIMMER_OT_export_for_farm)
    for cls in ui.CLASSES:
        bpy.utils.register_class(cls)
    ui.borrow_builtin_panels()
    ui.borrow_shader_nodes()
    closure_schema, _schema_origin, error = current_schema()
    if error:
        print("Glimmer: using the built-in closure schema snapshot (%s)" % error)
    nodes.register(closure_schema)


def unregister():
    nodes.unregister()
    ui.return_shader_nodes()
    ui.return_builtin_panels()
    for cls in reversed(ui.CLASSES):
        bpy.utils.unregister_class(cls)
    bpy.utils.unregister_class(farm.GLIMMER_OT_export_for_farm)
    bpy.utils.unregister_class(engine.GlimmerRenderEngine)
    del bpy.types.Scene.glimmer
    bpy.utils.unregister_class(properties.GlimmerRenderSettings)
    bpy.utils.unregister_class(preferences.GlimmerPreferences)
    schema.clear_cache()
