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


def enable_addon_with_renderer():
    """enable_addon(), skipping the test (77) while the CLI under test has no
    `render` sub-command. Returns (addon module, path of the glimmer executable)."""
    glimmer = os.environ.get("GLIMMER_EXECUTABLE", "")
    mod = enable_addon()
    if not mod.runner.supports_render(glimmer):
        skip("`%s` has no `render` sub-command yet (issue 3); this test runs once it lands" % glimmer)
    return mod, glimmer


def empty_exr_scene(width, height):
    """Empties the file and returns its scene, rendered by Glimmer at width x height
    (100 %) to 32-bit OpenEXR with the Standard view transform."""
    import bpy

    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "GLIMMER"
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = width, height, 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.view_settings.view_transform = "Standard"
    return scene


def new_glimmer_scene():
    """An empty scene rendered by Glimmer at 32 x 24 with a camera at z = 5 looking down -z."""
    import bpy
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "GLIMMER"
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 32, 24, 100
    add_camera(scene, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0))
    return scene


def export_with_reports(mod, out_dir):
    """Exports the current depsgraph into out_dir: (scene.xml path, the Exporter, the report messages)."""
    import bpy
    reports = []
    xml, exp = mod.exporter.export_scene(bpy.context.evaluated_depsgraph_get(), out_dir,
                                         report=lambda kind, msg: reports.append(msg))
    return xml, exp, reports


def add_camera(scene, location, rotation_euler):
    """A camera object at location with rotation_euler (radians), made the scene camera."""
    import bpy

    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location = location
    cam.rotation_euler = rotation_euler
    scene.camera = cam
    return cam


def add_light(scene, kind, energy, location, name="Light"):
    import bpy

    light = bpy.data.objects.new(name, bpy.data.lights.new(name, kind))
    light.data.energy = energy
    light.location = location
    scene.collection.objects.link(light)
    return light


def set_world_color(scene, color):
    """A node world whose Background has the given RGB colour."""
    import bpy

    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (*color, 1.0)
    scene.world = world
    return world


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
