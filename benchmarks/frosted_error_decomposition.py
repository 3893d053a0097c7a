#!/usr/bin/python3
"""Splits frosted_glass sg's error in a scene into bias and noise per region
(docs/history/frosted_glass_sessions.md, "Where sg's error comes from"): renders a `path` reference at many
samples, `sg` variants at fewer samples on two seeds each,
and an id render that marks which pixels show which frosted object; then, per region and variant,

    noise^2 = mean((a - b)^2) / 2                      (one render's per-pixel variance)
    bias^2  = mean(((a + b) / 2 - ref)^2) - noise^2 / 2 - ref_noise^2

(ref_noise^2: the reference's own variance, path's two-seed variance at the variants' samples scaled to the
reference's), all relative to the region's reference mean.

    python3 benchmarks/frosted_error_decomposition.py examples/frosted_closeup.xml --glimmer build/bridge/glimmer \
        --width 96 --height 60 --samples 1024 --reference-samples 4096 --out-dir /tmp/decomp

Variants: every frosted_glass_bsdf as `sg`, and each frosted shader alone as `sg` (the others `path`), so a
region's bias can be told apart from light that reached it through another object.

--per-light (issue 12, seventh session) adds, for each light source alone (each <light> with a black world, and the
world without lamps), a `path` reference and two `sg` seeds, and prints each region's sg bias / offset per source
and its absolute offset (the share of the full scene's offset that source carries). --no-clamp renders every
variant with sample_clamp_indirect=0 (the estimators' own expectations; the clamp changes sg's and path's images
differently, docs/frosted_glass.md "Lamps through the exit lobe").
"""
import argparse
import os
import re
import subprocess

import numpy as np


def set_method(text, method, shader=None):
    """The scene with frosted_glass_bsdf's method set (in one <shader name=...> only when shader is given)."""
    def rewrite(block):
        block = re.sub(r'(<frosted_glass_bsdf\b[^>]*?)\s+method="[^"]*"', r"\1", block)
        return re.sub(r"<frosted_glass_bsdf\b", '<frosted_glass_bsdf method="%s"' % method, block)
    if shader is None:
        return rewrite(text)
    return re.sub(r'(<shader name="%s">.*?</shader>)' % re.escape(shader), lambda m: rewrite(m.group(1)), text,
                  flags=re.S)


def id_scene(text, shaders):
    """Each frosted shader an emitter of its own colour channel, everything else black, no lamps."""
    text = re.sub(r"<light\b[^>]*/>", "", text)
    text = re.sub(r'<background name="[^"]*"[^>]*/>', '<background name="sky" color="0 0 0" strength="0" />', text)
    for k, name in enumerate(shaders):
        colour = ["0", "0", "0"]
        colour[k % 3] = "1"
        text = re.sub(r'<shader name="%s">.*?</shader>' % re.escape(name),
                      '<shader name="%s"><emission name="id" color="%s" strength="1" />'
                      '<connect from="id emission" to="output surface" /></shader>' % (name, " ".join(colour)),
                      text, flags=re.S)
    text = re.sub(r'<shader name="(floor)">.*?</shader>',
                  r'<shader name="\1"><diffuse_bsdf name="d" color="0 0 0" />'
                  r'<connect from="d bsdf" to="output surface" /></shader>', text, flags=re.S)
    return text


def light_sources(text):
    """(name, scene) for each <light> alone with a black world, and the world alone without lamps."""
    lights = re.findall(r"<light\b[^>]*/>", text)
    out = []
    for k, light in enumerate(lights):
        t = text
        for other in lights:
            if other is not light:
                t = t.replace(other, "", 1)
        t = re.sub(r'<background name="([^"]*)"[^>]*/>', r'<background name="\1" color="0 0 0" strength="0" />', t)
        out.append(("light%d" % k, t))
    out.append(("world", re.sub(r"<light\b[^>]*/>", "", text)))
    return out


def split_line(region, mask, ref, ref_var_pixel, results):
    """noise / bias / offset per variant for one region (relative to its reference mean)."""
    rmean = ref[mask].mean()
    ref_var = ref_var_pixel[mask].mean()
    line = "%-16s %5d  ref mean %.4f" % (region, int(mask.sum()), rmean)
    for name, (a, b) in results.items():
        var = 0.5 * ((a - b)[mask] ** 2).mean()
        m2 = (((a + b) / 2 - ref)[mask] ** 2).mean()
        bias = np.sqrt(max(0.0, m2 - 0.5 * var - ref_var))
        offset = ((a + b) / 2)[mask].mean() / rmean - 1.0
        line += " | %s %.4f / %.4f / %+.4f" % (name, np.sqrt(var) / rmean, bias / rmean, offset)
    return line


def read_combined(exr, width, height):
    """The Combined RGB of a glimmer EXR as an array (height, width, 3), read through `oiiotool --dumpdata`."""
    out = subprocess.run(["oiiotool", "--dumpdata", exr], check=True, capture_output=True, text=True).stdout
    header = re.search(r"channel list: (.*)", subprocess.run(["oiiotool", "--info", "-v", exr], check=True,
                                                             capture_output=True, text=True).stdout).group(1)
    names = [c.strip() for c in header.split(",")]
    idx = [names.index("ViewLayer.Combined." + c) for c in "RGB"]
    img = np.zeros((height, width, 3))
    for m in re.finditer(r"Pixel \((\d+), (\d+)\): (.*)", out):
        v = m.group(3).split()
        img[int(m.group(2)), int(m.group(1))] = [float(v[i]) for i in idx]
    return img


def render(args, scene_text, name, samples, seed):
    xml = os.path.join(args.out_dir, name + ".xml")
    exr = os.path.join(args.out_dir, "%s_%d_%d.exr" % (name, samples, seed))
    if not os.path.exists(exr):
        with open(xml, "w") as f:
            f.write(scene_text)
        subprocess.run([args.glimmer, "render", xml, "-o", exr, "--samples", str(samples), "--seed", str(seed),
                        "--width", str(args.width), "--height", str(args.height), "--threads", str(args.threads),
                        "--quiet"], check=True)
    img = read_combined(exr, args.width, args.height)
    return img if name == "ids" else img.mean(axis=2)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("--glimmer", default="build/bridge/glimmer")
    ap.add_argument("--width", type=int, default=96)
    ap.add_argument("--height", type=int, default=60)
    ap.add_argument("--samples", type=int, default=1024)
    ap.add_argument("--reference-samples", type=int, default=4096)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--out-dir", required=True)
    ap.add_argument("--per-light", action="store_true", help="also split the sg bias by light source")
    ap.add_argument("--no-clamp", action="store_true", help="sample_clamp_indirect=0 in every variant")
    args = ap.parse_args()
    os.makedirs(args.out_dir, exist_ok=True)
    with open(args.scene) as f:
        text = f.read()
    # The scene's relative mesh paths resolve against its folder: write the variants there via absolute paths.
    folder = os.path.dirname(os.path.abspath(args.scene))
    text = re.sub(r'src="([^"/][^"]*)"', lambda m: 'src="%s"' % os.path.join(folder, m.group(1)), text)
    if args.no_clamp:
        text = re.sub(r'sample_clamp_indirect="[^"]*"', 'sample_clamp_indirect="0"', text)
    shaders = [m.group(1) for m in re.finditer(r'<shader name="([^"]+)">(?:(?!</shader>).)*<frosted_glass_bsdf',
                                                text, flags=re.S)]
    ids_rgb = render(args, id_scene(text, shaders), "ids", 16, 1)
    regions = {name: ids_rgb[:, :, k % 3] > 0.99 for k, name in enumerate(shaders)}
    regions["rest"] = ~np.logical_or.reduce([m for m in regions.values()])
    regions["all"] = np.ones_like(regions["rest"])

    path_text = set_method(text, "path")
    ref = render(args, path_text, "path", args.reference_samples, 101)
    p1, p2 = render(args, path_text, "path", args.samples, 1), render(args, path_text, "path", args.samples, 2)
    variants = [("path", path_text), ("sg", set_method(text, "sg"))]
    variants += [("sg_only_" + s, set_method(path_text, "sg", s)) for s in shaders]
    print("region pixels; per variant: noise / bias / mean offset, relative to the region's reference mean "
          "(%d spp vs path at %d spp, %dx%d)" % (args.samples, args.reference_samples, args.width, args.height))
    ref_var_pixel = 0.5 * (p1 - p2) ** 2 * args.samples / args.reference_samples
    results = {}
    for name, vtext in variants:
        a, b = (p1, p2) if name == "path" else (render(args, vtext, name, args.samples, 1),
                                                 render(args, vtext, name, args.samples, 2))
        results[name] = (a, b)
    for region, mask in regions.items():
        if mask.any():
            print(split_line(region, mask, ref, ref_var_pixel, results))
    if not args.per_light:
        return
    print("per light source: sg (every frosted shader) vs path, noise / bias / offset relative to the source's own "
          "reference mean; abs = the source's absolute offset")
    for source, stext in light_sources(text):
        sref = render(args, set_method(stext, "path"), source + "_path", args.reference_samples, 101)
        s1 = render(args, set_method(stext, "path"), source + "_path", args.samples, 1)
        s2 = render(args, set_method(stext, "path"), source + "_path", args.samples, 2)
        g1 = render(args, set_method(stext, "sg"), source + "_sg", args.samples, 1)
        g2 = render(args, set_method(stext, "sg"), source + "_sg", args.samples, 2)
        svar = 0.5 * (s1 - s2) ** 2 * args.samples / args.reference_samples
        for region, mask in regions.items():
            if mask.any():
                absolute = ((g1 + g2) / 2 - sref)[mask].mean()
                print("%-7s %s abs %+.4f" % (source, split_line(region, mask, sref, svar, {"sg": (g1, g2)}), absolute))

if __name__ == "__main__":
    main()
