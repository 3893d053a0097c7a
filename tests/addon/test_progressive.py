"""Issue 16, step 4: a final render shows progressive updates (the renderer's display images: means, alpha).

Each update at n samples must equal the CLI render of the same scene with n samples (same seed: the first n
samples of a longer render are the n-sample render), and there must be at least two before the end.
Skipped (77) while the executable cannot render."""
import os
import shutil
import subprocess
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
mod, glimmer = util.enable_addon_with_renderer()
out = os.path.join(opts.out, "progressive")
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)

W, H, SAMPLES = 160, 120, 24  # a pass takes long enough to show its checkpoint
scene = util.empty_exr_scene(W, H)
scene.glimmer.samples = SAMPLES
scene.glimmer.threads = 1
scene.glimmer.seed = 9
scene.glimmer.film_exposure = 1.5
scene.glimmer.use_progressive = True
scene.glimmer.progressive_interval = 0.0  # after every sample pass
scene.glimmer.export_dir = os.path.join(out, "export")
scene.glimmer.keep_export = True
util.add_camera(scene, (0.0, -6.0, 2.0), (1.35, 0.0, 0.0))
util.add_light(scene, "AREA", 300.0, (1.0, -1.0, 4.0))
bpy.ops.mesh.primitive_plane_add(size=10.0)
bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, location=(0.0, 0.0, 1.0))

updates = []  # (samples done, copy of the progressive image)
_show = mod.engine.GlimmerRenderEngine.show_progress


def recording_show(self, result, image, done, total):
    shown = _show(self, result, image, done, total)
    if shown is not None:
        copy = os.path.join(out, "update_%03d.exr" % shown[0])
        shutil.copy(shown[1], copy)
        updates.append((shown[0], total, copy))
    return shown


mod.engine.GlimmerRenderEngine.show_progress = recording_show
bpy.ops.render.render()
print("progressive updates (samples):", [u[0] for u in updates])
before_end = [u for u in updates if u[0] < SAMPLES]  # the renderer also shows its last pass
check(len(before_end) >= 2, "at least two progressive updates before the end: %s" % updates)
check(all(total == SAMPLES for _, total, _ in updates), "of %d samples" % SAMPLES)
check(all(a[0] <= b[0] for a, b in zip(updates, updates[1:])), "sample counts never shrink")
check(before_end[0][0] < before_end[-1][0], "updates at different sample counts before the end")


def pixels(path):
    img = bpy.data.images.load(path)
    px = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px


xml = os.path.join(scene.glimmer.export_dir, "frame_%04d" % scene.frame_current, "scene.xml")
checked = [updates[0], updates[len(updates) // 2]]
for done, _, path in checked:
    cli = os.path.join(out, "cli_%03d.exr" % done)
    cmd = mod.runner.render_command(glimmer, xml, cli, done, 1, 9, W, H)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    rgba = os.path.join(out, "cli_%03d_rgba.exr" % done)
    subprocess.run(["oiiotool", cli, "--ch", "ViewLayer.Combined.R,ViewLayer.Combined.G,ViewLayer.Combined.B,"
                    "ViewLayer.Combined.A", "--chnames", "R,G,B,A", "-d", "float", "-o", rgba], check=True)
    a, b = pixels(path), pixels(rgba)
    diff = np.abs(a - b).max() / max(np.abs(b[..., :3]).max(), 1e-6)
    print("update at %d samples vs CLI %d-sample render: max relative difference %.3g, mean %.4f"
          % (done, done, diff, b[..., :3].mean()))
    check(np.isfinite(a).all() and (a[..., 3] == 1.0).all(), "finite, alpha 1")
    check(diff <= 1e-5, "update at %d samples equals the %d-sample render (%.3g)" % (done, done, diff))
# Negative control: the first update differs from the final image (it is not just the final image).
final = os.path.join(out, "final.exr")
bpy.data.images["Render Result"].save_render(final, scene=scene)
first, last = pixels(updates[0][2]), pixels(final)
noise = np.abs(first[..., :3] - last[..., :3]).max()
print("first update vs final: max difference %.3g" % noise)
check(noise > 1e-3, "the first update is an earlier image")
util.done("test_progressive")
