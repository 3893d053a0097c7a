#!/usr/bin/env python3
"""Compares two builds of a shared object function by function (objdump -d -C, addresses and RIP offsets masked),
to show that a refactor keeps every function's instructions (issue 10, session 22). usage:
  tools/compare_functions.py <a.so> <b.so> [--diff]
Prints the functions whose instructions differ (with their instruction counts), those only in one build, and
with --diff a unified diff of each differing function."""
import difflib
import re
import subprocess
import sys


def functions(path):
    out = subprocess.run(['objdump', '-d', '--no-show-raw-insn', '-C', path], capture_output=True, text=True).stdout
    fns, cur = {}, None
    for line in out.splitlines():
        m = re.match(r'^[0-9a-f]+ <(.*)>:$', line)
        if m:
            cur = m.group(1)
            fns[cur] = []
            continue
        if cur and '\t' in line:
            ins = line.split('\t')[-1].strip()
            ins = re.sub(r'[0-9a-f]{4,} <[^>]*>', 'ADDR', ins)
            ins = re.sub(r'0x[0-9a-f]+\(%rip\)', 'RIP', ins)
            ins = re.sub(r'#.*', '', ins).strip()
            fns[cur].append(ins)
    return fns


def main():
    args = [a for a in sys.argv[1:] if a != '--diff']
    if len(args) != 2:
        sys.exit(__doc__)
    a, b = functions(args[0]), functions(args[1])
    differing = 0
    for name in sorted(set(a) | set(b)):
        if name not in a or name not in b:
            print('ONLY', 'a' if name in a else 'b', name[:160])
        elif a[name] != b[name]:
            differing += 1
            print('DIFF', name[:160], len(a[name]), len(b[name]))
            if '--diff' in sys.argv:
                for line in difflib.unified_diff(a[name], b[name], lineterm='', n=1):
                    print('   ', line)
    print('functions differing:', differing)


main()
