"""Progressive viewport rendering: export, then one persistent `glimmer serve` process renders it.

The session keeps the renderer process for its whole life: each change (start()) exports the scene and sends the
render's arguments as one line to the process's stdin, which interrupts the render in progress and starts the new
one (no process start-up, plugin loading or first use of the DSO per change). The renderer writes the image so
far after every sample pass as a plain uncompressed RGBA EXR (`--display`), which a reader thread loads with numpy
(read_uncompressed_exr): no image-conversion process. The engine's view_update restarts on depsgraph or view
changes; view_draw draws the newest image. The session itself does not use the GPU, so tests drive it
headless."""
import math
import os
import shlex
import shutil
import signal
import struct
import subprocess
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
    `glimmer render --display` and `oiiotool ... --compression none -d float` write them)."""
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


class ViewportSession:
    """Progressive renders of a depsgraph seen from a view, one persistent renderer process. `updates` counts
    the images of the current render, `pixels` is the newest (RGBA, premultiplied, rows top to bottom),
    `first_pixels_seconds` the time from start() to its first image."""

    def __init__(self, executable, on_update=None):
        self.executable = executable
        self.on_update = on_update
        self.pixels = None
        self.samples_shown = 0
        self.updates = 0
        self.first_pixels_seconds = None
        self.exit_code = None  # the renderer process's, once it ended (3: stopped)
        self.failure = None
        self._lock = threading.Lock()
        self._proc = None
        self._reader = None
        self._work_dir = None
        self._job = 0
        self._current = None  # (display image path, output path, start time) of the newest render
        self._done = True     # the newest render has finished

    def start(self, depsgraph, width, height, view, samples=VIEWPORT_SAMPLES):
        """Exports (in the calling thread: the depsgraph is Blender's) and has the renderer render it."""
        started = time.monotonic()
        if self._proc is None or self._proc.poll() is not None:
            self._spawn()
        self._job += 1
        job_dir = os.path.join(self._work_dir, "job_%d" % self._job)
        os.makedirs(job_dir)
        settings = depsgraph.scene.glimmer
        xml, _ = exporter_mod.export_scene(depsgraph, job_dir, width=width, height=height, view=view)
        display, output = os.path.join(job_dir, "display.exr"), os.path.join(job_dir, "render.exr")
        cmd = runner.render_command(self.executable, xml, output, samples, settings.threads, settings.seed, width,
                                    height, display=display)
        with self._lock:
            self._current, self._done = (display, output, started), False
            self.pixels, self.samples_shown, self.updates, self.first_pixels_seconds = None, 0, 0, None
            self.failure = None
        try:
            self._proc.stdin.write((shlex.join(cmd[2:]) + "\n").encode())  # the arguments after `render`
            self._proc.stdin.flush()
        except OSError as e:  # the renderer died: the next start() spawns a new one
            self.failure = "the renderer process ended (%s)" % e

    def _spawn(self):
        self._work_dir = tempfile.mkdtemp(prefix="glimmer_view_")
        self.exit_code = None
        self._proc = subprocess.Popen([self.executable, "serve"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                      stderr=subprocess.STDOUT)
        self._reader = threading.Thread(target=self._read, args=(self._proc, self._work_dir), daemon=True)
        self._reader.start()

    def _read(self, proc, work_dir):
        """The renderer's output: display images of the newest render become `pixels`; finished older renders'
        folders are removed."""
        tail = []
        for raw in iter(proc.stdout.readline, b""):
            line = raw.decode(errors="replace").rstrip("\r\n")
            shown, finished = runner.DISPLAY_LINE.match(line), runner.FINISHED_LINE.match(line)
            if shown is not None:
                self._show(shown.group(3), int(shown.group(1)))
            elif finished is not None:
                with self._lock:
                    current = self._current is not None and finished.group(2) == self._current[1]
                    if current:
                        self._done = True
                        if int(finished.group(1)) not in (0, runner.EXIT_INTERRUPTED):
                            self.failure = "\n".join(tail[-5:])
                if not current:
                    shutil.rmtree(os.path.dirname(finished.group(2)), ignore_errors=True)
            elif not runner.SAMPLE_LINE.search(line):
                tail = (tail + [line])[-40:]
        proc.wait()
        self.exit_code = proc.returncode
        shutil.rmtree(work_dir, ignore_errors=True)

    def _show(self, path, samples):
        with self._lock:
            if self._current is None or path != self._current[0]:
                return  # an older render's image
            started = self._current[2]
        try:
            pixels = read_uncompressed_exr(path)
        except (OSError, ValueError, KeyError) as e:  # a lost update; the next comes after the next pass
            self.failure = str(e)
            return
        with self._lock:
            if self._current is None or path != self._current[0]:
                return
            self.pixels, self.samples_shown = pixels, samples
            self.updates += 1
            if self.first_pixels_seconds is None:
                self.first_pixels_seconds = time.monotonic() - started
        if self.on_update is not None:
            self.on_update()

    def running(self):
        """The newest render is in progress."""
        return self._proc is not None and self._proc.poll() is None and not self._done

    def stop(self, timeout=2.0):
        """Ends the renderer process (SIGTERM: it stops the render and exits 3; SIGKILL after `timeout` s)."""
        proc, self._proc = self._proc, None
        with self._lock:
            self._current, self._done = None, True
        if proc is None:
            return
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        if self._reader is not None:
            self._reader.join(timeout)
        proc.stdin.close()
        self.exit_code = proc.returncode
