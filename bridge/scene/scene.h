// The in-memory scene the XML loader produces: Cycles' standalone scene
// description (camera, film, integrator, background, shaders, meshes, lights)
// with every mesh already transformed to world space.
#pragma once

#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "glimmer/math.h"
#include "scene/transform.h"

namespace glimmer::scene {

// Where a scene element came from, for "file:line: message" diagnostics.
struct SourceLocation {
  std::string file;
  int line = 0;
  std::string str() const { return file + ":" + std::to_string(line); }
};

// Bad scene input: the message already starts with file:line.
class SceneError : public std::runtime_error {
 public:
  SceneError(const SourceLocation &where, const std::string &message)
      : std::runtime_error(where.str() + ": " + message) {}
  explicit SceneError(const std::string &message) : std::runtime_error(message) {}
};

struct Camera {
  Transform camera_to_world;    // camera looks along +Z, +Y up, +X right (Cycles)
  float fov = 0.785398163f;     // radians, across the shorter image side (Cycles' viewplane)
  int width = 1024, height = 512;  // Cycles' Camera defaults
  float nearclip = 1e-5f, farclip = 1e30f;
  float aperture_size = 0.0f;    // thin-lens aperture radius (Cycles' aperturesize; 0 = pinhole)
  float focal_distance = 10.0f;  // distance of the plane in focus along the view axis (Cycles' focaldistance)
  SourceLocation where;
};

enum class FilterType { Box, Gaussian, BlackmanHarris };

struct Film {
  float exposure = 1.0f;  // Cycles multiplies the image by `exposure`
  FilterType filter = FilterType::Box;  // DESIGN.md: box by default (Cycles standalone uses Blackman-Harris 1.5)
  float filter_width = 1.0f;            // pixels
};

// Cycles' Integrator sockets (3.4 defaults).
struct IntegratorSettings {
  int max_bounce = 7;
  int min_bounce = 0;
  int max_diffuse_bounce = 7;
  int max_glossy_bounce = 7;
  int max_transmission_bounce = 7;
  int transparent_max_bounce = 7;
  float filter_glossy = 0.0f;
  float sample_clamp_direct = 0.0f;    // 0 = off
  float sample_clamp_indirect = 10.0f; // Cycles' default; 0 = off
  int seed = 0;
  int samples = 16;                    // `samples` attribute (the CLI overrides)
};

// One node of a shader graph as written in the file; compiled by the renderer.
struct ShaderNode {
  std::string type;  // XML element name, e.g. diffuse_bsdf
  std::string name;
  std::map<std::string, std::string> attributes;  // without `name`
  SourceLocation where;
};

struct ShaderLink {
  std::string from_node, from_socket, to_node, to_socket;
  SourceLocation where;
};

struct ShaderGraph {
  std::string name;
  std::string displacement_method = "bump";  // Cycles' <shader displacement_method>: bump | true | both
  std::vector<ShaderNode> nodes;
  std::vector<ShaderLink> links;
  SourceLocation where;
  const ShaderNode *find(const std::string &node_name) const {
    for (const auto &n : nodes)
      if (n.name == node_name) return &n;
    return nullptr;
  }
  // The link feeding `node.socket`, or nullptr.
  const ShaderLink *link_to(const std::string &node, const std::string &socket) const {
    for (const auto &l : links)
      if (l.to_node == node && l.to_socket == socket) return &l;
    return nullptr;
  }
};

// A triangle mesh in world space (polygons fan-triangulated).
// A point on one triangle of a mesh: everything shading, the host's trace_ray
// and emissive-triangle lights read, computed in one place (Mesh::surface_at).
struct SurfacePoint {
  Vec3 P{0.0f};
  Vec3 Ng{0.0f, 0.0f, 1.0f};  // unit, from the winding (not flipped toward any ray)
  Vec3 N{0.0f, 0.0f, 1.0f};   // unit shading normal: interpolated when smooth and non-zero, else Ng
  Vec3 generated{0.0f};
  float uv[2] = {0.0f, 0.0f};  // mesh uv, or the barycentrics (b1, b2) without uv
  Vec3 e1{0.0f}, e2{0.0f};     // dP/db1, dP/db2 (triangle edges)
  Vec3 dPdu{0.0f}, dPdv{0.0f}; // from the uv map; the edges without uv or for a degenerate uv triangle
  float duv1[2] = {1.0f, 0.0f}, duv2[2] = {0.0f, 1.0f};  // duv/db1, duv/db2
  Vec3 dn1{0.0f}, dn2{0.0f};   // d(unnormalized N)/db1, /db2 (zero when N = Ng)
  Vec3 tangent{0.0f};          // the UV map's tangent, interpolated unnormalized (zero without a UV map)
  float tangent_sign = 1.0f;   // its handedness: the bitangent is sign * N x tangent
};

// What the host's trace_ray / trace_ray_closure services report of a hit (closure_abi.h GlimmerRayHit): P, Ng, N
// and uv of the SurfacePoint at the same barycentrics, the same bits (Mesh::hit_geometry).
struct HitGeometry {
  Vec3 P{0.0f};
  Vec3 Ng{0.0f, 0.0f, 1.0f};
  Vec3 N{0.0f, 0.0f, 1.0f};
  float uv[2] = {0.0f, 0.0f};
};

struct Mesh {
  std::string object_name;
  int shader = -1;  // index into Scene::shaders (-1: default grey diffuse)
  bool smooth = false;
  std::vector<Vec3> P;                     // per vertex, world space
  std::vector<Vec3> N;                     // per vertex (smooth shading), world space; may be empty
  std::vector<Vec3> generated;             // per vertex, object-space bbox-normalized (Cycles "generated")
  std::vector<std::array<uint32_t, 3>> triangles;
  std::vector<std::array<float, 2>> uv;    // per triangle corner (3 per triangle); may be empty
  std::vector<Vec3> tangent;               // per corner, with the UV map: unit UV tangents (scene/uv_tangents.h)
  std::vector<float> tangent_sign;         // per corner, their handedness (+1 or -1)
  Transform object_to_world;               // the object's transform (P and N above already went through it)
  SourceLocation where;

  // The surface of triangle `prim` at barycentrics (b1, b2), b0 = 1 - b1 - b2.
  SurfacePoint surface_at(size_t prim, float b1, float b2) const {
    const auto &tri = triangles[prim];
    const float b0 = 1.0f - b1 - b2;
    SurfacePoint s;
    const Interpolated in = interpolate(prim, b0, b1, b2, s);
    s.e1 = in.e1;
    s.e2 = in.e2;
    if (in.smooth_normal) {
      s.dn1 = N[tri[1]] - N[tri[0]];
      s.dn2 = N[tri[2]] - N[tri[0]];
    }
    s.dPdu = s.e1;
    s.dPdv = s.e2;
    if (!uv.empty()) {
      const auto &a = uv[3 * prim], &b = uv[3 * prim + 1], &c = uv[3 * prim + 2];
      for (int k = 0; k < 2; ++k) {
        s.duv1[k] = b[k] - a[k];
        s.duv2[k] = c[k] - a[k];
      }
      // Solve [e1 e2] = [dPdu dPdv] [[du1 du2] [dv1 dv2]] for dPdu, dPdv.
      const float det = s.duv1[0] * s.duv2[1] - s.duv2[0] * s.duv1[1];
      if (std::fabs(det) > 1e-12f) {
        const float inv = 1.0f / det;
        s.dPdu = (s.e1 * s.duv2[1] - s.e2 * s.duv1[1]) * inv;
        s.dPdv = (s.e2 * s.duv1[0] - s.e1 * s.duv2[0]) * inv;
      }
    }
    s.generated = generated[tri[0]] * b0 + generated[tri[1]] * b1 + generated[tri[2]] * b2;
    if (!tangent.empty()) {
      s.tangent = tangent[3 * prim] * b0 + tangent[3 * prim + 1] * b1 + tangent[3 * prim + 2] * b2;
      s.tangent_sign = tangent_sign[3 * prim] * b0 + tangent_sign[3 * prim + 1] * b1 + tangent_sign[3 * prim + 2] * b2;
    }
    return s;
  }

  // surface_at's P, Ng, N and uv alone (the host's traced rays: the services' hit records), bit for bit: the same
  // interpolation, without the derivatives, tangents and generated coordinates only shading reads (~420
  // instructions per hit for surface_at, frosted_glass sg traces ~9 rays per sample; docs/frosted_glass.md).
  HitGeometry hit_geometry(size_t prim, float b1, float b2) const {
    HitGeometry g;
    interpolate(prim, 1.0f - b1 - b2, b1, b2, g);
    return g;
  }

  // P, Ng, N and uv of a SurfacePoint or a HitGeometry: the one copy of the interpolation both use. Returns the
  // edges e1 = dP/db1, e2 = dP/db2 and whether N is the interpolated smooth normal (not Ng), by value: written
  // through references into the SurfacePoint they made surface_at 359 -> 391 instructions per call (the GGX twin of
  // examples/glint.xml, 160 x 100 4 spp); by value 380. Still 21 over the unshared form: open.
  struct Interpolated {
    Vec3 e1, e2;
    bool smooth_normal = false;
  };
  template <class Point>
  Interpolated interpolate(size_t prim, float b0, float b1, float b2, Point &s) const {
    const auto &tri = triangles[prim];
    const Vec3 p0 = P[tri[0]], p1 = P[tri[1]], p2 = P[tri[2]];
    const Vec3 e1 = p1 - p0, e2 = p2 - p0;
    s.P = p0 * b0 + p1 * b1 + p2 * b2;
    s.Ng = normalize(cross(e1, e2));
    s.N = s.Ng;
    bool smooth_normal = false;
    if (smooth && !N.empty()) {
      const Vec3 n = N[tri[0]] * b0 + N[tri[1]] * b1 + N[tri[2]] * b2;
      if (length_squared(n) > 0.0f) {  // opposite vertex normals can cancel: keep Ng
        s.N = normalize(n);
        smooth_normal = true;
      }
    }
    s.uv[0] = b1;
    s.uv[1] = b2;
    if (!uv.empty()) {
      const auto &a = uv[3 * prim], &b = uv[3 * prim + 1], &c = uv[3 * prim + 2];
      for (int k = 0; k < 2; ++k) s.uv[k] = a[k] * b0 + b[k] * b1 + c[k] * b2;
    }
    return {e1, e2, smooth_normal};
  }
};

enum class LightType { Point, Sun, Spot, Area, Background };

struct Light {
  LightType type = LightType::Point;
  Spectrum strength{1.0f};  // light socket strength x the shader's emission (color * strength)
  Vec3 co{0.0f};
  Vec3 dir{0.0f, 0.0f, -1.0f};
  float radius = 0.0f;     // point/spot `size`
  float angle = 0.0f;      // sun angular diameter (radians)
  float spot_angle = 0.785398163f;
  float spot_smooth = 0.0f;
  Vec3 axisu{1, 0, 0}, axisv{0, 1, 0};
  float sizeu = 1.0f, sizev = 1.0f;
  bool round = false;      // disk/ellipse area light
  float spread = 3.14159265f;  // area light spread angle (radians, (0, pi]; pi = Lambertian)
  bool use_camera = true;  // visible to camera rays (Cycles' socket default; Blender lights default to false)
  int shader = -1;
  SourceLocation where;
};

struct Background {
  int shader = -1;           // -1: black
  bool transparent = false;  // Cycles' film transparency: camera rays that escape give alpha 0
};

struct Scene {
  std::string path;       // the main file
  std::string directory;  // folder of the main file (relative asset paths)
  Camera camera;
  Film film;
  IntegratorSettings integrator;
  Background background;
  std::vector<ShaderGraph> shaders;
  std::vector<Mesh> meshes;
  std::vector<Light> lights;
  std::vector<std::string> warnings;  // "file:line: message", in reading order
  int find_shader(const std::string &name) const {
    for (size_t i = 0; i < shaders.size(); ++i)
      if (shaders[i].name == name) return static_cast<int>(i);
    return -1;
  }
};

}  // namespace glimmer::scene
