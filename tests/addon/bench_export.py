"""Export time of a 1-million-triangle scene (goal: under 5 s). A benchmark,
not a unit test: it prints the figures (run by `make stress`, label stress).

    blender -b --factory-startup --python tests/addon/bench_export.py -- --out /tmp/bench
"""
import os
import shutil
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

opts = util.args()
mod = util.enable_addon()


def scene_with_grid(smooth, uv, auto_smooth=False, subdivisions=708):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=subdivisions, y_subdivisions=subdivisions, size=10.0,
                                    calc_uvs=uv)
    grid = bpy.context.active_object
    grid.rotation_euler = (0.2, 0.1, 0.3)
    if smooth:
        bpy.ops.object.shade_smooth()
    if auto_smooth and hasattr(grid.data, "use_auto_smooth"):  # 3.x/4.0: split normals path
        grid.data.use_auto_smooth = True
    mat = bpy.data.materials.new("Mat")
    mat.use_nodes = True
    grid.data.materials.append(mat)
    grid.data.calc_loop_triangles()
    return len(grid.data.loop_triangles)


results = []
for label, smooth, uv, auto in (("flat, no UV", False, False, False), ("smooth, no UV", True, False, False),
                                ("smooth + UV (per-corner)", True, True, False),
                                ("smooth + UV + split normals", True, True, True)):
    triangles = scene_with_grid(smooth, uv, auto)
    out_dir = os.path.join(opts.out, "bench_export")
    shutil.rmtree(out_dir, ignore_errors=True)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    start = time.perf_counter()
    xml, exp = mod.exporter.export_scene(depsgraph, out_dir)
    seconds = time.perf_counter() - start
    size = sum(os.path.getsize(os.path.join(out_dir, "meshes", f)) for f in os.listdir(os.path.join(out_dir, "meshes")))
    util.check(exp.stats["triangles"] == triangles, "all triangles exported")
    results.append((label, triangles, exp.stats["vertices"], seconds, size))
    print("export %-26s %9d triangles %9d vertices: %.2f s, PLY %.1f MB"
          % (label, triangles, exp.stats["vertices"], seconds, size / 1e6))
shutil.rmtree(os.path.join(opts.out, "bench_export"), ignore_errors=True)
util.done("bench_export")
