"""An artist's edge cases of the exporter (session 40 audit): what reaches the XML/PLY must be what Cycles
renders, or be reported.

- UV maps: a mesh with two UV maps exports the render UV map (camera icon, `active_render`), not the map
  selected for editing (`active`), as Cycles does for textures without a Vector link.
"""
import os
import shutil
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
mod = util.enable_addon()
out_root = os.path.join(opts.out, "export_edges")
shutil.rmtree(out_root, ignore_errors=True)


def new_scene():
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "GLIMMER"
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 32, 24, 100
    util.add_camera(scene, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0))
    return scene


def export(name):
    reports = []
    xml, exp = mod.exporter.export_scene(bpy.context.evaluated_depsgraph_get(), os.path.join(out_root, name),
                                         report=lambda kind, msg: reports.append(msg))
    return xml, exp, reports


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

util.done("test_export_edges")
