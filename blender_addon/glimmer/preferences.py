"""Addon preferences: where the glimmer executable is."""
import os
import shutil

import bpy

ADDON_ID = __package__


def default_executable():
    """$GLIMMER_EXECUTABLE, else the build next to the repository checkout the
    addon lives in (<repo>/blender_addon/glimmer -> <repo>/build/glimmer),
    else `glimmer` on PATH. Returns '' when none is found."""
    env = os.environ.get("GLIMMER_EXECUTABLE", "")
    if env:
        return env
    here = os.path.dirname(os.path.realpath(__file__))
    repo = os.path.dirname(os.path.dirname(here))
    for build in ("build", "build-release", "build-debug"):
        candidate = os.path.join(repo, build, "glimmer")
        if os.path.isfile(candidate) and os.access(candidate, os.X_OK):
            return candidate
    return shutil.which("glimmer") or ""


def executable_path(context=None):
    """The executable the addon runs: the preference when set, else the default."""
    context = context or bpy.context
    addon = context.preferences.addons.get(ADDON_ID) if context.preferences else None
    if addon is not None and addon.preferences is not None and addon.preferences.executable:
        return bpy.path.abspath(addon.preferences.executable)
    return default_executable()


class GlimmerPreferences(bpy.types.AddonPreferences):
    bl_idname = ADDON_ID

    executable: bpy.props.StringProperty(
        name="Glimmer Executable",
        description="Path of the `glimmer` command-line renderer (empty: the build next to the addon's "
                    "repository checkout, else `glimmer` on PATH)",
        subtype="FILE_PATH",
        default="",
    )

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "executable")
        found = executable_path(context)
        layout.label(text="Using: " + (found or "none found (nodes use the built-in schema snapshot)"))
