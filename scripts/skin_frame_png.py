#!/usr/bin/env python3
# Looks at a skinned export by eye (issue 16): renders frame F of the exact animation (.pc2,
# left, grey) and of the skinned .glb evaluated as a viewer does it (joint TRS x inverse bind
# matrix, blended by JOINTS_0/WEIGHTS_0; right, blue shading to red at >= 15 mm error) into
# one PNG with a tiny z-buffer rasteriser (front view, no dependencies beyond Python 3).
#   scripts/skin_frame_png.py EXACT.pc2 SKIN.glb FRAME OUT.png
import struct, json, sys, zlib, math
pc2, glb, frame, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
d = open(pc2, 'rb').read()
nv = struct.unpack_from('<i', d, 16)[0]
exact = struct.unpack_from('<%df' % (nv * 3), d, 32 + frame * nv * 12)
g = open(glb, 'rb').read()
jl = struct.unpack_from('<I', g, 12)[0]
J = json.loads(g[20:20 + jl]); bin_ = g[20 + jl + 8:]
def acc(i, fmt, comps):
    a = J['accessors'][i]; v = J['bufferViews'][a['bufferView']]
    off = v.get('byteOffset', 0) + a.get('byteOffset', 0); n = a['count'] * comps
    return struct.unpack_from('<%d%s' % (n, fmt), bin_, off)
prim = J['meshes'][0]['primitives'][0]; at = prim['attributes']
P = acc(at['POSITION'], 'f', 3); F = acc(prim['indices'], 'I', 1)
JO = acc(at['JOINTS_0'], 'B', 4); WE = acc(at['WEIGHTS_0'], 'f', 4)
skin = J['skins'][0]; joints = skin['joints']; nb = len(joints)
IBM = acc(skin['inverseBindMatrices'], 'f', 16)
an = J['animations'][0]; T = {}; Q = {}
for ch in an['channels']:
    s = an['samplers'][ch['sampler']]; node = ch['target']['node']; j = joints.index(node)
    if ch['target']['path'] == 'translation': T[j] = acc(s['output'], 'f', 3)[3 * frame:3 * frame + 3]
    else: Q[j] = acc(s['output'], 'f', 4)[4 * frame:4 * frame + 4]
M = []
for j in range(nb):
    x, y, z, w = Q[j]
    R = [[1-2*(y*y+z*z), 2*(x*y-z*w), 2*(x*z+y*w)], [2*(x*y+z*w), 1-2*(x*x+z*z), 2*(y*z-x*w)], [2*(x*z-y*w), 2*(y*z+x*w), 1-2*(x*x+y*y)]]
    I = IBM[16 * j:16 * j + 16]
    M.append([[sum(R[r][q] * I[4 * c + q] for q in range(3)) + (T[j][r] if c == 3 else 0) for c in range(4)] for r in range(3)])
sk = []
for i in range(nv):
    p = P[3*i:3*i+3]; v = [0, 0, 0]
    for s in range(4):
        w = WE[4*i+s]
        if w == 0: continue
        m = M[JO[4*i+s]]
        for r in range(3): v[r] += w * (m[r][0]*p[0] + m[r][1]*p[1] + m[r][2]*p[2] + m[r][3])
    sk.extend(v)
err = [math.dist(sk[3*i:3*i+3], exact[3*i:3*i+3]) for i in range(nv)]
print('frame %d: max %.2f mm, rms %.2f mm' % (frame, max(err)*1e3, math.sqrt(sum(e*e for e in err)/nv)*1e3))
W, H = 420, 520
xs = exact[0::3] + tuple(sk[0::3]); ys = exact[1::3] + tuple(sk[1::3])
x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys); sc = min((W-20)/(x1-x0), (H-20)/(y1-y0))
def draw(V, color_err):
    img = [[(255, 255, 255)] * W for _ in range(H)]; zb = [[-1e9] * W for _ in range(H)]
    for t in range(0, len(F), 3):
        a, b, c = F[t], F[t+1], F[t+2]
        A = V[3*a:3*a+3]; B = V[3*b:3*b+3]; C = V[3*c:3*c+3]
        u = [B[k]-A[k] for k in range(3)]; v = [C[k]-A[k] for k in range(3)]
        n = [u[1]*v[2]-u[2]*v[1], u[2]*v[0]-u[0]*v[2], u[0]*v[1]-u[1]*v[0]]; ln = math.sqrt(sum(q*q for q in n)) or 1
        sh = abs(n[2]/ln)*0.8 + 0.2
        if color_err:
            e = min(1, (err[a]+err[b]+err[c])/3/0.015); col = (int(255*sh*(0.5+0.5*e)), int(255*sh*(1-e)*0.8+40*e), int(255*sh*(1-e)))
        else: col = (int(200*sh), int(200*sh), int(220*sh))
        pts = [((X[0]-x0)*sc+10, H-((X[1]-y0)*sc+10), X[2]) for X in (A, B, C)]
        mnx = max(0, int(min(p[0] for p in pts))); mxx = min(W-1, int(max(p[0] for p in pts))+1)
        mny = max(0, int(min(p[1] for p in pts))); mxy = min(H-1, int(max(p[1] for p in pts))+1)
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = pts
        den = (by-cy)*(ax-cx)+(cx-bx)*(ay-cy)
        if abs(den) < 1e-12: continue
        for py in range(mny, mxy+1):
            for px in range(mnx, mxx+1):
                l1 = ((by-cy)*(px-cx)+(cx-bx)*(py-cy))/den; l2 = ((cy-ay)*(px-cx)+(ax-cx)*(py-cy))/den; l3 = 1-l1-l2
                if l1 < 0 or l2 < 0 or l3 < 0: continue
                z = l1*az+l2*bz+l3*cz
                if z > zb[py][px]: zb[py][px] = z; img[py][px] = col
    return img
L = draw(exact, False); Rimg = draw(sk, True)
raw = b''.join(b'\0' + bytes(sum((L[y][x] for x in range(W)), ())) + bytes(sum((Rimg[y][x] for x in range(W)), ())) for y in range(H))
def chunk(t, d): return struct.pack('>I', len(d)) + t + d + struct.pack('>I', zlib.crc32(t + d) & 0xffffffff)
open(out, 'wb').write(b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', 2*W, H, 8, 2, 0, 0, 0)) + chunk(b'IDAT', zlib.compress(raw)) + chunk(b'IEND', b''))
