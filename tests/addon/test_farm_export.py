"""Export for Farm: an animated scene, frames 1-3, exports frame_0001..3/scene.xml
(each with its frame's object position), writes the `glimmer farm slurm` command,
and that command (with --dry-run) accepts the export; one exported frame renders."""
import os
import shutil
import subprocess
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
mod, glimmer = util.enable_addon_with_renderer()
out_dir = os.path.join(opts.out, "farm_export")
shutil.rmtree(out_dir, ignore_errors=True)

bpy.ops.wm.read_homefile(use_empty=True)
scene = bpy.context.scene
scene.render.engine = "GLIMMER"
scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 32, 24, 100
scene.frame_start, scene.frame_end, scene.frame_current = 1, 3, 2
scene.glimmer.samples = 3
util.add_camera(scene, (0.0, -6.0, 0.0), (1.5708, 0.0, 0.0))
util.add_light(scene, "POINT", 500.0, (0.0, -3.0, 3.0), name="Lamp")
bpy.ops.mesh.primitive_cube_add(size=1.0)
cube = bpy.context.active_object
for frame, x in ((1, -1.0), (3, 1.0)):  # the cube moves from x = -1 to x = 1
    cube.location = (x, 0.0, 0.0)
    cube.keyframe_insert("location", frame=frame)

result = bpy.ops.glimmer.export_for_farm(directory=out_dir, split="SAMPLES", parts=2)
check(result == {"FINISHED"}, "operator returned %s" % result)
check(scene.frame_current == 2, "the current frame is restored (got %d)" % scene.frame_current)

# One scene per frame, each with its meshes; the cube's vertices move with the frame.
ply_bytes = []
for frame in (1, 2, 3):
    xml = os.path.join(out_dir, "frame_%04d" % frame, "scene.xml")
    check(os.path.isfile(xml), "%s exported" % xml)
    meshes = os.path.join(out_dir, "frame_%04d" % frame, "meshes")
    plys = sorted(os.listdir(meshes))
    check(len(plys) == 1, "one mesh per frame, got %s" % plys)
    with open(os.path.join(meshes, plys[0]), "rb") as f:
        ply_bytes.append(f.read())
check(len(set(ply_bytes)) == 3, "the animated cube differs between the three frames")

# The command line: farm slurm over frame_####/scene.xml, frames 1-3, 2 sample splits, the scene's samples.
command_file = os.path.join(out_dir, "farm_command.sh")
with open(command_file) as f:
    text = f.read()
for want in ("farm slurm", os.path.join(out_dir, "frame_####", "scene.xml"), "--frames 1-3", "--sample-splits 2",
             "--samples 3", os.path.join(out_dir, "render", "frame_####.exr")):
    check(want in text, "%r in %s:\n%s" % (want, command_file, text))

check(os.path.isdir(os.path.join(out_dir, "render")), "the folder of the merged frames exists")

# The farm command accepts the export (every frame's scene found) and prints the job array.
run = subprocess.run(["sh", command_file, "--dry-run"], capture_output=True, text=True, timeout=60)
check(run.returncode == 0, "dry run failed:\n%s%s" % (run.stdout, run.stderr))
check("#SBATCH --array=0-5" in run.stdout and "FRAMES=(1 2 3)" in run.stdout, run.stdout)

# An exported frame renders (one of its parts, as a farm task would).
part = os.path.join(out_dir, "part.exr")
run = subprocess.run([glimmer, "render", os.path.join(out_dir, "frame_####", "scene.xml"), "--frames", "2",
                      "-o", part, "--samples", "3", "--sample-split", "1/2", "--quiet"],
                     capture_output=True, text=True, timeout=120)
check(run.returncode == 0 and os.path.isfile(part), "render of frame 2 failed:\n%s%s" % (run.stdout, run.stderr))

util.done("test_farm_export")
