"""Time to first viewport pixels after a change, on the demo scene (make_demo_blend.py), 120x80 viewport render.

Measures, interleaved in one run, the viewport session of this addon (one persistent `glimmer serve` process, the
renderer's display image read with numpy) and, when --before names a folder holding an earlier version of the
addon's `glimmer` package (e.g. `git archive <commit> blender_addon/glimmer | tar -x -C DIR`), that version's
session (a `glimmer render` process per change, checkpoint -> means with oiiotool). Each change moves the cube by
1 cm and restarts the session; the time is from start() (export included) to the first image.

    blender -b --factory-startup --python tests/addon/bench_viewport.py -- --glimmer build/glimmer \\
        [--before DIR] [--changes 7]

Part of `make stress` (label stress) without --before."""
import argparse
import importlib
import importlib.util
import math
import os
import statistics
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402
import make_demo_blend  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
parser = argparse.ArgumentParser()
parser.add_argument("--glimmer", default=os.environ.get("GLIMMER_EXECUTABLE", ""))
parser.add_argument("--out", default="")
parser.add_argument("--before", default="", help="folder containing an earlier `glimmer` addon package")
parser.add_argument("--changes", type=int, default=7)
opts = parser.parse_args(argv)
glimmer = os.path.abspath(opts.glimmer)
os.environ["GLIMMER_EXECUTABLE"] = glimmer
mod = util.enable_addon()

W, H = 120, 80
make_demo_blend.build_scene(argparse.Namespace(samples=32, width=480, height=320))
scene = bpy.context.scene
scene.glimmer.threads = 2
cube = bpy.data.objects["Cube"]
camera = scene.camera
view = {"matrix": np.array(camera.matrix_world), "fov": 2.0 * math.atan(18.0 / camera.data.lens)}

sessions = {"after": mod.viewport.ViewportSession(glimmer)}
if opts.before:
    # The earlier package is imported under another name so that both versions live side by side.
    spec = importlib.util.spec_from_file_location(
        "glimmer_before", os.path.join(os.path.abspath(opts.before), "glimmer", "__init__.py"),
        submodule_search_locations=[os.path.join(os.path.abspath(opts.before), "glimmer")])
    package = importlib.util.module_from_spec(spec)
    sys.modules["glimmer_before"] = package
    before = importlib.import_module("glimmer_before.viewport")
    sessions["before"] = before.ViewportSession(glimmer)


def first_pixels(session):
    cube.location.x += 0.01
    bpy.context.view_layer.update()
    session.start(bpy.context.evaluated_depsgraph_get(), W, H, view)
    deadline = time.monotonic() + 120
    while session.first_pixels_seconds is None and time.monotonic() < deadline:
        time.sleep(0.002)
    if session.first_pixels_seconds is None:
        raise AssertionError("no image within 120 s: %s" % session.failure)
    return session.first_pixels_seconds


times = {name: [] for name in sessions}
for name, session in sessions.items():
    first_pixels(session)  # the first start (process start-up for both): not a change
for _ in range(opts.changes):
    for name, session in sessions.items():
        times[name].append(first_pixels(session))
for name, session in sessions.items():
    session.stop()
    t = times[name]
    print("viewport %s: time to first pixels after a change, %d changes: median %.3f s (min %.3f, max %.3f): %s"
          % (name, len(t), statistics.median(t), min(t), max(t), " ".join("%.3f" % v for v in t)))
if "before" in times:
    print("viewport: median after / before = %.3f" % (statistics.median(times["after"])
                                                     / statistics.median(times["before"])))
util.done("bench_viewport")
