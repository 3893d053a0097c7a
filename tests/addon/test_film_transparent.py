"""Issue 16: Film > Transparent. Rendered by the engine in Blender, the background has alpha 0 (and no colour:
premultiplied), the sphere alpha 1, its edge pixels fractional alpha; the result equals the CLI render of the export
(also the progressive updates' alpha); without Film Transparent alpha is 1 everywhere. Cycles renders the same
scene: mean alpha and the alpha of the edge pixels agree within the measured noise.
Skipped (77) while the executable cannot render."""
import math
import os
import subprocess
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
mod, glimmer = util.enable_addon_with_renderer()

W, H, SAMPLES = 40, 30, 32
scene = util.empty_exr_scene(W, H)
g = scene.glimmer
g.samples, g.threads, g.seed = SAMPLES, 2, 4
g.filter_type, g.filter_width = "box", 1.0
g.use_progressive, g.progressive_interval = True, 0.0
g.export_dir, g.keep_export = os.path.join(opts.out, "export"), True
scene.render.film_transparent = True
util.add_camera(scene, (0.0, -6.0, 1.0), (math.radians(90.0), 0.0, 0.0))
util.set_world_color(scene, (0.2, 0.25, 0.3))
util.add_light(scene, "POINT", 500.0, (1.0, -2.0, 3.0))
bpy.ops.mesh.primitive_uv_sphere_add(location=(0.0, 0.0, 1.0))

updates = []
_show = mod.engine.GlimmerRenderEngine.show_progress


def recording_show(self, result, image, done, total):
    shown = _show(self, result, image, done, total)
    if shown is not None:
        updates.append(mod.viewport.read_uncompressed_exr(shown[1]))
    return shown


mod.engine.GlimmerRenderEngine.show_progress = recording_show


def render(name):
    """The render result as RGBA, top row first."""
    bpy.ops.render.render()
    path = os.path.join(opts.out, name + ".exr")
    bpy.data.images["Render Result"].save_render(path, scene=scene)
    return load(path)


def load(path):
    img = bpy.data.images.load(path)
    w, h = img.size
    px = np.array(img.pixels[:], dtype=np.float64).reshape(h, w, 4)[::-1]
    bpy.data.images.remove(img)
    return px


px = render("transparent")
alpha = px[..., 3]
corners = np.array([alpha[0, 0], alpha[0, -1], alpha[-1, 0], alpha[-1, -1]])
edge = (alpha > 0.0) & (alpha < 1.0)
print("alpha: corners %s, centre %.3f, %d edge pixels, %d opaque, %d transparent"
      % (corners, alpha[H // 2, W // 2], edge.sum(), (alpha == 1.0).sum(), (alpha == 0.0).sum()))
check((corners == 0.0).all(), "alpha 0 on the background: %s" % corners)
check((px[alpha == 0.0, :3] == 0.0).all(), "no background colour where alpha is 0 (premultiplied)")
check(alpha[H // 2, W // 2] == 1.0, "alpha 1 on the sphere")
check(edge.sum() >= 8, "fractional alpha on the sphere's edge (%d pixels)" % edge.sum())
check(px[H // 2, W // 2, :3].max() > 0.05, "the sphere is lit")

# The CLI render of the same export, and the progressive updates' alpha.
xml = os.path.join(g.export_dir, "frame_%04d" % scene.frame_current, "scene.xml")
with open(xml) as f:
    check('<background transparent="true">' in f.read(), "exported as <background transparent=\"true\">")
cli = os.path.join(opts.out, "cli.exr")
subprocess.run(mod.runner.render_command(glimmer, xml, cli, SAMPLES, 2, 4, W, H) + ["--quiet"], check=True)
rgba = os.path.join(opts.out, "cli_rgba.exr")
subprocess.run(["oiiotool", cli, "--ch", "ViewLayer.Combined.R,ViewLayer.Combined.G,ViewLayer.Combined.B,"
                "ViewLayer.Combined.A", "--chnames", "R,G,B,A", "-d", "float", "-o", rgba], check=True)
diff = np.abs(load(rgba) - px).max()
check(diff <= 1e-6, "Blender's result equals the CLI render (max difference %.3g)" % diff)
check(len(updates) >= 1 and all((u[0, 0, 3] == 0.0) and (u[H // 2, W // 2, 3] == 1.0) for u in updates),
      "progressive updates carry alpha (%d updates)" % len(updates))

# Negative control: without Film Transparent alpha is 1 and the background shows the world colour.
scene.render.film_transparent = False
opaque = render("opaque")
check((opaque[..., 3] == 1.0).all(), "alpha 1 without Film Transparent")
check(abs(opaque[0, 0, 2] - 0.3) < 1e-3, "the world colour without Film Transparent (%.4f)" % opaque[0, 0, 2])

# Cycles: the same scene's alpha (box filter 1 px, same samples).
scene.render.film_transparent = True
scene.render.engine = "CYCLES"
c = scene.cycles
c.device, c.samples, c.use_adaptive_sampling, c.use_denoising = "CPU", SAMPLES, False, False
c.pixel_filter_type, c.filter_width = "BOX", 1.0
cycles_alpha = render("cycles")[..., 3]
d = alpha - cycles_alpha
sigma = d.std() / math.sqrt(d.size)
edge_any = edge | ((cycles_alpha > 0.0) & (cycles_alpha < 1.0))
print("mean alpha: glimmer %.4f, cycles %.4f (difference %.4f, sigma %.4f); edge pixels %.4f vs %.4f"
      % (alpha.mean(), cycles_alpha.mean(), d.mean(), sigma, alpha[edge_any].mean(), cycles_alpha[edge_any].mean()))


def inner(mask):
    """Pixels of mask whose four neighbours are in it too (away from the edge, where the samples differ)."""
    m = mask.copy()
    m[1:] &= mask[:-1]
    m[:-1] &= mask[1:]
    m[:, 1:] &= mask[:, :-1]
    m[:, :-1] &= mask[:, 1:]
    return m


check((cycles_alpha[inner(alpha == 1.0)] == 1.0).all() and (cycles_alpha[inner(alpha == 0.0)] == 0.0).all(),
      "opaque and transparent pixels away from the edge agree with Cycles")
check(abs(d.mean()) <= 4.0 * sigma + 0.003 * cycles_alpha.mean(), "mean alpha as Cycles'")
util.done("test_film_transparent")
