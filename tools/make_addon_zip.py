#!/usr/bin/env python3
"""Builds the installable Blender addon zip (`make addon`).

    python3 tools/make_addon_zip.py [--output build/glimmer_blender_addon-<version>.zip]
    python3 tools/make_addon_zip.py --refresh-schema [--glimmer build/glimmer]

The zip holds the folder glimmer/ (Blender: Preferences > Add-ons > Install...).
--refresh-schema rewrites blender_addon/glimmer/closures_schema.json (and scene_settings.json, the
scene elements' attributes, key "scene") from `glimmer describe --json`: closures the DSO lists are copied ("source": "dso"),
closures only the snapshot defines stay as they are ("source": "planned").
"""
import argparse
import ast
import json
import os
import subprocess
import sys
import zipfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ADDON = os.path.join(REPO, "blender_addon", "glimmer")
SNAPSHOT = os.path.join(ADDON, "closures_schema.json")
SCENE_SETTINGS = os.path.join(ADDON, "scene_settings.json")


def addon_version():
    with open(os.path.join(ADDON, "__init__.py"), encoding="utf-8") as f:
        tree = ast.parse(f.read())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "bl_info" for t in node.targets):
            return ".".join(str(v) for v in ast.literal_eval(node.value)["version"])
    raise SystemExit("bl_info not found in %s" % ADDON)


def refresh_schema(glimmer):
    live = json.loads(subprocess.run([glimmer, "describe", "--json"], check=True, stdout=subprocess.PIPE).stdout)
    with open(SNAPSHOT, encoding="utf-8") as f:
        snapshot = json.load(f)
    names = {c["name"] for c in live["closures"]}
    closures = [dict(c, source="dso") for c in live["closures"]]
    closures += [c for c in snapshot["closures"] if c["name"] not in names and c.get("source") == "planned"]
    snapshot["plugin"] = {k: live["plugin"][k] for k in ("name", "version", "abi_version")}
    snapshot["closures"] = closures
    with open(SNAPSHOT, "w", encoding="utf-8") as f:
        f.write(json.dumps(snapshot, indent=2) + "\n")
    print("make_addon_zip: refreshed %s (%d closures from the DSO, %d planned)"
          % (SNAPSHOT, len(names), len(closures) - len(names)))
    with open(SCENE_SETTINGS, "w", encoding="utf-8") as f:
        f.write(json.dumps(live["scene"], indent=2) + "\n")
    print("make_addon_zip: refreshed %s (the scene elements' attributes)" % SCENE_SETTINGS)


def build_zip(output):
    os.makedirs(os.path.dirname(output), exist_ok=True)
    count = 0
    with zipfile.ZipFile(output, "w", zipfile.ZIP_DEFLATED) as z:
        for folder, dirs, files in os.walk(ADDON):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__")
            for name in sorted(files):
                if name.endswith((".pyc", ".pyo")):
                    continue
                path = os.path.join(folder, name)
                z.write(path, os.path.join("glimmer", os.path.relpath(path, ADDON)))
                count += 1
    with zipfile.ZipFile(output) as z:
        names = z.namelist()
        if any("glimmer/" + f not in names for f in ("__init__.py", "closures_schema.json", "scene_settings.json")):
            raise SystemExit("make_addon_zip: the zip lacks __init__.py or a schema snapshot")
    print("make_addon_zip: wrote %s (%d files)" % (output, count))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--output", default=None)
    parser.add_argument("--refresh-schema", action="store_true")
    parser.add_argument("--glimmer", default=os.path.join(REPO, "build", "glimmer"))
    opts = parser.parse_args()
    if opts.refresh_schema:
        refresh_schema(opts.glimmer)
        return 0
    output = opts.output or os.path.join(REPO, "build", "glimmer_blender_addon-%s.zip" % addon_version())
    build_zip(os.path.abspath(output))
    return 0


if __name__ == "__main__":
    sys.exit(main())
