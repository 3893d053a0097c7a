"""Equal-error time against Blender's own Cycles (3.4, CPU): the issue-13 benchmark scenes.

Run headless (not part of `make test`; it takes minutes):
  blender -b --factory-startup --python benchmarks/cycles_equal_error.py -- --glimmer build/glimmer --out DIR
      [--scenes a,b,c] [--samples 256] [--reference-samples 4096] [--size 96] [--repeats 3]
      [--reuse-references] [--ladder 16,32,64,128,256] [--noise-seeds 5] [--means]

Scenes, built by script as tests/addon/test_cycles_parity.py builds its scenes (box filter width 1, no clamps,
no filter glossy, no denoising, linear float EXR) and exported by the addon:
  a  a white multi-GGX sphere (roughness 0.9) in a constant white world
  b  a rough glass sphere (GGX 0.3, IOR 1.45) on a glossy floor under an HDR environment
  c  a diffuse box lit by an area light with a glossy (GGX 0.3) sphere
  g  a white glass sphere (GGX 0.6, IOR 1.5) filling the frame in a constant white world (full depth)
  m  the same with multi_ggx glass
  b1..b11  scene (b) with one part changed (scene_b_variant; BUILD lists them), to bisect its bias
For each: a Cycles reference (seed 7), then Cycles and Glimmer at the same sample count, interleaved
--repeats times in ABBA order (C G G C C G ...: the two renderers share the machine's load drift), seed 1,
wall time of each render (median of the repeats; the images are identical across repeats), RMSE against
the Cycles reference (and Glimmer's against its own reference, which separates its noise from model
differences), and the equal-error time ratio
  time_glimmer / time_cycles x (rmse_glimmer / rmse_cycles)^2  (< 1: Glimmer reaches the same error sooner).
TIMED SCOPE, the same on both sides: from the scene in Blender to the image file on disk. Cycles:
bpy.ops.render.render() (depsgraph sync into Cycles, BVH, render) + save_render (the EXR write). Glimmer: the
addon's export to Cycles XML (its sync) + the glimmer process (start-up, scene load, BVH, render, EXR write).
Both write the Combined pass only (Glimmer `--no-aovs` since session 6; its Albedo, Normal and Depth passes
were computed at every sample's first hit before, work Cycles does not do here).
Before session 6 Cycles' EXR write and Glimmer's export were both left out (a few ms each at 96x96).
The CPU time (user + system) of each timed render is printed too: on the shared machine a process gets a share
of the cores that the other engineers' load decides, so wall times alone mix speed with that share.
--reuse-references loads the reference EXRs an earlier run with the same settings left in --out instead of
rendering them again.
--noise-seeds N: the RMSE of one 256-spp image varies with the seed (scene c: 0.0252..0.0272 over Glimmer seeds
1-5, +-4 %), more than the gap being measured; with N > 1 both renderers also render seeds 2..N (untimed) and the
ratio uses each renderer's mean RMSE over seeds 1..N (the seed-1 figures are printed too).
--ladder 16,32,...: instead of the timing, each renderer's RMSE against its own reference at every rung and
the fitted log-log slope (Cycles' convergence next to Glimmer's on the same exported scene).
--means: instead of the timing, each renderer's image mean at --samples over seeds 1 and 2, its standard error
(from the two seeds' per-pixel difference) and glimmer / cycles; no reference (docs/architecture.md
"Scene (b)'s bias").
"""
import argparse
import os
import resource
import subprocess
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "tests", "addon"))
import addon_test_util as util  # noqa: E402
from scene_build_util import add_camera, add_plane, add_sphere, load_pixels, material  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
parser = argparse.ArgumentParser()
parser.add_argument("--glimmer", default=os.environ.get("GLIMMER_EXECUTABLE", ""))
parser.add_argument("--out", default="/tmp/glimmer_cycles_equal_error")
parser.add_argument("--scenes", default="a,b,c")
parser.add_argument("--samples", type=int, default=256)
parser.add_argument("--reference-samples", type=int, default=4096)
parser.add_argument("--size", type=int, default=96)
parser.add_argument("--threads", type=int, default=2)
parser.add_argument("--repeats", type=int, default=3)
parser.add_argument("--reuse-references", action="store_true")
parser.add_argument("--ladder", default="")
parser.add_argument("--means", action="store_true")
parser.add_argument("--noise-seeds", type=int, default=1)
opts = parser.parse_args(argv)
os.environ["GLIMMER_EXECUTABLE"] = os.path.abspath(opts.glimmer)
os.makedirs(opts.out, exist_ok=True)
mod = util.enable_addon()


def new_scene(samples, bounces=12):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    r = scene.render
    r.resolution_x = r.resolution_y = opts.size
    r.resolution_percentage = 100
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.threads_mode = "FIXED"
    r.threads = opts.threads
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    c = scene.cycles
    c.device = "CPU"
    c.samples = samples
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.light_sampling_threshold = 0.0
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = bounces
    c.transparent_max_bounces = bounces
    c.min_light_bounces = c.min_transparent_bounces = 0
    c.caustics_reflective = c.caustics_refractive = True
    g = scene.glimmer
    g.samples = samples
    g.threads = opts.threads
    g.max_bounce = g.max_diffuse_bounce = g.max_glossy_bounce = g.max_transmission_bounce = bounces
    g.transparent_max_bounce = bounces
    g.min_bounce = 0  # Russian roulette as Cycles' min_light_bounces = 0 above (the addon's default was 3 once)
    g.filter_glossy = 0.0
    g.sample_clamp_direct = g.sample_clamp_indirect = 0.0
    g.filter_type = "box"
    g.filter_width = 1.0
    g.film_exposure = 1.0
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    scene.world = world
    return scene


def set_world_color(scene, color, strength=1.0):
    bg = scene.world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength


def set_world_hdr(scene, path):
    tree = scene.world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(path)
    tree.links.new(env.outputs["Color"], tree.nodes["Background"].inputs["Color"])


def write_hdr(path, w=256, h=128):
    """A sky: blue-white gradient, dark ground, a small bright sun (an HDR with a 2000:1 range)."""
    img = bpy.data.images.new("sky", w, h, float_buffer=True)
    px = np.zeros((h, w, 4), dtype=np.float32)
    for y in range(h):
        v = (y + 0.5) / h  # 0 = bottom row
        sky = np.array([0.35, 0.5, 0.9]) * (0.3 + 0.7 * v) if v > 0.5 else np.array([0.15, 0.12, 0.1])
        px[y, :, :3] = sky
    px[int(0.8 * h):int(0.8 * h) + 3, int(0.3 * w):int(0.3 * w) + 3, :3] = 600.0
    px[..., 3] = 1.0
    img.pixels[:] = px.ravel()
    img.filepath_raw = path
    img.file_format = "OPEN_EXR"
    img.save()


def scene_a(samples):
    scene = new_scene(samples)
    set_world_color(scene, (1.0, 1.0, 1.0))
    add_camera(scene, (0.0, -4.0, 0.0), (90.0, 0.0, 0.0))
    add_sphere(1.0, (0, 0, 0), material("MultiGGX", "ShaderNodeBsdfGlossy", (1.0, 1.0, 1.0),
                                        distribution="MULTI_GGX", Roughness=0.9))
    return scene


def scene_b(samples):
    scene = new_scene(samples)
    hdr = os.path.join(opts.out, "sky.exr")
    write_hdr(hdr)
    set_world_hdr(scene, hdr)
    add_camera(scene, (0.0, -5.0, 1.6), (76.0, 0.0, 0.0))
    add_plane(20.0, mat=material("Floor", "ShaderNodeBsdfGlossy", (0.6, 0.6, 0.6), distribution="GGX", Roughness=0.3))
    add_sphere(1.0, (0, 0, 1.0), material("Glass", "ShaderNodeBsdfGlass", (1.0, 1.0, 1.0),
                                          distribution="GGX", Roughness=0.3, IOR=1.45))
    return scene


def scene_c(samples):
    scene = new_scene(samples)
    set_world_color(scene, (0.0, 0.0, 0.0), 0.0)
    add_camera(scene, (0.0, -3.9, 0.0), (90.0, 0.0, 0.0), lens=35.0)
    white = material("White", "ShaderNodeBsdfDiffuse", (0.8, 0.8, 0.8))
    add_plane(2.0, (0, 0, -1), (0, 0, 0), white)
    add_plane(2.0, (0, 0, 1), (180, 0, 0), white)
    add_plane(2.0, (0, 1, 0), (90, 0, 0), white)
    add_plane(2.0, (-1, 0, 0), (0, 90, 0), material("Red", "ShaderNodeBsdfDiffuse", (0.8, 0.1, 0.1)))
    add_plane(2.0, (1, 0, 0), (0, -90, 0), material("Green", "ShaderNodeBsdfDiffuse", (0.1, 0.8, 0.1)))
    add_sphere(0.4, (0.0, 0.2, -0.6), material("Glossy", "ShaderNodeBsdfGlossy", (0.9, 0.9, 0.9),
                                               distribution="GGX", Roughness=0.3))
    light = bpy.data.objects.new("Area", bpy.data.lights.new("Area", "AREA"))
    light.data.size = 0.5
    light.data.energy = 40.0
    light.location = (0.0, 0.2, 0.98)
    scene.collection.objects.link(light)
    return scene


def white_world_glass(samples, distribution):
    scene = new_scene(samples)
    set_world_color(scene, (1.0, 1.0, 1.0))
    add_camera(scene, (0.0, -4.0, 0.0), (90.0, 0.0, 0.0), lens=150.0)  # the sphere fills the frame
    add_sphere(1.0, (0, 0, 0), material("Glass", "ShaderNodeBsdfGlass", (1.0, 1.0, 1.0), distribution=distribution,
                                        Roughness=0.6, IOR=1.5))
    return scene


def fresnel_mix_glass(roughness, ior):
    """Mix(Fresnel(ior), GGX Refraction, GGX Glossy): the macro-surface Fresnel split of Cycles 3.x's Glass BSDF."""
    mat = material("FresnelMixGlass", "ShaderNodeBsdfGlossy", (1.0, 1.0, 1.0), distribution="GGX", Roughness=roughness)
    tree = mat.node_tree
    glossy = tree.nodes["Glossy BSDF"]
    refraction = tree.nodes.new("ShaderNodeBsdfRefraction")
    refraction.distribution = "GGX"
    refraction.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    refraction.inputs["Roughness"].default_value = roughness
    refraction.inputs["IOR"].default_value = ior
    fresnel = tree.nodes.new("ShaderNodeFresnel")
    fresnel.inputs["IOR"].default_value = ior
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(fresnel.outputs["Fac"], mix.inputs["Fac"])
    tree.links.new(refraction.outputs[0], mix.inputs[1])
    tree.links.new(glossy.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return mat


def scene_b_variant(samples, world="hdr", floor="glossy", sphere=True, world_sampling="AUTOMATIC",
                    sphere_node="ShaderNodeBsdfGlass", roughness=0.3):
    """Scene (b) with one part changed, to bisect its bias vs Cycles (--means): world "hdr" or "constant" (0.5),
    floor "glossy", "diffuse" or None, the glass sphere or not; world_sampling is Cycles' only (Glimmer has none)."""
    scene = new_scene(samples)
    if world == "hdr":
        hdr = os.path.join(opts.out, "sky.exr")
        write_hdr(hdr)
        set_world_hdr(scene, hdr)
    else:
        set_world_color(scene, (0.5, 0.5, 0.5))
    scene.world.cycles.sampling_method = world_sampling
    add_camera(scene, (0.0, -5.0, 1.6), (76.0, 0.0, 0.0))
    if floor == "glossy":
        add_plane(20.0, mat=material("Floor", "ShaderNodeBsdfGlossy", (0.6, 0.6, 0.6), distribution="GGX", Roughness=0.3))
    elif floor == "diffuse":
        add_plane(20.0, mat=material("Floor", "ShaderNodeBsdfDiffuse", (0.6, 0.6, 0.6)))
    if sphere == "fresnel_mix":  # Cycles 3.x's Glass BSDF written out as nodes (see docs/architecture.md)
        add_sphere(1.0, (0, 0, 1.0), fresnel_mix_glass(roughness, 1.45))
    elif sphere:
        ior = {} if sphere_node == "ShaderNodeBsdfGlossy" else {"IOR": 1.45}
        add_sphere(1.0, (0, 0, 1.0), material("Sphere", sphere_node, (1.0, 1.0, 1.0), distribution="GGX",
                                              Roughness=roughness, **ior))
    return scene


BUILD = {"a": scene_a, "b": scene_b, "c": scene_c, "g": lambda n: white_world_glass(n, "GGX"),
         "m": lambda n: white_world_glass(n, "MULTI_GGX"),
         # scene (b)'s bisection variants (--means)
         "b1": lambda n: scene_b_variant(n, floor="diffuse", sphere=False),  # the HDR sky alone on a diffuse floor
         "b2": lambda n: scene_b_variant(n, sphere=False),  # the glossy floor alone
         "b3": lambda n: scene_b_variant(n, world="constant", floor=None),  # the glass sphere alone, constant world
         "b4": lambda n: scene_b_variant(n, world="constant"),  # (b) with a constant world
         "b5": lambda n: scene_b_variant(n, world_sampling="NONE"),  # (b), Cycles' world importance sampling off
         "b6": lambda n: scene_b_variant(n, floor="diffuse"),  # (b) with a diffuse floor
         # the sphere alone in a constant world: smooth glass, the refraction and the reflection lobes alone
         "b7": lambda n: scene_b_variant(n, world="constant", floor=None, roughness=0.0),
         "b8": lambda n: scene_b_variant(n, world="constant", floor=None, sphere_node="ShaderNodeBsdfRefraction"),
         "b9": lambda n: scene_b_variant(n, world="constant", floor=None, sphere_node="ShaderNodeBsdfGlossy"),
         # the glass sphere as Cycles 3.x's split: Mix(Fresnel, Refraction, Glossy); constant world, then (b)'s
         "b10": lambda n: scene_b_variant(n, world="constant", floor=None, sphere="fresnel_mix"),
         "b11": lambda n: scene_b_variant(n, sphere="fresnel_mix")}  # (b) with a diffuse floor


def render_cycles(name, seed):
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.seed = seed
    path = os.path.join(opts.out, name + ".exr")
    cpu0 = cpu_seconds(resource.RUSAGE_SELF)
    t0 = time.time()
    bpy.ops.render.render()
    bpy.data.images["Render Result"].save_render(path, scene=scene)
    seconds = time.time() - t0  # as Glimmer's: from the Blender scene to the image file (see TIMED SCOPE)
    CPU[name] = cpu_seconds(resource.RUSAGE_SELF) - cpu0
    return load_pixels(path), seconds


def render_glimmer(name, seed):
    scene = bpy.context.scene
    cpu0 = cpu_seconds(resource.RUSAGE_SELF) + cpu_seconds(resource.RUSAGE_CHILDREN)
    t0 = time.time()
    xml, _ = mod.exporter.export_scene(bpy.context.evaluated_depsgraph_get(), os.path.join(opts.out, name + "_export"))
    export_seconds = time.time() - t0
    exr = os.path.join(opts.out, name + ".exr")
    g = scene.glimmer
    cmd = mod.runner.render_command(opts.glimmer, xml, exr, g.samples, g.threads, seed, opts.size, opts.size)
    # --no-aovs: the Combined pass only, as Cycles renders here (no denoising data, no extra passes).
    proc = subprocess.run(cmd + ["--quiet", "--stats", "--no-aovs"], check=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    seconds = time.time() - t0  # the export (Cycles' sync) + the process (load, BVH, render, EXR write)
    CPU[name] = cpu_seconds(resource.RUSAGE_SELF) + cpu_seconds(resource.RUSAGE_CHILDREN) - cpu0
    stats = proc.stdout.decode(errors="replace")
    render_phase = float(stats.split("render=")[1].split("s")[0]) if "render=" in stats else float("nan")
    TIMES[name] = (seconds, render_phase, export_seconds)
    channels = mod.engine.exr_channels(exr)
    combined = [c for c in channels if ".Combined." in c]
    order = ["%s.Combined.%s" % (combined[0].split(".Combined.")[0], c) for c in "RGBA"] if combined else list("RGBA")
    rgba = os.path.join(opts.out, name + "_rgba.exr")
    subprocess.run(["oiiotool", exr, "--ch", ",".join(order), "--chnames", "R,G,B,A", "-d", "float", "-o", rgba],
                   check=True)
    return load_pixels(rgba), seconds


TIMES = {}
PHASES = {}  # per scene: (render phase, export) of each timed Glimmer run
CPU = {}  # user + system CPU seconds of each render over the timed scope (Blender's process for Cycles)


def cpu_seconds(who):
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def rmse(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)))


def reference(render, name):
    """The reference render, or with --reuse-references the one an earlier run left in --out (time nan)."""
    path = os.path.join(opts.out, name + ("_rgba.exr" if render is render_glimmer else ".exr"))
    if opts.reuse_references and os.path.exists(path):
        return load_pixels(path), float("nan")
    return render(name, 7)


def interleaved(key):
    """Cycles and Glimmer renders of the scene, ABBA-interleaved; images of the first, median times."""
    times = {"c": [], "g": []}
    cpu = {"c": [], "g": []}
    images = {}
    for i in range(opts.repeats):
        for r in ("cg" if i % 2 == 0 else "gc"):
            name = "%s_%s" % (key, "cycles" if r == "c" else "glimmer")
            image, seconds = (render_cycles if r == "c" else render_glimmer)(name, 1)
            images.setdefault(r, image)
            times[r].append(seconds)
            cpu[r].append(CPU[name])
            if r == "g":
                PHASES.setdefault(key, []).append(TIMES[name][1:])
    print("scene %s CPU seconds (user + sys), interleaved: cycles %s glimmer %s" %
          (key, " ".join("%.2f" % t for t in cpu["c"]), " ".join("%.2f" % t for t in cpu["g"])), flush=True)
    return images["c"], images["g"], float(np.median(times["c"])), float(np.median(times["g"])), times


def mean_rmse_over_seeds(key, ref_c, ref_g, seed1):
    """Each renderer's RMSE (Glimmer's also against its own reference) averaged over seeds 1..--noise-seeds."""
    errors = [seed1]
    for seed in range(2, opts.noise_seeds + 1):
        cyc = render_cycles("%s_cycles_seed%d" % (key, seed), seed)[0]
        glim = render_glimmer("%s_glimmer_seed%d" % (key, seed), seed)[0]
        errors.append((rmse(cyc, ref_c), rmse(glim, ref_c), rmse(glim, ref_g)))
    print("scene %s RMSE per seed (cycles, glimmer, glimmer vs own ref): %s" %
          (key, " ".join("%d: %.5f %.5f %.5f" % ((i + 1,) + e) for i, e in enumerate(errors))), flush=True)
    return tuple(float(np.mean([e[k] for e in errors])) for k in range(3))


def ladder(key, ref_c, ref_g):
    """RMSE of each renderer against its own reference per rung, and the fitted log-log slopes."""
    spp = [int(n) for n in opts.ladder.split(",")]
    errors = {"c": [], "g": []}
    for n in spp:
        BUILD[key](n)
        errors["c"].append(rmse(render_cycles("%s_cycles_%d" % (key, n), 1)[0], ref_c))
        errors["g"].append(rmse(render_glimmer("%s_glimmer_%d" % (key, n), 1)[0], ref_g))
    slope = {r: float(np.polyfit(np.log(spp), np.log(e), 1)[0]) for r, e in errors.items()}
    return "scene %s convergence vs own %d-spp reference: %s | slope cycles %.3f glimmer %.3f" % (
        key, opts.reference_samples, " ".join("%d: c %.5f g %.5f" % (n, c, g) for n, c, g in zip(spp, errors["c"], errors["g"])),
        slope["c"], slope["g"])


def image_means(key):
    """Both renderers' image means at --samples with two seeds each: the mean of the four renders per renderer,
    its standard error from the two seeds' per-pixel difference, and the ratio glimmer / cycles."""
    BUILD[key](opts.samples)
    stats = {}
    for r, render in (("c", render_cycles), ("g", render_glimmer)):
        a = render("%s_%s_s1" % (key, r), 1)[0]
        b = render("%s_%s_s2" % (key, r), 2)[0]
        mean = 0.5 * (a.mean() + b.mean())
        se = float(np.sqrt(np.sum((a - b) ** 2) / 2.0)) / a.size / np.sqrt(2.0)
        stats[r] = (float(mean), se)
    (mc, sc), (mg, sg) = stats["c"], stats["g"]
    ratio = mg / mc
    return "scene %s %dx%d 2x%d spp means: cycles %.5f +- %.5f glimmer %.5f +- %.5f ratio %.4f +- %.4f" % (
        key, opts.size, opts.size, opts.samples, mc, sc, mg, sg, ratio, ratio * np.hypot(sc / mc, sg / mg))


lines = []
for key in opts.scenes.split(","):
    if opts.means:
        lines.append(image_means(key))
        print(lines[-1], flush=True)
        continue
    BUILD[key](opts.reference_samples)
    ref_c, t_ref_c = reference(render_cycles, "%s_cycles_ref" % key)
    ref_g, t_ref_g = reference(render_glimmer, "%s_glimmer_ref" % key)
    if opts.ladder:
        lines.append(ladder(key, ref_c, ref_g))
        print(lines[-1], flush=True)
        continue
    BUILD[key](opts.samples)
    cyc, glim, t_c, t_g, all_times = interleaved(key)
    print("scene %s times (s), interleaved: cycles %s glimmer %s" %
          (key, " ".join("%.2f" % t for t in all_times["c"]), " ".join("%.2f" % t for t in all_times["g"])), flush=True)
    e_c, e_g, e_g_own = rmse(cyc, ref_c), rmse(glim, ref_c), rmse(glim, ref_g)
    if opts.noise_seeds > 1:
        e_c, e_g, e_g_own = mean_rmse_over_seeds(key, ref_c, ref_g, (e_c, e_g, e_g_own))
    # Cycles can be exactly noise-free (its white multiscatter walk in a white world): the ratio is then infinite.
    ratio = t_g / t_c * (e_g / e_c) ** 2 if e_c > 0 else float("inf")
    ratio_own = t_g / t_c * (e_g_own / e_c) ** 2 if e_c > 0 else float("inf")
    t_g_render, t_g_export = (float(np.median([p[k] for p in PHASES[key]])) for k in (0, 1))  # medians
    line = ("scene %s %dx%d %d spp: cycles %.2f s rmse %.5f | glimmer %.2f s (export %.2f s, render phase %.2f s) rmse %.5f "
            "(vs own ref %.5f) | "
            "equal-error ratio %.2f (noise only %.2f) | refs %d spp: cycles %.1f s, glimmer %.1f s, "
            "mean cycles %.4f glimmer %.4f | rmse: mean of %d seed(s)" % (
                key, opts.size, opts.size, opts.samples, t_c, e_c, t_g, t_g_export, t_g_render, e_g, e_g_own, ratio, ratio_own,
                opts.reference_samples, t_ref_c, t_ref_g, ref_c.mean(), ref_g.mean(), opts.noise_seeds))
    print(line, flush=True)
    lines.append(line)
print("\n".join(["== equal-error summary"] + lines))
