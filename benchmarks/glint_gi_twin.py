#!/usr/bin/env python3
"""The GGX twin of a glint scene, made as glint/gi_scene_overhead makes it (benchmarks/bench_glint.cpp): every
glint_bsdf becomes a glossy_bsdf GGX of the same roughness, the glint-only attributes dropped.
usage: glint_gi_twin.py <scene.xml> <twin.xml>  (write the twin beside the scene: relative paths resolve the same)"""
import re
import sys

text = open(sys.argv[1]).read()
text = re.sub(r'<glint_bsdf([^>]*?)distribution="[a-z]+"', r'<glint_bsdf\1distribution="ggx"', text)
text = re.sub(r' (gamma|density|uv_scale|seed|filter_threshold)="[^"]*"', '', text)
text = text.replace('<glint_bsdf', '<glossy_bsdf')
open(sys.argv[2], 'w').write(text)
