# Blender as the exporter of a textured mesh split at its texture seams (what every glTF
# exporter writes, issue 11): run headless in two steps by run_blender_seams.sh.
#
#   export SRC.obj OUT.glb
#     imports SRC.obj, unwraps it with Smart UV Project (islands: the mesh is cut along every
#     island border), gives it a material whose base colour is a generated 64x32 image, and
#     exports OUT.glb with its texture coordinates and smooth normals; the
#     glTF exporter splits every vertex on an island border into copies at one position.
#   check SRC_UV.glb ANIM.pc2 ANIM.glb SKIN.glb
#     after kinemesh rig + animate of SRC_UV.glb: every vertex of the point cache that lay
#     exactly on another at rest (a seam's copies) is still exactly on it in every frame (the
#     seams stay shut), the mesh moved, and Blender's import of ANIM.glb has SRC_UV.glb's
#     texture coordinates loop for loop (kinemesh kept the vertex order and the UVs) and its
#     base colour texture, pixel for pixel (the material carried over); SKIN.glb
#     (animate --export skin), played by Blender's armature, keeps every copy on its vertex too
#     (within 1e-5 m: float32 skinning of the same weights).
#   export-skinned SRC.obj SRC.rig.json OUT.glb
#     the same, with an armature first: Mixamo's bone names (mixamorig:Hips, LeftArm,
#     LeftForeArm, ...) on the joints of kinemesh's sidecar, the mesh bound to it with
#     Blender's automatic weights (bone heat), exported skinned: a game character as Blender
#     writes one.
#   gaps SRC_UV.glb OUT...
#     every OUT (.pc2, or a .glb of per-frame morph targets) keeps each seam copy exactly on
#     its vertex in every frame.
# Exits 1 when a check fails, 2 on usage or import errors.
import os
import struct
import sys

import numpy

if "bool" not in vars(numpy):  # Debian's Blender 3.4 glTF importer uses numpy.bool
    numpy.bool = bool

import bpy  # noqa: E402


def fail(msg, rc=1):
    print(f"FAIL: {msg}")
    sys.exit(rc)


def glb_positions(path):
    """POSITION of the first primitive, in the file's order (y up, as kinemesh reads it)."""
    import json

    b = open(path, "rb").read()
    if b[:4] != b"glTF":
        fail(f"{path}: not a .glb", 2)
    jl = struct.unpack("<I", b[12:16])[0]
    j = json.loads(b[20 : 20 + jl])
    blob = b[20 + jl + 8 :]
    a = j["accessors"][j["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
    v = j["bufferViews"][a["bufferView"]]
    off = v.get("byteOffset", 0) + a.get("byteOffset", 0)
    return numpy.frombuffer(blob, numpy.float32, a["count"] * 3, off).reshape(-1, 3)


def glb_frames(path):
    """Per-frame positions of a morph-target .glb (base + each target), file order."""
    import json

    b = open(path, "rb").read()
    jl = struct.unpack("<I", b[12:16])[0]
    j = json.loads(b[20 : 20 + jl])
    blob = b[20 + jl + 8 :]

    def acc(i):
        a = j["accessors"][i]
        v = j["bufferViews"][a["bufferView"]]
        off = v.get("byteOffset", 0) + a.get("byteOffset", 0)
        if a["componentType"] != 5126 or "sparse" in a:
            fail(f"{path}: accessor {i} is not plain float32 (write it without --compress)", 2)
        return numpy.frombuffer(blob, numpy.float32, a["count"] * 3, off).reshape(-1, 3)

    p = j["meshes"][0]["primitives"][0]
    base = acc(p["attributes"]["POSITION"])
    targets = p.get("targets", [])
    if not targets:
        fail(f"{path}: no morph targets", 2)
    return numpy.stack([base + acc(t["POSITION"]) for t in targets])


def seam_pairs(rest):
    _, inv, cnt = numpy.unique(rest, axis=0, return_inverse=True, return_counts=True)
    first, pairs = {}, []
    for i, c in enumerate(inv.ravel()):
        if cnt[c] > 1:
            if c in first:
                pairs.append((first[c], i))
            else:
                first[c] = i
    return numpy.array([q[0] for q in pairs]), numpy.array([q[1] for q in pairs])


def seams_shut(path, frames, rest, a, b, min_move):
    """Fails unless every seam pair (a[i], b[i]) is exactly together in every frame of path
    (its vertex count the glb's: the order kept) and the mesh moved at least min_move m."""
    if frames.shape[1] != len(rest):
        fail(f"{path}: {frames.shape[1]} vertices, the glb {len(rest)}: the order is not kept")
    gap = max(float(numpy.linalg.norm(f[a] - f[b], axis=1).max()) for f in frames)
    moved = float(numpy.linalg.norm(frames - frames[0], axis=2).max())
    print(f"note: {path.rsplit('/', 1)[-1]}: {len(a)} seam copies, {len(frames)} frames, largest "
          f"seam gap {gap:.3g} m, largest move {moved:.3f} m")
    if gap > 0:
        fail(f"{path}: the seams opened by {gap:.3g} m")
    if moved < min_move:
        fail(f"{path}: the mesh moved {moved:.3g} m: no animation")


def pc2(path):
    b = open(path, "rb").read()
    nv, _, _, nf = struct.unpack("<iffi", b[16:32])
    return numpy.frombuffer(b, numpy.float32, nf * nv * 3, 32).reshape(nf, nv, 3)


def image_into(node_input):
    """The image of the Image Texture node linked into a shader input: (size, pixels), or None."""
    for link in node_input.links:
        node = link.from_node
        if node.type == "TEX_IMAGE" and node.image is not None:
            return tuple(node.image.size), numpy.array(node.image.pixels[:])
    return None


def blender_import(path):
    """A fresh scene with path imported by Blender's own importer (OBJ, PLY or glTF): its mesh."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if path.endswith(".obj"):
        bpy.ops.wm.obj_import(filepath=path)
    elif path.endswith(".ply"):
        bpy.ops.import_mesh.ply(filepath=path)
    else:
        bpy.ops.import_scene.gltf(filepath=path)
    return [o for o in bpy.context.scene.objects if o.type == "MESH"][0].data


def import_uvs(path):
    """Blender's import (glTF, or OBJ with its .mtl): vertex count, loops' vertices, UVs, its
    material's base colour texture's pixels (None: no textured material), and its normal map
    as (size, pixels, strength) (None: none)."""
    me = blender_import(path)
    if not me.uv_layers:
        fail(f"{path}: Blender finds no texture coordinates")
    uv = numpy.zeros(2 * len(me.loops))
    me.uv_layers[0].data.foreach_get("uv", uv)
    vi = numpy.zeros(len(me.loops), dtype=numpy.int64)
    me.loops.foreach_get("vertex_index", vi)
    px = nm = None
    for mat in me.materials:
        for node in (mat.node_tree.nodes if mat and mat.use_nodes else []):
            if node.type != "BSDF_PRINCIPLED":
                continue
            px = image_into(node.inputs["Base Color"]) or px
            for link in node.inputs["Normal"].links:
                if link.from_node.type == "NORMAL_MAP":
                    im = image_into(link.from_node.inputs["Color"])
                    strength = link.from_node.inputs["Strength"].default_value
                    nm = im + (strength,) if im else nm
    return len(me.vertices), vi, uv, px, nm


def same_surface(src_path, src, path):
    """path as Blender imports it is src (import_uvs of src_path): its vertices and loops, its
    UVs, its base colour texture and its normal map; returns (vertices, largest UV change)."""
    n0, vi0, uv0, px0, nm0 = src
    if px0 is None or nm0 is None:
        fail(f"{src_path}: Blender finds no base colour texture or normal map in its own export", 2)
    n1, vi1, uv1, px1, nm1 = import_uvs(path)
    same_normal_map(path, nm0, nm1)
    if px1 is None:
        fail(f"{path}: no base colour texture: the textured model comes out grey")
    if px1[0] != px0[0] or float(numpy.abs(px1[1] - px0[1]).max()) > 1e-6:
        fail(f"{path}: its texture ({px1[0]}) differs from the source's ({px0[0]})")
    if n0 != n1 or not numpy.array_equal(vi0, vi1):
        fail(f"Blender imports {n1} vertices from {path} and {n0} from {src_path}, or other loops")
    duv = float(numpy.abs(uv0 - uv1).max())
    if duv > 1e-6:
        fail(f"{path}: texture coordinates differ by {duv:.3g}")
    return n1, duv


def same_normal_map(path, nm0, nm1):
    """The output's normal map is the source's: same pixels, same strength."""
    if nm1 is None:
        fail(f"{path}: no normal map: the surface detail is lost")
    if nm1[0] != nm0[0] or float(numpy.abs(nm1[1] - nm0[1]).max()) > 1e-6:
        fail(f"{path}: its normal map ({nm1[0]}) differs from the source's ({nm0[0]})")
    if abs(nm1[2] - nm0[2]) > 1e-6:
        fail(f"{path}: its normal map's strength {nm1[2]} is not the source's {nm0[2]}")


argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
def packed_image(name, r, g, b, colorspace):
    """A Blender image of these channels (rows bottom-up, alpha 1), packed into the .blend."""
    h, w = r.shape
    img = bpy.data.images.new(name, w, h)
    if colorspace:
        img.colorspace_settings.name = colorspace
    img.pixels = numpy.stack([r, g, b, numpy.ones_like(r)], axis=-1).ravel().tolist()
    img.pack()
    return img


def unwrap_and_export(ob, out, skins):
    """Smart UV Project, a generated 64x32 image as its base colour texture, exported."""
    bpy.context.view_layer.objects.active = ob
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.uv.smart_project(angle_limit=1.15)
    bpy.ops.object.mode_set(mode="OBJECT")
    bpy.ops.object.shade_smooth()
    u, v = numpy.meshgrid(numpy.linspace(0, 1, 64), numpy.linspace(0, 1, 32))
    img = packed_image("skin", u, v, numpy.full_like(u, 0.5), None)
    mat = bpy.data.materials.new("skin")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    # and a normal map (16x16 ridges, strength 0.7: glTF's normalTexture.scale)
    ridge = numpy.tile(0.5 + 0.4 * numpy.sin(numpy.arange(16) * numpy.pi / 4), (16, 1))
    nimg = packed_image("ridges", ridge, numpy.full_like(ridge, 0.5), numpy.ones_like(ridge),
                        "Non-Color")
    ntex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    ntex.image = nimg
    nmap = mat.node_tree.nodes.new("ShaderNodeNormalMap")
    nmap.inputs["Strength"].default_value = 0.7
    mat.node_tree.links.new(ntex.outputs["Color"], nmap.inputs["Color"])
    mat.node_tree.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    ob.data.materials.append(mat)
    bpy.ops.export_scene.gltf(filepath=out, export_format="GLB", export_texcoords=True,
                              export_normals=True, export_skins=skins, export_animations=False)


def armature_on(body, rig_path):
    """Mixamo-named bones on the sidecar's joints, body bound with Blender's bone heat."""
    import json

    from mathutils import Vector

    J = {j["name"]: j["rest"] for j in json.load(open(rig_path))["joints"]}

    def bl(p):  # y up (kinemesh, OBJ) -> Blender's z up, as the OBJ importer maps it
        return Vector((p[0], -p[2], p[1]))

    bpy.ops.object.armature_add(enter_editmode=True)
    arm = bpy.context.object
    eb = arm.data.edit_bones
    eb.remove(eb[0])
    up, fwd = Vector((0, 0, 0.08)), Vector((0, -0.06, 0))
    spec = [("Hips", "HipCenter", "Spine", None), ("Spine", "Spine", "ShoulderCenter", "Hips"),
            ("Neck", "ShoulderCenter", "Head", "Spine"), ("Head", "Head", up, "Neck")]
    for s_ in ("Left", "Right"):
        spec += [(s_ + "Shoulder", "ShoulderCenter", "Shoulder" + s_, "Spine"),
                 (s_ + "Arm", "Shoulder" + s_, "Elbow" + s_, s_ + "Shoulder"),
                 (s_ + "ForeArm", "Elbow" + s_, "Wrist" + s_, s_ + "Arm"),
                 (s_ + "Hand", "Wrist" + s_, "Hand" + s_, s_ + "ForeArm"),
                 (s_ + "UpLeg", "Hip" + s_, "Knee" + s_, "Hips"),
                 (s_ + "Leg", "Knee" + s_, "Ankle" + s_, s_ + "UpLeg"),
                 (s_ + "Foot", "Ankle" + s_, "Foot" + s_, s_ + "Leg"),
                 (s_ + "ToeBase", "Foot" + s_, fwd, s_ + "Foot")]
    for name, h, t, parent in spec:
        b = eb.new("mixamorig:" + name)
        b.head = bl(J[h])
        b.tail = b.head + t if isinstance(t, Vector) else bl(J[t])
        if parent:
            b.parent = eb["mixamorig:" + parent]
    bpy.ops.object.mode_set(mode="OBJECT")
    bpy.ops.object.select_all(action="DESELECT")
    body.select_set(True)
    arm.select_set(True)
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.parent_set(type="ARMATURE_AUTO")
    bare = sum(1 for v in body.data.vertices if not v.groups)
    if bare:
        fail(f"Blender's automatic weights left {bare} vertices without a bone", 2)
    return len(spec)


if len(argv) == 4 and argv[0] == "export-skinned":
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.obj_import(filepath=argv[1])
    ob = bpy.context.selected_objects[0]
    nb = armature_on(ob, argv[2])
    unwrap_and_export(ob, argv[3], True)
    print(f"ok: exported {argv[3]}: {len(ob.data.vertices)} vertices on {nb} bones, unwrapped")
elif len(argv) >= 3 and argv[0] == "gaps":
    rest = glb_positions(argv[1]).astype(numpy.float64)
    a, b = seam_pairs(rest)
    if len(a) < 100:
        fail(f"{argv[1]}: only {len(a)} coincident vertices: the export was not split")
    for path in argv[2:]:
        seams_shut(path, pc2(path) if path.endswith(".pc2") else glb_frames(path), rest, a, b,
                   0.01)
    print(f"ok: {len(argv) - 2} outputs with {len(a)} seam copies each, every seam shut")
elif len(argv) >= 3 and argv[0] == "objcheck":
    # OBJ outputs (convert, animate's frame folder) as Blender's OBJ importer reads them: the
    # same vertices and loops as the source, its UVs, and its texture through the .mtl
    src = import_uvs(argv[1])
    for path in argv[2:]:
        n1, duv = same_surface(argv[1], src, path)
        print(f"note: {os.path.basename(path)}: {n1} vertices, the source's "
              f"{src[3][0][0]}x{src[3][0][1]} texture and normal map, UVs within {duv:.2g}")
    print(f"ok: {len(argv) - 2} OBJ outputs textured as the source")
elif len(argv) >= 3 and argv[0] == "colors":
    # vertex colours (a scan's) as Blender's PLY and glTF importers read kinemesh's outputs:
    # every corner's sRGB colour within 1.5/255 of its vertex's in the source OBJ (v x y z r g b)
    want = numpy.array([[float(t) for t in line.split()[4:7]]
                        for line in open(argv[1]) if line.startswith("v ")])
    for path in argv[2:]:
        me = blender_import(path)
        if len(me.vertices) != len(want) or not me.color_attributes:
            fail(f"{path}: Blender imports {len(me.vertices)} vertices and "
                 f"{len(me.color_attributes)} colour attributes (want {len(want)} and 1)")
        col = me.color_attributes[0]
        got = numpy.array([tuple(d.color_srgb)[:3] for d in col.data])
        if col.domain == "CORNER":
            vi = numpy.zeros(len(me.loops), dtype=numpy.int64)
            me.loops.foreach_get("vertex_index", vi)
            ref = want[vi]
        else:
            ref = want
        dev = float(numpy.abs(got - ref).max())
        if dev > 1.5 / 255:
            fail(f"{path}: vertex colours off by {dev * 255:.2f}/255 as Blender reads them")
        print(f"note: {os.path.basename(path)}: {len(me.vertices)} vertices, colours within "
              f"{dev * 255:.2f}/255")
    print(f"ok: {len(argv) - 2} outputs with the source's vertex colours")
elif len(argv) == 3 and argv[0] == "export":
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.obj_import(filepath=argv[1])
    ob = bpy.context.selected_objects[0]
    unwrap_and_export(ob, argv[2], False)
    print(f"ok: exported {argv[2]}: {len(ob.data.vertices)} vertices unwrapped")
elif len(argv) == 5 and argv[0] == "check":
    rest = glb_positions(argv[1]).astype(numpy.float64)
    a, b = seam_pairs(rest)
    if len(a) < 100:
        fail(f"{argv[1]}: only {len(a)} coincident vertices: the export was not split")
    seams_shut(argv[2], pc2(argv[2]), rest, a, b, 0.05)
    src = import_uvs(argv[1])
    n1, duv = same_surface(argv[1], src, argv[3])
    print(f"note: the animation's material has the source's {src[3][0][0]}x{src[3][0][1]} "
          f"texture and normal map (strength {src[4][2]:.2f})")
    # the skinned export, as Blender's armature plays it
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=argv[4])
    scene = bpy.context.scene
    ob = [o for o in scene.objects if o.type == "MESH"][0]
    if len(ob.data.vertices) != len(rest):
        fail(f"{argv[4]}: Blender imports {len(ob.data.vertices)} vertices, the glb {len(rest)}")
    sgap = 0.0
    for k in range(scene.frame_start, scene.frame_end + 1, 4):
        scene.frame_set(k)
        ev = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
        me = ev.to_mesh()
        co = numpy.empty(len(me.vertices) * 3)
        me.vertices.foreach_get("co", co)
        ev.to_mesh_clear()
        co = co.reshape(-1, 3)
        sgap = max(sgap, float(numpy.linalg.norm(co[a] - co[b], axis=1).max()))
    print(f"note: skinned export, largest seam gap as Blender plays it {sgap:.3g} m")
    if sgap > 1e-5:
        fail(f"the skinned export opens the seams by {sgap:.3g} m")
    print(f"ok: seams shut, {n1} vertices, texture coordinates kept ({duv:.2g})")
else:
    fail("usage: blender -b --python blender_seams.py -- export SRC.obj OUT.glb | "
         "check SRC_UV.glb ANIM.pc2 ANIM.glb SKIN.glb | export-skinned SRC.obj SRC.rig.json OUT.glb | "
         "gaps SRC_UV.glb OUT... | objcheck SRC_UV.glb OUT.obj... | colors SRC.obj OUT...", 2)
