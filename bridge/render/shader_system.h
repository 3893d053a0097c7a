// Shader graphs compiled for rendering: Cycles nodes mapped onto DSO closures,
// textures feeding closure weights, mix/add closure trees. Only shaders that
// geometry, lights or the background use are compiled (the feature scan), so
// unused closures are never created and unused images never loaded.
#pragma once

#include <atomic>
#include <limits>
#include <map>
#include <memory>
#include <new>
#include <set>
#include <string>
#include <type_traits>
#include <vector>

#include "glimmer/closure_abi.h"
#include "glimmer/math.h"
#include "host/closure_instance.h"
#include "host/plugin_library.h"
#include "render/clamped_parameters.h"
#include "render/closure_nodes.h"
#include "render/nodes/node_program.h"
#include "render/textures.h"
#include "scene/scene.h"

namespace glimmer::render {

// What a shader may read at a shading point (coordinates, normal, ray direction, path).
using TexCoords = nodes::ShadingPoint;

enum class VectorSource { UV, Generated, Object, Normal, Direction };

// A colour or float input: a constant, or the output of a texture node.
struct Input {
  Spectrum constant{0.0f};
  int texture = -1;        // index into ShaderSystem textures
  bool fac_output = false; // texture's fac/alpha output instead of color
  int program = -1;        // index into ShaderSystem programs (texture/utility nodes, render/nodes/)
  bool varies() const { return texture >= 0 || program >= 0; }
};

struct TextureNode {
  enum class Kind { Checker, Image, Environment } kind = Kind::Checker;
  Spectrum color1{0.8f}, color2{0.2f};
  float scale = 5.0f;
  const ImageTexture *image = nullptr;
  bool missing = false;  // the file does not exist: magenta, as Cycles renders it
  ImageSampling sampling;
  Projection projection = Projection::Flat;
  float projection_blend = 0.0f;  // box projection
  VectorSource vector = VectorSource::Generated;
  int vector_program = -1;  // a node program (e.g. Mapping) on the vector input instead
};

// Builtin host-side closures (not in the DSO).
enum class BuiltinClosure { None, Transparent };

// The shading points where one textured (varying) parameter fell outside the parameter's range while rendering.
// The closure clamps the value to the range (plugin/core/closure.h, param_float), which the image does not show: a
// noise texture in [0, 1] linked into a glint density (range [1, 1e12]) renders as density 1 everywhere. The render
// reports them (ShaderSystem::clamped_parameter_warnings) at the link's file:line, and keeps them with the image
// (render/clamped_parameters.h). Counted in per-thread slots (a texture out of range everywhere records at every
// shading point), merged when reported.
struct ClampedParameterCount {
  scene::SourceLocation where;  // the <connect> into the parameter
  std::string what;             // "<glint_bsdf> 'g' parameter 'density'"
  float min_value = 0.0f, max_value = 0.0f;
  // A shading point's value (per channel for a colour): counted once per point below and/or above the range, with
  // its extreme channel. Non-finite values are not counted (the closure keeps its constant for them).
  void record(const float *value, int channels);
  struct Totals {
    uint64_t below = 0, above = 0;
    float lowest = std::numeric_limits<float>::infinity(), highest = -std::numeric_limits<float>::infinity();
  };
  Totals totals() const;
  void reset();

 private:
  static constexpr int kSlots = 16;
  struct alignas(64) Slot {
    std::atomic<uint64_t> below{0}, above{0};
    std::atomic<float> lowest{std::numeric_limits<float>::infinity()};
    std::atomic<float> highest{-std::numeric_limits<float>::infinity()};
  };
  Slot slots_[kSlots];
};

struct ClosureLeaf {
  const GlimmerClosureType *type = nullptr;  // DSO closure (nullptr for builtins)
  const host::ClosureInstance *instance = nullptr;
  BuiltinClosure builtin = BuiltinClosure::None;
  Input weight;        // Cycles' colour input (possibly textured)
  float strength = 1;  // extra scalar on the weight
  bool emissive = false;
  bool singular = false;
  // filter_glossy: variants with alpha >= kBlurStep * k (k = 1..kBlurLevels), created only
  // when the scene sets filter_glossy > 0 (closure instances are immutable while rendering).
  static constexpr int kBlurLevels = 10;
  static constexpr float kBlurStep = 0.05f;
  std::vector<const host::ClosureInstance *> blurred;  // empty or kBlurLevels + 1 (index 0 = unblurred)
  // Linked sockets evaluated at each shading point into the closure's varying
  // parameters (GLIMMER_PARAM_VARYING), e.g. a checker texture into roughness.
  struct VaryingInput {
    uint32_t param = 0;  // index in the closure's schema
    Input input;
    bool color = false;  // COLOR/VECTOR parameter (else one float: the input's luminance)
    ClampedParameterCount *clamped = nullptr;  // counts the shading points outside the parameter's range
  };
  static constexpr int kMaxVarying = 4;
  std::vector<VaryingInput> varying;
  int varying_roughness = -1;  // index in `varying` of the roughness (filter_glossy raises it)
  // The closure's own shading frame (ShaderSystem::shading_frame): its normal socket (Bump, Normal Map),
  // tangent socket and tangent rotation (constant or per point). Without any, the point's frame is used.
  struct Frame {
    Input normal, tangent, rotation;
    bool radial_tangent = false;  // unlinked tangent: Cycles' radial Z default (anisotropic glossy)
    bool active = false;          // some socket above changes the frame
    bool bump_shadowing = false;  // a diffuse closure: Cycles' bump shadowing term when its normal is perturbed
    // The radial default with a linked anisotropy (schema index): where it is 0 and nothing else changes
    // the frame, the lobe is isotropic and keeps the point's frame, as a constant 0 does.
    bool radial_only = false;
    uint32_t anisotropy_param = 0;
  } frame;
  std::string node;    // for messages
};

struct ClosureTreeNode {
  enum class Kind { Leaf, Mix, Add } kind = Kind::Leaf;
  int leaf = -1;
  Input fac;
  int a = -1, b = -1;
};

struct CompiledShader {
  std::string name;
  std::vector<ClosureTreeNode> tree;
  int root = -1;  // -1: no surface closure (black, opaque)
  bool has_emission = false;
  bool has_transparent = false;
  bool has_bsdf = false;
  // Some input of its closure tree (a weight, a varying parameter, a frame socket, a mix factor) is a texture
  // or a node program, i.e. may read the point's texture coordinates and their footprint (ShadingPoint's
  // dPdx, duv_dx, dgenerated_dx, bump_*); false when every input is a constant (set by compile).
  bool reads_footprint = false;
};

// One weighted closure at a shading point.
struct ActiveClosure {
  const ClosureLeaf *leaf;
  const host::ClosureInstance *instance;  // leaf->instance, or a blurred variant (filter_glossy)
  Spectrum weight;
  float sample_weight;
  // The varying parameters' values at this shading point (handed to the closure in its context).
  uint32_t varying_count = 0;
  GlimmerVaryingValue varying[ClosureLeaf::kMaxVarying];
  // The closure's own frame at this point (ClosureLeaf::frame), on the side of the point's N.
  bool own_frame = false;
  Vec3 N{0.0f, 0.0f, 1.0f}, T{1.0f, 0.0f, 0.0f};
};

struct ClosureSet {
  static constexpr int kMax = 16;
  // Storage for kMax closures, of which the first `count` are constructed (by add): a ClosureSet is declared
  // at every shading point, and constructing all 16 (their default members) cost more than the one or two used.
  struct Slots {
    alignas(ActiveClosure) unsigned char bytes[kMax * sizeof(ActiveClosure)];
    ActiveClosure &operator[](int i) {
      return *std::launder(reinterpret_cast<ActiveClosure *>(bytes + i * sizeof(ActiveClosure)));
    }
    const ActiveClosure &operator[](int i) const {
      return *std::launder(reinterpret_cast<const ActiveClosure *>(bytes + i * sizeof(ActiveClosure)));
    }
  } closures;
  static_assert(std::is_trivially_copyable_v<ActiveClosure> && std::is_trivially_destructible_v<ActiveClosure>);
  int count = 0;
  Spectrum transparent{0.0f};  // weight of the transparent closure (pass-through)
  float sum_sample_weight = 0.0f;
  void add(const ActiveClosure &c) {
    if (count < kMax) {
      new (&closures.bytes[count++ * sizeof(ActiveClosure)]) ActiveClosure(c);
      sum_sample_weight += c.sample_weight;
    }
  }
};

// What the feature scan found (reported by --stats).
struct FeatureSet {
  std::set<std::string> closures;   // DSO closure names instantiated
  std::set<std::string> textures;   // image files loaded
  std::set<std::string> light_types;
  int emissive_triangles = 0;
  bool environment_map = false;
  bool background = false;
  bool transparent = false;
  bool volumes = false;  // volume nodes present (ignored)
  int used_shaders = 0, unused_shaders = 0;
  std::string world_sampling = "none";  // the world as a "light" or by BSDF rays only ("bsdf_only"), lights.h
};

class ShaderSystem {
 public:
  // `warnings` receives "file:line: warning: ..." lines for unsupported nodes.
  ShaderSystem(const scene::Scene &scene, const host::PluginLibrary &plugin, const GlimmerHostServices *host,
               std::vector<std::string> &warnings, FeatureSet &features);

  // Compiles shader `index` (once); -1 compiles the default grey diffuse.
  int compile(int shader_index);
  const CompiledShader &shader(int compiled) const { return compiled_[compiled]; }

  // Background: compiled separately (only the background/emission node matters).
  void compile_background(int shader_index);
  bool has_background() const { return background_.active; }
  bool background_is_constant() const { return !background_.color.varies(); }
  // Every closure instance the compiled shaders use (filter_glossy variants included).
  const std::vector<std::unique_ptr<host::ClosureInstance>> &instances() const { return instances_; }
  Spectrum background(const Vec3 &direction) const;
  // Sun discs of sky textures in the world (directions the background light samples explicitly).
  std::vector<nodes::SunDisc> background_suns() const;

  // The emission of a light's shader (color * strength; textures are not supported on lights).
  Spectrum light_emission(int shader_index, const scene::SourceLocation &where);

  void evaluate(int compiled, const TexCoords &tc, ClosureSet &out) const;
  // A closure's own normal and tangent at `tc` (its normal/tangent/rotation sockets), into `out`.
  void shading_frame(const ClosureLeaf &leaf, const TexCoords &tc, ActiveClosure &out) const;
  Spectrum eval_input(const Input &in, const TexCoords &tc) const;

  // The textured parameters whose values fell outside their range in the renders since
  // reset_clamped_parameter_counts() (the closures clamp them): how many shading points and the extreme values.
  ClampedParameterRecords clamped_parameter_records() const;
  // Their "file:line: warning: ..." lines (render::clamped_parameter_warnings).
  std::vector<std::string> clamped_parameter_warnings() const;
  void reset_clamped_parameter_counts();

  // filter_glossy: blur level k (1..ClosureLeaf::kBlurLevels) raises every glossy
  // closure to alpha >= k * kBlurStep (a precomputed variant, or the varying roughness).
  static void apply_filter_glossy(ClosureSet &cs, int k);

 private:
  const scene::Scene &scene_;
  const host::PluginLibrary &plugin_;
  const GlimmerHostServices *host_;
  std::vector<std::string> &warnings_;
  FeatureSet &features_;

  std::vector<CompiledShader> compiled_;
  std::map<int, int> compiled_index_;  // scene shader -> compiled
  std::vector<std::unique_ptr<ClosureLeaf>> leaves_;
  std::vector<std::unique_ptr<host::ClosureInstance>> instances_;
  std::vector<TextureNode> textures_;
  std::unique_ptr<TextureCache> texture_cache_;  // created by the first image a used shader reads
  std::vector<nodes::NodeProgram> programs_;
  std::vector<Input> program_externals_;  // textures outside the node table that programs read
  std::vector<std::unique_ptr<scene::ShaderGraph>> expanded_graphs_;  // composites (principled_bsdf) expanded
  std::vector<std::unique_ptr<ClampedParameterCount>> clamped_;       // one per bound varying parameter

  struct BackgroundShader {
    bool active = false;
    Input color;
    float strength = 1.0f;
  } background_;

  void warn(const scene::SourceLocation &where, const std::string &message);
  // The count of a bound varying parameter's out-of-range values (nullptr: already counted through another part
  // of the same composite node and link).
  ClampedParameterCount *clamped_count(const scene::ShaderGraph &g, const scene::ShaderNode &n,
                                       const scene::ShaderLink &link, const std::string &param,
                                       const GlimmerParamSpec &spec);
  bool any_varying_input(const CompiledShader &cs) const;  // CompiledShader::reads_footprint
  int compile_closure(const scene::ShaderGraph &g, const std::string &node, const std::string &socket,
                      CompiledShader &out, int depth);
  // One closure leaf from a node, driven by its ClosureNodeRow (-1: no row and no DSO closure of that name).
  int make_leaf(const scene::ShaderGraph &g, const scene::ShaderNode &n, CompiledShader &out);
  const ClosureNodeRow *row_for(const std::string &node_type, ClosureNodeRow &storage);
  static const std::string *attribute_of(const scene::ShaderNode &n, const SocketRow &s);
  void check_attributes(const scene::ShaderNode &n, const ClosureNodeRow &row, const GlimmerClosureType *type,
                        host::ParamList &params);
  float apply_sockets(const scene::ShaderGraph &g, const scene::ShaderNode &n, const ClosureNodeRow &row,
                      const GlimmerClosureType *type, ClosureLeaf &leaf, host::ParamList &params);
  // The normal, tangent and rotation sockets of a row into the leaf's frame (whether it changes the frame).
  void read_frame_socket(const scene::ShaderGraph &g, const scene::ShaderNode &n, const ClosureNodeRow &row,
                         const SocketRow &s, const std::string *text, ClosureLeaf &leaf);
  void bind_links(const scene::ShaderGraph &g, const scene::ShaderNode &n, const ClosureNodeRow &row,
                  ClosureLeaf &leaf);
  std::string apply_distribution(const scene::ShaderGraph &g, const scene::ShaderNode &n,
                                 const GlimmerClosureType &type, float roughness, host::ParamList &params);
  void apply_bounce_tint(const scene::ShaderNode &n, const GlimmerClosureType &type, const ClosureLeaf &leaf,
                         host::ParamList &params);
  void make_blurred_variants(const scene::ShaderNode &n, const GlimmerClosureType &type,
                             const std::string &distribution, float roughness, const host::ParamList &params,
                             ClosureLeaf &leaf);
  const host::ClosureInstance *diffuse_fallback(const scene::ShaderNode &n, ClosureLeaf &leaf);
  // A socket's constant: its attribute `text` (1 or 3 numbers) or `fallback`.
  static Spectrum read_constant(const scene::ShaderNode &n, const std::string &socket, const std::string *text,
                                Spectrum fallback);
  Input read_input(const scene::ShaderGraph &g, const scene::ShaderNode &n, const std::string &socket,
                   Spectrum fallback, VectorSource default_vector);
  // A linked `socket` becomes the closure's varying parameter `param`; returns
  // false (with a file:line warning) when the closure does not declare it varying.
  bool bind_varying(ClosureLeaf &leaf, const scene::ShaderGraph &g, const scene::ShaderNode &n,
                    const std::string &socket, const std::string &param);
  // Warns (file:line) for every link into `n` whose socket is not in `supported`.
  void warn_unsupported_links(const scene::ShaderGraph &g, const scene::ShaderNode &n,
                              std::initializer_list<const char *> supported);
  const host::ClosureInstance *instantiate(const GlimmerClosureType &type, const host::ParamList &params,
                                           const scene::SourceLocation &where);
  // The node's image (nullptr: no filename, or a missing file, then `missing` is set) and its
  // interpolation, extension and projection settings.
  void configure_image(const scene::ShaderNode &n, TextureNode &tex);
  const ImageTexture *load_image(const scene::ShaderNode &n, bool &missing);
  // An image texture node at coordinate `co` with its derivatives per pixel step (projection, lookup).
  Spectrum lookup_image(const TextureNode &t, const Vec3 &co, const Vec3 &dco_dx, const Vec3 &dco_dy,
                        const Vec3 &N, bool alpha) const;
  // The table nodes (render/nodes/) behind `link` as a program; returns its index.
  int compile_program(const scene::ShaderGraph &g, const scene::ShaderLink &link);
};

}  // namespace glimmer::render
