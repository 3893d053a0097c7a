"""The Glimmer RenderEngine: export, run `glimmer render`, load the EXR."""
import os
import re
import shutil
import struct
import subprocess
import tempfile
import time
import traceback

import bpy
import numpy as np

from . import exporter as exporter_mod
from . import preferences
from . import runner
from . import viewport

KILL_TIMEOUT_SECONDS = 5.0
# The renderer's EXR passes besides Combined (docs/cli.md), handed to Blender (its Denoise node takes Albedo and
# Normal): (pass name, channels, channel ids, compositor socket type, the view layer's switch for Blender's own pass).
AOV_PASSES = (("Albedo", 3, "RGB", "COLOR", None), ("Normal", 3, "XYZ", "VECTOR", "use_pass_normal"),
              ("Depth", 1, "Z", "VALUE", "use_pass_z"))
# Material/world/light preview thumbnails (Blender's preview scene, 128 px and smaller): samples per pixel.
PREVIEW_SAMPLES = 16

# Warnings already reported in this render job: an animation reports each warning once, not once per frame.
_reported = set()


def border_region(render, width, height):
    """Blender's render region (border) as the renderer's pixel rectangle (x0, y0, x1, y1), top row 0, x1/y1
    exclusive, or None without a border. Blender truncates border * size to pixels with y up
    (render_init_from_main); the renderer's rows go down."""
    if not render.use_border:
        return None
    x0, x1 = int(render.border_min_x * width), int(render.border_max_x * width)
    y0_up, y1_up = int(render.border_min_y * height), int(render.border_max_y * height)
    if x1 <= x0 or y1_up <= y0_up:
        return None
    return (x0, height - y1_up, x1, height - y0_up)


def executable_problem(executable):
    """Why executable cannot be run (None when it can)."""
    if not executable:
        return "no glimmer executable (set it in the addon preferences or put `glimmer` on PATH)"
    if not os.path.isfile(executable):
        return "the glimmer executable '%s' does not exist (addon preferences > Glimmer Executable)" % executable
    if not os.access(executable, os.X_OK):
        return ("the glimmer executable '%s' is not executable (chmod +x it, or fix addon preferences > "
                "Glimmer Executable)" % executable)
    return None


def exr_attributes(path):
    """The header attributes of an OpenEXR file: {name: (type name, raw value bytes)} (reads the header only)."""
    with open(path, "rb") as f:
        data = f.read(1 << 16)
    if data[:4] != b"\x76\x2f\x31\x01":
        raise ValueError("%s is not an OpenEXR file" % path)
    attributes, pos = {}, 8
    while pos < len(data) and data[pos] != 0:
        name_end = data.index(b"\0", pos)
        type_end = data.index(b"\0", name_end + 1)
        size = struct.unpack_from("<i", data, type_end + 1)[0]
        value_start = type_end + 5
        attributes[data[pos:name_end].decode()] = (data[name_end + 1:type_end].decode(),
                                                   data[value_start:value_start + size])
        pos = value_start + size
    return attributes


def exr_channels(path):
    """Channel names of an OpenEXR file."""
    value = exr_attributes(path).get("channels")
    if value is None:
        raise ValueError("%s has no channel list" % path)
    channels, p, raw = [], 0, value[1]
    while raw[p] != 0:
        end = raw.index(b"\0", p)
        channels.append(raw[p:end].decode())
        p = end + 1 + 16  # pixel type, pLinear + reserved, x/y sampling
    return channels


def load_exr_into_result(result, path, layer_name):
    """Copy the EXR's Combined pass into the render result.

    Multilayer files (`<layer>.Combined.R` ...) go through RenderResult.load_from_file, which matches
    layer and pass names; when the file's layer name differs from the view layer's, the channels are
    renamed with oiiotool first. Plain RGBA files are loaded into the first layer."""
    channels = exr_channels(path)
    combined = [c for c in channels if ".Combined." in c]
    if not combined:
        result.layers[0].load_from_file(path)
        return
    file_layer = combined[0].split(".Combined.")[0]
    if file_layer == layer_name:
        result.load_from_file(path)
        return
    oiiotool = shutil.which("oiiotool")
    if oiiotool is None:
        raise RuntimeError("the EXR's layer is '%s' but the view layer is '%s'; renaming needs oiiotool "
                           "(Debian package openimageio-tools)" % (file_layer, layer_name))
    # --chnames follows OpenImageIO's channel order (R, G, B, A first), not the file's alphabetical one.
    info = subprocess.run([oiiotool, "--info", "-v", path], check=True, stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, timeout=60).stdout.decode(errors="replace")
    listed = next(line.split(":", 1)[1] for line in info.splitlines() if line.strip().startswith("channel list:"))
    ordered = [c.strip() for c in listed.split(",")]
    renamed = [layer_name + c[len(file_layer):] if c.startswith(file_layer + ".") else c for c in ordered]
    fixed = path[:-4] + "_" + "".join(ch if ch.isalnum() else "_" for ch in layer_name) + ".exr"
    subprocess.run([oiiotool, path, "--chnames", ",".join(renamed), "-o", fixed], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, timeout=120)
    result.load_from_file(fixed)


class GlimmerRenderEngine(bpy.types.RenderEngine):
    bl_idname = "GLIMMER"
    bl_label = "Glimmer"
    bl_use_preview = True  # material, world and light previews render Blender's preview scene with Glimmer
    bl_use_shading_nodes_custom = False  # Cycles' shader nodes are used as they are
    bl_use_postprocess = True

    def render(self, depsgraph):
        scene = depsgraph.scene
        settings = scene.glimmer
        scale = scene.render.resolution_percentage / 100.0
        width = max(1, int(scene.render.resolution_x * scale))
        height = max(1, int(scene.render.resolution_y * scale))
        layer_name = depsgraph.view_layer.name
        preview = self.is_preview
        if not preview and (not self.is_animation or scene.frame_current == scene.frame_start):
            _reported.clear()
        if not preview:
            for name, channels, chan_id, _, builtin in AOV_PASSES:
                if builtin is None or not getattr(depsgraph.view_layer, builtin, False):
                    self.add_pass(name, channels, chan_id, layer=layer_name)
        region = border_region(scene.render, width, height)  # Blender's result is just the region then
        result_width, result_height = (region[2] - region[0], region[3] - region[1]) if region else (width, height)
        result = self.begin_result(0, 0, result_width, result_height, layer=layer_name)
        out_dir = None
        temporary = False
        try:
            executable = preferences.executable_path()
            problem = executable_problem(executable)
            if problem is not None:
                self.fail("Glimmer: " + problem)
                return
            if settings.export_dir and not preview:
                out_dir = os.path.join(bpy.path.abspath(settings.export_dir), "frame_%04d" % scene.frame_current)
                os.makedirs(out_dir, exist_ok=True)
            else:
                out_dir = tempfile.mkdtemp(prefix="glimmer_")
                temporary = not settings.keep_export
            self.update_stats("", "Glimmer: exporting the scene")
            start = time.monotonic()
            # A preview's warnings are about Blender's preview scene, not the artist's: not reported.
            xml_path, exp = exporter_mod.export_scene(depsgraph, out_dir, report=None if preview else self.report_once,
                                                      width=width, height=height)
            export_seconds = time.monotonic() - start
            print("Glimmer: exported %d objects, %d triangles, %d lights to %s in %.2f s"
                  % (exp.stats["objects"], exp.stats["triangles"], exp.stats["lights"], xml_path, export_seconds))
            exr_path = os.path.join(out_dir, "render.exr")
            if os.path.exists(exr_path):
                os.remove(exr_path)
            seed = settings.seed + (scene.frame_current if settings.use_animated_seed else 0)
            samples = min(settings.samples, PREVIEW_SAMPLES) if preview else settings.samples
            progressive = settings.use_progressive and not preview
            display = os.path.join(out_dir, "progress.exr") if progressive else None
            cmd = runner.render_command(executable, xml_path, exr_path, samples, settings.threads,
                                        seed, width, height, region, display, settings.progressive_interval)
            render_start = time.monotonic()

            def progress(done, total):
                self.update_progress(done / max(total, 1))
                elapsed = time.monotonic() - render_start
                self.update_stats("", "Glimmer: sample %d/%d, %.1f s" % (done, total, elapsed))

            def renderer_line(line):  # the renderer's scene warnings (file:line) go to Blender's report
                shown = runner.DISPLAY_LINE.match(line)
                if shown and progressive:
                    self.show_progress(result, shown.group(3), int(shown.group(1)), int(shown.group(2)))
                elif "warning" in line.lower() and not preview:
                    self.report_once({"WARNING"}, "glimmer: " + line)

            code, cancelled, tail = runner.run(cmd, on_progress=progress, should_cancel=self.cancel_requested,
                                               kill_timeout=KILL_TIMEOUT_SECONDS, on_line=renderer_line)
            have_image = os.path.isfile(exr_path)
            if have_image and (code == 0 or code == runner.EXIT_INTERRUPTED):
                load_exr_into_result(result, exr_path, layer_name)
                print("Glimmer: rendered in %.2f s (%s)" % (time.monotonic() - render_start,
                                                             "cancelled, partial image" if cancelled else "done"))
            elif cancelled:
                print("Glimmer: render cancelled")
            else:
                self.fail("Glimmer: `glimmer render` failed with exit code %s:\n%s" % (code, "\n".join(tail[-10:])))
        except Exception as e:  # noqa: BLE001 - every failure becomes a Blender error report
            traceback.print_exc()  # the console keeps the details; the report says what failed
            self.fail("Glimmer: %s: %s" % (type(e).__name__, e))
        finally:
            self.end_result(result)
            if temporary and out_dir:
                shutil.rmtree(out_dir, ignore_errors=True)

    def update_render_passes(self, scene=None, renderlayer=None):
        """The passes Glimmer writes, for the compositor's Render Layers node."""
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        for name, channels, chan_id, kind, _ in AOV_PASSES:
            self.register_pass(scene, renderlayer, name, channels, chan_id, kind)

    # -- viewport ------------------------------------------------------------------------------------------
    def view_update(self, context, depsgraph):
        """The scene changed (Blender calls this on depsgraph updates): restart the viewport render."""
        self._sync_view(context, depsgraph, scene_changed=bool(depsgraph.updates))

    def _sync_view(self, context, depsgraph, scene_changed):
        """Restarts the progressive viewport render when the scene, the view or the viewport size changed."""
        region, region_data = context.region, context.region_data
        width = max(1, int(region.width * viewport.VIEWPORT_SCALE))
        height = max(1, int(region.height * viewport.VIEWPORT_SCALE))
        view = viewport.view_from_region(region_data)
        key = (width, height, view["matrix"].round(6).tobytes(), round(view["fov"], 6))
        changed = scene_changed or key != getattr(self, "_view_key", None)
        session = getattr(self, "_session", None)
        if session is None:
            problem = executable_problem(preferences.executable_path())
            if problem is not None:
                self.update_stats("", "Glimmer: " + problem)
                return
            session = self._session = viewport.ViewportSession(preferences.executable_path())
        if changed:
            self._view_key = key
            session.start(depsgraph, width, height, view)
            self._watch_session()

    def _watch_session(self):
        """Redraws the viewport (from the main thread) while the session brings new images: one timer per
        engine, which ends when the session stops or the engine is freed."""
        import weakref

        if getattr(self, "_watching", False):
            return
        self._watching = True
        engine, last = weakref.ref(self), [-1]

        def tick():
            me = engine()
            try:
                session = me._session
                if session.updates != last[0]:
                    last[0] = session.updates
                    me.tag_redraw()
                if session.running():
                    return 0.1
                me._watching = False
            except (AttributeError, ReferenceError):
                pass  # the engine is gone
            return None

        bpy.app.timers.register(tick, first_interval=0.1)

    def view_draw(self, context, depsgraph):
        """Draws the newest viewport image; navigating the view only calls this, so view changes restart here."""
        self._sync_view(context, depsgraph, scene_changed=False)
        session = getattr(self, "_session", None)
        pixels = session.pixels if session is not None else None
        if pixels is None:
            return
        import gpu
        from gpu_extras.presets import draw_texture_2d

        h, w = pixels.shape[:2]
        flat = np.ascontiguousarray(pixels[::-1]).ravel()  # GPU rows go up
        texture = gpu.types.GPUTexture((w, h), format="RGBA16F", data=gpu.types.Buffer("FLOAT", flat.size, flat))
        gpu.state.blend_set("ALPHA_PREMULT")
        self.bind_display_space_shader(depsgraph.scene)
        draw_texture_2d(texture, (0, 0), context.region.width, context.region.height)
        self.unbind_display_space_shader()
        gpu.state.blend_set("NONE")
        self.update_stats("", "Glimmer: sample %d" % session.samples_shown)

    def __del__(self):
        session = getattr(self, "_session", None)
        if session is not None:
            session.stop()

    def show_progress(self, result, image, done, total):
        """Shows the renderer's newest display image (`Display n/N <path>`: means x exposure and alpha at n of
        total samples; a later one may have replaced it meanwhile) in the render window. Returns (samples
        shown, the file shown) or None when there was nothing to show."""
        snapshot = image[:-len(".exr")] + ".shown.exr"
        try:
            shutil.copyfile(image, snapshot)  # the renderer renames each new image into place
            raw = exr_attributes(snapshot).get("glimmer:samples", ("int", b""))[1]
            shown = struct.unpack("<i", raw)[0] if len(raw) == 4 else done
            result.layers[0].load_from_file(snapshot)
        except (OSError, RuntimeError, ValueError) as e:  # deleted at the end of the render: the final image comes
            print("Glimmer: progressive update at sample %d/%d skipped: %s" % (done, total, e))
            return None
        self.update_result(result)
        return shown, snapshot

    def cancel_requested(self):
        """Esc in the render window (or the job being stopped); a Python method so tests can drive it."""
        return self.test_break()

    def report_once(self, kind, message):
        """self.report, once per render job (an animation's frames repeat the same warnings; a parameter clamped
        to its range is one warning whatever each frame's count and extreme value)."""
        key = re.sub(r"(parameter '[^']*'): [0-9]+ shading points had .*", r"\1: clamped", message)
        if key not in _reported:
            _reported.add(key)
            self.send_report(kind, message)

    def send_report(self, kind, message):
        """Every report goes through here (a Python method, so tests can record them)."""
        self.report(kind, message)

    def fail(self, message):
        self.send_report({"ERROR"}, message)
        if hasattr(self, "error_set"):
            self.error_set(message)
        print(message)
