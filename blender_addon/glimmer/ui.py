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


class GlimmerRenderPanel(GlimmerPanel):
    """Render properties panel listing the scene settings named in `props`."""
    bl_context = "render"
    props = ()

    def draw(self, context):
        settings = context.scene.glimmer
        layout = self.layout
        layout.use_property_split = True
        for prop in self.props:
            layout.prop(settings, prop)


class GLIMMER_PT_sampling(GlimmerRenderPanel, bpy.types.Panel):
    bl_label = "Sampling"
    props = ("samples", "seed", "use_animated_seed", "threads")


class GLIMMER_PT_light_paths(GlimmerRenderPanel, bpy.types.Panel):
    bl_label = "Light Paths"

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


class GLIMMER_PT_film(GlimmerRenderPanel, bpy.types.Panel):
    bl_label = "Film"
    bl_options = {"DEFAULT_CLOSED"}
    props = ("film_exposure", "filter_type", "filter_width")


class GLIMMER_PT_materials(GlimmerRenderPanel, bpy.types.Panel):
    bl_label = "Glint and Frosted Glass"
    props = ("use_glint", "use_frosted_glass")

    def draw(self, context):
        GlimmerRenderPanel.draw(self, context)
        self.layout.label(text="Per-material settings are on the Glint / Frosted Glass BSDF nodes.")


class GLIMMER_PT_export(GlimmerRenderPanel, bpy.types.Panel):
    bl_label = "Export"
    bl_options = {"DEFAULT_CLOSED"}
    props = ("export_dir", "keep_export")

    def draw(self, context):
        GlimmerRenderPanel.draw(self, context)
        self.layout.operator("glimmer.export_for_farm", icon="NETWORK_DRIVE")


class GlimmerSurfacePanel(GlimmerPanel):
    """The node tree behind the active output's Surface input of context.<bl_context>
    (a material or the world); without nodes, the use_nodes switch and `color_prop`."""
    bl_label = "Surface"
    output_type = ""
    color_prop = ""
    color_text = None

    @classmethod
    def poll(cls, context):
        return getattr(context, cls.bl_context) is not None and super().poll(context)

    def draw(self, context):
        owner = getattr(context, self.bl_context)
        layout = self.layout
        if not owner.use_nodes:
            layout.prop(owner, "use_nodes", icon="NODETREE")
            if self.color_text is None:
                layout.prop(owner, self.color_prop)
            else:
                layout.prop(owner, self.color_prop, text=self.color_text)
            return
        ntree = owner.node_tree
        output = next((n for n in ntree.nodes if n.bl_idname == self.output_type and n.is_active_output), None)
        if output is None:
            output = next((n for n in ntree.nodes if n.bl_idname == self.output_type), None)
        if output is None:
            layout.label(text="No output node")
            return
        layout.template_node_view(ntree, output, output.inputs["Surface"])


class GLIMMER_PT_material_surface(GlimmerSurfacePanel, bpy.types.Panel):
    bl_context = "material"
    output_type = "ShaderNodeOutputMaterial"
    color_prop = "diffuse_color"
    color_text = "Color"


class GLIMMER_PT_world_surface(GlimmerSurfacePanel, bpy.types.Panel):
    bl_context = "world"
    output_type = "ShaderNodeOutputWorld"
    color_prop = "color"


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
