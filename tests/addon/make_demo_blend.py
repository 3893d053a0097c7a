"""Builds a demo .blend for the Glimmer engine: a glint sphere, a frosted-glass
sphere and a diffuse cube on a floor, one point light and a dim sky.

    blender -b --factory-startup --python tests/addon/make_demo_blend.py [-- --output path/demo.blend]

Default output: <repo>/build/demo/demo.blend. The script also links the addon
into <repo>/build/blender_scripts/addons/ and prints the command that renders
the file with the Glimmer engine (frame 1 -> <output folder>/demo_glint_0001.png):

    BLENDER_USER_SCRIPTS=<repo>/build/blender_scripts blender -b --addons glimmer demo.blend -E GLIMMER -f 1

(With the addon installed from the zip, `blender -b demo.blend -E GLIMMER -f 1` is enough.)
"""
import argparse
import math
import os
import sys

import bpy
from mathutils import Vector

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
ADDON_PARENT = os.path.join(REPO, "blender_addon")


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser()
    parser.add_argument("--output", default=os.path.join(REPO, "build", "demo", "demo.blend"))
    parser.add_argument("--samples", type=int, default=32)
    parser.add_argument("--width", type=int, default=480)
    parser.add_argument("--height", type=int, default=320)
    parser.add_argument("--no-install-addon", action="store_true",
                        help="do not link the addon into the user's Blender scripts folder and enable it")
    return parser.parse_args(argv)


def enable_addon():
    import addon_utils

    if ADDON_PARENT not in sys.path:
        sys.path.insert(0, ADDON_PARENT)
    if addon_utils.enable("glimmer", default_set=True) is None:
        raise RuntimeError("could not enable the glimmer addon from %s" % ADDON_PARENT)


def link_addon_for_command_line():
    """<repo>/build/blender_scripts/addons/glimmer -> blender_addon/glimmer, for BLENDER_USER_SCRIPTS."""
    scripts = os.path.join(REPO, "build", "blender_scripts")
    addons = os.path.join(scripts, "addons")
    os.makedirs(addons, exist_ok=True)
    link = os.path.join(addons, "glimmer")
    if not os.path.lexists(link):
        os.symlink(os.path.join(ADDON_PARENT, "glimmer"), link)
    return scripts


def install_addon_for_user():
    """Links the addon into the user's Blender scripts folder (e.g. ~/.config/blender/3.4/scripts/addons/glimmer)
    and enables it in the saved preferences, so `blender -b demo.blend -E GLIMMER -f 1` works as it is."""
    import addon_utils

    addons = bpy.utils.user_resource('SCRIPTS', path="addons", create=True)
    link = os.path.join(addons, "glimmer")
    if not os.path.lexists(link):
        os.symlink(os.path.join(ADDON_PARENT, "glimmer"), link)
    addon_utils.enable("glimmer", default_set=True, persistent=True)
    bpy.ops.wm.save_userpref()
    return link


def new_material(name):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tree = mat.node_tree
    out = tree.nodes["Material Output"]
    for node in [n for n in tree.nodes if n != out]:
        tree.nodes.remove(node)
    return mat, tree, out


def assign(obj, mat):
    obj.data.materials.clear()
    obj.data.materials.append(mat)


def build_scene(opts):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.name = "GlimmerDemo"
    scene.render.engine = "GLIMMER"
    scene.render.resolution_x, scene.render.resolution_y = opts.width, opts.height
    scene.render.resolution_percentage = 100
    scene.render.filepath = "//demo_glint_"
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.view_settings.view_transform = "Standard"
    scene.frame_start = scene.frame_end = scene.frame_current = 1
    scene.glimmer.samples = opts.samples
    scene.glimmer.max_bounce = 8

    world = bpy.data.worlds.new("Sky")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.03, 0.04, 0.06, 1.0)
    background.inputs["Strength"].default_value = 1.0
    scene.world = world

    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.data.lens = 40.0
    cam.location = (0.0, -7.5, 2.6)
    target = Vector((0.0, 0.0, 0.8))
    cam.rotation_euler = (target - cam.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam

    key = bpy.data.objects.new("Key", bpy.data.lights.new("Key", "POINT"))
    key.data.energy = 600.0
    key.data.shadow_soft_size = 0.05
    key.location = (2.5, -3.0, 5.0)
    scene.collection.objects.link(key)
    fill = bpy.data.objects.new("Fill", bpy.data.lights.new("Fill", "AREA"))
    fill.data.energy = 150.0
    fill.data.size = 3.0
    fill.location = (-4.0, -2.0, 4.0)
    fill.rotation_euler = (0.0, math.radians(-45.0), 0.0)
    scene.collection.objects.link(fill)

    bpy.ops.mesh.primitive_plane_add(size=30.0)
    floor_mat, tree, out = new_material("Floor")
    floor = tree.nodes.new("ShaderNodeBsdfPrincipled")
    floor.inputs["Base Color"].default_value = (0.35, 0.35, 0.33, 1.0)
    floor.inputs["Roughness"].default_value = 0.8
    tree.links.new(floor.outputs[0], out.inputs["Surface"])
    assign(bpy.context.active_object, floor_mat)

    # The glint sphere (centre).
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, location=(0.0, 0.0, 1.0), segments=64, ring_count=32)
    sphere = bpy.context.active_object
    sphere.name = "GlintSphere"
    bpy.ops.object.shade_smooth()
    glint_mat, tree, out = new_material("Glint")
    glint = tree.nodes.new("GlimmerNodeGlintBsdf")
    glint.inputs["Color"].default_value = (0.95, 0.85, 0.6, 1.0)
    glint.inputs["Roughness"].default_value = 0.25
    glint.inputs["Density"].default_value = 200000.0
    glint.location = (-250, 0)
    tree.links.new(glint.outputs["BSDF"], out.inputs["Surface"])
    assign(sphere, glint_mat)

    # Frosted glass (right) and a diffuse cube (left).
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.8, location=(2.4, 0.8, 0.8), segments=48, ring_count=24)
    bpy.context.active_object.name = "FrostedSphere"
    bpy.ops.object.shade_smooth()
    frosted_mat, tree, out = new_material("Frosted")
    frosted = tree.nodes.new("GlimmerNodeFrostedGlassBsdf")
    frosted.inputs["Roughness"].default_value = 0.35
    tree.links.new(frosted.outputs["BSDF"], out.inputs["Surface"])
    assign(bpy.context.active_object, frosted_mat)

    bpy.ops.mesh.primitive_cube_add(size=1.2, location=(-2.4, 0.8, 0.6), rotation=(0.0, 0.0, 0.5))
    bpy.context.active_object.name = "Cube"
    cube_mat, tree, out = new_material("Red")
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.7, 0.08, 0.05, 1.0)
    tree.links.new(diffuse.outputs[0], out.inputs["Surface"])
    assign(bpy.context.active_object, cube_mat)
    return scene


def main():
    opts = parse_args()
    enable_addon()
    build_scene(opts)
    output = os.path.abspath(opts.output)
    os.makedirs(os.path.dirname(output), exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=output)
    scripts = link_addon_for_command_line()
    print("demo: wrote %s" % output)
    if opts.no_install_addon:
        print("demo: render it with\n  BLENDER_USER_SCRIPTS=%s blender -b --addons glimmer %s -E GLIMMER -f 1"
              % (scripts, output))
    else:
        print("demo: enabled the Glimmer addon in your Blender preferences (%s)" % install_addon_for_user())
        print("demo: render it with\n  blender -b %s -E GLIMMER -f 1" % output)


if __name__ == "__main__":
    main()
