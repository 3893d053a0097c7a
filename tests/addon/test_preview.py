"""Issue 16, step 4: a material preview renders with Glimmer (bl_use_preview).

Blender 3.4 in background mode crashes when a preview job ends (Cycles' preview too: the job's end wants a
window), so the preview runs in a child Blender (this script with --child). The child wraps the engine's EXR loading
to copy the image it hands to the preview and writes what the engine saw; the parent checks those files, whatever
the child's exit code. Skipped (77) while the executable cannot render."""
import json
import os
import shutil
import subprocess
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
CHILD = "--child" in sys.argv
if CHILD:
    sys.argv.remove("--child")
opts = util.args()
mod, glimmer = util.enable_addon_with_renderer()
out = os.path.join(opts.out, "preview")

if not CHILD:
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    cmd = [bpy.app.binary_path, "-b", "--factory-startup", "--python", os.path.abspath(__file__), "--",
           "--glimmer", glimmer, "--out", opts.out, "--child"]  # BLENDER_USER_* come from the environment
    try:
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=240,
                              env=dict(os.environ, GLIMMER_EXECUTABLE=glimmer))
        log, code = proc.stdout.decode(errors="replace"), proc.returncode
    except subprocess.TimeoutExpired as e:  # the child's output so far says where it stopped
        log, code = (e.stdout or b"").decode(errors="replace") + "\n(child killed after 240 s)", -1
    print(log[-3000:])
    info_path = os.path.join(out, "preview.json")
    check(os.path.isfile(info_path), "the child's engine rendered a preview (exit code %d)" % code)
    info = json.load(open(info_path))
    print("preview:", info)
    check(info["is_preview"], "rendered as a preview")
    check(info["samples"] == mod.engine.PREVIEW_SAMPLES, "preview samples %s" % info["samples"])
    combined = [c for c in mod.engine.exr_channels(info["exr"]) if ".Combined." in c]
    layer = combined[0].split(".Combined.")[0]
    rgba = os.path.join(out, "preview_rgba.exr")
    subprocess.run(["oiiotool", info["exr"], "--ch", ",".join("%s.Combined.%s" % (layer, c) for c in "RGBA"),
                    "--chnames", "R,G,B,A", "-d", "float", "-o", rgba], check=True)
    img = bpy.data.images.load(rgba)
    import numpy as np

    w, h = img.size
    px = np.array(img.pixels[:]).reshape(h, w, 4)[..., :3]
    check(w >= 64 and h >= 64, "preview size %dx%d" % (w, h))
    centre = px[h // 2 - 8:h // 2 + 8, w // 2 - 8:w // 2 + 8].reshape(-1, 3).mean(axis=0)
    print("preview centre (the red preview sphere):", centre)
    check(np.isfinite(px).all(), "finite pixels")
    check(centre[0] > 0.05 and centre[0] > 3.0 * max(centre[1], centre[2]), "the red material is seen: %s" % centre)
    util.done("test_preview")
    sys.exit(0)

# -- child: render the preview of a red material -----------------------------------------------------------------
bpy.context.scene.render.engine = "GLIMMER"
mat = bpy.data.materials.new("PreviewRed")
mat.use_nodes = True
mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.9, 0.02, 0.02, 1.0)
engine_cls = mod.engine.GlimmerRenderEngine
seen = {}
_load = mod.engine.load_exr_into_result
_render_command = mod.runner.render_command


def recording_render_command(*args, **kwargs):
    seen["samples"] = args[3]  # (executable, scene, output, samples, ...)
    return _render_command(*args, **kwargs)


def recording_load(result, path, layer_name):
    copy = os.path.join(out, "preview.exr")
    shutil.copy(path, copy)
    _load(result, path, layer_name)
    info_path = os.path.join(out, "preview.json")
    with open(info_path + ".part", "w") as f:
        json.dump({"exr": copy, "is_preview": seen.get("is_preview"), "samples": seen.get("samples")}, f)
    os.replace(info_path + ".part", info_path)  # the main thread sees the whole file or none
    print("child: preview written", flush=True)


_render = engine_cls.render


def recording_render(self, depsgraph):
    seen["is_preview"] = bool(self.is_preview)
    _render(self, depsgraph)


mod.engine.load_exr_into_result = recording_load
mod.runner.render_command = recording_render_command
engine_cls.render = recording_render
with bpy.context.temp_override(id=mat):
    bpy.ops.ed.lib_id_generate_preview()
deadline = time.monotonic() + 200
while time.monotonic() < deadline and not os.path.isfile(os.path.join(out, "preview.json")):
    time.sleep(0.2)  # the preview job runs in its own thread
# Not sys.exit: Blender's exit (run from Python's atexit, holding the GIL) waits for the preview job's thread, which
# may still be in the engine's Python code after the load above and waits for the GIL: a deadlock (seen in CI, where
# the child hung until the parent's timeout). The files the parent reads are complete; leave at once.
sys.stdout.flush()
os._exit(0 if os.path.isfile(os.path.join(out, "preview.json")) else 1)
