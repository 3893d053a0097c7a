#!/usr/bin/env python3
"""Self instructions of one function of a callgrind profile, split by the inlined functions they came from.

Session 35 (glintwalk35). callgrind_annotate gives a noinline function's self cost as one figure; with
`--dump-instr=yes` the profile has it per instruction address, and addr2line -i on a -g build of the same code
names the inline chain of each address. Each address's cost goes to the outermost chain entry whose name is in
--passes (else the function itself), with the innermost entry in --parts as a second key.

usage: tools/callgrind_inlined_self.py <callgrind.out> <binary.so built with -g> <function substring>
                                       [--evals N] [--passes a,b,...] [--parts c,d,...]
Profile: valgrind --tool=callgrind --dump-instr=yes ... (benchmarks/glint_eval_instructions.sh's command with
--dump-instr=yes; the .so must be the -g build that ran, e.g. cmake -DCMAKE_CXX_FLAGS=-g into another build dir).
"""
import argparse, collections, re, subprocess

def self_cost_by_address(path, pattern):
    names, cost, last = {}, collections.Counter(), [0, 0]
    in_fn, skip = False, False
    def pos(tok, i):
        if tok == '*':
            return last[i]
        if tok[0] in '+-':
            v = int(tok[1:], 0)
            return last[i] + (v if tok[0] == '+' else -v)
        return int(tok, 0)
    with open(path) as f:
        for line in f:
            line = line.rstrip('\n')
            if not line:
                continue
            m = re.match(r'(c?fn)=\((\d+)\)(?: (.*))?', line)
            if m:
                if m.group(3):
                    names[m.group(2)] = m.group(3)
                if m.group(1) == 'fn':
                    in_fn = pattern in names.get(m.group(2), '')
                continue
            if line.startswith('calls='):
                skip = True  # the next cost line is the call's inclusive cost
                continue
            if line[0].isdigit() or line[0] in '+-*':
                toks = line.split()
                last[0] = pos(toks[0], 0)
                if len(toks) > 2 and re.match(r'^[-+*0-9]', toks[1]):
                    last[1] = pos(toks[1], 1)
                if skip:
                    skip = False
                    continue
                if in_fn:
                    cost[last[0]] += int(toks[-1])
    return cost

def inline_chains(binary, addresses):
    out = subprocess.run(['addr2line', '-i', '-f', '-C', '-a', '-e', binary] + [hex(a) for a in addresses],
                         capture_output=True, text=True, check=True).stdout.split('\n')
    chains, cur, i = {}, None, 0
    while i < len(out):
        if out[i].startswith('0x'):
            cur = int(out[i], 16)
            chains[cur] = []
            i += 1
        elif out[i]:
            chains[cur].append(re.sub(r'\(.*', '', out[i]).split('::')[-1].split('<')[0])
            i += 2
        else:
            i += 1
    return chains

def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('profile'); ap.add_argument('binary'); ap.add_argument('function')
    ap.add_argument('--evals', type=float, default=8192.0)
    ap.add_argument('--passes', default='paired_node_origins_avx2,tabled_node_origins_avx2,tabled_layer_bytes_avx2,'
                    'bounds_pairs_pass,lit_pairs_pass,tabled_layers_pass,FootprintFrame,PairPassCounter')
    ap.add_argument('--parts', default='list_pairs_avx2,flush_for,add_lit,add_listed,LitBoundHashes,LitCountBounds,'
                    'lit_count_at,walk_on,tabled_origins_chunk_avx2')
    a = ap.parse_args()
    cost = self_cost_by_address(a.profile, a.function)
    chains = inline_chains(a.binary, sorted(cost))
    passes, parts = a.passes.split(','), a.parts.split(',')
    agg = collections.Counter()
    for addr, c in cost.items():
        ch = chains.get(addr, [])
        p = next((n for n in reversed(ch) if n in passes), a.function)
        s = next((n for n in ch if n in parts), '')
        agg[(p, s)] += c
    total = sum(cost.values())
    print(f'{total:>10} {total / a.evals:8.1f}  total self of *{a.function}*')
    for (p, s), c in agg.most_common():
        print(f'{c:>10} {c / a.evals:8.1f}  {p} {s}')

if __name__ == '__main__':
    main()
