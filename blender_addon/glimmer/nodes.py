"""Glint BSDF and Frosted Glass BSDF shader nodes.

Each is a ShaderNodeCustomGroup whose sockets come from the closure schema
(`glimmer describe --json`, see schema.py): float/int/colour/vector
parameters are input sockets, enum/string/bool parameters are node
properties drawn on the node. The inner node group is a Cycles/EEVEE
approximation (Glossy BSDF for glints, Glass BSDF for frosted glass), so a
.blend using these nodes still renders sensibly without Glimmer. All nodes of
one kind share that inner group (".Glimmer Glint BSDF" ...).
"""
import bpy
from bpy.app.handlers import persistent

from . import schema as schema_mod

IS_4X = bpy.app.version >= (4, 0, 0)

# Fallback inner groups: Blender node type, its distribution, and which schema
# parameters feed which of its inputs.
FALLBACKS = {
    "glint": {"node": "ShaderNodeBsdfGlossy", "distribution": "GGX",
              "links": {"color": "Color", "roughness": "Roughness"}},
    "frosted_glass": {"node": "ShaderNodeBsdfGlass", "distribution": "GGX",
                      "links": {"color": "Color", "roughness": "Roughness", "ior": "IOR"}},
}

_node_classes = []
_menu_target = None
_CATEGORY_ID = "GLIMMER_SHADER_NODES"


def group_name(closure_name):
    return ".Glimmer " + schema_mod.NODE_CLOSURES[closure_name]["label"]


def property_name(param_name):
    """Node property holding a non-socket parameter (avoids clashing with Node attributes)."""
    base = bpy.types.ShaderNodeCustomGroup
    if param_name in base.bl_rna.properties or param_name in base.bl_rna.functions or hasattr(base, param_name):
        return "glimmer_" + param_name
    return param_name


def _socket_type(param):
    t = param["type"]
    if t == "float":
        return "NodeSocketFloatFactor" if (param.get("min") == 0.0 and param.get("max") == 1.0) else "NodeSocketFloat"
    return {"int": "NodeSocketInt", "color": "NodeSocketColor", "vector": "NodeSocketVector"}[t]


def interface_sockets(ng, in_out):
    if IS_4X:
        return [item for item in ng.interface.items_tree
                if getattr(item, "item_type", "SOCKET") == "SOCKET" and item.in_out == in_out]
    return list(ng.inputs if in_out == "INPUT" else ng.outputs)


def _new_interface_socket(ng, in_out, socket_type, name):
    if IS_4X:
        base = "NodeSocketFloat" if socket_type == "NodeSocketFloatFactor" else socket_type
        sock = ng.interface.new_socket(name=name, in_out=in_out, socket_type=base)
        if socket_type == "NodeSocketFloatFactor":
            try:
                sock.subtype = "FACTOR"
            except (AttributeError, TypeError):
                pass
        return sock
    return (ng.inputs if in_out == "INPUT" else ng.outputs).new(socket_type, name)


def _set_socket_default(sock, param):
    value = param["default"]
    if param["type"] == "color":
        sock.default_value = (value[0], value[1], value[2], 1.0)
    elif param["type"] == "vector":
        sock.default_value = tuple(value)
    else:
        sock.default_value = value


# Blender 3.x keeps a socket's description in a 64-byte buffer (63 characters): longer texts are cut short
# with " (...)", and the node's sidebar (draw_buttons_ext) shows every full text.
SOCKET_DESCRIPTION_MAX = 63
MORE = " (...)"


def socket_description(doc):
    """doc when it fits a socket description, else its longest word prefix that fits, followed by MORE."""
    if len(doc.encode()) <= SOCKET_DESCRIPTION_MAX:
        return doc
    room = SOCKET_DESCRIPTION_MAX - len(MORE)
    cut = doc.encode()[:room].decode(errors="ignore")
    if " " in cut:
        cut = cut[:cut.rindex(" ")]
    return cut.rstrip(" ,;:") + MORE


def parameter_notes(closure):
    """'Name: doc' for every parameter, the full texts behind socket_description."""
    return ["%s: %s" % (schema_mod.socket_name(p["name"]), p.get("doc", "")) for p in closure["params"]
            if p.get("doc")]


def _configure_interface_socket(sock, param):
    if param["type"] in ("float", "int"):
        lo, hi = param.get("min"), param.get("max")
        if lo is not None:
            sock.min_value = max(lo, -3.0e38) if param["type"] == "float" else int(max(lo, -2**31))
        if hi is not None:
            sock.max_value = min(hi, 3.0e38) if param["type"] == "float" else int(min(hi, 2**31 - 1))
    _set_socket_default(sock, param)
    if hasattr(sock, "description"):
        sock.description = socket_description(param.get("doc", ""))


def ensure_group(closure):
    """The shared inner group of a closure's node; created or completed to match the schema."""
    name = group_name(closure["name"])
    ng = bpy.data.node_groups.get(name)
    if ng is None:
        ng = bpy.data.node_groups.new(name, "ShaderNodeTree")
    have = {s.name for s in interface_sockets(ng, "INPUT")}
    for param in closure["params"]:
        if schema_mod.is_socket_param(param) and schema_mod.socket_name(param["name"]) not in have:
            sock = _new_interface_socket(ng, "INPUT", _socket_type(param), schema_mod.socket_name(param["name"]))
            _configure_interface_socket(sock, param)
    if "BSDF" not in {s.name for s in interface_sockets(ng, "OUTPUT")}:
        _new_interface_socket(ng, "OUTPUT", "NodeSocketShader", "BSDF")
    _build_fallback(ng, closure)
    return ng


def _build_fallback(ng, closure):
    """Group Input -> Glossy/Glass BSDF -> Group Output, the Cycles/EEVEE approximation."""
    fallback = FALLBACKS[closure["name"]]
    nodes = ng.nodes
    group_in = next((n for n in nodes if n.bl_idname == "NodeGroupInput"), None) or nodes.new("NodeGroupInput")
    group_out = next((n for n in nodes if n.bl_idname == "NodeGroupOutput"), None) or nodes.new("NodeGroupOutput")
    bsdf = next((n for n in nodes if n.bl_idname == fallback["node"]), None)
    if bsdf is None:
        bsdf = nodes.new(fallback["node"])
        bsdf.distribution = fallback["distribution"]
    group_in.location = (-400, 0)
    bsdf.location = (-100, 0)
    group_out.location = (200, 0)
    links = ng.links
    linked_inputs = {l.to_socket.identifier for l in links if l.to_node == bsdf}
    for param_name, input_name in fallback["links"].items():
        socket = schema_mod.socket_name(param_name)
        if socket in group_in.outputs and bsdf.inputs[input_name].identifier not in linked_inputs:
            links.new(group_in.outputs[socket], bsdf.inputs[input_name])
    if not group_out.inputs["BSDF"].is_linked:
        links.new(bsdf.outputs["BSDF"], group_out.inputs["BSDF"])


class GlimmerClosureNodeMixin:
    """Shared behaviour of the generated node classes (closure_name and schema set per class)."""
    closure_name = ""
    closure_schema = None

    @classmethod
    def poll(cls, node_tree):
        return node_tree.bl_idname == "ShaderNodeTree"

    def init(self, context):
        self.node_tree = ensure_group(self.closure_schema)
        for param in self.closure_schema["params"]:
            if schema_mod.is_socket_param(param):
                sock = self.inputs.get(schema_mod.socket_name(param["name"]))
                if sock is not None:
                    _set_socket_default(sock, param)

    def copy(self, node):
        self.node_tree = node.node_tree

    def draw_buttons(self, context, layout):
        for param in self.closure_schema["params"]:
            if not schema_mod.is_socket_param(param):
                layout.prop(self, property_name(param["name"]), text="")

    def draw_buttons_ext(self, context, layout):
        for param in self.closure_schema["params"]:
            if not schema_mod.is_socket_param(param):
                layout.prop(self, property_name(param["name"]))
        layout.label(text="Glimmer closure: " + self.closure_name)
        col = layout.column(align=True)
        for note in parameter_notes(self.closure_schema):
            col.label(text=note)

    def draw_label(self):
        return schema_mod.NODE_CLOSURES[self.closure_name]["label"]

    def param_values(self):
        """Non-socket parameter values {schema name: value} for the exporter."""
        out = {}
        for param in self.closure_schema["params"]:
            if not schema_mod.is_socket_param(param):
                out[param["name"]] = getattr(self, property_name(param["name"]))
        return out


def _tag_node_tree(node, _context):
    """A Python property's edit tags nothing by itself: without this the depsgraph's evaluated copy of the
    material keeps the old value once evaluated, so the viewport render and the exporter would not see it."""
    node.id_data.update_tag()


def _property_for(param):
    doc = param.get("doc", "")
    label = schema_mod.socket_name(param["name"])
    common = {"name": label, "description": doc, "update": _tag_node_tree}
    if param["type"] == "enum":
        items = [(c, c.replace("_", " ").title(), "") for c in param["choices"]]
        return bpy.props.EnumProperty(items=items, default=param["default"], **common)
    if param["type"] == "bool":
        return bpy.props.BoolProperty(default=bool(param["default"]), **common)
    return bpy.props.StringProperty(default=param.get("default", ""), **common)


def make_node_class(closure):
    info = schema_mod.NODE_CLOSURES[closure["name"]]
    annotations = {property_name(p["name"]): _property_for(p)
                   for p in closure["params"] if not schema_mod.is_socket_param(p)}
    return type(info["idname"], (GlimmerClosureNodeMixin, bpy.types.ShaderNodeCustomGroup), {
        "bl_idname": info["idname"],
        "bl_label": info["label"],
        "bl_description": closure.get("doc", ""),  # (parameter notes here crash Blender 3.4 at exit)
        "bl_width_default": 180,
        "closure_name": closure["name"],
        "closure_schema": closure,
        "__annotations__": annotations,
        "__doc__": closure.get("doc", ""),
    })


def _menu_draw(self, context):
    space = context.space_data
    if space is None or getattr(space, "tree_type", "") != "ShaderNodeTree":
        return
    layout = self.layout
    if _menu_target != "NODE_MT_add":
        layout.separator()
    for cls in _node_classes:
        op = layout.operator("node.add_node", text=cls.bl_label)
        op.type = cls.bl_idname
        op.use_transform = True


def menu_class():
    """The Shader submenu of the Add menu: a Python menu in 4.x, a generated
    nodeitems menu in 3.x."""
    for name in ("NODE_MT_category_shader_shader", "NODE_MT_category_SH_NEW_SHADER"):
        if hasattr(bpy.types, name):
            return name
    return None


def menu_draw_function():
    return _menu_draw


@persistent
def _sync_groups_on_load(_dummy=None):
    """After loading a .blend, complete inner groups if the schema grew new parameters."""
    for cls in _node_classes:
        if bpy.data.node_groups.get(group_name(cls.closure_name)) is not None:
            ensure_group(cls.closure_schema)


def register(schema):
    global _menu_target
    for closure_name in schema_mod.NODE_CLOSURES:
        closure = schema_mod.closure(schema, closure_name)
        if closure is None:
            continue
        cls = make_node_class(closure)
        bpy.utils.register_class(cls)
        _node_classes.append(cls)
    _menu_target = menu_class()
    if _menu_target is not None:
        getattr(bpy.types, _menu_target).append(_menu_draw)
    else:  # Some other layout: register a category in the nodeitems system.
        import nodeitems_utils
        from nodeitems_utils import NodeCategory, NodeItem

        class GlimmerCategory(NodeCategory):
            @classmethod
            def poll(cls, context):
                return context.space_data.tree_type == "ShaderNodeTree"

        nodeitems_utils.register_node_categories(
            _CATEGORY_ID, [GlimmerCategory(_CATEGORY_ID, "Glimmer", items=[NodeItem(c.bl_idname) for c in _node_classes])])
        _menu_target = "nodeitems"
    bpy.app.handlers.load_post.append(_sync_groups_on_load)


def unregister():
    global _menu_target
    if _sync_groups_on_load in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_sync_groups_on_load)
    if _menu_target == "nodeitems":
        import nodeitems_utils
        nodeitems_utils.unregister_node_categories(_CATEGORY_ID)
    elif _menu_target is not None and hasattr(bpy.types, _menu_target):
        getattr(bpy.types, _menu_target).remove(_menu_draw)
    _menu_target = None
    for cls in reversed(_node_classes):
        bpy.utils.unregister_class(cls)
    _node_classes.clear()


def node_classes():
    return list(_node_classes)
