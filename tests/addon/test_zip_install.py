"""`make addon`'s zip installs through Blender's own add-on installer and works
from the installed copy (not from the repository)."""
import os
import subprocess
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
scripts = os.environ.get("BLENDER_USER_SCRIPTS", "")
check(scripts and os.path.realpath(scripts).startswith(os.path.realpath(opts.out)),
      "BLENDER_USER_SCRIPTS must point into the scratch folder (set by ctest), got '%s'" % scripts)
zip_path = os.path.join(opts.out, "glimmer_addon.zip")
subprocess.run([sys.executable if os.path.basename(sys.executable).startswith("python") else "python3",
                os.path.join(util.REPO, "tools", "make_addon_zip.py"), "--output", zip_path], check=True)
result = bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True)
check(result == {"FINISHED"}, "addon_install: %s" % result)
import addon_utils  # noqa: E402

mod = addon_utils.enable("glimmer", default_set=True)
check(mod is not None, "installed addon enabled")
installed = os.path.realpath(os.path.dirname(mod.__file__))
check(installed.startswith(os.path.realpath(scripts)), "loaded from the installed copy: %s" % installed)
check("GLIMMER" in {e.bl_idname for e in bpy.types.RenderEngine.__subclasses__()}, "engine registered")
check(os.path.isfile(os.path.join(installed, "closures_schema.json")), "schema snapshot installed")
check(bpy.types.Node.bl_rna_get_subclass_py("GlimmerNodeGlintBsdf") is not None, "glint node registered")
addon_utils.disable("glimmer", default_set=True)
util.done("test_zip_install")
