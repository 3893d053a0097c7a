#!/usr/bin/env python3
"""Sums a tools/callgrind_asm.py listing (per-instruction self costs of one function, objdump -d -l of a -g build)
by the innermost inlined function and by source line, for the fixed-part breakdowns of docs/history/glints_sessions.md
(session 22).
usage:
  tools/callgrind_asm.py cg.out lib.so provably_dark 8192 > asm.txt
  tools/callgrind_asm_summary.py asm.txt [top N]"""
import collections
import re
import sys


def main():
    fn_cost = collections.Counter()
    line_cost = collections.Counter()
    cur_fn, cur_line = '?', '?'
    for raw in open(sys.argv[1]):
        s = raw.rstrip('\n')
        m = re.match(r'^\s*([0-9.]+)\s+[0-9a-f]+:\s', s)
        if m:
            c = float(m.group(1))
            fn_cost[cur_fn] += c
            line_cost[cur_line] += c
            continue
        t = s.strip()
        if t.startswith('total'):
            print(t)
        elif re.match(r'^/.*:\d+', t):
            t = re.sub(r'\s*\(discriminator \d+\)', '', t)
            cur_line = re.sub(r'^.*?/((plugin|shared|host|src)/)', r'\1', t)
        elif t.endswith(':') and '(' in t:
            cur_fn = re.sub(r'\(.*', '', t)[:110]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 40
    print('-- by inlined function')
    for k, v in fn_cost.most_common(n):
        print(f'{v:8.1f}  {k}')
    print('-- by source line')
    for k, v in line_cost.most_common(n):
        print(f'{v:8.1f}  {k}')


if __name__ == '__main__':
    main()
