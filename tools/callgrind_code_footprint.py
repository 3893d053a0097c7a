#!/usr/bin/env python3
"""The hot code footprint of a callgrind profile (--dump-instr=yes; best with --cache-sim=yes for the I1 misses), per
object and per function: how many 64-byte instruction-cache lines the executed code touches, how much of those lines
is executed code (density; the rest is cold code or padding sharing the line) and how much is padding (nop). For the
instruction-cache question of issue 10 (docs/history/glints_sessions.md, "Session 31 (glintlayout31)"): a hot set far
larger than the
32 KB L1i that is already dense can only shrink by running less code, not by moving it.

  tools/callgrind_code_footprint.py cg.out [--min-ir N] [--top N] [--match REGEX]
      --min-ir N   an instruction is hot when executed at least N times (default 1000)
      --top N      the N functions with the most I1 misses (default 25)
      --match RE   only objects whose path matches RE (default: all with hot code)

Instruction sizes come from `objdump -d` of each object at the path callgrind recorded (build the same tree).
"""
import argparse
import collections
import re
import subprocess
import sys

EVENT_NAMES = ('Ir', 'I1mr')


def position(token, cur):
    if token == '*':
        return cur
    if token[0] in '+-':
        return cur + int(token)
    return int(token, 16)


def parse(path):
    """(object, address) -> [Ir, I1mr] self costs, and (object, address) -> function name."""
    names, cost, fn_of = {}, collections.defaultdict(lambda: [0, 0]), {}
    ob = fn = None
    cur, skip, index = 0, False, {}
    for line in open(path):
        if line.startswith('events:'):
            events = line.split()[1:]
            index = {e: events.index(e) for e in EVENT_NAMES if e in events}
            continue
        if line[0] in '0123456789+-*':
            tokens = line.split()
            cur = position(tokens[0], cur)
            if skip:  # the inclusive cost of a call, not this instruction's own
                skip = False
                continue
            values = tokens[2:]  # positions: instr line
            entry = cost[(ob, cur)]
            for k, e in enumerate(EVENT_NAMES):
                i = index.get(e)
                if i is not None and i < len(values):
                    entry[k] += int(values[i])
            fn_of[(ob, cur)] = fn
            continue
        if line.startswith('calls='):
            skip = True
            continue
        m = re.match(r'(ob|fn|cob|cfn|cfi|cfl|fl|fi|fe)=\((\d+)\)(?: (.*))?', line)
        if not m:
            continue
        kind = 'ob' if m.group(1) in ('ob', 'cob') else 'fn' if m.group(1) in ('fn', 'cfn') else 'fl'
        if m.group(3):
            names[(kind, m.group(2))] = m.group(3).strip()
        if m.group(1) == 'ob':
            ob = names.get((kind, m.group(2)))
        elif m.group(1) == 'fn':
            fn = names.get((kind, m.group(2)))
    return cost, fn_of


def instructions(path):
    """address -> (size in bytes, is padding) of every instruction objdump lists in `path`."""
    out = subprocess.run(['objdump', '-d', '--no-show-raw-insn', path], capture_output=True, text=True).stdout
    rows = []
    for line in out.split('\n'):
        m = re.match(r'\s+([0-9a-f]+):\s+(\S+)', line)
        if m:
            rows.append((int(m.group(1), 16), m.group(2)))
    info = {}
    for (a, op), (b, _) in zip(rows, rows[1:]):
        info[a] = (min(b - a, 15), op.startswith('nop') or op in ('int3', 'data16', 'cs', 'xchg'))
    return info, rows


class Footprint:
    def __init__(self):
        self.ir = self.i1mr = self.hot_bytes = 0
        self.lines = set()


def summarise(cost, fn_of, min_ir, match):
    objects, functions, sizes = collections.defaultdict(Footprint), collections.defaultdict(Footprint), {}
    for (ob, addr), (ir, i1mr) in cost.items():
        if ob is None or (match and not re.search(match, ob)):
            continue
        for fp in (objects[ob], functions[(ob, fn_of[(ob, addr)])]):
            fp.ir += ir
            fp.i1mr += i1mr
        if ir < min_ir:
            continue
        if ob not in sizes:
            try:
                sizes[ob] = instructions(ob)
            except OSError:
                sizes[ob] = ({}, [])
        size = sizes[ob][0].get(addr, (4, False))[0]
        for fp in (objects[ob], functions[(ob, fn_of[(ob, addr)])]):
            fp.hot_bytes += size
            fp.lines.add(addr // 64)
    return objects, functions, sizes


def padding_in(lines, rows):
    total = pad = 0
    for (a, op), (b, _) in zip(rows, rows[1:]):
        if a // 64 in lines:
            total += min(b - a, 15)
            pad += min(b - a, 15) if (op.startswith('nop') or op in ('int3', 'data16', 'cs', 'xchg')) else 0
    return pad / total if total else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('file')
    ap.add_argument('--min-ir', type=int, default=1000)
    ap.add_argument('--top', type=int, default=25)
    ap.add_argument('--match', default='')
    args = ap.parse_args()
    cost, fn_of = parse(args.file)
    objects, functions, sizes = summarise(cost, fn_of, args.min_ir, args.match)
    print(f'hot: executed >= {args.min_ir} times; lines: 64-byte lines holding hot code; density: hot bytes / '
          'line bytes; pad: nop/int3 bytes in those lines')
    print(f'{"Ir M":>9} {"I1mr M":>8} {"lines":>6} {"KB":>6} {"density":>7} {"pad":>5}  object')
    for ob, fp in sorted(objects.items(), key=lambda kv: -kv[1].i1mr):
        if not fp.lines:
            continue
        pad = padding_in(fp.lines, sizes.get(ob, ({}, []))[1])
        print(f'{fp.ir / 1e6:9.2f} {fp.i1mr / 1e6:8.3f} {len(fp.lines):6d} {len(fp.lines) * 64 / 1024:6.1f} '
              f'{fp.hot_bytes / (64 * len(fp.lines)):7.2f} {100 * pad:4.1f}%  {ob}')
    print(f'\n{"Ir M":>9} {"I1mr M":>8} {"lines":>6} {"density":>7}  function (top {args.top} by I1 misses)')
    ranked = sorted(functions.items(), key=lambda kv: -kv[1].i1mr)[:args.top]
    for (ob, fn), fp in ranked:
        density = fp.hot_bytes / (64 * len(fp.lines)) if fp.lines else 0.0
        print(f'{fp.ir / 1e6:9.2f} {fp.i1mr / 1e6:8.3f} {len(fp.lines):6d} {density:7.2f}  {(fn or "?")[:100]}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
