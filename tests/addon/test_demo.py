"""Acceptance path: make_demo_blend.py writes a .blend and enables the addon in
the user's preferences, the plain `blender -b demo.blend -E GLIMMER -f 1`
renders it to PNG (both with HOME in a scratch folder, so the user's own
Blender configuration is not touched), and the glint sphere is
visible (lit, distinct from the sky behind it, and sparkling once the DSO has
the glint closure). Skipped (77) only while
`glimmer render` does not exist."""
import os
import subprocess
import sys

import bpy
import numpy as np
from bpy_extras.object_utils import world_to_camera_view

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
mod, glimmer = util.enable_addon_with_renderer()

blender = bpy.app.binary_path
blend = os.path.join(opts.out, "demo.blend")
png = os.path.join(opts.out, "demo_glint_0001.png")
if os.path.exists(png):
    os.remove(png)
home = os.path.join(opts.out, "home")
env = {k: v for k, v in os.environ.items() if not k.startswith("BLENDER_USER_")}
env["HOME"] = home
env.pop("XDG_CONFIG_HOME", None)
subprocess.run([blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python",
                os.path.join(util.HERE, "make_demo_blend.py"), "--", "--output", blend,
                "--width", "240", "--height", "160", "--samples", "16"], check=True, env=env)
render = subprocess.run([blender, "-b", blend, "-E", "GLIMMER", "-f", "1"], env=env,
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
log = render.stdout.decode(errors="replace")
print(log[-3000:])
check(render.returncode == 0, "blender -E GLIMMER -f 1 exit code %d" % render.returncode)
check(os.path.isfile(png), "rendered image written: %s" % png)

bpy.ops.wm.open_mainfile(filepath=blend)
scene = bpy.context.scene
img = bpy.data.images.load(png)
width, height = img.size
px = np.array(img.pixels[:]).reshape(height, width, 4)[..., :3]  # rows from the bottom
luminance = px @ np.array([0.2126, 0.7152, 0.0722])
sphere = bpy.data.objects["GlintSphere"]
centre = world_to_camera_view(scene, scene.camera, sphere.matrix_world.translation)
cx, cy = int(centre.x * width), int(centre.y * height)
region = luminance[cy - 6:cy + 7, cx - 6:cx + 7]
sky = luminance[height - 8:, :8]  # top-left corner: sky
print("glint sphere region: mean %.4f max %.4f; sky %.4f" % (region.mean(), region.max(), sky.mean()))
check(region.max() > 0.05, "the glint sphere reflects the light (max luminance %.4f)" % region.max())
check(abs(region.mean() - sky.mean()) > 0.01, "the glint sphere stands out from the sky")
schema, _, _ = mod.current_schema()
if any(c["name"] == "glint" and c.get("source") == "dso" for c in schema["closures"]):
    # The glint closure renders sparkles: a few very bright pixels over a darker base, unlike the smooth
    # shading of a diffuse fallback.
    wide = luminance[cy - 12:cy + 13, cx - 12:cx + 13]
    p99, median = np.percentile(wide, 99), np.median(wide)
    print("glint sparkle contrast: p99 %.3f / median %.3f = %.2f" % (p99, median, p99 / max(median, 1e-6)))
    check(p99 > 2.0 * median, "glints visible: 99th percentile %.3f > 2 x median %.3f" % (p99, median))
util.done("test_demo")
