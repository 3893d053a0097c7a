"""Closure parameter schema: one source for node sockets and the exporter.

The schema is the JSON printed by `glimmer describe --json` (see
bridge/cli/command_describe.cpp). The addon asks the configured executable
for it; when no executable can be run, it uses the snapshot shipped next to
this file (closures_schema.json). Closures the DSO does not list yet (marked
"source": "planned" in the snapshot) are taken from the snapshot, so the
Glint / Frosted Glass nodes exist before the closures land in the plugin.
"""
import json
import os
import subprocess

SNAPSHOT_PATH = os.path.join(os.path.dirname(__file__), "closures_schema.json")
# The scene elements' attributes (`glimmer describe --json`, key "scene"; bridge/scene/settings.cpp).
SCENE_SETTINGS_PATH = os.path.join(os.path.dirname(__file__), "scene_settings.json")

# The render settings (scene.glimmer) generated from the scene settings: every attribute of these
# elements except aliases and MANUAL_SETTINGS, which the addon declares itself because they are
# passed on the command line (--seed with the animated-seed option, --samples).
SETTINGS_ELEMENTS = ("integrator", "film")
MANUAL_SETTINGS = {("integrator", "seed"), ("integrator", "samples")}
# Property names kept from earlier addon versions (saved .blend files use them).
SETTING_PROPERTY_NAMES = {("film", "exposure"): "film_exposure"}

# Closures that get a Blender node, with the node's label and XML node name.
NODE_CLOSURES = {
    "glint": {"label": "Glint BSDF", "xml": "glint_bsdf", "idname": "GlimmerNodeGlintBsdf"},
    "frosted_glass": {"label": "Frosted Glass BSDF", "xml": "frosted_glass_bsdf",
                      "idname": "GlimmerNodeFrostedGlassBsdf"},
}

_cache = {}


def load_snapshot():
    with open(SNAPSHOT_PATH, "r", encoding="utf-8") as f:
        return json.load(f)


def describe_live(executable, timeout=10.0):
    """Run `<executable> describe --json`; returns the parsed JSON or raises."""
    out = subprocess.run([executable, "describe", "--json"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, timeout=timeout, check=False)
    if out.returncode != 0:
        raise RuntimeError("%s describe --json failed (exit %d): %s"
                           % (executable, out.returncode, out.stderr.decode(errors="replace").strip()))
    return json.loads(out.stdout.decode())


def merged_schema(executable):
    """Live closures (when the executable runs) plus the snapshot's closures the DSO lacks.

    Returns (schema dict, origin string, error or None)."""
    key = executable or ""
    if key in _cache:
        return _cache[key]
    snapshot = load_snapshot()
    error = None
    live = None
    if executable:
        try:
            live = describe_live(executable)
        except (OSError, ValueError, RuntimeError, subprocess.SubprocessError) as e:
            error = str(e)
    if live is None:
        result = (snapshot, "snapshot", error)
    else:
        names = {c["name"] for c in live["closures"]}
        closures = [dict(c, source="dso") for c in live["closures"]]
        closures += [c for c in snapshot["closures"] if c["name"] not in names]
        result = ({"plugin": live.get("plugin", {}), "closures": closures}, "live", None)
    _cache[key] = result
    return result


def load_scene_settings():
    with open(SCENE_SETTINGS_PATH, "r", encoding="utf-8") as f:
        return json.load(f)


def setting_rows(element=None):
    """(element, row, property name) of every generated render setting, in table order."""
    settings = load_scene_settings()
    for name in SETTINGS_ELEMENTS:
        if element is not None and name != element:
            continue
        for row in settings[name]["attributes"]:
            if row.get("alias_of") or (name, row["name"]) in MANUAL_SETTINGS:
                continue
            yield name, row, SETTING_PROPERTY_NAMES.get((name, row["name"]), row["name"])


def setting_default(row):
    """The property default: Blender 3.4's UI default where the table names one, else Cycles' socket default."""
    return row.get("blender_default", row["default"])


def clear_cache():
    _cache.clear()


def closure(schema, name):
    for c in schema["closures"]:
        if c["name"] == name:
            return c
    return None


def socket_name(param_name):
    """Blender socket name of a schema parameter: 'filter_threshold' -> 'Filter Threshold', 'uv_scale' -> 'UV Scale'."""
    upper = {"ior", "uv", "rgb"}
    return " ".join(w.upper() if w in upper else w.capitalize() for w in param_name.split("_"))


def is_socket_param(param):
    """Float, int, colour and vector parameters become sockets; enum/string/bool node properties."""
    return param["type"] in ("float", "int", "color", "vector")
