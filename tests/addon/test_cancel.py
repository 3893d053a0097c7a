"""Cancellation: test_break stops the renderer (SIGTERM, SIGKILL after the
timeout), the partial image is loaded, end_result runs, nothing is left running.

Uses tests/addon/fake_glimmer.py (the CLI's process protocol, deterministic
timing); with the real `glimmer render` available the engine path is also
run against it."""
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
real_glimmer = os.environ.get("GLIMMER_EXECUTABLE", "")
fake = os.path.join(util.HERE, "fake_glimmer.py")
os.chmod(fake, 0o755)
mod = util.enable_addon()
runner = mod.runner


def process_alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


scene_xml = os.path.join(opts.out, "cancel_scene.xml")
with open(scene_xml, "w") as f:
    f.write("<cycles></cycles>\n")
exr = os.path.join(opts.out, "cancel.exr")

os.environ["FAKE_SAMPLE_SECONDS"] = "0.1"  # full renders below take 20 s and 40 s: cancels are far earlier

# 1. Runner: progress parsing and SIGTERM -> exit 3 with the partial image.
progress = []
start = time.monotonic()
code, cancelled, tail = runner.run(
    runner.render_command(fake, scene_xml, exr, 200, 1, 0, 16, 8),
    on_progress=lambda n, total: progress.append((n, total)),
    should_cancel=lambda: len(progress) >= 5, kill_timeout=5.0)
elapsed = time.monotonic() - start
print("runner cancel: code", code, "after", progress[-1], "in %.2f s" % elapsed)
check(cancelled and code == runner.EXIT_INTERRUPTED, "SIGTERM gives exit 3 (got %s)" % code)
check(progress[:5] == [(i, 200) for i in range(1, 6)], "Sample n/N parsed in order: %s" % progress[:5])
check(progress[-1][0] < 200 and elapsed < 10.0, "stopped early (%s, %.2f s)" % (progress[-1], elapsed))
check(os.path.isfile(exr), "partial image written")
check(any("interrupted" in line for line in tail), "other output lines kept: %s" % tail)

# 2. Runner: a renderer ignoring SIGTERM is killed after the timeout.
os.environ["FAKE_IGNORE_TERM"] = "1"
progress.clear()
start = time.monotonic()
code, cancelled, _ = runner.run(runner.render_command(fake, scene_xml, exr, 400, 1, 0, 16, 8),
                                on_progress=lambda n, total: progress.append(n),
                                should_cancel=lambda: len(progress) >= 3, kill_timeout=0.5)
elapsed = time.monotonic() - start
del os.environ["FAKE_IGNORE_TERM"]
print("runner kill: code", code, "in %.2f s" % elapsed)
check(cancelled and code == -9, "killed with SIGKILL (code %s)" % code)
check(elapsed < 10.0, "kill after the 0.5 s timeout, not at the end of the render (%.2f s)" % elapsed)

# 3. Engine: cancel a render through Blender; the partial image reaches the render result.
scene = util.empty_exr_scene(16, 8)
scene.glimmer.samples = 100
cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
scene.collection.objects.link(cam)
scene.camera = cam
bpy.ops.mesh.primitive_plane_add(location=(0, 0, -3))

engine_cls = mod.engine.GlimmerRenderEngine
calls = {"n": 0}
progress_file = os.path.join(opts.out, "fake_progress.txt")


def samples_done():
    try:
        with open(progress_file) as f:
            return int(f.read() or 0)
    except (OSError, ValueError):
        return 0


def break_after_three_samples(self):  # the fake renderer reports its progress in a file
    calls["n"] += 1
    return samples_done() >= 3


def break_after_a_while(self):  # the real renderer: about 8 polls of 50 ms
    calls["n"] += 1
    return calls["n"] > 8


def render_and_read(path, layer_name=None):
    if layer_name:
        scene.view_layers[0].name = layer_name
    bpy.ops.render.render()
    bpy.data.images["Render Result"].save_render(path, scene=scene)
    img = bpy.data.images.load(path)
    px = np.array(img.pixels[:]).reshape(-1, 4)
    bpy.data.images.remove(img)
    return px


os.environ["GLIMMER_EXECUTABLE"] = fake
os.environ["FAKE_PROGRESS_FILE"] = progress_file
os.environ["FAKE_SAMPLE_SECONDS"] = "0.2"  # 100 samples: 20 s uncancelled
if os.path.exists(progress_file):
    os.remove(progress_file)
engine_cls.cancel_requested = break_after_three_samples
try:
    start = time.monotonic()
    px = render_and_read(os.path.join(opts.out, "cancel_engine.exr"))
    elapsed = time.monotonic() - start
    red = px[:, 0]
    print("engine cancel: red %.3f, %d polls, %.2f s" % (red.mean(), calls["n"], elapsed))
    check(0.03 - 1e-6 <= red.mean() < 0.5, "partial image (fraction done %.3f) loaded into the result" % red.mean())
    check(np.allclose(px[:, 1], 0.5) and np.allclose(px[:, 2], 0.25), "green/blue of the fake image")
    check(elapsed < 12.0, "cancelled render returned well before the 20 s render (%.2f s)" % elapsed)
    os.environ["FAKE_SAMPLE_SECONDS"] = "0.01"

    # A view layer not named ViewLayer: channels renamed before loading.
    engine_cls.cancel_requested = lambda self: False
    scene.glimmer.samples = 3
    px = render_and_read(os.path.join(opts.out, "full_engine.exr"), layer_name="Beauty")
    check(np.allclose(px[:, 0], 1.0) and np.allclose(px[:, 1], 0.5), "full image loaded into view layer Beauty: %s" % px[:2])
    scene.view_layers[0].name = "ViewLayer"

    # A failing renderer: its message reaches Blender's error report, the result is still ended.
    os.environ["FAKE_FAIL"] = "1"
    try:
        bpy.ops.render.render()
        failed_message = ""
    except RuntimeError as e:
        failed_message = str(e)
    del os.environ["FAKE_FAIL"]
    print("failing renderer:", failed_message.strip().splitlines()[:2])
    check("exit code 1" in failed_message and "fake failure" in failed_message,
          "renderer failure reported: %r" % failed_message)

    # The real renderer, when it can render: cancellation returns fast and leaves no process.
    if real_glimmer and runner.supports_render(real_glimmer):
        os.environ["GLIMMER_EXECUTABLE"] = real_glimmer
        scene.glimmer.samples = 100000
        scene.render.resolution_x, scene.render.resolution_y = 64, 48
        calls["n"] = 0
        engine_cls.cancel_requested = break_after_a_while
        start = time.monotonic()
        render_and_read(os.path.join(opts.out, "cancel_real.exr"))
        elapsed = time.monotonic() - start
        print("real renderer cancelled in %.2f s" % elapsed)
        check(elapsed < 30.0, "real renderer cancelled (%.2f s)" % elapsed)
    else:
        print("note: `glimmer render` not available, engine cancel checked with the fake renderer only")
finally:
    del engine_cls.cancel_requested
util.done("test_cancel")
