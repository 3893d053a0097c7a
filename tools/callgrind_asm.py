#!/usr/bin/env python3
"""Per-instruction self costs of a callgrind profile (--dump-instr=yes) beside the
disassembly of one function of a shared object, for line profiles of the glint
eval (issue 10). usage:
  tools/callgrind_asm.py <callgrind.out> <lib.so> <function substring> [divisor]
Prints every instruction of the matching function (objdump -d -l, demangled)
with its self cost divided by `divisor` (e.g. the number of evals)."""
import re, subprocess, sys
from collections import defaultdict

def parse(path):
    names = {}
    cost = defaultdict(int)  # (ob, fn, addr) -> self Ir
    ob = fn = None
    addr = 0
    skip_next = False
    def name(kind, s):
        m = re.match(r'\((\d+)\)(?: (.*))?', s)
        if not m:
            return s
        key = (kind, m.group(1))
        if m.group(2):
            names[key] = m.group(2)
        return names.get(key, s)
    for line in open(path):
        line = line.rstrip('\n')
        if line.startswith('ob='):
            ob = name('ob', line[3:])
        elif line.startswith('fn='):
            fn = name('fn', line[3:])
        elif line.startswith('cob='):
            name('ob', line[4:])
        elif line.startswith(('cfi=', 'cfl=')):
            name('fl', line[4:])
        elif line.startswith('cfn='):
            name('fn', line[4:])
        elif line.startswith(('fl=', 'fi=', 'fe=')):
            name('fl', line[3:])
        elif line.startswith('calls='):
            skip_next = True
        elif line and (line[0] in '+-*' or line.startswith('0x')):
            parts = line.split()
            a = parts[0]
            if a.startswith('0x'):
                addr = int(a, 16)
            elif a[0] == '+':
                addr += int(a[1:], 16) if a[1:].startswith('0x') else int(a[1:])
            elif a[0] == '-':
                addr -= int(a[1:], 16) if a[1:].startswith('0x') else int(a[1:])
            if skip_next:
                skip_next = False
                continue
            if len(parts) >= 3:
                cost[(ob, fn, addr)] += int(parts[2])
    return cost

def main():
    out, lib, pat = sys.argv[1], sys.argv[2], sys.argv[3]
    div = float(sys.argv[4]) if len(sys.argv) > 4 else 1.0
    cost = parse(out)
    # Summed per address: a function with a [clone .cold] part is listed under several fn entries (callgrind's
    # cold'2 contexts), each with its own cost lines for the same addresses (session 36: kept only one before).
    mine, fns = {}, set()
    for (ob, fn, a), c in cost.items():
        if ob and ob.endswith(lib.split('/')[-1]) and pat in fn:
            mine[a] = mine.get(a, 0) + c
            fns.add(fn)
    if not mine:
        sys.exit('no costs for ' + pat)
    fns = sorted(fns)
    # symbol offset of the function in the .so
    syms = subprocess.run(['nm', '-C', '--defined-only', lib], capture_output=True, text=True).stdout
    lo = min(mine)
    # find load base: the symbol whose demangled name matches and whose offset aligns
    cands = []
    for l in syms.splitlines():
        p = l.split(' ', 2)
        if len(p) == 3 and pat in p[2]:
            cands.append((int(p[0], 16), p[2]))
    base = None
    for off, nm in cands:
        if (lo - off) % 0x1000 == 0:
            base = lo - off
            start_name = nm
            break
    if base is None:
        sys.exit('cannot find base; candidates %s' % cands[:5])
    offs = sorted(a - base for a in mine)
    dis = subprocess.run(['objdump', '-d', '-C', '-l', '--no-show-raw-insn',
                          '--start-address=0x%x' % offs[0], '--stop-address=0x%x' % (offs[-1] + 16), lib],
                         capture_output=True, text=True).stdout
    total = 0
    for l in dis.splitlines():
        m = re.match(r'\s+([0-9a-f]+):\s+(.*)', l)
        if m:
            a = int(m.group(1), 16) + base
            c = mine.get(a, 0)
            total += c
            print('%9.1f  %s' % (c / div, l.strip()) if c else '%9s  %s' % ('', l.strip()))
        else:
            print('           ' + l)
    print('total %.1f (%s)' % (total / div, ', '.join(fns)), file=sys.stderr)

main()
