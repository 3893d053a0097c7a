"""Blender scene -> Cycles standalone XML (+ binary PLY meshes) for `glimmer render`.

Conventions (see docs/blender.md):
- Meshes are baked to world space in PLY files (meshes/<object>.ply) referenced
  by `<mesh src=...>` inside `<state shader=... interpolation=...>`.
- Camera: `<transform translate rotate scale="sx sy -sz">` around `<camera>`:
  Blender cameras look along -Z, Cycles' along +Z, hence the scale 1 1 -1.
- Lights: use_camera from the object's camera visibility (off by default in Blender);
  world-space co/dir/axes, strength = colour * power (W) for point,
  spot and area lights and colour * strength (W/m^2) for sun lights, exactly
  the numbers Blender hands to Cycles (Cycles applies the 1/(4 pi) and area
  normalisation itself).
- Materials: nodes are translated to Cycles XML shader nodes; anything else is
  reported once per material as a warning and replaced by the documented
  fallback (a shader node -> diffuse_bsdf with the node's colour input, a
  texture/converter node -> its consumer keeps its own unlinked value).
"""
import math
import os
import re
import shutil
import xml.etree.ElementTree as ET

import bpy
import numpy as np

from . import mesh_export
from . import nodes as glimmer_nodes
from . import schema as schema_mod

# Object types exported as triangle meshes (hair curves, point clouds and volumes are skipped with a warning).
MESH_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT"}
# Types whose evaluated geometry the depsgraph also lists as a mesh instance of the same object (Blender 3.0+):
# only that instance is exported, else the surface would be written twice.
CURVE_LIKE_TYPES = {"CURVE", "SURFACE", "META", "FONT"}
# Renderable object types Glimmer cannot render, as named in the warning.
SKIPPED_TYPES = {"CURVES": "hair curves", "POINTCLOUD": "point cloud", "VOLUME": "volume", "GPENCIL": "grease pencil"}
# View layer switches that are passes Glimmer writes (Combined, Depth, Normal) or not passes at all.
HOST_PASSES = {"use_pass_combined", "use_pass_z", "use_pass_normal", "use_pass_cryptomatte_accurate"}
# Cycles renders a missing image texture in this colour.
MISSING_TEXTURE_COLOR = (255, 0, 255)

GLOSSY_DISTRIBUTION = {"SHARP": "sharp", "BECKMANN": "beckmann", "GGX": "GGX", "MULTI_GGX": "Multiscatter GGX",
                       "ASHIKHMIN_SHIRLEY": "GGX"}
# Principled BSDF inputs -> principled_bsdf attributes (Blender 3.x name first, then 4.x).
PRINCIPLED_SOCKETS = (("base_color", ("Base Color",)), ("metallic", ("Metallic",)), ("roughness", ("Roughness",)),
                      ("transmission", ("Transmission", "Transmission Weight")), ("ior", ("IOR",)),
                      ("clearcoat", ("Clearcoat", "Coat Weight")),
                      ("clearcoat_roughness", ("Clearcoat Roughness", "Coat Roughness")), ("alpha", ("Alpha",)),
                      ("emission", ("Emission", "Emission Color")), ("emission_strength", ("Emission Strength",)))
# Cycles 3.x's GGX and Beckmann lobes use the separable Smith G1(wi) G1(wo) (4.x the height-correlated G2, the
# closures' default): exported from Blender 3.x as `shadowing="separable"` (docs/microfacet.md). Multiscatter GGX
# keeps the height-correlated G its energy tables need (the closure refuses the combination).
SEPARABLE_SHADOWING = bpy.app.version < (4, 0, 0)


def microfacet_attributes(distribution):
    """The distribution attribute of a glossy/glass/refraction element (Blender's name -> Cycles XML) and, when
    exporting from Blender 3.x, Cycles 3.x's separable shadowing for its single-scattering distributions."""
    cycles_name = GLOSSY_DISTRIBUTION.get(distribution, "GGX")
    attributes = {"distribution": cycles_name}
    if SEPARABLE_SHADOWING and cycles_name in ("GGX", "beckmann"):
        attributes["shadowing"] = "separable"
    return attributes


IMAGE_INTERPOLATION = {"Closest": "closest", "Linear": "linear", "Cubic": "cubic", "Smart": "smart"}
IMAGE_EXTENSION = {"REPEAT": "periodic", "EXTEND": "extend", "CLIP": "clip", "MIRROR": "mirror"}
IMAGE_PROJECTION = {"FLAT": "flat", "BOX": "box", "SPHERE": "sphere", "TUBE": "tube"}

# Light attribute names (issue 3's scene format).
LIGHT_RADIUS = "radius"


def fmt(value):
    """Float(s) as XML text: '0.5' or '1 0 0'."""
    if isinstance(value, (list, tuple, np.ndarray)) or hasattr(value, "__len__"):
        return " ".join(fmt(v) for v in value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    return "%.9g" % (float(value) + 0.0)  # + 0.0 turns -0 into 0


def safe_name(name):
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name) or "unnamed"


class UniqueNames:
    def __init__(self):
        self.used = set()

    def __call__(self, name):
        base = safe_name(name)
        candidate, i = base, 1
        while candidate in self.used:
            i += 1
            candidate = "%s_%d" % (base, i)
        self.used.add(candidate)
        return candidate


def _input(node, *names):
    """First input of node with one of the given names (Blender renamed some in 4.x)."""
    for name in names:
        sock = node.inputs.get(name)
        if sock is not None:
            return sock
    return None


def _value(sock, default=0.0):
    if sock is None:
        return default
    value = sock.default_value
    if hasattr(value, "__len__"):
        return tuple(value)[:3]
    return value


def _scalar(sock, default=0.0):
    """A socket's value as a float socket reads it (Blender's implicit conversions, as the renderer's: a colour's
    luminance, Rec. 709 weights; a vector's mean)."""
    value = _value(sock, default)
    if not isinstance(value, tuple):
        return value
    if sock.type == "RGBA":
        return 0.2126 * value[0] + 0.7152 * value[1] + 0.0722 * value[2]
    return sum(value) / len(value)


class ShaderGraph:
    """Translates one Blender node tree into the children of an XML <shader>/<background>."""

    def __init__(self, exporter, element, owner):
        self.exporter = exporter
        self.element = element
        self.owner = owner
        self.names = UniqueNames()
        self.exported = {}  # (group path, node name, output identifier) -> (xml node, xml socket) or None
        self.warned = set()
        self.read_inputs = set()  # (group path, node name, input identifier) the translators looked at (mark_read)
        self.uses_generated = False  # a texture reads generated coordinates: meshes go in object space
        self.uv_maps = set()  # UV maps named by UV Map / Normal Map / Tangent nodes (a mesh has one UV map)
        self.uv_glints = set()  # Glint nodes whose flakes live in uv space (placement uv)
        # The artist's node groups being read, outermost first: a group is flattened, its nodes translated as if
        # they stood in the material's tree (group_path() keys them apart from nodes of the same name outside).
        self.groups = []

    # -- helpers -------------------------------------------------------------
    def group_path(self, groups=None):
        """The names of the group nodes (self.groups, or `groups`) from the material's tree inward: a node key's
        first part."""
        return tuple(g.name for g in (self.groups if groups is None else groups))

    def mark_read(self, node, sock):
        self.read_inputs.add((self.group_path(), node.name, sock.identifier))

    def warn(self, key, message):
        if key not in self.warned:
            self.warned.add(key)
            self.exporter.warn("%s: %s" % (self.owner, message))

    def add(self, xml_type, name, **attributes):
        xml_name = self.names(name)
        el = ET.SubElement(self.element, xml_type, name=xml_name)
        for key, value in attributes.items():
            if value is not None:
                el.set(key, value if isinstance(value, str) else fmt(value))
        return el

    def connect(self, source, target_node, target_socket):
        ET.SubElement(self.element, "connect", attrib={"from": "%s %s" % source,
                                                       "to": "%s %s" % (target_node, target_socket)})

    def set_input(self, el, attribute, sock, default=None, transform=None):
        """Link a Blender input into el's attribute, or write its value."""
        source = self.source_of(sock) if sock is not None else None
        if source is not None:
            if transform is not None:
                self.warn(("transform", el.get("name"), attribute),
                          "linked input '%s' feeds a value the exporter derives; its texture is used unscaled"
                          % sock.name)
            self.connect(source, el.get("name"), attribute)
            return
        value = _value(sock, default) if sock is not None else default
        if value is None:
            return
        if transform is not None:
            value = transform(value)
        el.set(attribute, fmt(value))

    def source_of(self, sock):
        """(xml node, xml socket) feeding a Blender input socket, or None when unlinked/unsupported (the socket's
        own value applies). Through the artist's node groups: a group input left unlinked outside the group, or a
        group output left unlinked inside, becomes a constant node of that socket's value."""
        self.mark_read(sock.node, sock)
        node, out, groups = self.upstream(sock)
        if node is None:
            return None if out is None or out.type == "SHADER" else self.constant(out, groups)
        key = (self.group_path(groups), node.name, out.identifier)
        if key not in self.exported:
            outer, self.groups = self.groups, groups
            try:
                self.exported[key] = self.translate(node, out)
            finally:
                self.groups = outer
        return self.exported[key]

    def upstream(self, sock):
        """What feeds input `sock` (in the current group context): (node, its output socket, the group stack at
        that node) for the node that computes it; (None, a group socket, stack) when the value is that group
        socket's own (an unlinked input of the group node, an unlinked output inside the group); (None, None,
        stack) when the socket's own value applies. Follows reroutes, muted nodes (their internal links) and group
        boundaries; muted and invalid links count as no link (a chain ending unlinked after a group socket takes
        that socket's value, as in Blender)."""
        groups = list(self.groups)
        value_sock = None  # a group socket crossed last: its value applies where the chain ends unlinked
        hidden = False  # the socket fed by the last Group Input crossed hides its value (a texture's Vector, Normal)
        while True:
            link = sock.links[0] if sock.is_linked else None
            if link is None or not link.is_valid or getattr(link, "is_muted", False):
                # Blender unlinks a hidden-value socket from a Group Input whose group socket is unlinked
                # (ntree_shader_unlink_hidden_value_sockets): it then reads the shading point, not the value.
                return None, None if hidden else value_sock, groups
            node, out = link.from_node, link.from_socket
            if node.bl_idname == "NodeReroute":
                sock = node.inputs[0]
                continue
            if node.mute:  # a muted node passes its first matching input through (Blender's internal links)
                internal = next((i for i in node.internal_links if i.to_socket == out), None)
                if internal is None:
                    return None, None, groups
                sock, value_sock = internal.from_socket, None
                continue
            if node.bl_idname == "NodeGroupInput":  # inside a group: the group node's input of that identifier
                outer = next((s for s in groups[-1].inputs if s.identifier == out.identifier), None) if groups \
                    else None
                if outer is None:
                    return None, None, groups
                groups.pop()
                hidden = bool(getattr(sock, "hide_value", False))
                sock = value_sock = outer
                continue
            if node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None:  # into the group
                inner = self.group_output_socket(node, out)
                if inner is None:
                    return None, None, groups
                groups.append(node)
                sock = value_sock = inner
                hidden = False
                continue
            return node, out, groups

    def group_output_socket(self, group, out):
        """The input of the group's active Group Output node that feeds the group node's output `out`."""
        outputs = [n for n in group.node_tree.nodes if n.bl_idname == "NodeGroupOutput"]
        node = next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)
        if node is None:
            self.warn((group.name, "no output"), "node group '%s' has no Group Output node: its outputs are "
                      "unlinked" % group.name)
            return None
        return next((s for s in node.inputs if s.identifier == out.identifier), None)

    def constant(self, sock, groups):
        """A constant node holding a group socket's value (float, colour or vector), or None for other types."""
        key = ("constant", self.group_path(groups), sock.node.name, sock.is_output, sock.identifier)
        if key not in self.exported:
            name = "%s_%s" % (sock.node.name, sock.name)
            value = _value(sock)
            if sock.type in ("VALUE", "INT", "BOOLEAN"):
                self.exported[key] = (self.add("value", name, value=float(value)).get("name"), "value")
            elif sock.type == "RGBA":
                self.exported[key] = (self.add("color", name, value=value).get("name"), "color")
            elif sock.type == "VECTOR":
                el = self.add("combine_xyz", name, x=value[0], y=value[1], z=value[2])
                self.exported[key] = (el.get("name"), "vector")
            else:
                self.exported[key] = None
        return self.exported[key]

    # -- node translation ------------------------------------------------------
    def translate(self, node, out):
        handler = TRANSLATORS.get(node.bl_idname)
        if handler is None and isinstance(node, glimmer_nodes.GlimmerClosureNodeMixin):
            handler = ShaderGraph.glimmer_node
        if handler is None:
            return self.unsupported(node, out)
        result = handler(self, node, out)
        self.warn_unread_links(node)
        return result

    def warn_unread_links(self, node):
        """Linked inputs of a translated node that no translator read (Normal <- Bump/Normal Map, Tangent, ...)."""
        for sock in node.inputs:
            if not sock.is_linked or not sock.enabled or (self.group_path(), node.name, sock.identifier) in \
                    self.read_inputs:
                continue
            source, value_sock, _ = self.upstream(sock)
            if source is None and value_sock is None:  # a muted link, an unlinked reroute or hidden group socket
                continue
            source = source or value_sock.node
            self.warn((node.name, "unread", sock.identifier),
                      "input '%s' of node '%s' is linked to '%s' (%s), which is not exported: the node renders "
                      "with that input unlinked" % (sock.name, node.name, source.name, source.bl_idname))

    def warn_unexported_values(self, node, *checks):
        """checks: (input names, value that has no effect, what it is); warns when the input is set otherwise."""
        for names, idle, label in checks:
            sock = _input(node, *names)
            if sock is None:
                continue
            self.mark_read(node, sock)
            source, value_sock, _ = self.upstream(sock)
            if source is not None or abs(float(_scalar(value_sock or sock, idle)) - idle) > 1e-6:
                self.warn((node.name, label), "node '%s': %s is not supported and is ignored" % (node.name, label))

    def unsupported(self, node, out):
        if out.type == "SHADER":
            self.warn(node.name, "node '%s' (%s) is not supported by Glimmer: rendered as a diffuse BSDF with its "
                      "colour" % (node.name, node.bl_idname))
            el = self.add("diffuse_bsdf", node.name + "_fallback")
            self.set_input(el, "color", _input(node, "Color", "Base Color"), default=(0.8, 0.8, 0.8))
            return (el.get("name"), "bsdf")
        self.warn(node.name, "node '%s' (%s) is not supported by Glimmer: the input it feeds keeps its own "
                  "value" % (node.name, node.bl_idname))
        return None

    def link_frame(self, el, node, *sockets):
        """The closure's Normal (Bump, Normal Map, ...) and Tangent inputs when linked: the renderer gives the
        closure its own frame per shading point. Unlinked, the renderer uses the shading point's own."""
        for name in sockets:
            sock = node.inputs.get(name)
            if sock is None:
                continue
            source = self.source_of(sock)
            if source is not None:
                self.connect(source, el.get("name"), name.lower())

    def bsdf_diffuse(self, node, out):
        el = self.add("diffuse_bsdf", node.name)
        self.set_input(el, "color", node.inputs["Color"])
        self.set_input(el, "roughness", node.inputs.get("Roughness"))
        self.link_frame(el, node, "Normal")
        return (el.get("name"), "bsdf")

    def bsdf_glossy(self, node, out):
        """Glossy / Anisotropic BSDF: anisotropy (Cycles 3.4 mapping), rotation, and the Normal and Tangent
        inputs; an unlinked tangent is Cycles' default in the renderer too (radial about generated Z)."""
        el = self.add("glossy_bsdf", node.name, **microfacet_attributes(node.distribution))
        self.set_input(el, "color", node.inputs["Color"])
        self.set_input(el, "roughness", node.inputs["Roughness"])
        anisotropy = node.inputs.get("Anisotropy")
        if anisotropy is not None:
            self.set_input(el, "anisotropy", anisotropy)
            source, value_sock, _ = self.upstream(anisotropy)
            if source is not None or abs(float(_scalar(value_sock or anisotropy))) > 1e-6:
                self.uses_generated = True  # the radial default tangent reads generated coordinates
        if node.inputs.get("Rotation") is not None:
            self.set_input(el, "rotation", node.inputs["Rotation"])
        self.link_frame(el, node, "Normal", "Tangent")
        return (el.get("name"), "bsdf")

    def bsdf_glass(self, node, out, xml_type="glass_bsdf"):
        if xml_type == "glass_bsdf" and SEPARABLE_SHADOWING and node.distribution in ("GGX", "BECKMANN"):
            return self.glass_as_cycles3(node)
        el = self.add(xml_type, node.name, **microfacet_attributes(node.distribution))
        self.set_input(el, "color", node.inputs["Color"])
        self.set_input(el, "roughness", node.inputs["Roughness"])
        self.set_input(el, "IOR", node.inputs["IOR"])
        self.link_frame(el, node, "Normal")
        return (el.get("name"), "bsdf")

    def glass_as_cycles3(self, node):
        """Cycles 3.x's rough Glass BSDF (GGX, Beckmann): a Fresnel-free reflection lobe weighted by the dielectric
        Fresnel of the shading normal, F(N.I), plus a Fresnel-free refraction lobe weighted by 1 - F(N.I)
        (svm_node_closure_bsdf), not Walter's single lobe with F at each microfacet that glass_bsdf is (Cycles 4.x):
        exported from Blender 3.x as mix(fresnel, refraction, glossy) (docs/microfacet.md, differences)."""
        fresnel = self.add("fresnel", node.name + "_fresnel")
        self.set_input(fresnel, "ior", node.inputs["IOR"])
        self.link_frame(fresnel, node, "Normal")
        lobes = []
        for xml_type, suffix in (("refraction_bsdf", "_refraction"), ("glossy_bsdf", "_reflection")):
            el = self.add(xml_type, node.name + suffix, **microfacet_attributes(node.distribution))
            self.set_input(el, "color", node.inputs["Color"])
            self.set_input(el, "roughness", node.inputs["Roughness"])
            if xml_type == "refraction_bsdf":
                self.set_input(el, "IOR", node.inputs["IOR"])
            self.link_frame(el, node, "Normal")
            lobes.append(el.get("name"))
        mix = self.add("mix_closure", node.name)
        self.connect((fresnel.get("name"), "fac"), mix.get("name"), "fac")
        self.connect((lobes[0], "bsdf"), mix.get("name"), "closure1")
        self.connect((lobes[1], "bsdf"), mix.get("name"), "closure2")
        return (mix.get("name"), "closure")

    def bsdf_refraction(self, node, out):
        return self.bsdf_glass(node, out, "refraction_bsdf")

    def emission(self, node, out):
        el = self.add("emission", node.name)
        self.set_input(el, "color", node.inputs["Color"])
        self.set_input(el, "strength", node.inputs["Strength"])
        return (el.get("name"), "emission")

    def mix_shader(self, node, out):
        el = self.add("mix_closure", node.name)
        self.set_input(el, "fac", node.inputs[0])
        for index, attribute in ((1, "closure1"), (2, "closure2")):
            source = self.source_of(node.inputs[index])
            if source is not None:
                self.connect(source, el.get("name"), attribute)
        return (el.get("name"), "closure")

    def add_shader(self, node, out):
        el = self.add("add_closure", node.name)
        for index, attribute in ((0, "closure1"), (1, "closure2")):
            source = self.source_of(node.inputs[index])
            if source is not None:
                self.connect(source, el.get("name"), attribute)
        return (el.get("name"), "closure")

    def texture_coordinates(self, node, default="the mesh's UV map", generated_by_default=False):
        """The texture's Vector input: the UV map, or Generated (object space normalised to the bounding box,
        as Cycles) through a texture_coordinate node; anything else is warned about (default: what is used
        instead). Returns the (xml node, socket) to link into the texture's vector, or None."""
        vector = node.inputs.get("Vector")
        if vector is None:
            return None
        self.mark_read(node, vector)
        src, out, groups = self.upstream(vector)
        if src is None:  # unlinked (a hidden Vector takes no group socket's value: upstream)
            self.uses_generated |= generated_by_default
            return None
        socket = out.name
        if src.bl_idname == "ShaderNodeUVMap" or (src.bl_idname == "ShaderNodeTexCoord" and socket == "UV"):
            if getattr(src, "uv_map", ""):
                self.uv_maps.add(src.uv_map)
            return None
        if src.bl_idname == "ShaderNodeTexCoord" and socket == "Generated":
            self.uses_generated = True
            key = (self.group_path(groups), src.name, "generated")
            if key not in self.exported:
                el = self.add("texture_coordinate", src.name)
                self.exported[key] = (el.get("name"), "generated")
            return self.exported[key]
        self.warn(("vector", node.name), "the Vector input of '%s' (from '%s', %s) is not exported: %s is used"
                  % (node.name, src.name, src.bl_idname, default))
        return None

    def link_vector(self, el, coordinates):
        if coordinates is not None:
            self.connect(coordinates, el.get("name"), "vector")

    def image_texture(self, node, out):
        if node.image is None:
            self.warn(node.name, "image texture '%s' has no image: its consumer keeps its own value" % node.name)
            return None
        coordinates = self.texture_coordinates(node)
        el = self.add("image_texture", node.name, filename=self.exporter.image_path(node.image, self.owner, node),
                      interpolation=IMAGE_INTERPOLATION.get(node.interpolation, "linear"),
                      extension=IMAGE_EXTENSION.get(node.extension, "periodic"),
                      colorspace=node.image.colorspace_settings.name,
                      projection=IMAGE_PROJECTION.get(node.projection, "flat"),
                      projection_blend=node.projection_blend if node.projection == "BOX" else None)
        self.link_vector(el, coordinates)
        return (el.get("name"), "alpha" if out.name == "Alpha" else "color")

    def environment_texture(self, node, out):
        if node.image is None:
            self.warn(node.name, "environment texture '%s' has no image: ignored" % node.name)
            return None
        coordinates = self.world_vector(node)
        el = self.add("environment_texture", node.name, filename=self.exporter.image_path(node.image, self.owner, node),
                      interpolation=IMAGE_INTERPOLATION.get(node.interpolation, "linear"),
                      colorspace=node.image.colorspace_settings.name,
                      projection="equirectangular" if node.projection == "EQUIRECTANGULAR" else "mirror_ball")
        self.link_vector(el, coordinates)
        return (el.get("name"), "alpha" if out.name == "Alpha" else "color")

    def world_vector(self, node):
        """A world texture's Vector input: unlinked, the ray direction; linked (e.g. Texture Coordinate Generated
        -> Mapping to rotate an HDRI), the exported nodes feeding it."""
        vector = node.inputs.get("Vector")
        return self.source_of(vector) if vector is not None else None

    def sky_texture(self, node, out):
        """Sky Texture: Cycles' sky_texture with every setting of the node (nishita, preetham, hosek_wilkie)."""
        coordinates = self.world_vector(node)
        if tuple(node.texture_mapping.rotation) != (0.0, 0.0, 0.0) or \
                tuple(node.texture_mapping.translation) != (0.0, 0.0, 0.0) or \
                tuple(node.texture_mapping.scale) != (1.0, 1.0, 1.0):
            self.warn(node.name, "sky texture '%s': its texture mapping is not exported" % node.name)
        el = self.add("sky_texture", node.name, sky_type=node.sky_type.lower(),
                      sun_direction=tuple(node.sun_direction), turbidity=node.turbidity,
                      ground_albedo=node.ground_albedo, sun_disc=bool(node.sun_disc), sun_size=node.sun_size,
                      sun_intensity=node.sun_intensity, sun_elevation=node.sun_elevation,
                      sun_rotation=node.sun_rotation, altitude=node.altitude, air_density=node.air_density,
                      dust_density=node.dust_density, ozone_density=node.ozone_density)
        self.link_vector(el, coordinates)
        return (el.get("name"), "color")

    def checker_texture(self, node, out):
        coordinates = self.texture_coordinates(node, "generated coordinates", generated_by_default=True)
        el = self.add("checker_texture", node.name)
        self.link_vector(el, coordinates)
        self.set_input(el, "color1", node.inputs["Color1"])
        self.set_input(el, "color2", node.inputs["Color2"])
        self.set_input(el, "scale", node.inputs["Scale"])
        return (el.get("name"), "fac" if out.name == "Fac" else "color")

    def principled(self, node, out):
        """Principled BSDF as Cycles' principled_bsdf (the renderer expands it, bridge/render/principled.cpp):
        base colour, metallic, specular, specular tint, roughness, transmission, IOR, clearcoat and its roughness,
        sheen and sheen tint (3.x), alpha, emission. Subsurface, anisotropy, transmission roughness and 4.x's
        microfiber sheen: warned and dropped; a linked Normal is reported unread (warn_unread_links)."""
        name = node.name
        el = self.add("principled_bsdf", name,
                      distribution=GLOSSY_DISTRIBUTION.get(getattr(node, "distribution", "GGX"), "GGX"))
        for attribute, names in PRINCIPLED_SOCKETS:
            sock = _input(node, *names)
            if sock is not None:
                self.set_input(el, attribute, sock)
        tint = _input(node, "Specular Tint")
        if tint is not None and tint.type == "VALUE":  # 3.x: a factor toward the base colour's hue (4.x: a colour)
            self.set_input(el, "specular_tint", tint)
        sheen, sheen_tint = _input(node, "Sheen"), _input(node, "Sheen Tint")
        # 3.x: Disney's sheen, its tint a factor toward the base colour's hue (4.x: a microfiber lobe, warned below)
        if sheen is not None and sheen_tint is not None and sheen_tint.type == "VALUE":
            self.set_input(el, "sheen", sheen)
            self.set_input(el, "sheen_tint", sheen_tint)
        spec = _input(node, "Specular")
        if spec is not None:
            self.set_input(el, "specular", spec)
        else:  # 4.x: Specular IOR Level; the dielectric f0 of the IOR times 2 * level as 0.08 * specular
            level, ior = _input(node, "Specular IOR Level"), _input(node, "IOR")
            eta = float(_value(ior, 1.5))
            f0 = ((eta - 1.0) / (eta + 1.0)) ** 2 * 2.0 * float(_value(level, 0.5))
            el.set("specular", fmt(min(max(f0, 0.0), 1.0) / 0.08))
        self.warn_unexported_values(node, (("Subsurface", "Subsurface Weight"), 0.0, "subsurface"),
                                    (("Sheen Weight",), 0.0, "sheen (4.x's microfiber sheen)"),
                                    (("Anisotropic",), 0.0, "anisotropy (rendered isotropic)"),
                                    (("Transmission Roughness",), 0.0, "transmission roughness"))
        return (el.get("name"), "bsdf")

    def glimmer_node(self, node, out):
        closure = node.closure_schema
        settings = self.exporter.settings
        enabled = {"glint": settings.use_glint if settings else True,
                   "frosted_glass": settings.use_frosted_glass if settings else True}.get(node.closure_name, True)
        if enabled and closure.get("source") != "dso":
            self.warn(("planned", node.closure_name), "the plugin does not have the '%s' closure yet: node '%s' is "
                      "exported as its microfacet fallback" % (node.closure_name, node.name))
            enabled = False
        if not enabled:  # the microfacet fallback instead of the glimmer closure
            fallback = glimmer_nodes.FALLBACKS[node.closure_name]
            xml_type = "glossy_bsdf" if fallback["node"] == "ShaderNodeBsdfGlossy" else "glass_bsdf"
            el = self.add(xml_type, node.name, distribution=GLOSSY_DISTRIBUTION[fallback["distribution"]])
            attributes = {"color": "color", "roughness": "roughness", "ior": "IOR"}
            for param_name in fallback["links"]:
                self.set_input(el, attributes[param_name], node.inputs.get(schema_mod.socket_name(param_name)))
            return (el.get("name"), "bsdf")
        el = self.add(schema_mod.NODE_CLOSURES[node.closure_name]["xml"], node.name)
        values = node.param_values()
        if node.closure_name == "glint" and values.get("placement", "uv") == "uv":
            self.uv_glints.add(node.name)
        for param in closure["params"]:
            if schema_mod.is_socket_param(param):
                sock = node.inputs.get(schema_mod.socket_name(param["name"]))
                if sock is None:
                    continue
                value_sock = sock
                if not param.get("varying", True) and param["name"] != "color":
                    # The host takes one value: a group socket's value passes, a texture is warned and the
                    # socket's own value is used.
                    source, value_sock = None, self.constant_socket(node, sock)
                else:
                    source = self.source_of(sock)
                if source is not None:
                    self.connect(source, el.get("name"), param["name"])
                else:
                    el.set(param["name"], fmt(self.schema_value(node, value_sock, param)))
            else:
                el.set(param["name"], fmt(values[param["name"]]) if param["type"] == "bool"
                       else str(values[param["name"]]))
        return (el.get("name"), "bsdf")

    def constant_socket(self, node, sock):
        """The socket whose value a parameter the closure takes as one constant gets (not varying in the schema;
        the colour's link is the weight instead): `sock` itself, or the group socket a link through the artist's
        node groups ends at. A link from a node (a texture) is warned with that node's name; `sock`'s value."""
        self.mark_read(node, sock)
        source, value_sock, _ = self.upstream(sock)
        if source is None:
            return value_sock or sock
        self.warn((node.name, "constant", sock.identifier),
                  "node '%s': %s cannot be textured (the closure takes one value per material): the link from '%s' "
                  "is ignored and the socket's own value %s is used" % (node.name, sock.name, source.name,
                                                                        fmt(_value(sock))))
        return sock

    def schema_value(self, node, sock, param):
        """An unlinked socket's value clamped to the closure's range: Blender's group sockets limit only dragging
        (typing 0 into Density works), and the renderer refuses the whole scene for a value outside the range."""
        value = _scalar(sock) if param["type"] in ("float", "int") else _value(sock)
        if param["type"] == "color" and not isinstance(value, tuple):  # a float socket read as a grey
            value = (value, value, value)
        lo, hi = param.get("min"), param.get("max")
        if lo is None and hi is None:
            return value

        def clamp(v):
            v = max(v, lo) if lo is not None else v
            v = min(v, hi) if hi is not None else v
            return int(v) if param["type"] == "int" else v

        clamped = tuple(clamp(v) for v in value) if isinstance(value, tuple) else clamp(value)
        moved = np.abs(np.subtract(clamped, value, dtype=np.float64))
        # A limit stored in the socket's float32 (thickness 1e-6 -> 9.99999997e-07) is clamped without a warning.
        if np.any(moved > 1e-6 * np.abs(np.asarray(clamped, dtype=np.float64))):
            self.warn((node.name, "range", param["name"]),
                      "node '%s': %s %s is outside the closure's range [%s, %s]: %s is used"
                      % (node.name, sock.name, fmt(value), fmt(lo), fmt(hi), fmt(clamped)))
        return clamped

    def value_node(self, node, out):
        """A texture/utility node the renderer evaluates per shading point (bridge/render/nodes/node_table.cpp):
        its settings (VALUE_NODES), every enabled input as the Cycles socket of the same name (linked or its
        value) and the output of the same name. A texture's unlinked Vector reads generated coordinates."""
        xml_type, settings = VALUE_NODES[node.bl_idname]
        if getattr(node, "uv_map", "") and (node.bl_idname != "ShaderNodeNormalMap" or node.space == "TANGENT") and \
                (node.bl_idname != "ShaderNodeTangent" or node.direction_type == "UV_MAP"):
            self.uv_maps.add(node.uv_map)
        if node.bl_idname == "ShaderNodeMapRange" and node.data_type != "FLOAT":
            return self.unsupported(node, out)
        attributes = {}
        if node.bl_idname in ("ShaderNodeValue", "ShaderNodeRGB"):  # the value is the output's own
            attributes["value"] = _value(node.outputs[0])
        for attribute, (prop, names) in settings.items():
            value = getattr(node, prop)
            attributes[attribute] = value if isinstance(value, bool) else (names or {}).get(value, str(value).lower())
        if node.bl_idname == "ShaderNodeValToRGB":  # Cycles' table form: 256 entries, as Blender bakes it
            ramp = node.color_ramp
            entries = [ramp.evaluate(i / 255.0) for i in range(256)]
            attributes["ramp"] = [c for e in entries for c in tuple(e)[:3]]
            attributes["ramp_alpha"] = [tuple(e)[3] for e in entries]
            attributes["interpolate"] = ramp.interpolation != "CONSTANT"
        el = self.add(xml_type, node.name, **attributes)
        sockets = VALUE_NODE_INPUTS.get(node.bl_idname, {})
        for sock in node.inputs:
            if not sock.enabled:
                continue
            name = sockets.get(sock.identifier, sock.name.lower().replace(" ", "_"))
            if getattr(sock, "hide_value", False) and self.upstream(sock)[0] is None:
                # An unlinked coordinate/normal input reads the shading point (not its hidden value).
                self.mark_read(node, sock)
                if name == "vector" and node.bl_idname.startswith("ShaderNodeTex"):
                    self.uses_generated = True
                continue
            self.set_input(el, name, sock)
        if node.bl_idname == "ShaderNodeTexCoord" and out.name == "Generated":
            self.uses_generated = True
        return (el.get("name"), out.name.lower().replace(" ", "_"))

    def background(self, node, out):
        el = self.add("background", node.name)
        self.set_input(el, "color", node.inputs["Color"])
        self.set_input(el, "strength", node.inputs["Strength"])
        return (el.get("name"), "background")

    def group_node(self, node, out):
        """A group node without a node tree (its data-block missing): upstream() flattens every other group."""
        self.warn(node.name, "node group '%s' has no node tree: %s"
                  % (node.name, "rendered as a diffuse BSDF" if out.type == "SHADER" else
                     "the input it feeds keeps its own value"))
        return self.unsupported_quiet(node, out)

    def unsupported_quiet(self, node, out):
        for sock in node.inputs:  # already warned
            self.mark_read(node, sock)
        if out.type == "SHADER":
            el = self.add("diffuse_bsdf", node.name + "_fallback", color=(0.8, 0.8, 0.8))
            return (el.get("name"), "bsdf")
        return None


# Blender nodes exported as the renderer's per-shading-point nodes: bl_idname -> (xml type, {xml setting:
# (node property, Blender value -> Cycles name, default: lower case)}).
_MATH_NAMES = {"FRACT": "fraction", "INVERSE_SQRT": "inversesqrt", "SMOOTH_MIN": "smoothmin",
               "SMOOTH_MAX": "smoothmax", "PINGPONG": "pingpong"}
_VECTOR_MATH_NAMES = {"CROSS_PRODUCT": "cross_product", "DOT_PRODUCT": "dot_product", "FRACTION": "fraction",
                      "MULTIPLY_ADD": "multiply_add"}
VALUE_NODES = {
    "ShaderNodeTexNoise": ("noise_texture", {"dimensions": ("noise_dimensions", None)}),
    "ShaderNodeTexVoronoi": ("voronoi_texture", {"dimensions": ("voronoi_dimensions", None),
                                                 "metric": ("distance", None), "feature": ("feature", None)}),
    "ShaderNodeTexMusgrave": ("musgrave_texture", {"musgrave_type": ("musgrave_type", {"FBM": "fbm"}),
                                                   "dimensions": ("musgrave_dimensions", None)}),
    "ShaderNodeTexWave": ("wave_texture", {"wave_type": ("wave_type", None),
                                           "bands_direction": ("bands_direction", None),
                                           "rings_direction": ("rings_direction", None),
                                           "profile": ("wave_profile", {"SIN": "sine", "SAW": "saw", "TRI": "tri"})}),
    "ShaderNodeValToRGB": ("rgb_ramp", {}),
    "ShaderNodeMath": ("math", {"math_type": ("operation", _MATH_NAMES), "use_clamp": ("use_clamp", None)}),
    "ShaderNodeVectorMath": ("vector_math", {"math_type": ("operation", _VECTOR_MATH_NAMES)}),
    "ShaderNodeMixRGB": ("mix", {"mix_type": ("blend_type", {"MIX": "mix"}), "use_clamp": ("use_clamp", None)}),
    "ShaderNodeHueSaturation": ("hsv", {}),
    "ShaderNodeMapping": ("mapping", {"mapping_type": ("vector_type", None)}),
    "ShaderNodeTexCoord": ("texture_coordinate", {}),
    "ShaderNodeFresnel": ("fresnel", {}),
    "ShaderNodeLayerWeight": ("layer_weight", {}),
    "ShaderNodeLightPath": ("light_path", {}),
    "ShaderNodeTexGradient": ("gradient_texture", {"gradient_type": ("gradient_type", None)}),
    "ShaderNodeTexWhiteNoise": ("white_noise_texture", {"dimensions": ("noise_dimensions", None)}),
    "ShaderNodeValue": ("value", {}),
    "ShaderNodeRGB": ("color", {}),
    "ShaderNodeInvert": ("invert", {}),
    "ShaderNodeGamma": ("gamma", {}),
    "ShaderNodeBrightContrast": ("brightness_contrast", {}),
    "ShaderNodeClamp": ("clamp", {"clamp_type": ("clamp_type", None)}),
    "ShaderNodeMapRange": ("map_range", {"range_type": ("interpolation_type", None), "clamp": ("clamp", None)}),
    "ShaderNodeSeparateXYZ": ("separate_xyz", {}),
    "ShaderNodeCombineXYZ": ("combine_xyz", {}),
    "ShaderNodeSeparateRGB": ("separate_rgb", {}),
    "ShaderNodeCombineRGB": ("combine_rgb", {}),
    "ShaderNodeRGBToBW": ("rgb_to_bw", {}),
    # Shading normals and tangents (bridge/render/nodes/normal_nodes.cpp); the mesh's one UV map is used.
    "ShaderNodeBump": ("bump", {"invert": ("invert", None)}),
    "ShaderNodeDisplacement": ("displacement", {"space": ("space", None)}),
    "ShaderNodeNewGeometry": ("geometry", {}),
    "ShaderNodeNormalMap": ("normal_map", {"space": ("space", None)}),
    "ShaderNodeTangent": ("tangent", {"direction_type": ("direction_type", None), "axis": ("axis", None)}),
}
# Inputs whose Cycles name is not the Blender name in lower case (sockets of the same name told apart).
VALUE_NODE_INPUTS = {
    "ShaderNodeMath": {"Value": "value1", "Value_001": "value2", "Value_002": "value3"},
    "ShaderNodeVectorMath": {"Vector": "vector1", "Vector_001": "vector2", "Vector_002": "vector3"},
    "ShaderNodeMixRGB": {"Color1": "color1", "Color2": "color2"},
    "ShaderNodeFresnel": {"IOR": "ior"},
    "ShaderNodeSeparateRGB": {"Image": "color"},
}

TRANSLATORS = {
    "ShaderNodeBsdfDiffuse": ShaderGraph.bsdf_diffuse,
    "ShaderNodeBsdfGlossy": ShaderGraph.bsdf_glossy,
    "ShaderNodeBsdfAnisotropic": ShaderGraph.bsdf_glossy,
    "ShaderNodeBsdfGlass": ShaderGraph.bsdf_glass,
    "ShaderNodeBsdfRefraction": ShaderGraph.bsdf_refraction,
    "ShaderNodeEmission": ShaderGraph.emission,
    "ShaderNodeMixShader": ShaderGraph.mix_shader,
    "ShaderNodeAddShader": ShaderGraph.add_shader,
    "ShaderNodeTexImage": ShaderGraph.image_texture,
    "ShaderNodeTexEnvironment": ShaderGraph.environment_texture,
    "ShaderNodeTexSky": ShaderGraph.sky_texture,
    "ShaderNodeTexChecker": ShaderGraph.checker_texture,
    "ShaderNodeBsdfPrincipled": ShaderGraph.principled,
    "ShaderNodeBackground": ShaderGraph.background,
    "ShaderNodeGroup": ShaderGraph.group_node,
}
TRANSLATORS.update({bl_idname: ShaderGraph.value_node for bl_idname in VALUE_NODES})


def _output_node(ntree, bl_idname):
    candidates = [n for n in ntree.nodes if n.bl_idname == bl_idname]
    for n in candidates:
        if n.is_active_output and getattr(n, "target", "ALL") in ("ALL", "CYCLES"):
            return n
    for n in candidates:
        if getattr(n, "target", "ALL") in ("ALL", "CYCLES"):
            return n
    return candidates[0] if candidates else None


class Exporter:
    """Writes <out_dir>/scene.xml and <out_dir>/meshes/*.ply for one frame of a depsgraph."""

    def __init__(self, depsgraph, out_dir, settings=None, width=None, height=None, report=None, view=None):
        """view: {"matrix": camera-to-world 4x4, "fov": radians across the smaller side} of a viewport, used
        instead of the scene camera."""
        self.depsgraph = depsgraph
        self.view = view
        self.scene = depsgraph.scene
        self.out_dir = out_dir
        self.settings = settings if settings is not None else getattr(self.scene, "glimmer", None)
        render = self.scene.render
        scale = render.resolution_percentage / 100.0
        self.width = width or max(1, int(render.resolution_x * scale))
        self.height = height or max(1, int(render.resolution_y * scale))
        self.report = report
        self.warnings = []
        self.shader_names = UniqueNames()
        self.mesh_names = UniqueNames()
        self.material_shaders = {}
        self.images = {}
        self.objects_checked = set()
        self.object_space_shaders = set()  # shaders reading generated coordinates
        self.shader_uv_maps = {}  # shader name -> (material name, UV maps its nodes name, uv-placed Glint nodes)
        self.stats = {"objects": 0, "triangles": 0, "vertices": 0, "lights": 0, "materials": 0}

    def warn(self, message):
        if message in self.warnings:
            return
        self.warnings.append(message)
        if self.report is not None:
            self.report({"WARNING"}, "Glimmer export: " + message)

    # -- entry ---------------------------------------------------------------
    def export(self, filename="scene.xml"):
        os.makedirs(os.path.join(self.out_dir, "meshes"), exist_ok=True)
        root = ET.Element("cycles")
        root.append(ET.Comment(" exported by the Glimmer Blender addon from %s "
                               % (bpy.data.filepath or "an unsaved .blend")))
        self.write_camera(root)
        self.write_film_integrator(root)
        self.write_world(root)
        default = ET.SubElement(root, "shader", name=self.shader_names("glimmer_default"))
        ET.SubElement(default, "diffuse_bsdf", name="diffuse", color="0.8 0.8 0.8")
        ET.SubElement(default, "connect", attrib={"from": "diffuse bsdf", "to": "output surface"})
        self.default_shader = default.get("name")
        self.objects_parent = root
        self.write_objects(root)
        if self.view is None:
            self.warn_view_layer_passes()
        path = os.path.join(self.out_dir, filename)
        if hasattr(ET, "indent"):
            ET.indent(root, space="  ")
        ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=False)
        return path

    def warn_view_layer_passes(self):
        """Render passes switched on in the view layer that Glimmer does not write (it writes Combined, Albedo,
        Normal and Depth, engine.AOV_PASSES): one warning listing them, as they are missing from the result."""
        view_layer = self.depsgraph.view_layer
        missing = []
        for owner in (view_layer, getattr(view_layer, "cycles", None)):
            if owner is None:
                continue
            for prop in owner.bl_rna.properties:
                name = prop.identifier
                if (name.startswith("use_pass_") or name in ("denoising_store_passes", "pass_debug_sample_count")) \
                        and name not in HOST_PASSES and getattr(owner, name, False) is True:
                    missing.append(prop.name)
        missing += ["AOV '%s'" % aov.name for aov in getattr(view_layer, "aovs", ())]
        missing += ["light group '%s'" % group.name for group in getattr(view_layer, "lightgroups", ())]
        if missing:
            self.warn("view layer '%s': Glimmer renders the Combined, Albedo, Normal and Depth passes only; %s %s "
                      "missing from the result" % (view_layer.name, ", ".join(missing),
                                                   "is" if len(missing) == 1 else "are"))

    # -- camera / film / integrator -------------------------------------------
    def write_camera(self, root):
        ET.SubElement(root, "camera", width=str(self.width), height=str(self.height))
        cam_obj = self.scene.camera
        if self.view is not None:
            matrix, cam, cam_obj = np.array(self.view["matrix"], dtype=np.float64), None, None
        elif cam_obj is None:
            self.warn("the scene has no camera: using a camera at the origin looking down -Z")
            matrix = np.identity(4)
            cam = None
        else:
            cam_eval = cam_obj.evaluated_get(self.depsgraph)
            matrix = np.array(cam_eval.matrix_world)
            cam = cam_eval.data
        loc = matrix[:3, 3]
        linear = matrix[:3, :3]
        scale = np.linalg.norm(linear, axis=0)
        rot = linear / np.where(scale > 0, scale, 1.0)
        if np.linalg.det(rot) < 0:
            rot[:, 2] *= -1.0
            scale[2] *= -1.0
        angle, axis = _axis_angle(rot)
        tr = ET.SubElement(root, "transform", translate=fmt(loc), rotate=fmt([math.degrees(angle), *axis]),
                           scale=fmt([scale[0], scale[1], -scale[2]]))
        fov = self.view["fov"] if self.view is not None else self.camera_fov(cam)
        attributes = {"type": "perspective", "fov": fmt(fov), "nearclip": "0.1",
                      "farclip": "100"}
        if cam is not None:
            attributes["nearclip"] = fmt(cam.clip_start)
            attributes["farclip"] = fmt(cam.clip_end)
            if cam.type != "PERSP":
                self.warn("camera '%s': only perspective cameras are exported (type %s rendered as perspective)"
                          % (cam_obj.name, cam.type))
            if abs(cam.shift_x) > 1e-6 or abs(cam.shift_y) > 1e-6:
                self.warn("camera '%s': lens shift is not exported" % cam_obj.name)
            if cam.dof.use_dof:
                focus = cam.dof.focus_distance
                if cam.dof.focus_object is not None:
                    # Blender -> Cycles sync (blender_camera_focal_distance): the distance along the view axis.
                    view_dir = linear[:, 2] / max(float(np.linalg.norm(linear[:, 2])), 1e-30)
                    target = np.array(cam.dof.focus_object.matrix_world.translation)
                    focus = abs(float(np.dot(view_dir, loc - target)))
                attributes["aperturesize"] = fmt(cam.lens * 1e-3 / (2.0 * cam.dof.aperture_fstop))
                if cam.dof.aperture_blades >= 3:
                    self.warn("camera '%s': a %d-blade aperture is not supported: the bokeh is round"
                              % (cam_obj.name, cam.dof.aperture_blades))
                if abs(cam.dof.aperture_ratio - 1.0) > 1e-6:
                    self.warn("camera '%s': aperture ratio %s (anamorphic bokeh) is not supported: 1 is used"
                              % (cam_obj.name, fmt(cam.dof.aperture_ratio)))
                attributes["focaldistance"] = fmt(focus)
        ET.SubElement(tr, "camera", attrib=attributes)

    def camera_fov(self, cam):
        """Cycles' fov: the full angle across the smaller image dimension (radians)."""
        w, h = float(self.width), float(self.height)
        if cam is None:
            return math.radians(39.6)
        if cam.sensor_fit == "HORIZONTAL" or (cam.sensor_fit == "AUTO" and w >= h):
            tan_x = 0.5 * cam.sensor_width / cam.lens
            tan_y = tan_x * h / w
        elif cam.sensor_fit == "AUTO":
            tan_y = 0.5 * cam.sensor_width / cam.lens
            tan_x = tan_y * w / h
        else:
            tan_y = 0.5 * cam.sensor_height / cam.lens
            tan_x = tan_y * w / h
        return 2.0 * math.atan(min(tan_x, tan_y))

    def write_film_integrator(self, root):
        """<film> and <integrator> with every generated render setting (schema_mod.setting_rows), plus the seed."""
        s = self.settings
        if s is None:
            return
        for element in schema_mod.SETTINGS_ELEMENTS:
            attributes = {row["name"]: fmt(getattr(s, prop)) if row["type"] != "enum" else getattr(s, prop)
                          for _, row, prop in schema_mod.setting_rows(element)}
            if element == "integrator":
                attributes["seed"] = str(s.seed + (self.scene.frame_current if s.use_animated_seed else 0))
            ET.SubElement(root, element, attrib=attributes)

    # -- world -----------------------------------------------------------------
    def write_world(self, root):
        world = self.scene.world
        bg = ET.SubElement(root, "background")
        render = self.scene.render
        if render.film_transparent:  # Cycles XML: the Background node's `transparent` socket
            bg.set("transparent", "true")
            if getattr(self.scene, "cycles", None) is not None and getattr(self.scene.cycles, "film_transparent_glass",
                                                                            False):
                self.warn("Film > Transparent Glass is not supported: glass is opaque (alpha 1)")
        if world is None:
            ET.SubElement(bg, "background", name="bg", color="0 0 0", strength="0")
            ET.SubElement(bg, "connect", attrib={"from": "bg background", "to": "output surface"})
            return
        if not world.use_nodes or world.node_tree is None:
            ET.SubElement(bg, "background", name="bg", color=fmt(tuple(world.color)), strength="1")
            ET.SubElement(bg, "connect", attrib={"from": "bg background", "to": "output surface"})
            return
        graph = ShaderGraph(self, bg, "world '%s'" % world.name)
        out = _output_node(world.node_tree, "ShaderNodeOutputWorld")
        source = graph.source_of(out.inputs["Surface"]) if out is not None else None
        if source is None:
            ET.SubElement(bg, "background", name="bg", color="0 0 0", strength="0")
            source = ("bg", "background")
        graph.connect(source, "output", "surface")
        if out is not None and out.inputs["Volume"].is_linked:
            self.warn("world '%s': volumes are not exported" % world.name)

    # -- materials ---------------------------------------------------------------
    def shader_for(self, material):
        if material is None:
            return self.default_shader
        key = material.name_full if hasattr(material, "name_full") else material.name
        if key in self.material_shaders:
            return self.material_shaders[key]
        name = self.shader_names(material.name)
        el = ET.Element("shader", name=name)
        owner = "material '%s'" % material.name
        if not material.use_nodes or material.node_tree is None:
            ET.SubElement(el, "diffuse_bsdf", name="diffuse", color=fmt(tuple(material.diffuse_color)[:3]))
            ET.SubElement(el, "connect", attrib={"from": "diffuse bsdf", "to": "output surface"})
        else:
            graph = ShaderGraph(self, el, owner)
            out = _output_node(material.node_tree, "ShaderNodeOutputMaterial")
            source = graph.source_of(out.inputs["Surface"]) if out is not None else None
            if source is None:
                self.warn("%s has no surface shader: rendered black like Cycles" % owner)
            else:
                graph.connect(source, "output", "surface")
            if out is not None and out.inputs["Volume"].is_linked:
                self.warn("%s: volumes are not exported" % owner)
            displacement = graph.source_of(out.inputs["Displacement"]) if out is not None else None
            if displacement is not None:  # rendered as bump, Cycles' "Bump Only" (true displacement: warned)
                graph.connect(displacement, "output", "displacement")
                method = getattr(getattr(material, "cycles", None), "displacement_method", "BUMP")
                el.set("displacement_method", {"DISPLACEMENT": "true", "BOTH": "both"}.get(method, "bump"))
            if graph.uses_generated:
                self.object_space_shaders.add(name)
            if graph.uv_maps or graph.uv_glints:
                self.shader_uv_maps[name] = (material.name, graph.uv_maps, graph.uv_glints)
        # Shaders must come before the objects that use them.
        index = list(self.objects_parent).index(self.objects_anchor)
        self.objects_parent.insert(index, el)
        self.material_shaders[key] = name
        self.stats["materials"] += 1
        return name

    def image_path(self, image, owner, node):
        """The file the renderer reads for image (packed/generated images saved to textures/); a missing
        image becomes a magenta texture, as in Cycles, with one warning naming its first user."""
        if image.name in self.images:
            return self.images[image.name]
        path = bpy.path.abspath(image.filepath, library=image.library) if image.filepath else ""
        if image.packed_file is not None or image.source == "GENERATED":
            os.makedirs(os.path.join(self.out_dir, "textures"), exist_ok=True)
            saved = os.path.join(self.out_dir, "textures", safe_name(image.name) + ".exr")
            try:
                image.save_render(saved, scene=self.scene)
                path = saved
            except RuntimeError as e:
                path = self.missing_image(image, owner, node, "cannot be saved (%s)" % e)
        elif os.path.isfile(path):
            path = os.path.abspath(path)
        else:
            path = self.missing_image(image, owner, node, "file '%s' not found" % (path or image.filepath))
        self.images[image.name] = path
        return path

    def missing_image(self, image, owner, node, problem):
        self.warn("%s: image '%s' of node '%s' %s: rendered magenta, as Cycles does" % (owner, image.name, node.name,
                                                                                      problem))
        path = os.path.join(self.out_dir, "textures", "missing_image_magenta.ppm")
        if not os.path.isfile(path):
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "wb") as f:
                f.write(b"P6\n1 1\n255\n" + bytes(MISSING_TEXTURE_COLOR))
        return path

    # -- objects and lights ----------------------------------------------------------
    def write_objects(self, root):
        self.objects_anchor = ET.SubElement(root, "objects_begin")  # placeholder, removed below
        with_mesh_instance = {inst.parent.name for inst in self.depsgraph.object_instances
                              if inst.is_instance and inst.parent is not None and inst.object.type == "MESH"
                              and inst.parent.type in CURVE_LIKE_TYPES and inst.object.name == inst.parent.name}
        skipped = {}
        for inst in self.depsgraph.object_instances:
            obj = inst.object
            if obj.type == "LIGHT":
                self.write_light(root, obj, np.array(inst.matrix_world))
            elif obj.type in MESH_TYPES:
                if obj.type in CURVE_LIKE_TYPES and not inst.is_instance and obj.name in with_mesh_instance:
                    continue  # its surface comes as the mesh instance
                if not inst.is_instance or inst.parent is None or inst.parent.name != obj.name:
                    self.warn_object_features(obj)
                self.write_mesh_object(root, inst, obj)
            elif obj.type in SKIPPED_TYPES:
                skipped.setdefault(SKIPPED_TYPES[obj.type], []).append(obj.name)
        root.remove(self.objects_anchor)
        for kind, names in sorted(skipped.items()):
            self.warn("%s objects are not supported: skipped %s" % (kind, ", ".join("'%s'" % n for n in names)))
        if self.scene.render.use_motion_blur:
            self.warn("motion blur is not supported: objects are rendered at the current frame")

    def warn_object_features(self, obj):
        """Object settings the scene format cannot carry: one warning each, with the object's name."""
        original = obj.original if hasattr(obj, "original") else obj
        if original.name in self.objects_checked:
            return
        self.objects_checked.add(original.name)
        hidden = [ray for ray in ("camera", "diffuse", "glossy", "transmission", "volume_scatter", "shadow")
                  if not getattr(obj, "visible_" + ray, True)]
        if hidden:
            self.warn("object '%s': ray visibility (%s off) is not supported: the object is visible to every ray"
                      % (obj.name, ", ".join(hidden)))
        if getattr(obj, "is_shadow_catcher", False):
            self.warn("object '%s': shadow catcher is not supported: rendered as an ordinary object" % obj.name)
        if getattr(obj, "is_holdout", False):
            self.warn("object '%s': holdout is not supported: rendered as an ordinary object" % obj.name)
        elif self.view_layer_flag(original, "holdout_get"):
            self.warn("object '%s': holdout (its collection's Holdout in view layer '%s') is not supported: rendered "
                      "as an ordinary object" % (obj.name, self.depsgraph.view_layer.name))
        if self.view_layer_flag(original, "indirect_only_get"):
            self.warn("object '%s': Indirect Only (its collection's, in view layer '%s') is not supported: the object "
                      "is also seen by camera rays" % (obj.name, self.depsgraph.view_layer.name))
        for psys in getattr(original, "particle_systems", ()):
            if psys.settings.type == "HAIR" and psys.settings.render_type == "PATH":
                self.warn("object '%s': hair particle system '%s' is not supported: skipped" % (obj.name, psys.name))

    def warn_uv_maps(self, obj, mesh, materials):
        """A node naming a UV map other than the exported one (the render UV map): reported with the names."""
        layer = mesh_export.render_uv_layer(mesh)
        exported = layer.name if layer is not None else None
        for material in materials:
            if material is None:
                continue
            shader = self.shader_for(material)
            material_name, maps, glints = self.shader_uv_maps.get(shader, (None, (), ()))
            for glint in sorted(glints) if exported is None else ():
                self.warn("object '%s' has no UV map: Glint node '%s' of material '%s' (Placement uv) gets each "
                          "triangle's barycentric coordinates as uv (the same flakes on every triangle, whatever its "
                          "size); add a UV map or set Placement to object" % (obj.name, glint, material_name))
            for uv_map in sorted(maps):
                if uv_map != exported:
                    self.warn("object '%s': material '%s' reads UV map '%s' (UV Map, Normal Map or Tangent node); "
                              "Glimmer exports one UV map per mesh, the render one (%s), which is used instead"
                              % (obj.name, material_name, uv_map, "'%s'" % exported if exported else "none"))

    def material_override(self):
        """The view layer's Material Override (evaluated), or None."""
        material = getattr(self.depsgraph.view_layer, "material_override", None)
        if material is None:
            return None
        try:
            return material.evaluated_get(self.depsgraph)
        except (AttributeError, RuntimeError):
            return material

    def view_layer_flag(self, original, getter):
        """Object.holdout_get / indirect_only_get in the depsgraph's view layer (collection settings included);
        False when Blender cannot answer (an object without a base in the view layer)."""
        try:
            return bool(getattr(original, getter)(view_layer=self.depsgraph.view_layer))
        except (AttributeError, RuntimeError, TypeError):
            return False

    def write_mesh_object(self, root, inst, obj):
        try:
            mesh = obj.to_mesh()
        except RuntimeError:
            return
        if mesh is None:
            return
        try:
            arrays = mesh_export.mesh_arrays(mesh, inst.matrix_world)
            if len(arrays["triangles"]) == 0:
                return
            slots = [slot.material for slot in obj.material_slots] if obj.material_slots else []
            override = self.material_override()
            if override is not None:  # View Layer > Material Override: every surface (Cycles' find_used_shaders)
                slots = [override]
            own_geometry = not inst.is_instance or (inst.parent is not None and inst.parent.name == obj.name)
            base = self.mesh_names(obj.name if own_geometry else obj.name + "_instance")
            used = np.unique(arrays["material"]) if len(slots) > 1 else np.array([0])
            self.warn_uv_maps(obj, mesh, [slots[min(int(i), len(slots) - 1)] if slots else None for i in used])
            shaders = [self.shader_for(slots[min(int(index), len(slots) - 1)] if slots else None) for index in used]
            parent = root
            if self.object_space_shaders.intersection(shaders):
                # Generated coordinates come from the mesh's own (object-space) bounding box, as in Cycles:
                # the mesh is written in object space inside its object's transform.
                arrays = mesh_export.mesh_arrays(mesh, np.identity(4))
                matrix = np.array(inst.matrix_world, dtype=np.float64)
                parent = ET.SubElement(root, "transform", matrix=fmt(matrix.flatten(order="F")))
            for index, shader in zip(used, shaders):
                part = arrays if len(used) == 1 else mesh_export.subset(arrays, arrays["material"] == index)
                filename = "meshes/%s.ply" % (base if len(used) == 1 else "%s_%d" % (base, index))
                mesh_export.write_ply(os.path.join(self.out_dir, filename), part)
                state = ET.SubElement(parent, "state", shader=shader)
                if part["smooth"]:
                    state.set("interpolation", "smooth")
                ET.SubElement(state, "mesh", src=filename)
                self.stats["triangles"] += len(part["triangles"])
                self.stats["vertices"] += len(part["P"])
            self.stats["objects"] += 1
        finally:
            obj.to_mesh_clear()

    def write_light(self, root, obj, matrix):
        light = obj.data
        co = matrix[:3, 3]
        axes = matrix[:3, :3]
        lengths = np.linalg.norm(axes, axis=0)
        unit = axes / np.where(lengths > 0, lengths, 1.0)
        direction = -unit[:, 2]
        color = np.array(light.color)
        attributes = {"co": fmt(co), "dir": fmt(direction)}
        if light.type == "SUN":
            attributes.update(light_type="sun", strength=fmt(color * light.energy), angle=fmt(light.angle))
        elif light.type in ("POINT", "SPOT"):
            attributes.update(light_type=light.type.lower(), strength=fmt(color * light.energy))
            attributes[LIGHT_RADIUS] = fmt(light.shadow_soft_size)
            if light.type == "SPOT":
                attributes.update(spot_angle=fmt(light.spot_size), spot_smooth=fmt(light.spot_blend))
        elif light.type == "AREA":
            size_u = light.size
            size_v = light.size_y if light.shape in ("RECTANGLE", "ELLIPSE") else light.size
            attributes.update(light_type="area", strength=fmt(color * light.energy),
                              axisu=fmt(unit[:, 0]), axisv=fmt(unit[:, 1]),
                              sizeu=fmt(size_u * lengths[0]), sizev=fmt(size_v * lengths[1]),
                              round=fmt(light.shape in ("DISK", "ELLIPSE")))
            if hasattr(light, "spread") and light.spread < math.pi - 1e-6:
                attributes["spread"] = fmt(light.spread)
        else:
            self.warn("light '%s': type %s is not supported: skipped" % (obj.name, light.type))
            return
        # Blender lights are invisible to camera rays unless Object > Visibility > Camera is on (the default
        # is off); Cycles XML's use_camera defaults to true, so it is always written.
        attributes["use_camera"] = fmt(bool(getattr(obj, "visible_camera", False)))
        for factor in ("diffuse_factor", "specular_factor", "volume_factor"):
            if abs(getattr(light, factor, 1.0) - 1.0) > 1e-6:
                self.warn("light '%s': %s %s is not supported: 1 is used" % (obj.name, factor.replace("_", " "),
                                                                          fmt(getattr(light, factor))))
        cycles_light = getattr(light, "cycles", None)
        if cycles_light is not None and not getattr(cycles_light, "cast_shadow", True):
            self.warn("light '%s': Cast Shadow off is not supported: the light casts shadows" % obj.name)
        if light.use_nodes:
            self.warn("light '%s': light node trees are not exported (colour x power is used)" % obj.name)
        ET.SubElement(root, "light", attrib=attributes)
        self.stats["lights"] += 1


def _axis_angle(rotation):
    """Rotation matrix -> (angle radians, unit axis)."""
    cos_angle = max(-1.0, min(1.0, (np.trace(rotation) - 1.0) * 0.5))
    angle = math.acos(cos_angle)
    if angle < 1e-9:
        return 0.0, (0.0, 0.0, 1.0)
    if math.pi - angle < 1e-6:
        # 180 degrees: the axis is the column of (R + I) / 2 with the largest norm.
        m = (rotation + np.identity(3)) * 0.5
        i = int(np.argmax(np.diag(m)))
        axis = m[:, i] / math.sqrt(max(m[i, i], 1e-30))
    else:
        axis = np.array([rotation[2, 1] - rotation[1, 2], rotation[0, 2] - rotation[2, 0],
                         rotation[1, 0] - rotation[0, 1]]) / (2.0 * math.sin(angle))
    axis = axis / np.linalg.norm(axis)
    return angle, tuple(float(a) for a in axis)


def export_scene(depsgraph, out_dir, report=None, width=None, height=None, view=None):
    """Export depsgraph's scene to out_dir/scene.xml (seen from view, see Exporter); returns (path, exporter)."""
    exporter = Exporter(depsgraph, out_dir, width=width, height=height, report=report, view=view)
    return exporter.export(), exporter


def remove_export(out_dir):
    shutil.rmtree(out_dir, ignore_errors=True)
