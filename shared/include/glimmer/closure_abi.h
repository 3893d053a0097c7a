/*
 * Glimmer closure ABI: the plain-C contract between the host (bridge/) and the
 * shading DSO (libglimmer_closures.so).
 *
 * Conventions mirror Cycles (kernel/closure/bsdf.h):
 *  - All directions are unit vectors in world space pointing AWAY from the
 *    surface. ctx->wi points toward the viewer (the previous path vertex);
 *    wo is the light / continuation direction.
 *  - eval() returns f(wi, wo) * |cos(N, wo)| per RGB channel, WITHOUT the
 *    closure weight (the caller multiplies by it), and the solid-angle pdf with
 *    which sample() would have produced wo.
 *  - Labels use Cycles' ClosureLabel bit values.
 *  - Singular closures (label contains GLIMMER_LABEL_SINGULAR) return a zero
 *    eval and pdf from eval(); sample() returns the delta weight in `eval` and
 *    pdf = 1 (the host skips NEE and MIS for them, as Cycles does).
 *
 * Versioning: major.minor, packed as GLIMMER_ABI_VERSION = major << 16 | minor
 * (a value below 1 << 16 is a pre-2 version number: ABI 1). A minor version
 * only appends fields at the end of structs and adds flag bits; every struct a
 * side hands to the other by pointer starts with (or, for GlimmerPluginInfo,
 * follows abi_version with) its struct_size, so the reader knows which fields
 * exist. The host loads a plugin of its own major version and the same or an
 * older minor (a 2.0 plugin in a 2.1 host), and refuses any other version,
 * naming both. The DSO exports exactly one symbol, glimmer_plugin_entry.
 *   2.0: struct_size fields, major.minor versions.
 *   2.1: varying parameters: GlimmerParamSpec.flags, GlimmerShadingContext
 *        .varying_count / .varying (a 2.0 plugin never sees them).
 *   2.2: exact integer parameters: GlimmerClosureType.abi_version (the
 *        plugin's version, so a host holding a type knows what it speaks), and
 *        INT values carry their exact decimal text in GlimmerParamValue.string
 *        for 2.2 plugins (see GlimmerParamValue); older plugins get the float.
 *   2.3: GlimmerHostServices.trace_ray_closure (a hit with the closure found
 *        there and its parameter values at the hit: GlimmerHitClosure), and
 *        GlimmerSample.flags / .origin / .origin_Ng (GLIMMER_SAMPLE_MOVED: the
 *        path continues from another point, e.g. where light leaves a frosted
 *        object). A plugin checks the host's struct_size before calling it; a
 *        host reads the sample's new fields only from 2.3 plugins' closures.
 *        Also 2.3: one normal convention (see GlimmerShadingContext.N): every closure
 *        gets N and Ng turned toward wi, and `backfacing` decides the medium
 *        wi is in (eta = backfacing ? 1 / ior : ior). A host hands a
 *        TRANSMISSIVE closure of an older plugin the front-face N it expects.
 *        trace_ray hits report N and Ng facing the ray's origin.
 *   2.4: GlimmerSample.lobe_axis / .lobe_sharpness (GLIMMER_SAMPLE_EXIT_LOBE):
 *        a moved sample may describe the lobe its direction was drawn from
 *        (frosted glass sg: the spherical Gaussian of the light leaving the
 *        object), so the host can do next-event estimation and MIS at the
 *        moved origin. Written only when the host's struct_size holds them;
 *        a 2.3 plugin never sets the flag.
 *   2.5: object space in the shading context: GlimmerShadingContext.P_object /
 *        .dPdx_object / .dPdy_object / .Ng_object (the point, its pixel
 *        footprint and geometric normal before the object's transform; e.g.
 *        glint placement="object"). A plugin reads them only when struct_size
 *        holds them (GLIMMER_HAS_FIELD) and Ng_object is non-zero.
 *   2.6: GlimmerShadingContext.sampling_flags (GLIMMER_SAMPLING_UNCOMBINED:
 *        no light strategy is MIS-combined with this vertex's BSDF samples,
 *        so a closure may pick a sampler that is best alone; eval's pdf must
 *        follow the same choice). A plugin reads it only when struct_size
 *        holds it; an older host's contexts mean "combined".
 *   2.7: GlimmerSample.exit_mixture (GLIMMER_SAMPLE_EXIT_MIXTURE): a moved
 *        exit-lobe sample may describe the whole mixture of lobes its
 *        direction was drawn from (GlimmerExitMixture, written into a buffer
 *        the host owns), so the host evaluates the mixture whole (NEE and MIS
 *        with the mixture's density, lamps and the world's cone lookup as
 *        weighted sums over the lobes). A plugin writes it only when the
 *        host's struct_size holds the field and the pointer is not NULL; a
 *        2.6 host still gets the picked lobe in lobe_axis / lobe_sharpness.
 *   2.8: exit states: GlimmerSample.exit_state (a buffer the host owns, or
 *        NULL) and GlimmerClosureType.eval_exit. A SINGULAR sample may hand
 *        over, with GLIMMER_SAMPLE_EXIT_STATE, the state of the last scatter
 *        inside the closure: not moved (frosted_glass's path pane: the walk's
 *        last interface), the host may do NEE at the shading point through it,
 *        MIS-combined with the continued path (eval_exit's pdf at wo); MOVED
 *        with EXIT_LOBE (sg's rough pane), eval_exit is the exit's value over
 *        eval[] (lamps through the lobe). A plugin writes it only when the
 *        host's struct_size holds the field and the pointer is not NULL; a host calls eval_exit only
 *        when the type's struct_size holds it and it is not NULL. Older hosts
 *        and plugins keep the singular sample (MIS weight 1, no NEE).
 *   2.9: GlimmerShadingContext.max_bounce / .max_glossy_bounce /
 *        .max_transmission_bounce: the path's bounce limits as the host
 *        applies them, so that a closure folding several scatters into one
 *        sample (frosted_glass sg's walk through a solid) drops the light the
 *        host's path would have ended. Read only when struct_size holds them;
 *        0 (older hosts, the closure laboratory): no limit.
 *   2.10: GlimmerClosureType.prefetch (may be NULL): start the memory loads
 *        an eval() toward wo will make (a hint with no result), so a host
 *        that knows a direction early (next-event estimation's light
 *        direction, drawn before the BSDF sample) can overlap their cache
 *        misses with other work. A host calls it only when the type's
 *        struct_size holds it and it is not NULL; older plugins' types read
 *        as "no prefetch".
 *
 * Threading: create/prepare/destroy are called from one thread; eval/sample/
 * emit/albedo are called concurrently on an immutable, prepared instance and
 * never allocate.
 */
#ifndef GLIMMER_CLOSURE_ABI_H
#define GLIMMER_CLOSURE_ABI_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#ifndef GLIMMER_ABI_MAJOR
#define GLIMMER_ABI_MAJOR 2u
#endif
#ifndef GLIMMER_ABI_MINOR
#define GLIMMER_ABI_MINOR 10u
#endif
#ifndef GLIMMER_ABI_VERSION
#define GLIMMER_ABI_VERSION ((GLIMMER_ABI_MAJOR << 16) | GLIMMER_ABI_MINOR)
#endif
#define GLIMMER_ABI_VERSION_MAJOR(v) ((v) >= 0x10000u ? (v) >> 16 : (v))
#define GLIMMER_ABI_VERSION_MINOR(v) ((v) >= 0x10000u ? (v) & 0xFFFFu : 0u)

/* True when a struct of `size` bytes (its struct_size) holds `field`. */
#define GLIMMER_HAS_FIELD(size, type, field) \
  ((size) >= offsetof(type, field) + sizeof(((const type *)0)->field))

#define GLIMMER_PLUGIN_ENTRY_SYMBOL "glimmer_plugin_entry"

#if defined(_WIN32)
#define GLIMMER_EXPORT __declspec(dllexport)
#else
#define GLIMMER_EXPORT __attribute__((visibility("default")))
#endif

/* ---- Labels: Cycles' ClosureLabel bit values (kernel/types.h). ---- */
enum GlimmerLabel {
  GLIMMER_LABEL_NONE = 0,
  GLIMMER_LABEL_TRANSMIT = 1,
  GLIMMER_LABEL_REFLECT = 2,
  GLIMMER_LABEL_DIFFUSE = 4,
  GLIMMER_LABEL_GLOSSY = 8,
  GLIMMER_LABEL_SINGULAR = 16,
  GLIMMER_LABEL_TRANSPARENT = 32
};

typedef struct GlimmerVec3 {
  float x, y, z;
} GlimmerVec3;

/* ---- Host services: filled by the bridge, read-only for the plugin. ---- */
typedef struct GlimmerRay {
  uint32_t struct_size; /* filled by the plugin (0 = the 2.0 fields) */
  GlimmerVec3 origin;
  GlimmerVec3 direction; /* unit */
  float t_min, t_max;
} GlimmerRay;

typedef struct GlimmerRayHit {
  uint32_t struct_size; /* the plugin's buffer size; the host writes the fields it holds (0 = the 2.0 fields) */
  float t;
  GlimmerVec3 P;
  GlimmerVec3 N;  /* shading normal, turned as Ng (ABI 2.3; before, the mesh's outward normal) */
  GlimmerVec3 Ng; /* geometric normal, facing the ray's origin (ABI 2.3; before, the mesh's outward normal) */
  float uv[2];
  uint32_t object_id;
  uint32_t backfacing; /* 1 when the ray hit the back side of the mesh (N and Ng were turned) */
} GlimmerRayHit;

enum GlimmerLogLevel {
  GLIMMER_LOG_DEBUG = 0,
  GLIMMER_LOG_INFO = 1,
  GLIMMER_LOG_WARNING = 2,
  GLIMMER_LOG_ERROR = 3
};

/* ---- Varying parameters: per-shading-point values of parameters whose spec
 * carries GLIMMER_PARAM_VARYING (e.g. a textured roughness). The host
 * evaluates its shader graph at each shading point and lists the values of the
 * varying parameters that are linked; every parameter not listed keeps the
 * instance's constant value. `param` is the index in the closure's schema;
 * the plugin clamps values to the spec's range (non-finite -> the constant). ---- */
typedef struct GlimmerVaryingValue {
  uint32_t param;
  float value[3]; /* FLOAT uses [0]; COLOR/VECTOR use [0..2] */
} GlimmerVaryingValue;

struct GlimmerClosureType;
struct GlimmerInstance;

/* ABI 2.3: the closure a traced ray found (trace_ray_closure). The host
 * evaluates the hit's shader at the hit point and reports its principal
 * closure: the plugin closure with the largest sample weight (emission and
 * transparency excluded). A plugin recognises its own material by comparing
 * `instance` with its own instance pointer; the values of that closure's
 * varying parameters at the hit (e.g. a textured roughness) are listed as in
 * GlimmerShadingContext.varying (parameters not listed keep the instance's
 * constant). */
#define GLIMMER_HIT_MAX_VARYING 8
typedef struct GlimmerHitClosure {
  uint32_t struct_size; /* the plugin's buffer size; the host writes the fields it holds */
  const struct GlimmerClosureType *type; /* NULL: no plugin closure at the hit (or none but emission) */
  const struct GlimmerInstance *instance;
  uint32_t varying_count; /* <= GLIMMER_HIT_MAX_VARYING */
  GlimmerVaryingValue varying[GLIMMER_HIT_MAX_VARYING];
} GlimmerHitClosure;

typedef struct GlimmerHostServices {
  uint32_t struct_size; /* sizeof(GlimmerHostServices) of the host */
  uint32_t abi_version; /* the host's GLIMMER_ABI_VERSION */
  void *host_data;
  /* Returns 1 and fills hit when the ray hits scene geometry in (t_min, t_max).
   * May be NULL (e.g. in the closure laboratory). */
  int (*trace_ray)(void *host_data, const GlimmerRay *ray, GlimmerRayHit *hit);
  /* Environment radiance around `direction`, prefiltered over a cone of
   * half-angle `cone_angle` radians (0 = a point lookup). May be NULL. */
  void (*environment_lookup)(void *host_data, GlimmerVec3 direction, float cone_angle,
                             float out_rgb[3]);
  /* Log a message through the host (never NULL). */
  void (*log)(void *host_data, int level, const char *message);
  /* Resolve an asset name relative to the scene; writes a NUL-terminated
   * path and returns 1, or returns 0 when not found. May be NULL. */
  int (*resolve_asset)(void *host_data, const char *name, char *out_path, size_t out_size);
  /* Directory for on-disk caches of precomputed tables (may be NULL: no caching). */
  const char *cache_dir;
#if GLIMMER_ABI_MINOR >= 3
  /* ABI 2.3 (read only when struct_size holds it; may be NULL): trace_ray,
   * and the closure found at the hit with its parameter values there
   * (GlimmerHitClosure; hit_closure->type = NULL when there is none). Hit N
   * and Ng are the mesh's own (front-face) normals, not flipped toward the ray. */
  int (*trace_ray_closure)(void *host_data, const GlimmerRay *ray, GlimmerRayHit *hit,
                           GlimmerHitClosure *hit_closure);
#endif
} GlimmerHostServices;


/* ---- Shading context: one per shading point, built by the host. ---- */
typedef struct GlimmerShadingContext {
  uint32_t struct_size; /* sizeof as filled by the host; 0 = only the 2.0 fields */
  GlimmerVec3 wi; /* toward the viewer, unit */
  GlimmerVec3 P;
  /* Shading normal, unit. The normal convention (ABI 2.3, as Cycles; tests/
   * closures/test_normal_convention.cpp checks every closure against it):
   *  - every closure gets N and Ng turned toward the side the ray came from:
   *    wi is above Ng; wi may still be below a bent shading normal N, where
   *    glossy and transmissive closures scatter nothing (as Cycles');
   *  - `backfacing` says whether that side is the back of the mesh, i.e. the
   *    medium wi is in: a TRANSMISSIVE closure uses eta = backfacing ? 1 / ior
   *    : ior (ior = n_inside / n_outside), and a transmitted wo is below N;
   *  - a host hands TRANSMISSIVE closures of plugins built for ABI <= 2.2 the
   *    front-face (outward) N and Ng instead, which they expect (they take the
   *    side from the sign of dot(wi, N)). */
  GlimmerVec3 N;
  GlimmerVec3 Ng; /* geometric normal, unit */
  GlimmerVec3 T;  /* tangent, unit, orthogonal to N (anisotropy, glint uv frame) */
  float uv[2];
  GlimmerVec3 dPdu, dPdv;
  /* Texture-space footprint: the uv parallelogram spanned by the ray
   * differentials, duv/dx and duv/dy (uv units per pixel step), widened at
   * glossy bounces by the host. Zero vectors mean "a point query". */
  float duv_dx[2];
  float duv_dy[2];
  /* Accumulated angular spread of the path (radians): 0 for camera rays,
   * grows at glossy bounces (beta = 2 * alpha). */
  float spread_angle;
  uint32_t bounce;
  uint32_t diffuse_bounce;
  uint32_t glossy_bounce;
  uint32_t transmission_bounce;
  uint32_t backfacing; /* 1 when the ray arrived at the back side of the mesh (N and Ng were turned); see N */
  uint32_t path_seed;  /* hash of (seed, pixel, sample); never use for glint randomness */
  const GlimmerHostServices *host;
#if GLIMMER_ABI_MINOR >= 1
  /* ABI 2.1. Values of this closure's varying parameters at this point (may be
   * NULL with varying_count 0: every parameter is the instance's constant).
   * Read only when struct_size holds them (GLIMMER_HAS_FIELD). */
  uint32_t varying_count;
  const GlimmerVaryingValue *varying;
#endif
#if GLIMMER_ABI_MINOR >= 5
  /* ABI 2.5. The shading point in the object's own space (before the
   * object's transform): its position, its pixel footprint (the world-space
   * ray-differential steps dP/dx, dP/dy on the surface, the same footprint
   * duv_dx / duv_dy describe in uv, mapped by the inverse transform) and its
   * geometric normal (unit, the mesh's outward side; zero when the host has
   * no object space, e.g. the closure laboratory). Read only when
   * struct_size holds them. */
  GlimmerVec3 P_object;
  GlimmerVec3 dPdx_object, dPdy_object;
  GlimmerVec3 Ng_object;
#endif
#if GLIMMER_ABI_MINOR >= 6
  /* ABI 2.6. GlimmerSamplingFlags bits; read only when struct_size holds it. */
  uint32_t sampling_flags;
#endif
#if GLIMMER_ABI_MINOR >= 9
  /* ABI 2.9. The path's bounce limits as the host applies them (Cycles'
   * path_state_next): a scatter after which `bounce` reaches max_bounce (for
   * a reflection that is not diffuse glossy_bounce max_glossy_bounce, for a
   * transmission transmission_bounce max_transmission_bounce) is the path's
   * last: the next surface adds only its emission. A closure whose one sample
   * stands for several scatters (frosted_glass sg: the entry, the internal
   * reflections, the exit) drops the light that needed more than the limits
   * allow, as the host's path would. 0: no limit. Read only when struct_size
   * holds them. */
  uint32_t max_bounce;
  uint32_t max_glossy_bounce;
  uint32_t max_transmission_bounce;
#endif
} GlimmerShadingContext;

/* GlimmerShadingContext.sampling_flags (ABI 2.6). */
typedef enum GlimmerSamplingFlags {
  /* No light strategy is MIS-combined with BSDF samples at this vertex (the
   * host samples no light there: every light is found by BSDF rays only), so
   * the closure's sample() is the only estimator of the light it reaches and
   * may use a sampler whose point set is best alone (e.g. one whose weight is
   * constant but whose warp is discontinuous in the sample cube). eval() must
   * return the pdf of the sampler this flag selects. */
  GLIMMER_SAMPLING_UNCOMBINED = 1u << 0
} GlimmerSamplingFlags;

#if GLIMMER_ABI_MINOR >= 7
/* ABI 2.7: an exit lobe mixture (GlimmerSample.exit_mixture). Lobe k is the
 * exit lobe of ABI 2.4 (the vMF about axis[k] with sharpness[k] > 0,
 * restricted to the outside of the sample's origin_Ng by the same redraw
 * rule) and is picked with probability weight[k] (>= 0, summing to 1); the
 * mixture's density is sum_k weight[k] ExitLobe_k::pdf (glimmer/exit_lobe.h,
 * ExitLobeMixture) and the lobe as a BSDF at `origin` is eval[] x that
 * density. All lobes leave from the sample's origin. */
#define GLIMMER_EXIT_MAX_LOBES 10
typedef struct GlimmerExitMixture {
  uint32_t count; /* 1..GLIMMER_EXIT_MAX_LOBES; entries beyond count are not written */
  GlimmerVec3 axis[GLIMMER_EXIT_MAX_LOBES];
  float sharpness[GLIMMER_EXIT_MAX_LOBES];
  float weight[GLIMMER_EXIT_MAX_LOBES];
} GlimmerExitMixture;
#endif

#if GLIMMER_ABI_MINOR >= 8
/* ABI 2.8: an exit state (GlimmerSample.exit_state), opaque to the host: the
 * plugin writes it in sample() and reads it back in its type's eval_exit(),
 * for the same instance and shading context, in the same thread. */
#define GLIMMER_EXIT_STATE_WORDS 16
typedef struct GlimmerExitState {
  uint32_t words[GLIMMER_EXIT_STATE_WORDS];
} GlimmerExitState;
#endif

/* ---- Sampling result. ---- */
typedef struct GlimmerSample {
  uint32_t struct_size; /* the host's buffer size; the plugin writes the fields it holds (0 = the 2.0 fields) */
  GlimmerVec3 wo;  /* sampled direction, world space, unit */
  float eval[3];   /* f * |cos(N, wo)| (singular: the delta weight) */
  float pdf;       /* solid-angle density of wo (singular: 1) */
  float roughness; /* effective roughness of the sampled lobe (footprint widening, also of a singular sample: > 0 for a walk through a pane; filter_glossy) */
  float eta;       /* relative IOR crossed for transmission, 1 otherwise */
  uint32_t label;  /* GlimmerLabel bits; 0 = no sample */
#if GLIMMER_ABI_MINOR >= 3
  /* ABI 2.3 (written only when the host's struct_size holds them). With
   * GLIMMER_SAMPLE_MOVED the path continues from `origin` (a point on another
   * surface, e.g. where light leaves a frosted object; the host offsets it
   * along origin_Ng toward wo) instead of the shading point. Such a sample is
   * SINGULAR (eval() does not return it: no NEE/MIS toward it from here) and
   * `roughness` is the width of the lobe it was drawn from (ray footprint). */
  uint32_t flags;
  GlimmerVec3 origin;
  GlimmerVec3 origin_Ng;
#endif
#if GLIMMER_ABI_MINOR >= 4
  /* ABI 2.4 (written only when the host's struct_size holds them). With
   * GLIMMER_SAMPLE_EXIT_LOBE (only together with GLIMMER_SAMPLE_MOVED) wo was
   * drawn at `origin` from the exit lobe: the normalised spherical Gaussian
   * (von Mises-Fisher) about lobe_axis (unit) with sharpness lobe_sharpness
   * (kappa > 0), restricted to the outside of the exit surface origin_Ng by
   * this rule: draw; while below (origin_Ng . w <= 0) draw again, at most 16
   * times; a last direction still below is mirrored about the surface. Its
   * exact density is glimmer/exit_lobe.h's ExitLobe::pdf, and the lobe as a
   * BSDF at `origin` is eval[] x that density (eval[] is the weight the
   * singular sample carries), so a host may do next-event estimation and MIS
   * there; a host that does not still gets the singular sample. */
  GlimmerVec3 lobe_axis;
  float lobe_sharpness;
#endif
#if GLIMMER_ABI_MINOR >= 7
  /* ABI 2.7. Set by the host (its own buffer, or NULL; the plugin never
   * allocates): a plugin whose exit lobe is a mixture writes it there and sets
   * GLIMMER_SAMPLE_EXIT_MIXTURE (only together with GLIMMER_SAMPLE_EXIT_LOBE;
   * lobe_axis / lobe_sharpness then hold the lobe wo was drawn from, for hosts
   * that read only those). Read only when the flag is set. */
  GlimmerExitMixture *exit_mixture;
#endif
#if GLIMMER_ABI_MINOR >= 8
  /* ABI 2.8. Set by the host (its own buffer, or NULL; the plugin never
   * allocates). With GLIMMER_SAMPLE_EXIT_STATE (on a SINGULAR sample; if
   * MOVED, see the 2.8 note above) the plugin
   * wrote there the state its type's eval_exit() reads: the sample's
   * continuation was drawn from eval_exit's density given that state, so a
   * host may take a light sample at the shading point with eval_exit's f cos
   * (in the same units as eval[]: it multiplies both by the same closure
   * weight and pick probability) and MIS-combine it (power or balance
   * heuristic) with the continued path, whose emission hits it then weights
   * against eval_exit's pdf at wo instead of counting them whole. */
  GlimmerExitState *exit_state;
#endif
} GlimmerSample;

enum GlimmerSampleFlags {
  GLIMMER_SAMPLE_MOVED = 1u,
  GLIMMER_SAMPLE_EXIT_LOBE = 2u,
  GLIMMER_SAMPLE_EXIT_MIXTURE = 4u, /* ABI 2.7 */
  GLIMMER_SAMPLE_EXIT_STATE = 8u    /* ABI 2.8 */
};

/* The GlimmerSample a host passes to sample() when it offers no exit buffers:
 * every field zero (exit_mixture and exit_state NULL, so a plugin writes
 * neither) and struct_size this header's size. A host that offers a buffer
 * sets its pointer afterwards. */
static inline GlimmerSample glimmer_blank_sample(void) {
#ifdef __cplusplus
  GlimmerSample s{};
#else
  GlimmerSample s = {0};
#endif
  s.struct_size = (uint32_t)sizeof(GlimmerSample);
  return s;
}

/* ---- Parameters: declared once per closure type, validated at create. ---- */
typedef enum GlimmerParamType {
  GLIMMER_PARAM_FLOAT = 0,
  GLIMMER_PARAM_INT = 1,
  GLIMMER_PARAM_BOOL = 2,
  GLIMMER_PARAM_COLOR = 3,
  GLIMMER_PARAM_VECTOR = 4,
  GLIMMER_PARAM_ENUM = 5,
  GLIMMER_PARAM_STRING = 6
} GlimmerParamType;

/* GlimmerParamSpec.flags */
enum GlimmerParamFlags {
  /* The closure reads this parameter per shading point from
   * GlimmerShadingContext.varying when the host lists it there (textures
   * linked into it); otherwise the value given at create() applies. */
  GLIMMER_PARAM_VARYING = 1u
};

typedef struct GlimmerParamSpec {
  const char *name;          /* identifier used in XML, CLI and Blender */
  uint32_t type;             /* GlimmerParamType */
  float default_value[3];    /* FLOAT/INT/BOOL use [0]; COLOR/VECTOR use [0..2] */
  float min_value;           /* inclusive bounds for FLOAT/INT and COLOR components; INT: whole
                                numbers (any whole float, e.g. 2^31), compared exactly */
  float max_value;
  const char *enum_choices;  /* ENUM: '|'-separated choices, e.g. "ggx|beckmann" */
  const char *default_string;/* ENUM/STRING default */
  const char *doc;           /* one line for the user: meaning and unit */
#if GLIMMER_ABI_MINOR >= 1
  uint32_t flags;            /* GlimmerParamFlags (ABI 2.1; read only when param_spec_size holds it) */
#endif
} GlimmerParamSpec;

typedef struct GlimmerParamValue {
  /* An element of the array passed to create(): this struct never changes
   * within a major version (the array has no stride field). */
  const char *name;
  float value[3];     /* numeric value(s) */
  /* ENUM/STRING value. INT (ABI 2.2, only to plugins whose
   * GlimmerClosureType.abi_version is >= 2.2): the exact value as decimal
   * text ("-"? digits, fits int64), value[0] being its nearest float; a 2.2
   * plugin reads the text (integers beyond 2^24, e.g. seeds, arrive exactly).
   * Else NULL: older plugins read INT from value[0], and a host refuses an INT
   * value a float cannot hold exactly for them. */
  const char *string;
} GlimmerParamValue;

/* Opaque per-material instance. */
typedef struct GlimmerInstance GlimmerInstance;  /* declared above (GlimmerHitClosure) */

enum GlimmerClosureFlags {
  GLIMMER_CLOSURE_EMISSIVE = 1u,      /* has emit() */
  GLIMMER_CLOSURE_SINGULAR = 2u,      /* only delta lobes */
  GLIMMER_CLOSURE_TRANSMISSIVE = 4u,  /* may return TRANSMIT samples */
  GLIMMER_CLOSURE_NEEDS_TRACE = 8u,   /* calls host->trace_ray */
  GLIMMER_CLOSURE_NEEDS_ENVIRONMENT = 16u, /* calls host->environment_lookup */
  GLIMMER_CLOSURE_STOCHASTIC_EVAL = 32u, /* eval is an unbiased estimate (reference closures) */
  GLIMMER_CLOSURE_REFERENCE = 64u     /* slow, exact; for tests and benchmarks */
};

typedef struct GlimmerClosureType {
  uint32_t struct_size;     /* sizeof(GlimmerClosureType) of the plugin */
  uint32_t param_spec_size; /* sizeof(GlimmerParamSpec) of the plugin: the stride of params[] */
  const char *name; /* e.g. "diffuse"; the XML node is usually name + "_bsdf" */
  const char *doc;
  uint32_t flags;   /* GlimmerClosureFlags */
  uint32_t param_count;
  const GlimmerParamSpec *params;

  /* Validate parameters and create an instance. Unknown names, wrong types
   * and out-of-range values fail with a message naming the parameter.
   * Returns 1 on success; on failure writes `error` and returns 0. */
  int (*create)(const GlimmerParamValue *values, uint32_t value_count,
                const GlimmerHostServices *host, GlimmerInstance **out_instance,
                char *error, size_t error_size);
  /* Build or load tables (lazy; only for closures a scene uses). May be NULL. */
  int (*prepare)(GlimmerInstance *instance, const GlimmerHostServices *host, char *error,
                 size_t error_size);
  void (*destroy)(GlimmerInstance *instance);

  /* f*|cos| and pdf of sample() for direction wo. */
  void (*eval)(const GlimmerInstance *instance, const GlimmerShadingContext *ctx, GlimmerVec3 wo,
               float out_eval[3], float *out_pdf);
  /* Sample wo from three uniform numbers in [0,1). Returns the label (0 = absorbed). */
  uint32_t (*sample)(const GlimmerInstance *instance, const GlimmerShadingContext *ctx,
                     const float rand3[3], GlimmerSample *out);
  /* Directional albedo estimate toward ctx->wi (for sample weights and the
   * Albedo AOV). May be NULL: the host then uses 1. */
  void (*albedo)(const GlimmerInstance *instance, const GlimmerShadingContext *ctx,
                 float out_rgb[3]);
  /* Emitted radiance toward ctx->wi (EMISSIVE closures only, else NULL). */
  void (*emit)(const GlimmerInstance *instance, const GlimmerShadingContext *ctx,
               float out_rgb[3]);
#if GLIMMER_ABI_MINOR >= 2
  /* ABI 2.2: GLIMMER_ABI_VERSION the plugin was built with (a type whose
   * struct_size does not hold this field is 2.0 or 2.1). */
  uint32_t abi_version;
#endif
#if GLIMMER_ABI_MINOR >= 8
  /* ABI 2.8 (may be NULL): f * |cos| and pdf toward world direction w of
   * the last scatter described by `state` (written by this type's sample()
   * at `ctx` with GLIMMER_SAMPLE_EXIT_STATE). Zero where that scatter cannot
   * send light (e.g. the other side of the exit face). */
  void (*eval_exit)(const GlimmerInstance *instance, const GlimmerShadingContext *ctx,
                    const GlimmerExitState *state, GlimmerVec3 w, float out_eval[3], float *out_pdf);
#endif
#if GLIMMER_ABI_MINOR >= 10
  /* ABI 2.10 (may be NULL): starts loading what eval(instance, ctx, wo)
   * would read (e.g. a table's cache lines), and nothing else: no result, no
   * effect on any later value. Safe for any input (NaN or below-horizon wo,
   * an instance without tables): it then does nothing. Called concurrently,
   * like eval. A host calls it only when struct_size holds it. */
  void (*prefetch)(const GlimmerInstance *instance, const GlimmerShadingContext *ctx, GlimmerVec3 wo);
#endif
} GlimmerClosureType;

typedef struct GlimmerPluginInfo {
  uint32_t abi_version; /* GLIMMER_ABI_VERSION the plugin was built with (first in every version) */
  uint32_t struct_size; /* sizeof(GlimmerPluginInfo) of the plugin */
  const char *plugin_name;
  const char *plugin_version;
  uint32_t closure_count;
  const GlimmerClosureType *const *closures; /* sorted by name */
} GlimmerPluginInfo;

/* The one exported symbol. Always returns the plugin's info (never NULL) so a
 * host can report the plugin's version even when it differs from its own. */
typedef const GlimmerPluginInfo *(*GlimmerPluginEntryFn)(uint32_t host_abi_version);

GLIMMER_EXPORT const GlimmerPluginInfo *glimmer_plugin_entry(uint32_t host_abi_version);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* GLIMMER_CLOSURE_ABI_H */
