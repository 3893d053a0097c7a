"""Render settings stored on the scene (scene.glimmer)."""
import bpy


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

    max_bounce: bpy.props.IntProperty(name="Total", description="Maximum number of bounces", default=12,
                                      min=0, max=1024)
    min_bounce: bpy.props.IntProperty(name="Min (Russian roulette)",
                                      description="Bounces before Russian roulette starts", default=3,
                                      min=0, max=1024)
    max_diffuse_bounce: bpy.props.IntProperty(name="Diffuse", default=4, min=0, max=1024)
    max_glossy_bounce: bpy.props.IntProperty(name="Glossy", default=4, min=0, max=1024)
    max_transmission_bounce: bpy.props.IntProperty(name="Transmission", default=12, min=0, max=1024)
    transparent_max_bounce: bpy.props.IntProperty(name="Transparent", default=8, min=0, max=1024)
    filter_glossy: bpy.props.FloatProperty(name="Filter Glossy", description="Blur glossy after blurry bounces "
                                           "(0: off, like Cycles)", default=0.0, min=0.0, max=10.0)
    sample_clamp_direct: bpy.props.FloatProperty(name="Clamp Direct", description="0: no clamp", default=0.0,
                                                 min=0.0)
    sample_clamp_indirect: bpy.props.FloatProperty(name="Clamp Indirect", description="0: no clamp",
                                                   default=10.0, min=0.0)  # Blender's (and the host's) default

    film_exposure: bpy.props.FloatProperty(name="Exposure", description="Film exposure multiplier",
                                           default=1.0, min=0.0)
    filter_type: bpy.props.EnumProperty(name="Pixel Filter", items=[
        ("box", "Box", ""), ("gaussian", "Gaussian", ""), ("blackman_harris", "Blackman-Harris", "")],
        default="box")
    filter_width: bpy.props.FloatProperty(name="Filter Width", default=1.0, min=0.01, max=10.0, unit="NONE")

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
