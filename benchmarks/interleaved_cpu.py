#!/usr/bin/env python3
"""Samples per CPU-second of two glimmer builds, interleaved in one run (golden and demo scenes, 1 thread).

    python3 benchmarks/interleaved_cpu.py --base /path/to/base/build --new build [--rounds 5]

Each round renders the golden test scene (48x32, 4096 spp) and examples/demo.xml (240x150, 16 spp) with the base
and the new `glimmer`, one after the other, and measures user + sys CPU of each process (start-up included, about
0.13 s), which a loaded machine disturbs less than wall clock. Prints every run and the median and range of the
new/base ratios.
"""
import argparse
import os
import resource
import statistics
import subprocess
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = {
    "golden": (os.path.join(REPO, "tests", "bridge", "data", "golden.xml"), ["--samples", "4096", "--width", "48", "--height", "32"], 48 * 32 * 4096),
    "demo": (os.path.join(REPO, "examples", "demo.xml"), ["--samples", "16", "--width", "240", "--height", "150"], 240 * 150 * 16),
}


def cpu_seconds(glimmer, scene, options, output):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([glimmer, "render", scene, "-o", output, "--threads", "1", "--quiet"] + options, check=True,
                   stderr=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--base", required=True, help="build folder holding the base glimmer")
    parser.add_argument("--new", required=True, help="build folder holding the new glimmer")
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    rates = {}
    with tempfile.TemporaryDirectory() as out:
        for r in range(args.rounds):
            for name, (scene, options, samples) in SCENES.items():
                for which in ("base", "new"):
                    glimmer = os.path.join(getattr(args, which), "glimmer")
                    cpu = cpu_seconds(glimmer, scene, options, os.path.join(out, which + ".exr"))
                    rates.setdefault((name, which), []).append(samples / cpu)
                    print("%d %s %s %.3f s %d samples/CPU-s" % (r + 1, name, which, cpu, samples / cpu), flush=True)
    for name in SCENES:
        ratios = [n / b for n, b in zip(rates[(name, "new")], rates[(name, "base")])]
        print("%s new/base samples per CPU-second: median %.3f range %.3f-%.3f" %
              (name, statistics.median(ratios), min(ratios), max(ratios)))


if __name__ == "__main__":
    main()
