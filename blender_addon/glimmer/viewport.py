"""Progressive viewport rendering: export, `glimmer render` with a checkpoint after every sample pass, in a thread.

The session owns one renderer process at a time. The engine's view_update restarts it when the depsgraph or the
view changed; view_draw draws the newest image. The session itself does not use the GPU, so tests drive it
headless."""
import math
import os
import shutil
import struct
import tempfile
import threading
import time

import numpy as np

from . import exporter as exporter_mod
from . import runner

# Viewport renders: samples per pixel before the renderer stops, and the fraction of the region's pixels.
VIEWPORT_SAMPLES = 1024
VIEWPORT_SCALE = 0.5


def view_from_region(region_data):
    """{"matrix": camera-to-world, "fov": radians across the smaller side} of a 3D viewport (perspective)."""
    matrix = np.array(region_data.view_matrix.inverted(), dtype=np.float64)
    window = np.array(region_data.window_matrix, dtype=np.float64)
    return {"matrix": matrix, "fov": 2.0 * math.atan(1.0 / max(window[0, 0], window[1, 1]))}


def read_uncompressed_exr(path):
    """RGBA float32 pixels (rows top to bottom) of an uncompressed scanline EXR with channels A, B, G, R (as
    `oiiotool ... --compression none -d float` writes them)."""
    from .engine import exr_attributes  # noqa: PLC0415 - engine imports bpy; keep this module light

    attributes = exr_attributes(path)
    if attributes.get("compression", ("", b"\x01"))[1] != b"\x00":
        raise ValueError("%s is compressed" % path)
    x0, y0, x1, y1 = struct.unpack("<4i", attributes["dataWindow"][1])
    width, height = x1 - x0 + 1, y1 - y0 + 1
    with open(path, "rb") as f:
        data = f.read()
    pos = 8
    while data[pos] != 0:  # skip the header attributes
        name_end = data.index(b"\0", pos)
        type_end = data.index(b"\0", name_end + 1)
        pos = type_end + 5 + struct.unpack_from("<i", data, type_end + 1)[0]
    pos += 1 + 8 * height  # header end, line offset table
    line = 8 + 4 * 4 * width  # y, byte count, then A, B, G, R rows of floats
    rows = np.frombuffer(data, dtype="<f4", count=(line // 4) * height, offset=pos).reshape(height, line // 4)
    abgr = rows[:, 2:].reshape(height, 4, width)
    return np.ascontiguousarray(np.stack([abgr[:, 3], abgr[:, 2], abgr[:, 1], abgr[:, 0]], axis=-1))


def checkpoint_pixels(checkpoint, exposure, work_dir):
    """Means x exposure of a checkpoint as an RGBA float array, or None when it vanished meanwhile."""
    from .engine import checkpoint_to_rgba  # noqa: PLC0415

    snapshot, rgba = os.path.join(work_dir, "shown.exr"), os.path.join(work_dir, "shown_rgba.exr")
    try:
        shutil.copyfile(checkpoint, snapshot)
    except OSError:
        return None
    checkpoint_to_rgba(snapshot, exposure, rgba, extra=["--compression", "none"])
    return read_uncompressed_exr(rgba)


class ViewportSession:
    """One progressive render of a depsgraph seen from a view. `updates` counts the images shown, `pixels`
    is the newest (RGBA, rows top to bottom), `first_pixels_seconds` the time from start() to the first."""

    def __init__(self, executable, on_update=None):
        self.executable = executable
        self.on_update = on_update
        self.pixels = None
        self.samples_shown = 0
        self.updates = 0
        self.first_pixels_seconds = None
        self.exit_code = None
        self.failure = None
        self._stop = threading.Event()
        self._thread = None
        self._work_dir = None
        self._lock = threading.Lock()

    def start(self, depsgraph, width, height, view, samples=VIEWPORT_SAMPLES):
        """Exports (in the calling thread: the depsgraph is Blender's) and starts the renderer."""
        self.stop()
        self._stop.clear()
        self.pixels, self.samples_shown, self.updates, self.first_pixels_seconds = None, 0, 0, None
        self.exit_code = self.failure = None
        self._work_dir = tempfile.mkdtemp(prefix="glimmer_view_")
        settings = depsgraph.scene.glimmer
        started = time.monotonic()
        xml, _ = exporter_mod.export_scene(depsgraph, self._work_dir, width=width, height=height, view=view)
        exr = os.path.join(self._work_dir, "render.exr")
        cmd = runner.render_command(self.executable, xml, exr, samples, settings.threads, settings.seed, width,
                                    height, checkpoint_every=0.0)
        self._thread = threading.Thread(target=self._run, args=(cmd, settings.film_exposure, started),
                                        daemon=True)
        self._thread.start()

    def _run(self, cmd, exposure, started):
        work_dir = self._work_dir

        def on_line(line):
            m = runner.CHECKPOINT_LINE.match(line)
            if m is None or self._stop.is_set():
                return
            try:
                pixels = checkpoint_pixels(m.group(3), exposure, work_dir)
            except Exception as e:  # noqa: BLE001 - a lost update; the next checkpoint comes soon
                self.failure = str(e)
                return
            if pixels is None:
                return
            with self._lock:
                self.pixels = pixels
                self.samples_shown = int(m.group(1))
                self.updates += 1
                if self.first_pixels_seconds is None:
                    self.first_pixels_seconds = time.monotonic() - started
            if self.on_update is not None:
                self.on_update()

        try:
            self.exit_code, _, tail = runner.run(cmd, should_cancel=self._stop.is_set, on_line=on_line,
                                                 kill_timeout=2.0)
            if self.exit_code not in (0, runner.EXIT_INTERRUPTED):
                self.failure = "\n".join(tail[-5:])
        finally:
            shutil.rmtree(work_dir, ignore_errors=True)

    def running(self):
        return self._thread is not None and self._thread.is_alive()

    def stop(self, timeout=10.0):
        """Stops the renderer (SIGTERM, then SIGKILL) and waits for the thread."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
        self._thread = None
