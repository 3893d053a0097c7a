"""Runs `glimmer render` as a subprocess: progress, cancellation, errors.

Independent of bpy so it can be tested on its own. The CLI prints
`Sample n/N` lines when stdout is not a terminal; SIGTERM makes it write the
partial image and exit with code 3 (bridge/cli/commands.h).
"""
import queue
import re
import signal
import subprocess
import threading
import time

SAMPLE_LINE = re.compile(r"Sample\s+(\d+)\s*/\s*(\d+)")
DISPLAY_LINE = re.compile(r"^Display\s+(\d+)\s*/\s*(\d+)\s+(.+)$")
FINISHED_LINE = re.compile(r"^Finished\s+(-?\d+)\s+(.*)$")  # `glimmer serve`: a command ended (exit code, output)
EXIT_INTERRUPTED = 3


class RenderFailed(RuntimeError):
    pass


def render_command(executable, scene_path, output_path, samples, threads, seed, width, height, region=None,
                   display=None, display_every=0.0):
    """region: (x0, y0, x1, y1) pixels of the full image, top row 0, x1/y1 exclusive (`--region`: the EXR
    holds just that crop); display: the image so far (plain R, G, B, A float EXR, uncompressed: means x
    exposure, premultiplied alpha) written after the first sample pass and then every display_every seconds,
    announced by `Display n/N <path>` lines (DISPLAY_LINE)."""
    cmd = [executable, "render", scene_path, "-o", output_path, "--samples", str(samples),
           "--seed", str(seed), "--width", str(width), "--height", str(height)]
    if threads > 0:
        cmd += ["--threads", str(threads)]
    if region is not None:
        cmd += ["--region", ",".join(str(int(v)) for v in region)]
    if display is not None:
        cmd += ["--display", display, "--display-every", "%g" % display_every]
    return cmd


def supports_render(executable, timeout=10.0):
    """True when `<executable> --help` lists a `render` sub-command."""
    if not executable:
        return False
    try:
        out = subprocess.run([executable, "--help"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                             timeout=timeout, check=False)
    except (OSError, subprocess.SubprocessError):
        return False
    return re.search(r"^\s+render\b", out.stdout.decode(errors="replace"), re.MULTILINE) is not None


def _pump(stream, lines):
    for raw in iter(stream.readline, b""):
        lines.put(raw.decode(errors="replace").rstrip("\r\n"))
    lines.put(None)


def run(cmd, on_progress=None, should_cancel=None, poll_interval=0.05, kill_timeout=5.0, on_line=None):
    """Run cmd until it ends or should_cancel() turns true.

    on_progress(done, total) is called for every `Sample n/N` line, on_line(text)
    for every other line. On cancel: SIGTERM, then SIGKILL after kill_timeout
    seconds. Returns (exit code, cancelled, last output lines)."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    lines = queue.Queue()
    reader = threading.Thread(target=_pump, args=(proc.stdout, lines), daemon=True)
    reader.start()
    tail = []
    cancelled = False
    terminate_time = None
    stream_open = True
    try:
        while True:
            try:
                line = lines.get(timeout=poll_interval)
            except queue.Empty:
                line = ""
            if line is None:
                stream_open = False
            elif line:
                m = SAMPLE_LINE.search(line)
                if m and on_progress is not None:
                    on_progress(int(m.group(1)), int(m.group(2)))
                elif not m:
                    tail = (tail + [line])[-40:]
                    if on_line is not None:
                        on_line(line)
            if not cancelled and should_cancel is not None and should_cancel():
                cancelled = True
                terminate_time = time.monotonic()
                if proc.poll() is None:
                    proc.send_signal(signal.SIGTERM)
            if cancelled and proc.poll() is None and time.monotonic() - terminate_time > kill_timeout:
                proc.kill()
            if not stream_open and proc.poll() is not None:
                break
            if not stream_open:
                time.sleep(poll_interval)
    finally:
        if proc.poll() is None:  # an exception above: never leave the renderer running
            proc.kill()
        proc.wait()
        reader.join(timeout=1.0)
    return proc.returncode, cancelled, tail
