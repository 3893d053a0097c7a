#!/usr/bin/env python3
"""Compile with clang every source file that selects an instruction set itself (`make fuzz` builds with clang).

GCC's `#pragma GCC target(...)` is ignored by clang, so code that relied on it compiled with g++ (every other build)
and broke `make fuzz` (bridge/render/sampler_draw.cpp from 2026-12-02 to session 46). This check compiles, with
clang++ and the project's include folders, each .cpp under bridge/, plugin/ and shared/ that names a target
(`target("avx2")` in a pragma or an attribute) or includes a header there that does, and fails on any error.

Its negative control compiles a snippet that selects AVX2 only by GCC's pragma: clang must refuse it, or the check
could not see the defect it exists for.

usage: tools/check_clang_target_code.py [--root DIR] [--clang clang++] [--jobs N]
Exit 0: every file compiled and the control failed; 1: a file failed or the control compiled; 77: no clang++.
"""
import argparse
import concurrent.futures
import os
import re
import shutil
import subprocess
import sys
import tempfile

TARGET = re.compile(r'target\("avx2')
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
FOLDERS = ("bridge", "plugin", "shared")
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


def headers_naming_a_target(root, files):
    """Headers (by the name a quoted #include uses) that name a target, directly or through another header."""
    by_name = {}
    for path in files:
        if path.endswith(".h"):
            for d in INCLUDE_DIRS:
                prefix = os.path.join(root, d) + os.sep
                if path.startswith(prefix):
                    by_name.setdefault(path[len(prefix):], path)
    marked = {name for name, path in by_name.items() if TARGET.search(files[path])}
    changed = True
    while changed:
        changed = False
        for name, path in by_name.items():
            if name not in marked and any(inc in marked for inc in INCLUDE.findall(files[path])):
                marked.add(name)
                changed = True
    return marked


def compile_one(clang, root, path, text=None):
    args = [clang, "-std=c++20", "-O1", "-c", "-o", os.devnull, "-Wno-unknown-pragmas"]
    args += ["-I" + os.path.join(root, d) for d in INCLUDE_DIRS] + ["-isystem", "/usr/include/eigen3"]
    if text is None:
        args.append(path)
        return subprocess.run(args, capture_output=True, text=True)
    return subprocess.run(args + ["-x", "c++", "-"], input=text, capture_output=True, text=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    ap.add_argument("--clang", default="clang++")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    a = ap.parse_args()
    root = os.path.abspath(a.root)
    clang = shutil.which(a.clang)
    if not clang:
        print(f"no {a.clang}: skipped (make deps installs clang)")
        return 77
    control = compile_one(clang, root, None, CONTROL)
    if control.returncode == 0:
        print("negative control compiled: clang accepted AVX2 selected by GCC's pragma alone; the check is blind")
        return 1
    print("negative control: refused by clang, as it must be")
    files = sources(root)
    marked = headers_naming_a_target(root, files)
    units = sorted(p for p, t in files.items() if p.endswith(".cpp") and
                   (TARGET.search(t) or any(inc in marked for inc in INCLUDE.findall(t))))
    if not units:
        print("no source names a target: nothing to check")
        return 1
    failed = 0
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, a.jobs)) as pool:
        for path, r in zip(units, pool.map(lambda p: compile_one(clang, root, p), units)):
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
