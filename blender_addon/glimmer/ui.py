"""Property panels for the Glimmer engine, and Blender's own panels and shader nodes made available to it."""
import bpy

from . import exporter, schema

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
    props = ("samples", "seed", "use_animated_seed", "threads", "use_progressive", "progressive_interval")


class GLIMMER_PT_light_paths(GlimmerRenderPanel, bpy.types.Panel):
    """The integrator settings (generated from the scene settings table): bounce limits, then the rest."""
    bl_label = "Light Paths"

    def draw(self, context):
        settings = context.scene.glimmer
        layout = self.layout
        layout.use_property_split = True
        rows = list(schema.setting_rows("integrator"))
        col = layout.column(heading="Max Bounces")
        for _, row, prop in rows:
            if row["type"] == "int":
                col.prop(settings, prop)
        col = layout.column()
        for _, row, prop in rows:
            if row["type"] != "int":
                col.prop(settings, prop)


class GLIMMER_PT_film(GlimmerRenderPanel, bpy.types.Panel):
    bl_label = "Film"
    bl_options = {"DEFAULT_CLOSED"}
    props = tuple(prop for _, _, prop in schema.setting_rows("film"))


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


class GLIMMER_PT_light(GlimmerPanel, bpy.types.Panel):
    """Exactly the light settings the exporter writes (Blender's EEVEE/Workbench light panels show factors and
    shadow settings Glimmer ignores)."""
    bl_label = "Light"
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return context.light is not None and super().poll(context)

    def draw(self, context):
        light = context.light
        layout = self.layout
        layout.row().prop(light, "type", expand=True)
        layout.use_property_split = True
        col = layout.column()
        col.prop(light, "color")
        col.prop(light, "energy")
        if light.type in {"POINT", "SPOT"}:
            col.prop(light, "shadow_soft_size", text="Radius")
        elif light.type == "SUN":
            col.prop(light, "angle")
        elif light.type == "AREA":
            col.prop(light, "shape")
            if light.shape in {"SQUARE", "DISK"}:
                col.prop(light, "size")
            else:
                col.prop(light, "size", text="Size X")
                col.prop(light, "size_y", text="Size Y")
            if hasattr(light, "spread"):
                col.prop(light, "spread")
        if light.type == "SPOT":
            col.prop(light, "spot_size", text="Spot Size")
            col.prop(light, "spot_blend", text="Blend")
            col.prop(light, "show_cone")


CLASSES = (GLIMMER_PT_sampling, GLIMMER_PT_light_paths, GLIMMER_PT_film, GLIMMER_PT_materials,
           GLIMMER_PT_export, GLIMMER_PT_material_surface, GLIMMER_PT_world_surface, GLIMMER_PT_light)

# Blender's light panels: replaced by GLIMMER_PT_light (they would show a second "Light" panel).
LIGHT_PANELS = ("DATA_PT_light", "DATA_PT_EEVEE_light", "DATA_PT_EEVEE_light_distance", "NODE_DATA_PT_light",
                "NODE_DATA_PT_EEVEE_light", "DATA_PT_area", "DATA_PT_spot", "DATA_PT_falloff_curve")

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
        if (name.startswith(skip_prefixes) and name not in keep) or name in LIGHT_PANELS:
            continue
        engines.add(ENGINE)
        _borrowed.append(panel)
    for name in LIGHT_PANELS:  # also when their engine set is shared with a borrowed panel
        panel = getattr(bpy.types, name, None)
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if isinstance(engines, set) and ENGINE in engines:
            engines.discard(ENGINE)


def return_builtin_panels():
    for panel in _borrowed:
        panel.COMPAT_ENGINES.discard(ENGINE)
    _borrowed.clear()


# -- Standard shader nodes in the Add menu ---------------------------------------------------------------------
# Blender 3.x lists shader nodes through nodeitems; the Cycles ones have polls testing `context.engine == 'CYCLES'`.
# Nodes the exporter translates get a poll that answers as for Cycles (so the object/world restrictions stay).
SUPPORTED_SHADER_NODES = frozenset(exporter.TRANSLATORS) - {"ShaderNodeGroup"} | {
    "ShaderNodeOutputMaterial", "ShaderNodeOutputWorld", "ShaderNodeUVMap", "ShaderNodeTexCoord"}
_patched_items = []  # (NodeItem, original poll)


class _AsCycles:
    """A context that reports the Cycles engine, for the nodeitems polls."""

    def __init__(self, context):
        self._context = context

    engine = "CYCLES"

    def __getattr__(self, name):
        return getattr(self._context, name)


def _glimmer_poll(original):
    def poll(context):
        if context.engine == ENGINE:
            return original(_AsCycles(context))
        return original(context)
    return poll


def shader_node_items():
    """Blender's shader NodeItems (empty when this Blender has no nodeitems categories)."""
    try:
        import nodeitems_utils
    except ImportError:
        return []
    entry = nodeitems_utils._node_categories.get("SHADER")
    if entry is None:
        return []
    items = []
    for category in entry[0]:
        for item in category.items(None):  # no context: every item
            if hasattr(item, "nodetype"):
                items.append(item)
    return items


def borrow_shader_nodes():
    for item in shader_node_items():
        if item.nodetype in SUPPORTED_SHADER_NODES and item.poll is not None:
            _patched_items.append((item, item.poll))
            item.poll = _glimmer_poll(item.poll)


def return_shader_nodes():
    for item, original in _patched_items:
        item.poll = original
    _patched_items.clear()
