"""Blender mesh -> binary little-endian PLY, vectorised with numpy.

Geometry is baked to world space (the object's matrix is applied to P and N),
so the XML needs no per-object transform. Every array comes from foreach_get
on loop_triangles / loops / vertices; there is no per-vertex Python loop.

Vertex layout: when the mesh needs per-corner data (UVs, or flat/split
normals next to smooth ones) the PLY has one vertex per loop (corner);
otherwise one per mesh vertex.
"""
import numpy as np


def _get(collection, attr, count, dtype, width=1):
    out = np.empty(count * width, dtype=dtype)
    if count:
        collection.foreach_get(attr, out)
    return out.reshape(-1, width) if width > 1 else out


def _loop_normals(mesh):
    nloops = len(mesh.loops)
    if hasattr(mesh, "corner_normals"):  # Blender 4.1+
        return _get(mesh.corner_normals, "vector", nloops, np.float32, 3)
    if hasattr(mesh, "calc_normals_split"):
        mesh.calc_normals_split()
    return _get(mesh.loops, "normal", nloops, np.float32, 3)


def render_uv_layer(mesh):
    """The UV map Cycles renders with (textures without a Vector link, Texture Coordinate > UV): the one whose
    camera icon is on (active_render), not the one selected for editing (active)."""
    layer = next((layer for layer in mesh.uv_layers if layer.active_render), None)
    return layer if layer is not None else mesh.uv_layers.active


def _uv_layer_data(mesh):
    layer = render_uv_layer(mesh)
    if layer is None:
        return None
    nloops = len(mesh.loops)
    if hasattr(layer, "uv"):  # Blender 3.5+
        return _get(layer.uv, "vector", nloops, np.float32, 2)
    return _get(layer.data, "uv", nloops, np.float32, 2)


def mesh_arrays(mesh, matrix):
    """Triangles of an evaluated mesh in world space.

    Returns dict with P (n,3) float32, N (n,3) or None, UV (n,2) or None,
    triangles (m,3) int32, material (m,) int32, smooth (bool: write N)."""
    mesh.calc_loop_triangles()
    ntri = len(mesh.loop_triangles)
    tri_loops = _get(mesh.loop_triangles, "loops", ntri, np.int32, 3)
    material = _get(mesh.loop_triangles, "material_index", ntri, np.int32)
    nverts = len(mesh.vertices)
    co = _get(mesh.vertices, "co", nverts, np.float32, 3)
    loop_vert = _get(mesh.loops, "vertex_index", len(mesh.loops), np.int32)
    npoly = len(mesh.polygons)
    smooth_faces = _get(mesh.polygons, "use_smooth", npoly, bool) if npoly else np.zeros(0, bool)
    any_smooth = bool(smooth_faces.any())
    all_smooth = bool(smooth_faces.all()) if npoly else False
    uv = _uv_layer_data(mesh)
    split_normals = bool(getattr(mesh, "has_custom_normals", False) or getattr(mesh, "use_auto_smooth", False)
                         or getattr(mesh, "normals_domain", "POINT") == "CORNER")  # 4.1+: sharp edges

    if uv is None and (not any_smooth or (all_smooth and not split_normals)):
        # One vertex per mesh vertex: all-flat (no N written) or all-smooth without split normals.
        P = co
        triangles = loop_vert[tri_loops]
        N = None
        if any_smooth:
            N = _get(mesh.vertices, "normal", nverts, np.float32, 3)
    else:
        P = co[loop_vert]
        triangles = tri_loops
        N = None
        if all_smooth and not split_normals:  # vertex normals suffice: skip the split-normal computation
            N = _get(mesh.vertices, "normal", nverts, np.float32, 3)[loop_vert]
        elif any_smooth:
            N = _loop_normals(mesh)

    M = np.array(matrix, dtype=np.float64)
    linear = M[:3, :3]
    P = (P.astype(np.float64) @ linear.T + M[:3, 3]).astype(np.float32)
    if N is not None:
        N = N.astype(np.float64) @ np.linalg.inv(linear)  # (M^-1)^T n, row-vector form
        length = np.linalg.norm(N, axis=1, keepdims=True)
        N = (N / np.maximum(length, 1e-20)).astype(np.float32)
    triangles = np.ascontiguousarray(triangles, dtype=np.int32)
    if np.linalg.det(linear) < 0.0:  # mirrored: keep the winding consistent with the normals
        triangles = triangles[:, [0, 2, 1]]
    return {"P": P, "N": N, "UV": uv, "triangles": triangles, "material": material, "smooth": N is not None}


def subset(arrays, triangle_mask):
    """The part of `arrays` made of the masked triangles, with unused vertices dropped."""
    triangles = arrays["triangles"][triangle_mask]
    used, inverse = np.unique(triangles, return_inverse=True)
    out = dict(arrays)
    out["triangles"] = inverse.reshape(-1, 3).astype(np.int32)
    out["P"] = arrays["P"][used]
    out["N"] = arrays["N"][used] if arrays["N"] is not None else None
    out["UV"] = arrays["UV"][used] if arrays["UV"] is not None else None
    out["material"] = arrays["material"][triangle_mask]
    return out


def write_ply(path, arrays):
    """Binary PLY: float x y z [nx ny nz] [u v]; faces as uchar-count int lists."""
    P, N, UV, triangles = arrays["P"], arrays["N"], arrays["UV"], arrays["triangles"]
    columns = [P]
    props = ["x", "y", "z"]
    if N is not None:
        columns.append(N)
        props += ["nx", "ny", "nz"]
    if UV is not None:
        columns.append(UV)
        props += ["u", "v"]
    vertices = np.ascontiguousarray(np.hstack(columns), dtype="<f4") if len(columns) > 1 else \
        np.ascontiguousarray(P, dtype="<f4")
    faces = np.empty(len(triangles), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"] = 3
    faces["i"] = triangles
    header = ["ply", "format binary_little_endian 1.0", "comment written by the Glimmer Blender addon",
              "element vertex %d" % len(P)]
    header += ["property float %s" % p for p in props]
    header += ["element face %d" % len(triangles), "property list uchar int vertex_indices", "end_header"]
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode("ascii"))
        f.write(vertices.tobytes())
        f.write(faces.tobytes())


def read_ply(path):
    """Reads what write_ply writes (used by the tests)."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    nverts = nfaces = 0
    props = []
    for line in header:
        parts = line.split()
        if parts[:2] == ["element", "vertex"]:
            nverts = int(parts[2])
        elif parts[:2] == ["element", "face"]:
            nfaces = int(parts[2])
        elif parts[:2] == ["property", "float"]:
            props.append(parts[2])
    vertices = np.frombuffer(data, dtype="<f4", count=nverts * len(props), offset=end).reshape(nverts, len(props))
    faces = np.frombuffer(data, dtype=[("n", "u1"), ("i", "<i4", (3,))], count=nfaces,
                          offset=end + vertices.nbytes)
    return {"props": props, "vertices": vertices, "faces": faces}
