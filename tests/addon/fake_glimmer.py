#!/usr/bin/env python3
"""A stand-in for `glimmer render` with the CLI's process protocol, for the
cancellation tests: prints `Sample n/N` lines, on SIGTERM writes the partial
image and exits 3, at the end writes the image and exits 0. The image is a
multilayer EXR (ViewLayer.Combined.RGBA) whose red channel is the fraction
of samples done, written with oiiotool.

Environment: FAKE_SAMPLE_SECONDS (default 0.05), FAKE_IGNORE_TERM=1 (ignore
SIGTERM, to test the kill fallback), FAKE_FAIL=1 (exit 1 with an error message), FAKE_LOG (append the argv here), FAKE_PROGRESS_FILE (rewritten with the number of
samples done after each sample, so tests can cancel at a sample count rather than a time).
"""
import os
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET


def write_image(path, width, height, fraction):
    channels = ",".join("ViewLayer.Combined." + c for c in "RGBA")
    tmp = path + ".tmp.exr"
    subprocess.run(["oiiotool", "--pattern", "constant:color=%g,0.5,0.25,1" % fraction, "%dx%d" % (width, height),
                    "4", "--chnames", channels, "-d", "float", "-o", tmp], check=True)
    os.replace(tmp, path)


def main(argv):
    if os.environ.get("FAKE_LOG"):
        with open(os.environ["FAKE_LOG"], "a") as f:
            f.write(" ".join(argv) + "\n")
    if argv[1:] == ["--help"]:
        print("Usage: glimmer SUBCOMMAND\n\nSubcommands:\n  render    fake renderer for the addon tests")
        return 0
    if len(argv) < 2 or argv[1] != "render":
        print("fake glimmer: only `render` is implemented", file=sys.stderr)
        return 2
    if "--help" in argv:
        print("usage: glimmer render scene.xml -o out.exr")
        return 0
    if os.environ.get("FAKE_FAIL") == "1":
        print("glimmer: error: scene.xml:3: fake failure for the tests", file=sys.stderr)
        return 1
    scene = argv[2]
    opts = dict(zip(argv[3::2], argv[4::2]))
    ET.parse(scene)  # the exported scene must at least be well-formed XML
    out = opts["-o"]
    samples, width, height = int(opts["--samples"]), int(opts["--width"]), int(opts["--height"])
    state = {"done": 0}

    def on_term(signum, frame):
        write_image(out, width, height, state["done"] / samples)
        print("interrupted after %d samples" % state["done"], flush=True)
        os._exit(3)

    if os.environ.get("FAKE_IGNORE_TERM") == "1":
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    else:
        signal.signal(signal.SIGTERM, on_term)
    delay = float(os.environ.get("FAKE_SAMPLE_SECONDS", "0.05"))
    for i in range(1, samples + 1):
        time.sleep(delay)
        state["done"] = i
        print("Sample %d/%d" % (i, samples), flush=True)
        if os.environ.get("FAKE_PROGRESS_FILE"):
            with open(os.environ["FAKE_PROGRESS_FILE"], "w") as f:
                f.write(str(i))
    write_image(out, width, height, 1.0)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
