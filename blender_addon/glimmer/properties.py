"""Render settings stored on the scene (scene.glimmer).

The integrator and film properties are generated from the host's scene settings table
(`glimmer describe --json`, key "scene", shipped as scene_settings.json): name, default, range
and description come from its rows, so they cannot drift from the XML loader's.
"""
import bpy

from . import schema

# UI labels of the generated properties (default: the attribute name in words).
LABELS = {
    "max_bounce": "Total", "min_bounce": "Min (Russian roulette)", "max_diffuse_bounce": "Diffuse",
    "max_glossy_bounce": "Glossy", "max_transmission_bounce": "Transmission", "transparent_max_bounce": "Transparent",
    "sample_clamp_direct": "Clamp Direct", "sample_clamp_indirect": "Clamp Indirect", "filter_type": "Pixel Filter",
}
# Soft UI limits where a row's range is open-ended or very wide.
SOFT_MAX = {"filter_width": 10.0}


class GlimmerRenderSettings(bpy.types.PropertyGroup):
    samples: bpy.props.IntProperty(name="Samples", description="Samples per pixel", default=64, min=1,
                                   soft_max=4096, max=1 << 20)
    threads: bpy.props.IntProperty(name="Threads", description="Render threads (0: all cores)", default=0,
                                   min=0, max=1024)
    progressive_interval: bpy.props.FloatProperty(
        name="Update Interval", default=2.0, min=0.0, soft_max=60.0, unit="TIME_ABSOLUTE",
        description="Seconds between image updates during a final render (the renderer's checkpoints; "
                    "0: after every sample pass)")
    use_progressive: bpy.props.BoolProperty(
        name="Progressive Updates", default=True,
        description="Show the image as it converges during a final render")
    seed: bpy.props.IntProperty(name="Seed", description="Seed of the sampling pattern", default=0, min=0)
    use_animated_seed: bpy.props.BoolProperty(name="Animated Seed",
                                              description="Add the frame number to the seed", default=False)

    use_glint: bpy.props.BoolProperty(
        name="Glint Closures", default=True,
        description="Render Glint BSDF nodes with the glint closure (off: export their microfacet fallback, "
                    "handy for comparisons)")
    use_frosted_glass: bpy.props.BoolProperty(
        name="Frosted Glass Closures", default=True,
        description="Render Frosted Glass BSDF nodes with the frosted_glass closure (off: export a rough "
                    "glass_bsdf)")
    keep_export: bpy.props.BoolProperty(
        name="Keep Exported Scene", default=False,
        description="Keep the exported XML/PLY and the EXR in the export folder after rendering")
    export_dir: bpy.props.StringProperty(
        name="Export Folder", subtype="DIR_PATH", default="",
        description="Where the scene is exported for rendering (empty: a temporary folder)")


def _label(row):
    return LABELS.get(row["name"], " ".join(w.capitalize() for w in row["name"].split("_")))


def _choice_label(choice):
    return "-".join(w.capitalize() for w in choice.split("_")) if choice == "blackman_harris" else choice.capitalize()


def make_property(row):
    """A bpy property for one scene-settings row (range: the row's; an exclusive bound is nudged inward)."""
    kwargs = {"name": _label(row), "description": row["doc"], "default": schema.setting_default(row)}
    if row["type"] in ("int", "float"):
        step = 1 if row["type"] == "int" else 1e-3
        if row.get("min") is not None:
            kwargs["min"] = row["min"] + (step if row.get("min_exclusive") else 0)
        if row.get("max") is not None:
            kwargs["max"] = row["max"] - (step if row.get("max_exclusive") else 0)
        if row["name"] in SOFT_MAX:
            kwargs["soft_max"] = SOFT_MAX[row["name"]]
    if row["type"] == "int":
        return bpy.props.IntProperty(**kwargs)
    if row["type"] == "float":
        return bpy.props.FloatProperty(**kwargs)
    if row["type"] == "bool":
        return bpy.props.BoolProperty(**kwargs)
    if row["type"] == "enum":
        kwargs["items"] = [(c, _choice_label(c), "") for c in row["choices"]]
        return bpy.props.EnumProperty(**kwargs)
    raise ValueError("scene setting '%s': type %s has no Blender property" % (row["name"], row["type"]))


for _element, _row, _prop in schema.setting_rows():
    GlimmerRenderSettings.__annotations__[_prop] = make_property(_row)
