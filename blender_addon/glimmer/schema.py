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
