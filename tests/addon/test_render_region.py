"""Issue 16, step 3: a render region (border) equals the same pixels of the full render (the engine passes
`--region` and loads the EXR crop). Skipped (77) while the executable cannot render."""
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
mod, glimmer = util.enable_addon_with_renderer()

W, H = 40, 30
scene = util.empty_exr_scene(W, H)
scene.glimmer.samples = 4
scene.glimmer.threads = 2
scene.glimmer.seed = 3
util.add_camera(scene, (0.3, -5.0, 2.5), (1.1, 0.0, 0.05))
util.set_world_color(scene, (0.2, 0.25, 0.3))
util.add_light(scene, "POINT", 500.0, (1.0, -2.0, 3.0))
bpy.ops.mesh.primitive_plane_add(size=8.0)
mat = bpy.data.materials.new("Checker")
mat.use_nodes = True
checker = mat.node_tree.nodes.new("ShaderNodeTexChecker")
checker.inputs["Scale"].default_value = 9.0
mat.node_tree.links.new(checker.outputs["Color"], mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
bpy.context.active_object.data.materials.append(mat)
bpy.ops.mesh.primitive_uv_sphere_add(location=(0.0, 0.0, 1.0))


def render(name):
    bpy.ops.render.render()
    path = os.path.join(opts.out, name + ".exr")
    bpy.data.images["Render Result"].save_render(path, scene=scene)
    img = bpy.data.images.load(path)
    w, h = img.size
    px = np.array(img.pixels[:], dtype=np.float64).reshape(h, w, 4)  # rows from the bottom, as Blender
    bpy.data.images.remove(img)
    return px


full = render("region_full")
check(full.shape == (H, W, 4), "full size %s" % (full.shape,))
check(full[..., :3].std() > 0.05, "the full image has structure")

scene.render.use_border = True
scene.render.use_crop_to_border = True
scene.render.border_min_x, scene.render.border_max_x = 0.23, 0.71
scene.render.border_min_y, scene.render.border_max_y = 0.18, 0.87
x0, x1 = int(0.23 * W), int(0.71 * W)  # Blender's own truncation (render_init_from_main), y up
y0, y1 = int(0.18 * H), int(0.87 * H)
region = mod.engine.border_region(scene.render, W, H)
check(region == (x0, H - y1, x1, H - y0), "renderer region %s (rows down)" % (region,))
crop = render("region_crop")
check(crop.shape == (y1 - y0, x1 - x0, 4), "crop size %s" % (crop.shape,))
expected = full[y0:y1, x0:x1]
diff = np.abs(crop - expected).max()
shifted = np.abs(crop - full[y0 + 1:y1 + 1, x0:x1]).max()  # negative control: one row off
print("region (%d,%d)-(%d,%d): max difference to the full render %.3g; one row off %.3g"
      % (x0, y0, x1, y1, diff, shifted))
check(diff <= 1e-6, "the region equals the full render's pixels (max difference %.3g)" % diff)
check(shifted > 100 * max(diff, 1e-6), "a one-row shift is detected (%.3g)" % shifted)

scene.render.use_crop_to_border = False  # Blender pastes the region into the full frame
pasted = render("region_pasted")
check(pasted.shape == (H, W, 4), "uncropped size %s" % (pasted.shape,))
check(np.abs(pasted[y0:y1, x0:x1] - expected).max() <= 1e-6, "the pasted region equals the full render")
util.done("test_render_region")
