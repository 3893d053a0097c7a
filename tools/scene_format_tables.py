#!/usr/bin/env python3
"""Generates docs/scene-format.md's closure-node and element-attribute tables from
`glimmer describe --json` (keys "nodes": bridge/render/closure_nodes.cpp, "scene":
bridge/scene/settings.cpp), so the documentation is the tables the code runs.

    python3 tools/scene_format_tables.py --glimmer build/glimmer          # rewrite the doc
    python3 tools/scene_format_tables.py --glimmer build/glimmer --check  # exit 1 if the doc differs

Each table sits between `<!-- BEGIN generated: NAME -->` and `<!-- END generated: NAME -->`.
"""
import argparse
import json
import os
import re
import subprocess
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOC = os.path.join(REPO, "docs", "scene-format.md")
ELEMENTS = ("integrator", "film", "camera", "light", "background")


def number(value):
    if value is None:
        return "inf"
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e6:
        return str(int(value))
    if isinstance(value, float):
        return re.sub(r"e([+-])0*(\d+)", lambda m: "e" + ("-" if m.group(1) == "-" else "") + m.group(2), "%g" % value)
    return str(value)


def value_text(value):
    if isinstance(value, list):
        return " ".join(number(v) for v in value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return ""
    return number(value) if isinstance(value, (int, float)) else str(value)


def range_text(row):
    if "min" not in row:
        return ", ".join(row.get("choices", []))
    lo, hi = row["min"], row["max"]
    if lo is None and hi is None:
        return ""
    left = "(" if row.get("min_exclusive") else "["
    right = ")" if row.get("max_exclusive") or hi is None else "]"
    return "%s%s, %s%s" % (left, number(lo) if lo is not None else "-inf", number(hi), right)


def socket_text(s):
    role = s["role"]
    if role == "weight":
        return "`%s` = weight (%s)" % (s["socket"], value_text(s["default"]))
    if role == "strength":
        return "`%s` x weight (%s, constant)" % (s["socket"], value_text(s["default"]))
    if role in ("param", "schema_param", "param_or_weight"):
        name = s["socket"] + ("/" + s["alias"] if s.get("alias") else "")
        text = "`%s` -> %s" % (name, s["param"])
        extra = []
        if "default" in s:
            extra.append(value_text(s["default"]))
        if s.get("min") is not None or s.get("max") is not None:
            extra.append("clamp [%s, %s]" % (number(s["min"]) if s.get("min") is not None else "-inf",
                                             number(s["max"])))
        if role == "param_or_weight":
            extra.append("a link is the weight")
        if s.get("varying"):
            extra.append("**varying**")
        return text + (" (%s)" % ", ".join(extra) if extra else "")
    if role == "unsupported":
        return "`%s` unsupported (warns unless %s)" % (s["socket"], value_text(s["default"]))
    if role == "normal":
        return "`%s` = the closure's shading normal (a Bump, Normal Map or any vector, per shading point)" % s["socket"]
    if role == "tangent":
        unlinked = ("Cycles' radial Z tangent (generated coordinates)" if s.get("radial_default")
                    else "the UV map's dP/du")
        return "`%s` = the closure's tangent (per shading point; unlinked: %s)" % (s["socket"], unlinked)
    if role == "rotation":
        return "`%s` turns the tangent about the normal by value x 2 pi (%s, constant or per shading point)" % (
            s["socket"], value_text(s["default"]))
    return None


def nodes_table(nodes):
    lines = ["| Node | DSO closure | Sockets (**varying**: a linked texture is evaluated per shading point; "
             "other links warn) | Notes |", "|---|---|---|---|"]
    for n in nodes:
        sockets = [t for t in (socket_text(s) for s in n["sockets"]) if t]
        ignored = [s["socket"] for s in n["sockets"] if s["role"] == "ignored"]
        if ignored:
            sockets.append("ignored: " + ", ".join(ignored))
        if n["schema"] and not n["in_plugin"]:
            sockets.append("the closure's parameters (not in this plugin)")
        if n["distribution"]:
            sockets.append("`distribution`: ggx, beckmann, multi_ggx (Multiscatter GGX), sharp "
                           "(others warn: GGX); an unlinked roughness of 0 is sharp")
        notes = [n["doc"]]
        if n["fixed"]:
            notes.append("fixed: " + ", ".join("%s=%s" % kv for kv in sorted(n["fixed"].items())))
        if n["filter_glossy"]:
            notes.append("filter_glossy blurs it")
        closure = n["closure"] or {"transparent": "host", "composite": "host composite"}.get(n["kind"], "-")
        lines.append("| `%s` | %s | %s | %s |" % (n["node"], closure, "<br>".join(sockets) or "-", "; ".join(notes)))
    return "\n".join(lines)


def element_table(name, element):
    lines = ["| Attribute | Type | Default | Range | Notes |", "|---|---|---|---|---|"]
    for row in element["attributes"]:
        notes = [row["doc"]]
        if row.get("alias_of"):
            notes.append("alias of `%s`" % row["alias_of"])
        if row.get("lights"):
            notes.append("lights: " + ", ".join(row["lights"]))
        if "blender_default" in row:
            notes.append("Blender's default: %s (the addon's)" % value_text(row["blender_default"]))
        lines.append("| `%s` | %s | %s | %s | %s |" % (row["name"], row["type"], value_text(row["default"]),
                                                      range_text(row), "; ".join(notes)))
    if element["ignored"]:
        lines.append("")
        lines.append("Accepted without effect (warned as not supported): %s." %
                     ", ".join("`%s`" % a for a in element["ignored"]))
    return "\n".join(lines)


def tables(described):
    out = {"closure-nodes": nodes_table(described["nodes"])}
    for name in ELEMENTS:
        out["element-" + name] = element_table(name, described["scene"][name])
    return out


def replace_blocks(text, blocks):
    for name, body in blocks.items():
        pattern = re.compile(r"(<!-- BEGIN generated: %s -->\n)(.*?)(<!-- END generated: %s -->)"
                             % (re.escape(name), re.escape(name)), re.S)
        if not pattern.search(text):
            raise SystemExit("scene_format_tables: %s has no block '%s'" % (DOC, name))
        text = pattern.sub(lambda m: m.group(1) + body + "\n" + m.group(3), text)
    return text


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--glimmer", required=True)
    parser.add_argument("--check", action="store_true")
    a = parser.parse_args()
    described = json.loads(subprocess.run([a.glimmer, "describe", "--json"], check=True,
                                          stdout=subprocess.PIPE).stdout)
    with open(DOC, encoding="utf-8") as f:
        current = f.read()
    wanted = replace_blocks(current, tables(described))
    if a.check:
        if wanted != current:
            sys.stderr.write("docs/scene-format.md differs from the tables in the code; run "
                             "python3 tools/scene_format_tables.py --glimmer build/glimmer\n")
            return 1
        print("scene_format_tables: docs/scene-format.md matches the code's tables")
        return 0
    with open(DOC, "w", encoding="utf-8") as f:
        f.write(wanted)
    print("scene_format_tables: rewrote", DOC)
    return 0


if __name__ == "__main__":
    sys.exit(main())
