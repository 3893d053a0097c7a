#!/usr/bin/env python3
"""Estimate for docs/history/glints_sessions.md "Session 21 (glintdark21)": the walk's node list as the footprint's
bounding box of
particle nodes (no rasteriser) when the box holds <= T nodes. A node outside the footprint adds no particle (the
membership test is exact), so the counts are the same. Cost model of benchmarks/glint_dark_sim.cpp: 0.624 (walks
not in the node-list memo) x (150 per rasterised list + 190 per row) saved; per extra node a 4-lane hash (27 or 15),
its passing pairs (40 each) and positions (20 or 40 each); the box's own row fill is not counted.
usage: benchmarks/glint_box_path_estimate.py <walk log of benchmarks/glint_dark_walks.patch>
"""
import sys, math
walks=[]
for line in open(sys.argv[1]):
    f=line.split()
    if f[0]!='W': continue
    lvl=int(f[3]); P=float(f[4]); gd=float(f[5]); n=int(f[12])
    if n<=0: continue
    ij=list(map(int,f[16:16+2*n])); I=ij[0::2]; J=ij[1::2]
    lam=gd*(2.0**-lvl)**2*min(P,1.0)
    walks.append((n,(max(I)-min(I)+1)*(max(J)-min(J)+1),len(set(J)),lam))
memo=0.624
for hash4,pos in ((27,20),(15,40)):
    base=sum(memo*((150+190*r) if (b>4) else 0)+hash4*n for n,b,r,l in walks)
    print(f"costs hash4 {hash4} pos {pos}: mean list nodes {sum(w[0] for w in walks)/len(walks):.2f}, bbox nodes {sum(w[1] for w in walks)/len(walks):.2f}")
    for T in (4,6,8,9,12,16,24,32):
        tot=0
        for n,b,r,l in walks:
            if b<=T: tot+=hash4*b + (b-n)*4*min(l,1.0)*(40) + (b-n)*4*l*pos  # extra nodes: hashes, passing pairs, positions
            else: tot+=memo*((150+190*r) if b>4 else 0)+hash4*n
        print(f"  box up to {T:2d} nodes: {(tot-base)/len(walks):+7.1f} per walk, {(tot-base)/1e6:+6.2f} M")
