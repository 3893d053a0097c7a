#!/usr/bin/env python3
"""Compile with clang every source file that selects an instruction set itself (`make fuzz` builds with clang).

GCC's `#pragma GCC target(...)` is ignored by clang, so code that relied on it compiled with g++ (every other build)
and broke `make fuzz` (bridge/render/sampler_draw.cpp from 2026-12-02 to session 46). This check compiles, with
clang++ and the project's include folders, each .cpp under bridge/, plugin/, shared/ and fuzz/ that names a target
(`target("...")` in a pragma or an attribute: avx2, fma, arch=...) or includes, directly or through other headers, a
header that does, and fails on any error. Includes are resolved as the compiler does: beside the including file
first, then in the include folders.

Its negative control compiles a snippet that selects AVX2 only by GCC's pragma: clang must refuse it with "requires
target feature", or the check could not see the defect it exists for.

usage: tools/check_clang_target_code.py [--root DIR] [--clang clang++] [--jobs N] [--eigen-include DIR]
Exit 0: every file compiled and the control failed; 1: a file failed or the control compiled; 77: no clang++.
"""
import argparse
import concurrent.futures
import os
import re
import shutil
import subprocess
import sys

TARGET = re.compile(r'target\s*\(\s*"')
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
FOLDERS = ("bridge", "plugin", "shared", "fuzz")
INCLUDE_DIRS = ("bridge", "plugin", "shared/include")
CONTROL = """#include <immintrin.h>
#pragma GCC push_options
#pragma GCC target("avx2")
__m256i add8(__m256i a, __m256i b) { return _mm256_add_epi32(a, b); }
#pragma GCC pop_options
"""


def sources(root):
    files = {}
    for folder in FOLDERS:
        for base, _, names in os.walk(os.path.join(root, folder)):
            for name in names:
                if name.endswith((".cpp", ".h")):
                    path = os.path.join(base, name)
                    with open(path, encoding="utf-8", errors="replace") as f:
                        files[path] = f.read()
    return files


def resolve(root, path, name, files):
    """The file a quoted #include "name" in `path` names: beside `path` first, then in the include folders."""
    for folder in [os.path.dirname(path)] + [os.path.join(root, d) for d in INCLUDE_DIRS]:
        candidate = os.path.normpath(os.path.join(folder, name))
        if candidate in files:
            return candidate
    return None


def naming_a_target(root, files):
    """The files (sources and headers) that name a target, directly or through the headers they include."""
    includes = {p: [r for r in (resolve(root, p, n, files) for n in INCLUDE.findall(t)) if r] for p, t in files.items()}
    marked = {p for p, t in files.items() if TARGET.search(t)}
    changed = True
    while changed:
        changed = False
        for path, deps in includes.items():
            if path not in marked and any(d in marked for d in deps):
                marked.add(path)
                changed = True
    return marked


def compile_one(clang, root, eigen, path, text=None):
    args = [clang, "-std=c++20", "-O1", "-c", "-o", os.devnull, "-Wno-unknown-pragmas"]
    args += ["-I" + os.path.join(root, d) for d in INCLUDE_DIRS] + ["-isystem", eigen]
    if text is None:
        args.append(path)
        return subprocess.run(args, capture_output=True, text=True)
    return subprocess.run(args + ["-x", "c++", "-"], input=text, capture_output=True, text=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    ap.add_argument("--clang", default="clang++")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--eigen-include", default="/usr/include/eigen3")
    a = ap.parse_args()
    root = os.path.abspath(a.root)
    clang = shutil.which(a.clang)
    if not clang:
        print(f"no {a.clang}: skipped (make deps installs clang)")
        return 77
    control = compile_one(clang, root, a.eigen_include, None, CONTROL)
    if control.returncode == 0 or "requires target feature" not in control.stderr:
        print("negative control not refused for its target: clang accepted AVX2 selected by GCC's pragma alone,"
              " or failed for another reason; the check is blind\n" + control.stderr[:500])
        return 1
    print("negative control: refused by clang, as it must be")
    files = sources(root)
    units = sorted(p for p in naming_a_target(root, files) if p.endswith(".cpp"))
    if not units:
        print("no source names a target: nothing to check")
        return 1
    failed = 0
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, a.jobs)) as pool:
        for path, r in zip(units, pool.map(lambda p: compile_one(clang, root, a.eigen_include, p), units)):
            rel = os.path.relpath(path, root)
            if r.returncode == 0:
                print(f"ok     {rel}")
            else:
                failed += 1
                errors = [line for line in r.stderr.splitlines() if "error:" in line]
                print(f"FAILED {rel}: {len(errors)} errors, first: {errors[0] if errors else r.stderr[:300]}")
    print(f"{len(units) - failed} of {len(units)} files compile with {clang}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
