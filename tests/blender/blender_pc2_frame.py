# Blender as a real client of `animate --keep-frame` (issue 11): a z-up mesh file is imported
# into Blender as it is stored (Blender is z up: no axis conversion), a Mesh Cache modifier
# plays kinemesh's .pc2 on it, and the evaluated vertices must line up with the file: at the
# first frame (the take's reference: the body where it stands, its limbs in the performer's
# pose) the median vertex within TOL_MM of its imported rest position, and the cache must move
# the mesh by the last frame (it is read at all).
#
# Run headless:
#   blender -b --factory-startup --python tests/blender/blender_pc2_frame.py -- \
#       MESH.obj CACHE.pc2 TOL_MM
# Exits 1 when the first frame's median vertex is off by more than TOL_MM (a cache in
# kinemesh's frame on a z-up file: the mesh turned a quarter turn, metres off), 2 on usage /
# import errors.
import struct
import sys

import bpy


def fail(msg, rc=2):
    print(f"FAIL: {msg}")
    sys.stdout.flush()
    sys.exit(rc)


argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
if len(argv) != 3:
    fail("usage: blender -b --factory-startup --python blender_pc2_frame.py -- "
         "MESH.obj CACHE.pc2 TOL_MM")
obj_path, pc2_path, tol_mm = argv[0], argv[1], float(argv[2])

# The file's own positions, in its order (Blender's OBJ importer keeps the vertex order of a
# file whose faces use every vertex; checked below).
rest = []
with open(obj_path) as f:
    for line in f:
        if line.startswith("v "):
            rest.append(tuple(float(x) for x in line.split()[1:4]))
with open(pc2_path, "rb") as f:
    pc2 = f.read()
if len(pc2) < 32 or pc2[:11] != b"POINTCACHE2":
    fail(f"{pc2_path}: not a PC2 file")
nv, _start, _rate, nf = struct.unpack_from("<iffi", pc2, 16)
if nv != len(rest) or nf < 2:
    fail(f"{pc2_path}: {nv} points x {nf} frames for {len(rest)} vertices")

for o in list(bpy.data.objects):
    bpy.data.objects.remove(o, do_unlink=True)
# Blender's axes are the file's: z up, y forward (Blender's own convention), no conversion
bpy.ops.wm.obj_import(filepath=obj_path, forward_axis="Y", up_axis="Z")
objs = [o for o in bpy.context.scene.objects if o.type == "MESH"]
if len(objs) != 1:
    fail(f"{obj_path}: imported {len(objs)} mesh objects")
obj = objs[0]
me = obj.data
if len(me.vertices) != nv:
    fail(f"{obj_path}: Blender has {len(me.vertices)} vertices, the file {nv}")
W = obj.matrix_world
worst_import = max(
    ((W @ v.co) - __import__("mathutils").Vector(rest[i])).length for i, v in enumerate(me.vertices))
if worst_import > 1e-5:
    fail(f"{obj_path}: imported {worst_import:.3g} units off the file's positions (the axes "
         "were converted)")

mod = obj.modifiers.new("cache", "MESH_CACHE")
mod.cache_format = "PC2"
mod.filepath = pc2_path
mod.frame_start = 0.0
# the cache's axes as Blender's, as stored (the modifier's defaults)
mod.forward_axis = "POS_Y"
mod.up_axis = "POS_Z"


def positions(frame):
    bpy.context.scene.frame_set(frame)
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    m = ev.to_mesh()
    P = [tuple(W @ v.co) for v in m.vertices]
    ev.to_mesh_clear()
    return P


def dists(P):
    return sorted(sum((a - b) ** 2 for a, b in zip(p, q)) ** 0.5 for p, q in zip(P, rest))


first, last = dists(positions(0)), dists(positions(nf - 1))
off, moved = first[len(first) // 2], last[-1]
print(f"note: first frame's median vertex {off * 1e3:.3f} mm from the imported file (tolerance "
      f"{tol_mm} mm, its farthest {first[-1] * 1e3:.1f} mm), the last frame moves {moved * 1e3:.1f} "
      "mm at most")
if not moved > 0.01:
    fail(f"the cache does not move the mesh ({moved * 1e3:.3f} mm by the last frame)", 1)
if off > tol_mm * 1e-3:
    fail(f"the first frame's median vertex is {off * 1e3:.1f} mm off the file's positions", 1)
print("ok: the point cache lines up with the z-up file in Blender")
sys.exit(0)
