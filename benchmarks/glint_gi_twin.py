#!/usr/bin/env python3
"""The GGX twin of a glint scene, made as glint/gi_scene_overhead makes it (benchmarks/bench_glint.cpp): every
glint_bsdf becomes a glossy_bsdf GGX of the same roughness, the glint-only attributes dropped. With
--same-distribution each glossy_bsdf keeps its glint's distribution (examples/glint.xml's floor glint is Beckmann:
that twin separates what the glint costs from what its base distribution costs over GGX).
usage: glint_gi_twin.py [--same-distribution] <scene.xml> <twin.xml>  (write the twin beside the scene: relative
paths resolve the same)"""
import re
import sys

args = sys.argv[1:]
same = args[:1] == ['--same-distribution']
if same:
    args = args[1:]
text = open(args[0]).read()
if not same:
    text = re.sub(r'<glint_bsdf([^>]*?)distribution="[a-z]+"', r'<glint_bsdf\1distribution="ggx"', text)
text = re.sub(r' (gamma|density|uv_scale|seed|filter_threshold)="[^"]*"', '', text)
text = text.replace('<glint_bsdf', '<glossy_bsdf')
open(args[1], 'w').write(text)
