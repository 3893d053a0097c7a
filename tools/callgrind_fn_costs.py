#!/usr/bin/env python3
"""Per-function instruction counts from a callgrind output file, by symbol (inlined files merged).

callgrind_annotate splits a function's cost by the source file of its inlined code; this script sums it per symbol:
self Ir, inclusive Ir (self + its calls to other functions; recursive calls not counted twice), and how often it
was called. Used for docs/history/frosted_glass_sessions.md "Twentieth session" (the cost of method=sg per camera path).

  tools/callgrind_fn_costs.py cg.out [--match REGEX ...] [--top N] [--per N_PATHS]
      [--callees FN_REGEX]   # the calls made by the first matching function: count and inclusive Ir per callee
"""
import argparse
import collections
import re
import sys


def parse(path):
    names = {}
    self_ir = collections.Counter()
    calls_ir = collections.Counter()          # (caller, callee) -> inclusive Ir of the calls
    calls_n = collections.Counter()           # (caller, callee) -> number of calls
    npos = 1
    fn = None
    cfn = None
    pending_calls = None

    def name_of(spec):
        m = re.match(r"\((\d+)\)(?:\s+(.*))?$", spec)
        if not m:
            return spec
        if m.group(2) is not None:
            names[m.group(1)] = m.group(2)
        return names.get(m.group(1), spec)

    with open(path, errors="replace") as f:
        for line in f:
            line = line.rstrip("\n")
            if not line:
                continue
            c = line[0]
            if line.startswith("positions:"):
                npos = len(line.split()[1:])
                continue
            if line.startswith("fn="):
                fn = name_of(line[3:])
                continue
            if line.startswith("cfn="):
                cfn = name_of(line[4:])
                continue
            if line.startswith("calls="):
                pending_calls = int(line[6:].split()[0])
                continue
            if c.isdigit() or c in "+-*" or line.startswith("0x"):
                fields = line.split()
                ir = int(fields[npos]) if len(fields) > npos else 0
                if pending_calls is not None:
                    calls_ir[(fn, cfn)] += ir
                    calls_n[(fn, cfn)] += pending_calls
                    pending_calls = None
                else:
                    self_ir[fn] += ir
                continue
            # fl=, fi=, fe=, cfi=, cob=, ob=, headers: not needed
    return self_ir, calls_ir, calls_n


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("file")
    ap.add_argument("--match", action="append", default=[])
    ap.add_argument("--top", type=int, default=40)
    ap.add_argument("--per", type=float, default=0.0, help="also print Ir / this (e.g. camera paths)")
    ap.add_argument("--callees", default=None)
    ap.add_argument("--callers", default=None, help="the calls into the first matching function, by caller")
    args = ap.parse_args()
    self_ir, calls_ir, calls_n = parse(args.file)
    incl = collections.Counter(self_ir)
    called = collections.Counter()
    for (a, b), ir in calls_ir.items():
        if a != b:
            incl[a] += ir
    for (a, b), n in calls_n.items():
        if a != b:
            called[b] += n
    fns = set(self_ir) | set(incl)
    if args.match:
        fns = {f for f in fns if any(re.search(m, f) for m in args.match)}
    rows = sorted(fns, key=lambda f: -incl[f])[: args.top]
    per = args.per
    print(f"{'inclusive':>14} {'self':>14} {'calls':>10}" + (f" {'incl/per':>10}" if per else "") + "  function")
    for f in rows:
        extra = f" {incl[f] / per:10.1f}" if per else ""
        print(f"{incl[f]:14,d} {self_ir[f]:14,d} {called[f]:10,d}{extra}  {f[:160]}")

    def neighbours(pattern, pool, side, title):  # the calls into (side 1) or out of (side 0) the best match
        target = next((f for f in sorted(pool, key=lambda f: -incl[f]) if re.search(pattern, f)), None)
        if target is None:
            sys.exit(f"no function matches --{title}")
        print(f"\n{title} of {target[:160]} (inclusive {incl[target]:,d}, self {self_ir[target]:,d}):")
        out = [(pair[1 - side], calls_ir[pair], calls_n[pair]) for pair in calls_ir if pair[side] == target]
        for other, ir, n in sorted(out, key=lambda x: -x[1]):
            print(f"{ir:14,d} {n:10,d}  {other[:160]}")

    if args.callees:
        neighbours(args.callees, fns | set(self_ir), 0, "callees")
    if args.callers:
        neighbours(args.callers, set(self_ir) | set(incl), 1, "callers")


if __name__ == "__main__":
    main()
