"""Issue 16, step 4: the progressive viewport session, driven headless (no GPU: view_draw only uploads
session.pixels). It must bring at least two progressive images, restart on a change (the old renderer stopped,
the new image differs) and stop when cancelled. Prints the time to the first pixels.
Skipped (77) while the executable cannot render."""
import math
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
mod, glimmer = util.enable_addon_with_renderer()
check(hasattr(mod.engine.GlimmerRenderEngine, "view_update") and hasattr(mod.engine.GlimmerRenderEngine,
                                                                          "view_draw"), "viewport callbacks")

# The uncompressed EXR reader against oiiotool's own view of a known image.
probe = os.path.join(opts.out, "probe.exr")
import subprocess  # noqa: E402

subprocess.run(["oiiotool", "--pattern", "fill:topleft=1,0,0,1:topright=0,1,0,1:bottomleft=0,0,1,1:"
                "bottomright=1,1,1,0.5", "5x3", "4", "-d", "float", "--compression", "none", "-o", probe], check=True)
px = mod.viewport.read_uncompressed_exr(probe)
check(px.shape == (3, 5, 4), "probe shape %s" % (px.shape,))
check(np.allclose(px[0, 0], (1, 0, 0, 1)) and np.allclose(px[0, -1], (0, 1, 0, 1))
      and np.allclose(px[-1, 0], (0, 0, 1, 1)) and np.allclose(px[-1, -1], (1, 1, 1, 0.5)),
      "probe corners (top row first, RGBA): %s" % px[[0, 0, -1, -1], [0, -1, 0, -1]])

scene = util.empty_exr_scene(64, 48)
scene.glimmer.threads = 2
cam = util.add_camera(scene, (0.0, -6.0, 2.0), (1.35, 0.0, 0.0))
util.add_light(scene, "POINT", 800.0, (2.0, -2.0, 4.0))
util.set_world_color(scene, (0.2, 0.25, 0.3))
bpy.ops.mesh.primitive_plane_add(size=10.0)
bpy.ops.mesh.primitive_uv_sphere_add(location=(0.0, 0.0, 1.0))
sphere = bpy.context.active_object
view = {"matrix": np.array(cam.matrix_world), "fov": math.radians(39.6)}

session = mod.viewport.ViewportSession(glimmer)


def wait_for(condition, seconds):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and not condition():
        time.sleep(0.05)
    return condition()


W, H = 160, 120
session.start(bpy.context.evaluated_depsgraph_get(), W, H, view, samples=4096)
check(wait_for(lambda: session.updates >= 2, 120), "two progressive updates (%d, %s)" % (session.updates,
                                                                                          session.failure))
first = session.pixels.copy()
renderer_pid = session._proc.pid
print("viewport: first pixels after %.3f s; %d updates, sample %d" % (session.first_pixels_seconds,
                                                                       session.updates, session.samples_shown))
check(first.shape == (H, W, 4) and np.isfinite(first).all() and first[..., :3].max() > 0.05, "a real image")
check(wait_for(lambda: session.samples_shown >= 3, 60), "later samples shown")

# A change restarts: the old renderer stops, the new image shows the moved sphere.
sphere.location.x += 1.5
bpy.context.view_layer.update()
session.start(bpy.context.evaluated_depsgraph_get(), W, H, view, samples=4096)
check(wait_for(lambda: session.updates >= 2, 120), "updates after the restart (%s)" % session.failure)
moved = session.pixels.copy()
print("viewport restart: first pixels after %.3f s" % session.first_pixels_seconds)
check(session._proc.pid == renderer_pid, "the restart reuses the renderer process (glimmer serve)")
change = np.abs(moved[..., :3] - first[..., :3]).mean(axis=-1)
check((change > 0.2).mean() > 0.02, "the moved sphere is seen (%.3f of the pixels changed)" % (change > 0.2).mean())

# Cancelled: the renderer stops (SIGTERM -> exit 3, or killed) and no update follows.
start = time.monotonic()
session.stop()
stopped = time.monotonic() - start
count = session.updates
time.sleep(0.5)
print("viewport stop: %.2f s, exit code %s" % (stopped, session.exit_code))
check(not session.running() and session.exit_code is not None, "stopped (exit code %s)" % session.exit_code)
check(session.updates == count, "no update after stop")

# The engine's restart rule (view_update / view_draw -> _sync_view) with a stand-in engine and 3D view.
from types import SimpleNamespace  # noqa: E402

from mathutils import Matrix  # noqa: E402


class StandInEngine:
    _sync_view = mod.engine.GlimmerRenderEngine._sync_view
    watched = 0
    stats = ""

    def _watch_session(self):
        self.watched += 1

    def update_stats(self, _a, b):
        self.stats = b


def view_context(x):
    view_matrix = Matrix.Translation((x, 0.0, 0.0)) @ Matrix(cam.matrix_world).inverted()
    window = Matrix.Diagonal((2.7, 3.6, -1.0, 1.0))
    return SimpleNamespace(region=SimpleNamespace(width=2 * W, height=2 * H),
                           region_data=SimpleNamespace(view_matrix=view_matrix, window_matrix=window))


engine = StandInEngine()
depsgraph = bpy.context.evaluated_depsgraph_get()
engine._sync_view(view_context(0.0), depsgraph, scene_changed=False)
check(engine.watched == 1 and engine._session.running(), "the first draw starts a render")
check(wait_for(lambda: engine._session.updates >= 1, 120), "it brings images (%s)" % engine._session.failure)
engine._sync_view(view_context(0.0), depsgraph, scene_changed=False)
check(engine.watched == 1 and engine._session.updates >= 1, "an unchanged view keeps rendering")
engine._sync_view(view_context(0.3), depsgraph, scene_changed=False)
check(engine.watched == 2, "a moved view restarts")
engine._sync_view(view_context(0.3), depsgraph, scene_changed=True)
check(engine.watched == 3, "a scene update restarts")
check(wait_for(lambda: engine._session.updates >= 1, 120), "images after the restart")
check(engine._session.pixels.shape == (H, W, 4), "the viewport render is half the region's size")
engine._session.stop()
check(not engine._session.running(), "stopped")
util.done("test_viewport")
