"""Shared helpers of the Blender addon tests (run inside `blender -b --python`).

Arguments after `--`: --glimmer PATH (the CLI under test), --out DIR (scratch folder).
"""
import argparse
import os
import sys


HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
ADDON_PARENT = os.path.join(REPO, "blender_addon")
SKIP = 77  # ctest SKIP_RETURN_CODE


def args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser()
    parser.add_argument("--glimmer", default=os.environ.get("GLIMMER_EXECUTABLE", ""))
    parser.add_argument("--out", default=os.path.join(REPO, "build", "addon_tests"))
    parsed = parser.parse_args(argv)
    if parsed.glimmer:
        os.environ["GLIMMER_EXECUTABLE"] = os.path.abspath(parsed.glimmer)
    os.makedirs(parsed.out, exist_ok=True)
    return parsed


def enable_addon():
    import addon_utils

    if ADDON_PARENT not in sys.path:
        sys.path.insert(0, ADDON_PARENT)

    def fail(exc):
        raise exc

    mod = addon_utils.enable("glimmer", default_set=True, handle_error=fail)
    if mod is None:
        raise AssertionError("addon_utils.enable('glimmer') failed")
    return mod


def disable_addon():
    import addon_utils

    addon_utils.disable("glimmer", default_set=True)


def check(condition, message):
    if not condition:
        raise AssertionError(message)


def skip(reason):
    print("SKIPPED: " + reason)
    sys.stdout.flush()
    os._exit(SKIP)


def done(name):
    print("%s: OK" % name)
    sys.stdout.flush()
