"""Export for Farm: one Cycles XML scene per frame of the frame range (each in
<folder>/frame_####/ with its meshes) and the `glimmer farm slurm` command line
that renders them as a Slurm job array and merges the parts (docs/farm.md)."""
import os
import shlex

import bpy

from . import exporter, preferences

SCENE_PATTERN = os.path.join("frame_####", "scene.xml")
OUTPUT_PATTERN = os.path.join("render", "frame_####.exr")
COMMAND_FILE = "farm_command.sh"


def frame_list(start, end, step):
    """--frames text: "1-250", or "1,3,5" for a frame step other than 1."""
    if step == 1:
        return "%d-%d" % (start, end)
    return ",".join(str(f) for f in range(start, end + 1, step))


def farm_command(executable, directory, frames, split, parts, samples):
    """argv of `glimmer farm slurm` for the frames exported to `directory`."""
    return [executable or "glimmer", "farm", "slurm", os.path.join(directory, SCENE_PATTERN), "--frames", frames,
            "--tiles" if split == "TILES" else "--sample-splits", str(parts), "--samples", str(samples),
            "-o", os.path.join(directory, OUTPUT_PATTERN)]


def export_frames(context, directory, frames, report=None):
    """Exports every frame in `frames` to directory/frame_####/scene.xml; returns the paths.
    The current frame is restored afterwards."""
    scene = context.scene
    current = scene.frame_current
    paths = []
    try:
        for frame in frames:
            scene.frame_set(frame)
            depsgraph = context.evaluated_depsgraph_get()
            path, _ = exporter.export_scene(depsgraph, os.path.join(directory, "frame_%04d" % frame), report=report)
            paths.append(path)
    finally:
        scene.frame_set(current)
    return paths


class GLIMMER_OT_export_for_farm(bpy.types.Operator):
    """Export one scene per frame of the frame range and the glimmer farm command that renders them"""
    bl_idname = "glimmer.export_for_farm"
    bl_label = "Export for Farm"
    bl_options = {"REGISTER"}

    directory: bpy.props.StringProperty(name="Folder", subtype="DIR_PATH",
                                        description="Folder shared with the farm nodes")
    split: bpy.props.EnumProperty(name="Split", default="TILES", items=[
        ("TILES", "Tiles", "each frame is cut into bands of rows, merged bit-identically"),
        ("SAMPLES", "Sample Splits", "each frame's samples are cut into ranges, merged by weighted mean")])
    parts: bpy.props.IntProperty(name="Parts per Frame", default=4, min=1, max=4096,
                                 description="Farm tasks per frame")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        if not self.directory:
            self.report({"ERROR"}, "Glimmer: choose a folder for the farm export")
            return {"CANCELLED"}
        scene = context.scene
        directory = os.path.abspath(bpy.path.abspath(self.directory))
        frames = list(range(scene.frame_start, scene.frame_end + 1, scene.frame_step))
        export_frames(context, directory, frames, report=self.report)
        os.makedirs(os.path.join(directory, os.path.dirname(OUTPUT_PATTERN)), exist_ok=True)
        cmd = farm_command(preferences.executable_path(), directory,
                           frame_list(scene.frame_start, scene.frame_end, scene.frame_step),
                           self.split, self.parts, scene.glimmer.samples)
        line = shlex.join(cmd)
        command_path = os.path.join(directory, COMMAND_FILE)
        with open(command_path, "w") as f:
            f.write("#!/bin/sh\n# Glimmer farm job exported from %s: frames %d-%d.\n"
                    "# Add --dry-run to see the sbatch scripts; docs/farm.md for other farms.\nexec %s \"$@\"\n"
                    % (bpy.data.filepath or "an unsaved .blend", frames[0], frames[-1], line))
        os.chmod(command_path, 0o755)
        print("Glimmer: farm command: " + line)
        self.report({"INFO"}, "Glimmer: exported %d frames to %s; run %s" % (len(frames), directory, command_path))
        return {"FINISHED"}
