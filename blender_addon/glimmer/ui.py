"""Property panels for the Glimmer engine."""
import bpy

ENGINE = "GLIMMER"


class GlimmerPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class GLIMMER_PT_sampling(GlimmerPanel, bpy.types.Panel):
    bl_label = "Sampling"
    bl_context = "render"

    def draw(self, context):
        settings = context.scene.glimmer
        layout = self.layout
        layout.use_property_split = True
        layout.prop(settings, "samples")
        layout.prop(settings, "seed")
        layout.prop(settings, "use_animated_seed")
        layout.prop(settings, "threads")


class GLIMMER_PT_light_paths(GlimmerPanel, bpy.types.Panel):
    bl_label = "Light Paths"
    bl_context = "render"

    def draw(self, context):
        settings = context.scene.glimmer
        layout = self.layout
        layout.use_property_split = True
        col = layout.column(heading="Max Bounces")
        for prop in ("max_bounce", "max_diffuse_bounce", "max_glossy_bounce", "max_transmission_bounce",
                     "transparent_max_bounce", "min_bounce"):
            col.prop(settings, prop)
        col = layout.column()
        col.prop(settings, "filter_glossy")
        col.prop(settings, "sample_clamp_direct")
        col.prop(settings, "sample_clamp_indirect")


class GLIMMER_PT_film(GlimmerPanel, bpy.types.Panel):
    bl_label = "Film"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        settings = context.scene.glimmer
        layout = self.layout
        layout.use_property_split = True
        layout.prop(settings, "film_exposure")
        layout.prop(settings, "filter_type")
        layout.prop(settings, "filter_width")


class GLIMMER_PT_materials(GlimmerPanel, bpy.types.Panel):
    bl_label = "Glint and Frosted Glass"
    bl_context = "render"

    def draw(self, context):
        settings = context.scene.glimmer
        layout = self.layout
        layout.use_property_split = True
        layout.prop(settings, "use_glint")
        layout.prop(settings, "use_frosted_glass")
        layout.label(text="Per-material settings are on the Glint / Frosted Glass BSDF nodes.")


class GLIMMER_PT_export(GlimmerPanel, bpy.types.Panel):
    bl_label = "Export"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        settings = context.scene.glimmer
        layout = self.layout
        layout.use_property_split = True
        layout.prop(settings, "export_dir")
        layout.prop(settings, "keep_export")


def _surface_panel_draw(layout, ntree, output_type, input_name):
    output = next((n for n in ntree.nodes if n.bl_idname == output_type and n.is_active_output), None)
    if output is None:
        output = next((n for n in ntree.nodes if n.bl_idname == output_type), None)
    if output is None:
        layout.label(text="No output node")
        return
    layout.template_node_view(ntree, output, output.inputs[input_name])


class GLIMMER_PT_material_surface(GlimmerPanel, bpy.types.Panel):
    bl_label = "Surface"
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return context.material is not None and super().poll(context)

    def draw(self, context):
        mat = context.material
        layout = self.layout
        if not mat.use_nodes:
            layout.prop(mat, "use_nodes", icon="NODETREE")
            layout.prop(mat, "diffuse_color", text="Color")
            return
        _surface_panel_draw(layout, mat.node_tree, "ShaderNodeOutputMaterial", "Surface")


class GLIMMER_PT_world_surface(GlimmerPanel, bpy.types.Panel):
    bl_label = "Surface"
    bl_context = "world"

    @classmethod
    def poll(cls, context):
        return context.world is not None and super().poll(context)

    def draw(self, context):
        world = context.world
        layout = self.layout
        if not world.use_nodes:
            layout.prop(world, "use_nodes", icon="NODETREE")
            layout.prop(world, "color")
            return
        _surface_panel_draw(layout, world.node_tree, "ShaderNodeOutputWorld", "Surface")


CLASSES = (GLIMMER_PT_sampling, GLIMMER_PT_light_paths, GLIMMER_PT_film, GLIMMER_PT_materials,
           GLIMMER_PT_export, GLIMMER_PT_material_surface, GLIMMER_PT_world_surface)

# Blender's own panels shown for Glimmer too (object data, lights, cameras, output, ...).
_borrowed = []


def borrow_builtin_panels():
    wanted = {"BLENDER_RENDER", "BLENDER_EEVEE", "BLENDER_EEVEE_NEXT"}
    skip_prefixes = ("EEVEE_", "RENDER_PT_eevee", "MATERIAL_PT_", "WORLD_PT_", "RENDER_PT_simplify",
                     "VIEWLAYER_PT_eevee", "DATA_PT_EEVEE")
    keep = {"EEVEE_MATERIAL_PT_context_material", "WORLD_PT_context_world"}
    for name in dir(bpy.types):
        panel = getattr(bpy.types, name, None)
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if not isinstance(engines, set) or ENGINE in engines or not (engines & wanted):
            continue
        if name.startswith(skip_prefixes) and name not in keep:
            continue
        engines.add(ENGINE)
        _borrowed.append(panel)


def return_builtin_panels():
    for panel in _borrowed:
        panel.COMPAT_ENGINES.discard(ENGINE)
    _borrowed.clear()
