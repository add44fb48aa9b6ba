# Blender as a real writer of STL for kinemesh's reader: Blender imports an OBJ as stored and
# exports it as binary and as ASCII STL (its own exporter, no axis change); after kinemesh has
# converted each STL back to OBJ, the same script checks kinemesh's reading of them: the
# welded vertex count is the original's (every vertex of a closed triangle mesh is one
# position), the face count is the same, and each face's corner positions are those of the
# original's face with the same number, within float32 rounding (STL stores float32). And the
# other way: kinemesh's binary STL of the mesh imported by Blender's own STL importer, checked
# the same way against the original.
#
# Run headless:
#   blender -b --factory-startup --python tests/blender/blender_stl.py -- export MESH.obj ASCII.stl BINARY.stl
#   blender -b --factory-startup --python tests/blender/blender_stl.py -- check MESH.obj KM.obj
#   blender -b --factory-startup --python tests/blender/blender_stl.py -- import MESH.obj KM.stl
# Exits 1 when the check fails, 2 on usage / import / export errors.
import sys

import bpy


def fail(msg, rc=2):
    print(f"FAIL: {msg}")
    sys.stdout.flush()
    sys.exit(rc)


def read_obj(path):
    V, F = [], []
    with open(path) as f:
        for line in f:
            t = line.split()
            if not t:
                continue
            if t[0] == "v":
                V.append(tuple(float(x) for x in t[1:4]))
            elif t[0] == "f":
                F.append(tuple(int(x.split("/")[0]) - 1 for x in t[1:]))
    return V, F


argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
if len(argv) == 4 and argv[0] == "export":
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o, do_unlink=True)
    bpy.ops.wm.obj_import(filepath=argv[1], forward_axis="Y", up_axis="Z")
    objs = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    if len(objs) != 1:
        fail(f"{argv[1]}: imported {len(objs)} mesh objects")
    for path, ascii in ((argv[2], True), (argv[3], False)):
        r = bpy.ops.export_mesh.stl(filepath=path, ascii=ascii, axis_forward="Y", axis_up="Z",
                                    use_mesh_modifiers=False)
        if r != {"FINISHED"}:
            fail(f"{path}: Blender's STL export returned {r}")
    print(f"ok: exported {len(objs[0].data.vertices)} vertices, {len(objs[0].data.polygons)} "
          "faces as ASCII and binary STL")
    sys.exit(0)
if len(argv) != 3 or argv[0] not in ("check", "import"):
    fail("usage: blender -b --factory-startup --python blender_stl.py -- "
         "export MESH.obj ASCII.stl BINARY.stl | check MESH.obj KM.obj | import MESH.obj KM.stl")
V0, F0 = read_obj(argv[1])
if argv[0] == "check":
    V1, F1 = read_obj(argv[2])
else:
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o, do_unlink=True)
    r = bpy.ops.import_mesh.stl(filepath=argv[2], axis_forward="Y", axis_up="Z")
    objs = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    if r != {"FINISHED"} or len(objs) != 1:
        fail(f"{argv[2]}: Blender's STL import returned {r}, {len(objs)} mesh objects")
    me = objs[0].data
    V1 = [tuple(v.co) for v in me.vertices]
    F1 = [tuple(p.vertices) for p in me.polygons]
if len(V1) != len(V0) or len(F1) != len(F0):
    fail(f"{argv[2]}: {len(V1)} vertices and {len(F1)} faces, the original {len(V0)} and "
         f"{len(F0)}", 1)
# Blender writes each triangle's corners starting where it likes (its loop triangles): compare
# a face as the cyclic rotation that matches best, so a flipped or scrambled face still fails.
worst = 0.0
for i, (f0, f1) in enumerate(zip(F0, F1)):
    best = min(
        max(max(abs(a - b) for a, b in zip(V0[f0[k]], V1[f1[(k + r) % 3]])) for k in range(3))
        for r in range(3))
    worst = max(worst, best)
    if best > 1e-6 * (1 + max(abs(c) for c in V0[f0[0]])):
        fail(f"{argv[2]}: face {i + 1}'s corners are {best:.3g} away from the original's", 1)
print(f"ok: {argv[2]}: {len(V1)} vertices, {len(F1)} faces, corners within {worst:.2g} of the "
      "original")
