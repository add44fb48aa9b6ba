# Blender as a real client of kinemesh's .glb exports (issue 16): Debian's Blender imports
# FILE.glb with its own glTF importer (io_scene_gltf2), plays the animation to frames 0, the
# middle and the last, and the evaluated vertex positions (depsgraph: shape keys and the
# armature modifier applied) are compared with kinemesh's exact frames in EXACT.pc2.
#
# Run headless:
#   blender -b --factory-startup --python tests/blender/blender_check.py -- \
#       FILE.glb EXACT.pc2 REST.obj TOL_MM|auto [compressed]
# auto: the file's own reported max error (asset.extras.kinemesh.max_error_m) plus 0.1 mm
# (float32 payloads, Blender's float32 skinning); a number: that tolerance in mm.
# Exits 1 when a frame is off by more than the tolerance, 2 on usage / import errors.
# compressed: FILE is a --compress export; Blender 3.4's importer refusing it for
# EXT_meshopt_compression passes (that is documented); any other import error fails.
#
# Blender is Z up, glTF (and kinemesh) Y up: the importer maps glTF (x, y, z) to Blender
# (x, -z, y); the positions read back are mapped the other way before comparing.
# Vertex order: with merge_vertices off the importer keeps the glTF vertices that the
# triangles use, in index order, so Blender's vertex i is kinemesh's vertex i when every vertex
# is used. That is checked on the unevaluated (rest / bind) mesh against REST.obj; when the
# count or the positions disagree, each Blender vertex is matched to the nearest rest vertex
# instead (a KD tree), and the test says so.
import json
import re
import struct
import sys

# Debian's Blender 3.4 glTF importer still uses numpy.bool (gltf2_blender_mesh.py), an alias
# removed in numpy 1.24, which Debian ships: without this the import fails with an
# AttributeError. It must be set before the importer runs.
import numpy

if "bool" not in vars(numpy):  # (hasattr would print numpy's FutureWarning)
    numpy.bool = bool

import bpy  # noqa: E402  (after the numpy fix on purpose)
from mathutils import kdtree  # noqa: E402


def fail(msg, rc=2):
    print(f"FAIL: {msg}")
    sys.stdout.flush()
    sys.exit(rc)


argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
if len(argv) not in (4, 5) or (len(argv) == 5 and argv[4] != "compressed"):
    fail("usage: blender -b --factory-startup --python blender_check.py -- "
         "FILE.glb EXACT.pc2 REST.obj TOL_MM|auto [compressed]")
glb_path, pc2_path, rest_path, tol_arg = argv[:4]
compressed = len(argv) == 5

# The file's JSON chunk: the reported error and the frame rate.
with open(glb_path, "rb") as f:
    glb = f.read()
if len(glb) < 20 or glb[:4] != b"glTF":
    fail(f"{glb_path}: not a binary glTF")
jlen = struct.unpack_from("<I", glb, 12)[0]
gltf_json = json.loads(glb[20:20 + jlen].decode("utf-8"))
extras = gltf_json.get("asset", {}).get("extras", {}).get("kinemesh", {})
reported = float(extras.get("max_error_m", 0.0))
fps = float(extras.get("fps", 30.0))
tol = reported + 1e-4 if tol_arg == "auto" else float(tol_arg) / 1000.0

# The exact frames (PC2: "POINTCACHE2\0", version, points, start, rate, samples; float32).
with open(pc2_path, "rb") as f:
    pc2 = f.read()
if len(pc2) < 32 or pc2[:11] != b"POINTCACHE2":
    fail(f"{pc2_path}: not a PC2 file")
nv, _start, _rate, nf = struct.unpack_from("<iffi", pc2, 16)
if nv <= 0 or nf <= 0 or len(pc2) < 32 + nv * nf * 12:
    fail(f"{pc2_path}: truncated ({nv} points x {nf} frames)")
exact = numpy.frombuffer(pc2, dtype="<f4", count=nv * nf * 3, offset=32).reshape(nf, nv, 3)

rest = []
with open(rest_path) as f:
    for line in f:
        if line.startswith("v "):
            rest.append([float(x) for x in line.split()[1:4]])
rest = numpy.array(rest)
if len(rest) != nv:
    fail(f"{rest_path} has {len(rest)} vertices, {pc2_path} {nv}")

# Import into an empty scene at the file's frame rate: the importer turns seconds into frames
# with scene.render.fps, so Blender frame k is kinemesh frame k.
scene = bpy.context.scene
for ob in list(bpy.data.objects):
    bpy.data.objects.remove(ob, do_unlink=True)
scene.render.fps = max(1, round(fps))
scene.render.fps_base = scene.render.fps / fps
try:
    r = bpy.ops.import_scene.gltf(filepath=glb_path, merge_vertices=False)
except Exception as e:  # the importer raises on what it cannot read
    # A --compress file (compressed): Debian's Blender 3.4 importer does not decode
    # EXT_meshopt_compression (io/imp/gltf2_io_gltf.py: not in extensions_managed, so a file
    # that requires it is refused with "Extension EXT_meshopt_compression is not available on
    # this addon version"); the README says to give Blender the plain export. That refusal is
    # what this checks; an importer that decodes the file is checked like any other below.
    if compressed and "EXT_meshopt_compression" in str(e) and \
            "EXT_meshopt_compression" in gltf_json.get("extensionsRequired", []):
        print(f"note: Blender {bpy.app.version_string}'s glTF importer refuses "
              f"{glb_path.rsplit('/', 1)[-1]}: {str(e).strip()} (documented: give Blender the "
              f"plain export)")
        print(f"ok: {glb_path.rsplit('/', 1)[-1]}: refused as documented")
        sys.stdout.flush()
        sys.exit(0)
    fail(f"{glb_path}: Blender's importer: {e}")
if "FINISHED" not in r:
    fail(f"{glb_path}: Blender's importer returned {r}")
meshes = [ob for ob in scene.objects if ob.type == "MESH"]
if len(meshes) != 1:
    fail(f"{glb_path}: expected one mesh object, Blender made {len(meshes)}")
ob = meshes[0]
kind = ("skinned" if ob.find_armature() is not None else
        f"{len(ob.data.shape_keys.key_blocks) - 1} shape keys" if ob.data.shape_keys else "static")


def to_gltf(P):
    """Blender Z-up world coordinates -> glTF / kinemesh Y up."""
    return numpy.stack([P[:, 0], P[:, 2], -P[:, 1]], axis=1)


def world_positions(obj, evaluated):
    if evaluated:
        src = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        me = src.to_mesh()
    else:
        src, me = obj, obj.data
    co = numpy.empty(len(me.vertices) * 3, dtype=numpy.float64)
    me.vertices.foreach_get("co", co)
    M = numpy.array(src.matrix_world)
    P = co.reshape(-1, 3) @ M[:3, :3].T + M[:3, 3]
    if evaluated:
        src.to_mesh_clear()
    return to_gltf(P)


def clamped_weights(obj):
    """Animated shape-key weights outside their key's slider range (slider_min / slider_max,
    which clamp the value). Debian's Blender 3.4 importer widens a slider's default [0, 1] by
    the weight of the FIRST key of the animation only (gltf2_blender_animation_weight.py:
    min(coords[1:2]) where coords[1::2] was meant), so kinemesh writes every morph weight in
    [0, 1] (morphs:K: each basis target scaled and offset, the offset one more target) and the
    file plays as imported. Returns how many keyframes would be clamped (0 expected)."""
    sk = obj.data.shape_keys
    if sk is None or sk.animation_data is None:
        return 0
    acts = [sk.animation_data.action] + [st.action for tr in sk.animation_data.nla_tracks
                                         for st in tr.strips]
    clamped = 0
    for act in [a for a in acts if a is not None]:
        for fc in act.fcurves:
            m = re.match(r'key_blocks\["(.*)"\]\.value$', fc.data_path)
            if not m or m.group(1) not in sk.key_blocks:
                continue
            kb = sk.key_blocks[m.group(1)]
            clamped += sum(1 for p in fc.keyframe_points
                           if not kb.slider_min - 1e-6 <= p.co[1] <= kb.slider_max + 1e-6)
    return clamped


# Vertex correspondence, checked on the rest (bind) mesh.
scene.frame_set(0)
base = world_positions(ob, evaluated=False)
if len(base) == nv and numpy.abs(base - rest).max() <= 1e-4:
    order = numpy.arange(nv)
    how = "same vertex order"
else:
    tree = kdtree.KDTree(nv)
    for i, p in enumerate(rest):
        tree.insert(p, i)
    tree.balance()
    order = numpy.array([tree.find(p)[1] for p in base])
    how = f"matched by nearest rest position ({len(base)} Blender vertices, {nv} kinemesh)"
print(f"{glb_path}: {kind}, {len(base)} vertices, {how}; fps {fps:g}; "
      f"reported max error {reported * 1e3:.3f} mm")

frames = [0, (nf - 1) // 2, nf - 1]
# A test that passes when Blender plays nothing proves nothing: the take must move some checked
# frame away from the first by well over the tolerance.
moved = max(float(numpy.linalg.norm(exact[k] - exact[0], axis=1).max()) for k in frames)
if moved < 5 * tol:
    fail(f"{pc2_path}: the checked frames move at most {moved * 1e3:.3f} mm, under 5x the "
         f"tolerance ({tol * 1e3:.3f} mm): make a take that moves more")


def frame_error(k):
    scene.frame_set(k)
    d = numpy.linalg.norm(world_positions(ob, evaluated=True) - exact[k][order], axis=1)
    return float(d.max()), float(numpy.sqrt((d * d).mean()))


rc = 0
clamped = clamped_weights(ob)
if clamped:
    print(f"FAIL: {glb_path.rsplit('/', 1)[-1]}: {clamped} shape-key weights outside their "
          f"slider range as imported (Blender clamps them)")
    rc = 1
for k in frames:
    worst, rms = frame_error(k)
    ok = worst <= tol
    if not ok:
        rc = 1
    print(f"{'ok' if ok else 'FAIL'}: {glb_path.rsplit('/', 1)[-1]} ({kind}) frame {k}: "
          f"max {worst * 1e3:.3f} mm, rms {rms * 1e3:.3f} mm (tolerance {tol * 1e3:.3f} mm)")
sys.stdout.flush()
sys.exit(rc)
