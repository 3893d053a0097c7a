"""Scene building and image loading shared by the Blender scripts that compare with Cycles
(tests/addon/test_cycles_parity.py, benchmarks/cycles_equal_error.py); run inside `blender -b --python`."""
import math

import bpy
import numpy as np


def add_camera(scene, location, rotation_deg, lens=50.0, sensor_fit="AUTO"):
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.lens = lens
    cam.data.sensor_fit = sensor_fit
    cam.location = location
    cam.rotation_euler = [math.radians(a) for a in rotation_deg]
    scene.collection.objects.link(cam)
    scene.camera = cam
    return cam


def material(name, kind, color=(0.8, 0.8, 0.8), **inputs):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tree = mat.node_tree
    for n in list(tree.nodes):
        if n.bl_idname != "ShaderNodeOutputMaterial":
            tree.nodes.remove(n)
    out = tree.nodes["Material Output"]
    node = tree.nodes.new(kind)
    node.inputs["Color"].default_value = (*color, 1.0)
    for key, value in inputs.items():
        if key == "distribution":
            node.distribution = value
        else:
            node.inputs[key].default_value = value
    tree.links.new(node.outputs[0], out.inputs["Surface"])
    return mat


def add_plane(size, location=(0, 0, 0), rotation_deg=(0, 0, 0), mat=None):
    bpy.ops.mesh.primitive_plane_add(size=size, location=location,
                                     rotation=[math.radians(a) for a in rotation_deg])
    obj = bpy.context.active_object
    if mat is not None:
        obj.data.materials.append(mat)
    return obj


def add_sphere(radius, location, mat):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, location=location, segments=64, ring_count=32)
    bpy.ops.object.shade_smooth()
    obj = bpy.context.active_object
    obj.data.materials.append(mat)
    return obj


def load_pixels(path):
    img = bpy.data.images.load(path)
    px = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px[::-1, :, :3]  # top row first, RGB
